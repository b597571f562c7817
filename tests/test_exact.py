import numpy as np
import pytest

from signorini.studies.exact import ExactBar1D


def test_bar1d_matches_zone_table():
    ex = ExactBar1D.bar1d(T=9.0)
    rng = np.random.default_rng(0)
    for _ in range(200):
        x, t = rng.uniform(0, 1), rng.uniform(0, 9)
        tau = t % 3
        k, s = int(tau), tau - int(tau)
        z1, z2 = s <= x, s <= 1 - x
        table = {
            0: {(1, 1): (1 - x) / 2, (0, 1): (1 - s) / 2, (1, 0): (1 - x) / 2, (0, 0): (1 - s) / 2},
            1: {(1, 1): -s / 2, (0, 1): -x / 2, (1, 0): (x - 1) / 2, (0, 0): (s - 1) / 2},
            2: {(1, 1): s / 2, (0, 1): s / 2, (1, 0): (1 - x) / 2, (0, 0): (1 - x) / 2},
        }
        assert np.isclose(ex.u(x, t), table[k][(int(z1), int(z2))])
    t = np.array([0.5, 1.5, 2.5, 3.5, 4.5])
    assert np.allclose(ex.contact_stress(t), [0, -0.5, 0, 0, -0.5])
    assert np.allclose(ex.contact_displacement(t), [0.25, 0, 0.25, 0.25, 0])


@pytest.mark.parametrize("L, E, rho, gap", [(1, 1, 1, 0.5), (2.0, 4.0, 1.0, 0.3), (0.5, 1.0, 4.0, 0.1)])
def test_bar1d_scaled_events_and_energy(L, E, rho, gap):
    ex = ExactBar1D.bar1d(L, E, rho, gap, T=20)
    c = np.sqrt(E / rho)
    t_imp, t_rel = L / c, 2 * L / c
    eps = 1e-6 * L / c
    assert ex.contact_displacement(t_imp - eps) > 0
    assert np.isclose(ex.contact_stress(0.5 * (t_imp + t_rel)), -E * gap / L)
    assert np.isclose(ex.contact_displacement(3 * L / c + 0.5 * L / c), ex.contact_displacement(0.5 * L / c))
    x = np.linspace(0, L, 40001)
    for t in np.array([0.3, 1.3, 2.7, 4.1]) * L / c:
        e = 0.5 * np.trapezoid(rho * ex.u_t(x, t) ** 2 + E * ex.u_x(x, t) ** 2, x)
        assert np.isclose(e, E * gap**2 / (2 * L), rtol=1e-3)


@pytest.mark.parametrize("gap, v", [(0.2, 0.5), (0.1, 1.0), (0.3, 0.6)])
def test_bar1d_impact_events(gap, v):
    ex = ExactBar1D.bar1d_impact(gap=gap, velocity=v, T=12)
    t_imp = gap / v
    assert np.isclose(ex.contact_displacement(t_imp), 0, atol=1e-12)
    assert ex.contact_displacement(0.99 * t_imp) > 0
    assert np.isclose(ex.contact_stress(0.5 * (t_imp + 1.0)), -v)
    assert ex.contact_displacement(1.01) > 0  # released at L/c = 1
    x = np.linspace(0, 1, 40001)
    for t in (0.3, 1.3, 2.9, 5.0):
        e = 0.5 * np.trapezoid(ex.u_t(x, t) ** 2 + ex.u_x(x, t) ** 2, x)
        assert np.isclose(e, 0.5 * v**2, rtol=1e-3)
    # the constraint holds and the multiplier is compressive, complementarity
    t = np.linspace(0, 12, 5001)
    g, s = ex.contact_displacement(t), ex.contact_stress(t)
    assert g.min() > -1e-12 and s.max() < 1e-12
    assert np.max(np.abs(g * s)) < 1e-12

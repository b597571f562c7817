"""The dynamic solver against the 1D exact solutions, energy identities, 2D/3D facts."""

import numpy as np
import pytest

from signorini.dynamics.stepping.simulate import simulate
from signorini.errors import InputError
from signorini.studies.benchmarks import get_benchmark
from signorini.studies.study import errors_1d, observed_rates


def assert_complementarity(H, tol=1e-10):
    scale = np.max(np.abs(H.gap[0])) or 1.0
    assert H.gap.min() >= -tol * scale
    assert H.lam.max() <= 0.0
    lam_scale = max(np.abs(H.lam).max(), 1e-300)
    assert np.max(np.abs(H.gap * H.lam)) <= tol * scale * lam_scale
    assert H.residual.max() <= tol


def assert_energy_identity(H):
    dE = H.energy_increment[1:]
    pred = H.predicted_increment[1:]
    scale = H.energy[0]
    assert np.max(np.abs(dE - pred)) <= 5e-12 * scale  # measured 6.6e-14 (max over the tests using it)


def _levels(name, mass, scheme, levels, T=3.0, params=None):
    b = get_benchmark(name)
    rows, hs = [], []
    for n in levels:
        p = b.problem(n, params)
        h = b.h(n, params)
        dt = h / (2 * b.wave_speed(params))
        Tn = dt * round(T / dt)  # T must be a multiple of dt: the nearest one
        H = simulate(p, scheme, dt, Tn, mass=mass, snapshot_every=1)
        assert_complementarity(H)
        assert_energy_identity(H)
        rows.append(errors_1d(H, p, b.exact(b.params(params), Tn)))
        hs.append(h)
    return {k: observed_rates([r[k] for r in rows], hs) for k in rows[0]}, rows


LEVELS = (20, 40, 80, 160)


@pytest.mark.parametrize(
    "params, finest",
    [({"gap": 0.3, "E": 4.0}, (0.22, 0.028)), ({"L": 2.0, "rho": 2.0, "gap": 0.2}, (0.17, 0.0123))],
)
def test_cn_seed_converges_non_default_parameters(params, finest):
    """n = 20, 40, 80, 160 (dt = h/2c) against the exact solution (ExactBar1D, no reference
    run).  Measured mean rates u_H1 0.43 / 0.42, u_L2 0.99 / 1.01; finest errors u_H1
    0.199 / 0.153, u_L2 0.0252 / 0.0111 (bounds 10% above)."""
    rates, rows = _levels("bar1d", "seed", "cn", LEVELS, T=3.0 * params.get("L", 1.0), params=params)
    assert 0.3 < np.mean(rates["u_H1"]) < 0.55, rates["u_H1"]
    assert 0.85 < np.mean(rates["u_L2"]) < 1.15, rates["u_L2"]
    assert rows[-1]["u_H1"] <= finest[0] and rows[-1]["u_L2"] <= finest[1], rows[-1]


def test_impact_non_default_parameters_converge():
    """Against the exact solution (no reference run), n = 20 .. 160: measured stress rates 0.37,
    0.36, 0.31 (mean 0.34), finest errors stress 0.139, u_H1 0.143."""
    rates, rows = _levels("bar1d-impact", "seed", "cn", LEVELS, params={"gap": 0.1, "velocity": 1.0})
    assert 0.25 < np.mean(rates["stress"]) < 0.45, rates["stress"]
    assert rows[-1]["stress"] < 0.153 and rows[-1]["u_H1"] < 0.16, rows[-1]


@pytest.mark.parametrize("mass", ["standard", "seed"])
def test_be_converges_and_dissipates(mass):
    """Against the exact solution (no reference run), n = 20 .. 160: measured mean rates u_H1
    0.26 (standard) / 0.28 (seed), u_L2 0.52 / 0.51; finest errors u_H1 0.208 / 0.206, u_L2
    0.0746 / 0.0663 (bounds about 10% above)."""
    rates, rows = _levels("bar1d", mass, "be", LEVELS)
    assert 0.18 < np.mean(rates["u_H1"]) < 0.35, rates["u_H1"]
    assert 0.4 < np.mean(rates["u_L2"]) < 0.65, rates["u_L2"]
    assert rows[-1]["u_H1"] < 0.23 and rows[-1]["u_L2"] < (0.082 if mass == "standard" else 0.073), rows[-1]
    b = get_benchmark("bar1d")
    H = simulate(b.problem(40), "be", b.h(40) / 2, 6.0, mass=mass)
    assert np.all(np.diff(H.energy) <= 1e-14 * H.energy[0])
    assert H.energy[-1] < 0.8 * H.energy[0]


def test_cn_standard_mass_gains_energy_and_does_not_converge():
    b = get_benchmark("bar1d")
    E_end = []
    for n in (40, 160):
        H = simulate(b.problem(n), "cn", b.h(n) / 2, 3.0, mass="standard")
        assert_complementarity(H)
        assert_energy_identity(H)
        E_end.append(H.energy[-1])
    assert min(E_end) > 1.5 * 0.125  # the paper's finding: energy grows after impact
    rates, rows = _levels("bar1d", "standard", "cn", (40, 160))
    assert rows[-1]["stress"] > 1.0 and rows[-1]["u_H1"] > 0.5


def test_bar3d_contact_and_identity():
    b = get_benchmark("bar3d")
    H = simulate(b.problem(2), "cn", b.h(2) / 2, 1.0, mass="seed")
    assert_complementarity(H)
    assert_energy_identity(H)
    assert H.impacts == 1


@pytest.mark.parametrize("bench", ["bar2d", "bar3d"])
def test_far_obstacle_cn_conserves_energy(bench):
    from signorini.contact.obstacles import PlaneObstacle

    b = get_benchmark(bench)
    p = b.problem(2)
    e = np.eye(b.dim)[-1]
    p.obstacle = PlaneObstacle(-50.0 * e, e)  # the obstacle 50 lengths below the bar
    H = simulate(p, "cn", b.h(2) / 2, 2.0, mass="standard")
    assert H.lam.min() == 0.0
    assert np.max(np.abs(H.energy - H.energy[0])) < 1e-13 * H.energy[0] * H.steps


def test_bar2d_symmetric_about_midline():
    b = get_benchmark("bar2d")
    H = simulate(b.problem(4), "cn", b.h(4) / 2, 1.0, mass="seed", snapshot_every=5)
    x = H.coordinates[:, 0]
    order, mirror = np.argsort(x), np.argsort(0.1 - x)
    # docs/verification.md: symmetric to 1e-12 (measured 1.5e-13 max|lam|, 1e-14 on u ~ 0.2)
    assert np.allclose(H.lam[:, order], H.lam[:, mirror], rtol=0, atol=1e-12 * np.abs(H.lam).max())
    p = b.problem(4)
    pts = p.mesh.points
    key = np.lexsort((pts[:, 0], pts[:, 1]))
    key_m = np.lexsort((np.round(0.1 - pts[:, 0], 12), pts[:, 1]))
    u = H.snapshots["u"][-1].reshape(-1, 2)
    assert np.allclose(u[key, 1], u[key_m, 1], rtol=0, atol=4e-13)  # measured 4.2e-15 (u ~ 0.2)
    assert np.allclose(u[key, 0], -u[key_m, 0], rtol=0, atol=4e-13)  # measured 7.7e-15


def test_cn_seed_nearly_conservative_in_2d():
    b = get_benchmark("bar2d")
    H = simulate(b.problem(4), "cn", b.h(4) / 2, 4.0, mass="seed")
    Hs = simulate(b.problem(4), "cn", b.h(4) / 2, 4.0, mass="standard")
    drift = np.max(np.abs(H.energy - H.energy[0])) / H.energy[0]
    drift_std = np.max(np.abs(Hs.energy - Hs.energy[0])) / Hs.energy[0]
    assert drift < 0.05 and drift_std > 10 * drift


def test_bad_inputs():
    b = get_benchmark("bar1d")
    p = b.problem(4)
    with pytest.raises(InputError, match="dt must be > 0"):
        simulate(p, "cn", -0.1, 1.0)
    with pytest.raises(InputError, match="T must be >= dt"):
        simulate(p, "cn", 0.1, 0.01)
    with pytest.raises(InputError, match="unknown scheme 'rk4'; allowed"):
        simulate(p, "rk4", 0.1, 1.0)
    with pytest.raises(InputError, match="unknown mass"):
        simulate(p, "cn", 0.1, 1.0, mass="nope")
    with pytest.raises(InputError, match="pushes contact node 0 .* into the obstacle"):
        simulate(b.problem(4, {"gap": 0.0}).__class__(**{**b.problem(4).__dict__, "u0": -0.1}), "cn", 0.1, 1.0)


def test_contact_node_fixed_by_dirichlet_is_an_error():
    from signorini.fem.space import Dirichlet

    b = get_benchmark("bar2d")
    p = b.problem(2)
    p.dirichlet = list(p.dirichlet) + [Dirichlet("ymin", 0.0, (1,))]
    with pytest.raises(InputError, match="fixed by a Dirichlet condition"):
        simulate(p, "cn", 0.1, 1.0)


def test_simulate_takes_its_options_as_one_object_or_as_keywords_never_positional():
    """Issue 53, item 3: after (problem, scheme, dt, T) every option is keyword-only; ``options=RunOptions(...)``
    gives the same run as its keywords; both at once, an unknown keyword or a fifth positional argument is
    refused by name."""
    from signorini.dynamics.stepping.run_options import RunOptions

    b = get_benchmark("bar1d")
    p = b.problem(10, {})
    dt, _ = b.run_times(10, {})
    a = simulate(p, "cn", dt, 20 * dt, mass="standard", scheme_options={}, handle_signals=False)
    o = simulate(p, "cn", dt, 20 * dt, options=RunOptions(mass="standard", scheme_options={}), handle_signals=False)
    assert a.meta["mass"] == o.meta["mass"] == "standard" and np.array_equal(a.lam, o.lam)
    with pytest.raises(InputError, match="not both"):
        simulate(p, "cn", dt, 20 * dt, options={"mass": "standard"}, energy=False)
    with pytest.raises(InputError, match=r"unknown keyword\(s\) 'mas'; allowed: mass, "):
        simulate(p, "cn", dt, 20 * dt, mas="standard")
    with pytest.raises(TypeError):
        simulate(p, "cn", dt, 20 * dt, "standard")  # type: ignore[misc]

import numpy as np
import pytest

from signorini.dynamics.simulate import simulate
from signorini.errors import InputError
from signorini.studies.benchmarks import get_benchmark
from signorini.studies.study import observed_rates


def _stress_errors(mass):
    b = get_benchmark("bar1d")
    ex = b.exact(b.params(), 3.0)
    errs, hs = [], []
    for n in (20, 40, 80, 160):
        H = simulate(b.problem(n), "ps", b.h(n) / 2, 3.0, mass=mass)
        assert H.gap.min() > -1e-12 and H.lam.max() <= 0 and H.residual.max() < 1e-10
        sig = ex.contact_stress(H.t[1:])
        errs.append(np.sqrt(np.sum((H.lam[1:, 0] - sig) ** 2) / np.sum(sig**2)))
        hs.append(b.h(n))
    return errs, observed_rates(errs, hs), H


def test_paoli_schatzman_converges_with_standard_mass():
    errs, rates, H = _stress_errors("standard")
    assert errs[-1] < 0.6 * errs[0] and np.mean(rates) > 0.2
    # dissipative at impacts with e = 0, but never gains energy
    assert H.energy.max() <= H.energy[0] * (1 + 1e-12) and H.energy[-1] < H.energy[0]


def test_paoli_schatzman_conserves_energy_without_contact():
    b = get_benchmark("bar2d")
    from signorini.contact.obstacles import PlaneObstacle

    p = b.problem(2)
    p.obstacle = PlaneObstacle([0.0, -50.0], [0.0, 1.0])
    H = simulate(p, "paoli-schatzman", b.h(2) / 2, 2.0, mass="standard")
    E = H.energy[2:]  # the half-step energy E^{n-1/2}, after the CN start-up step
    assert np.max(np.abs(E - E[0])) < 1e-12 * E[0] * H.steps


def test_restitution_range():
    b = get_benchmark("bar1d")
    with pytest.raises(InputError, match="restitution"):
        simulate(b.problem(4), "ps", 0.1, 1.0, scheme_options={"restitution": 1.5})

import json

import numpy as np
import pytest

from signorini.dynamics.stepping.simulate import simulate
from signorini.errors import InputError
from signorini.studies.benchmarks import get_benchmark
from signorini.studies.study import observed_rates


def _stress_errors(mass):
    b = get_benchmark("bar1d")
    ex = b.exact(b.params(), 3.0)
    errs, hs = [], []
    for n in (20, 40, 80, 160):
        H = simulate(b.problem(n), "ps", b.h(n) / 2, 3.0, mass=mass)
        # measured gap >= -3.5e-18 and residual 2.1e-16 (relative): bounds at the round-off floor
        assert H.gap.min() > -1e-14 and H.lam.max() <= 0 and H.residual.max() < 1e-14
        sig = ex.contact_stress(H.t[1:])
        errs.append(np.sqrt(np.sum((H.lam[1:, 0] - sig) ** 2) / np.sum(sig**2)))
        hs.append(b.h(n))
    return errs, observed_rates(errs, hs), H


def test_paoli_schatzman_converges_with_standard_mass():
    """The contact stress of bar1d (T = 3, dt = h/2, n = 20, 40, 80, 160) against the exact
    d'Alembert contact stress (ExactBar1D, docs/exact_solutions.md; no reference run), in
    the relative L2-in-time norm.  Rates are data, two-sided around the measured ones
    (0.30, 0.22, 0.29; mean 0.27), with a bound on the finest error (measured 0.154)."""
    errs, rates, H = _stress_errors("standard")
    assert np.all((0.15 <= np.asarray(rates)) & (np.asarray(rates) <= 0.4)), rates
    assert 0.2 <= np.mean(rates) <= 0.35, rates
    assert errs[-1] <= 0.17 and errs[-1] < 0.6 * errs[0], errs
    # dissipative at impacts with e = 0, but never gains energy: up to round-off over the
    # 960 steps (measured max E / E0 - 1 = 7.2e-13; bound 100x that), and 0.24% lost at the end
    assert H.energy.max() <= H.energy[0] * (1 + 7e-11) and H.energy[-1] < H.energy[0]


def test_paoli_schatzman_conserves_energy_without_contact():
    b = get_benchmark("bar2d")
    from signorini.contact.obstacles import PlaneObstacle

    p = b.problem(2)
    p.obstacle = PlaneObstacle([0.0, -50.0], [0.0, 1.0])
    H = simulate(p, "paoli-schatzman", b.h(2) / 2, 2.0, mass="standard")
    E = H.energy  # E^{n-1/2} from level 0 (virtual U^{-1}), across the CN start-up step
    assert abs(E[1] - E[0]) < 1e-13 * E[0]  # was a -0.77% jump with the Taylor U^{-1}
    assert np.max(np.abs(E - E[0])) < 1e-14 * E[0] * H.steps  # measured 2.6e-16 (bound 9.6e-15)
    # the discrete energy is the physical one up to O(dt^2 |A|^2 + dt^2 |V|_S^2) (docs/schemes.md)
    physical = simulate(p, "cn", b.h(2) / 2, b.h(2) / 2, mass="standard").energy[0]
    assert 1e-3 < (physical - E[0]) / physical < 5e-3


def test_paoli_schatzman_identity_at_the_start_up_step_with_contact_and_data_of_t():
    """Contact at step 1 (gap 0), e = 0.5, a moving clamp and a load of t: the CN
    starter's step satisfies the scheme's identity to round-off, like every later step."""
    b = get_benchmark("bar2d")
    p = b.problem(2, {"gap": 0.0})
    p.dirichlet = [
        type(p.dirichlet[0])("ymax", lambda x, t: np.column_stack([0 * x[:, 0], 0.2 - 0.4 * t + 0 * x[:, 0]]))
    ]
    p.body_force = lambda x, t: np.column_stack([0.1 * np.sin(3 * t) + 0 * x[:, 0], -2.0 * t + 0 * x[:, 1]])
    H = simulate(p, "ps", b.h(2) / 2, 1.0, mass="standard", scheme_options={"restitution": 0.5})
    assert H.lam[1].min() < 0  # the starter step is in contact
    assert np.isfinite(H.predicted_increment[1:]).all()
    err = np.abs(H.energy_increment - H.predicted_increment)[1:]
    assert err.max() <= 1e-13 * np.abs(H.energy).max()
    total = H.external_work + H.contact_work + H.numerical_dissipation
    assert np.allclose(H.energy - H.energy[0], total, rtol=0, atol=1e-13 * np.abs(H.energy).max())  # 4.8e-15 max|E|


def test_restitution_range():
    b = get_benchmark("bar1d")
    with pytest.raises(InputError, match="restitution"):
        simulate(b.problem(4), "ps", 0.1, 1.0, scheme_options={"restitution": 1.5})


def test_paoli_schatzman_fallbacks_are_counted_in_summary(tmp_path):
    """lcp_max_iter = 1 sends the contact solves that need two active-set iterations to
    the NNLS fallback: counted per step, in the counters and in summary.json; same history."""
    b = get_benchmark("bar2d")
    p, dt = b.problem(2), b.h(2) / 2
    H = simulate(p, "ps", dt, 1.2, mass="standard", solver_options={"lcp_max_iter": 1})
    ref = simulate(p, "ps", dt, 1.2, mass="standard")
    assert H.status == "finished" and H.fallbacks.sum() > 0 and ref.fallbacks.sum() == 0
    assert H.counters["fallbacks"] == H.fallbacks.sum() and H.counters["factorizations"] == 1
    assert np.abs(H.lam - ref.lam).max() <= 1e-12 * np.abs(ref.lam).max()
    H.save(tmp_path)
    s = json.loads((tmp_path / "summary.json").read_text())
    assert s["counters"]["fallbacks"] == s["fallbacks"] == int(H.fallbacks.sum())
    assert s["solver_options"]["lcp_max_iter"] == 1

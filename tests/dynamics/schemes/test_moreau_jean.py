"""Moreau-Jean: velocity-level impacts, dissipation for e = 0, O(dt) penetration."""

import numpy as np
import pytest

from signorini.dynamics.stepping.simulate import simulate
from signorini.studies.benchmarks import get_benchmark
from signorini.studies.study import observed_rates


def _run(n, mass="standard", T=3.0, **options):
    b = get_benchmark("bar1d-impact")
    dt = b.h(n) / 2
    return simulate(b.problem(n), "moreau-jean", dt, dt * round(T / dt), mass=mass, scheme_options=options)


@pytest.mark.parametrize(
    "mass, theta", [("standard", 0.5), ("standard", 0.75), ("standard", 1.0), ("seed", 0.75), ("seed", 1.0)]
)
def test_energy_never_increases_with_zero_restitution(mass, theta):
    H = _run(40, mass, theta=theta)
    assert H.status == "finished" and H.impacts >= 1
    assert np.diff(H.energy).max() <= 1e-13 * H.energy[0]
    assert H.energy[-1] < H.energy[0]
    ok = np.isfinite(H.predicted_increment)
    assert ok[1:].all()
    assert np.abs(H.energy_increment - H.predicted_increment)[ok].max() <= 2e-13 * H.energy[0]  # measured 2.9e-15


def test_velocity_level_complementarity_on_the_index_set():
    """Where an impulse acts, nu.V^{n+1} + e nu.V^n = 0; elsewhere no impulse (e = 0 and 0.5)."""
    from signorini.dynamics.observe.observers import Observer

    class Velocities(Observer):
        def start(self, run):
            self.rows = [(run.ctx.rows.B @ run.initial.V, np.zeros(run.ctx.rows.B.shape[0]))]

        def record(self, run, n, state):
            self.rows.append((run.ctx.rows.B @ state.V, state.extra["impulse"]))

    b = get_benchmark("bar1d-impact")
    for e in (0.0, 0.5):
        obs = Velocities()
        simulate(b.problem(40), "moreau-jean", b.h(40) / 2, 3.0, mass="standard",
                 scheme_options={"restitution": e}, observers=[obs])  # fmt: skip
        acted = 0
        for (bv0, _), (bv1, P) in zip(obs.rows[:-1], obs.rows[1:], strict=True):
            w = bv1 + e * bv0
            assert P.max() <= 0.0
            assert np.abs(w[P < 0]).max(initial=0.0) <= 1e-14  # complementarity: P < 0 => w = 0; measured 1.4e-16
            acted += int((P < 0).any())
        assert acted >= 1


def test_penetration_is_first_order_in_dt():
    pens, hs = [], []
    for n in (20, 40, 80, 160):
        H = _run(n, T=1.0)
        pens.append(H.summary()["penetration_max"])
        hs.append(get_benchmark("bar1d-impact").h(n))
    rates = np.asarray(observed_rates(pens, hs))
    assert np.all((0.8 < rates) & (rates < 1.2)), rates  # O(dt) (dt = h/2), spec 6.4
    assert pens[-1] < 2e-3


@pytest.mark.parametrize("scheme", ["moreau-jean", "penalty"])
def test_cg_backend_is_refused_before_the_run(scheme):
    from signorini.errors import InputError

    b = get_benchmark("bar1d-impact")
    with pytest.raises(InputError, match="direct backend"):
        simulate(b.problem(20), scheme, b.h(20) / 2, 1.0, mass="standard", solver_options={"backend": "cg"})


def test_half_theta_with_massless_dofs_is_refused_and_theta_one_converges():
    """theta = 1/2 leaves an undamped (-1)^n mode on massless rows (docs/schemes.md)."""
    from exact_bar import exact_bar_runs
    from signorini.errors import InputError

    with pytest.raises(InputError, match="theta > 1/2"):
        _run(20, "seed")
    errs = [err["u_H1"] for *_, err in exact_bar_runs("moreau-jean", "seed", (40, 160), {"theta": 1.0})]
    assert errs[1] < 0.8 * errs[0] and errs[1] < 0.3  # measured 0.356 -> 0.246


@pytest.mark.parametrize("name", ["bar1d-impact", "bar2d"])
@pytest.mark.parametrize("mass", ["standard", "lumped"])
def test_energy_conserving_scheme_conserves_energy_through_impacts(name, mass):
    b = get_benchmark(name)
    n = 40 if b.dim == 1 else 2
    dt = b.h(n) / 2
    H = simulate(b.problem(n), "energy-conserving", dt, dt * round(3.0 / dt), mass=mass)
    assert H.status == "finished" and H.impacts >= 1 and H.lam.min() < 0
    assert np.abs(H.energy - H.energy[0]).max() <= 1e-12 * H.energy[0]
    assert H.meta["scheme"] == "energy-conserving" and H.counters["factorizations"] == 1


def test_energy_conserving_persistency():
    """Where an impulse acts, the step's normal increment vanishes: nu.(V^n + V^{n+1}) = 0."""
    from signorini.dynamics.observe.observers import Observer

    class Rates(Observer):
        def start(self, run):
            self.prev, self.bad, self.acted = run.ctx.rows.B @ run.initial.V, 0.0, 0

        def record(self, run, n, state):
            bv = run.ctx.rows.B @ state.V
            P = state.extra["impulse"]
            if (P < 0).any():
                self.acted += 1
                self.bad = max(self.bad, float(np.abs((bv + self.prev)[P < 0]).max()))
            self.prev = bv

    b = get_benchmark("bar1d-impact")
    obs = Rates()
    simulate(b.problem(40), "energy-conserving", b.h(40) / 2, 3.0, mass="standard", observers=[obs])
    assert obs.acted >= 1 and obs.bad <= 2e-14  # measured 2.2e-16

"""Moreau-Jean: velocity-level impacts, dissipation for e = 0, O(dt) penetration."""

import numpy as np
import pytest

from signorini.dynamics.simulate import simulate
from signorini.studies.benchmarks import get_benchmark
from signorini.studies.study import observed_rates


def _run(n, mass="seed", T=3.0, **options):
    b = get_benchmark("bar1d-impact")
    dt = b.h(n) / 2
    return simulate(b.problem(n), "moreau-jean", dt, dt * round(T / dt), mass=mass, scheme_options=options)


@pytest.mark.parametrize("mass", ["standard", "seed"])
@pytest.mark.parametrize("theta", [0.5, 0.75, 1.0])
def test_energy_never_increases_with_zero_restitution(mass, theta):
    H = _run(40, mass, theta=theta)
    assert H.status == "finished" and H.impacts >= 1
    assert np.diff(H.energy).max() <= 1e-13 * H.energy[0]
    assert H.energy[-1] < H.energy[0]
    ok = np.isfinite(H.predicted_increment)
    assert ok[1:].all()
    assert np.abs(H.energy_increment - H.predicted_increment)[ok].max() <= 1e-12 * H.energy[0]


def test_velocity_level_complementarity_on_the_index_set():
    """Where an impulse acts, nu.V^{n+1} + e nu.V^n = 0; elsewhere no impulse (e = 0 and 0.5)."""
    from signorini.dynamics.observers import Observer

    class Velocities(Observer):
        def start(self, run):
            self.rows = [(run.ctx.B @ run.initial.V, np.zeros(run.ctx.B.shape[0]))]

        def record(self, run, n, state):
            self.rows.append((run.ctx.B @ state.V, state.extra["impulse"]))

    b = get_benchmark("bar1d-impact")
    for e in (0.0, 0.5):
        obs = Velocities()
        simulate(b.problem(40), "moreau-jean", b.h(40) / 2, 3.0, scheme_options={"restitution": e}, observers=[obs])
        acted = 0
        for (bv0, _), (bv1, P) in zip(obs.rows[:-1], obs.rows[1:], strict=True):
            w = bv1 + e * bv0
            assert P.max() <= 0.0
            assert np.abs(w[P < 0]).max(initial=0.0) <= 1e-10  # complementarity: P < 0 => w = 0
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


def test_cg_backend_is_refused_clearly():
    b = get_benchmark("bar1d-impact")
    H = simulate(b.problem(20), "moreau-jean", b.h(20) / 2, 1.0, solver_options={"backend": "cg"})
    assert H.status == "failed" and "direct backend" in H.message

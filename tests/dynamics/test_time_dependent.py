"""Time-dependent data: a moving clamp, a moving obstacle, loads switched on.

Reference: the exact d'Alembert solutions of docs/exact_solutions.md (exact, so the
observed rates measure the discretization only).  Rates are data, checked two-sided,
with a bound on the finest error.
"""

import dataclasses

import numpy as np
import pytest

from distinct_schemes import DISTINCT_SCHEMES
from signorini.contact.obstacles import PlaneObstacle, SphereObstacle
from signorini.dynamics.schemes import SCHEMES
from signorini.dynamics.stepping.simulate import simulate
from signorini.studies.benchmarks import get_benchmark
from signorini.studies.study import errors_1d, observed_rates

LEVELS = (20, 40, 80, 160)
MOVING_CLAMP = {"velocity": 0.0, "gap": 0.2, "clamp_velocity": -0.5}
PUSHING_OBSTACLE = {"velocity": 0.0, "gap": 0.0, "obstacle_velocity": 0.3}

# (scenario, expected mean rate range per error, bound on the finest-level error)
CASES = {
    "moving-clamp": (MOVING_CLAMP, {"u_H1": (0.3, 0.6, 0.12), "u_L2": (0.85, 1.15, 0.007),
                                    "stress": (0.3, 0.6, 0.1), "energy_L2": (0.85, 1.15, 0.0025)}),
    "pushing-obstacle": (PUSHING_OBSTACLE, {"u_H1": (0.25, 0.5, 0.05), "u_L2": (0.9, 1.3, 0.001),
                                            "stress": (0.25, 0.5, 0.055), "energy_L2": (0.85, 1.15, 0.0016)}),
}  # fmt: skip


def assert_identity(H, scale):
    assert np.isfinite(H.predicted_increment[1:]).all()  # every step, the start-up step too
    assert np.abs(H.energy_increment - H.predicted_increment)[1:].max() <= 1e-11 * scale


@pytest.mark.parametrize("case", list(CASES))
def test_cn_seed_converges_to_the_exact_solution(case):
    params, expected = CASES[case]
    b = get_benchmark("bar1d-impact")
    rows, hs = [], []
    for n in LEVELS:
        p = b.problem(n, params)
        H = simulate(p, "cn", b.h(n) / 2, 3.0, mass="seed", snapshot_every=1)
        # measured gap >= -6.9e-18, residual (relative) 1.2e-16: bounds at the round-off floor
        assert H.gap.min() >= -1e-14 and H.lam.max() <= 0.0 and H.residual.max() <= 1e-14
        assert_identity(H, np.abs(H.energy).max())
        rows.append(errors_1d(H, p, b.exact(b.params(params), 3.0)))
        hs.append(b.h(n))
    for k, (lo, hi, finest) in expected.items():
        rates = observed_rates([r[k] for r in rows], hs)
        assert lo < np.mean(rates) < hi, (k, rates)
        assert rows[-1][k] < finest, (k, rows[-1][k])


def test_pushing_obstacle_stress_matches_closed_form():
    """Contact stress -E w / c on [0, 2L/c), -3 E w / c on [2L/c, 4L/c) (docs/exact_solutions.md)."""
    b = get_benchmark("bar1d-impact")
    H = simulate(b.problem(160, PUSHING_OBSTACLE), "cn", b.h(160) / 2, 3.0, mass="seed")
    lam = H.lam[:, 0]
    w = 0.3
    assert np.abs(lam[(H.t > 0.2) & (H.t < 1.8)] + w).max() < 0.05 * w
    assert np.abs(lam[(H.t > 2.2) & (H.t < 2.9)] + 3 * w).max() < 0.05 * w
    assert H.active[1:].min() == 1  # never released
    assert H.external_work[-1] == 0.0 and H.contact_work[-1] > 0.4  # the obstacle does the work


@pytest.mark.parametrize("scheme", DISTINCT_SCHEMES)
def test_energy_identity_with_external_work_every_scheme(scheme):
    """Moving clamp + time-dependent body force and traction: each scheme's identity."""
    b = get_benchmark("bar2d")
    p = b.problem(2, {"velocity": 0.0})
    dt = b.h(2) / 2
    p.dirichlet = [
        type(p.dirichlet[0])("ymax", lambda x, t: np.column_stack([0 * x[:, 0], 0.2 - 0.4 * t + 0 * x[:, 0]]))
    ]
    p.body_force = lambda x, t: np.column_stack(
        [0.1 * np.sin(3 * t) + 0 * x[:, 0], -2.0 * min(t / 0.2, 1.0) + 0 * x[:, 1]]
    )
    p.tractions = {"xmax": lambda x, t: np.column_stack([0.5 * t * x[:, 1], 0 * x[:, 1]])}
    mass = "seed" if SCHEMES.get(scheme).obj.massless_dofs_allowed else "standard"
    H = simulate(p, scheme, dt, 1.5, mass=mass)
    assert H.status == "finished" and H.lam.min() < 0  # contact happened
    assert_identity(H, np.abs(H.energy).max())
    assert abs(H.external_work[-1]) > 1e-3  # loads and the clamp did work


def test_moving_sphere_and_gravity_switched_on():
    """A disc (2D) pushed up by a ball that moves: identity and admissibility."""
    b = get_benchmark("bar2d")
    p = b.problem(2, {"velocity": 0.0, "gap": 0.0})
    p.dirichlet = []
    p.u0, p.v0 = 0.0, 0.0
    p.obstacle = SphereObstacle(lambda t: [0.05, -1.01 + 0.1 * t], 1.0)
    p.body_force = lambda x, t: np.column_stack([0 * x[:, 0], -0.5 * min(t, 1.0) + 0 * x[:, 1]])
    H = simulate(p, "cn", b.h(2) / 2, 0.5, mass="seed")
    assert H.status == "finished" and H.lam.min() < 0
    assert H.gap.min() >= -1e-14  # measured -1.4e-17
    assert_identity(H, np.abs(H.energy).max() + 1e-3)


def test_static_plane_given_as_function_of_time_matches_constant():
    b = get_benchmark("bar2d")
    p = b.problem(2)
    H1 = simulate(p, "cn", b.h(2) / 2, 1.0)
    p.obstacle = PlaneObstacle(lambda t: [0.0, 0.0], [0.0, 1.0])
    H2 = simulate(p, "cn", b.h(2) / 2, 1.0)
    assert np.array_equal(H1.lam, H2.lam)


@pytest.mark.parametrize("scheme", DISTINCT_SCHEMES)
def test_free_fall_has_no_elastic_energy(scheme):
    """A free disc-shaped block falling under gravity towards a plane far below (no contact
    in the run): every mass variant's M g makes it fall without stress, so ``elastic_energy``
    (1/2 U.SU) stays at round-off while ``load_potential`` (-U.F) is -m g dy, and ``energy``
    is still their sum with the kinetic energy, its identity closed to round-off."""
    b = get_benchmark("bar2d")
    p = b.problem(2, {"velocity": 0.0, "gap": 0.0})
    p.dirichlet = []
    p.u0, p.v0 = 0.0, 0.0
    p.obstacle = PlaneObstacle([0.0, -100.0], [0.0, 1.0])
    p.body_force = [0.0, -9.81]
    mass = "seed" if SCHEMES.get(scheme).obj.massless_dofs_allowed else "standard"
    H = simulate(p, scheme, b.h(2) / 2, 0.5, mass=mass)
    assert H.status == "finished" and H.active.max() == 0
    E_load = np.abs(H.load_potential).max()
    assert E_load > 1e-3 and np.all(H.load_potential[1:] < 0)  # the block falls: -U.F = -m g dy < 0
    assert np.abs(H.elastic_energy).max() <= 1e-12 * E_load
    assert np.allclose(H.energy, H.kinetic_energy + H.elastic_energy + H.load_potential, rtol=0, atol=1e-14 * E_load)
    assert_identity(H, E_load)


def _falling_block(**conventions):
    b = get_benchmark("bar2d")
    p = b.problem(2, {"velocity": 0.0, "gap": 0.0})
    p.dirichlet = []
    p.u0, p.v0 = 0.0, 0.0
    p.obstacle = PlaneObstacle([0.0, -0.05], [0.0, 1.0])
    p.body_force = [0.0, -9.81]
    return dataclasses.replace(p, **conventions), b.h(2) / 2


@pytest.mark.parametrize("mass", ["standard", "seed", "moment-preserving"])
def test_follow_mass_false_applies_the_consistent_load_whatever_the_mass(mass):
    """``follow_mass=False`` is GetFEM's rho int g phi: with the standard mass it is the same
    load as M g (1^T phi_j = 1), so the runs are identical; with a redistributed mass the
    loads differ (M_used g moves weight off the contact nodes) and so do the runs."""
    from signorini.dynamics.model.problem import discretize
    from signorini.fem.assembly import body_load

    p, _ = _falling_block(follow_mass=False)
    d = discretize(p, mass)
    assert np.allclose(d.load(0.0), body_load(p.mesh, [0.0, -9.81]), rtol=0, atol=1e-15)
    d_follow = discretize(dataclasses.replace(p, follow_mass=True), mass)
    if mass == "standard":
        assert np.allclose(d.load(0.0), d_follow.load(0.0), rtol=0, atol=1e-15)
    else:
        assert np.abs(d.load(0.0) - d_follow.load(0.0)).max() > 1e-3 * np.abs(d.load(0.0)).max()


@pytest.mark.parametrize("scheme", ["cn", "be", "generalized-alpha"])
def test_zero_initial_acceleration_keeps_the_energy_identity(scheme):
    """``initial_acceleration='zero'`` (GetFEM's Newmark start) leaves a level-0 imbalance
    F - S U0 that works in the first step: the identity closes to round-off with it, A0 is
    zero, and CN's history differs from the equilibrium start (it is another scheme start);
    backward Euler and generalized-alpha do not use A0 (the latter starts with its own
    step), so theirs do not."""
    p, dt = _falling_block(initial_acceleration="zero")
    H = simulate(p, scheme, dt, 0.5, mass="standard", snapshot_every=1)
    assert H.status == "finished" and H.lam.min() < 0 and H.meta["conventions"]["initial_acceleration"] == "zero"
    assert_identity(H, np.abs(H.energy).max())
    H_eq = simulate(dataclasses.replace(p, initial_acceleration="equilibrium"), scheme, dt, 0.5, mass="standard",
                    snapshot_every=1)  # fmt: skip
    change = np.abs(H.snapshots["u"][1] - H_eq.snapshots["u"][1]).max()
    assert change > 1e-6 if scheme == "cn" else change == 0.0

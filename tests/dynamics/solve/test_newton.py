"""The finite-strain step's Newton (``dynamics/solve/newton.py``): the increment as the unknown, the tangent's
correction per cell, the line search on the step's potential (issue 51)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import signorini.dynamics.solve.newton as newton
from signorini.contact.obstacles import PlaneObstacle
from signorini.dynamics.model.problem import Problem
from signorini.dynamics.schemes import finite_strain_schemes, make_scheme
from signorini.dynamics.stepping.simulate import simulate
from signorini.fem.hyperelastic import project_psd
from signorini.fem.material import NeoHookean
from signorini.fem.mesh import box, read_mesh

CYLINDER = Path(__file__).resolve().parents[3] / "examples" / "meshes" / "cylinder.msh"


def far_cylinder() -> Problem:
    """The examples' gmsh cylinder (365 nodes, 274 on its tagged skin: 822 of 1,095 dofs massless with the
    default mass), rubber, spinning at 20 rad/s and falling at 1 m/s, 1 m from its reference place."""
    m = read_mesh(CYLINDER)
    c, w = m.points.mean(axis=0), np.array([0.0, 0.0, 20.0])
    return Problem(m, NeoHookean.from_young(5e6, 0.45, 1100.0), "skin", PlaneObstacle([0, 0, -0.02], [0.2, 0, 1.0]),
                   v0=lambda x: np.cross(w, x - c) + [0.0, 0.0, -1.0], u0=np.array([1.0, 0.0, 0.0]))  # fmt: skip


@pytest.mark.parametrize("dt", [1e-5, 1e-7])
def test_a_part_far_from_its_place_converges_at_small_steps(dt):
    """The increment is Newton's unknown: a part 1 m from its reference place, most of its nodes massless, at
    steps of 1e-5 and 1e-7 s (the steps the energy control takes to locate an event).  With U itself as the
    unknown, c_M M times one ulp of |U| (1e-16 m) was above newton_tol: both failed at step 1 with a residual
    of the size of its scale (measured before the change); now 1-5 iterations per step."""
    H = simulate(far_cylinder(), "crank-nicolson", dt, 5 * dt)
    assert H.status == "finished", H.summary().get("message")
    assert H.nonlinear_iterations[1:].max() <= 6


def test_project_psd_clamps_the_negative_eigenvalues_of_each_cell_only():
    """Each cell's (nv d)-square tangent: an indefinite one becomes its PSD part V max(L, 0) V^T (the nearest PSD
    matrix), a PSD one is left bit for bit."""
    rng = np.random.default_rng(3)
    e, d, nv = 5, 3, 4
    A = rng.standard_normal((e, nv * d, nv * d))
    A = A @ np.swapaxes(A, 1, 2)  # PSD
    A[1] -= 2.0 * np.eye(nv * d) * np.linalg.eigvalsh(A[1])[2]  # indefinite: three eigenvalues below 0
    A[3] = -A[3]  # negative definite
    K = A.reshape(e, nv, d, nv, d).transpose(0, 2, 4, 1, 3).copy()
    before = K.copy()
    assert project_psd(K) == 2
    B = K.transpose(0, 3, 1, 4, 2).reshape(e, nv * d, nv * d)
    for c in range(e):
        w = np.linalg.eigvalsh(B[c])
        assert w.min() >= -1e-12 * np.abs(w).max()
        if c in (1, 3):
            w0, V0 = np.linalg.eigh(A[c])
            assert np.allclose(B[c], (V0 * np.maximum(w0, 0.0)) @ V0.T, rtol=0.0, atol=1e-12 * np.abs(w0).max())
        else:
            assert np.array_equal(K[c], before[c])
    assert np.abs(B[3]).max() <= 1e-12 * np.abs(A[3]).max()


def spinning_block(E: float = 1e3) -> Problem:
    """A soft Neo-Hookean block 1 x 0.5 x 0.5 spinning at 5 rad/s about a skew axis, far above its floor."""
    mesh, c = box(2, 2, 2, 1.0, 0.5, 0.5), np.array([0.5, 0.25, 0.25])
    w = 5.0 * np.array([1.0, 2.0, 3.0]) / np.sqrt(14.0)
    return Problem(mesh, NeoHookean.from_young(E, 0.3, 1.0), "zmin", PlaneObstacle([0, 0, -50.0], [0, 0, 1.0]),
                   v0=lambda x: np.cross(w, x - c) + [0.3, 0.0, 0.0])  # fmt: skip


def test_the_line_search_on_the_potential_carries_a_step_of_a_third_of_a_turn(monkeypatch):
    """Backward Euler, dt = 0.4 (2 rad per step), the full tangent: the full Newton steps raise the step's
    potential and |r| alike; backtracking on Pi (Armijo, non-monotone over 4 iterates) converges, while full
    steps only (the search removed) do not in 25 iterations (measured: residual 1e-2 of its scale)."""

    def run():
        return simulate(spinning_block(), "backward-euler", 0.4, 0.8, mass="standard",
                        solver_options={"tangent": "full"})  # fmt: skip

    H = run()
    assert H.status == "finished", H.summary().get("message")
    assert H.counters["line_search_backtracks"] > 0
    assert H.counters["line_search_backtracks"] == H.counters["line_search_steps"]
    monkeypatch.setattr(newton, "_armijo", lambda phi, elastic, a=1.0, allowance=0.0, agree=None: a)
    assert run().status == "failed"


def test_an_indefinite_tangent_is_corrected_where_the_factorization_fails(monkeypatch):
    """A tangent that a Cholesky factorization refuses (here: every plain tangent, made indefinite by hand) is
    replaced by the per-cell PSD one, counted in ``tangent_corrections``; without the correction the step
    fails naming the tangent that cannot be factorized."""
    from signorini.dynamics.solve.elasticity import FiniteStrain

    pytest.importorskip("cvxopt", reason="the cholmod backend (a Cholesky factorization) needs cvxopt")
    original = FiniteStrain.tangent

    def indefinite(self, U, project=False):
        K = original(self, U, project)
        return K if project else K - 10.0 * abs(K).max() * _identity(K.shape[0])

    monkeypatch.setattr(FiniteStrain, "tangent", indefinite)
    options = {"tangent": "full", "backend": "cholmod"}
    H = simulate(spinning_block(), "backward-euler", 0.05, 0.2, mass="standard", solver_options=options)
    assert H.status == "finished", H.summary().get("message")
    assert H.counters["tangent_corrections"] >= H.steps
    monkeypatch.setattr(newton._Factor, "correct", _refuse)
    H = simulate(spinning_block(), "backward-euler", 0.05, 0.2, mass="standard", solver_options=options)
    assert H.status == "failed" and "cannot be factorized" in H.summary()["message"]


def _identity(n: int):
    import scipy.sparse as sp

    return sp.identity(n, format="csr")


def _refuse(self, k, why, U, lam):
    from signorini.errors import ConvergenceError

    raise ConvergenceError(f"the tangent of Newton iterate {k} {why}")


def _bar3d_neo_hookean(T: float) -> tuple:
    """The paper's 3D bar (``bar3d``, n = 4, its default step 1/80) with Neo-Hookean: compressed against the
    obstacle at a strain of about 0.45, its contact face massless (the default mass)."""
    import dataclasses

    from signorini.studies.benchmarks import get_benchmark

    b = get_benchmark("bar3d")
    p = b.params()
    problem = dataclasses.replace(b.build(4, p), material=NeoHookean(p["lam"], p["mu"], p["rho"]))
    dt, _ = b.run_times(4, p)
    return problem, dt, T


def test_an_indefinite_tangent_at_the_solution_converges_with_the_active_set_held(monkeypatch):
    """At the bar's contact the step's Hessian is indefinite at its solution (the geometric stiffness of the
    compressed cells under a face without inertia): the plain tangent cannot be condensed and the corrected one
    converges at a rate of 0.55 (step 35: no convergence in 25 iterations, measured by removing the direction of
    the plain tangent with the active set held, below).  With it, Crank-Nicolson goes through the contact, each
    such step in at most 15 iterations, and the step's energy identity closes to round-off."""
    problem, dt, T = _bar3d_neo_hookean(0.45)
    H = simulate(problem, "crank-nicolson", dt, T)
    assert H.status == "finished", H.summary().get("message")
    assert H.counters["kkt_directions"] > 0 and H.counters["tangent_corrections"] > 0
    assert H.nonlinear_iterations[30:].max() <= 15
    assert H.summary()["energy_identity_residual"] <= 1e-9
    monkeypatch.setattr(newton, "_kkt_ok", lambda *a: False)
    H = simulate(problem, "crank-nicolson", dt, T)
    assert H.status == "failed" and "did not converge in 25 iterations" in H.summary()["message"]


@pytest.mark.slow
def test_energy_momentum_goes_through_the_bars_contact_with_the_exact_jacobian(monkeypatch):
    """``bar3d`` n = 4 with Neo-Hookean and energy-momentum through its contact (before: no convergence at step 35,
    rate 0.48: 1/2 K(U_mid) is not the Jacobian of the discrete gradient, and in contact its error dominates).
    With the exact Jacobian's directions (taken once a fresh tangent contracts slowly or needs a correction), the
    active set held, every step in at most 15 iterations (measured 13), the energy identity to round-off; without
    them step 35 fails again."""
    problem, dt, T = _bar3d_neo_hookean(0.45)
    H = simulate(problem, "energy-momentum", dt, T)
    assert H.status == "finished", H.summary().get("message")
    assert H.counters["exact_directions"] > 0 and H.nonlinear_iterations.max() <= 15
    assert H.summary()["energy_identity_residual"] <= 1e-9 and -H.gap.min() <= 1e-10
    monkeypatch.setattr(newton._Factor, "exact", lambda self, *a: None)
    H = simulate(problem, "energy-momentum", dt, T)
    assert H.status == "failed" and "did not converge in 25 iterations" in H.summary()["message"]


def test_energy_momentum_takes_spin3d_at_twice_its_step_with_the_exact_jacobian(monkeypatch):
    """``spin3d`` (a Neo-Hookean ball spinning at 0.3 of its wave speed, the default mass) with energy-momentum
    at twice its default step (0.4 rad a step): the symmetric tangent 1/2 K(U_mid) converges at 0.46 per
    iteration and step 1 failed after 25 iterations (shown below without the exact directions); with the exact
    Jacobian of the discrete gradient every step converges in at most 8 iterations, its identity closed."""
    from signorini.studies.benchmarks import get_benchmark

    b = get_benchmark("spin3d")
    p = b.params({"revolutions": 0.5})
    problem, (dt, T) = b.build(1, p), b.run_times(1, {"revolutions": 0.5})
    H = simulate(problem, "energy-momentum", 2 * dt, 2 * dt * np.floor(T / (2 * dt)))
    assert H.status == "finished", H.summary().get("message")
    assert H.counters["exact_directions"] > 0 and H.nonlinear_iterations[1:].max() <= 8
    assert H.summary()["energy_identity_residual"] <= 1e-9
    monkeypatch.setattr(newton._Factor, "exact", lambda self, *a: None)
    # without the exact directions Anderson's mixing of the symmetric tangent's iterates (the default) takes 21-23
    # iterations a step (measured); without both, step 1 fails
    H = simulate(problem, "energy-momentum", 2 * dt, 4 * dt, solver_options={"acceleration": "none"})
    assert H.status == "failed" and "did not converge in 25 iterations" in H.summary()["message"]


def landing_cylinder() -> Problem:
    """The examples' gmsh cylinder (822 of 1,095 dofs massless with the default mass), rubber, spinning at 20 rad/s
    and falling at 1 m/s onto a plane tilted by 11 degrees, about 2 ms above it."""
    m = read_mesh(CYLINDER)
    c, w = m.points.mean(axis=0), np.array([0.0, 0.0, 20.0])
    plane = PlaneObstacle([0, 0, m.points[:, 2].min() - 0.012], [0.2, 0, 1.0])
    return Problem(m, NeoHookean.from_young(5e6, 0.45, 1100.0), "skin", plane,
                   v0=lambda x: np.cross(w, x - c) + [0.0, 0.0, -1.0])  # fmt: skip


@pytest.mark.parametrize("scheme", finite_strain_schemes())
@pytest.mark.parametrize("tolerance", [None, 1e-6])
def test_the_energy_control_locates_the_first_contact_of_a_part_with_every_scheme(scheme, tolerance):
    """Issue 51: under the energy control the steps halved to locate ``stop_at = "first-contact"`` (and to meet a
    tolerance of 1e-6) stalled Newton on a part whose nodes are mostly on its skin, although the same steps taken
    fixed converged.  Every finite-strain scheme now stops at the event, at the same time to 1e-9 s."""
    control = {"control": "energy"} if tolerance is None else {"control": "energy", "tolerance": tolerance}
    H = simulate(landing_cylinder(), scheme, 2e-4, 4e-3, control=control, events=["first-contact"])
    assert H.status == "finished" and "first-contact" in H.message, H.message
    assert abs(H.t[-1] - 0.00205918) <= 5e-7  # the schemes' crossings differ by their steps' resolution
    if make_scheme(scheme).exact_contact:  # (penalty's compliance lets a node in by design)
        assert H.summary()["penetration_max"] <= 1e-12


@pytest.mark.slow
@pytest.mark.parametrize("scheme", ["crank-nicolson", "energy-momentum"])
def test_the_energy_control_at_a_tight_tolerance_goes_through_the_impact(scheme):
    """The same part through its impact at tolerance 1e-6: the control halves the step five times (to 6.25e-6 s) and
    every halved step converges (320-330 levels, about 5 iterations a step)."""
    H = simulate(landing_cylinder(), scheme, 2e-4, 8e-3, control={"control": "energy", "tolerance": 1e-6})
    assert H.status == "finished", H.message
    assert H.summary()["time_control"]["dt_smallest_used"] <= 2e-4 / 16
    assert np.abs(H.columns()["lambda_sum"]).max() > 0 and H.summary()["penetration_max"] <= 1e-12


def test_a_contact_problem_without_solution_corrects_the_tangent(monkeypatch):
    """bar3d n = 2, Neo-Hookean, the standard mass, Crank-Nicolson, through its impact (40 steps): at step 31 a
    plain tangent's contact problem has no solution its solver finds (an indefinite Delassus operator: residual 0.35);
    its direction left the rows violated by 3e-2 and Newton stalled there.  The tangent is corrected and the step
    converges; the contact forces equal the full-tangent run's (another path to the same answer) to 1e-7 of their
    largest, no node through the plane.  Without the correction (MAX_CONTACT_RESIDUAL infinite: its condition never
    true) the run fails.  SuperLU: it factorizes the indefinite tangent (a Cholesky backend, which auto takes for
    finite strain in 3D, refuses it and the tangent is corrected at its factorization)."""
    import dataclasses

    from signorini.fem.material import with_model
    from signorini.studies.benchmarks import get_benchmark

    b = get_benchmark("bar3d")
    dt = b.run_times(2)[0]
    p = b.problem(2)
    p = dataclasses.replace(p, material=with_model(p.material, "neo-hookean"))
    H = simulate(p, "crank-nicolson", dt, 40 * dt, mass="standard", backend="superlu")
    full = simulate(
        p, "crank-nicolson", dt, 40 * dt, mass="standard", solver_options={"tangent": "full"}, backend="superlu"
    )
    assert H.counters["tangent_corrections"] > 0 and H.lam.min() < 0 and H.gap.min() >= -1e-10
    assert np.abs(H.lambda_sum - full.lambda_sum).max() <= 1e-7 * np.abs(full.lambda_sum).max()
    assert H.status == "finished"
    monkeypatch.setattr(newton, "MAX_CONTACT_RESIDUAL", np.inf)
    bad = simulate(p, "crank-nicolson", dt, 40 * dt, mass="standard", backend="superlu")
    assert bad.status == "failed" and "did not converge" in bad.message

"""Contact rows in the current configuration: the consistent linearization of Newton's contact force
(``dynamics/rows/current_rows.py``, ``dynamics/solve/newton.py``).

The force of the multipliers through the rows of an iterate U is B(U)^T lambda; its derivative at fixed
lambda is sum_i lambda_i d^2 g_i / dU^2 (the facet's normal and the projection turn with the nodes; a
sphere's normal turns under a node that moves), which rows frozen at an iterate leave out.  Newton's
residual takes the force through the rows of each iterate itself, and its tangent that derivative: a
spinning block landing on another converges quadratically (before: linearly, and it failed)."""

import numpy as np
import pytest

import signorini.dynamics.solve.newton as newton
from signorini.contact.obstacles import SphereObstacle
from signorini.contact.pairs import ContactPair
from signorini.dynamics.model.problem import Problem, RegionInitial
from signorini.dynamics.rows.current_rows import CurrentPairRows, CurrentRows
from signorini.dynamics.stepping.simulate import simulate
from signorini.dynamics.stepping.stepper import Stepper
from signorini.fem.material import NeoHookean
from signorini.fem.mesh import join, rectangle


def spinning_landing(omega: float = 30.0) -> Problem:
    """A Neo-Hookean block 0.2 x 0.1 m (4 x 2 quads) spinning at ``omega`` rad/s, thrown at (0.5, -1) m/s onto
    another 0.6 x 0.1 m (12 x 2 quads) 2 mm below it (a contact pair; both free)."""
    upper, lower = rectangle(4, 2, 0.2, 0.1), rectangle(12, 2, 0.6, 0.1)
    upper.points = upper.points + [0.05, 0.102]
    center = np.array([0.15, 0.152])

    def spin(x):
        r = x - center
        return np.stack([0.5 - omega * r[:, 1], omega * r[:, 0] - 1.0], axis=1)

    return Problem(join({"upper": upper, "lower": lower}), NeoHookean.from_young(1e5, 0.3, 1000.0), None, None,
                   pairs=[ContactPair("upper_ymin", "lower_ymax")],
                   initial_regions=[RegionInitial("upper", velocity=spin)])  # fmt: skip


def block_on_ball() -> Problem:
    """A Neo-Hookean block 0.1 x 0.05 m (4 x 2 quads) thrown spinning (20 rad/s) onto a ball of radius 0.1 m."""
    m = rectangle(4, 2, 0.1, 0.05)
    m.points = m.points + [-0.05, 0.101]
    center = np.array([0.0, 0.126])

    def spin(x):
        r = x - center
        return np.stack([0.3 - 20.0 * r[:, 1], 20.0 * r[:, 0] - 1.0], axis=1)

    return Problem(m, NeoHookean.from_young(1e5, 0.3, 1000.0), "ymin", SphereObstacle([0.0, 0.0], 0.1), v0=spin)


def _pressed(problem: Problem, dt: float, steps: int) -> tuple[Stepper, np.ndarray, np.ndarray]:
    s = Stepper(problem, "crank-nicolson", (dt, steps * dt), {"solver_options": {"tangent": "full"}})
    while s.status == "running":
        s.step()
    assert s.state.lam.min() < 0, "no contact at the level tested"
    return s, s.state.U.copy(), s.state.lam.copy()


@pytest.mark.parametrize("case", ["pair", "sphere"])
def test_the_geometric_stiffness_is_the_derivative_of_the_contact_force(case):
    """d/dU [B(U)^T lambda] v (central differences of the force through the rows of U +- eps v) equals
    -K_c v, K_c = sum_i lambda_i d^2 g_i / dU^2 (the rows are -grad g), to 1e-6 of its size, in random
    directions; K_c is symmetric."""
    if case == "pair":
        s, U, lam = _pressed(spinning_landing(), 2e-4, 40)
        rows = s.run.ctx.rows.current
        assert isinstance(rows, CurrentPairRows)
    else:
        s, U, lam = _pressed(block_on_ball(), 2e-4, 20)
        rows = s.run.ctx.rows.current
        assert isinstance(rows, CurrentRows)
    t = s.t
    K = rows.geometric_stiffness(U, t, lam)
    assert K is not None and abs(K - K.T).max() <= 1e-12 * abs(K).max()
    rng = np.random.default_rng(1)
    size = float(np.abs(U).max())
    for _ in range(3):
        v = rng.standard_normal(U.size)
        eps = 1e-6 * size / np.abs(v).max()
        dF = (rows.contact_force(U + eps * v, t, lam) - rows.contact_force(U - eps * v, t, lam)) / (2 * eps)
        Kv = -(K @ v)  # Newton's residual is ... - B(U)^T lambda: its derivative ... + K_c
        assert np.abs(dF - Kv).max() <= 1e-6 * np.abs(Kv).max(), np.abs(dF - Kv).max() / np.abs(Kv).max()
    s.finish()


def _newton_residuals(problem: Problem, dt: float, steps: int, drop_geometric: bool, monkeypatch) -> list[list[float]]:
    """The residual sequences (|r| / scale, full steps only) of each step's Newton iterations."""
    seqs: list[list[float]] = []
    original = newton.residual_norm

    def traced(*args, **kw):
        out = original(*args, **kw)
        seqs[-1].append(out[0] / out[1])
        return out

    monkeypatch.setattr(newton, "residual_norm", traced)
    s = Stepper(problem, "crank-nicolson", (dt, steps * dt), {"solver_options": {"tangent": "full"}})
    if drop_geometric:
        monkeypatch.setattr(CurrentPairRows, "geometric_stiffness", lambda self, U, t, lam: None)
    while s.status == "running":
        seqs.append([])
        s.step()
    s.finish()
    return seqs, s


def test_a_spinning_block_landing_on_another_converges_quadratically(monkeypatch):
    """The contact steps' Newton residuals fall as e_{k+1} <= C e_k^2 (the last iterate of each of the
    steps after the landing, as data); with the geometric stiffness left out (rows frozen at an iterate) the
    same steps converge linearly, and the ratio bound fails: the test can fail."""
    seqs, s = _newton_residuals(spinning_landing(), 2e-4, 60, False, monkeypatch)
    assert s.status == "finished"
    quadratic = []
    for seq in seqs[30:]:
        e = [x for x in seq if x > 1e-13]
        if len(e) >= 3:
            quadratic.append(max(e[k + 1] / e[k] ** 2 for k in range(len(e) - 2, len(e) - 1)))
    assert quadratic and max(quadratic) < 1e3, max(quadratic)
    assert np.mean([len(q) for q in seqs[30:]]) <= 5

    frozen, _ = _newton_residuals(spinning_landing(), 2e-4, 60, True, monkeypatch)
    rates = [q[-1] / q[-2] for q in frozen[30:] if len(q) >= 6]
    assert rates and min(rates) > 0.2  # linear: every contact step's last iterations contract by 0.2 or less


@pytest.mark.parametrize("scheme", ["crank-nicolson", "energy-momentum", "backward-euler"])
def test_the_spinning_landing_finishes(scheme):
    """30 rad/s, dt = 2e-4, to t = 40 ms (the landing, the block rolling on the other): energy-momentum failed
    at t = 10 ms before (Newton did not converge in 25 iterations), Crank–Nicolson and backward Euler took 10
    iterations a step; now about 5 (the default tangent policy)."""
    H = simulate(spinning_landing(), scheme, 2e-4, 0.04, solver_options={"energy_check": "fail"})
    assert H.status == "finished", H.message
    assert H.lam.min() < 0 and H.gap.min() >= -1e-10 * 0.6
    assert np.mean(H.columns()["nonlinear_iterations"][1:]) <= 7


def test_a_rows_facing_flips_are_counted_within_a_step_only():
    """RIM_FLIPS: a pair row whose facing changes twice between the iterates of one step faces its facet's line
    for the rest of the step.  The count starts at the step's first iterate: the facing left by the last step
    (or by a resume, or by a rejected try of the same step) is not a flip, so a step depends on its level alone
    (a review found a resumed run marking a row sticky one iterate earlier than the continuous one)."""
    import types

    import scipy.sparse as sp

    from signorini.dynamics.rows.current_rows import RIM_FLIPS, CurrentPairRows

    assert RIM_FLIPS == 2

    def rows(facing_before: bool) -> CurrentPairRows:  # one row, its projection stubbed
        o = object.__new__(CurrentPairRows)
        o.contact = types.SimpleNamespace(size=1, B=sp.csr_matrix((1, 2)), normals=np.zeros((1, 2)),
                                          master_facet=np.zeros(1, int), master_shape=np.zeros((1, 2)),
                                          master_dofs=np.zeros((1, 2, 2), int))  # fmt: skip
        o.space = types.SimpleNamespace(dofs=lambda n: np.zeros((n.size, 2), int))
        o.far, o._last, o._first = 1e6, None, False
        o.facing, o._flips, o._sticky = np.array([facing_before]), np.zeros(1, int), np.zeros(1, bool)
        o._set = lambda new: np.zeros(0, int)
        o.rows = types.SimpleNamespace(keep_level=lambda t: None)
        return o

    def stub(f: bool) -> list:
        proj = types.SimpleNamespace(normals=np.zeros((1, 2)), facet=np.zeros(1, int), xi=np.zeros((1, 2)),
                                     facet_nodes=np.zeros((1, 2), int), facing=np.array([f]),
                                     gaps=np.array([0.0]))  # fmt: skip
        return [(np.array([0]), proj)]

    def gap_after(o: CurrentPairRows, iterates, then: bool) -> float:
        """The row's gap at a point where it faces ``then``, after a step's iterates facing ``iterates``."""
        o.keep_level(0.0)
        for f in iterates:
            o._project = lambda U, f=f: stub(f)
            o.follow(np.zeros(2), 0.1)
        o._project = lambda U: stub(then)
        return float(o.gaps(np.zeros(2), 0.1)[0])

    # beyond the rim at the level, pulled in at the next iterate (one flip), beyond it again at the test: not
    # sticky, whatever the facing the previous step (or a resume) left
    assert gap_after(rows(False), [False, True], False) == gap_after(rows(True), [False, True], False) == 1e6
    # out, in, out within the step: two flips, the line faced for the rest of the step
    assert gap_after(rows(True), [False, True, False], False) == 0.0

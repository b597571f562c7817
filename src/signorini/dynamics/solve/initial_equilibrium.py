"""A static preload: the bodies held by supports or resting in contact start in equilibrium.

With ``[initial] equilibrium = true`` (``Problem(..., initial_equilibrium=True)``) level 0's displacement of the
*held* bodies solves the static contact problem under the loads at t = 0,

    f(U) = F(0) + B^T lambda,    B U <= g(0)  ⊥  lambda <= 0,    U = U_D(0) on the Dirichlet dofs,

and level 0's multipliers are its lambda (so that the balance M A0 = F + B^T lambda - f(U) gives A0 = 0 there
and the supports' reactions at t = 0 carry the loads).  A body is held when a chain of touching contacts (gaps
within :data:`RESTING` of the body's size at t = 0) links it to a Dirichlet support or to a rigid obstacle; the
others (*free* bodies, in flight) keep their given displacement.  Velocities are kept as given.

The static operator of a body held only by contact is singular (its rigid motions), so the problem is solved by
proximal iterations: each solves (delta M + S) dU = F + B^T lambda - S U_k with contact, U_{k+1} = U_k + dU,
delta = :data:`PROXIMAL`
tr(S)/tr(M) (a small fraction of the mean squared frequency: an elastic mode of frequency w contracts by
delta/(delta + w^2) per iteration, a rigid motion the contact holds is held exactly, one nothing holds moves by its
load / delta and is refused).  The iterations stop when the force the proximal term leaves, |delta M dU|, is below
:data:`TOLERANCE` of the load's scale.  With finite strain the same iterations are a modified Newton method (the
linear stiffness S as the operator, f(U) the law's internal force; 5 iterations on a steel beam under its weight,
whose force residual then sits at 2e-11 of the load, the internal force's round-off since it forms the strain from
the displacement gradient, not from F^T F - I); the contact rows are the reference configuration's (a preload's
displacements are small).  Refused by name: friction (the tangential forces of a support at rest are not unique).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from ...errors import InputError

if TYPE_CHECKING:
    from .context import Context

#: a gap at t = 0 within this fraction of the body's size is a resting contact (the body is held through it)
RESTING = 1e-9
#: the proximal weight delta, as a fraction of tr(S)/tr(M) (module docstring)
PROXIMAL = 1e-8
#: the iterations stop when |delta M dU| <= TOLERANCE * (|F| + |f(U)|) (inf-norms)
TOLERANCE = 1e-12
#: at most this many proximal iterations (measured: 2-4 on the beams and blocks of the tests)
MAX_ITERATIONS = 60


def held_nodes(ctx: Context, U: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """(held, labels, n_bodies): bool (N,) the nodes of the held bodies (module docstring), the body of every
    node (:func:`~signorini.fem.mesh.bodies`) and the number of bodies."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    from ...fem.mesh import bodies
    from ..rows.current_rows import level_gaps
    from .context import TOUCH

    mesh = ctx.disc.problem.mesh
    labels = bodies(mesh)
    nb = int(labels.max(initial=-1)) + 1
    ground = nb  # the supports and the rigid obstacle
    d = mesh.dim
    edges = []
    if ctx.has_fixed:
        held = labels[np.unique(np.unravel_index(ctx.fixed, (mesh.n_nodes, d))[0])]
        edges.append(np.column_stack([held, np.full(held.size, ground)]))
    c = ctx.disc.contact
    if c.size:
        gaps = level_gaps(ctx, U, 0.0)
        touching = np.flatnonzero(gaps <= RESTING / TOUCH * ctx.touch_tolerance)  # RESTING of the body's size
        slave = labels[c.nodes[touching]]
        pair = c.pair[touching] if c.pair is not None else np.full(touching.size, -1)
        rigid = pair < 0
        edges.append(np.column_stack([slave[rigid], np.full(int(rigid.sum()), ground)]))
        if (~rigid).any():
            rows = touching[~rigid]
            master = labels[np.unravel_index(c.master_dofs[rows][:, :, 0], (mesh.n_nodes, d))[0]]  # (rows, nodes)
            edges.append(np.column_stack([np.repeat(slave[~rigid], master.shape[1]), master.ravel()]))
    e = np.concatenate(edges) if edges else np.zeros((0, 2), dtype=np.int64)
    graph = coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(nb + 1, nb + 1))
    _, comp = connected_components(graph, directed=False)
    held_body = comp[:nb] == comp[ground]
    return held_body[labels], labels, nb


def static_equilibrium(ctx: Context, U0: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """Level 0's displacement and multipliers in static equilibrium (module docstring).

    Returns U (n,), lambda (nc,) and what ``summary.json`` ``initial_equilibrium`` reports (the held and free
    bodies, the iterations, the force left).  Raises InputError naming the body when a held body has no
    equilibrium (a rigid motion its supports do not hold), and with friction (module docstring)."""
    from ..model.operator import Operator

    M, S, el = ctx.M, ctx.S, ctx.elastic
    if ctx.rows.components > 1:
        raise InputError(
            "[initial] equilibrium = true with friction is not supported: the static solve is frictionless and a "
            "frictional support's tangential forces at rest are not unique; start from rest without it"
        )
    mesh = ctx.disc.problem.mesh
    d = mesh.dim
    held, labels, nb = held_nodes(ctx, U0)
    held_dofs = np.repeat(held, d)
    held_bodies = np.unique(labels[held])
    report: dict[str, Any] = {
        "solved": True,
        "held_bodies": held_bodies.tolist(),
        "free_bodies": np.setdiff1d(np.arange(nb), held_bodies).tolist(),
    }
    lam = np.zeros(ctx.disc.contact.size)
    if not held.any():
        report.update(solved=False, reason="no body is held by a support or rests in contact")
        return U0.copy(), lam, report
    delta = PROXIMAL * float(S.diagonal().sum()) / float(M.diagonal().sum())
    op = Operator(delta, 1.0)
    U = U0.copy()
    fixed = ctx.dirichlet(0.0) if ctx.has_fixed else None
    if fixed is not None:
        U[ctx.fixed] = fixed
    f = el.force(U)
    scale = max(np.abs(F).max(initial=0.0), np.abs(f).max(initial=0.0))
    try:
        U, lam, k, left, scale = _proximal(ctx, op, U, F, f, held_dofs, fixed, scale)
    finally:
        ctx.factors.release(op)  # the static operator is of no use to the steps
    if left <= TOLERANCE * max(scale, 1e-300):
        report.update(iterations=k, force_left=float(left), scale=float(scale), proximal_weight=float(delta))
        return U, lam, report
    moved = np.abs((U - U0).reshape(-1, d)).max(axis=1)
    node = int(np.argmax(np.where(held, moved, -1.0)))
    raise InputError(
        f"[initial] equilibrium = true: body {int(labels[node])} has no static equilibrium under the loads at t = 0 "
        f"(after {k} proximal iterations a force of {left:.3g} is left, load scale {scale:.3g}; node {node} moved "
        f"{moved[node]:.3g}): a rigid motion of it that its supports and contacts do not hold (it would slide or "
        "fall); support it, or leave equilibrium off"
    )


def _proximal(
    ctx: Context,
    op: Any,
    U: np.ndarray,
    F: np.ndarray,
    f: np.ndarray,
    held_dofs: np.ndarray,
    fixed: np.ndarray | None,
    scale: float,
) -> tuple[np.ndarray, np.ndarray, int, float, float]:
    """The proximal iterations of the module docstring from U (f = S U): (U, lambda, iterations, the force
    |delta M dU| left, the load scale), stopped at :data:`TOLERANCE`, at a motion that runs away, or after
    :data:`MAX_ITERATIONS`."""
    M, el, delta = ctx.M, ctx.elastic, op.mass
    k, left, lam = 0, np.inf, np.zeros(ctx.disc.contact.size)
    while k < MAX_ITERATIONS:
        k += 1
        # the free bodies' rows balance themselves at their own U0 (no load, no motion)
        r = np.where(held_dofs, F - f, 0.0)
        dU, lam, _ = ctx.solve(op, r, ctx.gaps(0.0) - ctx.rows.B @ U, None if fixed is None else 0.0 * fixed)
        U = U + dU
        f = el.force(U)
        scale = max(scale, np.abs(f).max(initial=0.0))
        left = delta * float(np.abs(M @ dU).max(initial=0.0))
        if not np.isfinite(left) or left > 1e6 * max(scale, 1e-300) or left <= TOLERANCE * max(scale, 1e-300):
            break
    return U, lam, k, left, scale

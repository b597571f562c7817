"""Newton's method for a step whose internal force is nonlinear (finite strain), with contact.

A scheme's step with a nonlinear stiffness force g (theta-method: g = f(U^{n+1}); energy-momentum:
the discrete gradient) is

    c_M M U + c_S g(U) = rhs + B^T lambda (+ T^T lambda_t),   B U <= bound,   lambda <= 0,   complementarity.

Each iteration k linearizes g at the iterate U^k, G_k = dg/dU(U^k), and solves the contact problem of
today's linear step with the operator c_M M + c_S G_k (:class:`~.context.Tangent`, factorized by the
run's :class:`~.factorizations.Factorizations`, its Delassus columns by its contact solver):

    (c_M M + c_S G_k) U^{k+1} = rhs - c_S (g(U^k) - G_k U^k) + B^T lambda^{k+1}

so every iterate satisfies the contact conditions exactly (the rows B are linear in U) and only the
force residual

    r^{k+1} = c_M M U^{k+1} + c_S g(U^{k+1}) - rhs - B^T lambda^{k+1} - T^T lambda_t^{k+1}   (free dofs)

measures the distance to the step's solution; the iterations stop when |r|_inf <= ``newton_tol`` times
the largest of the step's forces plus the round-off of its own terms (:func:`residual_norm`).  When a
full step does not reduce |r| (far from the solution), the step is halved along the segment from U^k
(a line search, at most :data:`LINE_SEARCH_HALVINGS` times; only a full step, which solved the contact
problem, may end the iterations).

``tangent=modified`` keeps G of the step's first iterate while |r| falls at least tenfold per iteration
(:data:`MODIFIED_CONTRACTION`) and refactorizes at the iterate where it does not; each step starts from
the tangent at U^n, so that a step depends on its starting level only (a checkpoint resumes bit for bit).
A step that does not converge in ``newton_max`` iterations raises :class:`ConvergenceError` (the run
fails, exit 3, levels kept; the energy control rejects and halves the step).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from ..contact.solver import ContactLaw, StepInfo
from ..errors import ConvergenceError
from .context import Operator, Tangent

if TYPE_CHECKING:
    from .context import Context

#: the residual's round-off relative to its largest term (1e3 machine epsilons: sums over a row of a few
#: tens of entries)
ROUNDOFF = 1e3 * np.finfo(float).eps
#: the most halvings of a Newton step that did not reduce the residual
LINE_SEARCH_HALVINGS = 5
#: contact in the current configuration: a step converges when the linearized gaps of its last rows are the
#: true ones to this many touch tolerances (1e-12 of the body: 1e-10 of it)
GAP_TOLERANCE = 100.0
#: tangent=modified keeps its factor while the residual falls by at least this factor per iteration
MODIFIED_CONTRACTION = 0.1


def residual_norm(ctx: Context, op: Operator, rhs: np.ndarray, gU: np.ndarray, U: np.ndarray,
                  lam: np.ndarray, lam_t: np.ndarray | None, inertia: np.ndarray | None = None
                  ) -> tuple[float, float]:  # fmt: skip
    """(|r|_inf, scale, floor) of the step's force residual on the free dofs (module docstring) [force].

    The scale is the largest of the step's forces: the inertia c_M M U - M p (``inertia``: the part
    M p of ``rhs`` that is the scheme's inertial prediction; the whole rhs when None), the internal
    force, the loads and the contact force; not c_M M U itself, which grows with the distance a body
    has travelled.  ``floor``: the round-off of r's largest terms (:data:`ROUNDOFF` of them)."""
    MU = op.mass * (ctx.M @ U)
    contact = ctx.contact_force(lam, lam_t)
    r = MU + op.stiffness * gU - rhs - contact
    f = ctx.free
    terms = (MU - rhs, op.stiffness * gU, contact) if inertia is None else (
        MU - inertia, op.stiffness * gU, rhs - inertia, contact)  # fmt: skip
    scale = max(max(float(np.max(np.abs(np.broadcast_to(a, U.shape)[f]), initial=0.0)) for a in terms), 1e-300)
    # the round-off of the sum itself (c_M M U and M p cancel): a residual below it is converged
    floor = ROUNDOFF * max(float(np.max(np.abs(MU[f]), initial=0.0)), float(np.max(np.abs(rhs[f]), initial=0.0)))
    return float(np.max(np.abs(r[f]), initial=0.0)), scale, floor


def newton_solve(
    ctx: Context,
    op: Operator,
    rhs: np.ndarray,
    force: Callable[[np.ndarray], np.ndarray],
    tangent: Callable[[np.ndarray], object],
    start: np.ndarray,
    bound: np.ndarray | Callable[[np.ndarray], np.ndarray],
    fixed: np.ndarray | None,
    law: ContactLaw,
    inertia: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, StepInfo]:
    """Solve the nonlinear step of the module docstring from the iterate ``start`` (n,).

    ``op``: the step's linear operator (its coefficients c_M, c_S; its S is replaced by each tangent);
    ``force(U)`` g(U) (n,) and ``tangent(U)`` dg/dU (sparse, n x n).  ``bound``: the gaps, or (contact in
    the current configuration, :class:`~.current_rows.FollowingBound`) a function that moves the rows to the
    iterate and returns their bound; then the iterations also wait for the linearized gaps to be the true
    ones to ``GAP_TOLERANCE`` times the context's touch tolerance.  ``inertia``: the inertial part M p of
    ``rhs`` (:func:`residual_norm`'s scale).  Returns U (n,), lambda (nc,) and the
    last contact solve's info with ``nonlinear_iterations`` (the Newton iterations) set."""
    opts = ctx.solver_options
    tol, most = float(opts.get("newton_tol", 1e-10)), int(opts.get("newton_max", 25))
    modified = opts.get("tangent", "modified") == "modified"
    U = np.array(start, dtype=float, copy=True)
    gU = force(U)
    lam = lam_t = None
    previous = np.inf
    current: Operator | None = None
    elastic = ctx.elastic
    norm = scale = allowed = np.nan
    try:
        for k in range(1, most + 1):
            refactor = current is None or not modified or norm > MODIFIED_CONTRACTION * previous
            if refactor:
                if current is not None:
                    ctx.factors.release(current)
                current = Operator(op.mass, op.stiffness, Tangent(tangent(U)))
                elastic.factorizations += 1
            G = current.tangent.matrix
            bnd = bound(U) if callable(bound) else bound
            U_new, lam_new, info = ctx.solve(current, rhs - op.stiffness * (gU - G @ U), bnd, fixed, law)
            g_new = force(U_new)
            n_new, scale, floor = residual_norm(ctx, op, rhs, g_new, U_new, lam_new, info.lam_t, inertia)
            allowed = tol * scale + floor
            if lam is not None and not n_new < norm and n_new > allowed:  # no decrease: halve the step
                for _ in range(LINE_SEARCH_HALVINGS):
                    U_try = 0.5 * (U + U_new)
                    lam_try = 0.5 * (lam + lam_new)
                    lt_try = None if info.lam_t is None else 0.5 * (lam_t + info.lam_t)
                    g_try = force(U_try)
                    n_try = residual_norm(ctx, op, rhs, g_try, U_try, lam_try, lt_try, inertia)[0]
                    elastic.line_search_steps += 1
                    U_new, lam_new, g_new, n_new = U_try, lam_try, g_try, n_try
                    info.lam_t = lt_try
                    if n_try < norm:
                        break
                full = False
            else:
                full = True
            previous, norm = norm, n_new
            U, lam, lam_t, gU = U_new, lam_new, info.lam_t, g_new
            gaps_ok = not callable(bound) or bound.gap_error(U) <= GAP_TOLERANCE * ctx.touch_tolerance
            if full and norm <= allowed and gaps_ok:
                info.nonlinear_iterations = k
                return U, lam, info
    finally:
        if current is not None:
            ctx.factors.release(current)
    raise ConvergenceError(
        f"Newton's method did not converge in {most} iterations (force residual {norm:.3g}, {norm / scale:.3g} of "
        f"its scale against newton_tol = {tol:g}); reduce the step, or raise newton_max"
    )

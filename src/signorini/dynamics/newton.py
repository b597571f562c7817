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
the largest of its terms.  When a full step does not reduce |r| (far from the solution), the step is
halved along the segment from U^k (a line search, at most :data:`LINE_SEARCH_HALVINGS` times; only a
full step, which solved the contact problem, may end the iterations).

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

#: the most halvings of a Newton step that did not reduce the residual
LINE_SEARCH_HALVINGS = 5
#: tangent=modified keeps its factor while the residual falls by at least this factor per iteration
MODIFIED_CONTRACTION = 0.1


def residual_norm(ctx: Context, op: Operator, rhs: np.ndarray, gU: np.ndarray, U: np.ndarray,
                  lam: np.ndarray, lam_t: np.ndarray | None) -> tuple[float, float]:  # fmt: skip
    """(|r|_inf, scale) of the step's force residual on the free dofs (module docstring) [force]."""
    inertia = op.mass * (ctx.M @ U)
    r = inertia + op.stiffness * gU - rhs - ctx.contact_force(lam, lam_t)
    f = ctx.free
    scale = max(float(np.max(np.abs(rhs[f]), initial=0.0)), float(np.max(np.abs(inertia[f]), initial=0.0)),
                float(np.max(np.abs(op.stiffness * gU[f]), initial=0.0)), 1e-300)  # fmt: skip
    return float(np.max(np.abs(r[f]), initial=0.0)), scale


def newton_solve(
    ctx: Context,
    op: Operator,
    rhs: np.ndarray,
    force: Callable[[np.ndarray], np.ndarray],
    tangent: Callable[[np.ndarray], object],
    start: np.ndarray,
    bound: np.ndarray,
    fixed: np.ndarray | None,
    law: ContactLaw,
) -> tuple[np.ndarray, np.ndarray, StepInfo]:
    """Solve the nonlinear step of the module docstring from the iterate ``start`` (n,).

    ``op``: the step's linear operator (its coefficients c_M, c_S; its S is replaced by each tangent);
    ``force(U)`` g(U) (n,) and ``tangent(U)`` dg/dU (sparse, n x n).  Returns U (n,), lambda (nc,) and
    the last contact solve's info with ``nonlinear_iterations`` (the Newton iterations) set."""
    opts = ctx.solver_options
    tol, most = float(opts.get("newton_tol", 1e-10)), int(opts.get("newton_max", 25))
    modified = opts.get("tangent", "modified") == "modified"
    U = np.array(start, dtype=float, copy=True)
    gU = force(U)
    lam = lam_t = None
    previous = np.inf
    current: Operator | None = None
    elastic = ctx.elastic
    norm = scale = np.nan
    try:
        for k in range(1, most + 1):
            refactor = current is None or not modified or norm > MODIFIED_CONTRACTION * previous
            if refactor:
                if current is not None:
                    ctx.factors.release(current)
                current = Operator(op.mass, op.stiffness, Tangent(tangent(U)))
                elastic.factorizations += 1
            G = current.tangent.matrix
            U_new, lam_new, info = ctx.solve(current, rhs - op.stiffness * (gU - G @ U), bound, fixed, law)
            g_new = force(U_new)
            n_new, scale = residual_norm(ctx, op, rhs, g_new, U_new, lam_new, info.lam_t)
            if lam is not None and not n_new < norm:  # no decrease: halve the step along the segment
                for _ in range(LINE_SEARCH_HALVINGS):
                    U_try = 0.5 * (U + U_new)
                    lam_try = 0.5 * (lam + lam_new)
                    lt_try = None if info.lam_t is None else 0.5 * (lam_t + info.lam_t)
                    g_try = force(U_try)
                    n_try, _ = residual_norm(ctx, op, rhs, g_try, U_try, lam_try, lt_try)
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
            if full and norm <= tol * scale:
                info.nonlinear_iterations = k
                return U, lam, info
    finally:
        if current is not None:
            ctx.factors.release(current)
    raise ConvergenceError(
        f"Newton's method did not converge in {most} iterations (force residual {norm:.3g}, {norm / scale:.3g} of "
        f"its scale against newton_tol = {tol:g}); reduce the step, or raise newton_max"
    )

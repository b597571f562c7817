"""Newton's method for a step whose internal force is nonlinear (finite strain), with contact.

A scheme's step with a nonlinear stiffness force g (theta-method: g = f(U^{n+1}); energy-momentum:
the discrete gradient) is

    c_M M U + c_S g(U) = rhs + B^T lambda (+ T^T lambda_t),   B U <= bound,   lambda <= 0,   complementarity.

Each iteration k linearizes g at the iterate U^k, G_k = dg/dU(U^k), and solves the contact problem of
today's linear step with the operator c_M M + c_S G_k (:class:`~.context.Tangent`, factorized by the
run's :class:`~.factorizations.Factorizations`, its Delassus columns by its contact solver):

    (c_M M + c_S G_k) U^{k+1} = rhs - c_S (g(U^k) - G_k U^k) + B^T lambda^{k+1}

so every iterate satisfies the contact conditions of its linearized rows exactly and only the force residual

    r^{k+1} = c_M M U^{k+1} + c_S g(U^{k+1}) - rhs - B^T lambda^{k+1} - T^T lambda_t^{k+1}   (free dofs)

measures the distance to the step's solution.  With rows of the current configuration
(:mod:`~.current_rows`) B in r is that of the iterate itself, B(U^{k+1}), and the tangent gains the derivative
of B(U)^T lambda at fixed lambda (the rows' own turning, ``geometric_stiffness``), so that Newton converges
quadratically where the normals turn under the force; the iterations stop when |r|_inf <= ``newton_tol`` times
the largest of the step's forces plus the round-off of its own terms (:func:`residual_norm`).  When a
full step does not reduce |r| (far from the solution), the step is halved along the segment from U^k
(a line search, at most :data:`LINE_SEARCH_HALVINGS` times; only a full step, which solved the contact
problem, may end the iterations).

``tangent=modified`` keeps G of the step's first iterate while |r| falls fast enough to reach the tolerance in a
few more iterations (:func:`_renew`) and refactorizes at the iterate where it does not (a step that starts near
the reference configuration starts with the scheme's linear operator, :data:`REFERENCE_GRADIENT`); each step starts from
the tangent at U^n, so that a step depends on its starting level only (a checkpoint resumes bit for bit).
A step that does not converge in ``newton_max`` iterations raises :class:`ConvergenceError` (the run
fails, exit 3, levels kept; the energy control rejects and halves the step).

On several ranks (``petsc``) the state is replicated but its arithmetic is not bitwise the same on every rank
(a dot product's round-off can depend on memory alignment), and each iteration's branches (the reference
start, the residual against the tolerance, a kept tangent renewed, the line search, the gaps settled) decide
collective factorizations and solves: they are taken on rank 0's values, broadcast (one small message per
evaluation), so that every rank takes the same branch.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp

from ..contact.solver import ContactLaw, StepInfo
from ..errors import ConvergenceError, InputError
from ..linalg.row_block import RowBlock
from .context import Operator, Tangent

if TYPE_CHECKING:
    from .context import Context

#: the residual's round-off relative to its largest term (1e3 machine epsilons: sums over a row of a few
#: tens of entries)
ROUNDOFF = 1e3 * np.finfo(float).eps
#: the most halvings of a Newton step that did not reduce the residual
LINE_SEARCH_HALVINGS = 5
#: tangent=modified keeps its factor while the residual falls by at least this factor per iteration and reaches
#: the tolerance in at most KEPT_ITERATIONS more iterations at that rate (a factorization costs tens of solves)
MODIFIED_CONTRACTION = 0.5
KEPT_ITERATIONS = 10
#: tangent=modified starts a step with the scheme's linear operator c_M M + c_S S (no factorization) when the
#: displacement gradient at its start is at most this (max |F - I| over the quadrature points): its contraction is
#: then about this times the stiffness's share of the operator (measured in docs/finite_strain.md)
REFERENCE_GRADIENT = 0.25
#: an iterate of a fresh tangent whose residual fell by less than this factor has stalled; it is converged when its
#: residual is below the round-off of the internal force itself (:meth:`~.elasticity.FiniteStrain.force_noise`)
STALLED = 0.9
#: a step of a kept (modified) tangent that does not reduce the residual by this factor is taken back and the
#: tangent renewed at the iterate it started from (a poor stale step leads Newton astray: measured below)
KEPT_CONTRACTION = 0.5


def residual_norm(ctx: Context, op: Operator, base: np.ndarray, rest: np.ndarray, gU: np.ndarray, U: np.ndarray,
                  lam: np.ndarray, lam_t: np.ndarray | None, inertia: np.ndarray | None = None,
                  contact_force: Callable | None = None) -> tuple[float, float, float]:  # fmt: skip
    """(|r|_inf, scale, floor) of the step's force residual on the free dofs [force], in increments:

        r = c_M M (U - U_base) + c_S g(U) - rest - B^T lambda - T^T lambda_t,   rest = rhs - c_M M U_base,

    so that its precision is that of the step's forces, not of the displacement (a body that has travelled
    far).  The scale is the largest of the step's forces: the inertia c_M M (U - U_base) - M q (``inertia``:
    the inertial part M q of ``rest``; 0 when None), the internal force, the loads and the contact force;
    ``floor`` the round-off of r's largest terms (:data:`ROUNDOFF` of them).  ``contact_force(U, lam, lam_t)``:
    the contact force through the rows of U itself (rows of the current configuration); else B^T lambda +
    T^T lambda_t through the rows of the last solve."""
    MdU = _mass_part(ctx, op, U - base)
    contact = ctx.contact_force(lam, lam_t) if contact_force is None else contact_force(U, lam, lam_t)
    r = MdU + op.stiffness * gU - rest - contact
    f = ctx.free
    q = 0.0 if inertia is None else inertia
    terms = (MdU - q, op.stiffness * gU, rest - q, contact)
    scale = max(max(float(np.max(np.abs(np.broadcast_to(a, U.shape)[f]), initial=0.0)) for a in terms), 1e-300)
    floor = ROUNDOFF * max(float(np.max(np.abs(MdU[f]), initial=0.0)), float(np.max(np.abs(rest[f]), initial=0.0)))
    return float(np.max(np.abs(r[f]), initial=0.0)), scale, floor


def _renew(norm: float, previous: float, allowed: float) -> bool:
    """Whether a kept tangent should be renewed: its rate |r_k| / |r_k-1| is above :data:`MODIFIED_CONTRACTION`,
    or it would take more than :data:`KEPT_ITERATIONS` more iterations at that rate to reach ``allowed``."""
    if not np.isfinite(previous) or norm <= allowed:
        return False
    rate = norm / previous
    if rate > MODIFIED_CONTRACTION:
        return True
    return bool(np.log(allowed / norm) / np.log(rate) > KEPT_ITERATIONS) if rate > 0 else False


def _mass_part(ctx: Context, op: Operator, dU: np.ndarray) -> np.ndarray:
    """c_M M dU, plus c C dU when the operator holds a damping matrix (damping per region) [force]."""
    out = op.mass * (ctx.M @ dU)
    if op.viscous is not None:
        out = out + op.viscous.coefficient * (op.viscous.matrix @ dU)
    return out


def _shifted(law: ContactLaw, ctx: Context, U: np.ndarray) -> ContactLaw:
    """The law of a solve for the increment from U: the slip reference c_t less T U."""
    if law.reference is None:
        return law
    return replace(law, reference=law.reference - (ctx.T @ U).reshape(law.reference.shape))


def newton_solve(
    ctx: Context,
    op: Operator,
    base: np.ndarray,
    rest: np.ndarray,
    force: Callable[[np.ndarray], np.ndarray],
    tangent: Callable[[np.ndarray], object],
    bound: np.ndarray | Callable[[np.ndarray], np.ndarray],
    fixed: np.ndarray | None,
    law: ContactLaw,
    inertia: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, StepInfo]:
    """Solve the nonlinear step of the module docstring, whose right-hand side is c_M M U_base + ``rest``, from
    the iterate ``base`` = U_base (n,: the level the step starts from).

    Each iteration solves for the increment d = U^{k+1} - U^k, (c_M M + c_S G_k) d = -r(U^k) + B^T lambda with
    B d <= bound - B U^k (the same contact problem; lambda the whole multiplier), so that the iterates keep
    the precision of the step's forces (:func:`residual_norm`).  ``op``: the step's linear operator (its
    coefficients c_M, c_S; its S is replaced by each tangent); ``force(U)`` g(U) (n,) and ``tangent(U)``
    dg/dU (sparse, n x n).  ``bound``: the gaps, or (contact in the current configuration,
    :class:`~.current_rows.FollowingBound`) a function that moves the rows to the iterate and returns their
    bound; then the iterations also wait for the linearized gaps to be the true ones (to ``GAP_TOLERANCE``
    touch tolerances, or their round-off).  ``inertia``: the inertial part M q of ``rest``.  Returns U (n,),
    lambda (nc,) and the last contact solve's info with ``nonlinear_iterations`` (the Newton iterations) set."""
    opts = ctx.solver_options
    tol, most = float(opts.get("newton_tol", 1e-10)), int(opts.get("newton_max", 25))
    modified = opts.get("tangent", "modified") == "modified"
    U = np.array(base, dtype=float, copy=True)
    gU = force(U)
    lam = lam_t = None
    previous = np.inf
    current: Operator | None = None
    elastic = ctx.elastic
    norm = scale = allowed = np.nan
    full = True
    D = ctx.fixed
    # rows of the current configuration: the residual's contact force through the rows of each iterate itself
    through = bound.contact_force if callable(bound) else None
    # a step that starts near the reference configuration starts with the scheme's own linear operator (factorized
    # at set-up): no factorization while it contracts (a mass-dominated impact's steps)
    agree = ctx.comm.bcast  # every branch below on rank 0's values (module docstring: several ranks)
    reference = modified and agree(bool(elastic.displacement_gradient(U) <= REFERENCE_GRADIENT))
    owned = False  # whether ``current`` is this step's tangent (released after it), not the scheme's operator
    try:
        for k in range(1, most + 1):
            refactor = current is None or not modified or not full or _renew(norm, previous, allowed)
            if refactor:
                if owned:
                    ctx.factors.release(current)
                if k == 1 and reference:
                    current, owned = op, False
                else:
                    G = tangent(U)
                    Kc = bound.geometric_stiffness(U, lam) if callable(bound) and lam is not None else None
                    if Kc is not None:  # the rows' own turning under the multipliers of the last iterate
                        G = _plus(G, Kc / op.stiffness)
                    current, owned = Operator(op.mass, op.stiffness, Tangent(G), op.viscous), True
                    elastic.factorizations += 1
            bnd = bound(U) if callable(bound) else bound
            # the slip measured in the frames of the rows just moved to U; the rows that face nothing left out
            law_k = bound.law(law) if callable(bound) else law
            minus_r = rest - _mass_part(ctx, op, U - base) - op.stiffness * gU
            try:
                d, lam_new, info = ctx.solve(current, minus_r, bnd - ctx.B @ U, None if fixed is None else fixed - U[D],
                                             _shifted(law_k, ctx, U))  # fmt: skip
            except InputError as exc:  # the tangent itself cannot be factorized: not the set-up's input
                raise ConvergenceError(
                    f"the tangent of Newton iterate {k} cannot be factorized: it is not positive definite (an "
                    "unstable state: buckling, or a material driven beyond its stability); reduce the step"
                ) from exc
            U_new = U + d
            g_new = force(U_new)
            n_new, scale, floor = agree(
                residual_norm(ctx, op, base, rest, g_new, U_new, lam_new, info.lam_t, inertia, through)
            )
            allowed = tol * scale + floor
            if lam is not None and refactor and n_new > allowed and n_new > STALLED * norm:
                # no longer falling: at the internal force's own round-off (a body far from its reference place)
                # the iterate is converged as far as the force can tell
                noise = agree(op.stiffness * elastic.force_noise(U_new))
                if n_new <= noise:
                    allowed = n_new
            if lam is not None and not refactor and n_new > allowed and not n_new <= KEPT_CONTRACTION * norm:
                full = False  # a kept tangent's step that does not halve |r|: taken back, the tangent renewed here
                continue
            if lam is not None and not n_new < norm and n_new > allowed:  # no decrease: halve the step
                for _ in range(LINE_SEARCH_HALVINGS):
                    U_try = U + 0.5 * (U_new - U)
                    lam_try = 0.5 * (lam + lam_new)
                    lt_try = None if info.lam_t is None else 0.5 * (lam_t + info.lam_t)
                    g_try = force(U_try)
                    r_try = residual_norm(ctx, op, base, rest, g_try, U_try, lam_try, lt_try, inertia, through)
                    n_try = agree(r_try[0])
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
            gaps_ok = not callable(bound) or agree(bool(bound.converged(U)))
            if full and norm <= allowed and gaps_ok:
                info.nonlinear_iterations = k
                return U, lam, info
    finally:
        if owned:
            ctx.factors.release(current)
    if norm <= allowed:  # the forces balance; the rows of the current configuration did not settle
        raise ConvergenceError(
            f"Newton's method did not converge in {most} iterations: the forces balance (residual {norm / scale:.3g} "
            f"of its scale, newton_tol = {tol:g}) but the contact rows of the current configuration did not settle "
            "(their linearized gaps are not the true ones: a node alternating between facets, or a large rotation "
            "within the step); reduce the step, or raise newton_max"
        )
    raise ConvergenceError(
        f"Newton's method did not converge in {most} iterations (force residual {norm:.3g}, {norm / scale:.3g} of "
        f"its scale against newton_tol = {tol:g}); reduce the step, or raise newton_max"
    )


def _plus(G: sp.csr_matrix | RowBlock, K: sp.spmatrix) -> sp.csr_matrix | RowBlock:
    """G + K (n, n); G by rows (a distributed backend's tangent): this rank's rows of the sum."""
    if isinstance(G, RowBlock):
        return RowBlock((G.local + sp.csr_matrix(K)[G.lo : G.hi]).tocsr(), G.bounds, G.comm)
    return (G + K).tocsr()

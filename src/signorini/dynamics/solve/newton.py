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
the largest of the step's forces plus the round-off of its own terms (:func:`residual_norm`).  The unknown is
the step's increment X = U - U^n, so that the residual's precision is that of the forces at any step size.

Globalization (``../shared`` spec section 15, issue 51): a full step that does not lower |r| is searched along
its direction, by Armijo backtracking on the step's incremental potential Pi (:class:`_Potential`; the schemes
whose step minimizes one pass the stored energy W, ``energy``) or, for energy-momentum, by halving on |r|; a
trial that inverts a cell is halved.  A tangent that cannot be factorized, or has a negative curvature along a
direction that did not lower |r|, is rebuilt with each cell's matrix positive semi-definite, then shifted
(:class:`_Factor`).  Only a full step, which solved the contact problem, may end the iterations.

``tangent=modified`` keeps G of the step's first iterate while |r| falls fast enough to reach the tolerance in a
few more iterations (:func:`_renew`) and refactorizes at the iterate where it does not (a step that starts near
the reference configuration starts with the scheme's linear operator, :data:`REFERENCE_GRADIENT`).  On one
process the last plain tangent a step made is kept across levels (``Factorizations.keep``) and starts the next
steps of the same coefficients while it contracts as a kept tangent must; a step it does not serve (a renewal, a
step that did not halve |r|, a solve that fails) starts again from its level with its own operator, its iterates
dropped (counted in ``nonlinear_iterations``; contact pairs in the current configuration keep the flips at a
master surface's rim that those iterates counted, as a step's later iterates do), and the kept tangent is dropped;
on a ``petsc`` backend (operators by rows) none is kept.  A kept tangent turns with its bodies (:mod:`~.turning`):
made at U_k, it serves a level where a body has turned by R since as Q K_k Q^T, its factor solved between two
rotations (re-aimed at the step's first iterate).  A checkpoint records the kept tangent's matrix and where it was
made, and a rejected step's rollback keeps the one before again (:mod:`~..restart.protocol`), so a step depends on
its level and that tangent only: a resume is bit for bit.
While the operator is kept (the scheme's own or a kept tangent), ``acceleration=anderson`` (the default) mixes
the iterates with the last ones (:mod:`~.anderson`: a Krylov method preconditioned by the factorized operator) as
long as the rows held at their bound stay the same and no friction acts; a mixed iterate that does not lower |r|,
or leaves the contact conditions, is replaced by the plain one.
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
import scipy.sparse.linalg  # noqa: F401  (sp.linalg.spsolve)

from ...contact.solver import MAX_CONTACT_RESIDUAL, ContactLaw, StepInfo
from ...errors import ConvergenceError, InputError
from ...fem.hyperelastic import InvertedCellError
from ...linalg.row_block import RowBlock
from ..model.operator import Operator, Tangent
from .anderson import Anderson

if TYPE_CHECKING:
    from ..rows.current_rows import FixedBound, FollowingBound
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
#: a fresh tangent whose step reduces the residual by less than this factor is taken for an approximate Jacobian:
#: with a scheme's exact one (``jacobian``: energy-momentum) the rest of the step takes its directions (measured:
#: the symmetric tangent of energy-momentum contracts by 0.23-0.5 where it is poor; where it is good, as on the gmsh
#: bracket of examples/bracket_tumble.toml, the exact directions on every iteration cost 3.1x the run's time)
EXACT_RATE = 0.1
#: a step of a kept (modified) tangent that does not reduce the residual by this factor is taken back and the
#: tangent renewed at the iterate it started from (a poor stale step leads Newton astray: measured below)
KEPT_CONTRACTION = 0.5
#: what a tangent's factorization costs, in Newton iterations, for the choice of keeping a tangent across levels
#: (:func:`_served`; measured: about 1 on a 2D block of 108 dofs, 12 on the 2,853-dof gmsh bracket of
#: examples/bracket_tumble.toml, docs/finite_strain.md)
KEPT_FACTORIZATION = 4.0


def residual_norm(
    ctx: Context,
    op: Operator,
    X: np.ndarray,
    rest: np.ndarray,
    gU: np.ndarray,
    U: np.ndarray,
    lam: np.ndarray,
    lam_t: np.ndarray | None,
    inertia: np.ndarray | None = None,
    contact_force: Callable | None = None,
) -> tuple[float, float, float]:
    """(|r|_inf, scale, floor) of the step's force residual on the free dofs [force], in increments:

        r = c_M M X + c_S g(U) - rest - B^T lambda - T^T lambda_t,   X = U - U_base,   rest = rhs - c_M M U_base,

    with the increment X kept as the unknown itself (not formed as U - U_base), so that the residual's precision is
    that of the step's forces, not of the displacement (a body that has travelled far: at a step of 1e-7 s, c_M M
    times one ulp of |U| is above newton_tol, measured on a spinning puck).  The scale is the largest of the
    step's forces: the inertia c_M M X - M q (``inertia``: the inertial part M q of ``rest``; 0 when None), the
    internal force, the loads and the contact force; ``floor`` the round-off of r's largest terms
    (:data:`ROUNDOFF` of them).  ``contact_force(U, lam, lam_t)``: the contact force through the rows of U itself
    (rows of the current configuration); else B^T lambda + T^T lambda_t through the rows of the last solve."""
    r, MdU, contact = _residual(ctx, op, X, rest, gU, U, lam, lam_t, contact_force)
    f = ctx.free
    q = 0.0 if inertia is None else inertia
    terms = (MdU - q, op.stiffness * gU, rest - q, contact)
    scale = max(max(float(np.max(np.abs(np.broadcast_to(a, U.shape)[f]), initial=0.0)) for a in terms), 1e-300)
    floor = ROUNDOFF * max(float(np.max(np.abs(MdU[f]), initial=0.0)), float(np.max(np.abs(rest[f]), initial=0.0)))
    return float(np.max(np.abs(r[f]), initial=0.0)), scale, floor


def _residual(
    ctx: Context,
    op: Operator,
    X: np.ndarray,
    rest: np.ndarray,
    gU: np.ndarray,
    U: np.ndarray,
    lam: np.ndarray,
    lam_t: np.ndarray | None,
    contact_force: Callable | None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(r, c_M M X, the contact force), r (n,) the residual of :func:`residual_norm` on every dof [force]."""
    MdU = _mass_part(ctx, op, X)
    contact = ctx.rows.contact_force(lam, lam_t) if contact_force is None else contact_force(U, lam, lam_t)
    return MdU + op.stiffness * gU - rest - contact, MdU, contact


def _force_residual(
    ctx: Context,
    op: Operator,
    X: np.ndarray,
    rest: np.ndarray,
    gU: np.ndarray,
    U: np.ndarray,
    lam: np.ndarray,
    lam_t: np.ndarray | None,
    contact_force: Callable | None,
) -> np.ndarray:
    """r (n,) of :func:`residual_norm` at the solution, 0 on the Dirichlet dofs (their reactions balance them)."""
    r = _residual(ctx, op, X, rest, gU, U, lam, lam_t, contact_force)[0]
    r[ctx.fixed] = 0.0
    return r


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
    return replace(law, reference=law.reference - (ctx.rows.T @ U).reshape(law.reference.shape))


def start_increment(ctx: Context, base: np.ndarray, fixed: np.ndarray | None) -> np.ndarray:
    """The first iterate X^0 of the increment (n,): 0 (the level itself), the prescribed increment on the Dirichlet
    dofs, so that no iterate, full or partial, moves them off their values.  (A Taylor predictor dt V + dt^2/2 A was
    measured and left out: 5.5 against 5.9 iterations per step on a spinning puck, but on a block turning a quarter
    turn in 6 steps it led the iterates into an inverted cell, docs/finite_strain.md.)"""
    X = np.zeros_like(base)
    if fixed is not None:
        X[ctx.fixed] = fixed - base[ctx.fixed]
    return X


class _Potential:
    """phi(a) = Pi(X + a d) - Pi(X) of a minimizing step (module docstring) along one direction d [energy]:

        Pi(X) = 1/2 X.(c_M M + c C) X + c_S W(U_base + X) - rest.X,

    the mass part from the products M X and M d (exact in the increment), W the stored energy (``energy``).  Made
    only for a line search: W is evaluated there, not at every iteration."""

    def __init__(
        self,
        ctx: Context,
        op: Operator,
        energy: Callable,
        base: np.ndarray,
        X: np.ndarray,
        d: np.ndarray,
        rest: np.ndarray,
        gU: np.ndarray,
    ):
        self.ctx, self.op, self.rest = ctx, op, rest
        self.energy, self.base, self.X, self.d, self.c = energy, base, X, d, op.stiffness
        Md = _mass_part(ctx, op, d)
        self.linear = float(d @ _mass_part(ctx, op, X)) - float(rest @ d)  # the slope's part outside W
        self.quadratic = 0.5 * float(d @ Md)
        #: grad Pi . d, the slope at a = 0 (negative for a descent direction)
        self.slope = self.linear + self.c * float(gU @ d)
        self.W0 = energy(base + X)

    def total(self, X: np.ndarray) -> float:
        """Pi(X) itself [energy] (the non-monotone search's reference: the largest over the last iterates)."""
        inertia = 0.5 * float(X @ _mass_part(self.ctx, self.op, X))
        return inertia + self.c * self.energy(self.base + X) - float(self.rest @ X)

    def __call__(self, a: float) -> tuple[float, float]:
        """(phi(a), its round-off) [energy]; +inf where a cell inverts."""
        try:
            Wa = self.energy(self.base + self.X + a * self.d)
        except InvertedCellError:
            return np.inf, 0.0
        value = a * self.linear + a * a * self.quadratic + self.c * (Wa - self.W0)
        noise = ROUNDOFF * (self.c * (abs(Wa) + abs(self.W0)) + abs(a * self.linear) + a * a * abs(self.quadratic))
        return value, noise


def newton_solve(
    ctx: Context,
    op: Operator,
    base: np.ndarray,
    rest: np.ndarray,
    force: Callable[[np.ndarray], np.ndarray],
    tangent: Callable[..., object],
    bound: FixedBound | FollowingBound,
    fixed: np.ndarray | None,
    law: ContactLaw,
    inertia: np.ndarray | None = None,
    *,
    energy: Callable[[np.ndarray], float] | None = None,
    jacobian: Callable[[np.ndarray], object] | None = None,
    configuration: Callable[[np.ndarray], np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray, StepInfo]:
    """Solve the nonlinear step of the module docstring, whose right-hand side is c_M M U_base + ``rest``, from
    the level ``base`` = U_base (n,).

    The unknown is the increment X = U - U_base (:func:`residual_norm`), started at 0 (:func:`start_increment`).
    Each iteration solves for the direction d, (c_M M + c_S G_k) d = -r(U^k) + B^T lambda with
    B d <= bound - B U^k (the same contact problem; lambda the whole multiplier).  ``op``: the step's
    linear operator (its coefficients c_M, c_S; its S is replaced by each tangent); ``force(U)`` g(U) (n,)
    and ``tangent(U, project=False)`` dg/dU (sparse, n x n; ``project``: each cell's tangent made positive
    semi-definite).  ``energy(U)``: the stored energy W whose gradient g is (a step that minimizes Pi,
    :class:`_Potential`: Armijo backtracking on Pi), or None (energy-momentum: backtracking on |r|).  ``bound``:
    the rows' bound at an iterate, :class:`~.current_rows.FixedBound` (the gaps) or (contact in the current
    configuration) :class:`~.current_rows.FollowingBound`, which moves the rows to the iterate and returns their
    bound; then (``bound.moves``) the iterations also wait for the linearized gaps to be the true ones (to
    ``GAP_TOLERANCE`` touch tolerances, or their round-off).  ``inertia``: the
    inertial part M q of ``rest``.  ``jacobian(U)``: the exact dg/dU (not symmetric) when ``tangent`` only
    approximates it (energy-momentum); the directions are then taken from it once the step needs a tangent of
    its own (:meth:`_Factor.exact`).  ``configuration(U)``: the displacement at which ``tangent(U)`` evaluates the
    body's tangent (energy-momentum: the midpoint), None: U itself; a kept tangent is turned with its bodies
    from there to the step's (:mod:`~.turning`).  Returns U (n,), lambda (nc,) and the last contact solve's info
    with ``nonlinear_iterations`` (the Newton iterations) set."""
    modified = ctx.solver_options.get("tangent", "modified") == "modified"
    # a tangent kept across levels (serial: a checkpoint records it, :mod:`~..restart.protocol`) serves while it
    # contracts; a step it does not serve starts again with its own operator (its iterates dropped)
    # (a petsc backend on one process holds its operators by rows, as on several ranks: not kept there either)
    carry = modified and ctx.comm.size == 1 and not isinstance(ctx.M, RowBlock)
    if not carry and ctx.factors.kept:  # another tangent policy (a resume with tangent=full): no longer of use
        ctx.factors.drop_kept()
    kept = ctx.factors.kept_for(op) if carry else None
    where = (lambda U: U) if configuration is None else configuration
    args = (ctx, op, base, rest, force, tangent, bound, fixed, law, inertia, energy, jacobian, where)
    if kept is not None:
        ctx.elastic.kept_tangent_steps += 1
        try:
            U, lam, info = _iterate(args, kept=kept, carry=carry)
        except (_Abandoned, ConvergenceError) as exc:
            ctx.elastic.kept_tangent_restarts += 1
            most = int(ctx.solver_options.get("newton_max", 25))
            spent = int(getattr(exc, "iterations", most))  # the iterations of the attempt dropped
            ctx.factors.drop_kept()  # it did not serve: the next steps do not try it again
        else:
            _served(ctx.factors, info.nonlinear_iterations)
            return U, lam, info
        U, lam, info = _iterate(args, kept=None, carry=carry)
        info.nonlinear_iterations += spent  # the step's work: the iterations dropped too
        return U, lam, info
    return _iterate(args, kept=None, carry=carry)


def _served(factors, iterations: int) -> None:
    """The kept tangent served a step in ``iterations``: it is dropped (the next step makes its own) when that is
    more than the mean cost of its steps so far, (KEPT_FACTORIZATION + the iterations of its steps) / its steps,
    the step that made it included: a tangent growing stale would raise that mean."""
    steps, total = factors.kept_use
    steps, total = steps + 1, total + iterations
    if iterations > (KEPT_FACTORIZATION + total) / steps:
        factors.drop_kept()
    else:
        factors.kept_use = (steps, total)


class _Abandoned(Exception):
    """A step started with a kept tangent needs an operator of its own: it starts again without the kept one
    (``iterations``: those dropped; a :class:`~signorini.errors.ConvergenceError` raised within the iterations
    carries them too)."""

    def __init__(self, iterations: int):
        super().__init__(iterations)
        self.iterations = iterations


def _iterate(args: tuple, *, kept: Operator | None, carry: bool) -> tuple[np.ndarray, np.ndarray, StepInfo]:
    """The iterations of :func:`newton_solve`, started with the tangent ``kept`` from a level before (abandoned,
    :class:`_Abandoned`, where it needs renewing) or with the step's own operator; ``carry``: the step's last
    plain tangent is kept for the next levels.  ``args``: :func:`newton_solve`'s, in its order."""
    ctx, op, base, rest, force, tangent, bound, fixed, law, inertia, energy, jacobian, where = args
    opts = ctx.solver_options
    tol, most = float(opts.get("newton_tol", 1e-10)), int(opts.get("newton_max", 25))
    modified = opts.get("tangent", "modified") == "modified"
    elastic = ctx.elastic
    agree = ctx.comm.bcast  # every branch below on rank 0's values (module docstring: several ranks)
    X = start_increment(ctx, base, fixed)
    U = base + X
    gU = force(U)
    lam = lam_t = None
    previous = np.inf
    norm = scale = allowed = np.nan
    full = True
    D = ctx.fixed
    # the residual's contact force through the rows of the iterate (the current configuration's move with it)
    through = bound.contact_force
    # a step that starts near the reference configuration starts with the scheme's own linear operator (factorized
    # at set-up): no factorization while it contracts (a mass-dominated impact's steps)
    reference = modified and agree(bool(elastic.displacement_gradient(base) <= REFERENCE_GRADIENT))
    factor = _Factor(ctx, op, tangent, bound, elastic, jacobian, where)
    if kept is not None:  # its first step is held to KEPT_CONTRACTION of |r| at the level (no contact force)
        factor.current, factor.carried, reference = kept, True, False
        factor.turn_to(where(base))
        norm = agree(residual_norm(ctx, op, X, rest, gU, U, np.zeros(ctx.rows.B.shape[0]), None, inertia, through)[0])
    converged = 0  # the iterations of a converged step
    accel = Anderson(ctx.free) if opts.get("acceleration", "anderson") == "anderson" else None
    recent = [X]  # the last iterates (the non-monotone search's reference: the largest Pi among them)
    keep = False  # the operator was just corrected at this iterate: no renewal before its direction
    k = 0
    try:
        for k in range(1, most + 1):
            if keep:  # corrected at this iterate already (a fresh operator)
                refactor, keep = True, False
            else:
                refactor = factor.current is None or not modified or not full or _renew(norm, previous, allowed)
                if refactor and factor.carried:
                    raise _Abandoned(k - 1)
                if refactor:
                    factor.renew(U, lam, use_reference=k == 1 and reference)
            bnd = bound(U)
            # the slip measured in the frames of the rows just moved to U; the rows that face nothing left out
            law_k = _shifted(bound.law(law), ctx, U)
            minus_r = rest - _mass_part(ctx, op, X) - op.stiffness * gU
            slack = bnd - ctx.rows.B @ U
            feasible = energy is not None and agree(bool(np.all(slack >= -ctx.touch_tolerance)))
            fixed_d = None if fixed is None else np.zeros(D.size)
            d, lam_new, info, renewed = factor.direction(k, minus_r, slack, fixed_d, law_k, U, lam)
            fresh = refactor or renewed
            lam0 = np.zeros_like(lam_new) if lam is None else lam
            lt0 = None if info.lam_t is None else (np.zeros_like(info.lam_t) if lam_t is None else lam_t)
            lt1 = info.lam_t

            def along(d: np.ndarray, lam1: np.ndarray, lam0=lam0, lt0=lt0, lt1=lt1, X=X) -> Callable:
                """The trial of a step length along d whose solve gave the multiplier ``lam1``."""

                def trial_at(s: float):
                    """(X, U, g, lambda, lambda_t, |r|, scale, floor) s along d, or None where a cell inverts."""
                    Xs = X + s * d
                    Us = base + Xs
                    try:
                        gs = force(Us)
                    except InvertedCellError:
                        return None
                    ls = lam1 if s == 1.0 else lam0 + s * (lam1 - lam0)
                    lts = lt1 if s == 1.0 or lt0 is None else lt0 + s * (lt1 - lt0)
                    norms = agree(residual_norm(ctx, op, Xs, rest, gs, Us, ls, lts, inertia, through))
                    return (Xs, Us, gs, ls, lts, *norms)

                return trial_at

            plain = None
            if accel is not None:
                # a new operator, friction, or the corrected tangent (whose directions may be the plain tangent's with
                # the active set held, :meth:`_Factor.kkt`): the history starts here
                own = info.lam_t is None and not factor.corrected
                if fresh or not own or factor.unturned:
                    accel.reset()
                    factor.unturned = False
                mixed = accel.mix(X, d, lam_new, agree) if own else None
                if mixed is not None and agree(_admissible(ctx, law_k, mixed, slack, bound.moves)):
                    plain, (d, lam_new) = (d, lam_new), mixed
            at = along(d, lam_new)
            a, trial = 1.0, at(1.0)
            # the mixed iterate must lower |r| as a kept operator's step must (else taken back, a tangent made)
            enough = norm if fresh else KEPT_CONTRACTION * norm
            if plain is not None and (trial is None or not trial[5] <= enough):  # the mixed iterate did not help
                accel.reset(keep_last=True)
                d, lam_new = plain
                at = along(d, lam_new)
                a, trial = 1.0, at(1.0)
            elif plain is not None:
                accel.taken += 1
            while trial is None:  # the full step inverts a cell: back along d until none is
                if a < 0.5**BACKTRACKS:
                    force(base + X + a * d)  # raises the inverted cell's error, naming it
                a *= 0.5
                elastic.line_search_steps += 1
                trial = at(a)
            n_new, scale, floor = trial[5:]
            allowed = tol * scale + floor
            if lam is not None and fresh and n_new > allowed and n_new > STALLED * norm:
                # no longer falling: at the internal force's own round-off (a body far from its reference place)
                # the iterate is converged as far as the force can tell
                noise = agree(op.stiffness * elastic.force_noise(trial[1]))
                if n_new <= noise:
                    allowed = n_new
            if (
                (lam is not None or factor.carried)
                and not fresh
                and n_new > allowed
                and not n_new <= KEPT_CONTRACTION * norm
            ):
                full = False  # a kept tangent's step that does not halve |r|: taken back, the tangent renewed here
                continue
            # |r| does not fall (at the first iterate: below |r| there, without contact force): a line search
            if n_new > allowed and not n_new < (
                norm
                if lam is not None
                else agree(
                    residual_norm(ctx, op, X, rest, gU, U, np.zeros(ctx.rows.B.shape[0]), None, inertia, through)[0]
                )
            ):
                if feasible and factor.owned and not agree(factor.convex_along(d)):
                    # a tangent with a negative curvature along d (an indefinite cell): corrected at U, and the
                    # direction taken again
                    factor.correct(k, "has a negative curvature along its Newton direction", U, lam)
                    keep, full = True, True
                    continue
                if feasible:
                    phi = _Potential(ctx, op, energy, base, X, d, rest, gU)
                    here = phi.total(X)
                    allowance = max([0.0] + [phi.total(Y) - here for Y in recent[:-1]])
                    b = _armijo(phi, elastic, a, allowance, agree)
                elif lam is not None:  # energy-momentum: halvings on |r|
                    b = _halvings(lambda b, at=at: np.inf if (x := at(b)) is None else x[5], norm, elastic, a)
                else:
                    b = a
                if b < a:
                    shorter = at(b)
                    if shorter is not None:
                        a, trial = b, shorter
            full = a == 1.0
            X_new, U_new, g_new, lam_new, info.lam_t, n_new = trial[:6]
            previous, norm = norm, n_new
            slow = 0 < previous < np.inf and norm > EXACT_RATE * previous
            if fresh and factor.jacobian is not None and factor.owned and slow:  # not the Jacobian: the exact one
                factor.exact_wanted = True
            X, U, lam, lam_t, gU = X_new, U_new, lam_new, info.lam_t, g_new
            recent = [*recent[1 - NONMONOTONE :], X]
            if k == 1 and full and factor.turnable:  # turned to the level: now to the first iterate
                factor.turn_to(where(U))
                if accel is not None:
                    accel.reset()
            gaps_ok = not bound.moves or agree(bool(bound.converged(U)))
            solved = not info.residual > MAX_CONTACT_RESIDUAL  # a contact solve short of complementarity: go on
            if full and norm <= allowed and gaps_ok and solved:
                info.nonlinear_iterations = k
                info.force_residual = _force_residual(ctx, op, X, rest, gU, U, lam, lam_t, through)
                converged = k
                return U, lam, info
    except ConvergenceError as exc:  # an inverted cell, a solve that failed: after k iterations
        exc.iterations = k
        raise
    finally:
        if converged and carry and factor.owned and not factor.corrected:  # the step's own tangent, kept
            ctx.factors.keep(factor.current, (1, converged))
            factor.current, factor.owned = None, False
        factor.release()
        if accel is not None:
            elastic.accelerated_iterations += accel.taken
    if norm <= allowed:  # the forces balance; the rows of the current configuration did not settle
        raise ConvergenceError(
            f"Newton's method did not converge in {most} iterations: the forces balance (residual {norm / scale:.3g} "
            f"of its scale, newton_tol = {tol:g}) but the contact rows of the current configuration did not settle "
            "(their linearized gaps are not the true ones: a node alternating between facets, or a large rotation "
            "within the step); reduce the step, or raise newton_max"
        )
    rate = norm / previous if np.isfinite(previous) and previous > 0 else np.nan
    raise ConvergenceError(
        f"Newton's method did not converge in {most} iterations (force residual {norm:.3g}, {norm / scale:.3g} of "
        f"its scale against newton_tol = {tol:g}, falling by a factor {rate:.3g} in the last iteration); "
        + _remedy(ctx, rate)
    )


def _remedy(ctx: Context, rate: float) -> str:
    """What to change after a step that did not converge: the cause the residual's last rate points to."""
    free_massless = np.setdiff1d(ctx.massless, ctx.fixed).size
    n_free = ctx.free.size
    if ctx.velocity_space is not None:  # mixed-velocity: the directions without inertia are ker W_f
        free_massless = n_free - ctx.velocity_space.W.shape[0]
    if np.isfinite(rate) and rate > STALLED:
        why = "the residual stalled (not a slow convergence: more iterations will not help)"
        if free_massless and free_massless > n_free // 2:
            return (
                f"{why}; the mass {ctx.disc.mass_name!r} leaves {free_massless} of {n_free} free "
                f"{'directions' if ctx.velocity_space is not None else 'dofs'} without "
                "inertia: use mass 'lumped' or 'standard', or refine the mesh under the contact skin"
            )
        return f"{why}; raise newton_tol to the residual's level, or reduce the step"
    return "the residual was still falling: raise newton_max, or reduce the step"


#: Armijo's sufficient decrease phi(a) <= c a phi'(0)
ARMIJO = 1e-4
#: the most halvings of a line search
BACKTRACKS = 12
#: the line search's reference is the largest Pi of the last NONMONOTONE iterates (Grippo, Lampariello and Lucidi
#: 1986): a full Newton step may raise Pi above the last iterate's on its way to a minimum (a large rotation)
NONMONOTONE = 4


def _armijo(phi: _Potential, elastic, a: float = 1.0, allowance: float = 0.0, agree: Callable = lambda x: x) -> float:
    """The step length a of a backtracking line search on the potential: the first of a, a/2, a/4, ... with
    phi(a) <= ARMIJO a phi'(0) (or, when the decrease is below the potential's round-off, the first that does not
    raise it beyond that round-off); ``a`` itself when d is not a descent direction.  ``allowance``: how far phi
    may rise above the last iterate's Pi (the non-monotone reference)."""
    if not agree(bool(phi.slope < 0.0)):  # each decision on rank 0's values (several ranks)
        return a
    for _ in range(BACKTRACKS):
        value, noise = phi(a)
        if agree(bool(value <= allowance + ARMIJO * a * phi.slope or (abs(a * phi.slope) <= noise and value <= noise))):
            return a
        a *= 0.5
        elastic.line_search_steps += 1
    return a


def _halvings(norm_at: Callable[[float], float], norm: float, elastic, a: float = 1.0) -> float:
    """The step length of at most :data:`LINE_SEARCH_HALVINGS` halvings of ``a`` that lowers |r| below ``norm`` (a
    step that does not minimize a potential: energy-momentum)."""
    for _ in range(LINE_SEARCH_HALVINGS):
        a *= 0.5
        elastic.line_search_steps += 1
        if norm_at(a) < norm:
            break
    return a


class _Factor:
    """The operator of a step's Newton directions: the scheme's own (reference) operator, a kept tangent or a fresh
    one; corrected (each cell's tangent positive semi-definite, then a diagonal shift) when it cannot be factorized
    or has a negative curvature along a direction that did not lower |r|."""

    #: shifts tau of the corrected tangent's diagonal shift tau diag(S) (S the reference stiffness)
    SHIFTS = (1e-3, 1e-1, 1e1)

    def __init__(
        self,
        ctx: Context,
        op: Operator,
        tangent: Callable,
        bound,
        elastic,
        jacobian: Callable | None = None,
        configuration: Callable[[np.ndarray], np.ndarray] = lambda U: U,
    ):
        self.ctx, self.op, self.tangent, self.bound, self.elastic = ctx, op, tangent, bound, elastic
        #: the displacement at which ``tangent(U)`` evaluates the body's tangent (newton_solve's ``configuration``)
        self.configuration = configuration
        self.jacobian = jacobian
        #: whether a fresh tangent contracted |r| by less than EXACT_RATE: the directions of the rest of the step
        #: are the exact Jacobian's (:meth:`exact`)
        self.exact_wanted = False
        self.current: Operator | None = None
        self.owned = False  # whether ``current`` is this step's tangent (released after it), not the scheme's
        #: whether ``current`` is the tangent kept from a level before (``Factorizations.keep``; not released here)
        self.carried = False
        self.corrected = False  # whether ``current`` is the corrected tangent (projected per cell, maybe shifted)
        self.shift = 0
        #: the rotation of each body since a kept tangent was made (:mod:`~.turning`), None: used as it is
        self.turn: np.ndarray | None = None
        #: whether the kept tangent turns with its bodies in this step (re-aimed at its first iterate)
        self.turnable = False
        #: a turned direction fell back to the kept tangent as it is at this iterate (the mixing restarts)
        self.unturned = False
        self._plain: tuple[np.ndarray, sp.csr_matrix | RowBlock] | None = None  # (U, the plain tangent at U)

    def renew(
        self, U: np.ndarray, lam: np.ndarray | None, use_reference: bool = False, corrected: bool = False
    ) -> None:
        """A new operator at U (the reference one when ``use_reference``); ``corrected``: the corrected tangent
        (else the plain one: a correction holds for the operator it was made for, so that Newton converges
        quadratically again where the tangent is definite)."""
        self.release()
        self.carried, self.turn, self.turnable = False, None, False
        if not corrected:
            self.corrected, self.shift = False, 0
        if use_reference:
            self.current, self.owned = self.op, False
            return
        G = self.assembled(U, lam, project=self.corrected)
        if self.corrected:
            self.elastic.tangent_corrections += 1
        if self.shift:
            G = _plus(G, self.SHIFTS[self.shift - 1] * sp.diags(self.ctx.S.diagonal()))
        op = self.op
        made = Tangent(G, at=np.array(self.configuration(U)))  # where: it turns with its bodies from there when kept
        self.current, self.owned = Operator(op.mass, op.stiffness, made, op.viscous), True
        self.elastic.factorizations += 1

    def assembled(
        self, U: np.ndarray, lam: np.ndarray | None, project: bool = False, exact: bool = False
    ) -> sp.csr_matrix | RowBlock:
        """G(U) (``project``: each cell's part PSD; ``exact``: the exact Jacobian ``jacobian``) plus the rows' own
        turning under the multipliers ``lam`` of the iterate, Kc / c_S; the plain one is kept for its iterate (the
        KKT direction asks for it again after a correction at the same U)."""
        if exact:
            G = self.jacobian(U)
            Kc = self.bound.geometric_stiffness(U, lam) if lam is not None else None
            return G if Kc is None else _plus(G, Kc / self.op.stiffness)
        if not project and self._plain is not None and self._plain[0] is U:
            return self._plain[1]
        G = self.tangent(U, project=True) if project else self.tangent(U)
        bound = self.bound
        Kc = bound.geometric_stiffness(U, lam) if lam is not None else None
        if Kc is not None:  # the rows' own turning under the multipliers of the last iterate
            G = _plus(G, Kc / self.op.stiffness)
        if not project:
            self._plain = (U, G)
        return G

    def release(self) -> None:
        if self.owned:
            self.ctx.factors.release(self.current)
        self.current, self.owned = None, False

    def correct(self, k: int, why: str, U: np.ndarray, lam: np.ndarray | None) -> None:
        """Renew the operator at U, corrected one degree further (projection, then shifts)."""
        if not self.corrected:
            self.corrected = True
        elif self.shift < len(self.SHIFTS):
            self.shift += 1
        else:
            raise ConvergenceError(
                f"the tangent of Newton iterate {k} {why}, even with each cell's tangent made positive "
                "semi-definite and a diagonal shift (an unstable state: buckling, or a material driven beyond its "
                "stability); reduce the step"
            )
        self.renew(U, lam, corrected=True)

    def convex_along(self, d: np.ndarray) -> bool:
        """Whether d.H d > 0 for the operator H = c_M M + c C + c_S G (d = 0 counts as convex), G the tangent of
        :attr:`current` (a distributed tangent by rows is not checked: its factorization fails when it is
        indefinite, a Cholesky one)."""
        G = None if self.current.tangent is None else self.current.tangent.matrix
        if G is None or isinstance(G, RowBlock) or not np.any(d):
            return True
        curvature = float(d @ _mass_part(self.ctx, self.op, d)) + self.op.stiffness * float(d @ (G @ d))
        return curvature > 0.0

    def direction(
        self,
        k: int,
        minus_r: np.ndarray,
        slack: np.ndarray,
        fixed_d: np.ndarray | None,
        law: ContactLaw,
        U: np.ndarray,
        lam: np.ndarray | None,
    ):
        """(d, lambda, info, renewed): the Newton direction d (n,), the whole multiplier and the solve's info, the
        operator corrected (renewed at U) until it factorizes and its contact problem is solved."""
        renewed = False
        if self.turn is not None:
            turned = self.turned(minus_r, slack, fixed_d, law)
            if turned is not None:
                return (*turned, False)
            # a row reached: the kept tangent as it is, with its contact solve (another operator: the mixing restarts)
            self.turn, self.unturned = None, True
        while True:
            try:
                d, lam_new, info = self.ctx.solve(self.current, minus_r, slack, fixed_d, law)
            except (InputError, np.linalg.LinAlgError, ArithmeticError):  # the tangent (or its Delassus operator)
                # cannot be factorized: not the set-up's input
                if self.carried:
                    raise _Abandoned(k - 1) from None
                if not self.owned:
                    raise
                self.correct(k, "cannot be factorized: it is not positive definite", U, lam)
                renewed = True
                continue
            if (
                (self.owned or self.carried)
                and not self.corrected
                and self.ctx.comm.bcast(bool(info.residual > MAX_CONTACT_RESIDUAL))
            ):
                # a plain tangent whose contact problem has no solution its solver finds (an indefinite Delassus
                # operator: bar3d with the standard mass in contact): its direction would leave rows violated
                if self.carried:
                    raise _Abandoned(k - 1)
                self.correct(k, "gives a contact problem that cannot be solved", U, lam)
                renewed = True
                continue
            exact = self.jacobian is not None and (self.exact_wanted or self.corrected)
            if exact and self.owned and _kkt_ok(self.ctx, law, info, rows=False):
                exact = self.exact(U, lam, lam_new, minus_r, slack, fixed_d, law)
                if exact is not None:
                    d, lam_new = exact
                    renewed = True  # a direction of the exact Jacobian at U: as a fresh tangent's
            elif self.corrected and lam is not None and _kkt_ok(self.ctx, law, info):
                kkt = self.kkt(U, lam, lam_new, minus_r, slack, fixed_d, law)
                if kkt is not None:
                    d, lam_new = kkt
            return d, lam_new, info, renewed

    def turn_to(self, where: np.ndarray) -> None:
        """Turn the kept tangent (:attr:`current`) with its bodies to the configuration ``where`` (n,): the
        rotation of each body since it was made (:mod:`~.turning`); none when it does not apply."""
        made, turning = self.current.tangent.at, self.ctx.turning
        self.turnable = made is not None and turning is not None
        self.turn = turning.rotations(made, where) if self.turnable else None

    def turned(
        self, minus_r: np.ndarray, slack: np.ndarray, fixed_d: np.ndarray | None, law: ContactLaw
    ) -> tuple[np.ndarray, np.ndarray, StepInfo] | None:
        """(d, lambda = 0, info) of the kept tangent turned with its bodies, d = Q K_k^-1 Q^T (-r) (:mod:`~.turning`),
        when d reaches no contact row (B d <= slack: then lambda = 0 solves the contact problem of the turned
        operator); None when a row is reached."""
        ctx = self.ctx
        turning = ctx.turning
        d = turning.turn(self.turn, ctx.solve_linear(self.current, turning.turn(self.turn, minus_r, True), fixed_d))
        q = slack - ctx.rows.B @ d
        if law.subset is not None:
            q = q[law.subset]
        if not ctx.comm.bcast(bool(np.all(q >= 0.0))):
            return None
        nc = ctx.rows.B.shape[0]
        return d, np.zeros(nc), StepInfo(0, False, 0.0, np.zeros(nc, dtype=bool))

    def exact(
        self,
        U: np.ndarray,
        lam: np.ndarray | None,
        lam_new: np.ndarray,
        minus_r: np.ndarray,
        slack: np.ndarray,
        fixed_d: np.ndarray | None,
        law: ContactLaw,
    ) -> tuple[np.ndarray, np.ndarray] | None:
        """The Newton direction of the exact Jacobian J(U) (``jacobian``, not symmetric) with the active set of the
        symmetric tangent's direction held (the empty one too), or else the last iterate's, (d, lambda); None when
        each answer leaves the contact conditions (a multiplier that pulls, a free row through its bound).

        A scheme whose tangent only approximates its Jacobian (energy-momentum: 1/2 K(U_mid) for the derivative
        of the discrete gradient) converges linearly with it, at a rate that grows with the step's rotation and
        strain (measured: 0.46 per iteration at `spin3d`'s doubled step, 0.5 in `bar3d`'s contact), and no longer
        converges beyond; the exact Jacobian in the system of :meth:`kkt` (one sparse LU) converges
        quadratically.  Taken only once a fresh tangent of the step contracted slowly (:data:`EXACT_RATE`) or had to
        be corrected (indefinite: the bar's contact): a step
        that the scheme's linear operator, a kept tangent or its fresh symmetric tangent solves fast does not pay an
        LU per iteration."""
        H = self._hessian(self.assembled(U, lam, exact=True))  # once for the active sets tried below
        sets = [np.flatnonzero(lam_new < 0.0)]
        if lam is not None and not np.array_equal(sets[0], last := np.flatnonzero(lam < 0.0)):
            sets.append(last)
        for active in sets:
            out = self._held(H, active, lam_new, minus_r, slack, fixed_d, law)
            if out is not None:
                self.elastic.exact_directions += 1
                return out
        return None

    def kkt(
        self,
        U: np.ndarray,
        lam: np.ndarray,
        lam_new: np.ndarray,
        minus_r: np.ndarray,
        slack: np.ndarray,
        fixed_d: np.ndarray | None,
        law: ContactLaw,
    ) -> tuple[np.ndarray, np.ndarray] | None:
        """The Newton direction of the plain (indefinite) tangent with the active set held, (d, lambda), when the
        corrected direction's active set is the last iterate's and not empty; None when it is not, or the answer
        leaves the contact conditions (a multiplier that pulls, a free row through its bound).

        Where the step's Hessian H = c_M M + c_S G is indefinite at the solution (a body compressed against an
        obstacle whose contact face has no inertia: the geometric stiffness of its compressed cells), the corrected
        tangent converges at a linear rate (measured: 0.5 on ``bar3d`` with Neo-Hookean) and the plain one cannot
        be condensed (its Delassus operator B H^-1 B^T is indefinite); the active rows hold the directions of
        negative curvature, so the equality-constrained problem

            [ H_ff   -B_Af^T ] [ d_f      ]   [ -r_f     ]
            [ B_Af    0      ] [ lambda_A ] = [ slack_A  ]

        is regular, and its sparse LU gives Newton's quadratic convergence back (once the active set has settled)."""
        active = np.flatnonzero(lam_new < 0.0)
        if not active.size or not np.array_equal(active, np.flatnonzero(lam < 0.0)):  # no rows: no constraint holds
            # a direction of negative curvature (the corrected direction is the one that descends)
            return None
        out = self._held(self._hessian(self.assembled(U, lam)), active, lam_new, minus_r, slack, fixed_d, law)
        if out is not None:
            self.elastic.kkt_directions += 1
        return out

    def _hessian(self, G: sp.spmatrix) -> sp.csr_matrix:
        """H = c_M M (+ c C) + c_S G (n, n), the step's matrix with the tangent or Jacobian G."""
        H = self.op.mass * self.ctx.M + self.op.stiffness * G
        if self.op.viscous is not None:
            H = H + self.op.viscous.coefficient * self.op.viscous.matrix
        return sp.csr_matrix(H)

    def _held(
        self,
        H: sp.csr_matrix,
        active: np.ndarray,
        lam_new: np.ndarray,
        minus_r: np.ndarray,
        slack: np.ndarray,
        fixed_d: np.ndarray | None,
        law: ContactLaw,
    ) -> tuple[np.ndarray, np.ndarray] | None:
        """(d, lambda) of the system of :meth:`kkt` with the step's matrix H (:meth:`_hessian`) and the rows
        ``active`` held at their bound (one sparse LU); None when it is singular, or its multipliers pull, or a free
        row goes through its bound."""
        ctx = self.ctx
        B = sp.csr_matrix(ctx.rows.B)
        f, D = ctx.free, ctx.fixed
        d = np.zeros_like(minus_r)
        if D.size and fixed_d is not None:
            d[D] = fixed_d
        BA = B[active]
        if D.size:
            Hf = H[f]
            rhs, gA = minus_r[f] - Hf[:, D] @ d[D], slack[active] - BA[:, D] @ d[D]
            Hff, BAf = Hf[:, f], BA[:, f]
        else:
            rhs, gA, Hff, BAf = minus_r[f], slack[active], H, BA
        A = sp.bmat([[Hff, -BAf.T], [BAf, None]], format="csc")
        try:
            x = sp.linalg.spsolve(A, np.concatenate([rhs, gA]))
        except (RuntimeError, np.linalg.LinAlgError, ArithmeticError):
            return None
        if not np.all(np.isfinite(x)):
            return None
        d[f] = x[: f.size]
        out = np.zeros_like(lam_new)
        out[active] = x[f.size :]
        held = np.zeros(out.size, dtype=bool)
        held[active] = True
        if not _keeps_contact(ctx, law, B @ d, out, slack, held, float(np.max(np.abs(lam_new), initial=0.0))):
            return None
        return d, out


def _admissible(
    ctx: Context, law: ContactLaw, mixed: tuple[np.ndarray, np.ndarray], slack: np.ndarray, moves: bool = False
) -> bool:
    """Whether an accelerated (d, lambda) (:mod:`~.anderson`) keeps the contact conditions of the rows at the
    iterate: no multiplier pulls (beyond the round-off of the largest) and no free row goes through its bound
    (beyond the touch tolerance); with rows that move with the iterate (``moves``: the current configuration, whose
    rows and bounds differ from one iterate to the next, so that a combination of iterates need not hold its active
    rows) the active rows at their bound too."""
    d, lam = mixed
    active = lam < 0.0
    Bd = ctx.rows.B @ d
    if not _keeps_contact(ctx, law, Bd, lam, slack, active, float(np.max(np.abs(lam), initial=0.0))):
        return False
    return not (moves and bool(np.any(np.abs(Bd[active] - slack[active]) > ctx.touch_tolerance)))


def _keeps_contact(
    ctx: Context,
    law: ContactLaw,
    Bd: np.ndarray,
    lam: np.ndarray,
    slack: np.ndarray,
    active: np.ndarray,
    scale: float,
) -> bool:
    """Whether a direction d (its row values ``Bd`` = B d) with multipliers ``lam`` (nc,) keeps the contact
    conditions at the iterate: no multiplier pulls beyond :data:`ROUNDOFF` ``scale`` and no free row (outside the
    boolean ``active``, within the law's ``subset``) goes through its bound ``slack`` beyond the touch tolerance."""
    if np.any(lam > ROUNDOFF * scale):
        return False
    free = ~active if law.subset is None else np.asarray(law.subset, dtype=bool) & ~active
    return not bool(np.any(Bd[free] - slack[free] > ctx.touch_tolerance))


def _kkt_ok(ctx: Context, law: ContactLaw, info: StepInfo, rows: bool = True) -> bool:
    """Whether a step's direction may be taken from the plain tangent with the active set held (:meth:`_Factor.kkt`):
    frictionless exact contact on one process (a distributed or frictional system is not assembled whole), after a
    contact solve that reached complementarity (its active set is the one to hold); ``rows``: with contact rows."""
    return (
        ctx.rows.components == 1
        and law.compliance is None
        and info.lam_t is None
        and not isinstance(ctx.M, RowBlock)
        and (ctx.rows.B.shape[0] > 0 or not rows)
        and bool(info.residual <= MAX_CONTACT_RESIDUAL)
    )


def _plus(G: sp.csr_matrix | RowBlock, K: sp.spmatrix) -> sp.csr_matrix | RowBlock:
    """G + K (n, n); G by rows (a distributed backend's tangent): this rank's rows of the sum."""
    if isinstance(G, RowBlock):
        return RowBlock((G.local + sp.csr_matrix(K)[G.lo : G.hi]).tocsr(), G.bounds, G.comm)
    return (G + K).tocsr()

"""One implicit step as one problem in the increment, and the one solver that solves it.

Every implicit scheme (Newmark and Crank-Nicolson, theta and backward Euler, HHT and generalized-alpha,
energy-momentum, the penalty) states its step as

    c_M M dU + c_C C dU + c_S g(U^n + dU) = M q + F - C d + B^T lambda,     dU = U^{n+1} - U^n,
    B U^{n+1} <= bound  ⊥  lambda (the step's contact law),   U^{n+1} = U_D(t_{n+1}) on the Dirichlet dofs,

with its weights (c_M, c_S: :meth:`Scheme.operator`; c_C: :meth:`Scheme.damping_coefficient`), its
inertia predictor q (the right-hand side's inertial part is M q), its known forces F (loads, the lagged
forces of a weighted balance), its damping offset d (Rayleigh C, or None) and its internal force g: the
body's f (the default) or the scheme's own (energy-momentum's discrete gradient on the rows with mass).
:func:`solve_step` solves it: when the internal force is linear (g(U) = S U + const, rows that do not move)
in one linear complementarity solve of the step operator; otherwise by Newton's method
(:func:`~..newton.newton_solve`, rows in the current configuration moving with each iterate).  No scheme
branches on the material model.

The linear case is Newton's first iteration written for U^{n+1} itself (not the increment): an iterative
backend's relative tolerance applies to the whole right-hand side, as before the step had this form, and
the histories keep their round-off,

    (c_M M + c_C C + c_S S) U^{n+1} = M (q + c_M U^n) + F - C (d - c_C U^n) - c_S (g(U^n) - S U^n)

(q + c_M U^n in the scheme's own form when it gives one, ``StepProblem.total``: Newmark's and theta's
predictor p, so that their linear histories are those of before, bit for bit).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ...contact.solver import ContactLaw, StepInfo
from ..rows.current_rows import contact_bound
from ..solve.newton import newton_solve

if TYPE_CHECKING:
    from ..solve.context import Context
    from .base import Scheme, State


@dataclass
class StepProblem:
    """One implicit step from the level ``level`` to the time ``t`` (module docstring).

    Attributes
    ----------
    scheme, level : the scheme and the level it steps from (U^n = ``level.U``, t_n = ``level.t``).
    t : the new level's time [s].
    q : (n,) the inertia predictor: the right-hand side's inertial part is M q [length / time^2].
    forces : (n,) F, the known forces of the balance [force].
    law : the step's contact law (friction, compliance, restricted rows).
    damping : (n,) d, the damping offset (C d leaves the right-hand side), or None [length / time].
    force : g(U) (n,) -> (n,), the step's internal force when it is not the body's f(U); None: f.
    tangent : dg/dU(U, project=False) when ``force`` is given; None: the body's tangent.
    force_start : (n,) g(U^n) when ``force`` is given (the linear solve's constant; the scheme knows it from
        the level's f(U^n) without evaluating g).
    potential : whether g is the gradient of the body's stored energy (Newton's line search on the step's
        incremental potential); False: a merit function on the residual (energy-momentum).
    jacobian : the exact dg/dU(U) (n, n), not symmetric, when ``tangent`` is a symmetric approximation of it
        (energy-momentum: K(U_mid) for the discrete gradient's Jacobian); Newton takes its directions from it
        where its tangent converges slowly (:meth:`~..solve.newton._Factor.exact`); None: ``tangent`` is exact.
        Unused by the linear solve (one solve, no iteration).
    configuration : the displacement at which ``tangent(U)`` evaluates the body's tangent (energy-momentum: the
        midpoint (U^n + U) / 2); None: U.  A kept tangent turns with its bodies between two of them.
    total : (n,) q + c_M U^n as the scheme computes it in its own form (Newmark's and theta's predictor p), for
        the linear solve; None: q + c_M U^n.  The same vector to round-off: the linear histories keep the
        rounding they had before the steps were stated this way (a run that reaches its obstacle exactly at a
        level, as the paper's bars do, is a tie that round-off decides).
    """

    scheme: Scheme
    level: State
    t: float
    q: np.ndarray
    forces: np.ndarray
    law: ContactLaw
    damping: np.ndarray | None = None
    force: Callable[[np.ndarray], np.ndarray] | None = None
    tangent: Callable[..., object] | None = None
    force_start: np.ndarray | None = None
    potential: bool = True
    total: np.ndarray | None = None
    jacobian: Callable[[np.ndarray], object] | None = None
    configuration: Callable[[np.ndarray], np.ndarray] | None = None


def solve_step(ctx: Context, p: StepProblem) -> tuple[np.ndarray, np.ndarray, StepInfo]:
    """Solve the step ``p`` (module docstring).  Returns U^{n+1} (n,), lambda^{n+1} (nc,) and the contact
    solve's info (with ``nonlinear_iterations`` when Newton iterated)."""
    scheme, s, dt = p.scheme, p.level, ctx.dt
    weights = scheme.operator(dt)
    op = scheme.step_operator(ctx, dt)
    fixed = ctx.dirichlet(p.t) if ctx.has_fixed else None
    el = ctx.elastic
    if el.finite:
        inertia = ctx.Mop @ p.q
        rest = inertia + p.forces
        if p.damping is not None:
            rest = rest - ctx.damping.force(ctx, p.damping)
        force = el.force if p.force is None else p.force
        tangent = el.tangent if p.tangent is None else p.tangent
        energy = el.energy if p.potential else None
        bound = contact_bound(ctx, s.U, s.t, p.t)
        return newton_solve(
            ctx,
            op,
            s.U,
            rest,
            force,
            tangent,
            bound,
            fixed,
            p.law,
            inertia,
            energy=energy,
            jacobian=p.jacobian,
            configuration=p.configuration,
        )
    rhs = ctx.Mop @ (p.q + weights.mass * s.U if p.total is None else p.total) + p.forces
    if p.damping is not None:
        rhs -= ctx.damping.force(ctx, p.damping - scheme.damping_coefficient(dt) * s.U)
    if p.force_start is not None:  # g(U) = S U + (g(U^n) - S U^n)
        f0 = s.product("SU", lambda: el.force(s.U))
        rhs -= weights.stiffness * (p.force_start - f0)
    return ctx.solve(op, rhs, ctx.gaps(p.t), fixed, p.law, functools.partial(scheme.taylor_guess, ctx, s))

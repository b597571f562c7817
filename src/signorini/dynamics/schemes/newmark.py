"""Newmark(beta, gamma) with contact enforced exactly at t_{n+1}; Crank-Nicolson.

    U^{n+1} = U^n + dt V^n + dt^2 ((1/2 - beta) A^n + beta A^{n+1})
    V^{n+1} = V^n + dt ((1 - gamma) A^n + gamma A^{n+1})
    M A^{n+1} + S U^{n+1} = F^{n+1} + B^T lambda^{n+1},   0 >= B U^{n+1} - g ⊥ lambda <= 0

i.e. ``(M/(beta dt^2) + S) U^{n+1} = M p + F^{n+1} + B^T lambda`` with
``p = (U^n + dt V^n)/(beta dt^2) + (1/(2 beta) - 1) A^n``.  The dynamics only sees
``M p``, so singular (redistributed) mass matrices are handled exactly.
``crank-nicolson`` = Newmark(1/4, 1/2), the seed's eq. (8)-(9).

Energy identity (exact, derived in docs/schemes.md), with R = M A + S U - F - B^T lambda
(the reactions on Dirichlet dofs; zero on free dofs except at t = 0 with massless dofs
out of equilibrium) and <x> = (x^n + x^{n+1})/2:

    Delta [1/2 V.MV + 1/2 U.SU - U.F + 1/2 dt^2 (beta - gamma/2) A.MA]
        = dU.<F> - Delta(U.F)          (work of time-dependent loads)
        + dU_D.<R_D>                   (work of the prescribed motion)
        + 1/2 (B dU).(lambda^n + lambda^{n+1})        (contact)
        + 1/2 (T dU).(lambda_t^n + lambda_t^{n+1})    (friction)
        + dt (gamma - 1/2) <V>.M dA + dU_f.<R_f>      (numerical)
        - dU.<C V_d>                                  (damping, and numerical for gamma != 1/2)

With Rayleigh damping C the balance is M A + C V_d + S U = ..., C V_d^{n+1} = c C U^{n+1} + C q
(c = gamma/(beta dt)): the operator gains c C and the right-hand side -C q; V_d is Newmark's
velocity on every dof (:func:`~.base.damping_velocity`: V itself where there is mass).  For CN
<V_d> = dU/dt, so the damping term is -dU.C dU/dt <= 0 (``damping_split``).

For CN the A.MA and dA terms vanish: the seed's identity with a plus sign.
"""

from __future__ import annotations

import numpy as np

from ...contact.solver import SIGNORINI, ContactLaw
from ...registry import Parameter
from ..model.operator import Operator
from .base import (
    EnergyParts,
    Scheme,
    State,
    contact_works,
    damping_split,
    damping_velocity,
    elastic_work_error,
    load_work,
    mechanical_energy,
    reaction_work,
    solver_work,
)
from .step_problem import StepProblem, solve_step


class Newmark(Scheme):
    #: ``mean_acceleration``: (V^{n+1} - V^n) / dt of the step to the level (:meth:`local_error`)
    state_fields = {"mean_acceleration": "dofs"}
    name = "newmark"
    description = "Newmark(beta, gamma), implicit, exact contact at t_{n+1}"
    parameters = (
        Parameter("beta", 0.25, "Newmark beta", float, 0.0, 0.5, open_low=True),
        Parameter("gamma", 0.5, "Newmark gamma (>= 1/2: no negative damping)", float, 0.5, 1.0),
    )
    energy_definition = "E = 1/2 V.MV + 1/2 U.SU - U.F(t) + 1/2 dt^2 (beta - gamma/2) A.MA"
    friction_refusal = None
    damping_refusal = None
    finite_strain_refusal = None

    def operator(self, dt: float) -> Operator:
        return Operator(1.0 / (self.beta * dt * dt), 1.0)

    def damping_coefficient(self, dt: float) -> float:
        """gamma / (beta dt): V^{n+1} = gamma / (beta dt) dU + d (:meth:`damping_offset_increment`)."""
        return self.gamma / (self.beta * dt)

    def _damping_level(self, ctx, s: State, U: np.ndarray) -> dict[str, np.ndarray]:
        """The new level's damping data: Newmark's update of (V_d, A_d) on every dof."""
        dt, g = ctx.dt, self.gamma
        Vd0, Ad0 = damping_velocity(s)
        Ad = U / (self.beta * dt * dt) - self._predictor(ctx, s.U, Vd0, Ad0)
        Vd = Vd0 + dt * ((1 - g) * Ad0 + g * Ad)
        return {"damping_velocity": Vd, "damping_acceleration": Ad}

    @property
    def conserving(self) -> bool:
        return self.gamma == 0.5  # no numerical damping (any beta >= 1/4)

    def step_control_refusal(self) -> str:
        """Newmark is unconditionally stable for 2 beta >= gamma >= 1/2 only; below, a step the
        control changes may cross its stability limit (beta = 0.01 blew up at level 88)."""
        if 2.0 * float(self.beta) < float(self.gamma):
            return (
                f"it is only conditionally stable with beta = {float(self.beta):g} < gamma / 2 = "
                f"{float(self.gamma) / 2:g} (a changing step may cross its stability limit)"
            )
        return super().step_control_refusal()

    def local_error(self, ctx, old: State, new: State, dt_before: float | None = None) -> np.ndarray:
        """Zienkiewicz and Xie's estimate (beta - 1/6) dt^2 (A^{n+1} - A^n), with the steps' mean accelerations in
        place of A where there is mass:

            e = (beta - 1/6) dt^2 (Abar^{n+1/2} - Abar^{n-1/2}) 2 dt / (dt + dt_before),
            Abar^{n+1/2} = (V^{n+1} - V^n) / dt

        (``mean_acceleration`` of each level; Abar^{n+1/2} - Abar^{n-1/2} = A' (dt + dt_before) / 2 for a smooth
        motion, so the factor gives back the former's A' dt whatever the two steps).  Crank–Nicolson moves U and V by
        A's mean over a step only, so an alternating part of A (a contact force that alternates level to level while
        the body rests: the damping velocity's (-1)^n mode on massless contact dofs) changes neither, yet entered
        A^{n+1} - A^n: a damped steel block at rest held the step at dt/8 by it (issue 52).  On massless dofs, where
        A = 0, in a run whose contact normals are massless (``seed-normal``), and without the level before's mean
        acceleration or step ``dt_before`` (level 1, a checkpoint written before it): (beta - 1/6) / beta (U^{n+1} -
        U^n - dt V^n - dt^2/2 A^n) (Newmark's own update: that difference is beta dt^2 (A^{n+1} - A^n); the second
        difference of U where A = 0)."""
        beta = float(self.beta)
        e = (beta - 1.0 / 6.0) / beta * (new.U - self.taylor_guess(ctx, old))
        before, now = old.extra.get("mean_acceleration"), new.extra.get("mean_acceleration")
        if before is None or now is None or dt_before is None or not dt_before > 0 or ctx.rotated_kernel:
            return e
        dt = ctx.dt
        massless = e[ctx.massless]
        e = (beta - 1.0 / 6.0) * dt * dt * (2.0 * dt / (dt + dt_before)) * (now - before)
        e[ctx.massless] = massless
        return e

    def step(self, ctx, s: State) -> State:
        t = ctx.next_time(s.t)
        law = ctx.rows.friction_law(s.U, s.t, t, self.contact_law(ctx))
        q = self.increment_predictor(ctx, s.V, s.A)  # M A^{n+1} = M (dU/(beta dt^2) - q)
        damping = None if ctx.damping is None else self.damping_offset_increment(ctx, s)
        p = self.predictor(ctx, s)  # q + U^n/(beta dt^2), as the linear solve rounds it
        U, lam, info = solve_step(ctx, StepProblem(self, s, t, q, ctx.load(t), law, damping, total=p))
        return self.update(ctx, s, t, U, lam, info, p)

    def increment_predictor(self, ctx, V: np.ndarray, A: np.ndarray) -> np.ndarray:
        """q = p - U^n/(beta dt^2) = V/(beta dt) + (1/(2 beta) - 1) A, without the cancellation of p's U^n
        (the step is a problem in the increment, :mod:`~.step_problem`)."""
        b, dt = self.beta, ctx.dt
        return V / (b * dt) + (0.5 / b - 1.0) * A

    def damping_offset_increment(self, ctx, s: State) -> np.ndarray:
        """d = V_d^n + dt (1 - gamma) A_d^n - gamma dt q_d, the part of Newmark's V_d^{n+1} = gamma dU/(beta dt) + d
        that does not depend on U^{n+1} (:func:`~.base.damping_velocity`: q_d the increment predictor of
        (V_d^n, A_d^n))."""
        dt, g = ctx.dt, self.gamma
        Vd, Ad = damping_velocity(s)
        return Vd + (dt * (1 - g)) * Ad - (g * dt) * self.increment_predictor(ctx, Vd, Ad)

    def predictor(self, ctx, s: State) -> np.ndarray:
        """p with A^{n+1} = U^{n+1}/(beta dt^2) - p: (U + dt V)/(beta dt^2) + (1/(2 beta) - 1) A."""
        return self._predictor(ctx, s.U, s.V, s.A)

    def _predictor(self, ctx, U: np.ndarray, V: np.ndarray, A: np.ndarray) -> np.ndarray:
        b, dt = self.beta, ctx.dt
        return (U + dt * V) / (b * dt * dt) + (0.5 / b - 1.0) * A

    def update(self, ctx, s: State, t: float, U: np.ndarray, lam: np.ndarray, info, p: np.ndarray) -> State:
        """The new level from U^{n+1}: Newmark's A and V; V = dU/dt and A = 0 on massless dofs."""
        dt, g = ctx.dt, self.gamma
        A = U / (self.beta * dt * dt) - p
        V = s.V + dt * ((1 - g) * s.A + g * A)
        extra = {} if ctx.damping is None else self._damping_level(ctx, s, U)
        ctx.massless_update(V, A, U, s.U)
        extra["mean_acceleration"] = (V - s.V) / dt  # the step's (:meth:`local_error`)
        return State(t, U, V, A, lam, info, extra=extra)

    def impulse(self, ctx, old: State, new: State) -> np.ndarray:
        """dt ((1 - gamma) lambda^n + gamma lambda^{n+1}): M dV = dt ((1 - gamma) M A^n + gamma M A^{n+1})."""
        return ctx.dt * ((1 - self.gamma) * old.lam + self.gamma * new.lam)

    def contact_law(self, ctx) -> ContactLaw:
        """The contact law of the solve: exact Signorini contact (``penalty`` adds a compliance)."""
        return SIGNORINI

    def _extra(self, ctx) -> float:
        return 0.5 * ctx.dt**2 * (self.beta - 0.5 * self.gamma)

    def energy(self, ctx, s: State) -> tuple[float, float]:
        kin, pot = mechanical_energy(ctx, s)
        c = self._extra(ctx)
        if c:
            kin += c * float(s.A @ s.product("MA", lambda: ctx.M @ s.A))
        return kin, pot

    def energy_increment(self, ctx, old: State, new: State) -> EnergyParts:
        dU = new.U - old.U
        dR_fixed, dR_free = reaction_work(ctx, old, new, 0.5)
        normal, tangential = contact_works(ctx, dU, old, new, 0.5)
        damping, rest = damping_split(ctx, dU, old, new, 0.5)
        parts = EnergyParts(
            external=load_work(ctx, old, new, 0.5) + dR_fixed,
            contact=normal,
            numerical=dR_free + rest,
            friction=tangential,
            damping=damping,
            solver=solver_work(ctx, dU, old, new, 0.5, 0.5),
        )
        # Delta Pi - dU.(f^n + f^{n+1})/2: the trapezoid's error on f (0 when linear)
        parts.numerical += elastic_work_error(ctx, dU, old, new, 0.5)
        if self.gamma != 0.5:
            MA0 = old.product("MA", lambda: ctx.M @ old.A)
            MA1 = new.product("MA", lambda: ctx.M @ new.A)
            parts.numerical += ctx.dt * (self.gamma - 0.5) * float(0.5 * (old.V + new.V) @ (MA1 - MA0))
        return parts


class CrankNicolson(Newmark):
    name = "crank-nicolson"
    description = "Crank-Nicolson = Newmark(1/4, 1/2), the seed's scheme (8)-(9)"
    parameters = ()
    energy_definition = "E = 1/2 V.MV + 1/2 U.SU - U.F(t)"
    beta, gamma = 0.25, 0.5

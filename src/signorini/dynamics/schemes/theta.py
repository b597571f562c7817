"""The theta-method (GetFEM's ``add_theta_method_for_second_order``); backward Euler.

    U^{n+1} = U^n + dt (theta V^{n+1} + (1 - theta) V^n)
    V^{n+1} = V^n + dt (theta A^{n+1} + (1 - theta) A^n)
    M A^{n+1} + S U^{n+1} = F^{n+1} + B^T lambda^{n+1}

i.e. ``(M/(theta dt)^2 + S) U^{n+1} = M p + F^{n+1} + B^T lambda`` with
``p = (U^n + dt V^n)/(theta dt)^2 + ((1 - theta)/theta) A^n``.
``backward-euler`` = theta 1 (the seed's eq. (10)-(11)); theta = 1/2 is Crank-Nicolson.

Energy identity (exact; docs/schemes.md), with x_theta = theta x^{n+1} + (1-theta) x^n:

    Delta [1/2 V.MV + 1/2 U.SU - U.F] = dU.F_theta - Delta(U.F) + dU_D.R_D,theta
        + (B dU).lambda_theta + (T dU).lambda_t,theta        (contact, friction)
        - (theta - 1/2) (|dV|_M^2 + |dU|_S^2) + dU_f.R_f,theta
        - dU.(C V)_theta                                     (damping, when given)

Finite strain (``[material] model``): S U^{n+1} becomes the internal force f(U^{n+1}), solved by Newton
(:mod:`~signorini.dynamics.solve.newton`), 1/2 U.SU the stored energy Pi(U), and the term in |dU|_S^2
becomes Delta Pi - dU.f_theta - (theta - 1/2)|dV|_M^2 (numerical: for CN the trapezoid's error on f,
third order in dU; no longer of one sign, so that Crank-Nicolson may gain energy under large rotations).

so the scheme dissipates for theta > 1/2 (BE: -1/2|dV|_M^2 - 1/2|dU|_S^2 + dU.B^T lambda^{n+1},
the seed's identity with a plus sign on the contact term).
"""

from __future__ import annotations

import numpy as np

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
    products,
    reaction_work,
    solver_work,
)
from .step_problem import StepProblem, solve_step


class Theta(Scheme):
    name = "theta"
    description = "theta-method on (U, V, A), exact contact at t_{n+1}; dissipative for theta > 1/2"
    parameters = (Parameter("theta", 1.0, "implicitness", float, 0.5, 1.0),)
    energy_definition = "E = 1/2 V.MV + 1/2 U.SU - U.F(t)"
    friction_refusal = None
    damping_refusal = None
    finite_strain_refusal = None

    def operator(self, dt: float) -> Operator:
        return Operator(1.0 / (self.theta * dt) ** 2, 1.0)

    def damping_coefficient(self, dt: float) -> float:
        """1 / (theta dt): V^{n+1} = (U^{n+1} - U^n - dt (1 - theta) V^n) / (theta dt)."""
        return 1.0 / (self.theta * dt)

    @property
    def conserving(self) -> bool:
        return self.theta == 0.5

    def local_error(self, ctx, old: State, new: State, dt_before: float | None = None) -> np.ndarray | None:
        """theta = 1/2 (CN): (U^{n+1} - U^n - dt V^n - dt^2/2 A^n) / 3, Zienkiewicz and Xie's
        dt^2/12 (A^{n+1} - A^n).  None for theta > 1/2: its first-order error is the scheme's
        choice (backward Euler's), not a step to refine (the control judges it by energy)."""
        if self.theta != 0.5:
            return None
        return (new.U - self.taylor_guess(ctx, old)) / 3.0

    def step(self, ctx, s: State) -> State:
        dt, th = ctx.dt, self.theta
        t = ctx.next_time(s.t)
        Vd0 = damping_velocity(s)[0]
        law = ctx.rows.friction_law(s.U, s.t, t)
        q = s.V / (th * th * dt) + (1 - th) / th * s.A  # M A^{n+1} = M (dU / (theta dt)^2 - q)
        # C V_d^{n+1} = C dU / (theta dt) - C (1 - theta)/theta V_d^n
        damping = None if ctx.damping is None else -(1 - th) / th * Vd0
        p = (s.U + dt * s.V) / (th * dt) ** 2 + (1 - th) / th * s.A  # q + U^n/(theta dt)^2, as the linear solve
        U, lam, info = solve_step(ctx, StepProblem(self, s, t, q, ctx.load(t), law, damping, total=p))
        V = (U - s.U - dt * (1 - th) * s.V) / (th * dt)
        A = (V - s.V - dt * (1 - th) * s.A) / (th * dt)
        extra = {}
        if ctx.damping is not None:  # the theta update of V_d on every dof (massless ones included)
            Vd = (U - s.U - dt * (1 - th) * Vd0) / (th * dt)
            extra = {"damping_velocity": Vd}
        ctx.massless_update(V, A, U, s.U)
        return State(t, U, V, A, lam, info, extra=extra)

    def impulse(self, ctx, old: State, new: State) -> np.ndarray:
        """dt lambda_theta: M dV = dt (theta M A^{n+1} + (1 - theta) M A^n)."""
        return ctx.dt * (self.theta * new.lam + (1 - self.theta) * old.lam)

    def energy_increment(self, ctx, old: State, new: State) -> EnergyParts:
        th = self.theta
        dU, dV = new.U - old.U, new.V - old.V
        MV0, MV1 = products(ctx, old)[0], products(ctx, new)[0]
        dR_fixed, dR_free = reaction_work(ctx, old, new, th)
        # Delta Pi - dU.f_theta - (theta - 1/2)|dV|_M^2 (-(theta - 1/2)(|dV|_M^2 + |dU|_S^2) when linear)
        numerical = dR_free + elastic_work_error(ctx, dU, old, new, th)
        if th != 0.5:
            numerical -= (th - 0.5) * float(dV @ (MV1 - MV0))
        normal, tangential = contact_works(ctx, dU, old, new, th)
        damping, rest = damping_split(ctx, dU, old, new, th)
        return EnergyParts(
            external=load_work(ctx, old, new, th) + dR_fixed,
            contact=normal,
            numerical=numerical + rest,
            friction=tangential,
            damping=damping,
            solver=solver_work(ctx, dU, old, new, 1.0 - th, th),
        )


class BackwardEuler(Theta):
    name = "backward-euler"
    description = "backward Euler = theta 1, the seed's scheme (10)-(11); unconditionally dissipative"
    parameters = ()
    theta = 1.0

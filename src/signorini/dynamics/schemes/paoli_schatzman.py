"""Paoli-Schatzman (SIAM J. Numer. Anal. 40, 2002): a two-step scheme with exact contact.

    M (U^{n+1} - 2 U^n + U^{n-1}) / dt^2 + S (U^{n+1} + 2 U^n + U^{n-1}) / 4
        = F^n + B^T lambda^n,
    0 >= B (U^{n+1} + e U^{n-1}) / (1 + e) - g  ⊥  lambda^n <= 0,

with restitution coefficient e in [0, 1] (e = 0 for the wave equation).  The operator
is ``M/dt^2 + S/4`` = (4 M/dt^2 + S)/4: proportional to Crank-Nicolson's, so the
one-step starter (one CN step) reuses the run's only factorization.  The constraint
reads ``B U^{n+1} <= (1 + e) g - e B U^{n-1}``: a per-step bound for the same
contact solver.

Discrete energy: the half-step energy of the pair (U^{n-1}, U^n), recorded at level n,

    E^{n-1/2} = 1/2 D.MD + 1/2 Ubar.S Ubar - Ubar.Fbar,
    D = (U^n - U^{n-1})/dt,  Ubar = (U^n + U^{n-1})/2,  Fbar = (F^n + F^{n-1})/2;

at level 0 the same formula with the virtual level U^{-1} that makes the starter's
Crank-Nicolson step a Paoli-Schatzman step from (U^{-1}, U^0):

    (M/dt^2 + S/4) U^{-1} = M (U^0 - dt V^0)/dt^2 - M A^0/4 - S U^0/2 + F^0 - F^1/4

on the free rows (one solve with the run's factor, only when the energy is recorded;
U^{-1} = U^0 - dt V^0 + dt^2/2 A^0 on the Dirichlet dofs).  Then the CN step
(4 M/dt^2 + S) U^1 = 4 M (U^0 + dt V^0)/dt^2 + M A^0 + F^1 + B^T lambda_CN is, divided
by 4, the step below at n = 0 with lambda^0 = lambda_CN/4.  Energy identity (multiply
the step by (U^{n+1} - U^{n-1})/2, exact, for every step from n = 0 on):

    E^{n+1/2} - E^{n-1/2} = 1/2 (B (U^{n+1} - U^{n-1})).lambda^n
        + 1/2 (U^{n+1} - U^{n-1}).F^n - Delta(Ubar.Fbar) + 1/2 (U^{n+1} - U^{n-1})_D.R_D^n

The velocity stored at level n is D = (U^n - U^{n-1})/dt.  Because of the virtual
level, E^{-1/2} is not the physical energy at t = 0 but differs from it by O(dt^2)
(docs/schemes.md gives the measured differences).
"""

from __future__ import annotations

import numpy as np

from ...registry import Parameter
from ..model.operator import Operator
from .base import EnergyParts, Scheme, State


class PaoliSchatzman(Scheme):
    name = "paoli-schatzman"
    #: the previous level and its products M U, S U; the Dirichlet reaction of the step; whether
    #: the level was made by the starter
    state_fields = {"U_prev": "dofs", "MU_prev": "dofs", "SU_prev": "dofs", "R_D": "fixed", "starter": "flag"}
    variable_step = False
    variable_step_refusal = "its state is the last two levels, a fixed step apart"
    description = "two-step scheme with exact contact on (U^{n+1} + e U^{n-1})/(1+e) (restitution e)"
    parameters = (Parameter("restitution", 0.0, "restitution coefficient e", float, 0.0, 1.0),)
    starter = "crank-nicolson"
    friction_refusal = "its two-step contact law on (U^{n+1} + e U^{n-1})/(1 + e) has no derived tangential counterpart"
    energy_definition = (
        "E^{n-1/2} = 1/2 D.MD + 1/2 Ubar.S Ubar - Ubar.Fbar with D = (U^n - U^{n-1})/dt, "
        "Ubar = (U^n + U^{n-1})/2, Fbar = (F^n + F^{n-1})/2 (at level 0 the virtual U^{-1} that makes the "
        "Crank-Nicolson starter a Paoli-Schatzman step)"
    )

    massless_dofs_allowed = False
    damping_refusal = "its two-step balance has no velocity at the levels for a damping force C V"

    def check_context(self, ctx, prepared: bool = False) -> None:
        self._refuse_massless(
            ctx,
            "the stiffness average (U^{n+1} + 2 U^n + U^{n-1})/4 then leaves an undamped, growing oscillation on them",
            "the 'standard' or 'lumped' mass, or crank-nicolson with a redistributed mass",
        )

    def operator(self, dt: float) -> Operator:
        return Operator(1.0 / dt**2, 0.25)

    def start(self, ctx, first: State, second: State) -> State:
        V = (second.U - first.U) / ctx.dt
        return State(
            second.t, second.U, V, np.zeros_like(V), second.lam, second.info, {"U_prev": first.U, "starter": True}
        )

    def step(self, ctx, s: State) -> State:
        dt, e = ctx.dt, self.restitution
        Un, Up = s.U, self._previous(ctx, s)
        t = ctx.next_time(s.t)
        F = ctx.load(s.t)
        MU, SU = self._MU(ctx, s), self._SU(ctx, s)
        MUp, SUp = s.extra["MU_prev"], s.extra["SU_prev"]
        rhs = (2 * MU - MUp) / dt**2 - 0.25 * (2 * SU + SUp) + F
        t_bound = (t + e * (s.t - dt)) / (1 + e)
        bound = (1 + e) * ctx.gaps(t_bound) - e * (ctx.rows.B @ Up) if e else ctx.gaps(t)
        fixed = ctx.dirichlet(t) if ctx.has_fixed else None
        U, lam, info = ctx.solve(self.operator(dt), rhs, bound, fixed)
        new = State(t, U, (U - Un) / dt, np.zeros_like(U), lam, info, {"U_prev": Un, "MU_prev": MU, "SU_prev": SU})
        if ctx.has_fixed and ctx.disc.dirichlet_varies:
            D = ctx.fixed
            MU1, SU1 = self._MU(ctx, new), self._SU(ctx, new)
            R = (MU1 - 2 * MU + MUp)[D] / dt**2 + 0.25 * (SU1 + 2 * SU + SUp)[D] - F[D] - ctx.rows.contact_on_fixed(lam)
            new.extra["R_D"] = R
        return new

    @staticmethod
    def _MU(ctx, s: State) -> np.ndarray:
        return s.product("MU", lambda: ctx.M @ s.U)

    @staticmethod
    def _SU(ctx, s: State) -> np.ndarray:
        return s.product("SU", lambda: ctx.Sop @ s.U)

    def _previous(self, ctx, s: State) -> np.ndarray:
        """U^{n-1} (the virtual level U^{-1} at n = 0); fills MU_prev/SU_prev."""
        if "U_prev" not in s.extra:
            s.extra["U_prev"] = self._virtual_level(ctx, s)
        Up = s.extra["U_prev"]
        if "MU_prev" not in s.extra:
            s.extra["MU_prev"], s.extra["SU_prev"] = ctx.M @ Up, ctx.S @ Up
        return Up

    def _virtual_level(self, ctx, s: State) -> np.ndarray:
        """U^{-1} of level 0: the CN starter step (U^0, V^0, A^0) -> U^1 is then exactly
        this scheme's step from (U^{-1}, U^0) with lambda^0 = lambda_CN/4 (module doc)."""
        dt = ctx.dt
        rhs = (
            ctx.M @ ((s.U - dt * s.V) / dt**2 - 0.25 * s.A)
            - 0.5 * self._SU(ctx, s)
            + ctx.load(s.t)
            - 0.25 * ctx.load(ctx.next_time(s.t))
        )
        fixed = (s.U - dt * s.V + 0.5 * dt**2 * s.A)[ctx.fixed] if ctx.has_fixed else None
        return ctx.solve_linear(self.operator(dt), rhs, fixed)

    @staticmethod
    def _reaction(ctx, Up: np.ndarray, old: State, new: State, lam: np.ndarray) -> np.ndarray:
        """R_D^n of the step (U^{n-1}, U^n) -> U^{n+1} with the contact forces ``lam``."""
        D, dt = ctx.fixed, ctx.dt
        R = ctx.M[D] @ (new.U - 2 * old.U + Up) / dt**2 + 0.25 * (ctx.S[D] @ (new.U + 2 * old.U + Up))
        return R - ctx.load(old.t)[D] - ctx.rows.contact_on_fixed(lam)

    def energy(self, ctx, s: State) -> tuple[float, float]:
        Up = self._previous(ctx, s)
        dt = ctx.dt
        D = (s.U - Up) / dt
        MD = (self._MU(ctx, s) - s.extra["MU_prev"]) / dt
        Ubar = 0.5 * (s.U + Up)
        SUbar = 0.5 * (self._SU(ctx, s) + s.extra["SU_prev"])
        Fbar = 0.5 * (ctx.load(s.t) + ctx.load(s.t - dt))
        return 0.5 * float(D @ MD), 0.5 * float(Ubar @ SUbar) - float(Ubar @ Fbar)

    def load_potential(self, ctx, s: State) -> float:
        """-Ubar.Fbar, the loads' part of :meth:`energy` (means of the two levels)."""
        Ubar = 0.5 * (s.U + self._previous(ctx, s))
        return -float(Ubar @ (0.5 * (ctx.load(s.t) + ctx.load(s.t - ctx.dt))))

    def energy_increment(self, ctx, old: State, new: State) -> EnergyParts:
        dt = ctx.dt
        Up = self._previous(ctx, old)
        W = 0.5 * (new.U - Up)
        starter = bool(new.extra.get("starter"))
        lam = 0.25 * new.lam if starter else new.lam  # the CN starter as a step from (U^{-1}, U^0)
        parts = EnergyParts(contact=float((ctx.rows.B @ W) @ lam))
        F0, F1 = ctx.load(old.t), ctx.load(new.t)
        if F1 is not F0:
            Fm = ctx.load(old.t - dt)
            ubar0, ubar1 = 0.5 * (old.U + Up), 0.5 * (new.U + old.U)
            parts.external = float(W @ F0 - (ubar1 @ (0.5 * (F1 + F0)) - ubar0 @ (0.5 * (F0 + Fm))))
        if starter and ctx.has_fixed and ctx.disc.dirichlet_varies:
            parts.external += float(W[ctx.fixed] @ self._reaction(ctx, Up, old, new, lam))
        elif "R_D" in new.extra:
            parts.external += float(W[ctx.fixed] @ new.extra["R_D"])
        return parts

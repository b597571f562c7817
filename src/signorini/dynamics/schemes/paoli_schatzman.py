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

at level 0 the same formula with the virtual level U^{-1} = U^0 - dt V^0 + dt^2/2 A^0.
Energy identity (multiply the step by (U^{n+1} - U^{n-1})/2, exact):

    E^{n+1/2} - E^{n-1/2} = 1/2 (B (U^{n+1} - U^{n-1})).lambda^n
        + 1/2 (U^{n+1} - U^{n-1}).F^n - Delta(Ubar.Fbar) + 1/2 (U^{n+1} - U^{n-1})_D.R_D^n

(no identity for the starter step: ``predicted_increment`` is nan there).  The
velocity stored at level n is D = (U^n - U^{n-1})/dt.
"""

from __future__ import annotations

import numpy as np

from ...registry import Parameter
from ..context import Operator
from .base import EnergyParts, Scheme, State


class PaoliSchatzman(Scheme):
    name = "paoli-schatzman"
    description = "two-step scheme with exact contact on (U^{n+1} + e U^{n-1})/(1+e) (restitution e)"
    parameters = (Parameter("restitution", 0.0, "restitution coefficient e", float, 0.0, 1.0),)
    starter = "crank-nicolson"
    energy_definition = (
        "E^{n-1/2} = 1/2 D.MD + 1/2 Ubar.S Ubar - Ubar.Fbar with D = (U^n - U^{n-1})/dt, "
        "Ubar = (U^n + U^{n-1})/2, Fbar = (F^n + F^{n-1})/2 (U^{-1} = U^0 - dt V^0 + dt^2/2 A^0)"
    )

    massless_dofs_allowed = False

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
        bound = (1 + e) * ctx.gaps(t_bound) - e * (ctx.B @ Up) if e else ctx.gaps(t)
        fixed = ctx.dirichlet(t) if ctx.has_fixed else None
        U, lam, info = ctx.solve(self.operator(dt), rhs, bound, fixed)
        new = State(t, U, (U - Un) / dt, np.zeros_like(U), lam, info, {"U_prev": Un, "MU_prev": MU, "SU_prev": SU})
        if ctx.has_fixed and ctx.disc.dirichlet_varies:
            D = ctx.fixed
            MU1, SU1 = self._MU(ctx, new), self._SU(ctx, new)
            R = (MU1 - 2 * MU + MUp)[D] / dt**2 + 0.25 * (SU1 + 2 * SU + SUp)[D] - F[D]
            if ctx.BD is not None:
                R = R - ctx.B[:, D].T @ lam
            new.extra["R_D"] = R
        return new

    @staticmethod
    def _MU(ctx, s: State) -> np.ndarray:
        return s.product("MU", lambda: ctx.M @ s.U)

    @staticmethod
    def _SU(ctx, s: State) -> np.ndarray:
        return s.product("SU", lambda: ctx.S @ s.U)

    def _previous(self, ctx, s: State) -> np.ndarray:
        """U^{n-1} (the virtual level U^{-1} at n = 0); fills MU_prev/SU_prev."""
        if "U_prev" not in s.extra:
            s.extra["U_prev"] = s.U - ctx.dt * s.V + 0.5 * ctx.dt**2 * s.A
        Up = s.extra["U_prev"]
        if "MU_prev" not in s.extra:
            s.extra["MU_prev"], s.extra["SU_prev"] = ctx.M @ Up, ctx.S @ Up
        return Up

    def energy(self, ctx, s: State) -> tuple[float, float]:
        Up = self._previous(ctx, s)
        dt = ctx.dt
        D = (s.U - Up) / dt
        MD = (self._MU(ctx, s) - s.extra["MU_prev"]) / dt
        Ubar = 0.5 * (s.U + Up)
        SUbar = 0.5 * (self._SU(ctx, s) + s.extra["SU_prev"])
        Fbar = 0.5 * (ctx.load(s.t) + ctx.load(s.t - dt))
        return 0.5 * float(D @ MD), 0.5 * float(Ubar @ SUbar) - float(Ubar @ Fbar)

    def energy_increment(self, ctx, old: State, new: State) -> EnergyParts | None:
        if new.extra.get("starter"):
            return None
        dt = ctx.dt
        Up = self._previous(ctx, old)
        W = 0.5 * (new.U - Up)
        parts = EnergyParts(contact=float((ctx.B @ W) @ new.lam))
        F0, F1 = ctx.load(old.t), ctx.load(new.t)
        if F1 is not F0:
            Fm = ctx.load(old.t - dt)
            ubar0, ubar1 = 0.5 * (old.U + Up), 0.5 * (new.U + old.U)
            parts.external = float(W @ F0 - (ubar1 @ (0.5 * (F1 + F0)) - ubar0 @ (0.5 * (F0 + Fm))))
        if "R_D" in new.extra:
            parts.external += float(W[ctx.fixed] @ new.extra["R_D"])
        return parts

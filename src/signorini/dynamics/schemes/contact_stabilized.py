"""Contact-stabilized Newmark (Deuflhard, Krause, Ertel 2008): a mass projection of the
free-flight predictor onto the admissible set, then a CN-type corrector.

    predictor  U^p = argmin_{B W <= g(t_{n+1})} 1/2 |W - (U^n + dt V^n)|_M^2
               i.e. M U^p = M (U^n + dt V^n) + B^T mu,  B U^p <= g  ⊥  mu <= 0
    corrector  (4/dt^2) M (U^{n+1} - U^p) + S (U^n + U^{n+1}) = F^n + F^{n+1} + B^T mu',
               B U^{n+1} <= g(t_{n+1})  ⊥  mu' <= 0
    velocity   V^{n+1} = V^n + (2/dt) (U^{n+1} - U^p)

(formulas as in R. Krause's group's implementation, see
docs/literature/competing-schemes.md section 2; without contact this is CN).  The
corrector shares CN's factorization; the predictor factorizes M once more (counted in
``factorizations``), so the mass must be nonsingular on the free dofs: redistributed
masses are refused.  The history's contact force is mu'/2 (mu' balances the sum of two
levels, like lambda^n + lambda^{n+1} in CN).  No penetration at the nodes.

Energy identity (exact, derived here: with delta = U^p - U^n - dt V^n, dU = dt <V> + delta),
E = 1/2 V.MV + 1/2 U.SU - U.F:

    Delta E = 1/2 dU.(F^n + F^{n+1}) - Delta(U.F) + 1/2 dU_D.r_D          (loads, clamp)
            + 1/2 (B dU).mu'                                             (contact)
            - 1/2 delta.(F^n + F^{n+1} - S (U^n + U^{n+1}) + B^T mu')    (the projection)

with r_D the corrector's residual on the Dirichlet dofs.  The last term has no sign of
its own; the non-increase of the energy claimed for this scheme could not be confirmed.
"""

from __future__ import annotations

import numpy as np

from ..model.operator import Operator
from .base import EnergyParts, Scheme, State, load_work


class ContactStabilizedNewmark(Scheme):
    name = "contact-stabilized-newmark"
    description = "Deuflhard-Krause-Ertel: mass projection of the predictor, then a CN corrector (standard masses)"
    parameters = ()
    energy_definition = "E = 1/2 V.MV + 1/2 U.SU - U.F(t)"
    friction_refusal = "its contact-stabilizing L2 projection is defined for the normal component only"
    massless_dofs_allowed = False
    damping_refusal = "its contact-stabilizing projection of the predictor is derived without damping"
    #: the predictor's correction Up - (U + dt V) and the multiplier mu of the new level
    state_fields = {"delta": "dofs", "mu": "contact"}

    def check_context(self, ctx, prepared: bool = False) -> None:
        self._refuse_massless(ctx, "the predictor's projection in the mass norm is then undefined")

    def operator(self, dt: float) -> Operator:
        return Operator(4.0 / (dt * dt), 1.0)

    def step(self, ctx, s: State) -> State:
        dt = ctx.dt
        t1 = ctx.next_time(s.t)
        g1 = ctx.gaps(t1)
        free = s.U + dt * s.V
        fixed_free = free[ctx.fixed] if ctx.has_fixed else None
        Up, mu, _ = ctx.solve(Operator(1.0, 0.0), ctx.M @ free, g1, fixed_free)
        F0, F1 = ctx.load(s.t), ctx.load(t1)
        SU = s.product("SU", lambda: ctx.Sop @ s.U)
        rhs = (4.0 / (dt * dt)) * (ctx.M @ Up) - SU + F0 + F1
        fixed = ctx.dirichlet(t1) if ctx.has_fixed else None
        U, mu1, info = ctx.solve(self.operator(dt), rhs, g1, fixed)
        V = s.V + (2.0 / dt) * (U - Up)
        ml = ctx.massless  # only fixed dofs can be massless here
        if ml.size:
            V[ml] = (U[ml] - s.U[ml]) / dt
        return State(t1, U, V, np.zeros_like(U), 0.5 * mu1, info, extra={"delta": Up - free, "mu": mu1})

    def energy_increment(self, ctx, old: State, new: State) -> EnergyParts:
        dt = ctx.dt
        dU = new.U - old.U
        delta, mu1 = new.extra["delta"], new.extra["mu"]
        Fs = ctx.load(old.t) + ctx.load(new.t)
        Ss = old.product("SU", lambda: ctx.Sop @ old.U) + new.product("SU", lambda: ctx.Sop @ new.U)
        parts = EnergyParts(external=load_work(ctx, old, new, 0.5), contact=0.5 * float((ctx.rows.B @ dU) @ mu1))
        parts.numerical = -0.5 * float(delta @ (Fs - Ss + ctx.rows.B.T @ mu1))
        if ctx.has_fixed and ctx.disc.dirichlet_varies:
            D = ctx.fixed
            Up = old.U + dt * old.V + delta
            r = (4.0 / (dt * dt)) * (ctx.M[D] @ (new.U - Up)) + Ss[D] - Fs[D] - ctx.rows.contact_on_fixed(mu1)
            parts.external += 0.5 * float(dU[D] @ r)
        return parts

"""Moreau-Jean time-stepping: a theta-method on velocities with impulses and an index set.

    M (V^{n+1} - V^n) = dt [theta (F^{n+1} - S U^{n+1}) + (1 - theta)(F^n - S U^n)] + B^T P^{n+1}
    U^{n+1} = U^n + dt [theta V^{n+1} + (1 - theta) V^n]
    I = {i : g_i(t_n + dt/2) - nu_i . (U^n + dt/2 V^n)_i <= tol}         (predicted gap)
    for i in I:   0 >= nu.V^{n+1}_i + e nu.V^n_i - (1 + e) gdot_i  ⊥  P_i <= 0,
    for i not in I:  P_i = 0,

with tol = 1e-12 of the body's size (:attr:`~signorini.dynamics.solve.context.Context.touch_tolerance`):
a node resting on the obstacle is in I whatever the sign of its gap's round-off (with 0,
a corner node sliding on a plane left I at a step where its gap rounded to +6e-36 and
fell 6e-5 into the plane, a result that changed with the machine), the obstacle's
normal velocity gdot_i = (g_i(t_{n+1}) - g_i(t_n))/dt (zero for a fixed obstacle) and the
restitution coefficient e.  Eliminating U^{n+1}:

    (M + theta^2 dt^2 S) V^{n+1} = M V^n + dt (F_theta - S U^n) - theta (1 - theta) dt^2 S V^n + B^T P,

one factorization, proportional to CN's operator M/(dt^2/4) + S when theta = 1/2 (the
same factor is shared).  The contact force reported in the history is P/dt; the impulse
is ``state.extra['impulse']``.  Penetration is O(dt): the constraint is on velocities.

With massless dofs (redistributed masses) theta = 1/2 is refused: those rows are only
balanced on average, S (U^n + U^{n+1})/2 = ..., an undamped (-1)^n mode (measured on
bar1d: the contact is lost entirely); theta > 1/2 damps it by -(1 - theta)/theta per step.

Energy identity (exact; derived in docs/schemes.md), E = 1/2 V.MV + 1/2 U.SU - U.F,
V_theta = theta V^{n+1} + (1 - theta) V^n, so that dU = dt V_theta:

    Delta E = dU.F_theta - Delta(U.F) + V_theta[D].r[D]                   (loads, clamp)
            + (B V_theta).P                                              (impacts)
            - (theta - 1/2)(dV.M dV + dU.S dU)                           (numerical)
            - dU.(C V)_theta                                             (damping, when given)

With e = 0 and theta = 1/2, (B V_theta).P = 1/2 (B V^n).P <= 0 at every active node: the
impacts dissipate and the energy never increases (constant loads, fixed clamp).
Sources: J. J. Moreau (1988, 1999), M. Jean (1999); V. Acary, B. Brogliato, *Numerical
methods for nonsmooth dynamical systems* (Springer 2008), the Siconos documentation.
"""

from __future__ import annotations

import numpy as np

from ...contact.solver import ContactLaw
from ...registry import Parameter
from ..model.operator import Operator
from .base import EnergyParts, Scheme, State, damping_force, damping_split, friction_work, load_work


class MoreauJean(Scheme):
    name = "moreau-jean"
    #: the step's normal and tangential impulses (the history's force is P/dt)
    state_fields = {"impulse": "contact", "impulse_t": "contact_t"}
    description = "Moreau-Jean theta-method on velocities, impulses on a predicted index set (restitution e)"
    parameters = (
        Parameter("theta", 0.5, "theta of the velocity theta-method (1/2 <= theta <= 1)", float, 0.5, 1.0),
        Parameter("restitution", 0.0, "Newton restitution coefficient e", float, 0.0, 1.0),
    )
    energy_definition = "E = 1/2 V.MV + 1/2 U.SU - U.F(t)"
    exact_contact = False  # velocity-level: penetration O(dt)
    needs_condensed_solve = True
    massless_dofs_allowed = False  # with the default theta = 1/2 (theta > 1/2 accepts them)
    friction_refusal = None  # Coulomb on the slip rate T V^{n+1} of the index set (as Siconos)
    damping_refusal = None

    def check_context(self, ctx, prepared: bool = False) -> None:
        self._needs_condensed_solve(ctx, prepared, "index sets")
        if self.theta == 0.5:
            self._refuse_massless(
                ctx,
                "with the midpoint rule (theta = 1/2) they are only balanced on average, "
                "S (U^n + U^{n+1})/2 = ..., an undamped (-1)^n mode that loses the contact (measured on bar1d)",
                "theta > 1/2 (e.g. 1) or a mass without massless dofs" if self.parameters else "another mass",
            )

    def operator(self, dt: float) -> Operator:
        return Operator(1.0, (self.theta * dt) ** 2)

    def damping_coefficient(self, dt: float) -> float:
        """theta dt: the balance holds dt theta C V^{n+1}, V^{n+1} the unknown [time]."""
        return self.theta * dt

    def step(self, ctx, s: State) -> State:
        dt, th, e = ctx.dt, self.theta, self.restitution
        t0, t1 = s.t, ctx.next_time(s.t)
        SU = s.product("SU", lambda: ctx.Sop @ s.U)
        Fth = th * ctx.load(t1) + (1 - th) * ctx.load(t0)
        rhs = ctx.M @ s.V + dt * (Fth - SU)
        if th != 1.0:
            rhs -= th * (1 - th) * dt * dt * (ctx.S @ s.V)
            if ctx.damping is not None:
                rhs -= (1 - th) * dt * damping_force(ctx, s)
        BV0 = ctx.rows.B @ s.V
        index = ctx.gaps(t0 + 0.5 * dt) - ctx.rows.B @ (s.U + 0.5 * dt * s.V) <= ctx.touch_tolerance
        gdot = (ctx.gaps(t1) - ctx.gaps(t0)) / dt if ctx.disc.contact.moving else 0.0
        bound = (1 + e) * gdot - e * BV0
        fixed = None
        if ctx.has_fixed:
            D = ctx.fixed
            fixed = (ctx.dirichlet(t1) - s.U[D]) / (th * dt) - (1 - th) / th * s.V[D]
        bound = np.broadcast_to(bound, BV0.shape).copy()
        law = ctx.rows.friction_rate_law(t0, t1, ContactLaw(subset=index))
        V, P, info = ctx.solve(self.step_operator(ctx, dt), rhs, bound, fixed, law)
        U = s.U + dt * (th * V + (1 - th) * s.V)
        P_t = info.lam_t  # tangential impulses (friction), or None
        lam_t = None if P_t is None else P_t / dt
        return State(t1, U, V, np.zeros_like(U), P / dt, info, extra={"impulse": P, "impulse_t": P_t}, lam_t=lam_t)

    def impulse(self, ctx, old: State, new: State) -> np.ndarray:
        """The impulse P of the step, unknown of the velocity-level solve."""
        return new.extra["impulse"]

    def energy_increment(self, ctx, old: State, new: State) -> EnergyParts:
        th, dt = self.theta, ctx.dt
        dU, dV = new.U - old.U, new.V - old.V
        Vth = th * new.V + (1 - th) * old.V
        P = new.extra["impulse"]
        P_t = new.extra.get("impulse_t")
        parts = EnergyParts(
            external=load_work(ctx, old, new, th),
            contact=float((ctx.rows.B @ Vth) @ P),
            friction=friction_work(ctx, Vth, P_t),
        )
        parts.damping, parts.numerical = damping_split(ctx, dU, old, new, th)
        if ctx.has_fixed and ctx.disc.dirichlet_varies:
            D = ctx.fixed
            Fth = th * ctx.load(new.t) + (1 - th) * ctx.load(old.t)
            SUth = th * (ctx.S[D] @ new.U) + (1 - th) * (ctx.S[D] @ old.U)
            r = ctx.M[D] @ dV + dt * (SUth - Fth[D]) - ctx.rows.contact_on_fixed(P, P_t)
            if ctx.damping is not None:
                r += dt * (th * damping_force(ctx, new)[D] + (1 - th) * damping_force(ctx, old)[D])
            parts.external += float(Vth[D] @ r)
        if th != 0.5:
            parts.numerical -= (th - 0.5) * (float(dV @ (ctx.M @ dV)) + float(dU @ (ctx.S @ dU)))
        return parts


class EnergyConserving(MoreauJean):
    """The midpoint rule with a persistency condition on the predicted active set.

    On the index set I of the predicted gap, the normal increment of the step and the
    contact impulse are complementary: 0 >= nu.(U^{n+1} - U^n)_i ⊥ P_i <= 0 (Laursen and
    Chawla's persistency condition lambda . d/dt gap = 0, imposed on the step).  The
    contact then does no work and the energy identity of the midpoint rule has no
    contact term: E^{n+1} - E^n = (work of loads and prescribed motion) exactly, through
    impacts.  Algebraically this is Moreau-Jean with theta = 1/2 and e = 1.  The price is
    an O(dt) penetration (positions are not constrained); Laursen and Love's velocity
    update, which also restores the gap, is not implemented (its formula could not be
    confirmed from a primary source).
    """

    name = "energy-conserving"
    description = "midpoint rule + persistency (Laursen-Chawla): energy exactly conserved through impacts"
    parameters = ()
    conserving = True  # type: ignore[assignment]
    theta, restitution = 0.5, 1.0
    friction_refusal = "its persistency condition conserves energy and is derived for frictionless contact"

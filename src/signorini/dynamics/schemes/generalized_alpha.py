"""Generalized-alpha (Chung-Hulbert 1993) and HHT-alpha (Hilber-Hughes-Taylor 1977)
with contact enforced exactly at t_{n+1}.

Balance at the intermediate levels (alpha_m, alpha_f in [0, 1)):

    (1 - a_m) M A^{n+1} + a_m M A^n + (1 - a_f) S U^{n+1} + a_f S U^n
        = (1 - a_f) F^{n+1} + a_f F^n + B^T ((1 - a_f) lambda^{n+1} + a_f lambda^n),
    0 >= B U^{n+1} - g(t_{n+1})  ⊥  lambda^{n+1} <= 0,

with the Newmark updates of (beta, gamma) = ((1 - a_m + a_f)^2 / 4, 1/2 - a_m + a_f).
The contact force enters at the same weighted level as the elastic force, so a
level where the balance holds exactly (a_m = a_f = 1/2) stays so: ``rho_inf = 1`` is
Crank-Nicolson, to round-off.  Dividing by (1 - a_f) gives the operator
``(1 - a_m)/((1 - a_f) beta dt^2) M + S`` (factorized once) and the multiplier of the
solve is lambda^{n+1} itself.  On massless dofs the M terms vanish, V = dU/dt, A = 0,
and the balance is taken at t_{n+1} instead of the weighted level (those rows have no
inertia; with a_f = 1/2 the weighted balance S (U^n + U^{n+1})/2 = ... would leave an
undamped (-1)^n mode, measured: a stress error of 0.96 that does not converge on the
1D bar with the `seed` mass).

``generalized-alpha``: a_m = (2 rho_inf - 1)/(rho_inf + 1), a_f = rho_inf/(rho_inf + 1)
(Chung-Hulbert's optimal choice for a spectral radius rho_inf at infinite frequency).
``hht``: a_m = 0, a_f = alpha in [0, 1/3] (Hilber-Hughes-Taylor's alpha with the sign
convention alpha >= 0 = dissipative; HHT's own parameter is -alpha).

Energy identity (exact; derived in docs/schemes.md by multiplying the weighted balance
by dU = U^{n+1} - U^n and using dU = dt <V> + dt^2 (beta - gamma/2) dA), with
x_w = (1 - w) x^{n+1} + w x^n and <x> = (x^n + x^{n+1})/2:

    Delta [1/2 V.MV + 1/2 U.SU - U.F + 1/2 dt^2 (beta - gamma/2) A.MA]
        = dU.F_{a_f} - Delta(U.F) + dU_D.R_D               (loads, prescribed motion)
        + (B dU).lambda_{a_f}                               (contact)
        - (1/2 - a_f) (dt <V>.M dA + dU.S dU)
        - dt^2 (beta - gamma/2) (1/2 - a_m) dA.M dA         (numerical)
        - dU.(C V)_{a_f}                                    (damping, when given)

where beta - gamma/2 = (a_f - a_m)^2 / 4 >= 0 and R_D = M A_{a_m} + S U_{a_f} - F_{a_f}
- B^T lambda_{a_f} on the Dirichlet dofs (the weighted reactions).  For
a_m = a_f = 1/2 every numerical term vanishes: the CN identity.
"""

from __future__ import annotations

import numpy as np

from ...errors import InputError
from ...registry import Parameter
from ..model.operator import Operator
from .base import (
    EnergyParts,
    State,
    contact_works,
    damping_force,
    damping_split,
    elastic_work_error,
    load_work,
    products,
    reaction_work,
    solver_work,
    weighted,
)
from .newmark import Newmark
from .step_problem import StepProblem, solve_step


class GeneralizedAlpha(Newmark):
    name = "generalized-alpha"
    finite_strain_refusal = None
    description = "Chung-Hulbert generalized-alpha, exact contact at t_{n+1}; rho_inf = 1 is CN"
    parameters = (
        Parameter("rho_inf", 1.0, "spectral radius at infinite frequency (1: no dissipation)", float, 0.0, 1.0),
    )
    energy_definition = "E = 1/2 V.MV + 1/2 U.SU - U.F(t) + 1/2 dt^2 (a_f - a_m)^2/4 A.MA"

    @property
    def conserving(self) -> bool:
        a_m, a_f = self.alphas()
        return a_m == a_f  # gamma = 1/2 + a_f - a_m = 1/2: no numerical damping

    def check_context(self, ctx, prepared: bool = False) -> None:
        if self.alphas()[1] != 0.0:
            self._refuse_massless_directions(ctx)

    def _refuse_massless_directions(self, ctx) -> None:
        """Massless rows are balanced at t_{n+1} along the coordinate axes only."""
        if ctx.rotated_kernel:
            self._refuse_massless(
                ctx,
                "the weighted balance leaves an undamped (-1)^n mode along them (its massless rows are balanced at "
                "t_{n+1} along the coordinate axes only)",
                "crank-nicolson, newmark, backward-euler or theta, or another mass",
            )

    def alphas(self) -> tuple[float, float]:
        r = self.rho_inf
        return (2 * r - 1) / (r + 1), r / (r + 1)

    def newmark(self) -> tuple[float, float]:
        am, af = self.alphas()
        return 0.25 * (1 - am + af) ** 2, 0.5 - am + af

    @property
    def beta(self) -> float:  # type: ignore[override]
        return self.newmark()[0]

    @property
    def gamma(self) -> float:  # type: ignore[override]
        return self.newmark()[1]

    def operator(self, dt: float) -> Operator:
        am, af = self.alphas()
        beta, _ = self.newmark()
        return Operator((1 - am) / ((1 - af) * beta * dt * dt), 1.0)

    def step(self, ctx, s: State) -> State:
        am, af = self.alphas()
        t = ctx.next_time(s.t)
        Fd0 = damping_force(ctx, s)
        lagged = 0.0
        if af:
            lagged = af * (ctx.load(s.t) - products(ctx, s)[1] + ctx.rows.contact_force(s.lam, s.lam_t, s.t))
            if Fd0 is not None:  # the damping force weighs as the elastic one: a_f C V^n lagged
                lagged -= af * Fd0
            if ctx.massless.size:  # no inertia: balanced at t_{n+1}, not on average (no (-1)^n mode)
                lagged[ctx.massless] = 0.0
        law = ctx.rows.friction_law(s.U, s.t, t)
        # (1 - a_m) M A^{n+1} + a_m M A^n + (1 - a_f) f(U^{n+1}) + a_f f(U^n) = ..., over (1 - a_f)
        q = ((1 - am) * self.increment_predictor(ctx, s.V, s.A) - am * s.A) / (1 - af)
        damping = None if ctx.damping is None else self.damping_offset_increment(ctx, s)
        forces = ctx.load(t) + lagged / (1 - af) if af else ctx.load(t)
        U, lam, info = solve_step(ctx, StepProblem(self, s, t, q, forces, law, damping))
        return self.update(ctx, s, t, U, lam, info, self.predictor(ctx, s))  # A^{n+1} = U^{n+1}/(beta dt^2) - p

    def impulse(self, ctx, old: State, new: State) -> np.ndarray:
        """dt lambda_{a_f}, the contact term of the weighted balance (exact momentum for a_m = a_f)."""
        af = self.alphas()[1]
        return ctx.dt * ((1 - af) * new.lam + af * old.lam)

    def energy_increment(self, ctx, old: State, new: State) -> EnergyParts:
        am, af = self.alphas()
        dt = ctx.dt
        dU = new.U - old.U
        lam_w = (1 - af) * new.lam + af * old.lam
        lam_t_w = weighted(new.lam_t, old.lam_t, 1 - af)
        normal, tangential = contact_works(ctx, dU, old, new, 1 - af, af)
        damping, rest = damping_split(ctx, dU, old, new, 1 - af)
        # Newton's r is the weighted balance over (1 - a_f): its work (1 - a_f) r^{n+1}; the massless rows' balances
        # at both levels, weighted as their forces (measured: tests/dynamics/test_solver_work.py)
        parts = EnergyParts(
            external=load_work(ctx, old, new, 1 - af),
            contact=normal,
            friction=tangential,
            damping=damping,
            numerical=rest,
            solver=solver_work(ctx, dU, old, new, 0.0, 1 - af, massless_old=af),
        )
        if ctx.massless.size:  # massless rows balanced at t_{n+1}: the level-0 imbalance R0 works once
            parts.numerical += reaction_work(ctx, old, new, 1 - af)[1]
        if ctx.has_fixed and ctx.disc.dirichlet_varies:
            D = ctx.fixed
            A_w = (1 - am) * new.A + am * old.A
            F_w = (1 - af) * ctx.load(new.t) + af * ctx.load(old.t)
            if ctx.rows.rows_of(old.t)[0] is ctx.rows.B:
                on_fixed = ctx.rows.contact_on_fixed(lam_w, lam_t_w)
            else:  # a contact pair re-paired between the levels: each level through its own rows
                on_fixed = (1 - af) * ctx.rows.contact_on_fixed(new.lam, new.lam_t, new.t) + af * (
                    ctx.rows.contact_on_fixed(old.lam, old.lam_t, old.t)
                )
            f_w = (1 - af) * products(ctx, new)[1][D] + af * products(ctx, old)[1][D]
            RD = ctx.M[D] @ A_w + f_w - F_w[D] - on_fixed
            Fd0, Fd1 = damping_force(ctx, old), damping_force(ctx, new)
            if Fd0 is not None or Fd1 is not None:  # the weighted damping force on the Dirichlet dofs
                RD = RD + (0.0 if Fd1 is None else (1 - af) * Fd1[D]) + (0.0 if Fd0 is None else af * Fd0[D])
            parts.external += float(dU[D] @ RD)
        if af != 0.5 or am != 0.5:
            dA = new.A - old.A
            MdA = new.product("MA", lambda: ctx.M @ new.A) - old.product("MA", lambda: ctx.M @ old.A)
            vbar = 0.5 * (old.V + new.V)
            parts.numerical -= (0.5 - af) * dt * float(vbar @ MdA)
            parts.numerical -= 2 * self._extra(ctx) * (0.5 - am) * float(dA @ MdA)
        # Delta Pi - dU.f_{a_f}: -(1/2 - a_f)|dU|_S^2 when linear
        parts.numerical += elastic_work_error(ctx, dU, old, new, 1 - af)
        return parts


class HHT(GeneralizedAlpha):
    name = "hht"
    description = "Hilber-Hughes-Taylor alpha (alpha >= 0 dissipative), exact contact at t_{n+1}; alpha = 0 is CN"
    parameters = (Parameter("alpha", 0.1, "HHT alpha in [0, 1/3] (0: Crank-Nicolson)", float, 0.0, 1.0 / 3.0),)

    def check(self) -> None:
        if not 0.0 <= self.alpha <= 1.0 / 3.0:
            raise InputError(f"scheme hht: alpha must be in [0, 1/3], got {self.alpha}")

    def alphas(self) -> tuple[float, float]:
        return 0.0, self.alpha

"""The energy-momentum scheme: the midpoint rule with Gonzalez's discrete gradient (spec 12).

On the dofs with mass (m) and the massless ones (l: the contact nodes whose inertia the mass
redistribution removed):

    U^{n+1} - U^n = dt/2 (V^n + V^{n+1})
    M (V^{n+1} - V^n) = dt [F_mid - f_alg(U^n, U^{n+1}) + B^T lambda^{n+1}]      (rows m)
    0 = F^{n+1} - f(U^{n+1}) + B^T lambda^{n+1}                                   (rows l)

with F_mid = (F^n + F^{n+1})/2 and f_alg the discrete gradient: f_alg . dU = Pi(U^{n+1}) - Pi(U^n)
exactly, sum_a f_alg,a = 0 and sum_a x_mid,a x f_alg,a = 0 (:func:`~signorini.fem.hyperelastic.algorithmic_force`;
linear elasticity: f_alg = S (U^n + U^{n+1})/2).  A free body with mass on every node (``standard``,
``lumped``) keeps its energy and its linear and angular momentum to the Newton tolerance.  The massless
rows are balanced at t_{n+1}, as Crank-Nicolson does (a midpoint balance there leaves an undamped
(-1)^n mode: docs/design.md); what that costs is the term below, third order in dU.

Energy identity (E = 1/2 V.MV + Pi(U) - U.F(t); docs/schemes.md):

    Delta E = dU.F_mid - Delta(U.F) + (B dU).lambda_w + (T dU).lambda_t,w + dU_l.(f_alg - (f^n + f^{n+1})/2)_l
              + dU_f.R_f,mid

with lambda_w = lambda^{n+1} on the rows of nodes with mass and (lambda^n + lambda^{n+1})/2 on those of
massless nodes (the scheme's contact impulse is dt lambda_w), lambda_t,w the tangential (friction) forces
weighted alike, the last but one term its numerical part (0 in linear elasticity, where the scheme conserves
energy exactly).  Friction (Coulomb, Tresca): the tangential forces of the halved massless rows are halved
too (Coulomb's cone is invariant; a Tresca threshold is halved with them) and doubled back.

Momenta (finite strain): the massless rows' balance at t_{n+1} takes O(dt^2) of the linear and angular
momentum, and a pair's forces a moment of their own (:mod:`~signorini.dynamics.schemes.momentum_projection`); after
each step the velocities of the nodes with mass get the rigid motion
closest in M's norm that gives it back (:mod:`~signorini.dynamics.schemes.momentum_projection`, solver option
``momentum_projection``), and the kinetic energy that motion changes is part of the numerical term above.

The step is solved by Newton (:mod:`~signorini.dynamics.solve.newton`) with the operator 2/dt^2 M + 1/2 K(U_mid)
(proportional to Crank-Nicolson's: one factorization serves both in linear elasticity), the massless
rows' equations halved so that the tangent stays symmetric (their multipliers are doubled back).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import scipy.sparse as sp

from ...fem.dofmap import block_of
from ..model.operator import Operator
from .base import EnergyParts, Scheme, State, contact_works, load_work, products, reaction_work, solver_work, weighted
from .momentum_projection import applies, groups, velocity_correction
from .step_problem import StepProblem, solve_step


class EnergyMomentum(Scheme):
    name = "energy-momentum"
    description = (
        "midpoint rule with a discrete-gradient stress: a free body keeps its energy, linear and angular "
        "momentum (finite strain too); contact at t_{n+1}"
    )
    energy_definition = "E = 1/2 V.MV + Pi(U) - U.F(t)"
    friction_refusal = None
    finite_strain_refusal = None
    momentum_projection = True

    def operator(self, dt: float) -> Operator:
        return Operator(2.0 / (dt * dt), 0.5)

    @property
    def conserving(self) -> bool:
        return True

    def check_context(self, ctx, prepared: bool = False) -> None:
        self.row_weights(ctx)  # refuses rows that mix nodes with and without mass
        if ctx.rotated_kernel:
            self._refuse_massless(ctx, "its massless rows are balanced by components")

    def local_error(self, ctx, old: State, new: State, dt_before: float | None = None) -> np.ndarray:
        """(U^{n+1} - U^n - dt V^n - dt^2/2 A^n) / 3, as Crank-Nicolson's (a second-order scheme)."""
        return (new.U - self.taylor_guess(ctx, old)) / 3.0

    def row_weights(self, ctx) -> np.ndarray:
        """(nc,) the weight of lambda^{n+1} in a row's contact impulse: 1 on rows of nodes with mass,
        1/2 on those of massless nodes (module docstring); a row that joins both is refused.  One product
        with B's pattern (the rows move with sliding pairs and in the current configuration)."""
        ml = np.zeros(ctx.M.shape[0])
        ml[ctx.massless] = 1.0
        pattern = (ctx.rows.B != 0).astype(float)
        on_massless, on_all = pattern @ ml, pattern @ np.ones(ml.size)
        joined = (on_massless > 0) & (on_massless < on_all)
        if joined.any():
            from ...errors import InputError

            row = int(np.flatnonzero(joined)[0])
            raise InputError(
                f"scheme {self.name}: contact row {row} joins nodes with and without mass (mass "
                f"{ctx.disc.mass_name!r}); its balance needs either; use a mass that removes the inertia on "
                "both sides of a pair, or crank-nicolson"
            )
        return np.where(on_massless > 0, 0.5, 1.0)

    def _massless_mask(self, ctx) -> np.ndarray:
        mask = np.zeros(ctx.M.shape[0], dtype=bool)
        mask[ctx.massless] = True
        return mask

    def step(self, ctx, s: State) -> State:
        dt = ctx.dt
        t = ctx.next_time(s.t)
        F0, F1 = ctx.load(s.t), ctx.load(t)
        ml = self._massless_mask(ctx)
        Fw = np.where(ml, 0.5 * F1, 0.5 * (F0 + F1))
        w = self.row_weights(ctx)
        law = ctx.rows.friction_law(s.U, s.t, t)
        if law.radius is not None:  # Tresca: the halved rows' multipliers are half the forces, so is their bound
            law = replace(law, radius=law.radius * w)
        el, U0 = ctx.elastic, s.U

        def force(U):  # g with 1/2 g = f_alg on rows with mass, 1/2 f on the massless rows l
            return np.where(ml, el.force(U), 2.0 * el.algorithmic_force(U0, U))

        def tangent(U, project=False):
            return el.tangent(0.5 * (U0 + U), project)

        def jacobian(U):  # dg/dU exactly: K(U) on the massless rows, 2 d f_alg / dU on the others
            J = sp.diags(2.0 * (~ml)) @ el.algorithmic_tangent(U0, U)
            return (J + sp.diags(ml.astype(float)) @ el.tangent(U) if ml.any() else J).tocsr()

        f0 = products(ctx, s)[1]  # f_alg(U^n, U^n) = f(U^n): g(U^n) without evaluating it
        step = StepProblem(
            self,
            s,
            t,
            (2.0 / dt) * s.V,
            Fw,
            law,
            force=force,
            tangent=tangent,
            force_start=np.where(ml, f0, 2.0 * f0),
            potential=False,
            jacobian=jacobian,
            configuration=lambda U: 0.5 * (U0 + U),
        )
        U, mu, info = solve_step(ctx, step)
        lam = np.where(w == 0.5, 2.0 * mu, mu) if mu.size else mu
        if info.lam_t is not None:  # the tangential forces of the halved rows, doubled back alike
            info.lam_t = np.where((w == 0.5)[:, None], 2.0 * info.lam_t, info.lam_t)
        V = 2.0 * (U - s.U) / dt - s.V
        cache = {}
        if applies(self, ctx):
            f_alg = cache["f_alg"] = el.algorithmic_force(s.U, U)
            f_mean = 0.5 * (products(ctx, s)[1] + cache.setdefault("SU", el.force(U)))  # the new level's f, kept
            if "R0" in s.extra:  # t = 0: the massless rows' imbalance, not a force
                f_mean = f_mean - 0.5 * s.extra["R0"]
            h = np.where(ml, f_mean - f_alg, 0.0) - self._pair_force(ctx, s, w, lam, info.lam_t)
            mesh = ctx.disc.problem.mesh
            dV = velocity_correction(ctx.M, mesh.points, s.U, U, h, dt, ~ml, self._groups(ctx, s.lam, lam))
            V += ctx.comm.bcast(dV)  # on several ranks, rank 0's: their dot products may differ in round-off
        A = (V - s.V) / dt
        ctx.massless_update(V, A, U, s.U)
        return State(t, U, V, A, lam, info, cache=cache)

    def _groups(self, ctx, lam0: np.ndarray, lam1: np.ndarray) -> list[np.ndarray] | None:
        """The groups of bodies of the momentum projection (nodes, bool (N,) each): the bodies a pair row that acts
        at t_n or t_{n+1} joins are one (:func:`~.momentum_projection.groups`); None: one body."""
        from ...fem.mesh import bodies

        mesh = ctx.disc.problem.mesh
        if getattr(self, "_labels", (None,))[0] is not mesh:
            self._labels = (mesh, bodies(mesh))
        labels = self._labels[1]
        if labels.max(initial=0) == 0:
            return None
        c, d = ctx.disc.contact, mesh.dim
        joined = np.zeros((0, 2), dtype=np.int64)
        if c.pair is not None and c.master_dofs is not None and lam1.size:
            rows = np.flatnonzero((c.pair >= 0) & ((lam1 != 0) | (lam0 != 0 if lam0.size else False)))
            master = labels[block_of(c.master_dofs[rows][:, :, 0], d)]  # (rows, facet nodes) their bodies
            slave = np.repeat(labels[c.nodes[rows]], master.shape[1])
            joined = np.unique(np.column_stack([slave, master.ravel()]), axis=0)
        return groups(labels, joined)

    @staticmethod
    def _pair_force(ctx, s: State, w: np.ndarray, lam: np.ndarray, lam_t: np.ndarray | None = None) -> np.ndarray:
        """B^T (w lambda^{n+1}) + B_n^T ((1 - w) lambda^n) (n,) on the contact pairs' rows, and with friction
        T^T (w lambda_t^{n+1}) + T_n^T ((1 - w) lambda_t^n) (each level's multipliers through its own rows, as in
        the energy identity's contact work): the pairs' part of the scheme's contact impulse / dt (0 without
        pairs)."""
        pair = ctx.disc.contact.pair
        if pair is None or not lam.size or not (pair >= 0).any():
            return np.zeros(s.U.size)
        on = pair >= 0
        tangential = weighted(lam_t, None, w)
        if tangential is not None:
            tangential = np.where(on[:, None], tangential, 0.0)
        f = ctx.rows.contact_force(np.where(on, w * lam, 0.0), tangential)
        old_t = weighted(None, s.lam_t, w)  # (1 - w) lambda_t^n: 0 where w = 1
        if old_t is not None:
            old_t = np.where(on[:, None], old_t, 0.0)
        if s.lam.size and np.any(w < 1.0):
            f = f + ctx.rows.contact_force(np.where(on, (1.0 - w) * s.lam, 0.0), old_t, s.t)
        return f

    def impulse(self, ctx, old: State, new: State) -> np.ndarray:
        """dt lambda_w (module docstring)."""
        w = self.row_weights(ctx)
        return ctx.dt * (w * new.lam + (1.0 - w) * old.lam)

    def energy_increment(self, ctx, old: State, new: State) -> EnergyParts:
        dU = new.U - old.U
        w = self.row_weights(ctx)
        _, dR_free = reaction_work(ctx, old, new, 0.5)
        contact, friction = contact_works(ctx, dU, old, new, w)
        numerical = dR_free
        el, ml = ctx.elastic, ctx.massless
        f0, f1 = products(ctx, old)[1], products(ctx, new)[1]
        # the massless rows balance f, not f_alg: dU.(f_alg - <f>) on them (0 when linear: f_alg = <f>)
        f_alg = new.product("f_alg", lambda: el.algorithmic_force(old.U, new.U, f0, f1))
        numerical += float(dU[ml] @ (f_alg[ml] - 0.5 * (f0[ml] + f1[ml])))
        if applies(self, ctx):
            numerical += self._projection_work(ctx, old, new)
        # Newton's r of the halved balance: its work r^{n+1} on the rows with mass; the massless rows' balances at
        # both levels (each 2 r, averaged)
        return EnergyParts(
            external=load_work(ctx, old, new, 0.5) + self._prescribed_work(ctx, old, new, w, f0, f1),
            contact=contact,
            numerical=numerical,
            friction=friction,
            solver=solver_work(ctx, dU, old, new, 0.0, 1.0, massless_old=1.0),
        )

    def _projection_work(self, ctx, old: State, new: State) -> float:
        """(V + dV/2) . M dV: the kinetic energy the momentum projection gave the step, dV = V^{n+1} - V_s on the
        rows with mass (V_s = 2 dU/dt - V^n, the scheme's own velocity; 0 without the projection)."""
        Vs = 2.0 * (new.U - old.U) / ctx.dt - old.V
        dV = np.where(self._massless_mask(ctx), 0.0, new.V - Vs)
        return float((Vs + 0.5 * dV) @ (ctx.M @ dV))  # M by rows on several ranks: a product every rank makes

    def _prescribed_work(self, ctx, old: State, new: State, w, f0, f1) -> float:
        """dU_D . R_D: the work of the reactions of a prescribed motion, R = M dV/dt + g_w - F_mid - B^T lambda_w
        on the Dirichlet dofs (g_w = f_alg with mass, (f^n + f^{n+1})/2 without); 0 when it does not move."""
        if not (ctx.has_fixed and ctx.disc.dirichlet_varies):
            return 0.0
        D, dt = ctx.fixed, new.t - old.t
        f_alg = new.product("f_alg", lambda: ctx.elastic.algorithmic_force(old.U, new.U, f0, f1))
        g = np.where(self._massless_mask(ctx), 0.5 * (f0 + f1), f_alg)
        contact = 0.0
        if new.lam.size:  # each level's weighted forces through its own rows
            contact = ctx.rows.contact_force(
                w * new.lam, weighted(new.lam_t, None, w) if new.lam_t is not None else None
            )
            contact = contact + ctx.rows.contact_force(
                (1.0 - w) * old.lam, weighted(None, old.lam_t, w) if old.lam_t is not None else None, old.t
            )
        R = (ctx.M @ (new.V - old.V)) / dt + g - 0.5 * (ctx.load(old.t) + ctx.load(new.t)) - contact
        return float((new.U - old.U)[D] @ R[D])

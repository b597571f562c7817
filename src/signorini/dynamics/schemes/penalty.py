"""Crank-Nicolson with penalized contact: lambda_i = -k_i max(0, nu.u_i - g_i) at t_{n+1}.

The penalty replaces the Signorini condition by a stiff spring on each contact node,

    k_i = stiffness * E * w_i / h      [force / length],

with E the Young's modulus, w_i = int_{Gamma_C} N_i ds the node's contact area (1 in
1D), h = (|Omega| / n_cells)^(1/d) the mean cell size and ``stiffness`` the
dimensionless option (default 100).  The contact pressure k_i delta / w_i then equals
stiffness * E * delta / h: a penetration delta costs ``stiffness`` times the stress of
compressing one cell by delta, so the penetration is O(h p / (stiffness E)) for a
contact pressure p -- O(1/stiffness).  Larger values approach exact contact.

It is solved exactly as a linear complementarity problem with compliance
c_i = 1/k_i (``B U + c lambda <= g  ⊥  lambda <= 0``), on the same single factorization
as CN.  The CN energy identity holds unchanged (its contact term is
1/2 (B dU).(lambda^n + lambda^{n+1})); the penalty springs' stored energy
1/2 sum k_i max(0, nu.u_i - g_i)^2 is not part of E.
"""

from __future__ import annotations

import numpy as np

from ...contact.solver import ContactLaw
from ...fem.assembly import geometry
from ...registry import Parameter
from .newmark import CrankNicolson


class PenaltyCN(CrankNicolson):
    name = "penalty"
    finite_strain_refusal = None  # Crank-Nicolson's Newton step, the compliance in each contact solve
    description = "Crank-Nicolson with penalized contact, k_i = stiffness E w_i / h (penetration O(1/stiffness))"
    parameters = (Parameter("stiffness", 100.0, "penalty factor on E w_i / h (dimensionless)", float, 0.0, None, True),)
    energy_definition = "E = 1/2 V.MV + 1/2 U.SU - U.F(t) (penalty springs' energy not included)"
    exact_contact = False
    beta, gamma = 0.25, 0.5
    needs_condensed_solve = True
    friction_refusal = "a penalty on the tangential slip is not implemented (its springs would store the stick energy)"

    def check_context(self, ctx, prepared: bool = False) -> None:
        self._needs_condensed_solve(ctx, prepared, "penalty compliances")

    def compliance(self, ctx) -> np.ndarray:
        """c_i = 1/k_i (nc,), computed once per run."""
        if getattr(self, "_c", None) is None or self._c_ctx is not ctx:
            mesh = ctx.disc.problem.mesh
            wdet, _ = geometry(mesh)
            h = (float(wdet.sum()) / mesh.n_cells) ** (1.0 / mesh.dim)
            w = ctx.disc.contact.weights if mesh.dim > 1 else np.ones(ctx.disc.contact.size)
            k = self.stiffness * float(np.max(ctx.disc.material.young)) * w / h  # the stiffest region's E
            self._c, self._c_ctx = 1.0 / k, ctx
        return self._c

    def contact_law(self, ctx) -> ContactLaw:
        return ContactLaw(compliance=self.compliance(ctx))

    def contact_energy(self, ctx, state, by_row: bool = False):
        """The springs' stored energy 1/2 sum c_i lambda_i^2 = 1/2 sum k_i max(0, nu.u_i - g_i)^2 (``by_row``:
        each spring's, (nc,))."""
        if by_row:
            return 0.5 * self.compliance(ctx) * state.lam**2
        return 0.5 * float(np.sum(self.compliance(ctx) * state.lam**2))

"""Implicit time schemes for ``M U'' + S U = F + B^T lambda`` with contact at t_{n+1}.

Every scheme has the form ``K_eff U^{n+1} = M p(state) + F^{n+1} + B^T lambda^{n+1}``
with ``K_eff = a M + S`` constant for a fixed time step, so the matrix is factorized
once per run.  A scheme only provides ``a``, the vector ``p`` and the kinematic update
of (V, A) from the new displacement.

Singular mass matrices are handled exactly: the dynamics only ever sees ``M V`` and
``M A`` (the rhs is ``M @ p``), so the values of V, A on massless dofs never enter.
On massless dofs the update stores V = (U^{n+1} - U^n)/dt and A = 0 (used for output).

Schemes
-------
``Newmark(beta, gamma)``:
    U^{n+1} = U^n + dt V^n + dt^2 ((1/2 - beta) A^n + beta A^{n+1})
    V^{n+1} = V^n + dt ((1 - gamma) A^n + gamma A^{n+1})
    a = 1/(beta dt^2), p = a U^n + V^n/(beta dt) + (1/(2 beta) - 1) A^n.
    ``crank-nicolson`` = Newmark(1/4, 1/2) (the seed's eq. (8)-(9)).
``Theta(theta)``:
    U^{n+1} = U^n + dt (theta V^{n+1} + (1-theta) V^n), same for V with A,
    a = 1/(theta dt)^2, p = a (U^n + dt V^n) + ((1-theta)/theta) A^n.
    ``backward-euler`` = Theta(1) (the seed's eq. (10)-(11)).

Energy identities (spec 6.3, re-derived; F constant, E = 1/2 V.MV + 1/2 U.SU - U.F):
    CN:  E^{n+1} - E^n = 1/2 (U^{n+1} - U^n)^T B^T (lambda^n + lambda^{n+1})
    BE:  E^{n+1} - E^n = -1/2 |V^{n+1}-V^n|_M^2 - 1/2 |U^{n+1}-U^n|_S^2
                         + (U^{n+1} - U^n)^T B^T lambda^{n+1}
The seed prints a leading minus on the contact terms; with its own conventions
(+B^T lambda, lambda <= 0) the sign is "+", which the test suite verifies to round-off.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError


class TimeScheme:
    """Base class; subclasses define :meth:`a`, :meth:`predictor` and :meth:`update`."""

    name: str = "scheme"

    def a(self, dt: float) -> float:
        raise NotImplementedError

    def predictor(self, U, V, A, dt: float) -> np.ndarray:
        """Vector p with rhs = M p + F + B^T lambda."""
        raise NotImplementedError

    def update(self, U, V, A, U_new, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """(V^{n+1}, A^{n+1}) from the kinematic relations."""
        raise NotImplementedError

    def energy_increment(self, dU, dV, lam_old, lam_new, BdU, MdV, SdU, R_old=None) -> float:
        """Right-hand side of the scheme's discrete energy identity (nan if none).

        ``R_old`` = F + B^T lambda^n - S U^n - M A^n, the equilibrium residual of the old
        state; it is zero except at n = 0 when massless dofs start out of equilibrium.
        """
        return float("nan")


@dataclass(frozen=True)
class Newmark(TimeScheme):
    beta: float = 0.25
    gamma: float = 0.5
    name: str = "newmark"

    def __post_init__(self):
        if not (0 < self.beta <= 0.5) or not (0 < self.gamma <= 1):
            raise InputError(
                f"Newmark needs 0 < beta <= 1/2 and 0 < gamma <= 1 (implicit), got {self.beta}, {self.gamma}"
            )

    def a(self, dt):
        return 1.0 / (self.beta * dt * dt)

    def predictor(self, U, V, A, dt):
        b = self.beta
        return (U + dt * V) / (b * dt * dt) + (0.5 / b - 1.0) * A

    def update(self, U, V, A, U_new, dt):
        b, g = self.beta, self.gamma
        A_new = (U_new - U - dt * V) / (b * dt * dt) - (0.5 / b - 1.0) * A
        V_new = V + dt * ((1 - g) * A + g * A_new)
        return V_new, A_new

    def energy_increment(self, dU, dV, lam_old, lam_new, BdU, MdV, SdU, R_old=None):
        if self.beta == 0.25 and self.gamma == 0.5:
            extra = 0.0 if R_old is None else -0.5 * float(dU @ R_old)
            return 0.5 * float(BdU @ (lam_old + lam_new)) + extra
        return float("nan")


@dataclass(frozen=True)
class Theta(TimeScheme):
    theta: float = 1.0
    name: str = "theta"

    def __post_init__(self):
        if not (0.5 <= self.theta <= 1.0):
            raise InputError(f"theta must satisfy 1/2 <= theta <= 1, got {self.theta}")

    def a(self, dt):
        return 1.0 / (self.theta * dt) ** 2

    def predictor(self, U, V, A, dt):
        th = self.theta
        return (U + dt * V) / (th * dt) ** 2 + (1 - th) / th * A

    def update(self, U, V, A, U_new, dt):
        th = self.theta
        V_new = (U_new - U - dt * (1 - th) * V) / (th * dt)
        A_new = (V_new - V - dt * (1 - th) * A) / (th * dt)
        return V_new, A_new

    def energy_increment(self, dU, dV, lam_old, lam_new, BdU, MdV, SdU, R_old=None):
        if self.theta == 1.0:
            return float(-0.5 * dV @ MdV - 0.5 * dU @ SdU + BdU @ lam_new)
        if self.theta == 0.5:
            extra = 0.0 if R_old is None else -0.5 * float(dU @ R_old)
            return 0.5 * float(BdU @ (lam_old + lam_new)) + extra
        return float("nan")


SCHEMES = {
    "crank-nicolson": lambda: Newmark(0.25, 0.5, name="crank-nicolson"),
    "backward-euler": lambda: Theta(1.0, name="backward-euler"),
}
ALIASES = {"cn": "crank-nicolson", "be": "backward-euler"}


def get_scheme(scheme: str | TimeScheme) -> TimeScheme:
    """Scheme by name (``crank-nicolson``/``cn``, ``backward-euler``/``be``) or instance."""
    if isinstance(scheme, TimeScheme):
        return scheme
    key = ALIASES.get(str(scheme).lower(), str(scheme).lower())
    if key not in SCHEMES:
        allowed = sorted(list(SCHEMES) + list(ALIASES))
        raise InputError(f"unknown scheme {scheme!r}; allowed: {', '.join(allowed)}")
    return SCHEMES[key]()

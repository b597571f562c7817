"""Exact solutions of the 1D bar with a clamped end and Signorini contact.

Problem: rho u_tt = E u_xx on (0, L), u(L, t) = u_D, contact at x = 0 with
u(0, t) >= 0, E u_x(0, t) <= 0, u(0, t) E u_x(0, t) = 0 (outward normal -1, so the
seed's nu.u <= g with g = 0).

Method (d'Alembert with reflection).  In scaled variables X = x/L, s = c t/L
(c = sqrt(E/rho)) every solution reads

    u(x, t) = u_D + f(s - X) - f(s + X - 2)

which satisfies the clamp for any f.  The initial data fix f on [-2, 0]; for s > 0
the boundary x = 0 gives, on free phases, f(s) = C - f(s - 2) (zero stress) and on
contact phases f(s) = f(s - 2) - u_D (zero displacement).  Contact starts when
u(0) reaches 0 and ends when the stress -2 E f'(s - 2)/L would become tensile.  For
piecewise-linear initial data f stays piecewise linear and the event times are found
exactly, so the construction below is exact (no time stepping) for any L, E, rho,
gap and velocity.  It reproduces spec 3.1 (period 3L/c, stress -E g/L on [L/c, 2L/c])
and spec 3.2 (impact at g/v, period 3L/c + g/v when g/v < L/c).
"""

from __future__ import annotations

import bisect

import numpy as np


class ExactBar1D:
    """Exact solution built from f on [-2, 0] given by breakpoints (s, f)."""

    def __init__(self, L: float, E: float, rho: float, u_D: float, s0, f0, T: float):
        self.L, self.E, self.rho, self.u_D = float(L), float(E), float(rho), float(u_D)
        self.c = float(np.sqrt(E / rho))
        self.energy0 = None
        s_end = self.c * T / self.L + 2.0
        s, f = list(map(float, s0)), list(map(float, f0))
        self._march(s, f, s_end)
        self.s = np.array(s)
        self.f = np.array(f)
        self.slope = np.diff(self.f) / np.diff(self.s)

    # -- construction ---------------------------------------------------------------
    def _f(self, s, f, x):
        return float(np.interp(x, s, f))

    def _march(self, s: list, f: list, s_end: float) -> None:
        uD = self.u_D
        t = 0.0
        contact = (uD + f[-1] - self._f(s, f, -2.0)) <= 0.0
        C = f[-1] + self._f(s, f, -2.0)
        while t < s_end - 1e-14:
            j = bisect.bisect_right(s, t - 2.0 + 1e-14)
            t_end = min(s[j] + 2.0 if j < len(s) else s_end, s_end)
            p = (self._f(s, f, t_end - 2.0) - self._f(s, f, t - 2.0)) / (t_end - t) if t_end > t else 0.0
            if contact:
                if p < 0.0:  # stress -2 E p / L would be tensile: release
                    contact = False
                    C = self._f(s, f, t) + self._f(s, f, t - 2.0)
                    continue
                t = t_end
                val = self._f(s, f, t - 2.0) - uD
                s.append(t)
                f.append(val)
            else:
                val = uD + C - 2.0 * self._f(s, f, t - 2.0)
                if p > 0.0 and val - 2.0 * p * (t_end - t) < 0.0:
                    t_hit = t + val / (2.0 * p)
                    if t_hit > t:
                        val = C - self._f(s, f, t_hit - 2.0)
                        s.append(t_hit)
                        f.append(val)
                    t = t_hit
                    contact = True
                    continue
                t = t_end
                val = C - self._f(s, f, t - 2.0)
                s.append(t)
                f.append(val)

    # -- constructors ---------------------------------------------------------------
    @classmethod
    def bar1d(cls, L=1.0, E=1.0, rho=1.0, gap=0.5, T=12.0) -> ExactBar1D:
        """Spec 3.1: u0 = gap (1 - x/L), v0 = 0, u(L) = 0.  f' = gap/2 on (-2, 0)."""
        ex = cls(L, E, rho, 0.0, [-2.0, -1.0, 0.0], [0.0, gap / 2, gap], T)
        ex.energy0 = 0.5 * E * gap**2 / L
        return ex

    @classmethod
    def bar1d_impact(cls, L=1.0, E=1.0, rho=1.0, gap=0.2, velocity=0.5, T=12.0) -> ExactBar1D:
        """Spec 3.2: u0 = gap, v0 = -velocity, u(L) = gap.  f' = -+ v L/(2c)."""
        c = np.sqrt(E / rho)
        k = velocity * L / (2 * c)
        ex = cls(L, E, rho, gap, [-2.0, -1.0, 0.0], [0.0, k, 0.0], T)
        ex.energy0 = 0.5 * rho * velocity**2 * L
        return ex

    # -- evaluation -----------------------------------------------------------------
    def _fp(self, x: np.ndarray) -> np.ndarray:
        i = np.clip(np.searchsorted(self.s, x + 1e-12, side="right") - 1, 0, self.slope.size - 1)
        return self.slope[i]

    def _args(self, x, t):
        X = np.asarray(x, dtype=float) / self.L
        s = self.c * np.asarray(t, dtype=float) / self.L
        return s - X, s + X - 2.0

    def u(self, x, t) -> np.ndarray:
        """Displacement u(x, t) (broadcasting x and t)."""
        a, b = self._args(x, t)
        return self.u_D + np.interp(a, self.s, self.f) - np.interp(b, self.s, self.f)

    def u_x(self, x, t) -> np.ndarray:
        """Strain u_x(x, t) (right-continuous in time)."""
        a, b = self._args(x, t)
        return (-self._fp(a) - self._fp(b)) / self.L

    def u_t(self, x, t) -> np.ndarray:
        """Velocity u_t(x, t)."""
        a, b = self._args(x, t)
        return self.c * (self._fp(a) - self._fp(b)) / self.L

    def contact_displacement(self, t) -> np.ndarray:
        """u(0, t) >= 0 (equals the gap to the obstacle)."""
        return self.u(0.0, t)

    def contact_stress(self, t) -> np.ndarray:
        """sigma_n(0, t) = E u_x(0, t) <= 0; equals the exact nodal multiplier lambda."""
        return self.E * self.u_x(0.0, t)

    def energy(self, t) -> np.ndarray:
        """Total energy per unit cross-section (constant in time)."""
        return np.full(np.shape(t), self.energy0, dtype=float)

"""Exact solutions of the 1D bar with a clamped end and Signorini contact.

Problem: rho u_tt = E u_xx on (0, L), clamp u(L, t) = u_D + b t, contact at x = 0
against an obstacle moving as o(t) = w t:

    u(0, t) >= o(t),   E u_x(0, t) <= 0,   (u(0, t) - o(t)) E u_x(0, t) = 0

(outward normal -1, so the seed's nu.u <= g with g = -o).  b = ``clamp_velocity`` and
w = ``obstacle_velocity`` default to 0 (fixed clamp and obstacle).

Method (d'Alembert with reflection).  In scaled variables X = x/L, s = c t/L
(c = sqrt(E/rho)), with beta = b L/c and omega = w L/c (so b t = beta s, w t = omega s),
every solution reads

    u(x, t) = u_D + beta s + f(s - X) - f(s + X - 2)

which solves the wave equation and satisfies the clamp for any f.  The initial data fix
f on [-2, 0]; for s > 0 the boundary x = 0 gives, on free phases, f(s) = C - f(s - 2)
(zero stress, C fixed by continuity of f) and on contact phases
f(s) = f(s - 2) - u_D - (beta - omega) s (u(0) = o).  With p the slope of f(s - 2):

* free phase: the gap u(0) - o = u_D + (beta - omega) s + C - 2 f(s - 2) changes at
  the rate (beta - omega) - 2 p; contact starts at the exact zero of this linear
  function;
* contact phase: the stress is E u_x(0) = -E (2 p - beta + omega)/L; contact ends at
  the first kink of f(s - 2) after which 2 p - beta + omega < 0 (tensile).

For piecewise-linear initial data f stays piecewise linear and the event times are
found exactly, so the construction is exact (no time stepping) for any L, E, rho, gap,
velocity, b and w.  It reproduces spec 3.1 (period 3L/c, stress -E g/L on
[L/c, 2L/c]) and spec 3.2 (impact at g/v, period 3L/c + g/v when g/v < L/c).  The
derivation is written up in ``docs/exact_solutions.md``.
"""

from __future__ import annotations

import bisect

import numpy as np


class ExactBar1D:
    """Exact solution built from f on [-2, 0] given by breakpoints (s, f).

    ``clamp_velocity`` b and ``obstacle_velocity`` w make the clamp u(L, t) = u_D + b t
    and the obstacle o(t) = w t move at constant velocity.  Note that f on [-2, 0]
    describes the initial data *together with* the b t term: u_t(x, 0) =
    b + c (f'(-X) - f'(X - 2))/L.
    """

    def __init__(
        self,
        L: float,
        E: float,
        rho: float,
        u_D: float,
        s0,
        f0,
        T: float,
        clamp_velocity: float = 0.0,
        obstacle_velocity: float = 0.0,
    ):
        self.L, self.E, self.rho, self.u_D = float(L), float(E), float(rho), float(u_D)
        self.c = float(np.sqrt(E / rho))
        self.clamp_velocity = float(clamp_velocity)
        self.obstacle_velocity = float(obstacle_velocity)
        self.T = float(T)
        self.energy0 = None
        s_end = self.c * T / self.L + 2.0
        s, f = list(map(float, s0)), list(map(float, f0))
        self._march(s, f, s_end)
        self.s = np.array(s)
        self.f = np.array(f)
        self.slope = np.diff(self.f) / np.diff(self.s)
        #: exact events on [0, T] as (t, "contact" | "release") in physical time
        self.events = [(e * self.L / self.c, k) for e, k in self._events if e * self.L / self.c <= self.T]

    # -- construction ---------------------------------------------------------------
    def _f(self, s, f, x):
        return float(np.interp(x, s, f))

    def _march(self, s: list, f: list, s_end: float) -> None:
        uD = self.u_D
        # scaled drift of the gap u(0) - o: (beta - omega) s with beta = b L/c, omega = w L/c
        d = (self.clamp_velocity - self.obstacle_velocity) * self.L / self.c
        t = 0.0
        contact = (uD + f[-1] - self._f(s, f, -2.0)) <= 0.0
        C = f[-1] + self._f(s, f, -2.0)
        self._events = [(0.0, "contact")] if contact else []
        while t < s_end - 1e-14:
            j = bisect.bisect_right(s, t - 2.0 + 1e-14)
            t_end = min(s[j] + 2.0 if j < len(s) else s_end, s_end)
            p = (self._f(s, f, t_end - 2.0) - self._f(s, f, t - 2.0)) / (t_end - t) if t_end > t else 0.0
            if contact:
                # stress -E (2 p - d)/L would be tensile: release.  The round-off margin
                # keeps grazing contact (2 p = d exactly, zero stress) from toggling.
                if 2.0 * p - d < -1e-12 * (abs(2.0 * p) + abs(d)):
                    contact = False
                    C = self._f(s, f, t) + self._f(s, f, t - 2.0)
                    self._events.append((t, "release"))
                    continue
                t = t_end
                val = self._f(s, f, t - 2.0) - uD - d * t
                s.append(t)
                f.append(val)
            else:
                val = uD + d * t + C - 2.0 * self._f(s, f, t - 2.0)  # gap u(0) - o at t
                rate = d - 2.0 * p  # d(gap)/ds on [t, t_end]
                if rate < 0.0 and val + rate * (t_end - t) < 0.0:
                    t_hit = max(t + val / -rate, t)
                    if t_hit > t:
                        val = C - self._f(s, f, t_hit - 2.0)
                        s.append(t_hit)
                        f.append(val)
                    t = t_hit
                    contact = True
                    self._events.append((t, "contact"))
                    continue
                t = t_end
                val = C - self._f(s, f, t - 2.0)
                s.append(t)
                f.append(val)

    # -- constructors ---------------------------------------------------------------
    @classmethod
    def bar1d(cls, L=1.0, E=1.0, rho=1.0, gap=0.5, T=12.0, clamp_velocity=0.0, obstacle_velocity=0.0) -> ExactBar1D:
        """Spec 3.1: u0 = gap (1 - x/L), v0 = 0, u(L, t) = b t, obstacle w t.

        f' = gap/2 on (-2, 0) when b = 0; a clamp velocity b adds -+ b L/(2c) on
        (-1, 0) / (-2, -1) so that v0 stays 0 on (0, L)."""
        c = np.sqrt(E / rho)
        a = clamp_velocity * L / (2 * c)
        s0, f0 = [-2.0, -1.0, 0.0], [0.0, gap / 2 + a, gap]
        ex = cls(L, E, rho, 0.0, s0, f0, T, clamp_velocity, obstacle_velocity)
        ex.energy0 = 0.5 * E * gap**2 / L
        return ex

    @classmethod
    def bar1d_impact(
        cls, L=1.0, E=1.0, rho=1.0, gap=0.2, velocity=0.5, T=12.0, clamp_velocity=0.0, obstacle_velocity=0.0
    ) -> ExactBar1D:
        """Spec 3.2: u0 = gap, v0 = -velocity, u(L, t) = gap + b t, obstacle w t.

        f' = -+ (velocity + b) L/(2c) on (-1, 0) / (-2, -1)."""
        c = np.sqrt(E / rho)
        k = (velocity + clamp_velocity) * L / (2 * c)
        ex = cls(L, E, rho, gap, [-2.0, -1.0, 0.0], [0.0, k, 0.0], T, clamp_velocity, obstacle_velocity)
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
        return (
            self.u_D
            + self.clamp_velocity * np.asarray(t, dtype=float)
            + np.interp(a, self.s, self.f)
            - np.interp(b, self.s, self.f)
        )

    def u_x(self, x, t) -> np.ndarray:
        """Strain u_x(x, t) (right-continuous in time)."""
        a, b = self._args(x, t)
        return (-self._fp(a) - self._fp(b)) / self.L

    def u_t(self, x, t) -> np.ndarray:
        """Velocity u_t(x, t)."""
        a, b = self._args(x, t)
        return self.clamp_velocity + self.c * (self._fp(a) - self._fp(b)) / self.L

    def obstacle_position(self, t) -> np.ndarray:
        """o(t) = w t: the constraint is u(0, t) >= o(t)."""
        return self.obstacle_velocity * np.asarray(t, dtype=float)

    def clamp_displacement(self, t) -> np.ndarray:
        """u(L, t) = u_D + b t."""
        return self.u_D + self.clamp_velocity * np.asarray(t, dtype=float)

    def contact_displacement(self, t) -> np.ndarray:
        """u(0, t) >= o(t) (with a fixed obstacle: the gap to the obstacle)."""
        return self.u(0.0, t)

    def gap(self, t) -> np.ndarray:
        """u(0, t) - o(t) >= 0."""
        return self.u(0.0, t) - self.obstacle_position(t)

    def contact_stress(self, t) -> np.ndarray:
        """sigma_n(0, t) = E u_x(0, t) <= 0; equals the exact nodal multiplier lambda."""
        return self.E * self.u_x(0.0, t)

    def clamp_stress(self, t) -> np.ndarray:
        """E u_x(L, t): the traction the clamp exerts on the bar (outward normal +1)."""
        return self.E * self.u_x(self.L, t)

    def power(self, t) -> np.ndarray:
        """dE/dt = b E u_x(L, t) - w E u_x(0, t): power of the clamp plus the obstacle."""
        return self.clamp_velocity * self.clamp_stress(t) - self.obstacle_velocity * self.contact_stress(t)

    def energy(self, t) -> np.ndarray:
        """Total energy per unit cross-section 1/2 int (rho u_t^2 + E u_x^2) dx at t.

        Exact: u_t and u_x are constant in x between the points where s - X or
        s + X - 2 meets a breakpoint of f, so the integral is a finite sum.  Equals
        ``energy0`` (to round-off) when b = w = 0."""
        tt = np.asarray(t, dtype=float)
        out = np.empty(tt.shape)
        for idx, ti in np.ndenumerate(tt):
            s = self.c * ti / self.L
            X = np.concatenate(([0.0, 1.0], s - self.s, self.s + 2.0 - s))
            X = np.unique(X[(X >= 0.0) & (X <= 1.0)])
            w = np.diff(X)
            m = 0.5 * (X[1:] + X[:-1])
            fa = self.slope[np.clip(np.searchsorted(self.s, s - m, side="right") - 1, 0, self.slope.size - 1)]
            fb = self.slope[np.clip(np.searchsorted(self.s, s + m - 2.0, side="right") - 1, 0, self.slope.size - 1)]
            ut = self.clamp_velocity + self.c * (fa - fb) / self.L
            ux = -(fa + fb) / self.L
            out[idx] = 0.5 * self.L * np.sum(w * (self.rho * ut**2 + self.E * ux**2))
        return out

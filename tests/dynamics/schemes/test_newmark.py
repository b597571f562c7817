"""Newmark's local error estimate from the steps' mean accelerations (``dynamics/schemes/newmark.py``, issue 52)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from signorini.dynamics.schemes.base import State
from signorini.dynamics.schemes.newmark import CrankNicolson


def levels(t0: float, dt: float, dt_before: float, c: np.ndarray) -> tuple[State, State]:
    """Two Crank–Nicolson levels t0 and t0 + dt of a motion whose acceleration is A = 6 c t (U = c t^3's), each
    with the mean acceleration of the step before it: U and V from the scheme's own update, U^{n+1} = U^n + dt V^n +
    dt^2/4 (A^n + A^{n+1}), V^{n+1} = V^n + dt/2 (A^n + A^{n+1}), so that its mean acceleration over a step of h
    ending at t is 6 c (t - h/2)."""
    A0, A1 = 6.0 * c * t0, 6.0 * c * (t0 + dt)
    U0, V0 = c * t0**3, 3.0 * c * t0**2
    V1 = V0 + 0.5 * dt * (A0 + A1)
    U1 = U0 + dt * V0 + 0.25 * dt * dt * (A0 + A1)
    old = State(t0, U0, V0, A0, np.zeros(0), None, extra={"mean_acceleration": 6.0 * c * (t0 - 0.5 * dt_before)})
    new = State(t0 + dt, U1, V1, A1, np.zeros(0), None, extra={"mean_acceleration": (V1 - V0) / dt})
    return old, new


@pytest.mark.parametrize("ratio", [0.125, 0.5, 1.0, 2.0, 8.0])
def test_the_estimate_is_the_former_one_on_a_smooth_motion_whatever_the_two_steps(ratio):
    """A = 6 c t: the former estimate is (beta - 1/6) dt^2 (A^{n+1} - A^n) = (beta - 1/6) dt^2 6 c dt; the mean
    accelerations' difference is 3 c (dt + dt_before), which the factor 2 dt / (dt + dt_before) brings back to 6 c dt
    for a step after a halving (ratio 2: 1.5 times too large without it), a growth or a cascade of halvings (ratio 8:
    4.5 times).  Without dt_before, or on massless dofs, the former estimate itself."""
    scheme = CrankNicolson()
    c, dt = np.array([1.0, -2.0, 0.5]), 0.01
    ctx = SimpleNamespace(dt=dt, massless=np.array([], dtype=int), rotated_kernel=False)
    old, new = levels(0.3, dt, ratio * dt, c)
    former = (0.25 - 1.0 / 6.0) * dt * dt * 6.0 * c * dt
    assert np.allclose(scheme.local_error(ctx, old, new, ratio * dt), former, rtol=1e-9, atol=0.0)
    assert np.allclose(scheme.local_error(ctx, old, new, None), former, rtol=1e-9, atol=0.0)
    ctx.massless = np.array([1])
    assert np.allclose(scheme.local_error(ctx, old, new, ratio * dt), former, rtol=1e-9, atol=0.0)


def test_an_alternating_acceleration_that_moves_neither_u_nor_v_is_not_an_error():
    """A level pair at rest whose A alternates (+a, -a: Crank–Nicolson's U and V see only A's mean over a step, 0):
    the former estimate reads (beta - 1/6) dt^2 2a, the mean accelerations' none (the resting damped block of
    tests/data/resting_steel_block.toml was held at dt/8 by it, issue 52)."""
    scheme = CrankNicolson()
    a, dt = np.array([3.0, -1.0]), 1e-3
    U, V, z = np.zeros(2), np.zeros(2), np.zeros(2)
    old = State(0.5, U, V, -a, np.zeros(0), None, extra={"mean_acceleration": z})
    new = State(0.5 + dt, U, V, a, np.zeros(0), None, extra={"mean_acceleration": z})
    ctx = SimpleNamespace(dt=dt, massless=np.array([], dtype=int), rotated_kernel=False)
    assert np.abs(scheme.local_error(ctx, old, new, dt)).max() == 0.0
    assert np.allclose(
        scheme.local_error(ctx, old, new, None), (0.25 - 1.0 / 6.0) * dt * dt * 2 * a, rtol=1e-12, atol=0
    )

"""``collision1d``: two equal free elastic bars, one moving towards the other at rest.

Bar A on (0, L) moves at ``velocity`` v towards bar B on (L + gap, 2 L + gap), at rest;
no support, no load (E, rho, unit cross-section A = 1, c = sqrt(E / rho)).  The exact
solution of two equal bars: contact starts at t_0 = gap / v, lasts 2 L / c (the wave's
round trip), the contact force is the plateau A rho c v / 2 (each bar's end stops at v/2),
and after it the bars have exchanged their velocities (A at rest, B at v): the kinetic
energy and the momentum 1/2 rho A L v^2 and rho A L v are kept.

The pair: the left end of B (``right_xmin``, slave) against the right end of A
(``left_xmax``, master); in 1D the master facet is a node, so the discrete condition is the
node-to-node gap (x_B - x_A) - (u_B - u_A) >= 0.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..contact.pairs import ContactPair
from ..dynamics.model.problem import Problem
from ..dynamics.observe.observers import Observer
from ..errors import InputError
from ..fem.material import IsotropicElastic
from ..fem.mesh import interval, join

COLLISION_DEFAULTS = {"L": 1.0, "gap": 0.1, "velocity": 0.5, "E": 1.0, "rho": 1.0, "order": 1.0}


def check_params(p: dict) -> None:
    """gap >= 0 and velocity > 0 (the bars must meet)."""
    if p["velocity"] <= 0:
        raise InputError(
            f"parameter 'velocity' of collision1d must be > 0 (bar A moves towards B), got {p['velocity']}"
        )


def build(n: int, p: dict) -> Problem:
    """Level n: n P1 cells per bar (``order`` 2: P2)."""
    L, g, v = p["L"], p["gap"], p["velocity"]
    a, b = interval(n, L, order=int(p["order"])), interval(n, L, order=int(p["order"]))
    b.points = b.points + (L + g)
    mesh = join({"left": a, "right": b})
    x_mid = L + 0.5 * g

    def v0(x: np.ndarray) -> np.ndarray:
        return np.where(x[:, 0] < x_mid, v, 0.0)[:, None]

    return Problem(
        mesh,
        IsotropicElastic.from_young(p["E"], 0.0, p["rho"]),
        None,
        None,
        u0=0.0,
        v0=v0,
        pairs=[ContactPair("right_xmin", "left_xmax")],
        name="collision1d",
    )


def exact(p: dict) -> dict:
    """The closed-form values (see the module docstring)."""
    c = float(np.sqrt(p["E"] / p["rho"]))
    return {
        "contact_start": p["gap"] / p["velocity"],
        "contact_duration": 2.0 * p["L"] / c,
        "contact_force": p["rho"] * c * p["velocity"] / 2.0,
        "final_velocities": [0.0, p["velocity"]],
        "energy": 0.5 * p["rho"] * p["L"] * p["velocity"] ** 2,
    }


def run_times(n: int, p: dict) -> tuple[float, float]:
    """dt = h / 2 (h = L / n, c = 1 units: CFL 1/2); T: the impact and as long again after it."""
    c = float(np.sqrt(p["E"] / p["rho"]))
    h = p["L"] / n
    dt = h / (2 * c)
    T = p["gap"] / p["velocity"] + 4.0 * p["L"] / c
    return dt, dt * np.ceil(T / dt - 1e-9)


def sizes(n: int, p: dict) -> tuple[float, int, int, int, int]:
    q = int(p["order"])
    return p["L"] / n, 2 * (q * n + 1), 2 * n, q + 1, 1


class CollisionMeasure:
    """Contact start, duration and mean force (over the middle half of the contact), the bars'
    mean velocities after it, beside the exact ones (summary ``collision``)."""

    def __init__(self, params: dict):
        self.params = dict(params)

    def observers(self) -> list[Observer]:
        return []

    def summary(self, H) -> dict:
        ex = exact(self.params)
        out: dict = {"exact": ex}
        f = -H.lambda_sum
        on = np.flatnonzero(f > 0)
        if on.size:
            t0, t1 = H.t[on[0]], H.t[on[-1]]
            dt = H.t[1] - H.t[0]
            mid = (H.t >= t0 + 0.25 * (t1 - t0)) & (H.t <= t1 - 0.25 * (t1 - t0))
            out.update(
                contact_start=float(t0),  # the first level with a contact force (within a step of the start)
                contact_duration=float(t1 - t0 + dt),
                mean_force_middle=float(f[mid].mean()) if mid.any() else None,
                force_definition="mean of the total contact force over the middle half of the contact",
            )
        bodies = H.meta.get("bodies") or []
        if len(bodies) == 2 and all("momentum" in b for b in bodies):
            out["final_velocities"] = [b["momentum"][0] / b["mass"] for b in bodies]
        E = H.energy
        out["energy_ratio_final"] = float(E[-1] / E[0]) if E[0] else None
        return {"collision": out}

    @staticmethod
    def text(summary: dict) -> str:
        s = summary["collision"]
        ex = s["exact"]
        if "contact_duration" not in s:
            return f"  collision: no contact in the run (exact contact starts at t = {ex['contact_start']:.6g})"
        v = s.get("final_velocities") or [float("nan")] * 2
        fm = s["mean_force_middle"]
        return (
            f"  collision: contact from t = {s['contact_start']:.6g} (exact {ex['contact_start']:.6g}) for "
            f"{s['contact_duration']:.6g} (exact 2L/c = {ex['contact_duration']:.6g}); mean force "
            f"{fm if fm is not None else float('nan'):.6g} (exact rho c v / 2 = {ex['contact_force']:.6g}); "
            f"final velocities {v[0]:.4g}, {v[1]:.4g} (exact {ex['final_velocities'][0]:g}, "
            f"{ex['final_velocities'][1]:g}); E(T)/E(0) = {s['energy_ratio_final']:.6g}"
        )


def measure() -> Callable[[dict], CollisionMeasure]:
    return CollisionMeasure

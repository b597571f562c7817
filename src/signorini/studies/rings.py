"""The benchmark ``rings2d`` (issue 41): two Neo-Hookean rings colliding, the classic test of energy-momentum
contact schemes (plane strain, a contact pair in the current configuration, large deformations).

Two equal rings of outer radius ``R`` and inner radius ``inner`` R, each a grid of 32 n x 2 n quadrilaterals in
(angle, radius) closed on itself (no gmsh), ``gap`` apart along x and offset by ``offset`` R along y (an
oblique impact: the rings leave spinning), thrown towards each other at ``velocity`` each.  The pair: the left
ring's outer circle (slave) against the right ring's (master).  The summary (``rings``) gives the largest drifts
of the energy, of the linear and of the angular momentum over the run, the contact's duration and the peak
of the contact force: with the default mass the rings' outer circles are massless (they are the pair's
sides), so energy-momentum keeps the momenta to O(dt^2) there; ``--mass standard`` keeps them to the Newton
tolerance and shows the contact force's oscillation.

Parameters: ``R`` = 1, ``inner`` = 0.8, ``E`` = 100, ``nu`` = 0.3, ``rho`` = 1, ``velocity`` = 1 (about a tenth
of the wave speed), ``gap`` = 0.02, ``offset`` = 0.3.  Level n (default 1): 32 n x 2 n cells a ring; default
dt = 1 / (400 n), T = 1 (at 1 / (200 n) the energy drifts by 2.4e-3 over the run: docs/finite_strain.md).
"""

from __future__ import annotations

import math

import numpy as np

from ..contact.pairs import ContactPair
from ..dynamics.model.problem import Problem, RegionInitial
from ..errors import InputError
from ..fem.material import NeoHookean
from ..fem.mesh import Mesh, join

RINGS_DEFAULTS = {
    "R": 1.0,
    "inner": 0.8,
    "E": 100.0,
    "nu": 0.3,
    "rho": 1.0,
    "velocity": 1.0,
    "gap": 0.02,
    "offset": 0.3,
    "order": 1.0,
}


def check_params(p: dict) -> None:
    """0 < inner < 1, Poisson ratio in (-1, 1/2), |offset| < 1 (gap >= 0: the common check)."""
    if not 0.0 < p["inner"] < 1.0:
        raise InputError(f"parameter 'inner' (inner radius / R) must be in (0, 1), got {p['inner']}")
    if not -1.0 < p["nu"] < 0.5:
        raise InputError(f"parameter 'nu' must be in (-1, 0.5), got {p['nu']}")
    if not abs(p["offset"]) < 1.0:
        raise InputError(f"parameter 'offset' (a fraction of R) must be in (-1, 1), got {p['offset']}")


def ring(n_angle: int, n_radius: int, R: float, r: float, order: int = 1) -> Mesh:
    """A ring of quadrilaterals centred at the origin: ``n_angle`` x ``n_radius`` cells in (angle, radius), the
    grid closed on itself; facet tags ``outer`` and ``inner``.  ``order`` 2: quad9 cells on the grid of half the
    spacing in (angle, radius), every node on its circle (the cells curved)."""
    k = order  # nodes per cell side - 1
    na, nr = k * n_angle, k * n_radius
    theta = 2 * math.pi * np.arange(na) / na
    radius = np.linspace(r, R, nr + 1)
    points = np.column_stack([np.outer(radius, np.cos(theta)).ravel(), np.outer(radius, np.sin(theta)).ravel()])
    i, j = np.meshgrid(np.arange(n_angle), np.arange(n_radius), indexing="ij")
    i, j = k * i.ravel(), k * j.ravel()
    node = lambda a, b: b * na + a % na  # noqa: E731
    cells = np.column_stack([node(i, j), node(i, j + k), node(i + k, j + k), node(i + k, j)])  # counter-clockwise
    a = k * np.arange(n_angle)
    outer = np.column_stack([node(a, nr), node(a + k, nr)])
    inside = np.column_stack([node(a + k, 0), node(a, 0)])
    if order == 2:  # quad9: the midpoints of the edges (0,1), (1,2), (2,3), (3,0), then the centre
        cells = np.column_stack(
            [cells, node(i, j + 1), node(i + 1, j + 2), node(i + 2, j + 1), node(i + 1, j), node(i + 1, j + 1)]
        )
        outer = np.column_stack([outer, node(a + 1, nr)])
        inside = np.column_stack([inside, node(a + 1, 0)])
    return Mesh(points, cells, "quad" if order == 1 else "quad9", facets={"outer": outer, "inner": inside})


def build(n: int, p: dict) -> Problem:
    R, v = p["R"], p["velocity"]
    q = int(p["order"])
    a, b = ring(32 * n, 2 * n, R, p["inner"] * R, q), ring(32 * n, 2 * n, R, p["inner"] * R, q)
    shift = R + 0.5 * p["gap"]
    a.points = a.points + [-shift, -0.5 * p["offset"] * R]
    b.points = b.points + [shift, 0.5 * p["offset"] * R]
    mesh = join({"left": a, "right": b})
    return Problem(
        mesh,
        NeoHookean.from_young(p["E"], p["nu"], p["rho"]),
        None,
        None,
        pairs=[ContactPair("left_outer", "right_outer")],
        initial_regions=[RegionInitial("left", velocity=[v, 0.0]), RegionInitial("right", velocity=[-v, 0.0])],
        name="rings2d",
    )


def sizes(n: int, p: dict) -> tuple[float, int, int, int, int]:
    na, nr, q = 32 * n, 2 * n, int(p["order"])
    return 2 * math.pi * p["R"] / na, 2 * q * na * (q * nr + 1), 2 * na * nr, (q + 1) ** 2, q * na


def run_times(n: int, p: dict) -> tuple[float, float]:
    return 1.0 / (400 * n), 1.0


class RingsMeasure:
    """The drifts of the energy and of the momenta, the contact's duration and peak force (summary ``rings``)."""

    def __init__(self, params: dict):
        self.params = dict(params)

    def observers(self) -> list:
        return []

    def summary(self, H) -> dict:
        c = H.columns()
        E = c["energy"]
        P = np.column_stack([c["momentum_x"], c["momentum_y"]])
        L = c["angular_momentum_z"]
        on = np.flatnonzero(c["active_contacts"] > 0)
        scale = float(np.linalg.norm(P[0])) or float(np.abs(P).max()) or 1.0  # the bodies' momenta cancel
        each = float(self.params["rho"] * self.params["velocity"])  # a momentum scale per unit area
        return {
            "rings": {
                "energy_max_relative_drift": float(np.abs(E - E[0]).max() / abs(E[0])),
                "momentum_max_drift": float(np.abs(P - P[0]).max()),
                "momentum_scale": max(scale, each),
                "angular_momentum_max_drift": float(np.abs(L - L[0]).max()),
                "contact_start": float(H.t[on[0]]) if on.size else None,
                "contact_end": float(H.t[on[-1]]) if on.size else None,
                "peak_contact_force": float(-np.min(c["lambda_sum"])) if on.size else 0.0,
                "contact_at_T": bool(on.size and on[-1] == len(E) - 1),
                "definition": "drifts: max over the levels of |X^n - X^0| (momenta: absolute, the two rings' cancel); "
                "contact from the first to the last level with an active row",
            }
        }

    @staticmethod
    def text(summary: dict) -> str:
        s = summary["rings"]
        span = "no contact"
        if s["contact_start"] is not None:
            end = f"{s['contact_end']:.4g}" + (", still in contact at T" if s.get("contact_at_T") else "")
            span = (
                f"contact from t = {s['contact_start']:.4g} to {end} (the case's time unit), peak force "
                f"{s['peak_contact_force']:.4g} per unit thickness"
            )
        return (
            f"  rings: {span}; energy drift {s['energy_max_relative_drift']:.2e} of E0, linear momentum drift "
            f"{s['momentum_max_drift']:.2e}, angular momentum drift "
            f"{s['angular_momentum_max_drift']:.2e}"
        )


def measure(p: dict) -> RingsMeasure:
    return RingsMeasure(p)

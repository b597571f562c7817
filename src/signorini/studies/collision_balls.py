"""``collision2d`` / ``collision3d``: two elastic discs (plane strain) or balls of their own
radii and materials meeting head-on, against Hertz's quasi-static impact of two bodies.

Ball ``a`` (radius R1, E1, nu1, rho1) moves at ``velocity`` v towards ball ``b`` (R2, E2,
nu2, rho2) at rest; they touch at t = 0 at the origin, ``a`` above (x_d >= 0), ``b``
below.  Each is :func:`~signorini.fem.meshing.pole_refined_ball`'s mesh refined towards the
contact point (``b`` turned by 180 degrees); the pair is ``a_cap`` (slave) against
``b_cap`` (master); the regions ``a`` and ``b`` carry the two materials.

Hertz's two-body figures (K. L. Johnson, Contact Mechanics, 1985, sections 4.2, 5.6, 11.4):
the relative approach delta of the centres obeys m delta'' = -F(delta), delta(0) = 0,
delta'(0) = v, with

    1/E* = (1 - nu1^2)/E1 + (1 - nu2^2)/E2,   R = R1 R2 / (R1 + R2),   m = m1 m2 / (m1 + m2),

3D: F = (4/3) E* R^(1/2) delta^(3/2) (closed forms as for a ball on a plane, with these R,
E*, m: :func:`signorini.studies.hertz.hertz_prediction`'s formulas); 2D (per unit
thickness): the approach of two cylinders' axes under a line load P is the sum of each
body's (Johnson's eq. 5.36 form),

    delta(P) = (P / pi) sum_i k_i (2 ln(4 R_i / b) - 1),   k_i = (1 - nu_i^2)/E_i,
    b = (4 P R / (pi E*))^(1/2),

inverted and integrated numerically.  The same validity limits as
:mod:`signorini.studies.hertz` (a*/R << 1, v << c_p, t_c >> 2R/c_p for both bodies).

Measured: force = -sum lambda (total over the pair's rows), duration and peak as in
:func:`signorini.studies.hertz.measured`; approach = the relative displacement of the two
bodies' centres of mass (each from the run's mass matrix) along the line of centres.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from scipy.optimize import brentq

from ..contact.pairs import ContactPair
from ..dynamics.model.problem import Problem, RegionInitial
from ..dynamics.observe.observers import CentreOfMassRecorder, Observer
from ..errors import InputError
from ..fem.material import IsotropicElastic
from ..fem.mesh import join
from ..fem.meshing import estimate_counts, pole_refined_ball
from .hertz import (
    DEFINITIONS,
    SPHERE_DURATION_FACTOR,
    HertzPrediction,
    figure_rows,
    impact_ode,
    p_wave_speed,
    sphere_force,
)

BALLS_DEFAULTS = {
    "R1": 1.0,
    "R2": 1.0,
    "E1": 1.0,
    "E2": 1.0,
    "nu1": 0.3,
    "nu2": 0.3,
    "rho1": 1.0,
    "rho2": 1.0,
    "velocity": 0.002,
    "cap": 2.0,
    "far": 0.25,
    "grading": 0.5,
    "order": 1.0,
}
DEFAULT_LEVEL = {2: 8, 3: 2}
STEPS_PER_DURATION = 25
MAX_CONTACT_RATIO = 0.5


def check_params(p: dict) -> None:
    """Positive radii, moduli, densities and velocity; Poisson ratios in (-1, 1/2); cap > 1."""
    for k in ("R1", "R2", "E1", "E2", "rho1", "rho2", "velocity", "far", "grading"):
        if p[k] <= 0:
            raise InputError(f"parameter {k!r} must be > 0, got {p[k]}")
    for k in ("nu1", "nu2"):
        if not -1.0 < p[k] < 0.5:
            raise InputError(f"parameter {k!r} must be in (-1, 0.5), got {p[k]}")
    if p["cap"] <= 1:
        raise InputError(f"parameter 'cap' (cap radius / Hertz contact radius) must be > 1, got {p['cap']}")


def _compliances(p: dict) -> tuple[float, float]:
    return (1 - p["nu1"] ** 2) / p["E1"], (1 - p["nu2"] ** 2) / p["E2"]


def effective(dim: int, p: dict) -> tuple[float, float, float]:
    """(R, E*, m) of the pair: R1 R2/(R1 + R2), 1/(k1 + k2), m1 m2/(m1 + m2)."""
    k1, k2 = _compliances(p)
    R = p["R1"] * p["R2"] / (p["R1"] + p["R2"])
    vol = (lambda r: 4.0 / 3.0 * math.pi * r**3) if dim == 3 else (lambda r: math.pi * r**2)
    m1, m2 = p["rho1"] * vol(p["R1"]), p["rho2"] * vol(p["R2"])
    return R, 1.0 / (k1 + k2), m1 * m2 / (m1 + m2)


def line_approach(P: float, p: dict) -> float:
    """delta(P) of two cylinders under a line load P (the module docstring)."""
    if P <= 0:
        return 0.0
    R, Es, _ = effective(2, p)
    b = math.sqrt(4 * P * R / (math.pi * Es))
    k = _compliances(p)
    return P / math.pi * sum(ki * (2 * math.log(4 * Ri / b) - 1) for ki, Ri in zip(k, (p["R1"], p["R2"]), strict=True))


def line_force(delta: float, p: dict) -> float:
    """The inverse of :func:`line_approach` on its increasing branch (b below the turning width)."""
    if delta <= 0:
        return 0.0
    R, Es, _ = effective(2, p)
    k = _compliances(p)
    # d delta / dP = 0 where sum k_i ln(4 R_i / b) = sum k_i: b = exp(sum k_i ln(4 R_i) / sum k_i - 1); a margin e^-1
    b_top = math.exp(sum(ki * math.log(4 * Ri) for ki, Ri in zip(k, (p["R1"], p["R2"]), strict=True)) / sum(k) - 2)
    P_top = math.pi * Es * b_top**2 / (4 * R)
    if delta >= line_approach(P_top, p):
        raise ValueError("approach beyond the range of the line-contact law")
    return brentq(lambda P: line_approach(P, p) - delta, 0.0, P_top, xtol=1e-300, rtol=1e-14)


def prediction(dim: int, p: dict) -> HertzPrediction:
    """Hertz's two-body figures; an InputError when the contact would exceed 0.5 R."""
    R, Es, m = effective(dim, p)
    v = p["velocity"]
    if dim == 3:
        d = (15 * m * v**2 / (16 * Es * math.sqrt(R))) ** 0.4
        pred = HertzPrediction(
            d, float(sphere_force(d, R, Es)), SPHERE_DURATION_FACTOR * d / v, math.sqrt(R * d), m, Es, "two spheres"
        )
    else:
        try:
            d, F, tc = impact_ode(lambda x: line_force(x, p), m, v)
        except ValueError:
            raise InputError(f"velocity {v:g} is too large for Hertz's line-contact law; lower the velocity") from None
        law = "two discs: Johnson's line contact"
        pred = HertzPrediction(d, F, tc, math.sqrt(4 * F * R / (math.pi * Es)), m, Es, law)
    if pred.contact_radius > MAX_CONTACT_RATIO * min(p["R1"], p["R2"]):
        raise InputError(
            f"velocity {v:g}: Hertz's contact radius would be {pred.contact_radius:.3g} (> {MAX_CONTACT_RATIO} x the "
            "smaller radius); Hertz's theory needs a contact much smaller than the radii: lower the velocity"
        )
    return pred


def _cap(dim: int, p: dict, R: float) -> float:
    """Polar half-angle of a ball's contact cap: R sin theta = cap x a*."""
    return math.asin(min(1.0, p["cap"] * prediction(dim, p).contact_radius / R))


def _sizes(dim: int, n: int, p: dict, R: float) -> tuple[float, float, float]:
    a = prediction(dim, p).contact_radius
    h_far = p["far"] * R
    return min(a / n, h_far), h_far, R * math.sin(_cap(dim, p, R))


def builder(dim: int) -> Callable[[int, dict], Problem]:
    def build(n: int, p: dict) -> Problem:
        balls = {}
        for name, R in (("a", p["R1"]), ("b", p["R2"])):
            h_c, h_far, r_fine = _sizes(dim, n, p, R)
            balls[name] = pole_refined_ball(dim, R, _cap(dim, p, R), h_c, h_far, r_fine, p["grading"], int(p["order"]))
        b = balls["b"]
        b.points = -b.points if dim == 2 else b.points * np.array([-1.0, 1.0, -1.0])  # turned by 180 degrees
        mesh = join(balls)
        e = np.eye(dim)[-1]
        mats = {k: IsotropicElastic.from_young(p[f"E{i}"], p[f"nu{i}"], p[f"rho{i}"]) for i, k in ((1, "a"), (2, "b"))}
        return Problem(
            mesh,
            mats["a"],
            None,
            None,
            materials={"b": mats["b"]},
            initial_regions=[RegionInitial("a", velocity=-p["velocity"] * e)],
            pairs=[ContactPair("a_cap", "b_cap")],
            name=f"collision{dim}d",
        )

    return build


def sizes(dim: int) -> Callable[[int, dict], tuple[float, int, int, int, int]]:
    def counts(n: int, p: dict) -> tuple[float, int, int, int, int]:
        total = [0, 0, 0]
        h = math.inf
        for R in (p["R1"], p["R2"]):
            h_c, h_far, r_fine = _sizes(dim, n, p, R)
            h = min(h, h_c)
            for k, c in enumerate(estimate_counts(dim, R, h_c, h_far, r_fine, p["grading"])):
                total[k] += c
        if p["order"] == 2:  # about 2^d nodes per vertex (a simplicial mesh's edges), 2^(d-1) per contact vertex
            return h, total[0] * 2**dim, total[1], (dim + 1) * (dim + 2) // 2, total[2] * 2 ** (dim - 1) // 2
        return h, total[0], total[1], dim + 1, total[2] // 2

    return counts


def run_times(dim: int) -> Callable[[int, dict], tuple[float, float]]:
    """Default (dt, T): dt = t_c / (25 n), T = 1.5 t_c (rounded up to a step)."""

    def times(n: int, p: dict) -> tuple[float, float]:
        tc = prediction(dim, p).duration
        dt = tc / (STEPS_PER_DURATION * n)
        return dt, math.ceil(1.5 * STEPS_PER_DURATION * n) * dt

    return times


class BallsMeasure:
    """Observers (the two centres of mass) and ``summary.json`` ``hertz`` of a two-ball run:
    ``predicted``, ``computed``, ``relative_deviation`` and ``validity`` as for ``hertz3d``."""

    def __init__(self, dim: int, params: dict):
        self.dim, self.params = dim, dict(params)
        self.pred = prediction(dim, params)
        e = np.eye(dim)[-1]
        self.coms = [CentreOfMassRecorder(e, r) for r in ("a", "b")]

    def observers(self) -> list[Observer]:
        return self.coms

    def summary(self, H) -> dict:
        from .hertz import _contact_radius

        force = -H.lambda_sum
        dt = float(H.t[1] - H.t[0]) if H.t.size > 1 else 0.0
        on = np.flatnonzero(force > 1e-12 * max(float(force.max(initial=0.0)), 1e-300))
        comp: dict = {
            "duration": float((on[-1] - on[0] + 1) * dt) if on.size else 0.0,
            "peak_force": float(force.max(initial=0.0)),
            "contact_levels": int(on.size),
            "contact_ended": bool(on.size and on[-1] < force.size - 1),
        }
        if self.coms and self.coms[0].position.size == H.t.size:
            a, b = self.coms
            approach = -((a.position - a.position[0]) - (b.position - b.position[0]))
            v_rel = b.velocity - a.velocity  # closing speed along the line of centres
            comp["max_approach"] = float(approach.max(initial=0.0))
            comp["restitution"] = float(-v_rel[-1] / v_rel[0]) if v_rel[0] else None
        comp["contact_radius"] = _contact_radius(H)
        pred = {k: getattr(self.pred, k) for k in ("max_approach", "peak_force", "duration", "contact_radius")}
        dev = {k: (comp[k] / pred[k] - 1.0 if comp.get(k) is not None else None) for k in pred if k in comp}
        p = self.params
        validity = {}
        for i in (1, 2):
            c = p_wave_speed(p[f"E{i}"], p[f"nu{i}"], p[f"rho{i}"])
            validity[f"velocity_over_wave_speed_{i}"] = p["velocity"] / c
            validity[f"wave_transit_over_duration_{i}"] = 2 * p[f"R{i}"] / c / self.pred.duration
        validity["contact_radius_over_R"] = self.pred.contact_radius / effective(self.dim, p)[0]
        definitions = {
            **DEFINITIONS,
            "approach": "relative displacement of the two balls' centres of mass (the "
            "run's mass matrix) along the line of centres",
        }
        return {
            "hertz": {
                "law": self.pred.law,
                "per_unit_thickness": self.dim == 2,
                "mass": self.pred.mass,
                "E_star": self.pred.E_star,
                "R_effective": effective(self.dim, p)[0],
                "predicted": pred,
                "computed": comp,
                "relative_deviation": dev,
                "validity": validity,
                "definitions": definitions,
            }
        }

    @staticmethod
    def text(summary: dict) -> str:
        h = summary["hertz"]
        unit = " per unit thickness" if h["per_unit_thickness"] else ""
        rows = [
            f"  Hertz ({h['law']}{unit}, R = {h['R_effective']:.4g}, E* = {h['E_star']:.4g}, m = {h['mass']:.4g}): "
            "quasi-static prediction vs computed",
            *figure_rows(h),
        ]
        r = h["computed"].get("restitution")
        if r is not None:
            rows.append(f"    restitution {r:.4g} (relative velocity of the centres after / before)")
        return "\n".join(rows)


def measure(dim: int) -> Callable[[dict], BallsMeasure]:
    return lambda p: BallsMeasure(dim, p)

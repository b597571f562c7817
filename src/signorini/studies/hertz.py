"""Quasi-static Hertz impact of an elastic ball (3D) or disc (2D, plane strain) on a
rigid plane, and the same figures measured on a run.

Predictions (:func:`hertz_prediction`)
--------------------------------------
The body (mass m, speed v towards the plane) is a rigid mass whose centre approaches
the plane by delta(t) under the static contact force F(delta) of Hertz's theory:

    m delta'' = -F(delta),   delta(0) = 0,   delta'(0) = v.

Maximum approach delta*: (1/2) m v^2 = int_0^delta* F; peak force F* = F(delta*); contact
duration t_c = 2 int_0^delta* d delta / sqrt(v^2 - (2/m) int_0^delta F) (the motion is
symmetric about delta*).

3D, sphere of radius R on a rigid plane, E* = E/(1 - nu^2), m = rho 4/3 pi R^3:
    F = (4/3) E* R^(1/2) delta^(3/2),
    delta* = (15 m v^2 / (16 E* R^(1/2)))^(2/5),   F* = (4/3) E* R^(1/2) delta*^(3/2),
    t_c = 2 I delta*/v,  I = int_0^1 (1 - x^(5/2))^(-1/2) dx = (2/5) B(2/5, 1/2) = 1.4716
    (t_c = 2.9432 delta*/v = 2.868 (m^2/(R E*^2 v))^(1/5)), contact radius a* = (R delta*)^(1/2)
    (K. L. Johnson, Contact Mechanics, 1985, sections 4.2 and 11.4).

2D, disc of radius R per unit thickness (plane strain), m = rho pi R^2: there is no
power law; the approach of the centre of a cylinder pressed on a plane by a force P
per unit length (Johnson 1985, section 5.6; the "Johnson model" of Pereira, Ramalho
and Ambrosio, Nonlinear Dyn. 63, 2011) is

    delta(P) = (P / (pi E*)) (2 ln(4 R / b) - 1),   b = (4 P R / (pi E*))^(1/2)

(b = half-width of the contact strip), which is inverted and integrated numerically.
It is a relation for a cylinder held by a diametrically opposite line load; an
impacting disc is held by its inertia, a body force, which changes the constant of the
logarithm by O(1) and so the prediction by a few per cent (docs/verification.md).

Validity (both): linear elasticity and small strain (a*/R << 1), frictionless contact,
quasi-static response (v much smaller than the wave speed c_p, contact duration much
longer than the time 2R/c_p an elastic wave takes to cross the body, so that the energy
left in vibrations is small).  ``validity`` reports v/c_p, a*/R and t_c c_p/(2R).

Measured on a run (:func:`measured`)
------------------------------------
force(t) = -sum_i lambda_i (total contact force, per unit thickness in 2D);
approach(t) = -(displacement of the centre of mass along the plane's normal), the
centre of mass of the discrete mass matrix M of the run, x_G = (E^T M U)/(E^T M E)
with E the rigid translation along the normal: its motion obeys m x_G'' = F exactly
when no other load acts, which is the quantity the 1-dof model above describes;
duration = dt x (number of levels with a nonzero force) from the first to the last
(an estimate within dt); peak force = max force; max approach = max approach(t);
restitution = final over initial normal velocity of the centre of mass.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq
from scipy.special import beta

from ..contact.friction import Friction
from ..contact.obstacles import PlaneObstacle
from ..dynamics.model.problem import Problem
from ..dynamics.observe.observers import CentreOfMassRecorder, Observer
from ..errors import InputError
from ..fem.material import IsotropicElastic
from ..fem.meshing import estimate_counts, pole_refined_ball

SPHERE_DURATION_FACTOR = 2 * 0.4 * beta(0.4, 0.5)  # 2 int_0^1 (1 - x^(5/2))^(-1/2) dx = 2.9432


@dataclass(frozen=True)
class HertzPrediction:
    """Quasi-static Hertz figures of one impact (per unit thickness in 2D)."""

    max_approach: float
    peak_force: float
    duration: float
    contact_radius: float  # a* (3D) or the half-width b* (2D) at the peak force
    mass: float
    E_star: float
    law: str


def effective_modulus(E: float, nu: float) -> float:
    """E* = E / (1 - nu^2) for an elastic body on a rigid plane."""
    return E / (1.0 - nu * nu)


def sphere_force(delta: np.ndarray | float, R: float, E_star: float) -> np.ndarray | float:
    """Hertz force of a sphere on a plane: F = (4/3) E* R^(1/2) delta^(3/2)."""
    return 4.0 / 3.0 * E_star * math.sqrt(R) * np.maximum(delta, 0.0) ** 1.5


def cylinder_approach(P: float, R: float, E_star: float) -> float:
    """Johnson's approach of a cylinder's axis under a line load P (per unit length):
    delta = P/(pi E*) (2 ln(4R/b) - 1), b = (4 P R/(pi E*))^(1/2)."""
    if P <= 0:
        return 0.0
    b = math.sqrt(4 * P * R / (math.pi * E_star))
    return P / (math.pi * E_star) * (2 * math.log(4 * R / b) - 1)


def cylinder_force(delta: float, R: float, E_star: float) -> float:
    """The inverse of :func:`cylinder_approach` on its increasing branch (b < 4R/e^2)."""
    if delta <= 0:
        return 0.0
    P_top = math.pi * E_star * (4 * R / math.e**2) ** 2 / (4 * R)  # dδ/dP = 0 there
    if delta >= cylinder_approach(P_top, R, E_star):
        raise ValueError("approach beyond the range of the line-contact law (b >= 4R/e^2)")
    return brentq(lambda P: cylinder_approach(P, R, E_star) - delta, 0.0, P_top, xtol=1e-300, rtol=1e-14)


def impact_ode(force: Callable[[float], float], m: float, v: float) -> tuple[float, float, float]:
    """(max approach, peak force, duration) of m delta'' = -F(delta), delta(0) = 0, delta'(0) = v.

    Integrated to the turning point delta' = 0 (an event) with rtol 1e-11; the duration
    is twice that time (a conservative, symmetric motion)."""

    def rhs(t, y):
        return [y[1], -force(y[0]) / m]

    def turning(t, y):
        return y[1]

    turning.terminal, turning.direction = True, -1
    scale = 100.0  # a time long enough to stop: the 1-dof model always turns back
    t_end = scale
    while True:
        sol = solve_ivp(rhs, (0.0, t_end), [0.0, v], rtol=1e-11, atol=1e-14 * max(v, 1e-300), events=turning)
        if sol.t_events[0].size:
            break
        t_end *= 10
    t_max, d_max = float(sol.t_events[0][0]), float(sol.y_events[0][0][0])
    return d_max, float(force(d_max)), 2 * t_max


def force_curve(dim: int, p: dict, t: np.ndarray) -> np.ndarray:
    """F(t) of the 1-dof Hertz impact (sphere or Johnson's disc law) at times t; 0 after t_c."""
    pred = _prediction(dim, p)
    R, Es, m, v = p["R"], pred.E_star, pred.mass, p["velocity"]
    law = (lambda x: float(sphere_force(x, R, Es))) if dim == 3 else (lambda x: cylinder_force(x, R, Es))
    half = pred.duration / 2
    sol = solve_ivp(
        lambda s, y: [y[1], -law(y[0]) / m], (0.0, half), [0.0, v], rtol=1e-10, atol=1e-14 * v, dense_output=True
    )
    tt = np.asarray(t, dtype=float)
    mirrored = np.where(tt <= half, tt, pred.duration - tt)  # symmetric about the turning point
    out = np.array([law(max(float(sol.sol(min(max(s, 0.0), half))[0]), 0.0)) for s in mirrored])
    out[(tt < 0) | (tt > pred.duration)] = 0.0
    return out


def hertz_prediction(dim: int, R: float, E: float, nu: float, rho: float, v: float) -> HertzPrediction:
    """Hertz's quasi-static impact figures (see the module docstring for the formulas)."""
    Es = effective_modulus(E, nu)
    if dim == 3:
        m = rho * 4.0 / 3.0 * math.pi * R**3
        d = (15 * m * v**2 / (16 * Es * math.sqrt(R))) ** 0.4
        F = float(sphere_force(d, R, Es))
        return HertzPrediction(d, F, SPHERE_DURATION_FACTOR * d / v, math.sqrt(R * d), m, Es, "sphere")
    m = rho * math.pi * R**2
    try:
        d, F, tc = impact_ode(lambda x: cylinder_force(x, R, Es), m, v)
    except ValueError:
        raise InputError(
            f"velocity {v:g} is too large for Hertz's line-contact law (the contact strip would exceed "
            f"{8 / math.e**2:.2f} R); Hertz's theory needs a contact much narrower than R: lower the velocity"
        ) from None
    return HertzPrediction(d, F, tc, math.sqrt(4 * F * R / (math.pi * Es)), m, Es, "disc: Johnson's line contact")


def p_wave_speed(E: float, nu: float, rho: float) -> float:
    """c_p = ((lambda + 2 mu)/rho)^(1/2) = (E (1 - nu)/((1 + nu)(1 - 2 nu) rho))^(1/2)."""
    return math.sqrt(E * (1 - nu) / ((1 + nu) * (1 - 2 * nu) * rho))


def validity(pred: HertzPrediction, R: float, E: float, nu: float, rho: float, v: float) -> dict[str, float]:
    """The small numbers Hertz's quasi-static theory needs: v/c_p, a*/R, 2R/(c_p t_c)."""
    c = p_wave_speed(E, nu, rho)
    return {
        "velocity_over_wave_speed": v / c,
        "contact_radius_over_R": pred.contact_radius / R,
        "wave_transit_over_duration": 2 * R / c / pred.duration,
    }


class HertzMeasure:
    """Observers and summary of a Hertz impact run (benchmarks ``hertz2d``, ``hertz3d``).

    ``summary(H)`` returns ``{"hertz": {...}}`` for summary.json: ``predicted``,
    ``computed`` (same keys), ``relative_deviation`` (computed/predicted - 1),
    ``validity``, ``cap_angle_degrees`` and the definitions used.
    """

    def __init__(self, dim: int, params: dict, cap_angle: float):
        self.dim, self.params, self.cap_angle = dim, dict(params), cap_angle
        p = params
        self.pred = hertz_prediction(dim, p["R"], p["E"], p["nu"], p["rho"], p["velocity"])
        self.com = CentreOfMassRecorder(np.eye(dim)[-1])

    def observers(self) -> list[Observer]:
        return [self.com]

    def summary(self, H) -> dict:
        p = self.params
        comp = measured(H, self.com)
        pred = {k: getattr(self.pred, k) for k in ("max_approach", "peak_force", "duration", "contact_radius")}
        dev = {k: (comp[k] / pred[k] - 1.0 if comp.get(k) is not None else None) for k in pred if k in comp}
        return {
            "hertz": {
                "law": self.pred.law,
                "per_unit_thickness": self.dim == 2,
                "mass": self.pred.mass,
                "E_star": self.pred.E_star,
                "cap_angle_degrees": math.degrees(self.cap_angle),
                "predicted": pred,
                "computed": comp,
                "relative_deviation": dev,
                "validity": validity(self.pred, p["R"], p["E"], p["nu"], p["rho"], p["velocity"]),
                "definitions": DEFINITIONS,
            }
        }

    @staticmethod
    def text(summary: dict) -> str:
        h = summary["hertz"]
        unit = " per unit thickness" if h["per_unit_thickness"] else ""
        rows = [f"  Hertz ({h['law']}{unit}): quasi-static prediction vs computed", *figure_rows(h)]
        v = h["validity"]
        rows.append(
            f"    Hertz assumes << 1: v/c_p {v['velocity_over_wave_speed']:.2g}, "
            f"a*/R {v['contact_radius_over_R']:.2g}, "
            f"wave transit 2R/c_p over t_c {v['wave_transit_over_duration']:.2g}"
        )
        rows.append(
            f"    restitution {h['computed']['restitution']:.4g}; contact candidates: cap of "
            f"{h['cap_angle_degrees']:.3g} deg around the pole"
        )
        return "\n".join(rows)


def figure_rows(h: dict) -> list[str]:
    """The duration, peak force and approach lines of a run's summary: Hertz's, computed, deviation."""
    rows = []
    for key, label in (
        ("duration", "contact duration"),
        ("peak_force", "peak force"),
        ("max_approach", "max approach"),
    ):
        c, d = h["computed"].get(key), h["relative_deviation"].get(key)
        ctext = f"{c:.5g}" if c is not None else "n/a"
        dtext = f"{100 * d:+.1f}%" if d is not None else ""
        rows.append(f"    {label:17s} {h['predicted'][key]:.5g}  computed {ctext}  {dtext}")
    return rows


DEFINITIONS = {
    "force": "total contact force -sum_i lambda_i (per unit thickness in 2D)",
    "approach": "displacement of the centre of mass of the run's mass matrix towards the plane",
    "duration": "dt x number of levels with a nonzero contact force (first to last)",
}


def measured(H, com: CentreOfMassRecorder) -> dict[str, float | None]:
    """Duration, peak force, max approach and restitution of a run (see the module docstring)."""
    force = -H.lambda_sum
    dt = float(H.t[1] - H.t[0]) if H.t.size > 1 else 0.0
    on = np.flatnonzero(force > 1e-12 * max(float(force.max(initial=0.0)), 1e-300))
    approach = -(com.position - com.position[0])
    v0 = -com.velocity[0]
    out: dict[str, float | None] = {
        "duration": float((on[-1] - on[0] + 1) * dt) if on.size else 0.0,
        "peak_force": float(force.max(initial=0.0)),
        "max_approach": float(approach.max(initial=0.0)),
        "contact_radius": _contact_radius(H),
        "restitution": float(com.velocity[-1] / v0) if v0 else None,
        "contact_levels": int(on.size),
        "contact_ended": bool(on.size and on[-1] < force.size - 1),
    }
    return out


def _contact_radius(H) -> float:
    """Largest distance from the pole, across the normal, of a node that carried a force."""
    x = H.coordinates
    radial = np.linalg.norm(x[:, :-1] - x[np.argmin(x[:, -1]), :-1], axis=1)
    active = (H.lam < 0).any(axis=0)
    return float(radial[active].max(initial=0.0))


# ----------------------------------------------------------------------------- benchmarks
HERTZ_DEFAULTS = {
    "R": 1.0,
    "E": 1.0,
    "nu": 0.3,
    "rho": 1.0,
    "velocity": 0.002,
    "cap": 2.0,
    "far": 0.25,
    "grading": 0.5,
    "skin": 0.0,
    "tangential_velocity": 0.0,
    "mu": 0.0,
    "order": 1.0,
}
DEFAULT_LEVEL = {2: 8, 3: 3}
STEPS_PER_DURATION = 25  # default dt = t_c / (25 n)


def check_params(p: dict) -> None:
    """Poisson ratio in (-1, 1/2), a positive velocity, a cap wider than the contact."""
    if not -1.0 < p["nu"] < 0.5:
        raise InputError(f"parameter 'nu' must be in (-1, 0.5), got {p['nu']}")
    if p["velocity"] <= 0:
        raise InputError(f"parameter 'velocity' must be > 0 (the speed towards the plane), got {p['velocity']}")
    if p["cap"] <= 1:
        raise InputError(f"parameter 'cap' (cap radius / Hertz contact radius) must be > 1, got {p['cap']}")
    if p["mu"] < 0:
        raise InputError(f"parameter 'mu' (Coulomb coefficient with the plane) must be >= 0, got {p['mu']}")
    if p["skin"] not in (0.0, 1.0):
        raise InputError(f"parameter 'skin' must be 0 (contact on the cap) or 1 (the whole skin), got {p['skin']}")


MAX_CONTACT_RATIO = 0.5


def _prediction(dim: int, p: dict) -> HertzPrediction:
    """Hertz's figures of the parameters; an InputError when a*/R > 0.5 (far outside the theory)."""
    pred = hertz_prediction(dim, p["R"], p["E"], p["nu"], p["rho"], p["velocity"])
    if pred.contact_radius > MAX_CONTACT_RATIO * p["R"]:
        raise InputError(
            f"velocity {p['velocity']:g}: Hertz's contact radius would be {pred.contact_radius / p['R']:.2f} R "
            f"(> {MAX_CONTACT_RATIO} R); Hertz's theory needs a contact much smaller than R: lower the velocity"
        )
    return pred


def cap_angle(dim: int, p: dict) -> float:
    """Polar half-angle theta_c of the contact cap: R sin theta_c = cap x a* (at most 90 deg).

    The cap must contain the contact zone (radius a*, or half-width b* in 2D) with margin:
    ``cap`` = 2 leaves the outer half of the cap free of contact even when the computed
    zone exceeds Hertz's by a node or two; nodes outside the cap are not contact
    candidates, which keeps the contact set (and its condensation) small."""
    a = _prediction(dim, p).contact_radius
    return math.asin(min(1.0, p["cap"] * a / p["R"]))


def _mesh_sizes(dim: int, n: int, p: dict) -> tuple[float, float, float]:
    """(h_contact, h_far, r_fine): a*/n on the cap, far x R far away, fine up to the cap's edge."""
    a = _prediction(dim, p).contact_radius
    h_far = p["far"] * p["R"]
    return min(a / n, h_far), h_far, p["R"] * math.sin(cap_angle(dim, p))


def builder(dim: int) -> Callable[[int, dict], Problem]:
    def build(n: int, p: dict) -> Problem:
        h_c, h_far, r_fine = _mesh_sizes(dim, n, p)
        mesh = pole_refined_ball(dim, p["R"], cap_angle(dim, p), h_c, h_far, r_fine, p["grading"], int(p["order"]))
        e = np.eye(dim)[-1]
        return Problem(
            mesh=mesh,
            material=IsotropicElastic.from_young(p["E"], p["nu"], p["rho"]),
            contact_tag=("cap", "surface") if p["skin"] else "cap",
            obstacle=PlaneObstacle(np.zeros(dim), e),
            u0=0.0,
            v0=-p["velocity"] * e + p["tangential_velocity"] * np.eye(dim)[0],
            name=f"hertz{dim}d",
            friction=Friction("coulomb", p["mu"]) if p["mu"] > 0 else None,
        )

    return build


def sizes(dim: int) -> Callable[[int, dict], tuple[float, int, int, int, int]]:
    def counts(n: int, p: dict) -> tuple[float, int, int, int, int]:
        h_c, h_far, r_fine = _mesh_sizes(dim, n, p)
        nodes, cells, contact = estimate_counts(dim, p["R"], h_c, h_far, r_fine, p["grading"])
        if p["order"] == 2:  # a vertex per edge more: about 2^d nodes per vertex (a simplicial mesh's edge count)
            return h_c, nodes * 2**dim, cells, (dim + 1) * (dim + 2) // 2, contact * 2 ** (dim - 1)
        return h_c, nodes, cells, dim + 1, contact

    return counts


def times(n: int, p: dict, dim: int | None = None) -> tuple[float, float]:
    """Default (dt, T): dt = t_c/(25 n), T = ceil(1.5 x 25 n) dt (t_c of Hertz's 3D or 2D law)."""
    tc = _prediction(dim or 3, p).duration
    dt = tc / (STEPS_PER_DURATION * n)
    return dt, math.ceil(1.5 * STEPS_PER_DURATION * n) * dt


def run_times(dim: int) -> Callable[[int, dict], tuple[float, float]]:
    return lambda n, p: times(n, p, dim)


def measure(dim: int) -> Callable[[dict], HertzMeasure]:
    return lambda p: HertzMeasure(dim, p, cap_angle(dim, p))

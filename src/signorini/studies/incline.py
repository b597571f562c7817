"""The inclined-plane benchmarks ``incline2d`` and ``incline3d``: an elastic block on a
plane under a gravity tilted by an angle, with Coulomb friction.

The block [0, width] x [0, height] (2D, plane strain) or [0, width]^2 x [0, height] (3D)
rests on the rigid plane y = 0 (z = 0 in 3D), unstressed and at rest at t = 0, under the
body force rho g (sin a, -cos a) (2D; (sin a, 0, -cos a) in 3D): the plane tilted by a
seen in its own frame.  Coulomb's law with coefficient mu (``--set mu=...``; an explicit
``--friction`` replaces it) gives, for the centre of mass x_G along the slope, once the
block is in gross slip or stuck (the total normal force is m g cos a on average, the
tangential one mu times it when sliding):

    x_G'' = g (sin a - mu cos a)   when tan a > mu (sliding),
    x_G'' = 0                      when tan a <= mu (sticking),

the closed form printed beside the computed acceleration: the second derivative of a
least-squares parabola through x_G(t) over the last 3/4 of the run (after the settling
of the normal waves started by switching gravity on).  The mass is that of the run's
mass matrix, the same one the body force follows (:mod:`signorini.dynamics.model.mass`), so
the closed form holds for every mass variant.

Parameters: ``E`` = 1000, ``nu`` = 0.3, ``rho`` = 1, ``g`` = 1, ``angle`` = 30 (degrees),
``mu`` = 0.3, ``width`` = 1, ``height`` = 0.25.  Level n: 4n x 2n elements (2D), 4n x 4n
x 2n (3D; two cells through the height, which the moment-preserving default mass needs),
h = height / (2n); default dt = 0.02 / n, T = 2.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from ..contact.friction import Friction
from ..contact.obstacles import PlaneObstacle
from ..dynamics.model.problem import Problem
from ..dynamics.observe.observers import CentreOfMassRecorder, Observer
from ..errors import InputError
from ..fem.material import IsotropicElastic
from ..fem.mesh import box, rectangle

INCLINE_DEFAULTS = {
    "E": 1000.0,
    "nu": 0.3,
    "rho": 1.0,
    "g": 1.0,
    "angle": 30.0,
    "mu": 0.3,
    "width": 1.0,
    "height": 0.25,
}
#: the fit of x_G(t) leaves out the first quarter of the run (settling)
SETTLING_FRACTION = 0.25


def check_params(p: dict) -> None:
    """Angle in [0, 90), mu >= 0, Poisson ratio in (-1, 1/2), g >= 0."""
    if not 0.0 <= p["angle"] < 90.0:
        raise InputError(f"parameter 'angle' (degrees) must be in [0, 90), got {p['angle']}")
    if p["mu"] < 0:
        raise InputError(f"parameter 'mu' (Coulomb coefficient) must be >= 0, got {p['mu']}")
    if not -1.0 < p["nu"] < 0.5:
        raise InputError(f"parameter 'nu' must be in (-1, 0.5), got {p['nu']}")
    if p["g"] < 0:
        raise InputError(f"parameter 'g' must be >= 0, got {p['g']}")
    for k in ("E", "height"):
        if p[k] <= 0:
            raise InputError(f"parameter {k!r} must be > 0, got {p[k]}")


def slope(dim: int) -> np.ndarray:
    """Unit vector down the slope (the x axis)."""
    return np.eye(dim)[0]


def gravity(dim: int, p: dict) -> np.ndarray:
    """g (sin a, -cos a) in 2D, g (sin a, 0, -cos a) in 3D [length / time^2]."""
    a = math.radians(p["angle"])
    out = np.zeros(dim)
    out[0], out[-1] = p["g"] * math.sin(a), -p["g"] * math.cos(a)
    return out


def predicted_acceleration(p: dict, mu: float | None = None) -> float:
    """g (sin a - mu cos a) if tan a > mu, else 0 (sticking)."""
    a = math.radians(p["angle"])
    mu = p["mu"] if mu is None else mu
    return p["g"] * (math.sin(a) - mu * math.cos(a)) if math.tan(a) > mu else 0.0


def builder(dim: int) -> Callable[[int, dict], Problem]:
    def build(n: int, p: dict) -> Problem:
        w, hgt = p["width"], p["height"]
        mesh = rectangle(4 * n, 2 * n, w, hgt) if dim == 2 else box(4 * n, 4 * n, 2 * n, w, w, hgt)
        return Problem(
            mesh=mesh,
            material=IsotropicElastic.from_young(p["E"], p["nu"], p["rho"]),
            contact_tag="ymin" if dim == 2 else "zmin",
            obstacle=PlaneObstacle(np.zeros(dim), np.eye(dim)[-1]),
            body_force=p["rho"] * gravity(dim, p),
            friction=Friction("coulomb", p["mu"]),
            name=f"incline{dim}d",
        )

    return build


def sizes(dim: int) -> Callable[[int, dict], tuple[float, int, int, int, int]]:
    def counts(n: int, p: dict) -> tuple[float, int, int, int, int]:
        h = p["height"] / (2 * n)
        if dim == 2:
            return h, (4 * n + 1) * (2 * n + 1), 8 * n * n, 4, 4 * n + 1
        return h, (4 * n + 1) ** 2 * (2 * n + 1), 32 * n**3, 8, (4 * n + 1) ** 2

    return counts


def run_times(n: int, p: dict) -> tuple[float, float]:
    return 0.02 / n, 2.0


class InclineMeasure:
    """The centre of mass along the slope and the closed-form acceleration (summary ``incline``)."""

    def __init__(self, dim: int, params: dict):
        self.dim, self.params = dim, dict(params)
        self.com = CentreOfMassRecorder(slope(dim))

    def observers(self) -> list[Observer]:
        return [self.com]

    def summary(self, H) -> dict:
        p = self.params
        law = H.meta.get("friction", {})
        mu = law.get("coefficient", 0.0) if law.get("law") == "coulomb" else None
        t, x = H.t, self.com.position
        keep = t >= SETTLING_FRACTION * t[-1]
        computed = float(2.0 * np.polyfit(t[keep], x[keep], 2)[0]) if keep.sum() >= 3 else None
        out = {
            "angle_degrees": p["angle"],
            "friction": law,
            "fit_window": [float(t[keep][0]), float(t[-1])] if keep.any() else None,
            "computed_acceleration": computed,
            "definition": "x_G'' of a parabola fitted to the centre of mass along the slope after the settling",
        }
        if mu is not None:
            pred = predicted_acceleration(p, mu)
            out.update(
                coefficient=mu,
                sticking=bool(math.tan(math.radians(p["angle"])) <= mu),
                predicted_acceleration=pred,
                relative_deviation=(computed / pred - 1.0) if computed is not None and pred else None,
            )
        return {"incline": out}

    @staticmethod
    def text(summary: dict) -> str:
        s = summary["incline"]
        c = s["computed_acceleration"]
        ctext = f"{c:.6g}" if c is not None else "n/a"
        if "predicted_acceleration" not in s:
            return f"  incline {s['angle_degrees']:g} deg ({s['friction'].get('law')}): x_G'' computed {ctext}"
        dev = s["relative_deviation"]
        dtext = f" ({100 * dev:+.3g}%)" if dev is not None else ""
        head = f"  incline {s['angle_degrees']:g} deg, mu {s['coefficient']:g}"
        if s["sticking"]:
            return f"{head} (sticks: tan a <= mu): x_G'' closed form 0, computed {ctext}"
        return (
            f"{head} (slides: tan a > mu): x_G'' closed form g (sin a - mu cos a) = "
            f"{s['predicted_acceleration']:.6g}, computed {ctext}{dtext}"
        )


def measure(dim: int) -> Callable[[dict], InclineMeasure]:
    return lambda p: InclineMeasure(dim, p)

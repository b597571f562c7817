"""The free-spin benchmarks ``spin2d`` and ``spin3d`` (issue 41): an elastic disc (plane strain) or ball
spinning about its centre, with nothing to hit.

A rigid rotation has no strain in finite-strain elasticity (``saint-venant-kirchhoff``, ``neo-hookean``): the
body only stretches under its centrifugal load, and a scheme that keeps the energy and the angular momentum
(``energy-momentum``) keeps both to its Newton tolerance whatever the step.  Linear elasticity is not invariant
under rotation: the velocity of a rigid spin, omega x X, is an infinitesimal rotation, a motion without strain
for the linear model, which therefore carries every point along its tangent, x = X + t omega x X: the linear
disc grows without bound (by sqrt(1 + (omega t)^2): 63 times its radius after 10 turns) and feels nothing.
The summary's ``radius_change`` (the largest distance of a node to the centroid at the end, over R, less 1)
shows it beside the finite-strain run's centrifugal stretch (a few per cent).

The disc of radius ``R`` is a structured grid of 4n x 4n quadrilaterals (the ball 4n x 4n x 4n hexahedra) of
the square (cube) [-1, 1]^d mapped onto it by x' = x sqrt(1 - y^2 / 2) (in 3D x' = x sqrt(1 - y^2/2 - z^2/2 +
y^2 z^2 / 3), and the same by permutation): no gmsh needed.  Initial velocity: the rigid spin about the
z axis (2D) or about the axis (1, 2, 3) / sqrt(14) (3D) at omega = ``tip`` c / R, c the compression wave
speed sqrt((lam + 2 mu) / rho) (a tip speed of ``tip`` times the wave speed: 0.3 by default).  Material
``model``: 2 (neo-hookean, default), 1 (saint-venant-kirchhoff) or 0 (linear).  Contact: the nodes of the
mapped face y = -1 (z = -1) against a plane far below the centre (:func:`plane_distance`), never reached,
which the Problem needs;
with the default (moment-preserving) mass those nodes are massless, and energy-momentum keeps the angular
momentum to O(dt^2) only (docs/finite_strain.md): ``--mass standard`` keeps both exactly.

Parameters: ``R`` = 1, ``E`` = 1, ``nu`` = 0.3, ``rho`` = 1, ``tip`` = 0.3, ``revolutions`` = 10, ``model`` = 2.
Level n (default 2 in 2D, 1 in 3D): h = 2 R / (4 n); default dt = the period / (32 n), T = ``revolutions``
periods.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from ..contact.obstacles import PlaneObstacle
from ..dynamics.model.problem import Problem
from ..dynamics.observe.observers import Observer
from ..errors import InputError
from ..fem.material import IsotropicElastic, NeoHookean, SaintVenantKirchhoff
from ..fem.mesh import Mesh, box, rectangle

SPIN_DEFAULTS = {"R": 1.0, "E": 1.0, "nu": 0.3, "rho": 1.0, "tip": 0.3, "revolutions": 10.0, "model": 2.0, "order": 1.0}
#: the material of each value of the ``model`` parameter
MODELS = {0: IsotropicElastic, 1: SaintVenantKirchhoff, 2: NeoHookean}
DEFAULT_LEVEL = {2: 2, 3: 1}


def check_params(p: dict) -> None:
    """Poisson ratio in (-1, 1/2), 0 < tip < 1, revolutions > 0, model 0, 1 or 2."""
    if not -1.0 < p["nu"] < 0.5:
        raise InputError(f"parameter 'nu' must be in (-1, 0.5), got {p['nu']}")
    if not 0.0 < p["tip"] < 1.0:
        raise InputError(f"parameter 'tip' (tip speed / wave speed) must be in (0, 1), got {p['tip']}")
    if p["revolutions"] <= 0:
        raise InputError(f"parameter 'revolutions' must be > 0, got {p['revolutions']}")
    if p["model"] not in MODELS:
        raise InputError(
            f"parameter 'model' must be 0 (linear), 1 (saint-venant-kirchhoff) or 2 (neo-hookean), got {p['model']:g}"
        )


def material(p: dict) -> IsotropicElastic:
    return MODELS[int(p["model"])].from_young(p["E"], p["nu"], p["rho"])


def omega(p: dict) -> float:
    """The spin rate tip c / R [rad / time]."""
    return p["tip"] * material(p).wave_speed(2) / p["R"]


def axis(dim: int) -> np.ndarray:
    """The unit spin axis: z in 2D, (1, 2, 3) / sqrt(14) in 3D."""
    return np.array([0.0, 0.0, 1.0]) if dim == 2 else np.array([1.0, 2.0, 3.0]) / math.sqrt(14.0)


def round_mesh(dim: int, n: int, R: float, order: int = 1) -> Mesh:
    """The disc (ball) of radius R centred at the origin: the mapped grid of the module docstring (``order`` 2:
    quadratic cells, their mid-side nodes mapped too: curved)."""
    m = (
        rectangle(4 * n, 4 * n, 2.0, 2.0, order=order)
        if dim == 2
        else box(4 * n, 4 * n, 4 * n, 2.0, 2.0, 2.0, order=order)
    )
    x = m.points - 1.0
    sq = x * x
    if dim == 2:
        y = x * np.sqrt(1.0 - sq[:, ::-1] / 2.0)
    else:
        y = np.empty_like(x)
        for i in range(3):
            j, k = (i + 1) % 3, (i + 2) % 3
            y[:, i] = x[:, i] * np.sqrt(1.0 - sq[:, j] / 2 - sq[:, k] / 2 + sq[:, j] * sq[:, k] / 3)
    m.points = R * y
    return m


def builder(dim: int) -> Callable[[int, dict], Problem]:
    def build(n: int, p: dict) -> Problem:
        w = omega(p) * axis(dim)

        def v0(x: np.ndarray) -> np.ndarray:
            if dim == 2:
                return w[2] * np.column_stack([-x[:, 1], x[:, 0]])
            return np.cross(w, x)

        e = np.eye(dim)[-1]
        return Problem(
            mesh=round_mesh(dim, n, p["R"], int(p["order"])),
            material=material(p),
            contact_tag="ymin" if dim == 2 else "zmin",
            obstacle=PlaneObstacle(-plane_distance(p) * e, e),
            v0=v0,
            name=f"spin{dim}d",
        )

    return build


def plane_distance(p: dict) -> float:
    """How far below the centre the plane lies: beyond the reach of the linear body, whose radius grows to
    R sqrt(1 + (2 pi revolutions)^2) (twice that, and at least 10 R) [length]."""
    return p["R"] * max(10.0, 2.0 * math.sqrt(1.0 + (2.0 * math.pi * p["revolutions"]) ** 2))


def sizes(dim: int) -> Callable[[int, dict], tuple[float, int, int, int, int]]:
    def counts(n: int, p: dict) -> tuple[float, int, int, int, int]:
        k, q = 4 * n, int(p["order"])
        return 2 * p["R"] / k, (q * k + 1) ** dim, k**dim, (q + 1) ** dim, (q * k + 1) ** (dim - 1)

    return counts


def run_times(n: int, p: dict) -> tuple[float, float]:
    period = 2 * math.pi / omega(p)
    return period / (32 * n), p["revolutions"] * period


class RadiusRecorder(Observer):
    """The largest distance of a node to the centroid of the nodes in the final state, x = X + U [length]."""

    radius: float = float("nan")

    def close(self, run, status: str, n_last: int, state) -> None:
        mesh = run.ctx.disc.problem.mesh
        x = mesh.points + state.U.reshape(mesh.points.shape)
        self.radius = float(np.linalg.norm(x - x.mean(axis=0), axis=1).max())


class SpinMeasure:
    """The drifts of the energy and of the angular momentum over the run, the elastic energy's largest share
    of E0 and the change of the radius at the end (summary ``spin``)."""

    def __init__(self, dim: int, params: dict):
        self.dim, self.params = dim, dict(params)
        self.radius = RadiusRecorder()

    def observers(self) -> list:
        return [self.radius]

    def summary(self, H) -> dict:
        c = H.columns()
        E, Ee = c["energy"], c["elastic_energy"]
        L = np.column_stack(
            [c[k] for k in ("angular_momentum_x", "angular_momentum_y", "angular_momentum_z") if k in c]
        )
        ok = np.isfinite(E)
        L0 = float(np.linalg.norm(L[0]))
        return {
            "spin": {
                "omega": omega(self.params),
                "tip_speed_over_wave_speed": self.params["tip"],
                "revolutions": float(H.t[ok][-1] * omega(self.params) / (2 * math.pi)),
                "energy_max_relative_drift": float(np.abs(E[ok] - E[0]).max() / abs(E[0])),
                "angular_momentum_max_relative_drift": float(np.linalg.norm(L[ok] - L[0], axis=1).max() / L0),
                "strain_energy_share_max": float(np.abs(Ee[ok]).max() / abs(E[0])),
                "radius_change": self.radius.radius / self.params["R"] - 1.0,
                "definition": "drifts: max over the levels of |X^n - X^0| / |X^0|; strain energy share: max elastic "
                "energy / E0; radius change: the largest distance of a node to the centroid at the end "
                "over R, less 1 (finite strain: the centrifugal stretch; linear: the body's spurious "
                "growth along the tangents)",
            }
        }

    @staticmethod
    def text(summary: dict) -> str:
        s = summary["spin"]
        return (
            f"  spin: {s['revolutions']:.3g} turn(s) at tip speed {s['tip_speed_over_wave_speed']:g} c: energy "
            f"drift {s['energy_max_relative_drift']:.2e}, angular momentum drift "
            f"{s['angular_momentum_max_relative_drift']:.2e}, strain energy up to "
            f"{100 * s['strain_energy_share_max']:.3g}% of E0, radius {100 * s['radius_change']:+.3g}% at the "
            "end"
        )


def measure(dim: int) -> Callable[[dict], SpinMeasure]:
    return lambda p: SpinMeasure(dim, p)

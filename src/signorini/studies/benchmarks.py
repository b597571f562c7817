"""Named benchmark problems with overridable parameters.

==============  ==========================================================================
``bar1d``       spec 3.1: bar (0, L), clamped u(L) = 0, contact at x = 0 (u(0) >= 0),
                at rest and compressed, u0 = gap (1 - x/L), v0 = 0.
                Parameters ``L``=1, ``E``=1, ``rho``=1, ``gap``=0.5.  Exact solution.
``bar1d-impact`` spec 3.2: clamped u(L) = gap, u0 = gap, v0 = -velocity, u(0) >= 0.
                Parameters ``L``=1, ``E``=1, ``rho``=1, ``gap``=0.2, ``velocity``=0.5.
                Exact solution; first impact at gap/velocity.

Both 1D bars also take ``clamp_velocity`` b (the clamp moves, u(L, t) = u_D + b t) and
``obstacle_velocity`` w (the obstacle moves, u(0, t) >= w t), default 0; their exact
solutions cover both (docs/exact_solutions.md).
``bar2d``       the seed's 2D bar (plane strain) [0, width] x [0, length], Q1,
                clamp u = (0, gap) on top (``ymax``), contact u_y >= 0 on ``ymin``,
                u0 = (0, gap), v0 = (0, -velocity).
``bar3d``       the same in 3D on [0, width]^2 x [0, length], contact on ``zmin``.
==============  ==========================================================================

2D/3D parameters: ``rho``=1, ``lam``=0.25, ``mu``=0.5, ``gap``=0.2, ``velocity``=0.5,
``width``=0.1, ``length``=1.  Mesh: ``n`` elements across the width and 10 n along
the bar (h = width/n); in 1D ``n`` elements along the bar.  Default time step h/2.

``hertz3d``     an elastic ball (P1 tetrahedra) of radius ``R`` on the rigid plane z = 0,
                touching it at t = 0 with speed ``velocity``; compared with Hertz's
                quasi-static impact (:mod:`signorini.studies.hertz`).
``hertz2d``     the same with a disc (P1 triangles, plane strain, per unit thickness).
``collision1d`` two equal free bars (0, L) and (L + gap, 2L + gap), the first moving at
                ``velocity`` towards the second at rest, in contact through a contact pair
                (:mod:`signorini.studies.collision`): contact for 2L/c with the force
                rho c v / 2, then the velocities exchanged.  Parameters ``L``=1, ``gap``=0.1,
                ``velocity``=0.5, ``E``=1, ``rho``=1; n cells per bar (default 40).
``collision2d`` two elastic discs (P1 triangles, plane strain) or balls (P1 tetrahedra) of
``collision3d`` radii ``R1``, ``R2`` and materials (``E1``, ``nu1``, ``rho1``), (``E2``, ...)
                touching at t = 0, the first moving at ``velocity`` towards the second at rest,
                each meshed towards the contact point; the contact pair a_cap / b_cap;
                Hertz's two-body duration, peak force and approach printed beside the computed
                ones (:mod:`signorini.studies.collision_balls`).
``incline2d``   an elastic block on a plane under a gravity tilted by ``angle`` degrees,
``incline3d``   Coulomb friction ``mu``; the closed-form sliding acceleration
                g (sin a - mu cos a) (0 when tan a <= mu) is printed beside the computed
                one (:mod:`signorini.studies.incline`).

``spin2d``      a free disc (plane strain, Q1) or ball (hexahedra) of radius ``R`` spinning at a tip
``spin3d``      speed ``tip`` times the wave speed for ``revolutions`` turns, Neo-Hookean (``model`` 2;
                1 Saint Venant-Kirchhoff, 0 linear): energy-momentum keeps its energy and angular
                momentum, a linear body builds a spurious strain energy (:mod:`signorini.studies.spin`).

``rings2d``     two Neo-Hookean rings colliding obliquely, a contact pair in the current configuration
                (:mod:`signorini.studies.rings`): the drifts of the energy and the momenta, the contact's
                span and peak force.

Hertz parameters: ``R``=1, ``E``=1, ``nu``=0.3, ``rho``=1, ``velocity``=0.002,
``tangential_velocity``=0 (along x: an oblique impact), ``mu``=0 (Coulomb friction with the
plane; 0 and no ``--friction``: frictionless), mesh
controls ``cap``=2 (radius of the contact cap / Hertz contact radius a*), ``far``=0.25
(element size far from the pole / R), ``grading``=0.5; level ``n``: element size a*/n
on the cap (gmsh, ``pip install ".[mesh]"``), default dt = t_c/(25 n) and T = 1.5 t_c
(t_c the Hertz contact duration).  Default n: 8 (2D), 3 (3D).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..contact.obstacles import PlaneObstacle
from ..dynamics.model.problem import Problem
from ..errors import InputError
from ..fem.material import IsotropicElastic
from ..fem.mesh import box, interval, rectangle
from ..fem.space import Dirichlet
from ..registry import Parameter, Registry
from . import collision, collision_balls, hertz, incline, rings, spin
from .exact import ExactBar1D


@dataclass(frozen=True)
class Benchmark:
    """A named problem family: ``build(n, params)`` makes level n.

    Optional hooks of benchmarks that are not bars: ``sizes(n, params)`` -> (h, nodes,
    cells, nodes per cell, contact nodes) estimated without meshing; ``times(n, params)``
    -> default (dt, T) of ``signorini run``; ``measure(params)`` -> an object with
    ``observers()``, ``summary(history)`` (extra summary.json fields) and ``text(summary)``
    (lines of the run's summary); ``check(params)`` validates the parameters.
    """

    name: str
    dim: int
    defaults: dict[str, float]
    build: Callable[[int, dict], Problem]
    exact: Callable[[dict, float], ExactBar1D] | None = None
    description: str = ""
    default_n: int | None = None
    sizes: Callable[[int, dict], tuple[float, int, int, int, int]] | None = None
    times: Callable[[int, dict], tuple[float, float]] | None = None
    measure: Callable[[dict], Any] | None = None
    check: Callable[[dict], None] | None = None
    #: structured levels nested by halving (the bars; the inclines: generated grids with sizes)
    structured: bool = False

    def params(self, overrides: dict | None = None) -> dict[str, float]:
        """Defaults updated with ``overrides``; unknown names and bad values are errors."""
        p = dict(self.defaults)
        for k, v in (overrides or {}).items():
            if k not in p:
                raise InputError(
                    f"unknown parameter {k!r} for benchmark {self.name!r}; allowed: {', '.join(sorted(p))}"
                )
            try:
                p[k] = float(v)
            except (TypeError, ValueError):
                raise InputError(f"parameter {k!r} of {self.name!r} must be a number, got {v!r}") from None
            if not np.isfinite(p[k]):
                raise InputError(f"parameter {k!r} of {self.name!r} must be finite, got {v!r}")
        for k in ("L", "E", "rho", "width", "length", "mu", "R", "far", "grading"):
            if k == "mu" and "lam" not in p:
                continue  # a friction coefficient (hertz, incline), not the Lame parameter of the bars
            if k in p and p[k] <= 0:
                raise InputError(f"parameter {k!r} of {self.name!r} must be > 0, got {p[k]}")
        for k in ("gap", "velocity"):
            if k in p and p[k] < 0:
                raise InputError(f"parameter {k!r} of {self.name!r} must be >= 0, got {p[k]}")
        if "order" in p and p["order"] not in (1.0, 2.0):
            raise InputError(
                f"parameter 'order' of {self.name!r} must be 1 (linear cells) or 2 (quadratic cells), "
                f"got {p['order']:g}"
            )
        if self.check is not None:
            self.check(p)
        return p

    @property
    def nested(self) -> bool:
        """Whether levels are nested structured meshes (what reference studies and compare need)."""
        return self.sizes is None or self.structured

    def require_nested(self, command: str, overrides: dict | None = None) -> None:
        """InputError for a command that measures errors against a finer nested level, unless the benchmark's
        levels are nested (the bars: 1D against its exact solution; 2D/3D against a finer level, their nodes on a
        tensor grid: linear cells, or with ``order = 2`` Q2 cells, :func:`~.reference_study.lattice`)."""
        if self.nested and self.dim > 1 and self.params(overrides).get("order", 1.0) != 1.0:
            from .reference_study import lattice

            try:
                lattice(self.problem(1, overrides).mesh)
            except InputError as exc:
                raise InputError(f"{command} of {self.name!r} with order = 2: {exc}") from None
        if not self.nested:
            how = (
                "is meshed by gmsh and compared with Hertz's theory"
                if self.name.startswith("hertz")
                else ("prints its closed-form values beside the computed ones")
            )
            raise InputError(
                f"{command} needs nested structured levels with an exact solution or a reference (the bars); "
                f"{self.name!r} {how} by: signorini run {self.name} [--n N] [--set NAME=VALUE]"
            )

    def n_default(self) -> int:
        """Level of ``signorini run`` without --n."""
        return self.default_n if self.default_n is not None else (40 if self.dim == 1 else 4)

    def run_times(self, n: int, overrides: dict | None = None) -> tuple[float, float]:
        """Default (dt, T) of ``signorini run``: h/2 and 6 (1D) or 1 (2D/3D) for the bars."""
        if self.times is not None:
            return self.times(n, self.params(overrides))
        return self.h(n, overrides) / 2, (6.0 if self.dim == 1 else 1.0)

    def mesh_counts(self, n: int, overrides: dict | None = None) -> tuple[int, int, int]:
        """(nodes, cells, nodes per cell) of level n, without building the mesh."""
        if self.sizes is not None:
            return self.sizes(n, self.params(overrides))[1:4]
        k = _order(self.params(overrides))  # nodes per cell edge - 1
        cells = n if self.dim == 1 else 10 * n**self.dim
        return (k * n + 1) ** (self.dim - 1) * (10 ** (self.dim > 1) * k * n + 1), cells, (k + 1) ** self.dim

    def contact_count(self, n: int, overrides: dict | None = None) -> int:
        """Number of contact nodes of level n (one end or side of the bar)."""
        if self.sizes is not None:
            return self.sizes(n, self.params(overrides))[4]
        return (_order(self.params(overrides)) * n + 1) ** (self.dim - 1)

    def problem(self, n: int, overrides: dict | None = None) -> Problem:
        if not isinstance(n, (int, np.integer)) or n < 1:
            raise InputError(f"n (number of elements) must be a positive integer, got {n!r}")
        return self.build(int(n), self.params(overrides))

    def h(self, n: int, overrides: dict | None = None) -> float:
        """Mesh size of level n (near the contact for the Hertz benchmarks)."""
        p = self.params(overrides)
        if self.sizes is not None:
            return self.sizes(n, p)[0]
        return (p["L"] if self.dim == 1 else p["width"]) / n

    def wave_speed(self, overrides: dict | None = None) -> float:
        p = self.params(overrides)
        if self.dim == 1:
            return float(np.sqrt(p["E"] / p["rho"]))
        if "nu" in p:
            return float(np.sqrt(p["E"] * (1 - p["nu"]) / ((1 + p["nu"]) * (1 - 2 * p["nu"]) * p["rho"])))
        return float(np.sqrt((p["lam"] + 2 * p["mu"]) / p["rho"]))


def _order(p: dict) -> int:
    """The cells' order of a bar (parameter ``order``: 1 linear, 2 quadratic)."""
    return int(p.get("order", 1.0))


def _clamp(value: float, b: float) -> float | Callable:
    """Clamp value u_D, or the prescribed motion u_D + b t."""
    if b == 0.0:
        return value
    return lambda x, t: np.full((len(x), 1), value + b * t)


def _obstacle_1d(w: float) -> PlaneObstacle:
    """The plane x = 0 (normal +1, towards the bar), or x = w t when it moves."""
    return PlaneObstacle([0.0] if w == 0.0 else (lambda t: [w * t]), [1.0])


def _bar1d(n: int, p: dict) -> Problem:
    L, g = p["L"], p["gap"]
    return Problem(
        mesh=interval(n, L, order=_order(p)),
        material=IsotropicElastic.from_young(p["E"], 0.0, p["rho"]),
        contact_tag="xmin",
        obstacle=_obstacle_1d(p["obstacle_velocity"]),
        dirichlet=[Dirichlet("xmax", _clamp(0.0, p["clamp_velocity"]))],
        u0=lambda x: g * (1.0 - x / L),
        v0=0.0,
        name="bar1d",
    )


def _bar1d_impact(n: int, p: dict) -> Problem:
    g = p["gap"]
    return Problem(
        mesh=interval(n, p["L"], order=_order(p)),
        material=IsotropicElastic.from_young(p["E"], 0.0, p["rho"]),
        contact_tag="xmin",
        obstacle=_obstacle_1d(p["obstacle_velocity"]),
        dirichlet=[Dirichlet("xmax", _clamp(g, p["clamp_velocity"]))],
        u0=g,
        v0=-p["velocity"],
        name="bar1d-impact",
    )


def _bar(dim: int) -> Callable[[int, dict], Problem]:
    def build(n: int, p: dict) -> Problem:
        w, length, g, v = p["width"], p["length"], p["gap"], p["velocity"]
        if dim == 2:
            mesh = rectangle(n, 10 * n, w, length, order=_order(p))
        else:
            mesh = box(n, n, 10 * n, w, w, length, order=_order(p))
        e = np.eye(dim)[-1]
        top, bottom = ("ymax", "ymin") if dim == 2 else ("zmax", "zmin")
        return Problem(
            mesh=mesh,
            material=IsotropicElastic(p["lam"], p["mu"], p["rho"]),
            contact_tag=bottom,
            obstacle=PlaneObstacle(np.zeros(dim), e),
            dirichlet=[Dirichlet(top, tuple(g * e))],
            u0=g * e,
            v0=-v * e,
            name=f"bar{dim}d",
        )

    return build


_BAR = {"rho": 1.0, "lam": 0.25, "mu": 0.5, "gap": 0.2, "velocity": 0.5, "width": 0.1, "length": 1.0, "order": 1.0}
_MOTION = {"clamp_velocity": 0.0, "obstacle_velocity": 0.0, "order": 1.0}


def _exact_bar1d(p: dict, T: float) -> ExactBar1D:
    return ExactBar1D.bar1d(
        p["L"],
        p["E"],
        p["rho"],
        p["gap"],
        T,
        clamp_velocity=p["clamp_velocity"],
        obstacle_velocity=p["obstacle_velocity"],
    )


def _exact_impact(p: dict, T: float) -> ExactBar1D:
    return ExactBar1D.bar1d_impact(
        p["L"],
        p["E"],
        p["rho"],
        p["gap"],
        p["velocity"],
        T,
        clamp_velocity=p["clamp_velocity"],
        obstacle_velocity=p["obstacle_velocity"],
    )


BENCHMARKS = Registry("benchmark")
#: the final time of ``study`` and ``compare`` of a benchmark without --T: in 1D one period 3L/c of bar1d (its
#: contact is on [1, 2)), in 2D/3D the bars' first impact
STUDY_T = {1: 3.0, 2: 1.0, 3: 1.0}


def _register(b: Benchmark) -> None:
    params = tuple(Parameter(k, v, k.replace("_", " "), float) for k, v in b.defaults.items())
    BENCHMARKS.register(b.name, b, b.description, (), params)


for _b in (
    Benchmark(
        "bar1d",
        1,
        {"L": 1.0, "E": 1.0, "rho": 1.0, "gap": 0.5, **_MOTION},
        _bar1d,
        _exact_bar1d,
        "1D clamped bar released from a compressed state (exact solution, period 3L/c)",
    ),
    Benchmark(
        "bar1d-impact",
        1,
        {"L": 1.0, "E": 1.0, "rho": 1.0, "gap": 0.2, "velocity": 0.5, **_MOTION},
        _bar1d_impact,
        _exact_impact,
        "1D clamped bar moving towards the obstacle (exact solution)",
    ),
    Benchmark("bar2d", 2, dict(_BAR), _bar(2), None, "the seed's 2D bar (plane strain, Q1)"),
    Benchmark("bar3d", 3, dict(_BAR), _bar(3), None, "the seed's 3D bar (Q1 hexahedra)"),
    *(
        Benchmark(
            f"hertz{d}d",
            d,
            dict(hertz.HERTZ_DEFAULTS),
            hertz.builder(d),
            None,
            f"elastic {'ball' if d == 3 else 'disc (plane strain)'} hitting a rigid plane vs Hertz's impact theory",
            hertz.DEFAULT_LEVEL[d],
            hertz.sizes(d),
            hertz.run_times(d),
            hertz.measure(d),
            hertz.check_params,
        )
        for d in (2, 3)
    ),
    Benchmark(
        "collision1d",
        1,
        dict(collision.COLLISION_DEFAULTS),
        collision.build,
        None,
        "two equal free bars colliding (contact pair): duration 2L/c, force rho c v/2, velocities exchanged",
        40,
        collision.sizes,
        collision.run_times,
        collision.measure(),
        collision.check_params,
    ),
    *(
        Benchmark(
            f"collision{d}d",
            d,
            dict(collision_balls.BALLS_DEFAULTS),
            collision_balls.builder(d),
            None,
            f"two elastic {'balls' if d == 3 else 'discs (plane strain)'} of their own radii and materials meeting "
            "head-on (contact pair) vs Hertz's two-body impact",
            collision_balls.DEFAULT_LEVEL[d],
            collision_balls.sizes(d),
            collision_balls.run_times(d),
            collision_balls.measure(d),
            collision_balls.check_params,
        )
        for d in (2, 3)
    ),
    *(
        Benchmark(
            f"incline{d}d",
            d,
            dict(incline.INCLINE_DEFAULTS),
            incline.builder(d),
            None,
            "elastic block on a tilted plane, Coulomb friction, vs the sliding acceleration g (sin a - mu cos a)",
            2,
            incline.sizes(d),
            incline.run_times,
            incline.measure(d),
            incline.check_params,
            True,
        )
        for d in (2, 3)
    ),
    *(
        Benchmark(
            f"spin{d}d",
            d,
            dict(spin.SPIN_DEFAULTS),
            spin.builder(d),
            None,
            f"a free elastic {'ball' if d == 3 else 'disc (plane strain)'} spinning (finite strain: energy and "
            "angular momentum kept; the linear model's spurious strain energy)",
            spin.DEFAULT_LEVEL[d],
            spin.sizes(d),
            spin.run_times,
            spin.measure(d),
            spin.check_params,
        )
        for d in (2, 3)
    ),
    Benchmark(
        "rings2d",
        2,
        dict(rings.RINGS_DEFAULTS),
        rings.build,
        None,
        "two Neo-Hookean rings colliding obliquely (contact pair in the current configuration, plane strain)",
        1,
        rings.sizes,
        rings.run_times,
        rings.measure,
        rings.check_params,
    ),
):
    _register(_b)


def get_benchmark(name: str) -> Benchmark:
    """The benchmark registered as ``name`` (error listing the allowed names otherwise)."""
    return BENCHMARKS.get(name).obj

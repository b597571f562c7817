"""Case files (TOML): a whole simulation described in one validated file.

Schema (every key is checked; unknown keys, wrong types and impossible values are
errors that name the key and the allowed values)::

    [mesh]                      # either a generator ...
    generator = "rectangle"     # interval | rectangle | box | file
    cells = [4, 40]             # elements per direction (1, 2 or 3 integers)
    size = [0.1, 1.0]           # lengths per direction
    cell = "quad"               # quad | triangle (2D), hexahedron | tetra (3D), line (1D)
    # file = "bar.msh"          # ... or a mesh file (generator = "file"), tags = physical groups

    [material]                  # lam + mu, or E + nu; rho always
    rho = 1.0
    lam = 0.25
    mu = 0.5

    [[dirichlet]]               # any number of blocks
    tag = "ymax"
    value = [0.0, 0.2]          # one number per listed component
    components = [0, 1]         # optional, default all

    [[traction]]                # optional, constant traction vectors
    tag = "xmax"
    value = [0.0, -1.0]

    [contact]
    tag = "ymin"
    obstacle = { type = "plane", point = [0.0, 0.0], normal = [0.0, 1.0] }
    # or { type = "sphere", center = [...], radius = R }: a rigid ball the body stays out of

    [initial]                   # numbers or expressions of x, y, z (numpy functions)
    displacement = [0.0, 0.2]
    velocity = [0.0, "-0.5"]

    [loads]                     # optional
    body_force = [0.0, 0.0]

    [time]
    scheme = "crank-nicolson"   # crank-nicolson | cn | backward-euler | be
    dt = 0.0125
    T = 1.0

    [solver]
    mass = "seed"               # standard | lumped | seed | seed-normal | moment-preserving |
                                # neighbour | mass-free-surface

    [output]
    directory = "out/case"
    snapshot_every = 0          # XDMF fields every k steps (0: none)
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..contact.obstacles import PlaneObstacle, SphereObstacle
from ..dynamics.mass import MASS_VARIANTS
from ..dynamics.problem import Problem
from ..dynamics.schemes import ALIASES, SCHEMES
from ..errors import InputError, check_choice, check_positive
from ..fem.material import IsotropicElastic
from ..fem.mesh import Mesh, box, interval, read_mesh, rectangle
from ..fem.space import Dirichlet

SECTIONS = {
    "mesh": {"generator", "cells", "size", "cell", "file"},
    "material": {"rho", "lam", "mu", "E", "nu"},
    "dirichlet": {"tag", "value", "components"},
    "traction": {"tag", "value"},
    "contact": {"tag", "obstacle"},
    "initial": {"displacement", "velocity"},
    "loads": {"body_force"},
    "time": {"scheme", "dt", "T"},
    "solver": {"mass"},
    "output": {"directory", "snapshot_every"},
}
REQUIRED = ("mesh", "material", "contact", "time")
_FUNCS = {k: getattr(np, k) for k in ("sin", "cos", "tan", "exp", "log", "sqrt", "abs", "tanh", "cosh", "sinh")}
_FUNCS.update(pi=math.pi, e=math.e)


@dataclass
class Case:
    problem: Problem
    scheme: str
    dt: float
    T: float
    mass: str
    out: Path | None
    snapshot_every: int


def _keys(section: str, table: dict, allowed: set[str]) -> None:
    if not isinstance(table, dict):
        raise InputError(f"[{section}] must be a table")
    for k in table:
        if k not in allowed:
            raise InputError(f"unknown key '{section}.{k}'; allowed: {', '.join(sorted(allowed))}")


def _number(key: str, v: Any) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise InputError(f"'{key}' must be a number, got {v!r}")
    return float(v)


def _vector(key: str, v: Any, dim: int) -> list[float]:
    if not isinstance(v, list) or len(v) != dim:
        raise InputError(f"'{key}' must be a list of {dim} numbers, got {v!r}")
    return [_number(f"{key}[{i}]", x) for i, x in enumerate(v)]


def expression(key: str, text: str, dim: int):
    """Compile an expression of x, y, z with numpy functions; errors name ``key``."""
    names = {"x", "y", "z"}
    try:
        code = compile(text, key, "eval")
    except SyntaxError as exc:
        raise InputError(f"'{key}': invalid expression {text!r}: {exc.msg}") from None
    bad = [n for n in code.co_names if n not in names and n not in _FUNCS]
    if bad:
        allowed = ", ".join(sorted(names | set(_FUNCS)))
        raise InputError(f"'{key}': unknown name(s) {bad} in {text!r}; allowed: {allowed}")

    def f(points: np.ndarray) -> np.ndarray:
        env = dict(_FUNCS)
        for i, n in enumerate("xyz"):
            env[n] = points[:, i] if i < points.shape[1] else np.zeros(points.shape[0])
        return np.broadcast_to(np.asarray(eval(code, {"__builtins__": {}}, env), dtype=float), points.shape[:1])

    return f


def _field(key: str, v: Any, dim: int):
    """A vector field given as numbers and/or expression strings."""
    if not isinstance(v, list) or len(v) != dim:
        raise InputError(f"'{key}' must be a list of {dim} numbers or expressions, got {v!r}")
    comps = []
    for i, c in enumerate(v):
        if isinstance(c, str):
            comps.append(expression(f"{key}[{i}]", c, dim))
        else:
            val = _number(f"{key}[{i}]", c)
            comps.append(lambda p, val=val: np.full(p.shape[0], val))
    if all(not isinstance(c, str) for c in v):
        return [float(c) for c in v]
    return lambda p: np.column_stack([c(p) for c in comps])


def _mesh(m: dict, base: Path) -> Mesh:
    _keys("mesh", m, SECTIONS["mesh"])
    gen = m.get("generator", "file" if "file" in m else None)
    gen = check_choice("mesh.generator", gen, {"interval", "rectangle", "box", "file"}) if gen else None
    if gen is None:
        raise InputError("missing key 'mesh.generator'; allowed: interval, rectangle, box, file")
    if gen == "file":
        if "file" not in m or not isinstance(m["file"], str):
            raise InputError("'mesh.file' must be the path of a mesh file")
        return read_mesh(base / m["file"])
    dim = {"interval": 1, "rectangle": 2, "box": 3}[gen]
    cells = m.get("cells")
    if not isinstance(cells, list) or len(cells) != dim or not all(isinstance(c, int) and c > 0 for c in cells):
        raise InputError(f"'mesh.cells' must be a list of {dim} positive integers, got {cells!r}")
    size = [
        check_positive(f"mesh.size[{i}]", _number(f"mesh.size[{i}]", s))
        for i, s in enumerate(_vector("mesh.size", m.get("size"), dim))
    ]
    default_cell = {1: "line", 2: "quad", 3: "hexahedron"}[dim]
    cell = m.get("cell", default_cell)
    allowed = {1: {"line"}, 2: {"quad", "triangle"}, 3: {"hexahedron", "tetra"}}[dim]
    check_choice("mesh.cell", cell, allowed)
    if dim == 1:
        return interval(cells[0], size[0])
    if dim == 2:
        return rectangle(cells[0], cells[1], size[0], size[1], cell)
    return box(*cells, *size, cell=cell)


def _material(t: dict) -> IsotropicElastic:
    _keys("material", t, SECTIONS["material"])
    if "rho" not in t:
        raise InputError("missing key 'material.rho'")
    rho = _number("material.rho", t["rho"])
    if {"lam", "mu"} <= set(t) and not ({"E", "nu"} & set(t)):
        return IsotropicElastic(_number("material.lam", t["lam"]), _number("material.mu", t["mu"]), rho)
    if "E" in t and not ({"lam", "mu"} & set(t)):
        return IsotropicElastic.from_young(_number("material.E", t["E"]), _number("material.nu", t.get("nu", 0.0)), rho)
    raise InputError("[material] needs either lam and mu, or E (and optionally nu), plus rho")


def load_case(path: str | Path) -> Case:
    """Read and validate a case file; raises :class:`InputError` on any problem."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"case file {str(path)!r} does not exist")
    try:
        data = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{path.name}: invalid TOML: {exc}") from None
    for k in data:
        if k not in SECTIONS:
            raise InputError(f"unknown section [{k}]; allowed: {', '.join(SECTIONS)}")
    for k in REQUIRED:
        if k not in data:
            raise InputError(f"missing section [{k}]")
    mesh = _mesh(data["mesh"], path.parent)
    dim = mesh.dim
    material = _material(data["material"])

    dirichlet = []
    for i, d in enumerate(data.get("dirichlet", [])):
        _keys(f"dirichlet[{i}]", d, SECTIONS["dirichlet"])
        if "tag" not in d:
            raise InputError(f"missing key 'dirichlet[{i}].tag'")
        mesh.nodes_of(d["tag"])
        comps = d.get("components", list(range(dim)))
        if not isinstance(comps, list) or not all(isinstance(c, int) and 0 <= c < dim for c in comps):
            raise InputError(f"'dirichlet[{i}].components' must be a list of integers in 0..{dim - 1}")
        value = _vector(f"dirichlet[{i}].value", d.get("value", [0.0] * len(comps)), len(comps))
        dirichlet.append(Dirichlet(d["tag"], tuple(value), tuple(comps)))
    tractions = {}
    for i, t in enumerate(data.get("traction", [])):
        _keys(f"traction[{i}]", t, SECTIONS["traction"])
        mesh.nodes_of(t.get("tag", ""))
        tractions[t["tag"]] = _vector(f"traction[{i}].value", t.get("value"), dim)

    c = data["contact"]
    _keys("contact", c, SECTIONS["contact"])
    if "tag" not in c:
        raise InputError("missing key 'contact.tag'")
    mesh.nodes_of(c["tag"])
    ob = c.get("obstacle")
    if not isinstance(ob, dict):
        raise InputError("missing table 'contact.obstacle' = { type = \"plane\", point = [...], normal = [...] }")
    kind = check_choice("contact.obstacle.type", ob.get("type", "plane"), {"plane", "sphere"})
    if kind == "plane":
        _keys("contact.obstacle", ob, {"type", "point", "normal"})
        obstacle = PlaneObstacle(
            _vector("contact.obstacle.point", ob.get("point"), dim),
            _vector("contact.obstacle.normal", ob.get("normal"), dim),
        )
    else:
        _keys("contact.obstacle", ob, {"type", "center", "radius"})
        radius = check_positive("contact.obstacle.radius", _number("contact.obstacle.radius", ob.get("radius")))
        obstacle = SphereObstacle(_vector("contact.obstacle.center", ob.get("center"), dim), radius)

    init = data.get("initial", {})
    _keys("initial", init, SECTIONS["initial"])
    u0 = _field("initial.displacement", init.get("displacement", [0.0] * dim), dim)
    v0 = _field("initial.velocity", init.get("velocity", [0.0] * dim), dim)
    loads = data.get("loads", {})
    _keys("loads", loads, SECTIONS["loads"])
    body = _vector("loads.body_force", loads["body_force"], dim) if "body_force" in loads else None

    tm = data["time"]
    _keys("time", tm, SECTIONS["time"])
    scheme = tm.get("scheme", "crank-nicolson")
    check_choice("time.scheme", scheme, set(SCHEMES) | set(ALIASES))
    for k in ("dt", "T"):
        if k not in tm:
            raise InputError(f"missing key 'time.{k}'")
    dt = check_positive("time.dt", _number("time.dt", tm["dt"]))
    T = check_positive("time.T", _number("time.T", tm["T"]))
    if T < dt:
        raise InputError(f"'time.T' must be >= 'time.dt', got T={T} < dt={dt}")
    sol = data.get("solver", {})
    _keys("solver", sol, SECTIONS["solver"])
    mass = check_choice("solver.mass", sol.get("mass", "seed"), set(MASS_VARIANTS))
    outp = data.get("output", {})
    _keys("output", outp, SECTIONS["output"])
    out = outp.get("directory")
    if out is not None and not isinstance(out, str):
        raise InputError("'output.directory' must be a string")
    every = outp.get("snapshot_every", 0)
    if not isinstance(every, int) or isinstance(every, bool) or every < 0:
        raise InputError(f"'output.snapshot_every' must be a non-negative integer, got {every!r}")
    problem = Problem(mesh, material, c["tag"], obstacle, dirichlet, u0, v0, body, tractions, name=path.stem)
    return Case(problem, scheme, dt, T, mass, Path(out) if out else None, every)

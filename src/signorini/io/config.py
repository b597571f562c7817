"""Case files (TOML): a whole simulation described in one validated file.

The keys, types, defaults and units are data in :mod:`signorini.io.schema`
(``docs/case-files.md`` is generated from it).

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
    value = [0.0, "0.2 - 0.1 * t"]   # one number or expression of x, y, z, t per component
    components = [0, 1]         # optional, default all

    [[traction]]                # optional; numbers or expressions of x, y, z, t
    tag = "xmax"
    value = [0.0, "-1.0 * min(t, 1)"]

    [contact]
    tag = "ymin"
    obstacle = { type = "plane", point = [0.0, "0.1 * t"], normal = [0.0, 1.0] }
    # friction = { law = "coulomb", coefficient = 0.3 }   # or { law = "tresca", threshold = 0.01 }
    # or { type = "sphere", center = [...], radius = R }: a rigid ball the body stays out of
    # or { type = "surface", file = "die.stl", flip = false }: a triangulated (2D: polygonal) surface
    # positions (point, center, translation) may be expressions of t: a moving obstacle, and
    # rotation = { angle = "0.1 * t", axis = [0, 0, 1], center = [...] } turns it (2D: no axis)

    [initial]                   # numbers or expressions of x, y, z (numpy functions)
    displacement = [0.0, 0.2]
    velocity = [0.0, "-0.5"]

    [loads]                     # optional; numbers or expressions of x, y, z, t
    body_force = [0.0, "-9.81 * min(t / 0.1, 1)"]

    [time]
    scheme = "crank-nicolson"   # any name of the scheme registry (docs/registries.md)
    dt = 0.0125
    T = 1.0
    # beta = 0.3                # the scheme's own options (newmark: beta, gamma; ...)

    [solver]
    mass = "moment-preserving"  # any name of the mass registry (this is the default)
    # backend = "auto"          # and the solver options: memory_budget, lcp_max_iter,
    # preconditioner = "jacobi" # condense_budget, the backend's own (cg: preconditioner,
                                # rtol, max_iter, max_newton)

    [output]
    directory = "out/case"
    snapshot_every = 0          # XDMF fields every k steps (0: none)
    checkpoint_every = 0        # checkpoint.h5 every k steps (0: at the end only)

    [limits]                    # optional: refuse larger runs unless yes = true
    max_steps = 1000000
    max_memory = 16.0           # GiB (default 80% of the machine's memory)
    yes = false
"""

from __future__ import annotations

import inspect
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..contact.friction import make_friction
from ..contact.obstacles import OBSTACLES, ROTATION_KEYS, RigidObstacle, Rotation, read_surface
from ..dynamics.model.damping import Rayleigh, RegionalRayleigh, make_damping, regional_damping
from ..dynamics.model.mass import DEFAULT_MASS, MASS_VARIANTS
from ..dynamics.model.problem import Problem
from ..dynamics.model.validate import INITIAL_ACCELERATIONS
from ..dynamics.schemes import SCHEMES
from ..errors import InputError, check_choice, check_positive, not_a_file
from ..fem.elements import QUADRATIC, reference_element
from ..fem.material import MATERIAL_MODELS, IsotropicElastic, with_model
from ..fem.mesh import Mesh, box, elevate, interval, read_mesh, rectangle
from ..fem.space import Dirichlet
from ..linalg import BACKENDS, SOLVER_OPTIONS, solver_options
from ..registry import FilePath, Motion, RotationTable, Vector
from .expressions import Expression, _short, check_finite, vector_field
from .schema import REQUIRED, section_keys

TIME_KEYS = {"scheme", "dt", "T", "stop_at", "control", "dt_min", "tolerance"}
SECTIONS = section_keys()  # the fixed keys; [time] and [solver] also take registry-defined ones


@dataclass
class Case:
    problem: Problem
    scheme: str
    dt: float
    T: float
    mass: str
    out: Path | None
    snapshot_every: int
    scheme_options: dict[str, Any] = field(default_factory=dict)
    solver_options: dict[str, Any] = field(default_factory=dict)
    limits: dict[str, Any] = field(default_factory=dict)
    #: whether the file names its mass variant ([solver] mass) or takes the default
    mass_named: bool = False
    #: built-in events that end the run ([time] stop_at)
    stop_at: list[str] = field(default_factory=list)
    #: a checkpoint every k levels ([output] checkpoint_every; 0: at the end only)
    checkpoint_every: int = 0
    #: the other files the case reads (a mesh file, a surface obstacle), part of its identity
    files: list[Path] = field(default_factory=list)
    #: the time-step control ([time] control, dt_min, tolerance); None: the key is absent
    control: dict[str, Any] | None = None


def _keys(section: str, table: dict, allowed: set[str]) -> None:
    if not isinstance(table, dict):
        raise InputError(f"[{section}] must be a table")
    for k in table:
        if k not in allowed:
            raise InputError(f"unknown key '{section}.{k}'; allowed: {', '.join(sorted(allowed))}")


def _number(key: str, v: Any) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise InputError(f"'{key}' must be a number, got {str(v)[:60]!r}")
    try:
        f = float(v)
    except OverflowError:
        f = math.inf
    if not math.isfinite(f):
        raise InputError(f"'{key}' must be a finite number, got {str(v)[:60]}")
    return f


def _vector(key: str, v: Any, dim: int) -> list[float]:
    if not isinstance(v, list) or len(v) != dim:
        raise InputError(f"'{key}' must be a list of {dim} numbers, got {v!r}")
    return [_number(f"{key}[{i}]", x) for i, x in enumerate(v)]


def _tag(mesh: Mesh, key: str, table: dict) -> str:
    if "tag" not in table:
        raise InputError(f"missing key '{key}.tag'")
    if not isinstance(table["tag"], str):
        raise InputError(f"'{key}.tag' must be a string, got {table['tag']!r}")
    mesh.nodes_of(table["tag"])
    return table["tag"]


def _contact_tags(mesh: Mesh, table: dict) -> str | tuple[str, ...]:
    """``[contact] tag``: one tag or a list of tags (their union)."""
    tags = table.get("tag")
    if isinstance(tags, list):
        if not tags or not all(isinstance(t, str) for t in tags):
            raise InputError(f"'contact.tag' must be a tag or a non-empty list of tags, got {_short(tags)}")
        mesh.nodes_of(tags)
        return tuple(tags)
    return _tag(mesh, "contact", table)


def _pairs(mesh: Mesh, table: dict) -> list:
    """``[contact] pairs = [{ slave = "...", master = "...", friction = { law = ... } }, ...]``:
    facet tags in contact, each with its own contact law (optional: the section's ``friction``)."""
    from ..contact.pairs import ContactPair

    given = table.get("pairs", [])
    if not isinstance(given, list) or not all(isinstance(p, dict) for p in given):
        raise InputError(
            f'\'contact.pairs\' must be a list of tables {{ slave = "tag", master = "tag" }}, got {_short(given)}'
        )
    out = []
    for k, p in enumerate(given):
        extra = sorted(set(p) - {"slave", "master", "friction"})
        if extra or not {"slave", "master"} <= set(p):
            raise InputError(
                f"'contact.pairs[{k}]' needs the keys slave and master (facet tags) and optionally "
                f"friction; got {sorted(p)}"
            )
        for side in ("slave", "master"):
            if not isinstance(p[side], str):
                raise InputError(f"'contact.pairs[{k}].{side}' must be a facet tag, got {_short(p[side])}")
            mesh.facets_of(p[side])
        law = make_friction(p["friction"], f"contact.pairs[{k}].friction") if "friction" in p else None
        out.append(ContactPair(p["slave"], p["master"], law))
    return out


def _where(table: dict):
    """``[contact] where``: a condition on x, y, z restricting the contact nodes, or None."""
    if "where" not in table:
        return None
    text = table["where"]
    if not isinstance(text, str):
        raise InputError(f"'contact.where' must be an expression string such as \"z < 0.2\", got {_short(text)}")
    ex = Expression("contact.where", text, conditions=True)
    if not ex.is_condition:  # a number would be taken as "!= 0": say what is expected instead
        raise InputError(
            f"'contact.where' must be a condition, a comparison such as \"z < 0.2\" (< <= > >= == !=, "
            f"combined with and, or, not), got {text!r}"
        )
    if "t" in ex.variables:
        raise InputError("'contact.where' may use x, y and z only (the contact nodes do not change in time)")
    return lambda p: check_finite("contact.where", text, ex(p), p, 0.0) != 0


def _mesh(m: dict, base: Path, guard=None, files: list | None = None) -> Mesh:
    _keys("mesh", m, SECTIONS["mesh"])
    gen = m.get("generator", "file" if "file" in m else None)
    gen = check_choice("mesh.generator", gen, {"interval", "rectangle", "box", "file"}) if gen else None
    if gen is None:
        raise InputError("missing key 'mesh.generator'; allowed: interval, rectangle, box, file")
    order = m.get("order")
    if order is not None and (not isinstance(order, int) or isinstance(order, bool) or order not in (1, 2)):
        raise InputError(f"'mesh.order' must be 1 (linear cells) or 2 (quadratic cells), got {_short(order)}")
    if gen == "file":
        if "file" not in m or not isinstance(m["file"], str):
            raise InputError("'mesh.file' must be the path of a mesh file")
        if files is not None:
            files.append(base / m["file"])
        mesh = read_mesh(base / m["file"])
        if order == 1 and mesh.order == 2:
            raise InputError(
                f"'mesh.order' = 1, but {m['file']!r} holds quadratic cells ({mesh.cell_type}); remove "
                "'order' (a file's cells are read as they are) or mesh it with linear cells"
            )
        return elevate(mesh) if order == 2 and mesh.order == 1 else mesh
    order = int(order or 1)
    dim = {"interval": 1, "rectangle": 2, "box": 3}[gen]
    cells = m.get("cells")
    if (
        not isinstance(cells, list)
        or len(cells) != dim
        or not all(isinstance(c, int) and not isinstance(c, bool) and c > 0 for c in cells)
    ):
        raise InputError(f"'mesh.cells' must be a list of {dim} positive integers, got {cells!r}")
    for i, c in enumerate(cells):
        if c > 10**15:  # beyond any run-size limit, and beyond exact float arithmetic
            text = str(c) if len(str(c)) <= 20 else f"{str(c)[:6]}... ({len(str(c))} digits)"
            raise InputError(f"'mesh.cells[{i}]' = {text} is too large: at most 1e15 cells per direction")
    size = [check_positive(f"mesh.size[{i}]", s) for i, s in enumerate(_vector("mesh.size", m.get("size"), dim))]
    for i, (s, c) in enumerate(zip(size, cells, strict=True)):
        if not (1e-100 <= s / c and s <= 1e100):
            raise InputError(f"'mesh.size[{i}]' = {s:g} over {c} cells: sizes must stay within 1e-100 .. 1e100")
    default_cell = {1: "line", 2: "quad", 3: "hexahedron"}[dim]
    cell = m.get("cell", default_cell)
    allowed = {1: {"line"}, 2: {"quad", "triangle"}, 3: {"hexahedron", "tetra"}}[dim]
    check_choice("mesh.cell", cell, allowed)
    if guard is not None:  # the run-size check, before anything is allocated
        per_cell, split = {"line": (2, 1), "quad": (4, 1), "triangle": (3, 2), "hexahedron": (8, 1), "tetra": (4, 6)}[
            cell
        ]
        if order == 2:  # the doubled grid (a split cell's diagonals meet at the grid's new points)
            per_cell = reference_element(QUADRATIC[cell]).n_nodes
        nodes = math.prod(order * c + 1 for c in cells)
        guard((nodes, split * math.prod(cells), per_cell, dim, nodes // (order * min(cells) + 1)))
    if dim == 1:
        return interval(cells[0], size[0], order=order)
    if dim == 2:
        return rectangle(cells[0], cells[1], size[0], size[1], cell, order=order)
    return box(*cells, *size, cell=cell, order=order)


def _material(
    t: dict, key: str = "material", allowed: set[str] | None = None, model: str = "linear"
) -> IsotropicElastic:
    """``[material]`` (or one of its ``regions`` entries, ``key`` naming it in messages; ``model``: the
    model when the table gives none)."""
    _keys(key, t, SECTIONS["material"] if allowed is None else allowed)
    if "rho" not in t:
        raise InputError(f"missing key '{key}.rho'")
    model = t.get("model", model)
    if not isinstance(model, str) or model not in MATERIAL_MODELS:
        raise InputError(f"'{key}.model' must be one of {', '.join(MATERIAL_MODELS)}; got {_short(model)}")
    return with_model(_linear_material(t, key), model)


def _linear_material(t: dict, key: str) -> IsotropicElastic:
    """The constants of a ``[material]`` table."""
    try:
        rho = _number(f"{key}.rho", t["rho"])
        if {"lam", "mu"} <= set(t) and not ({"E", "nu"} & set(t)):
            return IsotropicElastic(_number(f"{key}.lam", t["lam"]), _number(f"{key}.mu", t["mu"]), rho)
        if "E" in t and not ({"lam", "mu"} & set(t)):
            E, nu = _number(f"{key}.E", t["E"]), _number(f"{key}.nu", t.get("nu", 0.0))
            return IsotropicElastic.from_young(E, nu, rho)
    except InputError as exc:
        if key == "material" or str(exc).startswith(f"'{key}"):
            raise
        raise InputError(f"{key}: {exc}") from None
    where = "[material]" if key == "material" else f"'{key}'"
    raise InputError(f"{where} needs either lam and mu, or E (and optionally nu), plus rho")


def _region_tag(mesh: Mesh, key: str, entry: Any) -> str:
    """The ``tag`` of a ``regions`` entry: a region of the mesh (InputError naming ``key`` otherwise)."""
    if not isinstance(entry, dict):
        raise InputError(f"'{key}' must be an inline table {{ tag = \"region\", ... }}, got {_short(entry)}")
    tag = entry.get("tag")
    if not isinstance(tag, str) or not tag:
        raise InputError(f"'{key}.tag' must be the name of a region of cells, got {_short(tag)}")
    if tag not in mesh.regions or mesh.regions[tag].size == 0:
        known = ", ".join(sorted(t for t, c in mesh.regions.items() if c.size))
        known = known or "none (a mesh file makes regions from named physical groups of cells)"
        raise InputError(f"'{key}.tag': {tag!r} is not a region of the mesh; its regions: {known}")
    return tag


def _material_regions(t: dict, mesh: Mesh) -> dict[str, IsotropicElastic]:
    """``[material] regions = [{ tag = "plate", E = ..., nu = ..., rho = ... }, ...]``."""
    given = t.get("regions", [])
    if not isinstance(given, list):
        raise InputError(
            f"'material.regions' must be a list of tables {{ tag = \"region\", E = ..., rho = ... }}, "
            f"got {_short(given)}"
        )
    out: dict[str, IsotropicElastic] = {}
    allowed = SECTIONS["material"] - {"regions"}
    for k, entry in enumerate(given):
        key = f"material.regions[{k}]"
        tag = _region_tag(mesh, key, entry)
        if tag in out:
            raise InputError(f"'{key}.tag': region {tag!r} is listed twice in material.regions")
        own = {a: v for a, v in entry.items() if a != "tag"}
        if set(own) <= {"damping", "model"}:  # no constants of its own: the section's material (its damping, model)
            _keys(key, own, allowed)
            own = {**{a: v for a, v in t.items() if a in CONSTANTS}, **own}
        out[tag] = _material(own, key, allowed, t.get("model", "linear"))
    return out


#: the constants of a material table (a regions entry without any takes the section's)
CONSTANTS = ("E", "nu", "lam", "mu", "rho")


def _damping(t: dict, mesh: Mesh) -> Rayleigh | RegionalRayleigh | None:
    """``[material] damping = { alpha = ..., beta = ... }``: Rayleigh damping of the mesh; a ``regions`` entry
    with its own ``damping`` gives its cells theirs (an entry without one takes the section's), a
    :class:`~signorini.dynamics.model.damping.RegionalRayleigh` (docs/schemes.md, "Damping")."""
    damping = make_damping(t.get("damping"), "material.damping")
    own: dict[str, Rayleigh | None] = {}
    for k, entry in enumerate(t.get("regions", [])):
        if isinstance(entry, dict) and "damping" in entry:
            key = f"material.regions[{k}]"
            own[_region_tag(mesh, f"{key}", entry)] = make_damping(entry["damping"], f"{key}.damping")
    out = regional_damping(damping, own)
    if isinstance(out, RegionalRayleigh):
        out.cell_coefficients(mesh)  # regions sharing cells with different damping: refused now
    return out


def _initial_regions(init: dict, mesh: Mesh) -> list:
    """``[initial] regions = [{ tag = "ball", velocity = [...], displacement = [...] }, ...]``."""
    from ..dynamics.model.problem import RegionInitial

    given = init.get("regions", [])
    if not isinstance(given, list):
        raise InputError(
            f"'initial.regions' must be a list of tables {{ tag = \"region\", velocity = [...] }}, got {_short(given)}"
        )
    out = []
    for k, entry in enumerate(given):
        key = f"initial.regions[{k}]"
        tag = _region_tag(mesh, key, entry)
        _keys(key, entry, {"tag", "velocity", "displacement"})
        values = {}
        for name in ("velocity", "displacement"):
            if name in entry:
                f = vector_field(f"{key}.{name}", entry[name], mesh.dim)
                if getattr(f, "time_dependent", False):
                    raise InputError(f"'{key}.{name}' cannot depend on t (it is the state at t = 0)")
                values[name] = f
        out.append(RegionInitial(tag, **values))
    return out


def _dirichlet(blocks: Any, mesh: Mesh) -> list[Dirichlet]:
    if not isinstance(blocks, list):
        raise InputError("[[dirichlet]] must be an array of tables")
    out, dim = [], mesh.dim
    for i, d in enumerate(blocks):
        key = f"dirichlet[{i}]"
        _keys(key, d, SECTIONS["dirichlet"])
        tag = _tag(mesh, key, d)
        comps = d.get("components", list(range(dim)))
        if (
            not isinstance(comps, list)
            or not comps
            or not all(isinstance(c, int) and not isinstance(c, bool) and 0 <= c < dim for c in comps)
        ):
            raise InputError(f"'{key}.components' must be a list of integers in 0..{dim - 1}")
        value = vector_field(f"{key}.value", d.get("value", [0.0] * len(comps)), len(comps))
        for j, prev in enumerate(out):
            if prev.tag == tag and set(prev.components) & set(comps):
                raise InputError(
                    f"'{key}' and 'dirichlet[{j}]' both prescribe component(s) "
                    f"{sorted(set(prev.components) & set(comps))} on tag {tag!r}: give each component once per tag"
                )
        out.append(Dirichlet(tag, tuple(value) if isinstance(value, list) else value, tuple(comps)))
    return out


def _tractions(blocks: Any, mesh: Mesh) -> dict:
    if not isinstance(blocks, list):
        raise InputError("[[traction]] must be an array of tables")
    out = {}
    for i, t in enumerate(blocks):
        key = f"traction[{i}]"
        _keys(key, t, SECTIONS["traction"])
        tag = _tag(mesh, key, t)
        if tag in out:
            first = next(j for j, b in enumerate(blocks) if isinstance(b, dict) and b.get("tag") == tag)
            raise InputError(
                f"'{key}' repeats tag {tag!r} of 'traction[{first}]': give one block per tag (add the values)"
            )
        out[tag] = vector_field(f"{key}.value", t.get("value"), mesh.dim)
    return out


def _obstacle(ob: Any, dim: int, base: Path | None = None, files: list | None = None) -> RigidObstacle:
    """An obstacle of the registry; vector parameters may be expressions of t, ``rotation`` is a
    table of :data:`~signorini.contact.obstacles.ROTATION_KEYS`, a ``file`` is relative to ``base``
    (the case file's directory).  A parameter of default None is required; the others may be
    left out (the class's default: no rotation, no translation, no flip)."""
    if not isinstance(ob, dict):
        raise InputError("missing table 'contact.obstacle' = { type = \"plane\", point = [...], normal = [...] }")
    kind = OBSTACLES.get(check_choice("contact.obstacle.type", ob.get("type", "plane"), set(OBSTACLES.names())))
    _keys("contact.obstacle", ob, {"type"} | {p.name for p in kind.parameters})
    kwargs: dict[str, Any] = {}
    for p in kind.parameters:
        key = f"contact.obstacle.{p.name}"
        if p.name not in ob:
            if p.default is None:
                raise InputError(f"missing key '{key}'")
            continue
        if p.kind is Motion:
            kwargs[p.name] = vector_field(key, ob[p.name], dim, allow_space=False)
        elif p.kind is Vector:
            kwargs[p.name] = _vector(key, ob[p.name], dim)
        elif p.kind is RotationTable:
            kwargs[p.name] = _rotation(key, ob[p.name], dim)
        elif p.kind is FilePath:
            file = _file_path(key, ob[p.name], base)
            if files is not None:
                files.append(file)
            kwargs[p.name] = read_surface(file, dim, where=f"'{key}'")
        elif p.kind is bool:
            kwargs[p.name] = _bool(key, ob[p.name])
        else:
            kwargs[p.name] = p.convert(_number(key, ob[p.name]), "contact.obstacle")
    if "dim" in inspect.signature(kind.obj).parameters:
        kwargs["dim"] = dim
    return kind.obj(**kwargs)


def _bool(key: str, v: Any) -> bool:
    if not isinstance(v, bool):
        raise InputError(f"'{key}' must be true or false, got {_short(v)}")
    return v


def _file_path(key: str, v: Any, base: Path | None) -> Path:
    """A file name of the case file, relative to its directory."""
    if not isinstance(v, str) or not v.strip():
        raise InputError(f"'{key}' must be a file name (a non-empty string), got {_short(v)}")
    path = Path(v).expanduser()
    return path if path.is_absolute() or base is None else base / path


def _rotation(key: str, table: Any, dim: int) -> Rotation:
    """``rotation = { angle = ..., axis = [...], center = [...] }``: angle a number or an expression
    of t [rad]; axis in 3D only (in 2D the axis is out of the plane); center optional (the
    obstacle's default) except for a surface."""
    if not isinstance(table, dict):
        raise InputError(
            f"'{key}' must be an inline table {{ angle = ..., axis = [...], center = [...] }}, got {_short(table)}"
        )
    _keys(key, table, {p.name for p in ROTATION_KEYS})
    if dim == 1:
        raise InputError(f"'{key}': a 1D obstacle cannot rotate")
    if "angle" not in table:
        raise InputError(f"missing key '{key}.angle' (radians: a number or an expression of t)")
    angle = table["angle"]
    if isinstance(angle, str):
        ex = Expression(f"{key}.angle", angle)
        if ex.variables - {"t"}:
            raise InputError(f"'{key}.angle': only t may appear here, got {sorted(ex.variables)}")
        value = lambda t, ex=ex: float(check_finite(ex.key, ex.text, ex(None, t), None, t)[0])  # noqa: E731
        if not ex.time_dependent:  # a constant: a fixed rotated obstacle
            value = value(0.0)
    else:
        if isinstance(angle, (list, dict)):
            raise InputError(f"'{key}.angle' must be a number or an expression of t, got {_short(angle)}")
        value = _number(f"{key}.angle", angle)
        if not math.isfinite(value):
            raise InputError(f"'{key}.angle' must be finite, got {_short(angle)}")
    if dim == 2 and "axis" in table:
        raise InputError(f"'{key}.axis': in 2D the axis is out of the plane (angles counterclockwise); omit 'axis'")
    if dim == 3 and "axis" not in table:
        raise InputError(f"missing key '{key}.axis' (3D: the direction of the axis)")
    axis = _vector(f"{key}.axis", table["axis"], 3) if "axis" in table else None
    if axis is not None and not any(axis):
        raise InputError(f"'{key}.axis' must be a non-zero vector, got {axis}")
    center = _vector(f"{key}.center", table["center"], dim) if "center" in table else None
    return Rotation(value, axis, center)


def _time(tm: Any) -> tuple[str, float | list, float, dict]:
    if not isinstance(tm, dict):
        raise InputError("[time] must be a table")
    scheme = tm.get("scheme", "crank-nicolson")
    if not isinstance(scheme, str) or scheme not in SCHEMES:
        raise InputError(f"unknown time.scheme {scheme!r}; allowed: {', '.join(SCHEMES.names())}")
    entry = SCHEMES.get(scheme)
    _keys("time", tm, TIME_KEYS | {p.name for p in entry.parameters})
    if isinstance(tm.get("dt"), list):  # a schedule [{until, dt}, ...]: T defaults to the last until
        from ..dynamics.stepping.time_grid import TimeGrid, parse_schedule

        schedule = parse_schedule(tm["dt"], "time.dt")
        T = check_positive("time.T", _number("time.T", tm["T"])) if "T" in tm else schedule[-1][0]
        TimeGrid.build(schedule, T)  # every segment a whole number of steps
        options = entry.options({k: v for k, v in tm.items() if k not in TIME_KEYS}, where="time")
        return (
            entry.name,
            [{"until": u, "dt": d} for u, d in schedule],
            T,
            {k: v for k, v in options.items() if k in tm},
        )
    for k in ("dt", "T"):
        if k not in tm:
            raise InputError(f"missing key 'time.{k}'")
    dt = check_positive("time.dt", _number("time.dt", tm["dt"]))
    T = check_positive("time.T", _number("time.T", tm["T"]))
    if T < dt:
        raise InputError(f"'time.T' must be >= 'time.dt', got T={T} < dt={dt}")
    options = entry.options({k: v for k, v in tm.items() if k not in TIME_KEYS}, where="time")
    return entry.name, dt, T, {k: v for k, v in options.items() if k in tm}


def _solver(sol: Any) -> tuple[str, dict]:
    if not isinstance(sol, dict):
        raise InputError("[solver] must be a table")
    options = {p.name for p in SOLVER_OPTIONS} | {p.name for e in BACKENDS for p in e.parameters}
    _keys("solver", sol, SECTIONS["solver"] | options)
    mass = sol.get("mass", DEFAULT_MASS)
    if not isinstance(mass, str) or mass not in MASS_VARIANTS:
        raise InputError(f"unknown solver.mass {mass!r}; allowed: {', '.join(MASS_VARIANTS.names())}")
    given = {k: v for k, v in sol.items() if k != "mass"}
    solver_options(given, where="solver")
    return MASS_VARIANTS.resolve(mass), given


def _output(outp: Any) -> tuple[Path | None, int, int]:
    _keys("output", outp, SECTIONS["output"])
    out = outp.get("directory")
    if out is not None and not isinstance(out, str):
        raise InputError("'output.directory' must be a string")
    if out is not None and not out.strip():
        raise InputError("'output.directory' must not be empty (omit the key for the default out/<case name>)")
    every = outp.get("snapshot_every", 0)
    if not isinstance(every, int) or isinstance(every, bool) or every < 0:
        raise InputError(f"'output.snapshot_every' must be a non-negative integer, got {every!r}")
    ck = outp.get("checkpoint_every", 0)
    if not isinstance(ck, int) or isinstance(ck, bool) or ck < 0:
        raise InputError(f"'output.checkpoint_every' must be a non-negative integer, got {ck!r}")
    return (Path(out) if out else None), every, ck


def _limits(lim: Any) -> dict:
    _keys("limits", lim, SECTIONS["limits"])
    out: dict[str, Any] = {}
    if "max_steps" in lim:
        v = lim["max_steps"]
        if not isinstance(v, int) or isinstance(v, bool) or v < 1:
            raise InputError(f"'limits.max_steps' must be a positive integer, got {v!r}")
        out["max_steps"] = v
    if "max_memory" in lim:
        out["max_memory"] = check_positive("limits.max_memory", _number("limits.max_memory", lim["max_memory"]))
    if "yes" in lim:
        if not isinstance(lim["yes"], bool):
            raise InputError(f"'limits.yes' must be true or false, got {lim['yes']!r}")
        out["yes"] = lim["yes"]
    return out


def _read(path: Path) -> dict:
    if not path.is_file():
        raise InputError(f"case file {str(path)!r} {not_a_file(path, 'a case file')}")
    try:
        data = tomllib.loads(path.read_text())
    except OSError as exc:
        raise InputError(f"case file {str(path)!r} cannot be read: {exc.strerror or exc}") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"{path.name}: invalid TOML: {exc}") from None
    except RecursionError:
        raise InputError(f"{path.name}: invalid TOML: nested too deeply") from None
    for k in data:
        if k not in SECTIONS:
            raise InputError(f"unknown section [{k}]; allowed: {', '.join(SECTIONS)}")
    for k in REQUIRED:
        if k not in data:
            raise InputError(f"missing section [{k}]")
    return data


def load_case(path: str | Path, limits: dict | None = None, size_check=None, backend: str | None = None) -> Case:
    """Read and validate a case file; raises :class:`InputError` on any problem.

    ``limits`` override the file's ``[limits]``; ``size_check(counts, dt, T, limits, solver)``
    (the command line's run-size check) is called before a generated mesh is built, with
    the file's ``[solver]`` options and ``backend`` (the command line's) or else the file's.
    """
    path = Path(path)
    data = _read(path)
    scheme, dt, T, scheme_options = _time(data["time"])
    limits = {**_limits(data.get("limits", {})), **(limits or {})}
    guard = None
    if size_check is not None:
        solver = data.get("solver")
        named = solver.get("backend") if isinstance(solver, dict) else None
        chosen = backend or (named if named in BACKENDS.names() else None)  # a misspelling: refused later

        options = {**(solver if isinstance(solver, dict) else {}), "backend": chosen}

        def guard(counts):
            size_check(counts, dt, T, limits, options)

    files: list[Path] = []
    mesh = _mesh(data["mesh"], path.parent, guard, files)
    dim = mesh.dim
    material = _material(data["material"])
    materials = _material_regions(data["material"], mesh)
    damping = _damping(data["material"], mesh)
    dirichlet = _dirichlet(data.get("dirichlet", []), mesh)
    tractions = _tractions(data.get("traction", []), mesh)
    c = data["contact"]
    _keys("contact", c, SECTIONS["contact"])
    pairs = _pairs(mesh, c)
    rigid = not pairs or "tag" in c or "obstacle" in c
    tag = _contact_tags(mesh, c) if rigid else None
    if not rigid and "where" in c:
        raise InputError(
            "'contact.where' restricts the contact nodes of [contact] tag against the rigid obstacle; "
            "this case has contact pairs only, where it would not apply: remove it (a pair's slave "
            "nodes are those of its slave tag)"
        )
    where = _where(c) if rigid else None
    obstacle = _obstacle(c.get("obstacle"), dim, path.parent, files) if rigid else None
    friction = make_friction(c["friction"], "contact.friction") if "friction" in c else None
    init = data.get("initial", {})
    _keys("initial", init, SECTIONS["initial"])
    u0 = vector_field("initial.displacement", init.get("displacement", [0.0] * dim), dim)
    v0 = vector_field("initial.velocity", init.get("velocity", [0.0] * dim), dim)
    for key, f in (("initial.displacement", u0), ("initial.velocity", v0)):
        if getattr(f, "time_dependent", False):
            raise InputError(f"'{key}' cannot depend on t (it is the state at t = 0)")
    initial_regions = _initial_regions(init, mesh)
    acceleration = init.get("acceleration", "equilibrium")
    if acceleration not in INITIAL_ACCELERATIONS:
        raise InputError(
            f"'initial.acceleration' must be one of {', '.join(map(repr, INITIAL_ACCELERATIONS))}, got {acceleration!r}"
        )
    equilibrium = _bool("initial.equilibrium", init.get("equilibrium", False))
    loads = data.get("loads", {})
    _keys("loads", loads, SECTIONS["loads"])
    body = vector_field("loads.body_force", loads["body_force"], dim) if "body_force" in loads else None
    gravity = None
    if "gravity" in loads:
        vector_field("loads.gravity", loads["gravity"], dim, allow_space=False)  # an acceleration: of t only
        gravity = vector_field("loads.gravity", loads["gravity"], dim)
    follow_mass = loads.get("follow_mass", True)
    if not isinstance(follow_mass, bool):
        raise InputError(f"'loads.follow_mass' must be true or false, got {follow_mass!r}")
    mass, solver_opts = _solver(data.get("solver", {}))
    out, every, checkpoint_every = _output(data.get("output", {}))
    problem = Problem(
        mesh,
        material,
        tag,
        obstacle,
        dirichlet,
        u0,
        v0,
        body,
        tractions,
        name=path.stem,
        contact_where=where,
        friction=friction,
        follow_mass=follow_mass,
        initial_acceleration=acceleration,
        pairs=pairs,
        materials=materials,
        initial_regions=initial_regions,
        gravity=gravity,
        damping=damping,
        initial_equilibrium=equilibrium,
    )
    named = "mass" in data.get("solver", {})
    from ..dynamics.observe.events import parse_stop_at

    stop_at = parse_stop_at(data["time"].get("stop_at"), "time.stop_at")
    control = _control(data["time"], dt)
    return Case(
        problem,
        scheme,
        dt,
        T,
        mass,
        out,
        every,
        scheme_options,
        solver_opts,
        limits,
        named,
        stop_at,
        checkpoint_every,
        files,
        control,
    )


def _control(tm: dict, dt: Any) -> dict[str, Any] | None:
    """[time] control, dt_min and tolerance as ``{"control": ..., options}``; None when none is given."""
    from ..dynamics.stepping.step_control import control_spec

    given = {k: tm[k] for k in ("control", "dt_min", "tolerance") if k in tm}
    if not given:
        return None
    name = given.pop("control", "energy")
    if name == "fixed" and given:
        raise InputError(f'\'time.{sorted(given)[0]}\' applies to control = "energy", not "fixed"')
    name, options = control_spec({"control": name, **given}, "time.control", "time")
    for key in ("dt_min", "tolerance"):  # numbers in a file (a command line's strings are converted)
        if key in given and (isinstance(given[key], bool) or not isinstance(given[key], (int, float))):
            raise InputError(f"'time.{key}' must be a number, got {given[key]!r}")
    if "dt_min" in given:
        from ..dynamics.stepping.step_control import MAX_LEVELS

        smallest = min(s["dt"] for s in dt) if isinstance(dt, list) else dt
        low = smallest / 2**MAX_LEVELS
        if not low <= options["dt_min"] <= smallest:
            raise InputError(
                f"'time.dt_min' must satisfy dt / 2^{MAX_LEVELS} = {low:.4g} <= dt_min <= dt = "
                f"{smallest:g}, got {options['dt_min']!r}"
            )
    return {"control": name, **{k: v for k, v in options.items() if k in given}}


def case_problem(path: str | Path) -> Problem:
    """The Problem of a case file (a module-level function: picklable for worker processes)."""
    return load_case(path).problem

"""Fuzz tests of case files through the command line (issue 11, item 5).

Hypothesis builds case files from the schema of :mod:`signorini.io.config` (every name
comes from the registries), writes each one into its own temporary directory and runs
``signorini.io.cli.main(["run", case, "--out", out, "--quiet"])`` in-process, with the
working directory set to that temporary directory, stdout/stderr and warnings captured
and a per-case time limit (SIGALRM).  Every case must end in one of the documented ways
(:func:`check_outcome`):

* exit 0: ``summary.json`` (strict JSON, status ``finished``), ``history.csv`` and
  ``contact.npz`` written, every number finite (null in summary.json and nan in
  history.csv only where documented), the contact conditions satisfied at every level
  (gap >= -tol, lambda <= tol, lambda * gap = 0, small complementarity residual);
* exit 2: exactly one line on stderr (warnings count: a user sees them), starting
  ``signorini: error:``, and no file created anywhere (only the case file is left);
* exit 3: ``summary.json`` with status ``failed``;

and never exit 1 (a bug), exit 4 (no environment failure is possible for these tiny
cases), a "Traceback", a hang, a file outside the output directory or a hidden
temporary directory left behind.

Cases: :func:`valid_cases` (tiny meshes: 1D 1..8 cells, 2D 1..2 x 1..4, 3D 1x1x2;
at most 20 steps), :data:`MUTATIONS` (one strategy per kind of invalid or extreme
input, each applied to a valid case), :data:`HOSTILE_EXPRESSIONS` and :data:`EDGE_CASES`
(fixed lists, parametrized explicitly).  The default run is deterministic
(``derandomize=True``); ``pytest -m slow tests/io/test_fuzz_cases.py`` runs a longer
search, deterministic too so that CI's verdict does not depend on the draw (a random
search found a new case in two CI runs in a row); ``SIGNORINI_FUZZ_RANDOM=1`` makes it
a random search, to look for new bugs.
"""

from __future__ import annotations

import contextlib
import copy
import csv
import datetime
import io
import json
import math
import os
import re
import shutil
import signal
import tempfile
import time
import tomllib
import warnings
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

from signorini.contact.obstacles import OBSTACLES
from signorini.dynamics.model.mass import DEFAULT_MASS, MASS_VARIANTS, linear_cell_variants
from signorini.dynamics.schemes import SCHEMES, EnergyMomentum, GeneralizedAlpha, MoreauJean
from signorini.io.cli import main
from signorini.io.config import SECTIONS
from signorini.linalg import BACKENDS, SOLVER_OPTIONS, has_pardiso

CASE_SECONDS = 5.0  # per-case time limit (SIGALRM)
VALID_EXAMPLES = 150  # default (deterministic) run
MUTATION_EXAMPLES = 15  # per mutation kind, default run
SLOW_VALID_EXAMPLES = 1500
SLOW_MUTATION_EXAMPLES = 75

OUTCOMES: dict[str, Counter] = {}  # kind -> exit codes seen (printed at the end with -s)


# ----------------------------------------------------------------------------- TOML
_BARE_KEY = re.compile(r"^[A-Za-z0-9_-]+$")


def toml_key(k: str) -> str:
    return k if _BARE_KEY.match(k) else json.dumps(k)


def toml_value(v) -> str:
    """A TOML literal (ints are written as they are, even beyond 64 bits: invalid TOML)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)  # JSON string escapes are TOML basic-string escapes
    if isinstance(v, (datetime.date, datetime.time)):
        return v.isoformat()
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{toml_key(k)} = {toml_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(f"no TOML literal for {v!r}")


def toml_document(doc: dict) -> str:
    """Top-level tables as [sections], lists of tables as [[sections]], the rest as keys."""
    head, body = [], []
    for name, value in doc.items():
        if isinstance(value, dict):
            body.append(f"\n[{toml_key(name)}]")
            body.extend(f"{toml_key(k)} = {toml_value(v)}" for k, v in value.items())
        elif isinstance(value, list) and value and all(isinstance(b, dict) for b in value):
            for block in value:
                body.append(f"\n[[{toml_key(name)}]]")
                body.extend(f"{toml_key(k)} = {toml_value(v)}" for k, v in block.items())
        else:
            head.append(f"{toml_key(name)} = {toml_value(value)}")
    return "\n".join(head + body) + "\n"


# ----------------------------------------------------------------------------- cases
@dataclass
class Case:
    """A case file and the exit codes it may end with."""

    doc: dict | None  # the case as data (None when the text is not TOML of a dict)
    text: str | bytes  # the file's content
    expected: frozenset[int]
    kind: str = "valid"
    note: str = ""
    meta: dict = field(default_factory=dict)  # dim, steps, T, scheme, restitution, moving

    def __repr__(self) -> str:  # what Hypothesis prints for a falsifying example
        text = self.text if isinstance(self.text, str) else repr(self.text)
        return f"Case(kind={self.kind!r}, note={self.note!r}, expected={sorted(self.expected)}):\n{text}"


ANY = frozenset({0, 2, 3})
INVALID = frozenset({2})
RUNS = frozenset({0, 3})
VALID = frozenset({0})  # a generated valid case must run: a refusal is a bug of the code or of the generator


def case_from_doc(doc: dict, expected=ANY, kind="valid", note="", meta=None) -> Case:
    return Case(doc, toml_document(doc), frozenset(expected), kind, note, dict(meta or {}))


def decimals(lo: float, hi: float, step: float = 0.01):
    """Round numbers in [lo, hi] (short reproducers, good shrinking)."""
    return st.integers(round(lo / step), round(hi / step)).map(lambda k: round(k * step, 10))


def _in_bounds(p, draw) -> float:
    """A multiple of 0.01 inside the parameter's bounds (never rounded out of them: HHT's
    alpha <= 1/3 gives at most 0.33)."""
    lo = 0.0 if p.low is None else p.low
    hi = lo + 1.0 if p.high is None else p.high
    lo_i, hi_i = math.ceil(lo * 100 - 1e-9), math.floor(hi * 100 + 1e-9)
    if p.open_low and lo_i / 100 <= lo:
        lo_i += 1
    if p.open_high and hi_i / 100 >= hi:
        hi_i -= 1
    return draw(st.integers(lo_i, hi_i)) / 100


MESHES = {
    1: ("interval", ("line",), ("xmin", "xmax")),
    2: ("rectangle", ("quad", "triangle"), ("xmin", "xmax", "ymin", "ymax")),
    3: ("box", ("hexahedron", "tetra"), ("xmin", "xmax", "ymin", "ymax", "zmin", "zmax")),
}
DTS = (0.01, 0.02, 0.025, 0.05, 0.1, 0.125)


#: masses that need two cells across the contact layer: ``seed`` keeps the cells not
#: touching Gamma_C, the moment-preserving extrapolation needs affinely independent
#: non-contact nodes (a single layer above a side is collinear in 2D)
NEEDS_THICKNESS = {"seed", "seed-normal", "moment-preserving", "moment-preserving-tensor"}


def mass_choices(entry, tilted: bool, cell_type: str) -> list[str]:
    """The mass variants a valid case may name with this scheme and geometry (the code refuses the others,
    with a message: schemes that need mass on every dof, the tensor form on simplices, seed-normal
    on a tilted or curved contact with the schemes that balance massless rows along the axes)."""
    if not entry.obj.massless_dofs_allowed:
        return ["standard", "lumped"]
    names = list(linear_cell_variants())
    if tilted and issubclass(entry.obj, (GeneralizedAlpha, MoreauJean, EnergyMomentum)):
        names.remove("seed-normal")
    if cell_type not in ("line", "quad", "hexahedron"):
        names.remove("moment-preserving-tensor")
    return names


@st.composite
def valid_cases(draw) -> Case:
    """A valid case on a tiny mesh: the body above a plane or a ball, contact on its
    lowest side (along the last axis), at most 20 time steps."""
    dim = draw(st.sampled_from([1, 2, 3]))
    gen, cells_types, tags = MESHES[dim]
    last = "xyz"[dim - 1]
    if dim == 1:
        cells = [draw(st.integers(1, 8))]
        size = [draw(decimals(0.5, 2.0))]
    elif dim == 2:
        cells = [draw(st.integers(1, 2)), draw(st.integers(1, 4))]
        size = [draw(decimals(0.1, 1.0)), draw(decimals(0.5, 2.0))]
    else:
        cells = [1, 1, 2]
        w = draw(decimals(0.2, 0.5))
        size = [w, w, draw(decimals(0.5, 1.0))]
    mesh = {"generator": gen, "cells": cells, "size": size}
    if dim > 1 or draw(st.booleans()):
        mesh["cell"] = draw(st.sampled_from(cells_types))
    height = size[-1]

    if draw(st.booleans()):
        material = {"rho": draw(decimals(0.5, 5.0)), "lam": draw(decimals(0.0, 2.0)), "mu": draw(decimals(0.2, 2.0))}
    else:
        material = {"rho": draw(decimals(0.5, 5.0)), "E": draw(decimals(1.0, 10.0))}
        if draw(st.booleans()):
            material["nu"] = draw(decimals(0.0, 0.45))

    gap = draw(decimals(0.0, 0.3))
    moving = draw(st.booleans()) and draw(st.booleans())
    tilted = False
    speed = draw(decimals(-0.5, 0.5))
    if draw(st.sampled_from(["plane", "plane", "sphere"])) == "plane":
        normal = [0.0] * dim
        normal[-1] = draw(st.sampled_from([1.0, 2.0, 0.5]))
        if dim > 1 and draw(st.booleans()):
            normal[0] = draw(decimals(0.0, 0.5))
            tilted = normal[0] != 0
        point: list = [0.0] * dim
        point[-1] = -gap
        if moving:
            point[-1] = draw(st.sampled_from([f"{-gap} + {speed} * t", f"{-gap} - 0.1 * sin(5 * t)"]))
        obstacle = {"type": "plane", "point": point, "normal": normal}
        if draw(st.booleans()):
            obstacle = {"point": point, "normal": normal}  # type defaults to plane
    else:
        radius = draw(decimals(0.5, 3.0))
        center: list = [s / 2 for s in size[:-1]] + [round(-radius - gap, 10)]
        if moving:
            center[-1] = f"{-radius - gap:.10g} + {speed} * t"
        obstacle = {"type": "sphere", "center": center, "radius": radius}
        tilted = True  # curved: keep tangential initial displacement zero
    doc: dict = {"mesh": mesh, "material": material}

    top = f"{last}max"
    if draw(st.integers(0, 9)) < 7:  # a clamp on the top side
        value: list = [draw(decimals(-0.1, 0.1)) for _ in range(dim)]
        kind = draw(st.sampled_from(["constant", "moving", "normal-only"]))
        block: dict = {"tag": top}
        if kind == "moving":
            value[-1] = draw(st.sampled_from([f"{value[-1]} - 0.2 * t", f"{value[-1]} * cos(t)", "0.1 * min(t, 0.2)"]))
        if kind == "normal-only":
            block["components"] = [dim - 1]
            value = value[-1:]
        if draw(st.integers(0, 4)) > 0:
            block["value"] = value
        doc["dirichlet"] = [block]
    elif draw(st.booleans()):
        doc["dirichlet"] = []
    if dim > 1 and draw(st.integers(0, 4)) == 0:
        tval: list = [0.0] * dim
        tval[0] = draw(st.sampled_from([-0.5, 0.25, "-0.5 * min(t / 0.1, 1)", "0.2 * sin(3 * t)"]))
        doc["traction"] = [{"tag": "xmax", "value": tval}]

    doc["contact"] = {"tag": f"{last}min", "obstacle": obstacle}

    initial: dict = {}
    if draw(st.booleans()):
        d = round(-gap * draw(st.sampled_from([0.0, 0.5, 0.9])) + draw(decimals(0.0, 0.2)), 10)
        disp: list = [0.0] * dim
        disp[-1] = draw(st.sampled_from([d, f"{d} * {last} / {height}", f"{d} + 0.05 * sin(pi * {last} / {height})"]))
        if dim > 1 and not tilted and draw(st.booleans()):
            disp[0] = draw(st.sampled_from([0.05, "0.01 * x", "-0.02 * y"]))
        initial["displacement"] = disp
    if draw(st.booleans()):
        v = draw(decimals(0.0, 2.0))
        vel: list = [0.0] * dim
        vel[-1] = draw(st.sampled_from([-v, str(-v), f"-{v} * cos(pi * {last} / {2 * height})"]))
        if dim > 1 and draw(st.booleans()):
            vel[0] = draw(decimals(-0.5, 0.5))
        initial["velocity"] = vel
    if initial or draw(st.booleans()):
        doc["initial"] = initial
    if draw(st.integers(0, 3)) == 0:
        force: list = [0.0] * dim
        force[-1] = draw(st.sampled_from([-9.81, "-9.81 * min(t / 0.1, 1)", f"-2 * (1 + {last})"]))
        doc["loads"] = {"body_force": force}

    entry = draw(st.sampled_from(list(SCHEMES)))
    scheme = draw(st.sampled_from([entry.name, *entry.aliases]))
    dt = draw(st.sampled_from(DTS))
    steps = draw(st.integers(1, 20))
    T = steps * dt
    time_t: dict = {"scheme": scheme, "dt": dt, "T": int(T) if T.is_integer() and draw(st.booleans()) else T}
    if entry.name == "crank-nicolson" and draw(st.booleans()):
        del time_t["scheme"]  # the default
    options = {}
    for p in entry.parameters:
        if draw(st.booleans()):
            options[p.name] = _in_bounds(p, draw)
    time_t.update(options)
    doc["time"] = time_t

    solver: dict = {}
    cell_type = mesh.get("cell", {1: "line", 2: "quad", 3: "hexahedron"}[dim])
    choices = mass_choices(entry, tilted, cell_type)
    if draw(st.integers(0, 4)) > 0 or DEFAULT_MASS not in choices:
        solver["mass"] = draw(st.sampled_from(choices))
    if MASS_VARIANTS.resolve(solver.get("mass", DEFAULT_MASS)) in NEEDS_THICKNESS:
        cells[-1] = max(cells[-1], 2)  # two cells across the contact layer: mass left, an affine fit possible
    if draw(st.integers(0, 3)) == 0:
        backends = ["auto", "superlu"] + ([] if entry.obj.needs_condensed_solve else ["cg"])
        backends += ["pardiso"] if has_pardiso() else []  # (extra 'pardiso'; CI installs it)
        solver["backend"] = draw(st.sampled_from(backends))
        if solver["backend"] in ("auto", "cg") and draw(st.booleans()):
            solver["preconditioner"] = draw(st.sampled_from(["jacobi", "amg"]))
        if draw(st.booleans()):
            solver["lcp_max_iter"] = draw(st.integers(5, 100))
    if solver or draw(st.booleans()):
        doc["solver"] = solver
    if draw(st.integers(0, 6)) == 0:
        doc["output"] = {"directory": "results/elsewhere", "snapshot_every": draw(st.integers(0, 3))}
    if draw(st.integers(0, 4)) == 0:
        doc["limits"] = {"max_steps": draw(st.integers(steps, 1000)), "yes": draw(st.booleans())}
    restitution = float(options.get("restitution", 0.0)) if entry.name == "paoli-schatzman" else 0.0
    meta = {"dim": dim, "steps": steps, "T": T, "dt": dt, "scheme": entry.name, "restitution": restitution}
    meta.update(moving=moving, gap=gap, tilted=tilted)
    return case_from_doc(doc, VALID, "valid", "", meta)


# ----------------------------------------------------------------------------- mutations
def paths(doc, prefix=(), min_depth=1):
    """Every path to a value inside ``doc`` (dict keys and list indices)."""
    out = []
    items = doc.items() if isinstance(doc, dict) else enumerate(doc) if isinstance(doc, list) else ()
    for k, v in items:
        p = (*prefix, k)
        if len(p) >= min_depth:
            out.append(p)
        out.extend(paths(v, p, min_depth))
    return out


def get_at(doc, path):
    for k in path:
        doc = doc[k]
    return doc


def set_at(doc, path, value) -> None:
    get_at(doc, path[:-1])[path[-1]] = value


def delete_at(doc, path) -> None:
    del get_at(doc, path[:-1])[path[-1]]


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _mutated(base: Case, doc: dict, expected, kind: str, note: str, meta=None) -> Case:
    return case_from_doc(doc, expected, kind, note, {**base.meta, **(meta or {})})


UTC = datetime.UTC
GARBAGE = (
    True,
    False,
    "not a number",
    datetime.datetime(1979, 5, 27, 7, 32, tzinfo=UTC),
    datetime.date(1979, 5, 27),
    datetime.time(7, 32),
    {"k": 1},
    {},
    [[1.0, 2.0]],
    ["a", 1],
)


@st.composite
def wrong_type(draw, base: Case) -> Case:
    doc = copy.deepcopy(base.doc)
    path = draw(st.sampled_from(paths(doc, min_depth=2)))
    old = get_at(doc, path)
    choices = [g for g in GARBAGE if type(g) is not type(old) or (isinstance(g, list) and g != old)]
    if path[-1] == "yes":
        choices = [g for g in choices if not isinstance(g, bool)]
    if path == ("output", "directory"):
        choices = [g for g in choices if not isinstance(g, str)]
    garbage = draw(st.sampled_from(choices))
    set_at(doc, path, garbage)
    return _mutated(base, doc, INVALID, "wrong_type", f"{'.'.join(map(str, path))} = {garbage!r}")


EXTREMES = (
    1e308,
    -1e308,
    1.7976931348623157e308,
    -0.0,
    0.0,
    5e-324,
    -5e-324,
    2.2250738585072014e-308,
    1e-300,
    1e20,
    -1e20,
    2**63 - 1,
    -(2**63),
    2**53 + 1,
    2**64,  # not a TOML integer
    10**400,
    math.inf,
    -math.inf,
    math.nan,
)


@st.composite
def extreme_number(draw, base: Case) -> Case:
    doc = copy.deepcopy(base.doc)
    numeric = [p for p in paths(doc, min_depth=2) if _is_number(get_at(doc, p))]
    path = draw(st.sampled_from(numeric))
    value = draw(st.sampled_from(EXTREMES))
    set_at(doc, path, value)
    return _mutated(base, doc, ANY, "extreme_number", f"{'.'.join(map(str, path))} = {value!r}")


def expression_slots(doc: dict, dim: int) -> list[tuple]:
    """Paths of vector components that accept an expression (adds the optional vectors)."""
    slots = []
    for section, key in (("initial", "displacement"), ("initial", "velocity"), ("loads", "body_force")):
        doc.setdefault(section, {}).setdefault(key, [0.0] * dim)
        slots += [(section, key, i) for i in range(dim)]
    for i, block in enumerate(doc.get("dirichlet", [])):
        if isinstance(block.get("value"), list):
            slots += [("dirichlet", i, "value", j) for j in range(len(block["value"]))]
    for i in range(len(doc.get("traction", []))):
        slots += [("traction", i, "value", j) for j in range(dim)]
    ob = doc["contact"]["obstacle"]
    position = "center" if "center" in ob else "point"
    slots += [("contact", "obstacle", position, j) for j in range(dim)]
    return slots


# (expression, exit codes allowed wherever it is put); ANY: depends on where and when
HOSTILE_EXPRESSIONS = [
    ("(lambda: 1)()", INVALID),
    ("x.__class__", INVALID),
    ("x.__class__.__mro__[1].__subclasses__()", INVALID),
    ("__import__('os')", INVALID),
    ("__import__('os').system('touch pwned')", INVALID),
    ("open('/etc/passwd').read()", INVALID),
    ("eval('1')", INVALID),
    ("globals()", INVALID),
    ("9**9**9", INVALID),
    ("9**999", INVALID),
    ("2**-1074", INVALID),
    ("x**x", INVALID),
    ("1/0", INVALID),
    ("0/0", INVALID),
    ("1 % 0", INVALID),
    ("1e309", INVALID),
    ("-1e309", INVALID),
    ("1e308 * 10", INVALID),
    ("exp(710)", INVALID),
    ("log(0)", INVALID),
    ("sqrt(-1)", INVALID),
    ("1" * 400, INVALID),  # an integer literal beyond float64
    ("0x" + "f" * 300, INVALID),
    ("9" * 2000, INVALID),
    ("1" * 5000, INVALID),
    ("-" * 150 + "x", INVALID),  # deeper than MAX_DEPTH = 100
    ("-" * 100000 + "1", INVALID),
    ("sin(" * 150 + "x" + ")" * 150, INVALID),  # deeper than MAX_DEPTH = 100
    ("x" + " + x" * 500, INVALID),
    ("(" * 300 + "1" + ")" * 300, INVALID),
    ("x if x else 1", INVALID),
    ("[x][0]", INVALID),
    ("x[0]", INVALID),
    ("'a'", INVALID),
    ("f'{x}'", INVALID),
    ("x == 1", INVALID),
    ("x and 1", INVALID),
    ("not x", INVALID),
    ("x @ x", INVALID),
    ("x // 1", INVALID),
    ("~x", INVALID),
    ("1j", INVALID),
    ("True", INVALID),
    ("None", INVALID),
    ("...", INVALID),
    ("nan", INVALID),
    ("inf", INVALID),
    ("sin", INVALID),
    ("pi(1)", INVALID),
    ("sin(x)(1)", INVALID),
    ("sin(x=1)", INVALID),
    ("sin(*x)", INVALID),
    ("sin(x, 1)", INVALID),  # a second positional argument is numpy's `out`
    ("sin(x, x)", INVALID),
    ("max(1, 2, 3)", INVALID),
    ("min(x)", INVALID),
    ("x; 1", INVALID),
    ("x\n+ 1", INVALID),
    ("\x00", INVALID),
    ("", INVALID),
    ("   ", INVALID),
    ("# nothing", INVALID),
    ("ﬁ", INVALID),
    ("log(x - 1)", ANY),
    ("exp(1000 * x)", ANY),
    ("exp(1000 * t)", ANY),
    ("exp(exp(exp(x + 10)))", ANY),
    ("1 / (t - 0.05)", ANY),
    ("(x + 1e10)**64", ANY),
    ("tan(pi / 2)", ANY),
    ("2**64", ANY),
    ("10.0**-64", ANY),
    ("x**-1", ANY),
    ("x # a comment", ANY),
    ("1_000 * 0", ANY),
    ("+-+-0.0", ANY),
    ("ｘ * 0", ANY),  # NFKC: the fullwidth x is x
    ("(" * 100 + "0" + ")" * 100, ANY),
]


@st.composite
def hostile_expression(draw, base: Case) -> Case:
    doc = copy.deepcopy(base.doc)
    path = draw(st.sampled_from(expression_slots(doc, base.meta["dim"])))
    expr, expected = draw(st.sampled_from(HOSTILE_EXPRESSIONS))
    set_at(doc, path, expr)
    return _mutated(base, doc, expected, "hostile_expression", f"{'.'.join(map(str, path))} = {expr[:60]!r}")


REQUIRED_PATHS = {
    ("mesh",),
    ("material",),
    ("contact",),
    ("time",),
    ("mesh", "generator"),
    ("mesh", "cells"),
    ("mesh", "size"),
    ("material", "rho"),
    ("material", "lam"),
    ("material", "mu"),
    ("material", "E"),
    ("contact", "tag"),
    ("contact", "obstacle"),
    ("time", "dt"),
    ("time", "T"),
}


@st.composite
def missing_key(draw, base: Case) -> Case:
    doc = copy.deepcopy(base.doc)
    candidates = [p for p in paths(doc) if isinstance(p[-1], str)]
    path = draw(st.sampled_from(candidates))
    delete_at(doc, path)
    required = (
        path in REQUIRED_PATHS
        or path[-1] == "tag"
        or (path[0] == "traction" and path[-1] == "value")
        or (path[:2] == ("contact", "obstacle") and path != ("contact", "obstacle", "type"))
        or (path == ("contact", "obstacle", "type") and base.doc["contact"]["obstacle"]["type"] != "plane")
    )
    return _mutated(base, doc, INVALID if required else ANY, "missing_key", f"del {'.'.join(map(str, path))}")


EXTRA_KEYS = ("bogus", "dT", "Rho", "betta", "normals", "cell_type", "", " ", "ρ", "mass ", "scheme\n", "t")


@st.composite
def extra_key(draw, base: Case) -> Case:
    doc = copy.deepcopy(base.doc)
    tables = [(k,) for k, v in doc.items() if isinstance(v, dict)]
    tables += [(k, i) for k, v in doc.items() if isinstance(v, list) for i in range(len(v))]
    tables.append(("contact", "obstacle"))
    where = draw(st.sampled_from(tables))
    table = get_at(doc, where)
    allowed = set(SECTIONS.get(where[0], ())) | {p.name for e in SCHEMES for p in e.parameters}
    allowed |= {p.name for p in SOLVER_OPTIONS} | {p.name for e in BACKENDS for p in e.parameters}
    allowed |= {"type"} | {p.name for e in OBSTACLES for p in e.parameters}
    key = draw(st.sampled_from([k for k in EXTRA_KEYS if k not in allowed and k not in table]))
    table[key] = draw(st.sampled_from([1, 0.5, "x", True, [1.0]]))
    return _mutated(base, doc, INVALID, "extra_key", f"{'.'.join(map(str, where))}.{key!r} added")


@st.composite
def unknown_section(draw, base: Case) -> Case:
    doc = copy.deepcopy(base.doc)
    name = draw(st.sampled_from(["meshes", "Mesh", "boundary", "obstacle", "dirichlet_bc", "time step", "", "ключ"]))
    value = draw(st.sampled_from([{"a": 1}, {}, 1, "x", [{"tag": "xmin"}]]))
    items = list(doc.items())
    items.insert(draw(st.integers(0, len(items))), (name, value))
    return _mutated(base, dict(items), INVALID, "unknown_section", f"[{name}] = {value!r}")


@st.composite
def wrong_length(draw, base: Case) -> Case:
    doc = copy.deepcopy(base.doc)
    vectors = [("mesh", "cells"), ("mesh", "size")]
    for p in paths(doc):
        if p[-1] in ("point", "normal", "center", "displacement", "velocity", "body_force") or (
            p[0] in ("dirichlet", "traction") and p[-1] == "value"
        ):
            vectors.append(p)
    path = draw(st.sampled_from(vectors))
    vec = list(get_at(doc, path))
    how = draw(st.sampled_from(["drop", "append", "empty", "double"]))
    new = {"drop": vec[:-1], "append": [*vec, vec[-1]], "empty": [], "double": vec + vec}[how]
    set_at(doc, path, new)
    return _mutated(base, doc, INVALID, "wrong_length", f"{'.'.join(map(str, path))} = {new!r}")


BAD_TAGS = ("", "ymin ", "YMIN", "Xmin", "zmin", "wmin", "all", "top", "*", "xmin\x00", "ɣmin", "x" * 10000)


@st.composite
def bad_tag(draw, base: Case) -> Case:
    doc = copy.deepcopy(base.doc)
    tagged = [p for p in paths(doc) if p[-1] == "tag"]
    path = draw(st.sampled_from(tagged))
    existing = MESHES[base.meta["dim"]][2]
    tag = draw(st.sampled_from([t for t in BAD_TAGS if t not in existing]))
    set_at(doc, path, tag)
    return _mutated(base, doc, INVALID, "bad_tag", f"{'.'.join(map(str, path))} = {tag[:20]!r}")


@st.composite
def obstacle_inside(draw, base: Case) -> Case:
    """A flipped plane normal, a plane above the body, or the body inside the ball."""
    doc = copy.deepcopy(base.doc)
    ob = doc["contact"]["obstacle"]
    size = doc["mesh"]["size"]
    if "normal" in ob:
        how = draw(st.sampled_from(["flip", "above"]))
        if how == "flip" and base.meta["gap"] == 0 and not base.meta["tilted"]:
            how = "above"  # a flipped plane through the contact side: see EDGE_CASES
        if how == "flip":
            ob["normal"] = [-c for c in ob["normal"]]
        else:
            ob["point"] = [0.0] * (len(size) - 1) + [size[-1] + draw(decimals(0.01, 1.0))]
    else:
        # the initial configuration is x + u0: without u0 the contact nodes start inside the ball
        # (an overlap smaller than u0 would legitimately be lifted out of it)
        doc.setdefault("initial", {})["displacement"] = [0.0] * len(size)
        how = draw(st.sampled_from(["center", "radius"]))
        if how == "center":
            ob["center"] = [s / 2 for s in size]
            ob["radius"] = draw(st.sampled_from([10.0, 1e6]))
        else:  # just larger than the distance to the nearest contact node
            depth = ob["radius"] + base.meta["gap"]
            ob["center"][-1] = -depth  # fixed (it may have moved)
            cells = doc["mesh"]["cells"]
            off = [0.0 if n % 2 == 0 else s / n / 2 for n, s in zip(cells[:-1], size[:-1], strict=True)]
            reach = math.sqrt(depth**2 + sum(o * o for o in off))
            ob["radius"] = round(reach + draw(decimals(0.01, 1.0)), 10)
    return _mutated(base, doc, INVALID, "obstacle_inside", f"obstacle {how}: {ob!r}")


@st.composite
def t_not_multiple(draw, base: Case) -> Case:
    doc = copy.deepcopy(base.doc)
    dt, steps = base.meta["dt"], base.meta["steps"]
    frac = draw(st.sampled_from([0.5, 0.3, 1e-6, -0.5]))
    T = max(dt * (steps + frac), dt * 0.5)
    doc["time"]["T"] = T
    return _mutated(base, doc, INVALID, "t_not_multiple", f"T = {T!r}, dt = {dt!r}")


@st.composite
def huge_T(draw, base: Case) -> Case:
    doc = copy.deepcopy(base.doc)
    doc.pop("limits", None)  # the default step limit (1,000,000) must refuse these
    dt = base.meta["dt"]
    T = draw(st.sampled_from([dt * (10**6 + 1), dt * 10**9, dt * 10**15, 1e300, 1e308, 1.7976931348623157e308]))
    doc["time"]["T"] = T
    return _mutated(base, doc, INVALID, "huge_T", f"T = {T!r}, dt = {dt!r}")


@st.composite
def tiny_dt(draw, base: Case) -> Case:
    doc = copy.deepcopy(base.doc)
    doc.pop("limits", None)
    dt = draw(st.sampled_from([1e-12, 1e-200, 1e-300, 1e-310, 5e-324]))
    doc["time"]["dt"] = dt
    if draw(st.booleans()):
        k = draw(st.integers(1, 5))
        doc["time"]["T"] = dt * k
        expected = ANY
    else:
        expected = INVALID  # T/dt > 1,000,000 steps: refused
    return _mutated(base, doc, expected, "tiny_dt", f"dt = {dt!r}, T = {doc['time']['T']!r}")


CHOICE_SLOTS = {
    ("time", "scheme"): ["rk4", "crank nicolson", "crank_nicolson", "", "euler"],
    ("solver", "mass"): ["seedx", "", "heavy", "seed mass"],
    ("mesh", "generator"): ["cube", "Rectangle ", "", "circle", "file"],
    ("mesh", "cell"): ["quadrilateral", "hex", "tri", "", "line "],
    ("contact", "obstacle", "type"): ["ball", "plane ", "", "cylinder"],
    ("solver", "backend"): ["umfpack", "", "CG ", "mumps"],
    # registry names are case-insensitive and stripped ("AMG " is amg): not a bad choice
    ("solver", "preconditioner"): ["ilu", "", "amgx"],
}


@st.composite
def bad_choice(draw, base: Case) -> Case:
    doc = copy.deepcopy(base.doc)
    path = draw(st.sampled_from(sorted(CHOICE_SLOTS)))
    value = draw(st.sampled_from(CHOICE_SLOTS[path]))
    doc.setdefault(path[0], {})
    set_at(doc, path, value)
    return _mutated(base, doc, INVALID, "bad_choice", f"{'.'.join(path)} = {value!r}")


MESH_FILES = ("missing.msh", "case.toml", "/dev/null", ".", "", "../../../../etc/passwd", "sub/dir/x.vtk", "a\x00b")


@st.composite
def bad_mesh_file(draw, base: Case) -> Case:
    doc = copy.deepcopy(base.doc)
    name = draw(st.sampled_from(MESH_FILES))
    mesh = {"generator": "file", "file": name} if draw(st.booleans()) else {"file": name}
    doc["mesh"] = mesh
    return _mutated(base, doc, INVALID, "bad_mesh_file", f"mesh = {mesh!r}")


BAD_OPTIONS = {
    "newmark": {"beta": [0.0, 0.6, -1.0, "x", True], "gamma": [0.4, 1.5, math.nan]},
    "theta": {"theta": [0.4, 1.01, -0.0, math.inf]},
    "paoli-schatzman": {"restitution": [-0.1, 1.5, "x"]},
}
BAD_SOLVER_OPTIONS = {
    "rtol": [0.0, 1.0, -1e-3, "small"],
    "lcp_max_iter": [0, -5, 2.5, True],
    "max_iter": [0, 0.5],
    "max_newton": [0, -1],
    "memory_budget": [-1.0, math.inf],
    "condense_budget": [-1.0, math.nan],
    "backend": [3],
}


@st.composite
def bad_option(draw, base: Case) -> Case:
    doc = copy.deepcopy(base.doc)
    scheme = base.meta["scheme"]
    if draw(st.booleans()):
        if scheme in BAD_OPTIONS:
            name = draw(st.sampled_from(sorted(BAD_OPTIONS[scheme])))
            value = draw(st.sampled_from(BAD_OPTIONS[scheme][name]))
        else:  # an option of another scheme (not one of this scheme's own)
            own = {p.name for p in SCHEMES.get(scheme).parameters}
            foreign = [(k, v) for k, v in (("beta", 0.25), ("theta", 1.0), ("restitution", 0.0), ("stiffness", 10.0),
                                           ("rho_inf", 0.5), ("alpha", 0.1)) if k not in own]  # fmt: skip
            name, value = draw(st.sampled_from(foreign))
        doc["time"][name] = value
        where = "time"
    else:
        name = draw(st.sampled_from(sorted(BAD_SOLVER_OPTIONS)))
        value = draw(st.sampled_from(BAD_SOLVER_OPTIONS[name]))
        doc.setdefault("solver", {})[name] = value
        where = "solver"
    return _mutated(base, doc, INVALID, "bad_option", f"{where}.{name} = {value!r}")


@st.composite
def section_not_table(draw, base: Case) -> Case:
    doc = copy.deepcopy(base.doc)
    name = draw(st.sampled_from(sorted(SECTIONS)))
    value = draw(st.sampled_from([1, "mesh", [1, 2], True, 0.5]))
    doc[name] = value
    return _mutated(base, doc, INVALID, "section_not_table", f"{name} = {value!r}")


@st.composite
def huge_cells(draw, base: Case) -> Case:
    doc = copy.deepcopy(base.doc)
    doc.pop("limits", None)
    dim = base.meta["dim"]
    i = draw(st.integers(0, dim - 1))
    n = draw(st.sampled_from([10**12, 2**40, 2**53 + 1, 2**62, 2**63 - 1, 0, -1, -(2**63)]))
    doc["mesh"]["cells"][i] = n
    return _mutated(base, doc, INVALID, "huge_cells", f"mesh.cells[{i}] = {n}")


@st.composite
def initial_penetration(draw, base: Case) -> Case:
    doc = copy.deepcopy(base.doc)
    dim = base.meta["dim"]
    how = draw(st.sampled_from(["push", "depends on t", "obstacle depends on x"]))
    if how == "push":
        d: list = [0.0] * dim
        d[-1] = draw(st.sampled_from([-50.0, "-50 + 0 * x", -1e6]))
        doc.setdefault("initial", {})["displacement"] = d
        note = f"initial.displacement = {d!r}"
    elif how == "depends on t":
        key = draw(st.sampled_from(["displacement", "velocity"]))
        v: list = [0.0] * dim
        v[-1] = "0.01 * t"
        doc.setdefault("initial", {})[key] = v
        note = f"initial.{key} = {v!r}"
    else:
        ob = doc["contact"]["obstacle"]
        key = "center" if "center" in ob else "point"
        pos = list(ob[key])
        pos[-1] = f"{pos[-1]} + 0 * {'xyz'[draw(st.integers(0, dim - 1))]}"
        ob[key] = pos
        note = f"contact.obstacle.{key} = {pos!r}"
    return _mutated(base, doc, INVALID, "initial_penetration", note)


@st.composite
def dirichlet_on_contact(draw, base: Case) -> Case:
    doc = copy.deepcopy(base.doc)
    dim = base.meta["dim"]
    tag = doc["contact"]["tag"]
    block = {"tag": tag, "value": [0.0] * dim}
    if draw(st.booleans()):
        block["components"] = list(range(dim))
    doc["dirichlet"] = [*doc.get("dirichlet", []), block]
    return _mutated(base, doc, INVALID, "dirichlet_on_contact", f"dirichlet on {tag!r}")


BAD_MATERIALS = (
    {"rho": 1.0, "E": 1.0, "lam": 1.0},
    {"rho": 1.0, "lam": 1.0},
    {"rho": 1.0, "mu": 1.0},
    {"rho": 1.0, "nu": 0.3},
    {"rho": 1.0, "E": 1.0, "nu": 0.5},
    {"rho": 1.0, "E": 1.0, "nu": 0.6},
    {"rho": 1.0, "E": 1.0, "nu": -1.0},
    {"rho": 1.0, "E": -1.0},
    {"rho": 1.0, "E": 0.0},
    {"rho": -1.0, "E": 1.0},
    {"rho": 1.0, "lam": 1.0, "mu": 0.0},
    {"rho": 1.0, "lam": -1.0, "mu": 0.1},
    {"E": 1.0},
    {},
)


@st.composite
def bad_material(draw, base: Case) -> Case:
    doc = copy.deepcopy(base.doc)
    doc["material"] = dict(draw(st.sampled_from(BAD_MATERIALS)))
    return _mutated(base, doc, INVALID, "bad_material", f"material = {doc['material']!r}")


@st.composite
def raw_text(draw, base: Case) -> Case:
    text = base.text
    how = draw(st.sampled_from(["truncate", "garbage", "bytes", "empty", "duplicate", "bom", "nul"]))
    if how == "truncate":
        cut = draw(st.integers(0, len(text) - 1))
        return Case(None, text[:cut], ANY, "raw_text", f"truncated at {cut}", dict(base.meta))
    if how == "garbage":
        junk = draw(st.sampled_from(["[mesh", "= 1", "a = ", "[[contact]]\n", "x = [1,", "'''", "\\u", "a.b.c = 1"]))
        pos = draw(st.integers(0, len(text)))
        new: str | bytes = text[:pos] + "\n" + junk + "\n" + text[pos:]
        expected = ANY if junk == "a.b.c = 1" or junk == "[[contact]]\n" else INVALID
    elif how == "bytes":
        new = draw(st.sampled_from([b"\xff\xfe\x00\x01", b"\x80" * 10, text.encode()[:-1] + b"\xc3"]))
        expected = INVALID
    elif how == "empty":
        new = draw(st.sampled_from(["", "\n", "# only a comment\n", " "]))
        expected = INVALID
    elif how == "duplicate":
        new = text + '\n[mesh]\ngenerator = "interval"\n'
        expected = INVALID
    elif how == "bom":
        new = "\ufeff" + text
        expected = ANY
    else:
        new = text.replace("\n", "\n\x00", 1)
        expected = INVALID
    return Case(None, new, frozenset(expected), "raw_text", how, dict(base.meta))


MUTATIONS = {
    "wrong_type": wrong_type,
    "extreme_number": extreme_number,
    "hostile_expression": hostile_expression,
    "missing_key": missing_key,
    "extra_key": extra_key,
    "unknown_section": unknown_section,
    "wrong_length": wrong_length,
    "bad_tag": bad_tag,
    "obstacle_inside": obstacle_inside,
    "t_not_multiple": t_not_multiple,
    "huge_T": huge_T,
    "tiny_dt": tiny_dt,
    "bad_choice": bad_choice,
    "bad_mesh_file": bad_mesh_file,
    "bad_option": bad_option,
    "section_not_table": section_not_table,
    "huge_cells": huge_cells,
    "initial_penetration": initial_penetration,
    "dirichlet_on_contact": dirichlet_on_contact,
    "bad_material": bad_material,
    "raw_text": raw_text,
}


def mutated_cases(kind: str):
    return valid_cases().flatmap(MUTATIONS[kind])


# ----------------------------------------------------------------------------- running
class CaseTimeout(BaseException):
    """Raised by SIGALRM; a BaseException so that the CLI's `except Exception` cannot hide it."""


def _alarm(signum, frame):
    raise CaseTimeout


def listing(root: Path) -> set[str]:
    """Every file and directory below root (relative paths, hidden ones included)."""
    out = set()
    for dirpath, dirnames, filenames in os.walk(root):
        rel = Path(dirpath).relative_to(root)
        out.update(str(rel / n) for n in dirnames + filenames)
    return out


@dataclass
class Outcome:
    rc: int | None  # None: timed out
    stdout: str
    stderr: str  # the CLI's stderr, then the warnings it emitted (formatted as Python prints them)
    warnings: list[str]
    before: set[str]
    after: set[str]
    seconds: float
    out: Path
    summary: dict | None = None
    history: list[dict] | None = None
    contact: dict | None = None

    def __repr__(self) -> str:  # short: the assertion messages carry the details
        return f"Outcome(rc={self.rc})"


def run_case(case: Case, parent: Path) -> Outcome:
    """Write the case into a fresh directory and run the CLI there (cwd = that directory)."""
    root = Path(tempfile.mkdtemp(prefix="case-", dir=parent))
    try:
        path = root / "case.toml"
        if isinstance(case.text, bytes):
            path.write_bytes(case.text)
        else:
            path.write_text(case.text, encoding="utf-8", errors="surrogatepass")
        out = root / "out"
        before = listing(root)
        stdout, stderr = io.StringIO(), io.StringIO()
        old_cwd = os.getcwd()
        old_handler = signal.signal(signal.SIGALRM, _alarm)
        t0 = time.perf_counter()
        rc: int | None = None
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("default")
            try:
                os.chdir(root)
                with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
                    signal.setitimer(signal.ITIMER_REAL, CASE_SECONDS)
                    try:
                        rc = main(["run", str(path), "--out", str(out), "--quiet"])
                    finally:
                        signal.setitimer(signal.ITIMER_REAL, 0)
            except CaseTimeout:
                rc = None
            finally:
                os.chdir(old_cwd)
                signal.signal(signal.SIGALRM, old_handler)
        seconds = time.perf_counter() - t0
        shown = [warnings.formatwarning(w.message, w.category, w.filename, w.lineno, w.line) for w in caught]
        text = stderr.getvalue() + "".join(shown)
        o = Outcome(rc, stdout.getvalue(), text, shown, before, listing(root), seconds, out)
        read_results(o)
        return o
    finally:
        shutil.rmtree(root, ignore_errors=True)


def _reject_constant(name):
    raise ValueError(f"non-standard JSON constant {name}")


def read_results(o: Outcome) -> None:
    if (o.out / "summary.json").is_file():
        o.summary = json.loads((o.out / "summary.json").read_text(), parse_constant=_reject_constant)
    if (o.out / "history.csv").is_file():
        with open(o.out / "history.csv", newline="") as fh:
            o.history = list(csv.DictReader(fh))
    if (o.out / "contact.npz").is_file():
        with np.load(o.out / "contact.npz") as z:
            o.contact = {k: z[k] for k in z.files}


# ----------------------------------------------------------------------------- the contract
# null in summary.json: the relative energy drift when E0 = 0 (the CLI prints "E0 = 0"),
# min_gap and max_lambda without contact nodes, energy_identity_residual when the energy
# is zero at every level or no step has an identity (History.summary / diagnostics)
NULLABLE = {
    "energy_max_relative_drift",
    "energy_max_relative_drift_undamped",
    "min_gap",
    "max_lambda",
    "energy_identity_residual",
}  # the drifts: null when E0 = 0 (relative to nothing)
# nan in history.csv: energy_increment and impulse at level 0, predicted_increment at level 0 and
# wherever the scheme has no energy identity (History docstring)
NAN_COLUMNS = {"predicted_increment"}
LEVEL0_NAN_COLUMNS = {"energy_increment", "impulse", "dt"}  # per-step columns: no step ends at level 0
RESIDUAL_TOL = 1e-6


def _numbers(obj, path=""):
    """(path, value) of every number and null in a JSON document."""
    if isinstance(obj, dict):
        for k, v in obj.items():
            yield from _numbers(v, f"{path}.{k}" if path else k)
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            yield from _numbers(v, f"{path}[{i}]")
    elif obj is None or (isinstance(obj, (int, float)) and not isinstance(obj, bool)):
        yield path, obj


def describe(case: Case, o: Outcome) -> str:
    text = case.text if isinstance(case.text, str) else repr(case.text)
    return (
        f"\n--- case ({case.kind}: {case.note}) expected exit {sorted(case.expected)}, got {o.rc} "
        f"in {o.seconds:.2f}s\n{text}\n--- stderr:\n{o.stderr[-3000:]}\n--- stdout:\n{o.stdout[-1000:]}\n"
        f"--- new files: {sorted(o.after - o.before)[:20]}"
    )


def check_outcome(case: Case, o: Outcome) -> None:
    """The CLI contract; each kind of violation fails on its own line (Hypothesis reports
    distinct failures separately)."""
    info = describe(case, o)
    rc, expected = o.rc, case.expected
    assert rc is not None, f"hang: no exit within {CASE_SECONDS}s{info}"
    assert "Traceback" not in o.stdout + o.stderr, f"traceback in the output{info}"
    assert rc != 1, f"internal error (exit 1){info}"
    assert rc != 4, f"environment failure (exit 4) for a tiny case{info}"
    assert rc in expected, f"exit {rc} not in {sorted(expected)}{info}"
    new = o.after - o.before
    if o.rc == 2:
        lines = o.stderr.splitlines()
        assert len(lines) == 1 and lines[0].startswith("signorini: error:"), f"exit 2 needs one error line{info}"
        assert not new, f"exit 2 must create nothing{info}"
        return
    outside = {p for p in new if p != "out" and not p.startswith("out" + os.sep)}
    assert not outside, f"files outside the output directory: {sorted(outside)}{info}"
    assert "out" in new and o.summary is not None, f"exit {o.rc} without summary.json{info}"
    if o.rc == 3:
        assert o.summary.get("status") == "failed" and o.summary.get("success") is False, f"exit 3 status{info}"
        assert any(line.startswith("signorini: failed:") for line in o.stderr.splitlines()), f"exit 3 message{info}"
        return
    check_finished(case, o, info)


_NUMBER = re.compile(r"(?<![A-Za-z_])\d+\.?\d*(?:[eE][-+]?\d+)?")


def input_scale(case: Case) -> float:
    """max |number| / min |number| over the case's numbers (values and numbers inside
    expressions; at least 1 each way): the spread that round-off in the results scales with."""
    found = []
    for p in paths(case.doc or {}):
        v = get_at(case.doc, p)
        texts = [str(v)] if _is_number(v) else _NUMBER.findall(v) if isinstance(v, str) else []
        for text in texts:
            with contextlib.suppress(ValueError, OverflowError):
                found.append(abs(float(text)))
    found = [x for x in found if 0 < x < math.inf]
    return max(1.0, *found) / min(1.0, *found) if found else 1.0


def check_finished(case: Case, o: Outcome, info: str) -> None:
    s, H, C = o.summary, o.history, o.contact
    assert s["status"] == "finished" and s["success"] is True, f"exit 0 but status {s.get('status')}{info}"
    assert o.stdout == "", f"--quiet run printed on stdout{info}"
    assert H is not None and C is not None, f"exit 0 without history.csv or contact.npz{info}"
    for key, v in _numbers(s):
        if v is None:
            assert key in NULLABLE, f"summary.json: {key} is null{info}"
            if key in ("energy_max_relative_drift", "energy_max_relative_drift_undamped"):
                assert s["energy_initial"] == 0, f"summary.json: drift null with E0 != 0{info}"
            elif key == "energy_identity_residual":
                no_identity = not any(math.isfinite(float(r["predicted_increment"])) for r in H[1:])
                assert s["energy_initial"] == 0 or no_identity, f"summary.json: {key} null{info}"
            else:
                assert s["contact_nodes"] == 0, f"summary.json: {key} null with contact nodes{info}"
        else:
            assert math.isfinite(v), f"summary.json: {key} = {v}{info}"
    steps = case.meta.get("steps")
    if case.kind == "valid" and s["time_control"]["control"] == "energy":  # the default: dt is the largest step
        tc = s["time_control"]
        assert s["steps"] >= steps and len(H) == s["steps"] + 1 == tc["steps_accepted"] + 1, f"steps {tc}{info}"
        if isinstance(case.meta["dt"], (int, float)):
            k = [math.log2(case.meta["dt"] / float(row["dt"])) for row in H[1:]]
            deepest = round(math.log2(case.meta["dt"] / tc["dt_min"]))  # 10, deeper for a fine mesh's tolerance
            assert 10 <= deepest <= 20, f"dt_min {tc['dt_min']}{info}"
            assert all(abs(x - round(x)) <= 1e-6 and 0 <= round(x) <= deepest for x in k), f"steps not dt / 2^k{info}"
        assert math.isclose(float(H[-1]["t"]), case.meta["T"], rel_tol=1e-9, abs_tol=0.0), f"last t != T{info}"
    elif case.kind == "valid":
        assert s["steps"] == steps and len(H) == steps + 1, f"steps {s['steps']} != {steps}{info}"
        # 1e-9 relative: how far from a multiple of dt a valid T may be (number_of_steps); measured 0
        assert math.isclose(float(H[-1]["t"]), case.meta["T"], rel_tol=1e-9, abs_tol=0.0), f"last t != T{info}"
    for n, row in enumerate(H):
        for col, text in row.items():
            v = float(text)
            if math.isnan(v) and (col in NAN_COLUMNS or (col in LEVEL0_NAN_COLUMNS and n == 0)):
                continue
            assert math.isfinite(v), f"history.csv: {col} = {text} at level {n}{info}"
    res = np.array([float(r["complementarity_residual"]) for r in H])
    assert np.all(res <= RESIDUAL_TOL), f"complementarity residual {res.max():.3g}{info}"
    assert s["max_complementarity_residual"] <= RESIDUAL_TOL, f"max complementarity residual{info}"
    for k in ("t", "gap", "lam", "coordinates", "weights"):
        assert np.all(np.isfinite(C[k])), f"contact.npz: {k} not finite{info}"
    gap, lam = C["gap"], C["lam"]
    if gap.size == 0:
        return
    rel = 1e-9 * input_scale(case)  # round-off grows with the spread of the input numbers
    tol = rel * max(1.0, float(np.abs(gap).max()))
    ltol = rel * max(1.0, float(np.abs(lam).max()))
    gap_min = np.array([float(r["gap_min"]) for r in H])
    assert np.allclose(gap_min, gap.min(axis=1), rtol=1e-14, atol=0), f"gap_min column != min(gap){info}"  # measured 0
    assert np.all(lam <= ltol), f"positive contact force lambda = {lam.max():.3g}{info}"
    e = case.meta.get("restitution", 0.0)
    doc = case.doc if case.doc is not None else tomllib.loads(case.text)  # raw-text cases keep only their text
    scheme = SCHEMES.get(doc.get("time", {}).get("scheme", "crank-nicolson")).obj
    if not scheme.exact_contact:  # velocity-level impulses: penetration O(dt), reported honestly
        pen = np.array([float(r["penetration"]) for r in H])
        assert np.allclose(pen, np.maximum(0.0, -gap_min), rtol=1e-14, atol=0), (
            f"penetration column{info}"
        )  # measured 0
        assert s["penetration_max"] == pytest.approx(pen.max(), rel=1e-14, abs=0), (
            f"penetration_max{info}"
        )  # measured 0
        return
    if e == 0.0:
        assert np.all(gap_min >= -tol), f"penetration: gap_min = {gap_min.min():.3g} < 0{info}"
        assert np.all(np.abs(gap * lam) <= tol * max(1.0, float(np.abs(lam).max()))), f"lambda * gap != 0{info}"
    else:  # Paoli-Schatzman: the constraint is on (U^{n+1} + e U^{n-1})/(1 + e)
        assert gap[0].min() >= -tol and gap[min(1, len(gap) - 1)].min() >= -tol, f"penetration at level 0/1{info}"
        # a moving obstacle (the case's own, or an expression a mutation put there): the gaps
        # of levels n+1 and n-1 are to different obstacle positions, so their combination is
        # not the constraint
        obstacle = doc.get("contact", {}).get("obstacle", {})
        obstacle = obstacle if isinstance(obstacle, dict) else {}
        moving = case.meta.get("moving") or any(
            isinstance(v, str) or (isinstance(v, list) and any(isinstance(x, str) for x in v))
            for k, v in obstacle.items()
            if k != "type"
        )
        if not moving:
            combo = gap[2:] + e * gap[:-2]
            assert np.all(combo >= -tol), f"PS penetration: gap_n+1 + e gap_n-1 = {combo.min():.3g}{info}"


def record(kind: str, rc) -> None:
    OUTCOMES.setdefault(kind, Counter())[rc] += 1


@pytest.fixture(scope="module", autouse=True)
def _report_outcomes():
    yield
    total: Counter = Counter()
    for kind in sorted(OUTCOMES):
        total.update(OUTCOMES[kind])
    for kind, seen in [*sorted(OUTCOMES.items()), ("all", total)]:
        codes = dict(sorted(seen.items(), key=str))
        print(f"fuzz {kind:22s} {sum(seen.values()):5d} cases, exit codes {codes}")


#: ``SIGNORINI_FUZZ_RANDOM=1``: the long runs draw new cases each time (see the module docstring)
RANDOM_SEARCH = os.environ.get("SIGNORINI_FUZZ_RANDOM") == "1"


def fuzz_settings(examples: int, derandomize: bool = True, shrink: bool = True):
    """Deterministic by default; ``shrink=False`` for mutated cases, which are one edit away
    from a small valid case already (shrinking them would cost more than the whole run)."""
    phases = [Phase.explicit, Phase.reuse, Phase.generate, Phase.target] + ([Phase.shrink] if shrink else [])
    return settings(
        max_examples=examples,
        deadline=None,
        derandomize=derandomize,
        database=None,
        phases=phases,
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.filter_too_much],
    )


# ----------------------------------------------------------------------------- tests
def test_toml_writer_round_trips():
    doc = {"a": {"x": -0.0, "y": [1, 's"\\\n', 1e308], "z": {"k": True}}, "b": [{"tag": "t"}, {"tag": "u"}]}
    assert tomllib.loads(toml_document(doc)) == doc


def _run_valid(tmp_path: Path, examples: int, derandomize: bool) -> None:
    seen = Counter()

    @fuzz_settings(examples, derandomize)
    @given(valid_cases())
    def prop(case: Case):
        assert tomllib.loads(case.text) == case.doc  # the writer itself
        o = run_case(case, tmp_path)
        seen[o.rc] += 1
        record("valid", o.rc)
        check_outcome(case, o)

    prop()
    total = sum(seen.values())
    assert seen[0] == total, f"only {seen[0]} of {total} valid cases ran: {dict(seen)}"  # strict oracle


def _run_mutation(tmp_path: Path, kind: str, examples: int, derandomize: bool) -> None:
    @fuzz_settings(examples, derandomize, shrink=False)
    @given(mutated_cases(kind))
    def prop(case: Case):
        o = run_case(case, tmp_path)
        record(kind, o.rc)
        check_outcome(case, o)

    prop()


def test_valid_cases(tmp_path):
    _run_valid(tmp_path, VALID_EXAMPLES, True)


@pytest.mark.parametrize("kind", sorted(MUTATIONS))
def test_mutated_cases(tmp_path, kind):
    _run_mutation(tmp_path, kind, MUTATION_EXAMPLES, True)


@pytest.mark.slow
def test_valid_cases_long(tmp_path):
    _run_valid(tmp_path, SLOW_VALID_EXAMPLES, not RANDOM_SEARCH)


@pytest.mark.slow
@pytest.mark.parametrize("kind", sorted(MUTATIONS))
def test_mutated_cases_long(tmp_path, kind):
    _run_mutation(tmp_path, kind, SLOW_MUTATION_EXAMPLES, not RANDOM_SEARCH)


# ----------------------------------------------------------------------------- fixed lists
BASE_2D = {
    "mesh": {"generator": "rectangle", "cells": [1, 2], "size": [0.2, 1.0], "cell": "quad"},
    "material": {"rho": 1.0, "lam": 0.25, "mu": 0.5},
    "dirichlet": [{"tag": "ymax", "value": [0.0, 0.1]}],
    "contact": {"tag": "ymin", "obstacle": {"type": "plane", "point": [0.0, -0.05], "normal": [0.0, 1.0]}},
    "initial": {"displacement": [0.0, 0.0], "velocity": [0.0, -0.5]},
    "loads": {"body_force": [0.0, -1.0]},
    "time": {"scheme": "cn", "dt": 0.05, "T": 0.5},
}
BASE_META = {"dim": 2, "steps": 10, "T": 0.5, "dt": 0.05, "scheme": "crank-nicolson", "restitution": 0.0}
SLOTS = {
    "initial.displacement": ("initial", "displacement", 1),
    "initial.velocity": ("initial", "velocity", 0),
    "dirichlet.value": ("dirichlet", 0, "value", 1),
    "loads.body_force": ("loads", "body_force", 1),
    "obstacle.point": ("contact", "obstacle", "point", 1),
}


@pytest.mark.parametrize("slot", sorted(SLOTS))
@pytest.mark.parametrize(("expr", "expected"), HOSTILE_EXPRESSIONS, ids=[repr(e[:24]) for e, _ in HOSTILE_EXPRESSIONS])
def test_hostile_expression(tmp_path, expr, expected, slot):
    doc = copy.deepcopy(BASE_2D)
    set_at(doc, SLOTS[slot], expr)
    case = case_from_doc(doc, expected, "hostile", f"{slot} = {expr[:60]!r}", BASE_META)
    o = run_case(case, tmp_path)
    record("hostile (fixed list)", o.rc)
    check_outcome(case, o)


def _edit(**changes):
    """A copy of BASE_2D with 'section.key' (or 'section.key[i]') set; None deletes."""

    def make() -> dict:
        doc = copy.deepcopy(BASE_2D)
        for dotted, value in changes.items():
            parts = [int(p) if p.isdigit() else p for p in dotted.split("__")]
            if value is None:
                delete_at(doc, tuple(parts))
            else:
                cur = doc
                for k in parts[:-1]:
                    cur = cur.setdefault(k, {}) if isinstance(cur, dict) else cur[k]
                cur[parts[-1]] = value
        return doc

    return make


# A body without mass: the seed mass of a mesh one cell thick is zero (every cell touches
# the contact side), and nothing is clamped.
MASSLESS_2D = {
    "mesh": {"generator": "rectangle", "cells": [2, 1], "size": [0.12, 1.01]},
    "material": {"rho": 1.76, "lam": 0.42, "mu": 0.32},
    "contact": {"tag": "ymin", "obstacle": {"point": [0.0, 0.0], "normal": [0.0, 1.0]}},
    "loads": {"body_force": [0.0, -9.81]},
    "time": {"dt": 0.01, "T": 0.03},
}
MASSLESS_1D = {
    "mesh": {"generator": "interval", "cells": [1], "size": [0.5]},
    "material": {"rho": 1.0, "E": 1.0},
    "contact": {"tag": "xmin", "obstacle": {"point": [0.0], "normal": [1.0]}},
    "time": {"dt": 0.1, "T": 0.2},
}

# The same seed mass (zero) with the top clamped in y only: sliding along x is free.
MASSLESS_SLIDING = {
    "mesh": {"generator": "rectangle", "cells": [1, 1], "size": [0.1, 0.5]},
    "material": {"rho": 0.5, "E": 1.0},
    "dirichlet": [{"tag": "ymax", "components": [1]}],
    "contact": {"tag": "ymin", "obstacle": {"type": "sphere", "center": [0.05, -0.5], "radius": 0.5}},
    "loads": {"body_force": [0.0, -9.81]},
    "time": {"scheme": "backward-euler", "dt": 0.01, "T": 0.01},
}

# id -> (document maker, allowed exit codes)
EDGE_CASES = {
    "massless-sliding": (lambda: copy.deepcopy(MASSLESS_SLIDING), ANY),
    "massless-free-body-2d": (lambda: copy.deepcopy(MASSLESS_2D), ANY),
    "massless-free-body-1d": (lambda: copy.deepcopy(MASSLESS_1D), ANY),
    "T=1e308": (_edit(time__T=1e308), INVALID),
    "T=dt*1e15": (_edit(time__T=0.05 * 10**15), INVALID),
    "dt=T=1e308": (_edit(time__dt=1e308, time__T=1e308), ANY),
    "dt=1e-300,T=20dt": (_edit(time__dt=1e-300, time__T=2e-299), ANY),
    "dt=5e-324,T=2dt": (_edit(time__dt=5e-324, time__T=1e-323), ANY),
    "dt=1e-300,T=0.5": (_edit(time__dt=1e-300), INVALID),
    "dt=-0.0": (_edit(time__dt=-0.0), INVALID),
    "T=-0.0": (_edit(time__T=-0.0), INVALID),
    "T=nan": (_edit(time__T=math.nan), INVALID),
    "dt=inf": (_edit(time__dt=math.inf), INVALID),
    "T-not-multiple": (_edit(time__T=0.51), INVALID),
    "T<dt": (_edit(time__T=0.01), INVALID),
    "rho=1e308": (_edit(material__rho=1e308), ANY),
    "rho=5e-324": (_edit(material__rho=5e-324), ANY),
    "rho=-0.0": (_edit(material__rho=-0.0), INVALID),
    "mu=1e308": (_edit(material__mu=1e308), ANY),
    "lam=1e308": (_edit(material__lam=1e308), ANY),
    "size=[1e308,1e308]": (_edit(mesh__size=[1e308, 1e308]), ANY),
    "size=[5e-324,1]": (_edit(mesh__size=[5e-324, 1.0]), ANY),
    "size=[1e-300,1]": (_edit(mesh__size=[1e-300, 1.0]), ANY),
    "cells=[2**63-1,1]": (_edit(mesh__cells=[2**63 - 1, 1]), INVALID),
    "cells=[1,2**63-1]": (_edit(mesh__cells=[1, 2**63 - 1]), INVALID),
    "cells=[10**12,1]": (_edit(mesh__cells=[10**12, 1]), INVALID),
    "cells=[2**64,1]": (_edit(mesh__cells=[2**64, 1]), INVALID),
    "cells=[true,2]": (_edit(mesh__cells=[True, 2]), INVALID),
    "cells=[1.0,2]": (_edit(mesh__cells=[1.0, 2]), INVALID),
    "generator=table": (_edit(mesh__generator={"a": 1}), INVALID),
    "cell=list": (_edit(mesh__cell=["quad"]), INVALID),
    "obstacle.type=list": (_edit(contact__obstacle__type=["plane"]), INVALID),
    "scheme=list": (_edit(time__scheme=["cn"]), INVALID),
    "mass=table": (_edit(solver__mass={"a": 1}), INVALID),
    "backend=list": (_edit(solver__backend=["cg"]), INVALID),
    "displacement=1e308": (_edit(initial__displacement=[0.0, 1e308]), ANY),
    "velocity=1e308": (_edit(initial__velocity=[0.0, -1e308]), ANY),
    "dirichlet=1e308": (_edit(dirichlet__0__value=[0.0, 1e308]), ANY),
    "body_force=1e308": (_edit(loads__body_force=[0.0, -1e308]), ANY),
    "normal=[0,-1]": (_edit(contact__obstacle__normal=[0.0, -1.0]), INVALID),
    "normal-flipped-touching": (
        _edit(contact__obstacle__point=[0.0, 0.0], contact__obstacle__normal=[0.0, -1.0], initial__velocity=[0.0, 0.0]),
        INVALID,
    ),
    "normal=[0,0]": (_edit(contact__obstacle__normal=[0.0, 0.0]), INVALID),
    "normal=[0,1e308]": (_edit(contact__obstacle__normal=[1e308, 1e308]), ANY),
    "normal=[0,5e-324]": (_edit(contact__obstacle__normal=[0.0, 5e-324]), ANY),
    "point=1e308": (_edit(contact__obstacle__point=[0.0, -1e308]), ANY),
    "inside-sphere": (_edit(contact__obstacle={"type": "sphere", "center": [0.1, 0.5], "radius": 2.0}), INVALID),
    "sphere-radius-1e308": (_edit(contact__obstacle={"type": "sphere", "center": [0.1, -1e308], "radius": 1e308}), ANY),
    "sphere-radius-0": (_edit(contact__obstacle={"type": "sphere", "center": [0.1, -1.0], "radius": 0.0}), INVALID),
    "sphere-center-at-node": (
        _edit(contact__obstacle={"type": "sphere", "center": [0.0, 0.0], "radius": 1e-9}),
        INVALID,
    ),
    "missing-time": (_edit(time=None), INVALID),
    "missing-dt": (_edit(time__dt=None), INVALID),
    "unknown-section": (_edit(extra={"a": 1}), INVALID),
    "unknown-key": (_edit(time__dT=0.1), INVALID),
    "tag-missing": (_edit(contact__tag="bottom"), INVALID),
    "tag-nul": (_edit(contact__tag="ymin\x00"), INVALID),
    "snapshot_every=2**63-1": (_edit(output__snapshot_every=2**63 - 1), ANY),
    "max_steps=1": (_edit(limits__max_steps=1), INVALID),
    "max_memory=5e-324": (_edit(limits__max_memory=5e-324), INVALID),
    "lcp_max_iter=2**63-1": (_edit(solver__lcp_max_iter=2**63 - 1), ANY),
    "components=[true]": (_edit(dirichlet__0__components=[True], dirichlet__0__value=[0.0]), INVALID),
    "mesh-file=/dev/null": (_edit(mesh={"generator": "file", "file": "/dev/null"}), INVALID),
    "mesh-file=case.toml": (_edit(mesh={"generator": "file", "file": "case.toml"}), INVALID),
    "mesh-file=dir": (_edit(mesh={"generator": "file", "file": "."}), INVALID),
    "mesh-file=nul": (_edit(mesh={"generator": "file", "file": "a\x00b"}), INVALID),
}


@pytest.mark.parametrize("name", list(EDGE_CASES))
def test_edge_case(tmp_path, name):
    make, expected = EDGE_CASES[name]
    case = case_from_doc(make(), expected, "edge", name, BASE_META)
    o = run_case(case, tmp_path)
    record("edge (fixed list)", o.rc)
    check_outcome(case, o)


def test_harness_catches_hangs_and_leftovers(tmp_path, monkeypatch):
    """The oracle itself: a hang (through the CLI's `except Exception`) and a hidden
    temporary directory left behind by an exit-2 run are both failures."""
    import sys

    module = sys.modules[__name__]
    case = case_from_doc(copy.deepcopy(BASE_2D), ANY, "harness", "", BASE_META)

    slept = []

    def hanging_main(argv):
        try:
            time.sleep(30)
            slept.append(30)  # reached only if the time limit did not interrupt the sleep
        except Exception:
            return 1
        return 0

    monkeypatch.setattr(module, "CASE_SECONDS", 0.2)
    monkeypatch.setattr(module, "main", hanging_main)
    o = run_case(case, tmp_path)
    # a count, not a time (issue 31, item 5): no sleep ran to its end, and no exit code
    assert o.rc is None and slept == []
    with pytest.raises(AssertionError, match="hang"):
        check_outcome(case, o)

    def leaky_main(argv):
        out = Path(argv[argv.index("--out") + 1])
        (out.parent / f".{out.name}.x1y2").mkdir()
        print("signorini: error: invalid", file=__import__("sys").stderr)
        return 2

    monkeypatch.setattr(module, "main", leaky_main)
    o = run_case(case, tmp_path)
    assert o.rc == 2
    with pytest.raises(AssertionError, match="must create nothing"):
        check_outcome(case, o)


def test_base_cases_run(tmp_path):
    """The bases of the fixed lists are valid (so their failures come from the edit)."""
    case = case_from_doc(copy.deepcopy(BASE_2D), {0}, "base", "", BASE_META)
    check_outcome(case, run_case(case, tmp_path))

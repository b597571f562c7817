"""The case-file schema as data: sections, keys, types, defaults, units and examples.

:mod:`signorini.io.config` validates against it (its allowed keys come from here),
``docs/case-files.md`` is generated from it together with the registries
(:func:`reference_markdown`), and ``signorini template`` prints a commented starting
case from its examples (:func:`template`), which the tests load and run.

Units: the solver has none of its own; use any consistent system (SI: m, kg, s, Pa,
N).  The built-in benchmarks are nondimensional.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ..contact.friction import CONTACT_LAWS
from ..contact.obstacles import OBSTACLES, ROTATION_KEYS
from ..dynamics.model.mass import DEFAULT_MASS, MASS_VARIANTS
from ..dynamics.schemes import SCHEMES
from ..linalg import BACKENDS, SOLVER_OPTIONS
from .expressions import CONSTANTS, FUNCTIONS, MAX_DEPTH, MAX_EXPONENT, MAX_LENGTH, MAX_NODES, VARIABLES


@dataclass(frozen=True)
class Key:
    """One key of a section: TOML type, default ('required', or '' for none), units, meaning,
    and an example value per dimension (TOML text)."""

    name: str
    type: str
    default: str
    units: str
    doc: str
    example: dict[int, str] = field(default_factory=dict)


@dataclass(frozen=True)
class Section:
    name: str
    doc: str
    keys: tuple[Key, ...]
    required: bool = False
    array: bool = False  # [[name]]: any number of tables
    open_keys: str = ""  # other keys allowed, from a registry (documented below the table)


def _ex(v1: str, v2: str, v3: str) -> dict[int, str]:
    return {1: v1, 2: v2, 3: v3}


def _same(v: str) -> dict[int, str]:
    return {1: v, 2: v, 3: v}


EXPR = "number or expression string"
# fmt: off
SECTIONS: tuple[Section, ...] = (
    Section(
        "mesh",
        "The body: a generated structured mesh, or a mesh file (any format meshio reads; Gmsh physical groups "
        "of facets become tags).  Generated meshes have the side tags `xmin xmax ymin ymax zmin zmax`.",
        (
            Key("generator", "string", "`file` if `file` is given, else required", "",
                "interval | rectangle | box | file", _ex('"interval"', '"rectangle"', '"box"')),
            Key("cells", "array of 1-3 integers", "", "", "elements per direction (generators)",
                _ex("[20]", "[4, 40]", "[2, 2, 20]")),
            Key("size", "array of 1-3 numbers > 0", "", "length", "lengths per direction (generators)",
                _ex("[1.0]", "[0.1, 1.0]", "[0.1, 0.1, 1.0]")),
            Key("cell", "string", "line / quad / hexahedron", "",
                "line (1D); quad | triangle (2D); hexahedron | tetra (3D)", _ex('"line"', '"quad"', '"hexahedron"')),
            Key("file", "string", "", "", "mesh file, relative to the case file (generator = file)"),
            Key("order", "1 or 2", "1 (a file: its own)", "",
                "the cells' order: 1 linear, 2 quadratic (line3, triangle6 | quad9, tetra10 | hexahedron27; a "
                "file of linear cells is elevated with straight sides, a file of quadratic cells is read as it is)",
                _ex("", "", "")),
        ),
        required=True,
    ),
    Section(
        "material",
        "Isotropic elasticity (plane strain in 2D; Young's modulus in 1D), linear or of finite strain (`model`): "
        "`lam` and `mu`, or `E` and optionally `nu`; `rho` always.  Magnitudes must lie within 1e-100 .. 1e100 "
        "(their products must stay normal doubles: change units otherwise).",
        (
            Key("rho", "number > 0", "required", "mass / length^d", "density", _same("1.0")),
            Key("lam", "number", "", "stress", "first Lamé constant (3 lam + 2 mu > 0)", _ex("", "0.25", "0.25")),
            Key("mu", "number > 0", "", "stress", "shear modulus", _ex("", "0.5", "0.5")),
            Key("E", "number > 0", "", "stress", "Young's modulus (instead of lam, mu)", _ex("1.0", "", "")),
            Key("nu", "number in (-1, 0.5)", "0", "", "Poisson ratio (with E)"),
            Key("model", "string", "linear", "",
                "linear (small strains), saint-venant-kirchhoff or neo-hookean (finite strain, Total Lagrangian, "
                "the same lam, mu: each step solved by Newton, solver options newton_tol, newton_max, tangent; "
                "docs/finite_strain.md).  A regions entry without its own model takes this one",
                _ex("", '"neo-hookean"', "")),
            Key("damping", "inline table", "none", "alpha: 1/time, beta: time",
                "Rayleigh damping C = alpha M + beta S, { alpha = ..., beta = ... } (each >= 0, 0 by default; M the "
                "mass in use): a mode of angular frequency w decays with the ratio alpha/(2w) + beta w/2; its work "
                "is the damping_dissipation column.  A regions entry may give its cells their own (a regions entry "
                "without one takes this one): then C = D_a^(1/2) M D_a^(1/2) + sum of each cell's beta S_cell, "
                "alpha per node the mass-weighted mean of its cells' (bodies: each its own alpha M + beta S; serial "
                "direct backends only; docs/schemes.md)",
                _same("{ alpha = 0.0, beta = 0.0 }")),
            Key("regions", "array of inline tables", "none", "",
                "materials per region of cells: [{ tag = \"plate\", E = ..., nu = ..., rho = ... }, ...] (or lam, "
                "mu; rho required; model and damping optional); the section's own keys are the default for cells in "
                "no listed region.  Regions "
                "are a mesh file's named physical groups of cells (volumes in 3D, surfaces in 2D)"),
        ),
        required=True,
    ),
    Section(
        "dirichlet",
        "Prescribed displacements on a tag (any number of blocks).  A value may depend on x, y, z and t "
        "(a moving clamp).",
        (
            Key("tag", "string", "required", "", "boundary tag", _ex('"xmax"', '"ymax"', '"zmax"')),
            Key("value", f"array of {EXPR}s", "zeros", "length", "one value per listed component",
                _ex("[0.2]", "[0.0, 0.2]", "[0.0, 0.0, 0.2]")),
            Key("components", "array of integers", "all", "", "components 0..d-1 the values apply to"),
        ),
        array=True,
    ),
    Section(
        "traction",
        "Surface force density on a tag (any number of blocks).",
        (
            Key("tag", "string", "required", "", "boundary tag"),
            Key("value", f"array of {EXPR}s", "required", "force / length^(d-1)",
                "traction vector, may depend on x, t"),
        ),
        array=True,
    ),
    Section(
        "contact",
        "The contact boundary and the rigid obstacle.  `obstacle` is an inline table with a `type` from the "
        "obstacle registry and that type's parameters (below).  A plane's `normal` points out of the "
        "obstacle, towards the body; the body stays outside a sphere; a `surface` (a mesh file: triangles in "
        "3D, segments in 2D) has its facets' normals pointing towards the body.  Positions (`point`, `center`, "
        "`translation`) may be expressions of t (a moving obstacle), and `rotation = { angle = \"0.1 * t\", "
        "axis = [0.0, 0.0, 1.0], center = [...] }` turns it (in 2D the axis is out of the plane: no `axis`).",
        (
            Key("tag", "string or list of strings", "required (unless pairs)", "",
                "boundary tag(s) of Gamma_C (a list: their union)", _ex('"xmin"', '"ymin"', '"zmin"')),
            Key("where", "string", "all tagged nodes", "",
                "condition on x, y, z that restricts the contact nodes, e.g. \"z < 0.2\" (< <= > >=, and, or, not)"),
            Key("obstacle", "inline table", "required (unless pairs)", "length",
                "{ type = ..., parameters of the type }",
                _ex('{ type = "plane", point = [0.0], normal = [1.0] }',
                    '{ type = "plane", point = [0.0, 0.0], normal = [0.0, 1.0] }',
                    '{ type = "plane", point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, 1.0] }')),
            Key("pairs", "array of inline tables", "none", "",
                "contact between deformable surfaces: [{ slave = \"tag\", master = \"tag\" }, ...] (facet tags; "
                "docs/bodies.md), each with an optional friction = { law = ... } as below (default: the section's "
                "friction); with pairs, tag and obstacle are optional (both or neither)"),
            Key("friction", "inline table", "frictionless", "",
                "{ law = \"coulomb\", coefficient = mu } or { law = \"tresca\", threshold = s } "
                "(s: force / length^(d-1)); 2D and 3D only (docs/friction.md)"),
        ),
        required=True,
    ),
    Section(
        "initial",
        "The state at t = 0 (expressions of x, y, z; not of t).  Dirichlet values override it on fixed dofs.",
        (
            Key("displacement", f"array of {EXPR}s", "zeros", "length", "u0",
                _ex("[0.2]", "[0.0, 0.2]", "[0.0, 0.0, 0.2]")),
            Key("velocity", f"array of {EXPR}s", "zeros", "length / time", "v0",
                _ex('["-0.5"]', "[0.0, -0.5]", "[0.0, 0.0, -0.5]")),
            Key("acceleration", '"equilibrium" or "zero"', "equilibrium", "",
                "A0: from M A0 = F(0) - S U0, or zero (GetFEM's Newmark start); summary.json conventions"),
            Key("equilibrium", "true or false", "false", "",
                "true: the bodies held by supports or resting in contact (gap 0 at t = 0) start in static "
                "equilibrium under the loads at t = 0 (a static contact solve with the material's model, frictionless; "
                "free bodies keep their displacement; docs/initial_equilibrium.md); summary.json "
                "initial_equilibrium says what was solved"),
            Key("regions", "array of inline tables", "none", "",
                "per region of cells: [{ tag = \"ball\", velocity = [...], displacement = [...] }, ...] (either "
                "optional; expressions of x, y, z) on the nodes of the region's cells, over the section's values; "
                "a node shared by two listed regions takes the later one's"),
        ),
    ),
    Section(
        "loads",
        "Volume loads.",
        (Key("body_force", f"array of {EXPR}s", "none", "force / length^d", "may depend on x, y, z, t"),
         Key("gravity", f"array of {EXPR}s", "none", "length / time^2",
             "an acceleration g (may depend on t only): the load M_used g, or int rho g phi with follow_mass = "
             "false, each region with its own density"),
         Key("follow_mass", "true or false", "true", "",
             "true: a uniform body force is applied as M_used f / rho (the body falls at g with every mass); "
             "false: the consistent load int f phi whatever the mass (GetFEM's convention)")),
    ),
    Section(
        "time",
        "Time integration.  T must be an integer multiple of dt (to 1e-9 relative); dt within 1e-150 .. 1e150 "
        "(dt^2 must be a normal double).  The scheme's own parameters are keys of this section too.",
        (
            Key("scheme", "string", "crank-nicolson", "", "a name of the scheme registry", _same('"crank-nicolson"')),
            Key("dt", "number > 0, or a schedule [{until, dt}, ...]", "required", "time",
                "time step; a schedule changes it: from the previous until (0 first) to its own, its dt "
                "(e.g. [{until = 0.2, dt = 1e-3}, {until = 1.0, dt = 1e-2}]; T then defaults to the last until)",
                _ex("0.0125", "0.0125", "0.0125")),
            Key("T", "number >= dt", "required (a dt schedule: its last until)", "time", "final time",
                _ex("3.0", "1.0", "0.5")),
            Key("stop_at", "string or list of strings", "none", "",
                "end the run (status finished) at the first level where an event occurs: first-contact, "
                "separation, rest[:FRACTION] (summary.json events)"),
            Key("control", "string", "energy", "",
                "time-step control: energy (dt is the largest step; a step that creates or destroys energy no "
                "physical work explains is rejected and halved, down to dt_min; docs/schemes.md) or fixed (the "
                "steps asked for); a scheme that cannot change its step (paoli-schatzman) runs fixed, and says so"),
            Key("dt_min", "number > 0", "dt / 1024", "time", "smallest step of control = energy"),
            Key("tolerance", "number in [0, 1]", "from the mesh", "",
                "control = energy: the energy a contact episode may create or destroy, relative to the run's "
                "energy scale (summary.json spurious_energy.scale); 0 or absent: min(1e-3, 0.025 (h/L)^2) with h/L "
                "the mesh's resolution (a body's median cell size over its extent; summary.json "
                "time_control.mesh_resolution), so that a finer mesh gets a finer answer (docs/schemes.md)"),
        ),
        required=True,
        open_keys="the parameters of the chosen scheme",
    ),
    Section(
        "solver",
        "Mass variant and linear algebra.  The solver options are keys of this section too.",
        (Key("mass", "string", DEFAULT_MASS, "", "a name of the mass registry", _same(f'"{DEFAULT_MASS}"')),),
        open_keys="the solver options and the backend's parameters",
    ),
    Section(
        "output",
        "Where results go (the command line's --out and --snapshot-every override these).",
        (
            Key("directory", "string", "out/<case name>", "", "result directory"),
            Key("snapshot_every", "integer >= 0", "0", "steps", "XDMF fields every k steps and at the end (0: none)"),
            Key("checkpoint_every", "integer >= 0", "0", "steps",
                "checkpoint.h5 every k steps (0: only at the end; every run writes one at its end), for "
                "`signorini resume`"),
        ),
    ),
    Section(
        "limits",
        "Guards against runs that would not end or not fit: a larger run is refused with its estimate "
        "unless `yes = true` (command line: --max-steps, --max-memory, --yes).",
        (
            Key("max_steps", "integer >= 1", "1000000", "steps", "largest number of steps run without yes"),
            Key("max_memory", "number > 0", "80% of the machine", "GiB", "largest estimated memory without yes"),
            Key("yes", "boolean", "false", "", "run even if over a limit"),
        ),
    ),
)
# fmt: on
REQUIRED = tuple(s.name for s in SECTIONS if s.required)


def section_keys() -> dict[str, set[str]]:
    """Fixed keys of every section (the registry-defined ones are added by the validator)."""
    return {s.name: {k.name for k in s.keys} for s in SECTIONS}


def _registry_lines() -> list[str]:
    md = ["## Names from the registries", ""]
    md.append(f"* `[time] scheme`: {', '.join(f'`{n}`' for n in SCHEMES.names())}.  Scheme parameters:")
    for e in SCHEMES:
        if e.parameters:
            params = ", ".join(f"`{p.name}` (default {p.default}; {p.bounds_text()})" for p in e.parameters)
            md.append(f"  * `{e.name}`: {params}")
    md.append(f"* `[solver] mass`: {', '.join(f'`{n}`' for n in MASS_VARIANTS.names())}.")
    opts = [p.name for p in SOLVER_OPTIONS] + sorted({p.name for e in BACKENDS for p in e.parameters})
    md.append(f"* `[solver]` options: {', '.join(f'`{n}`' for n in opts)} (meanings in `docs/registries.md`).")
    md.append("* `[contact] friction` laws:")
    for e in CONTACT_LAWS:
        params = ", ".join(f"`{p.name}` ({p.doc}; {p.bounds_text()})" for p in e.parameters)
        md.append(f"  * `{e.name}`: {e.description}{'; ' + params if params else ''}")
    md.append("* `[contact] obstacle` types:")
    for e in OBSTACLES:
        params = ", ".join(f"`{p.name}` ({p.doc})" for p in e.parameters)
        md.append(f"  * `{e.name}`: {e.description}; {params}")
    keys = ", ".join(f"`{p.name}` ({p.doc})" for p in ROTATION_KEYS)
    md.append(
        f"* `[contact] obstacle` `rotation` keys: {keys}.  The obstacle at t is the given one turned by angle(t) "
        "about the axis through `center`, then translated (the axis moves with the obstacle; docs/bodies.md)."
    )
    md.append("")
    return md


def _expression_lines() -> list[str]:
    return [
        "## Expressions",
        "",
        f"A string where a number is expected is an expression of {', '.join(f'`{v}`' for v in VARIABLES)} "
        "(missing coordinates are 0), evaluated with numpy over all nodes at once.  Allowed: numbers, "
        f"`+ - * / ** %`, unary `+ -`, the constants {', '.join(f'`{c}`' for c in CONSTANTS)} and the "
        f"functions {', '.join(f'`{f}()`' for f in FUNCTIONS)} with positional arguments.  Anything else "
        "(names, attributes, subscripts, lambdas, keywords, strings) is an error naming the key: a case file "
        f"cannot run code.  Bounds: at most {MAX_LENGTH} characters, {MAX_NODES} terms, {MAX_DEPTH} levels "
        f"of nesting; the exponent of `**` must be a number of size <= {MAX_EXPONENT:g} (use `exp`/`log` "
        "otherwise).  The value must be finite at every node (else the error names the key, the expression "
        "and one point).  Initial data may not depend on `t`; obstacle positions may depend on `t` only.",
        "",
        "`[contact] where` is a *condition* of `x`, `y`, `z`: the same language plus the comparisons "
        "`< <= > >=` (chained, as in `0.1 < z < 0.2`) and `and`, `or`, `not`; a contact node is kept where it "
        "is true.  `==` and `!=` are not offered (floating-point equality); the compared values must be finite.",
        "",
    ]


def _cli_lines() -> list[str]:
    return [
        "## Command-line options and case files",
        "",
        "`signorini run CASE.toml` reads everything from the file.  These options override the file: "
        "`--scheme`, `--scheme-option`, `--mass`, `--backend`, `--solver-option`, `--snapshot-every`, `--out`, "
        "`--overwrite`, `--quiet`, `--max-steps`, `--max-memory`, `--yes`, and `--dt`, `--T`, `--dt-control` (the "
        "summary's `overrides` records `--dt` and `--T` against the file's values, its `time_control` the control "
        "that ran).  These apply to benchmarks only and are "
        "errors with a case file (set them in the file): `--n`, `--set`.",
        "",
        "`signorini template --dim D` prints a commented starting case (D = 1, 2, 3) that runs as it is.",
        "",
    ]


def reference_markdown() -> str:
    """The whole ``docs/case-files.md``."""
    md = [
        "# Case files",
        "",
        "Generated from `src/signorini/io/schema.py` and the registries by "
        "`python -m signorini.io.doctables --write`; do not edit by hand.",
        "",
        "A case file is TOML.  Every key is checked: an unknown section or key, a wrong type or an impossible "
        "value is an error (exit 2) naming the key and the allowed values, and nothing is written.  Units: "
        "any consistent system (e.g. SI: m, kg, s, Pa); the built-in benchmarks are nondimensional.  Start "
        "from `signorini template --dim 2 > case.toml` or from `examples/`.",
        "",
    ]
    for s in SECTIONS:
        head = f"[[{s.name}]]" if s.array else f"[{s.name}]"
        md += [f"## `{head}`{' (required)' if s.required else ''}", "", s.doc, ""]
        md += ["| key | type | default | units | meaning | example (2D) |", "|---|---|---|---|---|---|"]
        for k in s.keys:
            ex = k.example.get(2, "")
            md.append(
                f"| `{k.name}` | {k.type} | {k.default or '-'} | {k.units} | {k.doc} | {f'`{ex}`' if ex else ''} |"
            )
        if s.open_keys:
            md += ["", f"Also allowed: {s.open_keys} (next section)."]
        md.append("")
    md += _registry_lines() + _expression_lines() + _cli_lines()
    return "\n".join(md)


def template(dim: int = 2) -> str:
    """A commented case for a bar of dimension ``dim`` hitting a plane; it runs as printed."""
    lines = [
        f"# signorini case file ({dim}D): a bar released onto a rigid plane.  Reference: docs/case-files.md",
        "# Units: any consistent system; this example is nondimensional.",
    ]
    for s in SECTIONS:
        examples = [k for k in s.keys if k.example.get(dim)]
        if not examples:
            continue
        lines += ["", f"# {s.doc.split('.  ')[0].rstrip('.')}.", f"[[{s.name}]]" if s.array else f"[{s.name}]"]
        for k in examples:
            unit = f" [{k.units}]" if k.units else ""
            lines.append(f"{k.name} = {k.example[dim]}  # {k.doc}{unit}")
    lines += ["", "# Optional sections: [[traction]], [loads], [output], [limits] (see docs/case-files.md)", ""]
    return "\n".join(lines)

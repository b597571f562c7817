#!/usr/bin/python3
"""GetFEM reference runs of signorini's contact benchmarks (a live cross-check).

Run it with the system python that has Debian's ``python3-getfem`` (GetFEM 5.4)::

    apt-get install -y python3-getfem
    /usr/bin/python3 tests/getfem_reference.py \\
        '{"cases": [{"benchmark": "bar2d", "n": 2, "mass": "seed", "scheme": "cn", "dt": 0.025, "T": 1.0}]}'

It does not import ``signorini``: numpy and getfem only.  The spec is JSON, given as the
first argument (a JSON text or the path of a JSON file) or on stdin (no argument, or
``-``): ``{"cases": [...], "solver": {...}}``.  A case is

    benchmark   ``bar2d`` / ``bar3d`` with ``n``: the seed paper's bars, rebuilt as
                ``signorini.studies.benchmarks`` builds them; optional ``params``
                overriding width, length, rho, lam, mu, gap, velocity
    mesh        or the path of a Gmsh 2.2 file (``signorini.fem.mesh.write_mesh``) with
                ``contact`` (a physical name or a list of them), ``params`` rho, lam, mu,
                velocity: a free body (no Dirichlet condition), u0 = 0, v0 = -velocity e_d
                (the Hertz disc/ball of ``hertz2d``/``hertz3d``)
    mass        ``standard`` (consistent) or ``seed`` (the seed paper's M_mod, GetFEM's
                ``singular_mass=1``: the mass brick only on the elements that touch no
                contact node, so the contact nodes are massless in every component)
    scheme      ``cn`` (Newmark 1/4, 1/2) or ``be`` (theta-method, theta = 1)
    dt, T       time step and final time (round(T/dt) steps)

and ``solver`` may set ``max_res`` (Newton's residual target, default 1e-13), ``max_iter``
(50), ``r`` (the augmentation parameter, 1) and ``aug_version`` (1: non-symmetric
Alart-Curnier).

The discretization is signorini's: for the bars [0, w] x [0, L] (x [0, w]) with n x 10n
Q1 cells (GT_QK/FEM_QK, Gauss 2 points per direction, exact for the mass and stiffness of
rectangular cells), nodes numbered x fastest, then y (, then z), top face clamped at
u = gap e_d (Dirichlet with simplification), u0 = gap e_d, v0 = -velocity e_d on the
free dofs and 0 on the clamped ones; for a mesh file P1 simplices (FEM_PK, a rule exact
for degree 2); plane strain in 2D (GetFEM's isotropic linearized elasticity brick with
the Lame coefficients in 2D); A0 = 0 (S u0 = 0, no load).  Contact: the nodes of the
contact faces against the rigid obstacle x_d >= 0 (signed distance ``y`` / ``z``), i.e.
u_d >= -x_d, with GetFEM's nodal contact brick with a rigid obstacle (Alart-Curnier
augmented Lagrangian, solved by the semismooth Newton method of ``Model.solve`` at every
step).  Time integration: GetFEM's own schemes on ``Dot2_u`` (``add_Newmark_scheme``,
``add_theta_method_for_second_order``: the spec's sections 6.1 and 6.2), shifted by
``shift_variables_for_time_integration``.

Output, JSON lines on stdout: per case a header ``{"case": i, ..., "contact_points":
[[x, ...], ...], "contact_nodes": [...]}`` (the contact nodes in signorini's order:
increasing node index, the index being the position in the generator's / the file's node
list), then one line per time level n = 0..N::

    {"case": i, "step": n, "t": t_n, "lambda_sum": sum_i lambda_i, "lambda": [lambda_i],
     "normal_displacement": [u_d(a_i)], "energy": E_n, "kinetic": ..., "elastic": ...,
     "newton_iterations": k, "converged": true}

lambda_i are GetFEM's nodal contact forces (<= 0 in compression, signorini's sign),
u_d(a_i) the d-th displacement of contact node i (signorini's gap g_i - nu_i.u_i when the
node starts on the plane, g_i = 0), E = 1/2 V.M V + 1/2 U.S U with GetFEM's matrices (M of
the mass variant) and V = Dot_u of GetFEM's scheme.
"""

from __future__ import annotations

import functools
import json
import subprocess
import sys

import getfem as gf
import numpy as np

BAR_DEFAULTS = {"rho": 1.0, "lam": 0.25, "mu": 0.5, "gap": 0.2, "velocity": 0.5, "width": 0.1, "length": 1.0}
SOLVER = {"max_res": 1e-13, "max_iter": 50, "r": 1.0, "aug_version": 1}
CLAMP, CONTACT, MASS_REGION = 101, 102, 103


# ----------------------------------------------------------------------------- geometry
def bar_mesh(dim: int, n: int, width: float, length: float) -> tuple[gf.Mesh, np.ndarray]:
    """The bar of ``signorini.fem.mesh.rectangle``/``box``, with signorini's node numbering.

    The points are added first in signorini's order (x fastest), so GetFEM's point ids
    are signorini's node indices; the cells are then given by coordinates in GetFEM's QK
    vertex order (x fastest in the reference cell), which GetFEM merges with those points.
    """
    counts = [n] * (dim - 1) + [10 * n]
    sizes = [width] * (dim - 1) + [length]
    axes = [np.linspace(0.0, s, c + 1) for s, c in zip(sizes, counts, strict=True)]
    grids = np.meshgrid(*axes[::-1], indexing="ij")  # (z,) y, x
    pts = np.column_stack([g.ravel() for g in grids[::-1]])  # x fastest
    m = gf.Mesh("empty", dim)
    ids = np.asarray(m.add_point(pts.T)).ravel()
    if not np.array_equal(ids, np.arange(len(pts))):
        raise RuntimeError("GetFEM renumbered the points")
    gt = gf.GeoTrans(f"GT_QK({dim},1)")
    strides = np.cumprod([1] + [c + 1 for c in counts[:-1]])
    corners = np.stack(np.meshgrid(*[np.arange(c) for c in counts], indexing="ij"), axis=-1).reshape(-1, dim)
    local = np.stack(np.meshgrid(*[[0, 1]] * dim, indexing="ij"), axis=-1).reshape(-1, dim)[:, ::-1]
    for corner in corners:
        m.add_convex(gt, pts[((corner[None, :] + local) * strides).sum(axis=1)].T)
    if m.nbpts() != len(pts) or not np.array_equal(np.asarray(m.pts()).T, pts):
        raise RuntimeError("GetFEM merged or moved points")
    e_d = np.eye(dim)[-1]
    m.set_region(CLAMP, m.outer_faces_with_direction(e_d, 0.01))
    m.set_region(CONTACT, m.outer_faces_with_direction(-e_d, 0.01))
    return m, pts


def gmsh_nodes(path: str) -> np.ndarray:
    """The node coordinates of a Gmsh 2.2 ASCII file, in the file's order (signorini's numbering)."""
    with open(path) as fh:
        lines = fh.read().splitlines()
    start = lines.index("$Nodes")
    count = int(lines[start + 1])
    xyz = np.array([[float(v) for v in line.split()[1:4]] for line in lines[start + 2 : start + 2 + count]])
    return xyz


def gmsh_physical_ids(path: str) -> dict[str, int]:
    with open(path) as fh:
        lines = fh.read().splitlines()
    if "$PhysicalNames" not in lines:
        return {}
    start = lines.index("$PhysicalNames")
    out = {}
    for line in lines[start + 2 : start + 2 + int(lines[start + 1])]:
        _, number, name = line.split(maxsplit=2)
        out[name.strip('"')] = int(number)
    return out


def file_mesh(path: str, contact: str | list[str]) -> tuple[gf.Mesh, np.ndarray]:
    """A Gmsh file written by ``signorini.fem.mesh.write_mesh``; the contact region is the
    union of the physical groups named ``contact``."""
    m = gf.Mesh("import", "gmsh", path)
    dim = m.dim()
    pts = gmsh_nodes(path)[:, :dim]
    ids = gmsh_physical_ids(path)
    names = [contact] if isinstance(contact, str) else list(contact)
    regions = [ids[name] for name in names]
    m.set_region(CONTACT, np.zeros((2, 0), dtype=np.int64))
    for r in regions:
        m.region_merge(CONTACT, r)
    if m.nbpts() != len(pts):
        raise RuntimeError("GetFEM read another number of points")
    return m, pts


def dof_nodes(mf: gf.MeshFem, pts: np.ndarray, dim: int) -> tuple[np.ndarray, np.ndarray]:
    """(node, component) in signorini's numbering of every GetFEM dof (matched by coordinates)."""
    where = np.asarray(mf.basic_dof_nodes()).T  # (ndof, dim)
    tol = 1e-9 * float(np.ptp(pts, axis=0).max())
    node = np.empty(len(where), dtype=np.int64)
    for a in range(0, len(where), 256):  # nearest node, in chunks
        d2 = ((where[a : a + 256, None, :] - pts[None, :, :]) ** 2).sum(axis=2)
        node[a : a + 256] = d2.argmin(axis=1)
        if np.sqrt(d2.min(axis=1)).max() > tol:
            raise RuntimeError("a GetFEM dof is not at a node of the mesh")
    comp = np.arange(len(where)) % dim  # GetFEM interleaves the components of a vector fem
    for c in range(1, dim):
        if not np.array_equal(node[comp == c], node[comp == 0]):
            raise RuntimeError("unexpected dof layout of the vector fem")
    return node, comp


# ----------------------------------------------------------------------------- one run
def run_case(case: dict, solver: dict) -> tuple[dict, list[dict]]:
    """GetFEM's run of one case: (header, one row per time level)."""
    if "benchmark" in case:
        dim = {"bar2d": 2, "bar3d": 3}[case["benchmark"]]
        p = {**BAR_DEFAULTS, **case.get("params", {})}
        m, pts = bar_mesh(dim, int(case["n"]), p["width"], p["length"])
        fem, integ = f"FEM_QK({dim},1)", f"IM_GAUSS_PARALLELEPIPED({dim},3)"
        u0, clamped = p["gap"], True
    else:
        p = dict(case["params"])
        m, pts = file_mesh(case["mesh"], case["contact"])
        dim = m.dim()
        fem, integ = f"FEM_PK({dim},1)", f"IM_{'TRIANGLE' if dim == 2 else 'TETRAHEDRON'}(2)"
        u0, clamped = 0.0, False
    dt, steps = float(case["dt"]), round(float(case["T"]) / float(case["dt"]))
    e_d = np.eye(dim)[-1]

    mf = gf.MeshFem(m, dim)
    mf.set_fem(gf.Fem(fem))
    mim = gf.MeshIm(m, gf.Integ(integ))
    node, comp = dof_nodes(mf, pts, dim)
    ndof = mf.nbdof()

    md = gf.Model("real")
    md.add_fem_variable("u", mf)
    scheme = case["scheme"]
    if scheme == "cn":  # the scheme first: it defines Dot_u and Dot2_u
        md.add_Newmark_scheme("u", 0.25, 0.5)
    elif scheme == "be":
        md.add_theta_method_for_second_order("u", 1.0)
    else:
        raise ValueError(f"unknown scheme {scheme!r}; allowed: cn, be")
    md.set_time_step(dt)
    md.add_initialized_data("lambda", [p["lam"]])
    md.add_initialized_data("mu", [p["mu"]])
    md.add_initialized_data("rho", [p["rho"]])
    md.add_isotropic_linearized_elasticity_brick(mim, "u", "lambda", "mu")

    mass = case["mass"]
    if mass == "standard":
        md.add_mass_brick(mim, "Dot2_u", "rho")
        M = gf.asm_mass_matrix(mim, mf)
    elif mass == "seed":  # only the elements that touch no contact node (GetFEM's singular_mass = 1)
        touching = np.asarray(m.cvid_from_pid(m.pid_in_regions(CONTACT), True)).ravel()
        keep = np.setdiff1d(np.asarray(m.cvid()).ravel(), touching)
        m.set_region(MASS_REGION, keep[None, :])
        md.add_mass_brick(mim, "Dot2_u", "rho", MASS_REGION)
        M = gf.asm_mass_matrix(mim, mf, mf, MASS_REGION)
    else:
        raise ValueError(f"unknown mass {mass!r}; allowed: standard, seed")
    M.scale(p["rho"])

    if clamped:
        md.add_initialized_data("clamp", p["gap"] * e_d)
        md.add_Dirichlet_condition_with_simplification("u", CLAMP, "clamp")

    contact_dofs = np.sort(np.asarray(mf.basic_dof_on_region(CONTACT)).ravel())
    contact_nodes = np.unique(node[contact_dofs])  # signorini's order
    nc = contact_nodes.size
    mult_nodes = node[contact_dofs[::dim]]  # the brick's multiplier k: the k-th contact node in dof order
    mult_order = np.argsort(mult_nodes)
    if contact_dofs.size != nc * dim or not np.array_equal(mult_nodes[mult_order], contact_nodes):
        raise RuntimeError("unexpected dof layout on the contact boundary")
    md.add_variable("lambda_n", nc)
    md.add_initialized_data("r", [solver["r"]])
    obstacle = "xyz"[dim - 1]  # signed distance to the obstacle {x_d <= 0}
    md.add_nodal_contact_with_rigid_obstacle_brick(
        mim, "u", "lambda_n", "r", CONTACT, obstacle, int(solver["aug_version"])
    )

    # stiffness alone (for the energy), from the same brick
    md_s = gf.Model("real")
    md_s.add_fem_variable("u", mf)
    md_s.add_initialized_data("lambda", [p["lam"]])
    md_s.add_initialized_data("mu", [p["mu"]])
    md_s.add_isotropic_linearized_elasticity_brick(mim, "u", "lambda", "mu")
    md_s.assembly("build_matrix")
    S = md_s.tangent_matrix()

    U0 = np.zeros(ndof)
    U0[comp == dim - 1] = u0
    V0 = np.zeros(ndof)
    V0[comp == dim - 1] = -p["velocity"]
    if clamped:  # the clamped dofs are at rest
        V0[np.asarray(mf.basic_dof_on_region(CLAMP)).ravel()] = 0.0
    md.set_variable("u", U0)
    md.set_variable("Previous_u", U0)
    md.set_variable("Previous_Dot_u", V0)
    md.set_variable("Previous_Dot2_u", np.zeros(ndof))  # M A0 = -S U0 = 0

    normal_dof = np.empty(len(pts), dtype=np.int64)
    normal_dof[node[comp == dim - 1]] = np.flatnonzero(comp == dim - 1)
    cdofs = normal_dof[contact_nodes]
    header = {
        "contact_points": pts[contact_nodes].tolist(),
        "contact_nodes": contact_nodes.tolist(),
        "dofs": int(ndof),
        "getfem": getfem_version(),
        "solver": solver,
    }

    def level(step: int, U: np.ndarray, V: np.ndarray, lam: np.ndarray, its: int, conv: bool) -> dict:
        kinetic = 0.5 * float(V @ M.mult(V))
        elastic = 0.5 * float(U @ S.mult(U))
        return {
            "step": step,
            "t": step * dt,
            "lambda_sum": float(lam.sum()),
            "lambda": lam.tolist(),
            "normal_displacement": U[cdofs].tolist(),
            "energy": kinetic + elastic,
            "kinetic": kinetic,
            "elastic": elastic,
            "newton_iterations": its,
            "converged": conv,
        }

    rows = [level(0, U0, V0, np.zeros(nc), 0, True)]
    for k in range(1, steps + 1):
        md.set_time(k * dt)
        its, conv = md.solve("max_res", float(solver["max_res"]), "max_iter", int(solver["max_iter"]))
        md.shift_variables_for_time_integration()  # Previous_* := the new level's u, Dot_u, Dot2_u
        U = np.asarray(md.variable("u"))
        V = np.asarray(md.variable("Previous_Dot_u"))
        lam = np.asarray(md.variable("lambda_n"))[mult_order]
        rows.append(level(k, U, V, lam, int(its), bool(conv)))
    return header, rows


# ----------------------------------------------------------------------------- driver
@functools.cache
def getfem_version() -> str:
    """The installed GetFEM's version (the Debian package's when the module has none)."""
    version = getattr(gf, "__version__", None)
    if version:
        return str(version)
    try:
        out = subprocess.run(["dpkg-query", "-W", "-f=${Version}", "python3-getfem"], capture_output=True, text=True)
    except OSError:
        return "unknown"
    return out.stdout.strip() or "unknown"


def read_spec(argv: list[str]) -> dict:
    if len(argv) < 2 or argv[1] == "-":
        return json.load(sys.stdin)
    if argv[1].lstrip().startswith("{"):
        return json.loads(argv[1])
    with open(argv[1]) as fh:
        return json.load(fh)


def main(argv: list[str]) -> int:
    gf.util_trace_level(0)  # no assembly traces on stderr
    spec = read_spec(argv)
    solver = {**SOLVER, **spec.get("solver", {})}
    for i, case in enumerate(spec["cases"]):
        header, rows = run_case(case, solver)
        print(json.dumps({"case": i, **case, **header}), flush=True)
        for row in rows:
            print(json.dumps({"case": i, **row}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))

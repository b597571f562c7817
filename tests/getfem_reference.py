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
    block       or ``{"counts": [nx, ny(, nz)], "sizes": [lx, ly(, lz)]}``: the grid of
                ``rectangle``/``box`` (Q1), free, contact on the face x_d = 0 (the
                ``incline2d``/``incline3d`` block), ``params`` rho, lam, mu
    pair        or two (or more) deformable bodies in contact (below): ``mesh`` a Gmsh 2.2
                file of all the bodies, ``pair`` ``{"slave": tag, "master": tag}``
    static      or a static finite-strain case (no time, no contact): ``{"counts": [...], "sizes":
                [...], "law": "saint-venant-kirchhoff" | "neo-hookean", "lam", "mu", "traction":
                [...], "increments": k}``: the grid of ``rectangle``/``box`` (Q1, 2 Gauss points per
                direction) clamped on the face x_d = max, a dead traction on the face x_d = 0 applied
                in k equal increments, GetFEM's finite strain elasticity brick ("SaintVenant
                Kirchhoff", "Compressible Neo Hookean Bonet": W = mu/2 (I1 - 3) - mu ln J + lam/2
                (ln J)^2, signorini's) solved by Newton to max_res; one row per increment with the
                displacement ``u`` node-major
    mass        ``standard`` (consistent) or ``seed`` (the seed paper's M_mod, GetFEM's
                ``singular_mass=1``: the mass brick only on the elements that touch no
                contact node, so the contact nodes are massless in every component; with
                ``pair`` the contact nodes are the slave's and the master's nodes)
    scheme      ``cn`` (Newmark 1/4, 1/2) or ``be`` (theta-method, theta = 1)
    dt, T       time step and final time (round(T/dt) steps)

optional in every case:

    u0, v0      constant initial displacement and velocity vectors (the defaults above)
    plane       the obstacle is {x_d <= plane} (default 0; signed distance x_d - plane)
    gravity     g (a vector): the body force rho g, as GetFEM's source term brick, i.e. the
                consistent load int rho g . phi over the whole body whatever the mass
                variant (signorini's ``follow_mass=False``)
    friction    ``{"law": "coulomb", "coefficient": mu, "slip": "increment"}`` (default
                frictionless).  ``slip`` says which tangential displacement the nodal
                Alart-Curnier law acts on: ``increment`` (default) is the slip of the step,
                B_T (U^{n+1} - U^n), signorini's law (docs/friction.md): GetFEM's basic
                contact brick given the rigid-obstacle brick's own B_N, B_T, gap and alpha,
                with its dynamic term gamma = -1, wt = U^n (the brick's augmented tangential
                multiplier is lambda_t - r alpha B_T (u + gamma wt)); ``total`` is GetFEM's
                frictional rigid-obstacle brick as it is, whose law acts on B_T u, the
                displacement since t = 0 (a stick means u_T = 0: a quasi-static law)
    solver      overrides of the spec's ``solver`` for this case
    model       ``linear`` (default: the isotropic linearized elasticity brick), or a
                finite-strain law of ``static`` ("saint-venant-kirchhoff", "neo-hookean"):
                GetFEM's finite strain elasticity brick on [lam, mu] (the energy's ``elastic``
                stays 1/2 U.S U of the linear brick)

and ``solver`` may set ``max_res`` (Newton's residual target, default 1e-13), ``max_iter``
(50), ``r`` (the augmentation parameter, 1), ``aug_version`` (1: non-symmetric
Alart-Curnier) and ``relax`` (0: a step that does not reach max_res is solved again from
the same guess with max_res 10, 100, ... times larger, at most ``relax`` times; each row
says the ``max_res`` it reached) and ``polish`` (0: after convergence, that many more Newton
iterations, with no test: GetFEM's "external load" includes the scheme's inertia terms
M U^n / (beta dt^2), so a loose max_res can accept an iterate that is not at round-off).

The discretization is signorini's: for the bars [0, w] x [0, L] (x [0, w]) with n x 10n
Q1 cells (GT_QK/FEM_QK, Gauss 2 points per direction, exact for the mass and stiffness of
rectangular cells), nodes numbered x fastest, then y (, then z), top face clamped at
u = gap e_d (Dirichlet with simplification), u0 = gap e_d, v0 = -velocity e_d on the
free dofs and 0 on the clamped ones; for a mesh file P1 simplices (FEM_PK, a rule exact
for degree 2); plane strain in 2D (GetFEM's isotropic linearized elasticity brick with
the Lame coefficients in 2D); A0 = 0 (GetFEM's start, signorini's
``initial_acceleration="zero"``; for the bars S u0 = 0 and there is no load).  Contact: the nodes of the
contact faces against the rigid obstacle x_d >= plane (signed distance ``y`` / ``z``), i.e.
u_d >= plane - x_d, with GetFEM's nodal contact brick with a rigid obstacle (Alart-Curnier
augmented Lagrangian, solved by the semismooth Newton method of ``Model.solve`` at every
step).  Time integration: GetFEM's own schemes on ``Dot2_u`` (``add_Newmark_scheme``,
``add_theta_method_for_second_order``: the spec's sections 6.1 and 6.2), shifted by
``shift_variables_for_time_integration``.

Two bodies (``pair``): the file's bodies (one cell type: P1 simplices or Q1 quadrilaterals /
hexahedra, GetFEM's gmsh import; named physical groups of cells are regions, of facets
boundary tags, as ``signorini.fem.mesh.write_mesh`` writes them), with

    params      the default material {rho, lam, mu}
    materials   optional ``{region: {rho, lam, mu}}``: the cells of a listed region (those of
                an earlier listed one excepted) take its material, one elasticity brick and
                one mass brick per material (signorini's ``Problem(materials=...)``)
    velocity    optional ``{region: [v_x, v_y(, v_z)]}``: the initial velocity of the nodes
                of the region's cells (a later region's on shared nodes), else 0; u0 = 0
    clamp       optional facet tag (or list): u = 0 there (Dirichlet with simplification)

Contact: GetFEM's ``add_nodal_contact_between_nonmatching_meshes_brick`` on the one
displacement of all the bodies, rg1 = the slave tag (slave1), rg2 = the master tag.  The
brick computes B_N, the gaps and alpha at its first assembly, from the reference positions
of the nodes, and keeps them (``is_var_mf_newer_than_brick``): its pairing and master normal
are frozen at t = 0, as signorini's (docs/bodies.md).  Its discrete condition is signorini's,
B_N U <= gap with the row of slave node s = -n_m on s and N_j(xi) n_m on the master face's
nodes, gap = (x_s - p) . n_m with p the projection and n_m the face's outward unit normal;
the pairing algorithms differ: GetFEM takes the master *node* nearest to the slave node, then
among the tagged faces of that node the one where the projection is most inside (its
reference-element test ``is_in`` smallest, accepted below 0.05, so slightly outside the face
it extrapolates N_j); signorini takes the closest point over the nearest facets, clamped to
the facet, and drops a slave node laterally off the master surface.  A slave node GetFEM
pairs with no face (farther than 10 length units from every master node, or with no face
accepted) keeps a row of B_N = 0 and gap 10: inert (listed in ``inert_rows``).  The script
reads the brick's B_N and gaps back (a model of the brick alone at u = 0, lambda_n far in
the active branch of the nonsymmetric Alart-Curnier: the lambda_n rows of the tangent matrix
are -B_N, of the right-hand side -gap) and writes them in the header, in signorini's
numbering, so that a test compares the discrete conditions themselves.

Output of a ``pair`` case: the header has ``pair_nodes`` (the slave nodes, increasing: the
rows' order), ``pair_points``, ``inert_rows``, ``B`` (triplets ``rows``, ``cols``, ``vals``,
column = node * d + component), ``gap0``, ``brick``; a level has ``lambda_sum``,
``lambda`` (per row), ``gap`` (gap0 - B_N U per row), ``mean_gap``, ``energy`` =
1/2 V.MV + 1/2 U.SU (M of the mass variant, each part with its density), ``kinetic``,
``elastic``, ``newton_iterations``, ``converged``, ``max_res``.  Whatever GetFEM's C++ prints
on stdout (Debian's 5.4 prints "ok here" from this brick) is sent to stderr.

Output, JSON lines on stdout: per case a header ``{"case": i, ..., "contact_points":
[[x, ...], ...], "contact_nodes": [...]}`` (the contact nodes in signorini's order:
increasing node index, the index being the position in the generator's / the file's node
list), then one line per time level n = 0..N::

    {"case": i, "step": n, "t": t_n, "lambda_sum": sum_i lambda_i, "lambda": [lambda_i],
     "normal_displacement": [u_d(a_i)], "energy": E_n, "kinetic": ..., "elastic": ...,
     "load_potential": -U.F, "lambda_t": [[lambda_t,ik]], "tangential_force": [[..d]],
     "contact_force": [..d], "slip": [[..d]], "displacement": [[u(a_i)]],
     "newton_iterations": k, "converged": true, "seconds": s}

(``seconds``: the wall time of the step's Newton and shift, GetFEM's work alone).

lambda_i are GetFEM's nodal contact forces (<= 0 in compression, signorini's sign),
u_d(a_i) the d-th displacement of contact node i (signorini's gap g_i - nu_i.u_i when the
node starts on the plane, g_i = 0), E = 1/2 V.M V + 1/2 U.S U - U.F with GetFEM's matrices
(M of the mass variant), F the source term's vector and V = Dot_u of GetFEM's scheme.  The
header also has ``normals`` un_i = -e_d and ``tangents`` t_ik (the brick's frames: t = e_1
(, e_2), Gram-Schmidt on the coordinate axes); ``lambda_t`` are the tangential multipliers in
them, ``tangential_force`` = sum_k lambda_t,ik t_ik and ``contact_force`` = sum_i (lambda_i
un_i + tangential_force_i) are global components (the force on the body), and ``slip`` is
the tangential part of the contact node's U^n - U^{n-1} (0 at n = 0).  GetFEM's Newton
stops when min(|residual| / |external load|, |dU|_1 / |U|_1) <= max_res: on a sliding block
|U|_1 is mostly the rigid motion, and with an impact the contact forces are far larger than
the load, so 1e-13 may sit below the round-off floor: Newton then hops at the floor (and
after a number of iterations restarts from its initial guess, so that the iterate at
max_iter may be anything); ``relax`` retries with a looser target.
"""

from __future__ import annotations

import functools
import json
import os
import subprocess
import sys
import time

import getfem as gf
import numpy as np

BAR_DEFAULTS = {"rho": 1.0, "lam": 0.25, "mu": 0.5, "gap": 0.2, "velocity": 0.5, "width": 0.1, "length": 1.0}
SOLVER = {"max_res": 1e-13, "max_iter": 50, "r": 1.0, "aug_version": 1, "relax": 0, "polish": 0}
CLAMP, CONTACT, MASS_REGION = 101, 102, 103


# ----------------------------------------------------------------------------- geometry
def grid_mesh(counts: list[int], sizes: list[float]) -> tuple[gf.Mesh, np.ndarray]:
    """The grid of ``signorini.fem.mesh.rectangle``/``box`` ([0, sizes] with ``counts`` Q1
    cells), with signorini's node numbering; regions CLAMP (the face x_d = max) and
    CONTACT (the face x_d = 0).

    The points are added first in signorini's order (x fastest), so GetFEM's point ids
    are signorini's node indices; the cells are then given by coordinates in GetFEM's QK
    vertex order (x fastest in the reference cell), which GetFEM merges with those points.
    """
    dim = len(counts)
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


def bar_mesh(dim: int, n: int, width: float, length: float) -> tuple[gf.Mesh, np.ndarray]:
    """The seed paper's bar: n x 10 n (x n) Q1 cells on [0, w] x [0, L] (x [0, w])."""
    return grid_mesh([n] * (dim - 1) + [10 * n], [width] * (dim - 1) + [length])


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


def nearest_nodes(where: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """The node (row of ``pts``) at each point of ``where`` (m, dim), which must be one."""
    tol = 1e-9 * float(np.ptp(pts, axis=0).max())
    node = np.empty(len(where), dtype=np.int64)
    for a in range(0, len(where), 256):  # nearest node, in chunks
        d2 = ((where[a : a + 256, None, :] - pts[None, :, :]) ** 2).sum(axis=2)
        node[a : a + 256] = d2.argmin(axis=1)
        if np.sqrt(d2.min(axis=1)).max() > tol:
            raise RuntimeError("a GetFEM point is not at a node of the mesh")
    return node


def dof_nodes(mf: gf.MeshFem, pts: np.ndarray, dim: int) -> tuple[np.ndarray, np.ndarray]:
    """(node, component) in signorini's numbering of every GetFEM dof (matched by coordinates)."""
    node = nearest_nodes(np.asarray(mf.basic_dof_nodes()).T, pts)
    comp = np.arange(len(node)) % dim  # GetFEM interleaves the components of a vector fem
    for c in range(1, dim):
        if not np.array_equal(node[comp == c], node[comp == 0]):
            raise RuntimeError("unexpected dof layout of the vector fem")
    return node, comp


# ----------------------------------------------------------------------------- one run
def plane_frames(dim: int, nc: int) -> tuple[np.ndarray, np.ndarray]:
    """(un, ut) of GetFEM's rigid-obstacle brick for the obstacle {x_d <= p}: the unit normal
    un = -grad(x_d - p) = -e_d of every contact node (nc, d) and its tangents ut (nc, d-1, d)
    by the brick's Gram-Schmidt on e_1, e_2, ... (``orthonormal_basis_to_unit_vec`` of
    getfem_contact_and_friction_nodal.cc; e_1 (, e_2) here)."""
    un = -np.eye(dim)[-1]
    ut = []
    for k in range(dim):
        if len(ut) == dim - 1:
            break
        v = np.eye(dim)[k] - (un @ np.eye(dim)[k]) * un
        for w in ut:
            v = v - (w @ v) * w
        if np.linalg.norm(v) < 1e-3:
            continue
        ut.append(v / np.linalg.norm(v))
    return np.tile(un, (nc, 1)), np.tile(np.array(ut), (nc, 1, 1))


def spmat(rows: np.ndarray, cols: np.ndarray, vals: np.ndarray, shape: tuple[int, int]) -> gf.Spmat:
    """A GetFEM sparse matrix (CSC) from triplets."""
    out = gf.Spmat("empty", *shape)
    for r, c, v in zip(rows, cols, vals, strict=True):
        out.add(int(r), int(c), float(v))
    out.to_csc()
    return out


def newton(md: gf.Model, unknowns: list[str], solver: dict) -> tuple[int, bool, float]:
    """Newton to max_res; at its round-off floor (it then hops, and restarts from the initial
    guess after a while), again from the same guess with max_res 10 times larger, at most
    ``relax`` times: (iterations, converged, the max_res reached)."""
    ladder = [float(solver["max_res"]) * 10.0**j for j in range(int(solver["relax"]) + 1)]
    guess = {name: np.asarray(md.variable(name)).copy() for name in unknowns}
    total = 0
    for tol in ladder:
        for name in unknowns:
            md.set_variable(name, guess[name])
        its, conv = md.solve("max_res", tol, "max_iter", int(solver["max_iter"]))
        total += int(its)
        if conv:
            if int(solver["polish"]):  # Newton steps past the test (to the round-off floor)
                total += int(md.solve("max_res", 0.0, "max_iter", int(solver["polish"]))[0])
            return total, True, tol
    return total, False, ladder[-1]


GETFEM_LAWS = {"saint-venant-kirchhoff": "SaintVenant Kirchhoff", "neo-hookean": "Compressible Neo Hookean Bonet"}


def run_static_case(case: dict, solver: dict) -> tuple[dict, list[dict]]:
    """A static finite-strain case (module docstring, ``static``): (header, one row per load increment)."""
    c = case["static"]
    m, pts = grid_mesh(list(c["counts"]), list(c["sizes"]))
    dim = m.dim()
    mf = gf.MeshFem(m, dim)
    mf.set_fem(gf.Fem(f"FEM_QK({dim},1)"))
    mim = gf.MeshIm(m, gf.Integ(f"IM_GAUSS_PARALLELEPIPED({dim},3)"))
    node, comp = dof_nodes(mf, pts, dim)
    md = gf.Model("real")
    md.add_fem_variable("u", mf)
    md.add_initialized_data("params", [float(c["lam"]), float(c["mu"])])
    md.add_finite_strain_elasticity_brick(mim, GETFEM_LAWS[c["law"]], "u", "params")
    md.add_Dirichlet_condition_with_simplification("u", CLAMP)
    md.add_initialized_data("traction", np.zeros(dim))
    md.add_source_term_brick(mim, "u", "traction", CONTACT)
    traction, k = np.asarray(c["traction"], dtype=float), int(c["increments"])
    rows = []
    for step in range(1, k + 1):
        md.set_variable("traction", traction * step / k)
        its, conv, reached = newton(md, ["u"], solver)
        U = np.zeros((len(pts), dim))
        U[node, comp] = np.asarray(md.variable("u"))
        rows.append({"increment": step, "iterations": its, "converged": conv, "max_res": reached,
                     "u": U.ravel().tolist()})  # fmt: skip
    return {"getfem": getfem_version(), "points": pts.tolist()}, rows


def run_case(case: dict, solver: dict) -> tuple[dict, list[dict]]:
    """GetFEM's run of one case: (header, one row per time level)."""
    solver = {**solver, **case.get("solver", {})}
    if "static" in case:
        return run_static_case(case, solver)
    if "pair" in case:
        return run_pair_case(case, solver)
    if "benchmark" in case:
        dim = {"bar2d": 2, "bar3d": 3}[case["benchmark"]]
        p = {**BAR_DEFAULTS, **case.get("params", {})}
        m, pts = bar_mesh(dim, int(case["n"]), p["width"], p["length"])
        order = int(case.get("order", 1))  # 2: Q2 on the same (affine) cells, signorini's nodes in ``points``
        fem, integ = f"FEM_QK({dim},{order})", f"IM_GAUSS_PARALLELEPIPED({dim},{2 * order + 1})"
        if order == 2:
            pts = np.asarray(case["points"], dtype=float)
        u0, v0, clamped = p["gap"] * np.eye(dim)[-1], -p["velocity"] * np.eye(dim)[-1], True
    elif "block" in case:
        p = dict(case["params"])
        m, pts = grid_mesh(list(case["block"]["counts"]), list(case["block"]["sizes"]))
        dim = m.dim()
        fem, integ = f"FEM_QK({dim},1)", f"IM_GAUSS_PARALLELEPIPED({dim},3)"
        u0, v0, clamped = np.zeros(dim), np.zeros(dim), False
    else:
        p = dict(case["params"])
        m, pts = file_mesh(case["mesh"], case["contact"])
        dim = m.dim()
        fem, integ = cell_fem(m)  # P1 (or P2 on a file of triangle6) on the simplices of the file
        u0, v0, clamped = np.zeros(dim), -p["velocity"] * np.eye(dim)[-1], False
    u0 = np.asarray(case.get("u0", u0), dtype=float)
    v0 = np.asarray(case.get("v0", v0), dtype=float)
    plane = float(case.get("plane", 0.0))
    gravity = case.get("gravity")
    friction = dict(case.get("friction") or {"law": "frictionless"})
    law, slip_law = friction["law"], friction.get("slip", "increment")
    if law not in ("frictionless", "coulomb"):
        raise ValueError(f"unknown friction law {law!r}; allowed: frictionless, coulomb")
    if slip_law not in ("increment", "total"):
        raise ValueError(f"unknown slip {slip_law!r}; allowed: increment, total")
    dt, steps = float(case["dt"]), round(float(case["T"]) / float(case["dt"]))

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
    model = case.get("model", "linear")
    if model == "linear":
        md.add_isotropic_linearized_elasticity_brick(mim, "u", "lambda", "mu")
    elif model in GETFEM_LAWS:  # finite strain: GetFEM's brick on [lam, mu] (its Newton follows the brick's tangent)
        md.add_initialized_data("params", [p["lam"], p["mu"]])
        md.add_finite_strain_elasticity_brick(mim, GETFEM_LAWS[model], "u", "params")
    else:
        raise ValueError(f"unknown model {model!r}; allowed: linear, {', '.join(GETFEM_LAWS)}")

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

    F = np.zeros(ndof)
    if gravity is not None:  # the consistent load int rho g . phi over the whole body, whatever the mass
        md.add_initialized_data("body_force", p["rho"] * np.asarray(gravity, dtype=float))
        md.add_source_term_brick(mim, "u", "body_force")
        md_f = gf.Model("real")
        md_f.add_fem_variable("u", mf)
        md_f.add_initialized_data("body_force", p["rho"] * np.asarray(gravity, dtype=float))
        md_f.add_source_term_brick(mim, "u", "body_force")
        md_f.assembly("build_rhs")
        F = np.asarray(md_f.rhs()).copy()

    if clamped:
        md.add_initialized_data("clamp", p["gap"] * np.eye(dim)[-1])
        md.add_Dirichlet_condition_with_simplification("u", CLAMP, "clamp")

    contact_dofs = np.sort(np.asarray(mf.basic_dof_on_region(CONTACT)).ravel())
    contact_nodes = np.unique(node[contact_dofs])  # signorini's order
    nc = contact_nodes.size
    mult_nodes = node[contact_dofs[::dim]]  # the brick's multiplier k: the k-th contact node in dof order
    mult_order = np.argsort(mult_nodes)
    if contact_dofs.size != nc * dim or not np.array_equal(mult_nodes[mult_order], contact_nodes):
        raise RuntimeError("unexpected dof layout on the contact boundary")
    if not np.all(np.diff(contact_dofs.reshape(nc, dim), axis=1) == 1):
        raise RuntimeError("the components of a contact node are not consecutive dofs")
    un, ut = plane_frames(dim, nc)  # in the brick's (dof) order
    md.add_variable("lambda_n", nc)
    md.add_initialized_data("r", [solver["r"]])
    obstacle = "xyz"[dim - 1] + (f" - ({plane!r})" if plane else "")  # signed distance to {x_d <= plane}
    aug = int(solver["aug_version"])
    if law == "coulomb":
        md.add_variable("lambda_t", nc * (dim - 1))
        md.add_initialized_data("friction_coeff", [float(friction["coefficient"])])
    if law == "frictionless":
        md.add_nodal_contact_with_rigid_obstacle_brick(mim, "u", "lambda_n", "r", CONTACT, obstacle, aug)
    elif slip_law == "total":  # GetFEM's own frictional brick: Alart-Curnier on B_T u (the total displacement)
        md.add_nodal_contact_with_rigid_obstacle_brick(
            mim, "u", "lambda_n", "lambda_t", "r", "friction_coeff", CONTACT, obstacle, aug
        )
    else:  # the same brick's B_N, B_T, gap and alpha, given to the basic brick with its dynamic term
        first = contact_dofs[::dim]
        cols = first[:, None] + np.arange(dim)[None, :]
        BN = spmat(np.repeat(np.arange(nc), dim), cols.ravel(), un.ravel(), (nc, ndof))
        rows_t = np.repeat(np.arange(nc * (dim - 1)), dim)
        cols_t = np.repeat(cols, dim - 1, axis=0).ravel()
        BT = spmat(rows_t, cols_t, ut.reshape(-1), (nc * (dim - 1), ndof))
        boundary_mass = gf.asm_mass_matrix(mim, mf, mf, CONTACT)
        extent = float(np.ptp(pts, axis=0).max())
        alpha = np.array([boundary_mass[int(i), int(i)] for i in first]) / extent  # the brick's alpha
        md.add_initialized_data("gap", pts[node[first], dim - 1] - plane)
        md.add_initialized_data("alpha", alpha)
        md.add_initialized_data("gamma", [-1.0])  # B_T (u + gamma wt): the slip of the step
        md.add_initialized_data("wt", np.zeros(ndof))
        md.add_basic_contact_brick(
            "u", "lambda_n", "lambda_t", "r", BN, BT, "friction_coeff", "gap", "alpha", aug, "gamma", "wt"
        )

    # stiffness alone (for the energy), from the same brick
    md_s = gf.Model("real")
    md_s.add_fem_variable("u", mf)
    md_s.add_initialized_data("lambda", [p["lam"]])
    md_s.add_initialized_data("mu", [p["mu"]])
    md_s.add_isotropic_linearized_elasticity_brick(mim, "u", "lambda", "mu")
    md_s.assembly("build_matrix")
    S = md_s.tangent_matrix()

    U0 = u0[comp].copy()
    V0 = v0[comp].copy()
    if clamped:  # the clamped dofs are at rest
        V0[np.asarray(mf.basic_dof_on_region(CLAMP)).ravel()] = 0.0
    md.set_variable("u", U0)
    md.set_variable("Previous_u", U0)
    md.set_variable("Previous_Dot_u", V0)
    md.set_variable("Previous_Dot2_u", np.zeros(ndof))  # A0 = 0: GetFEM's start
    if law == "coulomb" and slip_law == "increment":
        md.set_variable("wt", U0)

    dofs_of = np.empty((len(pts), dim), dtype=np.int64)
    dofs_of[node, comp] = np.arange(ndof)
    cd = dofs_of[contact_nodes]  # (nc, d) the contact nodes' dofs, signorini's order
    un, ut = un[mult_order], ut[mult_order]  # frames in signorini's order (all equal here)
    header = {
        "contact_points": pts[contact_nodes].tolist(),
        "contact_nodes": contact_nodes.tolist(),
        "normals": un.tolist(),
        "tangents": ut.tolist(),
        "dofs": int(ndof),
        "getfem": getfem_version(),
        "solver": solver,
    }

    def level(step: int, U: np.ndarray, U_prev: np.ndarray, V: np.ndarray, its: int, conv: bool) -> dict:
        kinetic = 0.5 * float(V @ M.mult(V))
        elastic = 0.5 * float(U @ S.mult(U))
        potential = -float(U @ F)
        lam = np.asarray(md.variable("lambda_n"))[mult_order] if step else np.zeros(nc)
        if law == "coulomb" and step:
            lam_t = np.asarray(md.variable("lambda_t")).reshape(nc, dim - 1)[mult_order]
        else:
            lam_t = np.zeros((nc, dim - 1))
        tangential = np.einsum("ik,ikd->id", lam_t, ut)  # global components, per node
        nodal = lam[:, None] * un + tangential
        dU = U[cd] - U_prev[cd]
        slip = np.einsum("ikd,ik->id", ut, np.einsum("ikd,id->ik", ut, dU))  # tangential part of the step's dU
        return {
            "step": step,
            "t": step * dt,
            "lambda_sum": float(lam.sum()),
            "lambda": lam.tolist(),
            "lambda_t": lam_t.tolist(),
            "tangential_force": tangential.tolist(),
            "contact_force": nodal.sum(axis=0).tolist(),
            "slip": slip.tolist(),
            "normal_displacement": U[cd[:, -1]].tolist(),
            "displacement": U[cd].tolist(),
            "energy": kinetic + elastic + potential,
            "kinetic": kinetic,
            "elastic": elastic,
            "load_potential": potential,
            "newton_iterations": its,
            "converged": conv,
        }

    unknowns = ["u", "lambda_n"] + (["lambda_t"] if law == "coulomb" else [])
    rows = [level(0, U0, U0, V0, 0, True)]
    rows[0]["max_res"] = float(solver["max_res"])
    U_prev = U0
    for k in range(1, steps + 1):
        start = time.perf_counter()
        md.set_time(k * dt)
        its, conv, reached = newton(md, unknowns, solver)
        md.shift_variables_for_time_integration()  # Previous_* := the new level's u, Dot_u, Dot2_u
        seconds = time.perf_counter() - start
        U = np.asarray(md.variable("u")).copy()
        V = np.asarray(md.variable("Previous_Dot_u"))
        rows.append(level(k, U, U_prev, V, its, conv))
        rows[-1]["max_res"] = reached
        rows[-1]["seconds"] = seconds
        if law == "coulomb" and slip_law == "increment":
            md.set_variable("wt", U)  # the next step's slip is B_T (u - U^k)
        U_prev = U
    return header, rows


# ----------------------------------------------------------------------------- two bodies
def cell_fem(m: gf.Mesh) -> tuple[str, str]:
    """(fem, integration) of the one cell type of ``m``: P1 on simplices, Q1 on quadrilaterals /
    hexahedra, each with a rule exact for the mass and the stiffness of affine cells."""
    dim = m.dim()
    nv = {len(np.asarray(m.pid_from_cvid(int(cv))[0]).ravel()) for cv in np.asarray(m.cvid()).ravel()}
    if nv == {dim + 1}:
        return f"FEM_PK({dim},1)", f"IM_{'TRIANGLE' if dim == 2 else 'TETRAHEDRON'}(2)"
    if nv == {2**dim}:
        return f"FEM_QK({dim},1)", f"IM_GAUSS_PARALLELEPIPED({dim},3)"
    if nv == {6} and dim == 2:  # triangle6 (curved: GT_PK(2,2)): P2, the 6-point rule of degree 4 (signorini's)
        return "FEM_PK(2,2)", "IM_TRIANGLE(4)"
    if nv == {3**dim}:  # quad9 / hexahedron27: Q2, 3 Gauss points per direction
        return f"FEM_QK({dim},2)", f"IM_GAUSS_PARALLELEPIPED({dim},5)"
    raise ValueError(f"one cell type per file: simplices or quadrilaterals/hexahedra, got {sorted(nv)} vertices")


def merged_region(m: gf.Mesh, target: int, regions: list[int]) -> int:
    """Region ``target`` := the union of ``regions`` (faces or cells)."""
    m.set_region(target, np.zeros((2, 0), dtype=np.int64))
    for r in regions:
        m.region_merge(target, r)
    return target


def sub_matrix(K: gf.Spmat, rows: range, cols: range) -> np.ndarray:
    """The dense block K[rows, cols] of a GetFEM sparse matrix."""
    return np.asarray(K.full(list(rows), list(cols)))


def run_pair_case(case: dict, solver: dict) -> tuple[dict, list[dict]]:
    """GetFEM's run of the bodies of one Gmsh file in contact through a slave and a master facet
    tag, with GetFEM's nodal contact between non-matching meshes (the module doc's ``pair``)."""
    path = case["mesh"]
    ids = gmsh_physical_ids(path)
    m = gf.Mesh("import", "gmsh", path)
    dim = m.dim()
    pts = gmsh_nodes(path)[:, :dim]
    if m.nbpts() != len(pts):
        raise RuntimeError("GetFEM read another number of points (do two bodies touch at t = 0?)")
    fem, integ = cell_fem(m)
    base = dict(case["params"])
    materials = {tag: {**base, **mat} for tag, mat in (case.get("materials") or {}).items()}
    velocity = {tag: np.asarray(v, dtype=float) for tag, v in (case.get("velocity") or {}).items()}
    clamp = case.get("clamp") or []
    clamp = [clamp] if isinstance(clamp, str) else list(clamp)
    dt, steps = float(case["dt"]), round(float(case["T"]) / float(case["dt"]))
    all_cells = np.asarray(m.cvid()).ravel()
    top = max(ids.values(), default=0) + 1000  # region ids of ours, above the file's
    SLAVE, MASTER, BOTH, CLAMPED, PARTS = top + 1, top + 2, top + 3, top + 4, top + 10

    def cells_of(tag: str) -> np.ndarray:
        return np.unique(np.asarray(m.region(ids[tag]))[0]).astype(np.int64)

    merged_region(m, SLAVE, [ids[case["pair"]["slave"]]])
    merged_region(m, MASTER, [ids[case["pair"]["master"]]])
    merged_region(m, BOTH, [SLAVE, MASTER])  # the contact boundary of both bodies (the seed's)

    mf = gf.MeshFem(m, dim)
    mf.set_fem(gf.Fem(fem))
    mim = gf.MeshIm(m, gf.Integ(integ))
    node, comp = dof_nodes(mf, pts, dim)
    ndof = mf.nbdof()

    # the parts of one material (cells, {lam, mu, rho}): a listed region's cells (those of an
    # earlier listed region excepted), then the cells in no listed region with ``params``
    parts, listed = [], np.zeros(0, dtype=np.int64)
    for tag, mat in materials.items():
        cells = np.setdiff1d(cells_of(tag), listed)
        listed = np.union1d(listed, cells)
        parts.append((cells, mat))
    rest = np.setdiff1d(all_cells, listed)
    if rest.size:
        parts.append((rest, base))
    if case["mass"] == "seed":  # the elements that touch a contact node of either body are massless
        touching = np.asarray(m.cvid_from_pid(m.pid_in_regions(BOTH), True)).ravel()
    elif case["mass"] == "standard":
        touching = np.zeros(0, dtype=np.int64)
    else:
        raise ValueError(f"unknown mass {case['mass']!r}; allowed: standard, seed")

    md = gf.Model("real")
    md.add_fem_variable("u", mf)
    if case["scheme"] == "cn":
        md.add_Newmark_scheme("u", 0.25, 0.5)
    elif case["scheme"] == "be":
        md.add_theta_method_for_second_order("u", 1.0)
    else:
        raise ValueError(f"unknown scheme {case['scheme']!r}; allowed: cn, be")
    md.set_time_step(dt)
    md_s = gf.Model("real")  # the stiffness alone, for the energy
    md_s.add_fem_variable("u", mf)
    M = None
    for k, (cells, mat) in enumerate(parts):
        region, mass_region = PARTS + 2 * k, PARTS + 2 * k + 1
        m.set_region(region, cells[None, :])
        for model in (md, md_s):
            model.add_initialized_data(f"lambda{k}", [mat["lam"]])
            model.add_initialized_data(f"mu{k}", [mat["mu"]])
            model.add_isotropic_linearized_elasticity_brick(mim, "u", f"lambda{k}", f"mu{k}", region)
        heavy = np.setdiff1d(cells, touching)
        if heavy.size:
            m.set_region(mass_region, heavy[None, :])
            md.add_initialized_data(f"rho{k}", [mat["rho"]])
            md.add_mass_brick(mim, "Dot2_u", f"rho{k}", mass_region)
            Mk = gf.asm_mass_matrix(mim, mf, mf, mass_region)
            Mk.scale(mat["rho"])
            M = Mk if M is None else gf.Spmat("add", M, Mk)
    md_s.assembly("build_matrix")
    S = md_s.tangent_matrix()

    fixed = np.zeros(0, dtype=np.int64)
    if clamp:
        merged_region(m, CLAMPED, [ids[t] for t in clamp])
        md.add_initialized_data("clamp", np.zeros(dim))
        md.add_Dirichlet_condition_with_simplification("u", CLAMPED, "clamp")
        fixed = np.asarray(mf.basic_dof_on_region(CLAMPED)).ravel()

    # GetFEM's nodal contact between non-matching meshes, one displacement variable on both bodies
    # (rg1 the slave, rg2 the master surface): its B_N, gap and alpha are computed at the first
    # assembly from the reference positions and then kept (is_var_mf_newer_than_brick): frozen
    md.add_initialized_data("r", [solver["r"]])
    aug = int(solver["aug_version"])

    def contact_brick(model: gf.Model) -> None:
        model.add_nodal_contact_between_nonmatching_meshes_brick(
            mim, mim, "u", "u", "lambda_n", "r", SLAVE, MASTER, True, False, aug
        )

    contact_brick(md)
    # the brick's B_N, gap and alpha, read back from a model of the brick alone at u = 0 (the
    # brick's nonsymmetric Alart-Curnier: RLN = lambda_n + r alpha (gap - B_N u); the lambda_n
    # rows of the right-hand side are (RLN_- - lambda_n) / (r alpha), of the tangent matrix -B_N
    # where RLN <= 0, and -1 / (r alpha) on the diagonal where RLN > 0)
    probe = gf.Model("real")
    probe.add_fem_variable("u", mf)
    probe.add_initialized_data("r", [solver["r"]])
    contact_brick(probe)
    iu, il = probe.interval_of_variable("u"), probe.interval_of_variable("lambda_n")
    ru, rl = range(int(iu[0]), int(iu[0] + iu[1])), range(int(il[0]), int(il[0] + il[1]))
    nbc = len(rl)

    def assemble(lam: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        probe.set_variable("lambda_n", lam)
        probe.assembly("build_all")
        K = probe.tangent_matrix()
        return sub_matrix(K, rl, ru), np.diag(sub_matrix(K, rl, rl)), np.asarray(probe.rhs())[rl.start : rl.stop]

    extent = float(np.ptp(pts, axis=0).max())  # |gap| <= 10 (GetFEM's gap of an unpaired node) or the extent
    r_alpha = -1.0 / assemble(np.full(nbc, 1e100))[1]  # every row inactive: r alpha
    _, _, rough = assemble(-1e3 * r_alpha * (10.0 + extent))  # every row active: -gap to ~1e-13 (cancellation)
    K_nu, K_nn, rhs = assemble(-2.0 * r_alpha * (np.abs(rough) + 1e-3 * extent))  # -gap to ~1e-16 of |gap|
    if np.any(K_nn != 0.0):
        raise RuntimeError("reading GetFEM's gaps back: a row is not in the active branch")
    BN, gap0 = -K_nu, -rhs  # (nbc, ndof) in GetFEM's dofs, (nbc,)

    slave_dofs = np.sort(np.asarray(mf.basic_dof_on_region(SLAVE)).ravel())
    first = slave_dofs[slave_dofs % dim == 0]  # the brick's multiplier k: the k-th slave node in dof order
    if first.size != nbc or slave_dofs.size != nbc * dim:
        raise RuntimeError("unexpected dof layout on the slave surface")
    rows_nodes = node[first]
    order = np.argsort(rows_nodes)  # rows in signorini's order (increasing slave node)
    rows_nodes = rows_nodes[order]
    BN, gap0 = BN[order], gap0[order]
    inert = np.flatnonzero(~np.any(BN != 0.0, axis=1))  # slave nodes GetFEM paired with no master face
    for k in np.setdiff1d(np.arange(nbc), inert):  # row k's slave dofs carry -n_m, |n_m| = 1
        mine = np.flatnonzero(node == rows_nodes[k])
        if abs(np.linalg.norm(BN[k, mine]) - 1.0) > 1e-12:
            raise RuntimeError("the brick's multiplier order is not the slave nodes' dof order")

    U0 = np.zeros(ndof)
    V0 = np.zeros(ndof)
    point_node = nearest_nodes(np.asarray(m.pts()).T, pts)  # GetFEM's point id -> signorini's node
    for tag, v in velocity.items():  # the nodes of the region's cells, in the order given
        on = np.isin(node, point_node[np.asarray(m.pid_in_cvids(cells_of(tag))).ravel()])
        V0[on] = v[comp[on]]
    V0[fixed] = 0.0
    md.set_variable("u", U0)
    md.set_variable("Previous_u", U0)
    md.set_variable("Previous_Dot_u", V0)
    md.set_variable("Previous_Dot2_u", np.zeros(ndof))  # A0 = 0: GetFEM's start

    # B_N in signorini's dof numbering (node-major: node * d + component)
    sig = node * dim + comp
    BN_sig = np.zeros_like(BN)
    BN_sig[:, sig] = BN
    nz = np.nonzero(BN_sig)
    header = {
        "pair_nodes": rows_nodes.tolist(),
        "pair_points": pts[rows_nodes].tolist(),
        "inert_rows": inert.tolist(),
        "B": {"rows": nz[0].tolist(), "cols": nz[1].tolist(), "vals": BN_sig[nz].tolist()},
        "gap0": gap0.tolist(),
        "dofs": int(ndof),
        "getfem": getfem_version(),
        "solver": solver,
        "brick": "add_nodal_contact_between_nonmatching_meshes_brick",
    }

    def level(step: int, U: np.ndarray, V: np.ndarray, its: int, conv: bool) -> dict:
        kinetic = 0.5 * float(V @ M.mult(V)) if M is not None else 0.0
        elastic = 0.5 * float(U @ S.mult(U))
        lam = np.asarray(md.variable("lambda_n"))[order] if step else np.zeros(nbc)
        gaps = gap0 - BN @ U
        return {
            "step": step,
            "t": step * dt,
            "lambda_sum": float(lam.sum()),
            "lambda": lam.tolist(),
            "gap": gaps.tolist(),
            "mean_gap": float(gaps.mean()),
            "energy": kinetic + elastic,
            "kinetic": kinetic,
            "elastic": elastic,
            "newton_iterations": its,
            "converged": conv,
        }

    rows = [level(0, U0, V0, 0, True)]
    rows[0]["max_res"] = float(solver["max_res"])
    for k in range(1, steps + 1):
        md.set_time(k * dt)
        its, conv, reached = newton(md, ["u", "lambda_n"], solver)
        md.shift_variables_for_time_integration()
        rows.append(level(k, np.asarray(md.variable("u")).copy(), np.asarray(md.variable("Previous_Dot_u")), its, conv))
        rows[-1]["max_res"] = reached
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
    # the JSON lines on the real stdout; whatever GetFEM's C++ prints there (Debian's 5.4 prints
    # "ok here" from its contact code) goes to stderr
    sys.stdout.flush()
    out = os.fdopen(os.dup(1), "w")
    os.dup2(2, 1)
    spec = read_spec(argv)
    solver = {**SOLVER, **spec.get("solver", {})}
    for i, case in enumerate(spec["cases"]):
        header, rows = run_case(case, solver)
        print(json.dumps({"case": i, **case, **header}), file=out, flush=True)
        for row in rows:
            print(json.dumps({"case": i, **row}), file=out, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))

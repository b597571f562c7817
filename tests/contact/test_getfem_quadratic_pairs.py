"""Contact pairs on quadratic cells (issue 54, item 3): GetFEM's nodal contact between non-matching meshes as the
reference where the master is straight, the exact closest point where it is curved.

``disc``: a P2 disc of radius 0.25 (``pole_refined_ball(order=2)``: gmsh puts its mid-side nodes on the circle),
its ``cap`` the slave, 0.01 above a clamped, triangulated P2 block (1 x 0.3, 8 x 3 squares; its top, straight
``triangle6`` edges, the master), moving at (0.1, -0.5).  GetFEM 5.4 reads the same Gmsh file (GT_PK(2, 2)),
FEM_PK(2, 2), the 6-point rule of degree 4, its nodal contact between non-matching meshes; frozen pairing
(GetFEM pairs once), the consistent mass, CN and BE, GetFEM's conventions (``follow_mass=False``,
``initial_acceleration="zero"``).  Compared: the rows of B and the initial gaps, then the histories (relative max
norms, as tests/contact/test_getfem_pairs.py).  Measured: B 5.0e-16, initial gaps 6.9e-18; BE to t = 0.6 nodal
forces 1.0e-12, gaps 1.8e-13, energy 9.0e-14; CN to t = 0.2 1.4e-9, 1.2e-10, 2.1e-11.

``curved master``: the block's top (the slave) below the disc's cap (the master, curved).  GetFEM's brick does not
project on the curved face there (its initial gaps differ from the nodes' distances to the circle arcs by 8e-6,
its rows by 0.13): the reference is the distance itself, sampled on each master facet at 2e5 points (resolution
1e-11), and the projection's own conditions (x - p along the normal, the normal orthogonal to the facet there).
"""

from __future__ import annotations

import importlib.util
import math

import numpy as np
import pytest

from signorini.contact.pairs import ContactPair
from signorini.dynamics.model.problem import Problem, RegionInitial, discretize
from signorini.dynamics.stepping.simulate import simulate
from signorini.fem.material import IsotropicElastic
from signorini.fem.mesh import join, rectangle, write_mesh
from signorini.fem.space import Dirichlet
from test_getfem import _run_getfem
from test_getfem_pairs import GETFEM_SOLVER, _getfem_importable, _lame, relative

HAS_GMSH = importlib.util.find_spec("gmsh") is not None
#: (mass, scheme, T): CN with the consistent mass makes the contact rattle and amplifies round-off (as in
#: tests/contact/test_getfem_pairs.py: 3.5e-5 by t = 0.6): its run stops at 0.2
CASES = [("standard", "be", 0.6), ("standard", "cn", 0.2)]
DT = 0.004
#: rows and initial gaps (absolute, O(1) entries and gaps ~0.01), histories (relative)
ROW_ATOL, RTOL = 1e-12, 1e-8

pytestmark = pytest.mark.skipif(not HAS_GMSH, reason='the disc needs gmsh: pip install ".[mesh]"')


def _problem(path, curved_master: bool = False):
    from signorini.fem.meshing import pole_refined_ball

    disc = pole_refined_ball(2, 0.25, math.radians(60.0), 0.03, 0.08, 0.05, order=2)
    disc.points = disc.points + [0.0, 0.01]
    width = 0.2 if curved_master else 1.0  # every slave node faces the master surface
    block = rectangle(4 if curved_master else 8, 2 if curved_master else 3, width, 0.15 if curved_master else 0.3,
                      cell="triangle", order=2)  # fmt: skip
    block.points = block.points - [width / 2, block.points[:, 1].max()]
    mesh = join({"block": block, "disc": disc})
    write_mesh(mesh, path)
    v = [0.1, -0.5]
    BLOCK, DISC = IsotropicElastic.from_young(20.0, 0.25, 2.0), IsotropicElastic.from_young(10.0, 0.3, 1.0)
    pair = ContactPair("block_ymax", "disc_cap") if curved_master else ContactPair("disc_cap", "block_ymax")
    problem = Problem(mesh, DISC, None, None, dirichlet=[Dirichlet("block_ymin", 0.0)], materials={"block": BLOCK},
                      initial_regions=[RegionInitial("disc", velocity=v)], pairs=[pair], follow_mass=False,
                      initial_acceleration="zero")  # fmt: skip
    case = {"mesh": str(path), "pair": {"slave": pair.slave, "master": pair.master}, "clamp": "block_ymin",
            "params": _lame(DISC), "materials": {"block": _lame(BLOCK)}, "velocity": {"disc": v}}  # fmt: skip
    return problem, case


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    if not _getfem_importable():
        pytest.skip("python3-getfem not installed: apt-get install python3-getfem")
    problem, case = _problem(tmp_path_factory.mktemp("getfem_quadratic_pairs") / "disc2.msh")
    cases = [{**case, "mass": m, "scheme": s, "dt": DT, "T": T, "solver": GETFEM_SOLVER} for m, s, T in CASES]
    return dict(zip(CASES, _run_getfem(cases), strict=True)), problem


@pytest.mark.parametrize("key", CASES, ids=["-".join(k[:2]) for k in CASES])
def test_pairs_on_a_curved_master_agree_with_getfem(key, reference):
    runs, problem = reference
    mass, scheme, T = key
    header, rows = runs[key][0], runs[key][1:]
    assert header["inert_rows"] == [], "GetFEM paired a slave node with no master face"
    d = discretize(problem, mass)
    np.testing.assert_array_equal(d.contact.nodes, header["pair_nodes"])
    cap = problem.mesh.nodes_of("disc_cap")
    assert np.array_equal(d.contact.nodes, cap)  # every node of the cap: its vertices and mid-side nodes
    theirs_B = np.zeros(d.B.shape)
    theirs_B[header["B"]["rows"], header["B"]["cols"]] = header["B"]["vals"]
    H = simulate(problem, scheme, DT, T, mass=mass, solver_options={"pairing": "frozen"})
    assert H.success, H.message
    assert len(rows) == H.t.size and all(r["converged"] for r in rows)
    col = lambda k: np.array([r[k] for r in rows])  # noqa: E731
    assert col("lambda_sum").min() < 0, "no contact in the run: nothing compared"
    rows_diff = {"B": float(np.abs(d.B.toarray() - theirs_B).max()),
                 "initial gaps": float(np.abs(d.contact.gaps - np.array(header["gap0"])).max())}  # fmt: skip
    assert max(rows_diff.values()) <= ROW_ATOL, rows_diff
    diff = {
        "force": relative(H.lambda_sum, col("lambda_sum")),
        "energy": relative(H.energy, col("energy")),
        "nodal forces": relative(H.lam, col("lambda")),
        "gaps": relative(H.gap, col("gap")),
    }
    assert max(diff.values()) <= RTOL, diff


def test_a_curved_master_projects_each_slave_node_on_its_closest_point(tmp_path):
    """The curved master of the module docstring: every row's gap is the node's distance to the master arcs
    (measured to 7e-12, the sampling's resolution), the master's shape functions at the projection reproduce it,
    x - p lies along the row's normal, and the normal is orthogonal to the arc there (measured 1e-16)."""
    from signorini.contact.pairs import facet_owner_normals
    from signorini.fem.elements import shape_functions

    problem, _ = _problem(tmp_path / "m.msh", curved_master=True)
    mesh = problem.mesh
    d = discretize(problem, "standard")
    c = d.contact
    assert c.nodes.size == 9  # the block's top: 5 vertices and 4 mid-side nodes
    _, oriented = facet_owner_normals(mesh, mesh.facets_of("disc_cap"))
    N, _ = shape_functions("line3", np.linspace(0.0, 1.0, 200001)[:, None])
    arcs = np.einsum("sj,fjd->fsd", N, mesh.points[oriented])  # (facets, samples, 2)
    x = mesh.points[c.nodes]
    distance = np.linalg.norm(arcs[None] - x[:, None, None, :], axis=3).min(axis=(1, 2))
    assert np.abs(c.gaps - distance).max() < 2e-11
    p = np.einsum("mj,mjd->md", c.master_shape, mesh.points[c.master_dofs[:, :, 0] // 2])
    nu = c.normals  # out of the slave: -n_m
    s = c.master_shape @ np.array([0.0, 1.0, 0.5])  # the projections' parameters on their line3 facets
    inner = (s > 1e-9) & (s < 1 - 1e-9)  # a node facing a vertex (the pole's) meets the arcs' kink there
    assert inner.sum() == 8
    assert np.allclose((x - p)[inner], -(c.gaps[:, None] * nu)[inner], rtol=0, atol=1e-15)
    _, dN = shape_functions("line3", s[:, None])
    tangent = np.einsum("mj,mjd->md", dN[:, :, 0], mesh.points[c.master_dofs[:, :, 0] // 2])
    assert np.abs(np.einsum("md,md->m", tangent, nu)[inner]).max() < 1e-14 * np.abs(tangent).max()

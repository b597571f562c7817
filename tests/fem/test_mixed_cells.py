"""Several cell types in one mesh (issue 32): a triangle body on a quadrilateral one (2D), a
tetrahedral block on a hexahedral plate (3D).  The operators of a mixed mesh of two bodies are
the block diagonal of each body's own operators (one cell type each), the file round trip keeps
blocks, tags and regions, and a run of two free bodies keeps the momentum."""

from __future__ import annotations

import json
import subprocess
import sys

import meshio
import numpy as np
import pytest
import scipy.sparse as sp

from signorini.contact.pairs import ContactPair
from signorini.dynamics.model.mass import (
    mass_free_surface_scalar_mass,
    moment_preserving_scalar_mass,
    neighbour_scalar_mass,
    seed_scalar_mass,
)
from signorini.dynamics.model.problem import Problem, RegionInitial
from signorini.dynamics.stepping.simulate import simulate
from signorini.errors import MeshError
from signorini.fem.assembly import cell_volumes, scalar_mass_matrix, stiffness_matrix, von_mises
from signorini.fem.material import IsotropicElastic
from signorini.fem.mesh import box, join, read_mesh, rectangle, write_mesh

STEEL = IsotropicElastic.from_young(200.0, 0.3, 7.8)


def two_bodies(dim: int):
    """(mixed mesh, lower part, upper part): quads under triangles, hexahedra under tetrahedra."""
    if dim == 2:
        low, up = rectangle(6, 2, 1.0, 0.3, cell="quad"), rectangle(4, 2, 0.6, 0.3, cell="triangle")
        up.points = up.points + [0.2, 0.32]
    else:
        low, up = box(4, 4, 2, 1.0, 1.0, 0.25), box(2, 2, 2, 0.5, 0.5, 0.5, cell="tetra")
        up.points = up.points + [0.25, 0.25, 0.27]
    return join({"lower": low, "upper": up}), low, up


@pytest.mark.parametrize("dim", [2, 3])
def test_mixed_mesh_operators_are_each_bodys_own(dim):
    """S, M and every redistributed scalar mass of the mixed mesh equal blockdiag(lower's, upper's)
    to round-off; the volumes and the stress of the parts are the parts' own."""
    m, low, up = two_bodies(dim)
    assert m.mixed and [b.cell_type for b in m.blocks] == ([("quad"), ("triangle")] if dim == 2 else
                                                          ["hexahedron", "tetra"])  # fmt: skip
    top = "ymax" if dim == 2 else "zmax"
    bottom = "ymin" if dim == 2 else "zmin"
    c_low, c_up = low.nodes_of(top), up.nodes_of(bottom)
    c_mixed = np.concatenate([c_low, c_up + low.n_nodes])

    def close(a, b):
        a, b = sp.csr_matrix(a), sp.csr_matrix(b)
        assert a.shape == b.shape and abs(a - b).max() <= 1e-13 * abs(b).max()

    close(stiffness_matrix(m, STEEL), sp.block_diag([stiffness_matrix(low, STEEL), stiffness_matrix(up, STEEL)]))
    close(scalar_mass_matrix(m, 7.8), sp.block_diag([scalar_mass_matrix(low, 7.8), scalar_mass_matrix(up, 7.8)]))
    for variant in (seed_scalar_mass, neighbour_scalar_mass, mass_free_surface_scalar_mass,
                    moment_preserving_scalar_mass):  # fmt: skip
        close(variant(m, 7.8, c_mixed), sp.block_diag([variant(low, 7.8, c_low), variant(up, 7.8, c_up)]))
    assert np.allclose(cell_volumes(m), np.concatenate([cell_volumes(low), cell_volumes(up)]), rtol=1e-14, atol=0)
    u = np.random.default_rng(1).normal(size=m.n_nodes * dim)
    vm = von_mises(m, STEEL, u, nodal=False)
    assert np.allclose(
        vm[: low.n_cells], von_mises(low, STEEL, u[: low.n_nodes * dim], nodal=False), rtol=1e-12, atol=0
    )


@pytest.mark.parametrize("dim", [2, 3])
def test_mixed_mesh_file_round_trip(tmp_path, dim):
    m, _, _ = two_bodies(dim)
    write_mesh(m, tmp_path / "m.msh")
    r = read_mesh(tmp_path / "m.msh")
    assert [(b.cell_type, len(b.cells)) for b in r.blocks] == [(b.cell_type, len(b.cells)) for b in m.blocks]
    assert sorted(r.facets) == sorted(m.facets) and sorted(r.regions) == sorted(m.regions)
    assert np.array_equal(r.regions["upper"], m.regions["upper"])


def test_a_tag_of_triangles_and_quads_is_refused(tmp_path):
    m, _, _ = two_bodies(3)
    pts = np.asarray(m.points)
    tri, quad = m.facets["upper_zmin"], m.facets["lower_zmax"]
    out = meshio.Mesh(pts, [(b.cell_type, b.cells) for b in m.blocks] + [("triangle", tri), ("quad", quad)],
                      cell_data={"gmsh:physical": [np.full(len(b.cells), 1) for b in m.blocks] + [np.full(len(tri), 2),
                                 np.full(len(quad), 2)]},
                      field_data={"body": np.array([1, 3]), "both": np.array([2, 2])})  # fmt: skip
    out.cell_data["gmsh:geometrical"] = out.cell_data["gmsh:physical"]
    meshio.write(tmp_path / "bad.msh", out, file_format="gmsh22", binary=False)
    with pytest.raises(MeshError, match="holds facets of two types"):
        read_mesh(tmp_path / "bad.msh")


@pytest.mark.parametrize("dim", [2, 3])
def test_two_free_bodies_of_two_cell_types_collide(dim):
    """The upper body (triangles, tetrahedra) thrown at the free lower one (quads, hexahedra)
    through a pair: momentum kept to round-off, no slave penetration, and with the contact
    inertia removed on both sides CN keeps the energy (it grows with the standard mass)."""
    m, _, _ = two_bodies(dim)
    v = [0.0, -1.0] if dim == 2 else [0.0, 0.0, -1.0]
    top, bottom = ("ymax", "ymin") if dim == 2 else ("zmax", "zmin")
    p = Problem(m, STEEL, None, None, pairs=[ContactPair(f"upper_{bottom}", f"lower_{top}")],
                initial_regions=[RegionInitial("upper", velocity=v)])  # fmt: skip
    out = {}
    for mass in ("standard", "moment-preserving"):
        H = simulate(p, "cn", 0.002, 0.1, mass=mass)
        assert H.status == "finished" and H.active.max() > 0
        P = H.momentum
        assert np.abs(P - P[0]).max() <= 1e-12 * np.abs(P[0]).max()
        assert H.gap.min() >= -1e-12
        E = H.kinetic_energy + H.elastic_energy
        out[mass] = E[-1] / E[0]
    assert abs(out["moment-preserving"] - 1) < 0.02 and out["standard"] > out["moment-preserving"]


def test_cli_run_of_a_mixed_mesh_writes_both_blocks(tmp_path):
    """A case file on a tetrahedral block over a hexahedral plate: exit 0, XDMF with a
    hexahedron and a tetra block, each with its region and body ids; summary's two bodies."""
    m, _, _ = two_bodies(3)
    write_mesh(m, tmp_path / "parts.msh")
    (tmp_path / "case.toml").write_text(
        '[mesh]\nfile = "parts.msh"\n\n[material]\nE = 200.0\nnu = 0.3\nrho = 7.8\n\n'
        '[contact]\npairs = [{ slave = "upper_zmin", master = "lower_zmax" }]\n\n'
        '[[dirichlet]]\ntag = "lower_zmin"\nvalue = [0.0, 0.0, 0.0]\n\n'
        '[initial]\nregions = [{ tag = "upper", velocity = [0.0, 0.0, -1.0] }]\n\n'
        "[time]\ndt = 0.002\nT = 0.05\n\n[output]\nsnapshot_every = 5\n"
    )
    r = subprocess.run([sys.executable, "-m", "signorini", "run", "case.toml", "--quiet", "--out", "o"],
                       cwd=tmp_path, capture_output=True, text=True)  # fmt: skip
    assert r.returncode == 0, r.stderr
    s = json.loads((tmp_path / "o/summary.json").read_text())
    assert len(s["bodies"]) == 2 and s["status"] == "finished"
    with meshio.xdmf.TimeSeriesReader(str(tmp_path / "o/fields.xdmf")) as reader:
        points, cells = reader.read_points_cells()
        t, point_data, cell_data = reader.read_data(reader.num_steps - 1)
    assert [c.type for c in cells] == ["hexahedron", "tetra"]
    assert [np.unique(b).tolist() for b in cell_data["body"]] == [[0], [1]]
    assert point_data["displacement"].shape == (len(points), 3)


@pytest.mark.parametrize("order", [1, 2])
def test_a_contact_boundary_of_triangles_and_quads_drops_on_a_plane(order):
    """[contact] tag = the bottoms of a tetrahedral and a hexahedral body (two facet types in one list: they
    were stacked as one array, a ValueError): their union's nodes, the facets' area summed type by type, and a
    run through the impact with both bodies' nodes in contact."""
    from signorini.contact.obstacles import PlaneObstacle
    from signorini.fem.assembly import facet_weights

    a, b = box(2, 2, 2, cell="tetra", order=order), box(2, 2, 2, order=order)
    b.points = b.points + [2.0, 0.0, 0.0]
    mesh = join({"a": a, "b": b})
    tags = ["a_zmin", "b_zmin"]
    assert np.array_equal(mesh.nodes_of(tags), np.union1d(mesh.nodes_of("a_zmin"), mesh.nodes_of("b_zmin")))
    assert facet_weights(mesh, tags, positive=True).sum() == pytest.approx(2.0, rel=1e-14, abs=0)
    with pytest.raises(MeshError, match="several types"):
        mesh.facets_of(tags)
    problem = Problem(mesh, IsotropicElastic.from_young(100.0, 0.3, 1.0), tags,
                      PlaneObstacle([0.0, 0.0, -0.01], [0.0, 0.0, 1.0]), v0=[0.0, 0.0, -1.0])  # fmt: skip
    H = simulate(problem, "crank-nicolson", 0.005, 0.05)
    assert H.status == "finished" and H.nodes.size == mesh.nodes_of(tags).size
    assert (H.lam < 0).any(axis=0)[np.isin(H.nodes, mesh.nodes_of("a_zmin"))].any()
    assert (H.lam < 0).any(axis=0)[np.isin(H.nodes, mesh.nodes_of("b_zmin"))].any()

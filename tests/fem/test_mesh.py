import numpy as np
import pytest

from signorini.errors import MeshError
from signorini.fem.mesh import Mesh, box, interval, join, read_mesh, rectangle, uniform_cells, write_mesh


@pytest.mark.parametrize(
    "mesh, tags",
    [
        (interval(4, 2.0), {"xmin": 1, "xmax": 1}),
        (rectangle(3, 5, 1, 2), {"xmin": 5, "xmax": 5, "ymin": 3, "ymax": 3}),
        (rectangle(3, 5, 1, 2, "triangle"), {"xmin": 5, "xmax": 5, "ymin": 3, "ymax": 3}),
        (box(2, 3, 4), {"xmin": 12, "xmax": 12, "ymin": 8, "ymax": 8, "zmin": 6, "zmax": 6}),
        (
            box(2, 3, 4, cell="tetra"),
            {"xmin": 24, "xmax": 24, "ymin": 16, "ymax": 16, "zmin": 12, "zmax": 12},
        ),
    ],
)
def test_generators_tag_every_side(mesh, tags):
    mesh.check_cells()
    assert {k: len(v) for k, v in mesh.facets.items()} == tags
    lo, hi = mesh.points.min(0), mesh.points.max(0)
    for k, ax in enumerate("xyz"[: mesh.dim]):
        assert np.allclose(mesh.points[mesh.nodes_of(f"{ax}min"), k], lo[k], rtol=0, atol=1e-14)
        assert np.allclose(mesh.points[mesh.nodes_of(f"{ax}max"), k], hi[k], rtol=0, atol=1e-14)


@pytest.mark.parametrize("mesh", [rectangle(2, 3, 1, 1), box(2, 2, 3, cell="tetra"), interval(3)])
def test_gmsh_roundtrip_keeps_physical_groups(tmp_path, mesh):
    path = tmp_path / "m.msh"
    write_mesh(mesh, path)
    m2 = read_mesh(path)
    assert m2.cell_type == mesh.cell_type
    assert np.allclose(m2.points, mesh.points, rtol=0, atol=1e-15)  # a gmsh 2.2 round trip (%.16e)
    assert set(m2.tags) == set(mesh.tags)
    for t in mesh.tags:
        assert np.array_equal(m2.nodes_of(t), mesh.nodes_of(t))


def test_clear_errors(tmp_path):
    m = rectangle(2, 2)
    with pytest.raises(MeshError, match="unknown boundary tag 'bottom'.*xmin"):
        m.nodes_of("bottom")
    m.facets["empty"] = np.zeros((0, 2), dtype=int)
    with pytest.raises(MeshError, match="empty"):
        m.nodes_of("empty")
    with pytest.raises(MeshError, match="unsupported cell type 'pyramid'"):
        Mesh(np.zeros((5, 3)), np.zeros((1, 5), dtype=int), "pyramid")
    inv = Mesh(np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]]), np.array([[0, 3, 2, 1]]), "quad")
    with pytest.raises(MeshError, match="inverted"):
        inv.check_cells()
    flat = Mesh(np.array([[0, 0], [1, 0], [2, 0.0]]), np.array([[0, 1, 2]]), "triangle")
    with pytest.raises(MeshError, match="degenerate"):
        flat.check_cells()
    with pytest.raises(MeshError, match="does not exist"):
        read_mesh(tmp_path / "nope.msh")
    with pytest.raises(MeshError, match="positive integer"):
        rectangle(0, 2)


def test_uniform_meshes_are_checked_through_their_first_cell():
    """Translates of one cell (the generators' boxes) are checked through that cell: a
    box whose cells are all inverted reports every one of them."""
    m = box(2, 2, 2)
    assert uniform_cells(m)
    m.check_cells()
    flipped = Mesh(m.points, m.cells[:, [4, 5, 6, 7, 0, 1, 2, 3]], "hexahedron")
    with pytest.raises(MeshError, match=r"^8 inverted element\(s\)"):
        flipped.check_cells()
    moved = m.points.copy()
    moved[13] += 0.01  # the centre node: the cells are no longer translates
    assert not uniform_cells(Mesh(moved, m.cells, "hexahedron"))


def test_check_cells_sees_points_moved_after_a_first_check():
    m = box(2, 2, 2)
    m.check_cells()  # caches that the cells are translates
    m.points[13, 2] = 5.0  # the centre node pulled out of the box: cells inverted
    with pytest.raises(MeshError, match="inverted"):
        m.check_cells()


def test_a_facet_in_two_gmsh_physical_groups_carries_both_tags():
    """cylinder.msh (Gmsh 4.1): the bottom disc is in 'skin' and in 'bottom'."""
    from pathlib import Path

    from signorini.fem.mesh import read_mesh

    m = read_mesh(Path(__file__).parents[2] / "examples" / "meshes" / "cylinder.msh")
    assert set(m.tags) == {"skin", "bottom"}
    bottom = m.nodes_of("bottom")
    assert bottom.size > 10 and np.abs(m.points[bottom, 2]).max() < 1e-14  # measured 0
    assert np.isin(bottom, m.nodes_of("skin")).all()
    assert np.array_equal(m.nodes_of(["skin", "bottom"]), m.nodes_of("skin"))  # a union, each facet once
    assert len(m.facets_of(["skin", "bottom"])) == len(m.facets_of("skin"))


def test_physical_groups_that_hold_no_facet_are_an_error(tmp_path):
    import meshio

    from signorini.errors import MeshError
    from signorini.fem.mesh import read_mesh

    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    mesh = meshio.Mesh(
        pts,
        [("triangle", np.array([[0, 1, 2]]))],
        cell_data={"gmsh:physical": [np.array([1])], "gmsh:geometrical": [np.array([1])]},
        field_data={"domain": np.array([1, 2]), "contact": np.array([2, 1])},
    )
    path = tmp_path / "empty_group.msh"
    meshio.write(path, mesh, file_format="gmsh22", binary=False)
    with pytest.raises(MeshError, match=r"physical groups \['contact'\].*hold no line facets"):
        read_mesh(path)


def _write_msh22(path, points, cells, facets, phys=None):
    import meshio

    phys_f = np.full(len(facets), 1) if phys is None else phys
    mesh = meshio.Mesh(
        points,
        [("triangle", np.asarray(cells)), ("line", np.asarray(facets))],
        cell_data={"gmsh:physical": [np.full(len(cells), 2), phys_f], "gmsh:geometrical": [np.full(len(cells), 2),
                                                                                              np.full(len(facets), 1)]},
        field_data={"bottom": np.array([1, 1]), "domain": np.array([2, 2])},
    )  # fmt: skip
    meshio.write(path, mesh, file_format="gmsh22", binary=False)


SQUARE = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
TRIS = [[0, 1, 2], [0, 2, 3]]


@pytest.mark.parametrize(
    "points, facets, phys, match",
    [
        (SQUARE, [[0, 1], [0, 1]], None, "more than once"),
        (SQUARE, [[1, 3]], None, "not faces of any cell"),
        (SQUARE + np.array([[0, 0, 0], [0, 0, 0.5], [0, 0, 0], [0, 0, 0]]), [[0, 1]], None, "coordinate varies"),
        (SQUARE, [[0, 7]], None, "outside 0..3|cannot read mesh file"),
    ],
)
def test_corrupt_mesh_files_are_refused_in_one_line(tmp_path, points, facets, phys, match):
    from signorini.errors import MeshError
    from signorini.fem.mesh import read_mesh

    path = tmp_path / "bad.msh"
    try:
        _write_msh22(path, points, TRIS, facets, phys)
    except (ValueError, IndexError):
        pytest.skip("meshio cannot write this corruption")  # pragma: no cover
    with pytest.raises(MeshError, match=match) as info:
        read_mesh(path)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("bad", [np.nan, 1.5])
def test_non_integer_physical_tags_are_refused(tmp_path, bad):
    import meshio

    from signorini.errors import MeshError
    from signorini.fem.mesh import read_mesh

    mesh = meshio.Mesh(
        SQUARE,
        [("triangle", np.array(TRIS)), ("line", np.array([[0, 1]]))],
        cell_data={"gmsh:physical": [np.array([2.0, 2.0]), np.array([bad])]},
    )
    path = tmp_path / "bad.vtu"
    meshio.write(path, mesh)
    with pytest.raises(MeshError, match="integers"):
        read_mesh(path)


def test_vtu_cell_past_the_last_node_is_a_mesh_error(tmp_path):
    import meshio

    from signorini.errors import MeshError
    from signorini.fem.mesh import read_mesh

    path = tmp_path / "bad.vtu"
    meshio.write(path, meshio.Mesh(SQUARE, [("triangle", np.array([[0, 1, 2], [0, 2, 9]]))]))
    with pytest.raises(MeshError, match="outside 0..3|cannot read mesh file"):
        read_mesh(path)


def test_gmsh_physical_names_are_matched_with_their_dimension(tmp_path):
    """A surface group and a volume group may share an id (1): the surface's name tags the facets."""
    import meshio

    from signorini.fem.mesh import read_mesh

    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    mesh = meshio.Mesh(
        pts,
        [("tetra", np.array([[0, 1, 2, 3]])), ("triangle", np.array([[0, 1, 2]]))],
        cell_data={"gmsh:physical": [np.array([1]), np.array([1])], "gmsh:geometrical": [np.array([1]), np.array([1])]},
        field_data={"body": np.array([1, 3]), "skin": np.array([1, 2])},
    )
    path = tmp_path / "g.msh"
    meshio.write(path, mesh, file_format="gmsh22", binary=False)
    m = read_mesh(path)
    assert m.tags == ["skin"]


def test_non_conforming_meshes_and_interior_tags_are_refused(tmp_path):
    from signorini.errors import MeshError
    from signorini.fem.mesh import Mesh, _check_facets

    pts = SQUARE[:, :2]
    with pytest.raises(MeshError, match="same nodes"):
        _check_facets("m", Mesh(pts, np.array([[0, 1, 2], [2, 1, 0]]), "triangle", {}))
    with pytest.raises(MeshError, match="more than two cells"):
        five = np.vstack([pts, [[2.0, 2.0]]])  # a third triangle on the diagonal 0-2
        _check_facets("m", Mesh(five, np.array([[0, 1, 2], [0, 2, 3], [0, 4, 2]]), "triangle", {}))
    with pytest.raises(MeshError, match="inside the body"):
        _check_facets("m", Mesh(pts, np.array(TRIS), "triangle", {"diag": np.array([[0, 2]])}))


def test_face_keys_do_not_overflow_on_large_meshes():
    """Beyond 2,097,152 nodes n^3 leaves int64: the keys become opaque rows, still equal for the
    same face in any node order and different for different faces."""
    from signorini.fem.mesh import face_keys

    big = 3_000_001
    f = np.array([[3_000_000, 5, 7], [7, 3_000_000, 5], [3_000_000, 5, 8], [1, 2, 4]])
    k = face_keys(f, big)
    assert k[0] == k[1] and k[0] != k[2] and len(np.unique(k)) == 3
    assert face_keys(f[3:], 10).dtype == np.int64  # small meshes keep the fast integer keys


#: a unit hexahedron (nodes 0..7, z = 0 then z = 1) and two tetrahedra on its top face
HEX_POINTS = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1],
                       [0.5, 0.5, 2.0]], float)  # fmt: skip


def _write_3d(path, blocks, physical, names):
    import meshio

    mesh = meshio.Mesh(HEX_POINTS, blocks, cell_data={"gmsh:physical": physical, "gmsh:geometrical": physical},
                       field_data=names)  # fmt: skip
    meshio.write(path, mesh, file_format="gmsh22", binary=False)


def test_a_facet_tag_holding_faces_no_cell_has_is_refused(tmp_path):
    """A hexahedral mesh whose physical surface also lists triangles (faces no hexahedron has):
    they were dropped silently; now the tag is named."""
    from signorini.errors import MeshError
    from signorini.fem.mesh import read_mesh

    blocks = [("hexahedron", np.array([[0, 1, 2, 3, 4, 5, 6, 7]])), ("quad", np.array([[0, 1, 2, 3]])),
              ("triangle", np.array([[4, 5, 6]]))]  # fmt: skip
    names = {"body": np.array([1, 3]), "bottom": np.array([2, 2])}
    _write_3d(tmp_path / "m.msh", blocks, [np.array([1]), np.array([2]), np.array([2])], names)
    with pytest.raises(MeshError, match=r"tag 'bottom' holds triangle facets, but the mesh's cells \(hexahedron\)"):
        read_mesh(tmp_path / "m.msh")
    _write_3d(tmp_path / "ok.msh", blocks[:2], [np.array([1]), np.array([2])], names)
    assert read_mesh(tmp_path / "ok.msh").facets_of("bottom").shape == (1, 4)


def test_tetrahedra_glued_to_a_hexahedron_face_are_refused(tmp_path):
    """Four tetrahedra on the top face of a hexahedron, sharing its nodes but not its face
    (no pyramid): the body would be cut along that face; refused by name."""
    from signorini.errors import MeshError
    from signorini.fem.mesh import read_mesh

    tets = np.array([[4, 5, 6, 8], [4, 6, 7, 8]])  # the top face split in two triangles, apex above
    blocks = [("hexahedron", np.array([[0, 1, 2, 3, 4, 5, 6, 7]])), ("tetra", tets)]
    _write_3d(tmp_path / "m.msh", blocks, [np.array([1]), np.array([1, 1])], {"body": np.array([1, 3])})
    with pytest.raises(MeshError, match=r"2 face\(s\) of tetrahedra lie on a face of a hexahedron.*pyramids"):
        read_mesh(tmp_path / "m.msh")


def test_resolution_is_the_finest_bodys_median_cell_over_its_extent():
    """h / L: a bar of n cells along its length 1 / n (whatever its width); a box of 4 cells a side 1 / 4; two bodies,
    the finer one's (a beam 0.1 long of 50 x 4 cells, 1.25 mm thick rows: 0.0125, beside a block of 10 x 5 cells
    of 2 mm: 0.1); a graded bar (cells 1 to 3 units, the median 2 over 30) its median, not its smallest."""
    from signorini.fem.mesh import resolution

    assert resolution(rectangle(1, 80, 0.002, 0.01)) == pytest.approx(1 / 80, rel=1e-12, abs=0)
    assert resolution(interval(40)) == pytest.approx(1 / 40, rel=1e-12, abs=0)
    assert resolution(box(4, 4, 4)) == pytest.approx(1 / 4, rel=1e-12, abs=0)
    beam, block = rectangle(50, 4, 0.1, 0.005), rectangle(10, 5, 0.02, 0.01)
    block.points = block.points + [0.04, 0.005 + 1e-6]
    assert resolution(join({"beam": beam, "block": block})) == pytest.approx(0.0125, rel=1e-12, abs=0)
    graded = interval(15, 1.0)
    graded.points = np.concatenate([[0.0], np.cumsum(np.linspace(1.0, 3.0, 15))])[:, None]
    assert resolution(graded) == pytest.approx(2.0 / 30.0, rel=1e-12, abs=0)

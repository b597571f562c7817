"""Regions of cells with their own material and initial data (fem/mesh.py regions,
fem/material.py cell_material, Problem(materials=..., initial_regions=..., gravity=...)).

Closed form: a bar A hitting a bar B of another impedance Z = sqrt(E rho) (unit section):
the interface moves at v Z_A / (Z_A + Z_B) and the contact force is v Z_A Z_B / (Z_A + Z_B)
until the first reflected wave returns (2 L / c_A).  Measured with CN + moment-preserving,
Z_A = 2 (E = 4), Z_B = 1: mean force over the middle of that window -2.8% (n = 20), -0.47%
(n = 40), +0.016% (n = 80); largest deviation 8% at n = 40; energy kept to 1.1e-5;
momentum to 1.5e-12.  With the standard mass the energy grows 3.3x.
"""

import json

import numpy as np
import pytest

from signorini.contact.pairs import ContactPair
from signorini.dynamics.model.problem import Problem, RegionInitial, discretize
from signorini.dynamics.stepping.simulate import simulate
from signorini.errors import InputError, MeshError
from signorini.fem.assembly import mass_matrix, stiffness_matrix
from signorini.fem.material import CellMaterial, IsotropicElastic, cell_material
from signorini.fem.mesh import Mesh, interval, join, read_mesh, rectangle, region_ids, write_mesh

SOFT = IsotropicElastic.from_young(10.0, 0.3, 2.0)
HARD = IsotropicElastic.from_young(100.0, 0.25, 1.0)


def plate_and_block(cell: str = "quad") -> Mesh:
    a = rectangle(8, 2, 2.0, 0.5, cell=cell)
    b = rectangle(3, 3, 0.6, 0.6, cell=cell)
    b.points = b.points + [0.7, 0.55]
    return join({"plate": a, "block": b})


def test_join_makes_a_region_per_part_and_files_keep_them(tmp_path):
    m = plate_and_block()
    assert m.regions["plate"].tolist() == list(range(16)) and m.regions["block"].tolist() == list(range(16, 25))
    write_mesh(m, tmp_path / "m.msh")
    r = read_mesh(tmp_path / "m.msh")
    assert {k: v.tolist() for k, v in r.regions.items()} == {k: v.tolist() for k, v in m.regions.items()}
    assert region_ids(r).tolist() == [2] * 16 + [1] * 9  # sorted tags: block 1, plate 2
    with pytest.raises(MeshError, match="unknown region 'ball'"):
        m.cells_of("ball")
    with pytest.raises(MeshError, match="outside"):
        Mesh(m.points, m.cells, m.cell_type, regions={"x": np.array([99])})


def test_gmsh_physical_volumes_become_regions(tmp_path):
    gmsh = pytest.importorskip("gmsh", reason="gmsh is optional (pip install '.[mesh]')")
    gmsh.initialize(["", "-v", "0"])
    try:
        gmsh.model.add("two")
        a = gmsh.model.occ.addBox(0, 0, 0, 1, 1, 0.3)
        b = gmsh.model.occ.addBox(0.3, 0.3, 0.4, 0.4, 0.4, 0.4)
        gmsh.model.occ.synchronize()
        gmsh.model.addPhysicalGroup(3, [a], name="plate")
        gmsh.model.addPhysicalGroup(3, [b], name="cube")
        top = [s for _, s in gmsh.model.getBoundary([(3, a)], oriented=False)]
        gmsh.model.addPhysicalGroup(2, top, name="plate_skin")
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.25)
        gmsh.model.mesh.generate(3)
        gmsh.write(str(tmp_path / "two.msh"))
    finally:
        gmsh.finalize()
    m = read_mesh(tmp_path / "two.msh")
    assert set(m.regions) == {"plate", "cube"} and "plate_skin" in m.facets
    assert m.regions["plate"].size + m.regions["cube"].size == m.n_cells
    from signorini.fem.assembly import cell_volumes

    vol = cell_volumes(m)
    assert abs(vol[m.regions["plate"]].sum() - 0.3) <= 1e-12 and abs(vol[m.regions["cube"]].sum() - 0.064) <= 1e-12


def test_cell_material_and_its_refusals():
    m = plate_and_block()
    assert cell_material(m.n_cells, m.regions, SOFT, {}) is SOFT
    assert cell_material(m.n_cells, m.regions, SOFT, {"plate": SOFT}) is SOFT  # nothing changes: the same run
    cm = cell_material(m.n_cells, m.regions, SOFT, {"plate": HARD})
    assert isinstance(cm, CellMaterial)
    assert np.array_equal(cm.rho, [1.0] * 16 + [2.0] * 9) and np.array_equal(cm.mu[16:], [SOFT.mu] * 9)
    regions = {**m.regions, "both": np.arange(m.n_cells)}
    with pytest.raises(InputError, match="share 16 cell"):
        cell_material(m.n_cells, regions, SOFT, {"plate": HARD, "both": SOFT})
    with pytest.raises(InputError, match="materials\\['ball'\\].*regions: block, plate"):
        Problem(m, SOFT, None, None, materials={"ball": HARD}, pairs=[ContactPair("block_ymin", "plate_ymax")])
    with pytest.raises(InputError, match="initial_regions\\[0\\]"):
        Problem(m, SOFT, None, None, initial_regions=[RegionInitial("ball", velocity=[0, 1])],
                pairs=[ContactPair("block_ymin", "plate_ymax")])  # fmt: skip


@pytest.mark.parametrize("cell", ["quad", "triangle"])
def test_operators_are_the_sum_of_the_regions(cell):
    """S and M of two materials = each region's operator with its own material (assembled on
    the region's cells alone); measured 0 (the same sums in another order: <= 1e-15 max|S|)."""
    m = plate_and_block(cell)
    cm = cell_material(m.n_cells, m.regions, SOFT, {"plate": HARD})
    S = stiffness_matrix(m, cm)
    M = mass_matrix(m, cm.rho)
    parts = {"plate": HARD, "block": SOFT}
    S_sum = sum(stiffness_matrix(Mesh(m.points, m.cells[m.regions[t]], m.cell_type), mat) for t, mat in parts.items())
    M_sum = sum(mass_matrix(Mesh(m.points, m.cells[m.regions[t]], m.cell_type), mat.rho) for t, mat in parts.items())
    assert abs(S - S_sum).max() <= 1e-14 * abs(S).max()
    assert abs(M - M_sum).max() <= 1e-14 * abs(M).max()


def _bars(n: int, mass_right=None) -> Problem:
    L, gap = 1.0, 0.1
    m = join({"left": interval(n, L), "right": interval(n, L, x0=L + gap)})
    A = IsotropicElastic.from_young(4.0, 0.0, 1.0)  # c = 2, Z = 2
    B = IsotropicElastic.from_young(1.0, 0.0, 1.0)  # c = 1, Z = 1
    return Problem(m, A, None, None, materials={"right": B}, initial_regions=[RegionInitial("left", velocity=[1.0])],
                   pairs=[ContactPair("right_xmin", "left_xmax")])  # fmt: skip


def test_bars_of_two_impedances_meet_with_the_closed_form_force():
    n, v, ZA, ZB = 40, 1.0, 2.0, 1.0
    dt = (1.0 / n) / 4  # h / (2 c_A)
    H = simulate(_bars(n), "cn", dt, 0.1 + 2.5)
    assert H.status == "finished", H.message
    F = v * ZA * ZB / (ZA + ZB)
    win = (H.t > 0.1 + 0.25) & (H.t < 0.1 + 0.75)  # the middle of [gap / v, gap / v + 2 L / c_A]
    f = -H.lambda_sum[win]
    assert abs(f.mean() / F - 1) <= 0.01  # measured 0.47%
    assert np.abs(f / F - 1).max() <= 0.15  # measured 8%
    assert abs(H.energy[-1] / H.energy[0] - 1) <= 1e-4  # measured 1.1e-5
    P0 = H.momentum[0, 0]
    assert P0 == pytest.approx(1.0, rel=1e-12, abs=0.0)  # rho L v of the moving bar only
    assert np.abs(H.momentum[:, 0] - P0).max() <= 1e-10 * P0  # measured 1.5e-12
    bodies = H.meta["bodies"]
    assert [b["regions"] for b in bodies] == [["left"], ["right"]]
    assert [b["mass"] for b in bodies] == pytest.approx([1.0, 1.0], rel=1e-12, abs=0.0)
    H_std = simulate(_bars(n), "cn", dt, 0.1 + 2.5, mass="standard")
    assert H_std.energy[-1] / H_std.energy[0] > 2.0  # measured 3.3x


@pytest.mark.parametrize("follow_mass", [True, False])
def test_two_densities_fall_together_at_g_without_stress(follow_mass):
    """gravity is an acceleration: each region weighs its own rho g; a free body of two bonded
    regions of different densities falls at g without stress (moment-preserving and standard
    masses both reproduce constants: M g = int rho g phi)."""
    m = rectangle(4, 4, 1.0, 1.0)
    m.regions = {"top": np.flatnonzero(m.points[m.cells].mean(axis=1)[:, 1] > 0.5)}
    from signorini.contact.obstacles import PlaneObstacle

    p = Problem(m, SOFT, "ymin", PlaneObstacle([0.0, -10.0], [0.0, 1.0]), materials={"top": HARD},
                gravity=[0.0, -9.81], follow_mass=follow_mass)  # fmt: skip
    H = simulate(p, "cn", 0.01, 0.2, mass="standard")
    mass = 0.5 * SOFT.rho + 0.5 * HARD.rho
    assert H.momentum[-1, 1] == pytest.approx(-9.81 * 0.2 * mass, rel=1e-12, abs=0.0)
    u = 0.5 * 9.81 * 0.2**2  # the fall: 1/2 U.SU is round-off of E u^2 (measured 1.3e-15 = 3.5e-16 E u^2)
    assert np.abs(H.elastic_energy).max() <= 1e-14 * HARD.young * u**2


def test_initial_regions_set_the_nodes_of_their_cells():
    m = plate_and_block()
    p = Problem(m, SOFT, None, None, v0=[0.5, 0.0],
                initial_regions=[RegionInitial("block", velocity=[0.0, -1.0], displacement=lambda x: 0 * x + 0.01)],
                pairs=[ContactPair("block_ymin", "plate_ymax")])  # fmt: skip
    d = discretize(p)
    block = m.region_nodes("block")
    V = d.V0.reshape(-1, 2)
    assert np.array_equal(V[block], np.tile([0.0, -1.0], (block.size, 1)))
    others = np.setdiff1d(np.arange(m.n_nodes), block)
    assert np.array_equal(V[others], np.tile([0.5, 0.0], (others.size, 1)))
    assert np.all(d.U0.reshape(-1, 2)[block] == 0.01) and np.all(d.U0.reshape(-1, 2)[others] == 0.0)


CASE = """
[mesh]
file = "two.msh"
[material]
E = 10.0
nu = 0.3
rho = 2.0
regions = [{ tag = "plate", E = 100.0, nu = 0.25, rho = 1.0 }]
[[dirichlet]]
tag = "plate_xmin"
[contact]
pairs = [{ slave = "block_ymin", master = "plate_ymax" }]
[initial]
regions = [{ tag = "block", velocity = [0.0, "-1.0"] }]
[loads]
gravity = [0.0, "-9.81 * min(t / 0.1, 1)"]
[time]
dt = 0.01
T = 0.2
[output]
snapshot_every = 10
"""


def test_case_file_regions(tmp_path):
    from signorini.io.cli import main

    write_mesh(plate_and_block(), tmp_path / "two.msh")
    (tmp_path / "c.toml").write_text(CASE)
    assert main(["run", str(tmp_path / "c.toml"), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    s = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert [(r["tag"], r["id"], r["cells"], r["material"]["E"], r["material"]["listed"]) for r in s["regions"]] == [
        ("block", 1, 9, 10.0, False), ("plate", 2, 16, 100.0, True)]  # fmt: skip
    assert [b["regions"] for b in s["bodies"]] == [["plate"], ["block"]]
    assert [b["mass"] for b in s["bodies"]] == pytest.approx([1.0, 0.72], rel=1e-12, abs=0.0)
    import meshio

    with meshio.xdmf.TimeSeriesReader(str(tmp_path / "out" / "fields.xdmf")) as r:
        r.read_points_cells()
        _, _, cd = r.read_data(1)
    assert cd["region"][0].tolist() == [2] * 16 + [1] * 9 and cd["body"][0].tolist() == [0] * 16 + [1] * 9


@pytest.mark.parametrize(
    "edit, message",
    [
        ('regions = [{ tag = "plate", E = 100.0, nu = 0.25, rho = 1.0 }]', None),
        ('regions = [{ tag = "ball", E = 1.0, rho = 1.0 }]', "'material.regions\\[0\\].tag': 'ball' is not a region"),
        ('regions = [{ tag = "plate", E = 1.0 }]', "missing key 'material.regions\\[0\\].rho'"),
        ('regions = [{ tag = "plate", E = -1.0, rho = 1.0 }]', "material.regions\\[0\\]: material E"),
        ('regions = [{ tag = "plate", E = 1.0, rho = 1.0, colour = 2 }]', "unknown key 'material.regions.0..colour'"),
        ('regions = "plate"', "'material.regions' must be a list"),
    ],
)
def test_case_file_region_refusals(tmp_path, edit, message):
    from signorini.io.config import load_case

    write_mesh(plate_and_block(), tmp_path / "two.msh")
    text = CASE.replace('regions = [{ tag = "plate", E = 100.0, nu = 0.25, rho = 1.0 }]', edit)
    (tmp_path / "c.toml").write_text(text)
    if message is None:
        assert load_case(tmp_path / "c.toml").problem.materials["plate"] == HARD
        return
    with pytest.raises(InputError, match=message):
        load_case(tmp_path / "c.toml")


def test_gravity_may_not_depend_on_x(tmp_path):
    from signorini.io.config import load_case

    write_mesh(plate_and_block(), tmp_path / "two.msh")
    (tmp_path / "c.toml").write_text(CASE.replace('"-9.81 * min(t / 0.1, 1)"', '"-9.81 * x"'))
    with pytest.raises(InputError, match="loads.gravity.*only t"):
        load_case(tmp_path / "c.toml")

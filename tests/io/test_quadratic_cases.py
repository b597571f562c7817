"""Quadratic cells from the command line and case files (issue 54): ``[mesh] order = 2``, ``--set order=2``,
the refusals by name (exit 2, nothing written), a resume bit for bit, two ranks equal to one."""

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from signorini.fem.mesh import rectangle, write_mesh
from signorini.io.cli import main

BAR2D = (
    '[mesh]\ngenerator = "rectangle"\ncells = [2, 8]\nsize = [0.1, 0.4]\n{order}[material]\nrho = 1.0\n'
    'lam = 0.25\nmu = 0.5\n[[dirichlet]]\ntag = "ymax"\nvalue = [0.0, 0.2]\n[contact]\ntag = "ymin"\n'
    'obstacle = {{ type = "plane", point = [0.0, 0.0], normal = [0.0, 1.0] }}\n[initial]\n'
    "displacement = [0.0, 0.2]\nvelocity = [0.0, -1.0]\n[time]\ndt = 0.025\nT = 0.6\n"
)


def _run(capsys, args):
    rc = main(args)
    cap = capsys.readouterr()
    assert "Traceback" not in cap.err + cap.out
    return rc, cap.err


def _case(tmp_path: Path, order: str = "order = 2\n", name: str = "case.toml", mesh: str | None = None) -> Path:
    text = BAR2D.format(order=order)
    if mesh is not None:
        text = text.replace('generator = "rectangle"\ncells = [2, 8]\nsize = [0.1, 0.4]\n', f'file = "{mesh}"\n')
    p = tmp_path / name
    p.write_text(text)
    return p


def test_a_case_file_of_quadratic_cells_runs_and_says_so(tmp_path, capsys):
    rc, _ = _run(capsys, ["run", str(_case(tmp_path)), "--out", str(tmp_path / "o"), "--quiet"])
    assert rc == 0
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert s["dofs"] == 2 * 5 * 17 and s["contact_nodes"] == 5  # the mid-side nodes of the contact side too
    assert s["impacts"] >= 1 and s["energy_identity_residual"] < 1e-12


@pytest.mark.parametrize("order", ["order = 3\n", 'order = "2"\n', "order = true\n", "order = 2.5\n", "order = 2.0\n"])
def test_a_bad_order_is_refused_by_name(tmp_path, capsys, order):
    rc, err = _run(capsys, ["run", str(_case(tmp_path, order)), "--out", str(tmp_path / "o")])
    assert rc == 2 and "'mesh.order' must be 1 (linear cells) or 2 (quadratic cells)" in err
    assert not (tmp_path / "o").exists()


def test_a_mesh_file_is_read_as_it_is_or_elevated(tmp_path, capsys):
    write_mesh(rectangle(2, 8, 0.1, 0.4), tmp_path / "lin.msh")
    write_mesh(rectangle(2, 8, 0.1, 0.4, order=2), tmp_path / "quad.msh")
    a_case = _case(tmp_path, "", "a.toml", "quad.msh")
    rc, _ = _run(capsys, ["run", str(a_case), "--out", str(tmp_path / "a"), "--quiet"])
    assert rc == 0
    rc, _ = _run(capsys, ["run", str(_case(tmp_path, "order = 2\n", "b.toml", "lin.msh")), "--out",
                          str(tmp_path / "b"), "--quiet"])  # fmt: skip
    assert rc == 0
    a, b = (np.genfromtxt(tmp_path / k / "history.csv", delimiter=",", names=True) for k in "ab")
    assert np.array_equal(a["lambda_sum"], b["lambda_sum"])  # the file read as quad9 = the linear one elevated
    rc, err = _run(capsys, ["run", str(_case(tmp_path, "order = 1\n", "c.toml", "quad.msh")), "--out",
                            str(tmp_path / "c")])  # fmt: skip
    assert rc == 2 and "holds quadratic cells (quad9)" in err and not (tmp_path / "c").exists()


@pytest.mark.parametrize("mass", ["seed", "seed-normal", "neighbour"])
def test_masses_not_defined_on_quadratic_cells_are_refused_by_name(tmp_path, capsys, mass):
    rc, err = _run(capsys, ["run", "bar2d", "--set", "order=2", "--n", "1", "--mass", mass, "--out",
                            str(tmp_path / "o")])  # fmt: skip
    assert rc == 2 and f"mass {mass!r} is defined on linear cells only" in err and not (tmp_path / "o").exists()


def test_a_benchmark_order_other_than_one_or_two_is_refused(tmp_path, capsys):
    rc, err = _run(capsys, ["run", "bar1d", "--set", "order=3", "--out", str(tmp_path / "o")])
    assert rc == 2 and "parameter 'order' of 'bar1d' must be 1 (linear cells) or 2 (quadratic cells)" in err


def test_contact_pairs_on_quadratic_cells_run(tmp_path, capsys):
    """examples/block_on_block.toml (two quad9 blocks, Coulomb friction) elevated: the pair's rows take every
    node of the slave side, the run finishes with its identity closed (finite strain's pairs on quadratic cells:
    tests/contact/test_quadratic_pairs.py)."""
    root = Path(__file__).resolve().parents[2] / "examples"
    shutil.copytree(root / "meshes", tmp_path / "meshes")
    text = (
        (root / "block_on_block.toml")
        .read_text()
        .replace('file = "meshes/block_on_block.msh"', 'file = "meshes/block_on_block.msh"\norder = 2')
    )
    text = text.replace('directory = "out/block-on-block"', "").replace("T = 0.12", "T = 0.03")
    case = tmp_path / "bob.toml"
    case.write_text(text)
    rc, _ = _run(capsys, ["run", str(case), "--out", str(tmp_path / "o"), "--quiet"])
    assert rc == 0
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert s["energy_identity_residual"] < 1e-9 and s["impacts"] >= 1 and s["contact_nodes"] == 41


def test_a_resumed_quadratic_run_is_the_uninterrupted_one(tmp_path, capsys):
    case = _case(tmp_path)
    assert _run(capsys, ["run", str(case), "--out", str(tmp_path / "whole"), "--quiet"])[0] == 0
    assert _run(capsys, ["run", str(case), "--T", "0.3", "--checkpoint-every", "5", "--out", str(tmp_path / "half"),
                         "--quiet"])[0] == 0  # fmt: skip
    rest = ["resume", str(tmp_path / "half"), "--T", "0.6", "--out", str(tmp_path / "rest"), "--quiet"]
    assert _run(capsys, rest)[0] == 0
    a = (tmp_path / "whole" / "history.csv").read_text().splitlines()
    b = (tmp_path / "rest" / "history.csv").read_text().splitlines()
    assert a == b


def test_two_ranks_equal_one_on_quadratic_cells(tmp_path):
    root = Path(__file__).resolve().parents[2]
    mpiexec, exe = root / ".venv-mpi" / "bin" / "mpiexec", root / ".venv-mpi" / "bin" / "signorini"
    if not mpiexec.exists():
        pytest.skip("the MPI environment (bash scripts/mpi-env.sh) is not set up")
    args = ["run", "bar2d", "--set", "order=2", "--n", "2", "--T", "0.8", "--quiet"]
    subprocess.run([str(mpiexec), "-n", "2", str(exe), *args, "--backend", "petsc", "--out", str(tmp_path / "p")],
                   check=True, capture_output=True, timeout=300)  # fmt: skip
    subprocess.run([str(exe), *args, "--out", str(tmp_path / "s")], check=True, capture_output=True, timeout=300)
    p, s = (np.genfromtxt(tmp_path / k / "history.csv", delimiter=",", names=True) for k in "ps")
    assert np.abs(s["lambda_sum"]).max() > 0.05  # the bar is in contact
    # measured 3e-13 and 1e-15 relative: a distributed factorization's round-off, which another machine's MPI
    # and BLAS change (docs/parallel.md: ranks agree to 1e-12 .. 1e-10); bound 1e-10
    assert np.allclose(p["lambda_sum"], s["lambda_sum"], rtol=0, atol=1e-10 * np.abs(s["lambda_sum"]).max())
    assert np.allclose(p["energy"], s["energy"], rtol=0, atol=1e-10 * s["energy"][0])


def test_study_of_the_quadratic_2d_bar_against_a_finer_quadratic_reference(tmp_path, capsys):
    """`signorini study bar2d --set order=2` (issue 54): quad9 levels n = 1, 2, 4 against CN + moment-preserving
    on quad9 at n = 16 (4x finer), prolonged with the coarse cells' Q2 shape functions.  Measured: u_H1 0.279,
    0.231, 0.186 (rates 0.27, 0.32), energy_L2 rates 1.07, 1.22; the Q1 levels of the same nodes (n = 2, 4, 8):
    u_H1 0.258, 0.193, 0.139."""
    rc, _ = _run(capsys, ["study", "bar2d", "--set", "order=2", "--levels", "3", "--T", "1", "--quiet",
                          "--out", str(tmp_path / "o")])  # fmt: skip
    assert rc == 0
    result = json.loads((tmp_path / "o" / "study.json").read_text())
    assert result["reference"]["level"] == 16 and "moment-preserving" in result["reference"]["description"]
    assert all(0.15 < r < 0.6 for r in result["rates"]["u_H1"]), result["rates"]["u_H1"]
    assert all(0.8 < r < 1.5 for r in result["rates"]["energy_L2"]), result["rates"]["energy_L2"]
    assert result["rows"][-1]["u_H1"] <= 0.2, result["rows"]


def test_compare_of_the_quadratic_2d_bar_takes_a_reference_it_can_run(tmp_path, capsys):
    """The default reference of compare is CN + seed on linear cells; seed refuses quadratic cells, so there it is
    CN + moment-preserving (the report names it)."""
    rc, _ = _run(capsys, ["compare", "bar2d", "--set", "order=2", "--schemes", "cn", "--masses", "standard",
                          "--levels", "2", "--T", "0.5", "--out", str(tmp_path / "o")])  # fmt: skip
    assert rc == 0
    assert (
        "against the reference crank-nicolson + moment-preserving at n = 8"
        in (tmp_path / "o" / "compare.md").read_text()
    )


def test_study_of_the_quadratic_1d_bar_measures_its_rates(tmp_path, capsys):
    """`signorini study bar1d --set order=2` (issue 54): the P2 bar against its exact solution over one period,
    10, 20, 40 cells, CN, dt = h / 2, the default mass.  Measured: the contact stress's error 0.332, 0.235, 0.169
    (rates 0.50, 0.47), the energy's 5.9e-2 ... 1.5e-2 (rate 0.99), the displacement's L2 rate 0.90, 0.84."""
    rc, _ = _run(capsys, ["study", "bar1d", "--set", "order=2", "--n0", "10", "--levels", "3", "--T", "3",
                          "--out", str(tmp_path / "o"), "--quiet"])  # fmt: skip
    assert rc == 0
    result = json.loads((tmp_path / "o" / "study.json").read_text())
    stress = [r["stress"] for r in result["rows"]]
    assert all(0.35 < r < 0.65 for r in result["rates"]["stress"]), result["rates"]["stress"]
    assert stress[-1] <= 0.2, stress
    assert all(0.8 < r < 1.2 for r in result["rates"]["energy_L2"]), result["rates"]["energy_L2"]


def test_compare_of_the_quadratic_1d_bar_runs_against_its_exact_solution(tmp_path, capsys):
    rc, _ = _run(capsys, ["compare", "bar1d", "--set", "order=2", "--schemes", "cn", "--masses",
                          "moment-preserving,standard", "--levels", "2", "--n0", "10", "--T", "3",
                          "--out", str(tmp_path / "o")])  # fmt: skip
    assert rc == 0
    assert "exact solution" in (tmp_path / "o" / "compare.md").read_text()


def test_compare_runs_a_case_file_of_quadratic_cells(tmp_path, capsys):
    case = _case(tmp_path)
    rc, _ = _run(capsys, ["compare", str(case), "--schemes", "cn,be", "--masses", "standard,moment-preserving",
                          "--out", str(tmp_path / "o")])  # fmt: skip
    assert rc == 0
    assert (tmp_path / "o" / "compare.md").read_text().count("| crank-nicolson |") == 2


def test_spin_benchmark_on_curved_quadratic_cells(tmp_path, capsys):
    """spin2d with --set order=2: the mapped grid's mid-side nodes mapped too (on the circle at the rim)."""
    from signorini.studies.benchmarks import get_benchmark

    mesh = get_benchmark("spin2d").problem(1, {"order": 2}).mesh
    assert mesh.cell_type == "quad9"
    rim = np.linalg.norm(mesh.points, axis=1)
    assert rim.max() == pytest.approx(1.0, rel=1e-14, abs=0)
    mids = mesh.cells[:, 4:8].ravel()  # the mid-side nodes of the boundary sit on the unit circle too
    boundary = np.isclose(np.linalg.norm(mesh.points[mids], axis=1), 1.0, rtol=0, atol=1e-12)
    assert boundary.sum() == 16  # the 4 x 4 grid's 16 boundary edges, each midpoint in one cell
    args = ["run", "spin2d", "--set", "order=2", "--set", "revolutions=0.5", "--n", "1", "--quiet"]
    rc, _ = _run(capsys, [*args, "--out", str(tmp_path / "o")])
    assert rc == 0


@pytest.mark.parametrize("extra", ['model = "neo-hookean"\n', 'friction = { law = "coulomb", coefficient = 0.3 }\n'])
def test_finite_strain_and_friction_on_quadratic_cells(tmp_path, capsys, extra):
    """Neo-Hookean (contact in the current configuration) and Coulomb friction on quad9: the run finishes and its
    energy identity closes (solver_work in it for Newton)."""
    text = _case(tmp_path).read_text()  # a gentler impact (v / c = 0.25, contact at t = 0.17)
    text = text.replace("[0.0, 0.2]", "[0.0, 0.05]").replace("[0.0, -1.0]", "[0.0, -0.3]")
    if "model" in extra:
        text = text.replace("mu = 0.5\n", "mu = 0.5\n" + extra)
    else:
        text = text.replace("normal = [0.0, 1.0] }\n", "normal = [0.0, 1.0] }\n" + extra)
    case = tmp_path / "x.toml"
    case.write_text(text)
    rc, _ = _run(capsys, ["run", str(case), "--out", str(tmp_path / "o"), "--quiet"])
    assert rc == 0
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert s["impacts"] >= 1 and s["energy_identity_residual"] < 1e-12


def test_fields_of_quadratic_cells_are_quadratic_cells_for_vtk(tmp_path, capsys):
    """fields.xdmf holds the quad9 cells: VTK's XDMF reader (ParaView's) makes them biquadratic quads (drawn
    curved), its points ours, and the stress tensors written per cell."""
    rc, _ = _run(capsys, ["run", str(_case(tmp_path)), "--snapshot-every", "8", "--out", str(tmp_path / "o"),
                          "--quiet"])  # fmt: skip
    assert rc == 0
    import meshio

    with meshio.xdmf.TimeSeriesReader(str(tmp_path / "o" / "fields.xdmf")) as r:
        points, cells = r.read_points_cells()
        _, point_data, cell_data = r.read_data(r.num_steps - 1)
    assert [c.type for c in cells] == ["quad9"] and cells[0].data.shape == (16, 9)
    assert {"displacement", "von_mises"} <= set(point_data) and {"cauchy_stress", "strain"} <= set(cell_data)
    vtk = pytest.importorskip("vtkmodules.vtkIOXdmf2", reason="VTK's XDMF reader: pip install '.[vtk]'")
    reader = vtk.vtkXdmfReader()
    reader.SetFileName(str(tmp_path / "o" / "fields.xdmf"))
    reader.Update()
    out = reader.GetOutputDataObject(0)
    assert {out.GetCellType(i) for i in range(out.GetNumberOfCells())} == {28}  # VTK_BIQUADRATIC_QUAD
    assert out.GetNumberOfPoints() == points.shape[0]


def test_a_quadratic_run_says_so_on_its_first_line_and_in_its_summary(tmp_path, capsys):
    """Never change the physics silently: the run's first line and summary.json ``cells`` name the cells."""
    rc = main(["run", "bar2d", "--set", "order=2", "--n", "1", "--T", "0.2", "--out", str(tmp_path / "o")])
    out = capsys.readouterr().out
    assert rc == 0 and "dofs on quadratic cells (quad9)" in out.splitlines()[0]
    cells = json.loads((tmp_path / "o" / "summary.json").read_text())["cells"]
    assert cells == {"types": ["quad9"], "order": 2, "count": 10}
    rc = main(["run", "bar2d", "--n", "1", "--T", "0.2", "--out", str(tmp_path / "l")])
    assert "quadratic" not in capsys.readouterr().out.splitlines()[0]
    assert json.loads((tmp_path / "l" / "summary.json").read_text())["cells"]["order"] == 1

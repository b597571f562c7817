import meshio
import numpy as np
import pytest

from signorini.dynamics.stepping.simulate import simulate
from signorini.io.output import FieldWriter
from signorini.studies.benchmarks import get_benchmark


def test_xdmf_time_series_roundtrip(tmp_path):
    b = get_benchmark("bar3d")
    p = b.problem(2)
    H = simulate(
        p, "cn", b.h(2) / 2, 0.6, mass="seed", snapshot_every=4, observers=[FieldWriter(tmp_path / "f.xdmf", 4)]
    )
    assert (tmp_path / "f.h5").exists()
    with meshio.xdmf.TimeSeriesReader(str(tmp_path / "f.xdmf")) as r:
        points, cells = r.read_points_cells()
        # float64 in HDF5 and the times as repr in the XML: a lossless round trip (measured bit-identical)
        assert np.array_equal(points, p.mesh.points)
        assert r.num_steps == H.snapshots["t"].size
        for k in range(r.num_steps):
            t, pd, _ = r.read_data(k)
            assert t == H.snapshots["t"][k]
            assert np.array_equal(pd["displacement"], H.snapshots["u"][k].reshape(-1, 3))
            assert np.array_equal(pd["velocity"], H.snapshots["v"][k].reshape(-1, 3))
            assert pd["von_mises"].shape == (p.mesh.n_nodes,) and pd["von_mises"].min() >= 0
        # after the impact the bottom carries a compressive pressure
        assert pd["contact_pressure"].max() > 0


def test_the_contact_pressure_of_a_pair_is_written_on_both_sides(tmp_path):
    """A block sliding on a block (a pair with Coulomb friction, re-paired as it slides): the
    master side's pressure and traction are the slave forces carried to the master facet's
    nodes; the total normal force and the total traction over the master surface balance the
    slave side's at every snapshot (action and reaction, to round-off)."""
    import sys
    from pathlib import Path

    from signorini.fem.assembly import facet_weights

    sys.path.insert(0, str(Path(__file__).parents[1]))
    from test_checkpoint import _block_on_block

    p = _block_on_block([1.0, 0.0], True)
    H = simulate(p, "cn", 1e-3, 0.012, observers=[FieldWriter(tmp_path / "f.xdmf", 3)])  # 5 snapshots
    assert H.counters["pair_rows_repaired"] > 0
    (pair,) = p.pairs
    ws, wm = facet_weights(p.mesh, pair.slave), facet_weights(p.mesh, pair.master)
    slave, master = np.flatnonzero(ws > 0), np.flatnonzero(wm > 0)
    assert np.intersect1d(slave, master).size == 0
    seen = 0
    with meshio.xdmf.TimeSeriesReader(str(tmp_path / "f.xdmf")) as r:
        r.read_points_cells()
        for k in range(r.num_steps):
            _, pd, _ = r.read_data(k)
            ps, pm = pd["contact_pressure"][slave] @ ws[slave], pd["contact_pressure"][master] @ wm[master]
            fs = ws[slave] @ pd["contact_traction"][slave]
            fm = wm[master] @ pd["contact_traction"][master]
            scale = max(abs(ps), 1e-300)
            assert abs(ps - pm) <= 1e-12 * scale and np.abs(fs + fm).max() <= 1e-12 * np.abs(fs).max(initial=1e-300)
            seen += ps > 0
    assert seen >= 2  # the blocks press on each other at the snapshots (levels 0, 3, .., 12)


def _field_run(tmp_path):
    b = get_benchmark("bar2d")
    p = b.problem(2)
    simulate(p, "cn", b.h(2) / 2, 0.6, snapshot_every=4, observers=[FieldWriter(tmp_path / "f.xdmf", 4)])
    return p


def test_a_linear_run_writes_the_stress_and_strain_tensors_of_its_cells(tmp_path):
    """Issue 52, item 5: ``cauchy_stress`` and ``strain`` (n_cells, 9) at every time, the cell means of
    :func:`~signorini.fem.assembly.cell_tensors` of the written displacement (plane strain's zz included)."""
    from signorini.fem.assembly import cell_tensors

    p = _field_run(tmp_path)
    with meshio.xdmf.TimeSeriesReader(str(tmp_path / "f.xdmf")) as r:
        r.read_points_cells()
        t, pd, cd = r.read_data(r.num_steps - 1)
    eps, sig = cell_tensors(p.mesh, p.material, pd["displacement"][:, :2].ravel())
    assert np.allclose(cd["cauchy_stress"][0], sig.reshape(-1, 9), rtol=1e-12, atol=1e-12 * np.abs(sig).max())
    assert np.allclose(cd["strain"][0], eps.reshape(-1, 9), rtol=1e-12, atol=1e-12 * np.abs(eps).max())
    assert np.abs(sig[:, 2, 2]).max() > 0 and np.all(eps[:, 2, 2] == 0.0)  # plane strain


def test_the_xdmf_index_is_one_grid_that_vtk_reads_as_one_mesh(tmp_path):
    """Issue 52, item 5: meshio's index held the mesh twice (a grid of its own beside the time series), which
    VTK's XDMF reader (ParaView's, pyvista's) read as a multiblock of two meshes.  Now the domain holds the time
    series only, each step with the mesh's geometry and topology; meshio still reads it, and VTK (when
    installed: the ``vtk`` extra) reads one unstructured grid with every time step."""
    import xml.etree.ElementTree as ET

    p = _field_run(tmp_path)
    domain = ET.parse(tmp_path / "f.xdmf").getroot()[0]
    assert [g.get("GridType") for g in domain] == ["Collection"]
    for step in domain[0]:
        assert {e.tag for e in step} >= {"Geometry", "Topology", "Time", "Attribute"}
    with meshio.xdmf.TimeSeriesReader(str(tmp_path / "f.xdmf")) as r:
        points, cells = r.read_points_cells()
        assert np.array_equal(points[:, :2], p.mesh.points) and r.num_steps == len(domain[0])
    vtk = pytest.importorskip("vtkmodules.vtkIOXdmf2", reason="VTK's XDMF reader: pip install '.[vtk]'")
    from vtkmodules.vtkCommonExecutionModel import vtkStreamingDemandDrivenPipeline

    reader = vtk.vtkXdmfReader()
    reader.SetFileName(str(tmp_path / "f.xdmf"))
    reader.UpdateInformation()
    reader.Update()
    out = reader.GetOutputDataObject(0)
    assert out.GetClassName() == "vtkUnstructuredGrid"
    assert (out.GetNumberOfPoints(), out.GetNumberOfCells()) == (p.mesh.n_nodes, p.mesh.n_cells)
    times = reader.GetOutputInformation(0).Get(vtkStreamingDemandDrivenPipeline.TIME_STEPS())
    assert len(times) == len(domain[0])

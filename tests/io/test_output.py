import meshio
import numpy as np

from signorini.dynamics.simulate import simulate
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

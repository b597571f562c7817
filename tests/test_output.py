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

"""Field output for ParaView: an XDMF + HDF5 time series (meshio)."""

from __future__ import annotations

import contextlib
from pathlib import Path

import numpy as np

from ..dynamics.history import History
from ..dynamics.problem import Problem
from ..fem.assembly import von_mises


def write_fields(path: str | Path, problem: Problem, history: History) -> None:
    """Write displacement, velocity, von Mises stress and contact pressure snapshots.

    Point data per time: ``displacement`` and ``velocity`` (n_nodes, 3, padded with
    zeros below 3D), ``von_mises`` (n_nodes,), ``contact_pressure`` (n_nodes,, zero off
    Gamma_C, positive in compression).  Needs ``simulate(..., snapshot_every=k)``.
    """
    import meshio

    snaps = history.snapshots
    if not snaps:
        raise ValueError("the history holds no field snapshots; run simulate(..., snapshot_every=k)")
    mesh = problem.mesh
    d = mesh.dim
    pts = np.zeros((mesh.n_nodes, 3))
    pts[:, :d] = mesh.points
    contact_nodes = mesh.nodes_of(problem.contact_tag)
    step_of = np.rint(snaps["t"] / (history.t[1] - history.t[0])).astype(int) if history.steps else [0]
    path = Path(path).resolve()
    # meshio writes the HDF5 file next to the current directory: write from the target's
    with contextlib.chdir(path.parent), meshio.xdmf.TimeSeriesWriter(path.name) as w:
        w.write_points_cells(pts, [(mesh.cell_type, mesh.cells)])
        for k, t in enumerate(snaps["t"]):
            u = np.zeros((mesh.n_nodes, 3))
            v = np.zeros((mesh.n_nodes, 3))
            u[:, :d] = snaps["u"][k].reshape(-1, d)
            v[:, :d] = snaps["v"][k].reshape(-1, d)
            p = np.zeros(mesh.n_nodes)
            p[contact_nodes] = history.pressure[step_of[k]]
            vm = von_mises(mesh, problem.material, snaps["u"][k])
            w.write_data(
                float(t),
                point_data={"displacement": u, "velocity": v, "von_mises": vm, "contact_pressure": p},
            )

"""Field output for ParaView: an XDMF + HDF5 time series streamed during the run (meshio).

:class:`FieldWriter` is an observer of the time loop: every ``every`` steps it appends
the fields of the current level to the HDF5 file, so memory does not grow with the
number of snapshots; the last level computed is always written, also when the run is
interrupted or fails; the XDMF index is written when the observer is closed.

Point data per time: ``displacement`` and ``velocity`` (n_nodes, 3, padded with zeros
below 3D), ``von_mises`` (n_nodes,), ``contact_pressure`` (n_nodes,, zero off Gamma_C,
positive in compression, -lambda_i / w_i), ``contact_traction`` (n_nodes, 3): the traction
vector the obstacle exerts, (lambda_i nu_i + lambda_t,i . t_i) / w_i [force / length^(d-1)],
zero off Gamma_C (tangential part with friction only); on the master side of a contact
pair, both from the slave forces carried to the master facet's nodes through its shape
functions, per unit area of the master surface (so ParaView shows the pressure on both
bodies), and ``contact_status`` (n_nodes,), of the contact and slave nodes:
-1 off Gamma_C, 0 separated, 1 stick, 2 slip (without friction: 2 for every node in
contact, nothing holds it tangentially).  Cell data per time: ``region`` (n_cells,): k + 1
for the k-th region tag in sorted order (``summary.json`` ``regions``), 0 for none, and
``body`` (n_cells,): the body of the cell (``summary.json`` ``bodies``, numbered from 0).
Each time also has the cell data ``cauchy_stress`` (n_cells, 9: xx, xy, xz, yx, ... row by row; plane strain's
zz included; 1D: the bar's axial component) and a strain tensor, cell means: the linear model's small strain
``strain``; with finite strain (``[material] model`` not linear) ``green_lagrange`` and
``strain_energy_density`` (n_cells,: the stored energy W per unit reference volume), and ``von_mises`` is the
current configuration's (of the Cauchy stress); the fields stay on the reference mesh with the ``displacement``
(ParaView's Warp By Vector shows the current shape).  The XDMF index holds one grid, the time series, with the
mesh in every time step (:mod:`~.xdmf_index`): ParaView, pyvista and VTK read one mesh.

HDF5 runs in a child process (:mod:`signorini.io.field_process`): a crash inside it, which
a disk filled by another program during a write can cause, ends the run with exit 4 in
one line instead of killing it.  A full disk must not reach the HDF5 library either: once
a write has failed inside it, its metadata cache keeps retrying and closing the file
crashes the process.  Before every
snapshot the writer checks that the file system has room for it (twice its size plus
:data:`HEADROOM`) and keeps a reserve file of :data:`HEADROOM` bytes beside the fields,
released before the HDF5 file is closed so that the final metadata always fits.  When
the room is missing it stops with :class:`OSError` (ENOSPC), which the command line
reports as exit 4 in one line.
"""

from __future__ import annotations

import contextlib
import errno
import os
from pathlib import Path

import numpy as np

from ..dynamics.observe.observers import Observer, Run
from ..dynamics.schemes import State
from ..fem.assembly import cell_means, nodal_average
from ..fem.mesh import bodies, region_ids
from ..fem.node_order import to_user_nodes

#: bytes kept free for the HDF5 file's metadata and the XDMF index [B]
HEADROOM = 4 * 2**20


def _free_bytes(path: Path) -> int:
    st = os.statvfs(path)
    return st.f_bavail * st.f_frsize


def _no_space() -> OSError:
    return OSError(
        errno.ENOSPC, f"No space left on device while streaming fields ({HEADROOM // 2**20} MiB headroom kept)"
    )


def check_fields(source: Path) -> None:
    """InputError (one line) when a result's ``fields.xdmf`` (with its ``fields.h5``) cannot be
    read to its last snapshot: a resumed run copies them, and must refuse before it starts
    rather than fail midway (missing, truncated or edited files)."""
    import re
    import stat

    import meshio

    from ..errors import InputError

    h5 = source.with_suffix(".h5")
    for f in (source, h5):  # a FIFO or a device would block or never end: regular files only
        try:
            regular = stat.S_ISREG(f.lstat().st_mode)
        except OSError:
            regular = False
        if not regular:
            raise InputError(
                f"the fields of the run to resume: {str(f)!r} is missing or not a regular file; "
                "resume with --snapshot-every 0 to leave the earlier fields out"
            )
    text = source.read_text(errors="replace")
    formats = set(re.findall(r'Format="([^"]*)"', text))
    files = {m.split(":")[0].strip() for m in re.findall(r">\s*([^<>\s]+:/[^<>\s]*)\s*<", text)}
    if formats - {"HDF"} or files - {h5.name}:
        raise InputError(
            f"the fields of the run to resume: {source.name} reads other data than its {h5.name} "
            f"(formats {sorted(formats)}, files {sorted(files)}): not a field file of signorini; resume "
            "with --snapshot-every 0 to leave the earlier fields out"
        )
    try:
        with meshio.xdmf.TimeSeriesReader(str(source)) as reader:
            reader.read_points_cells()
            for k in range(reader.num_steps):
                reader.read_data(k)
    except Exception as exc:  # meshio and h5py raise many kinds (OSError, ParseError, KeyError, ...)
        first = (str(exc).splitlines() or [""])[0][:200]
        raise InputError(
            f"the fields of the run to resume ({source.name} and {source.with_suffix('.h5').name} in "
            f"{str(source.parent)!r}) cannot be read ({type(exc).__name__}: {first}); the checkpoint is intact: "
            "resume with --snapshot-every 0 to leave the earlier fields out, or restore the files"
        ) from None


class FieldWriter(Observer):
    """Stream displacement, velocity, von Mises stress and contact pressure to XDMF."""

    def __init__(self, path: str | Path, every: int = 1):
        self.path = Path(path).resolve()
        self.every = max(int(every), 1)
        self.times: list[float] = []
        self._writer = None
        self._last = -1
        self._reserve = self.path.with_name(f".{self.path.stem}.reserve")
        self._snapshot_bytes = 0

    def _hold_reserve(self) -> None:
        try:
            with open(self._reserve, "wb") as f:
                os.posix_fallocate(f.fileno(), 0, HEADROOM)
        except OSError as exc:
            self._release_reserve()
            if exc.errno in (errno.ENOSPC, errno.EDQUOT):
                raise _no_space() from None
            if exc.errno not in (errno.EOPNOTSUPP, errno.EINVAL):
                raise

    def _release_reserve(self) -> None:
        with contextlib.suppress(OSError):
            self._reserve.unlink()

    def _check_room(self) -> None:
        if _free_bytes(self.path.parent) < 2 * self._snapshot_bytes + HEADROOM:
            raise _no_space()

    def start(self, run: Run) -> None:
        from .field_process import FieldProcess

        mesh = run.problem.mesh
        self._mesh, self._material = mesh, run.ctx.disc.material  # per cell with regions
        # every cell's region (k + 1: the k-th region tag in sorted order, 0: none) and body
        ids, body = region_ids(mesh), bodies(mesh)[mesh.first_nodes()]
        self._cell_data = {
            "region": [ids[b.start : b.stop] for b in mesh.blocks],
            "body": [body[b.start : b.stop] for b in mesh.blocks],
        }
        self._nodes = run.ctx.disc.contact.nodes
        self._elastic = getattr(run.ctx, "elastic", None)
        self._weights = run.ctx.disc.contact.weights
        self._contact = run.ctx.disc.contact
        self._dofmap = run.ctx.disc.space.dofmap
        # the master sides of the pairs: their nodal weights (the pressure there is the slave
        # forces carried to the master facet's nodes, per unit area of the master surface)
        self._master_weights = None
        if self._contact.has_pair_rows:
            from ..fem.assembly import facet_weights

            masters = sorted({p.master for p in run.problem.pairs})
            self._master_weights = sum(facet_weights(mesh, tag) for tag in masters)
        pts = np.zeros((mesh.n_nodes, 3))
        pts[:, : mesh.dim] = mesh.points
        # displacement, velocity, traction (n, 3) and three scalars per node, in double precision
        self._snapshot_bytes = 8 * 12 * mesh.n_nodes
        self._hold_reserve()
        self._snapshot_bytes += pts.nbytes + sum(b.cells.nbytes for b in mesh.blocks)
        # HDF5 runs in a child process: a crash inside it (the disk filled by another program
        # during a write) costs the fields, not the run (:mod:`signorini.io.field_process`)
        try:
            self._check_room()
            self._writer = FieldProcess(self.path)
            user = (lambda c: c) if mesh.node_ids is None else (lambda c: mesh.node_ids[c])  # the user's numbers
            self._writer.mesh(to_user_nodes(mesh, pts), [(b.cell_type, user(b.cells)) for b in mesh.blocks])
            self._write(0, run.initial)
        except BaseException:  # a failed write, or a signal: this observer was not started, so
            if self._writer is not None:  # nobody else will end its child
                self._writer.abandon()
            self._writer = None
            self._release_reserve()
            raise

    def _write(self, n: int, s: State) -> None:
        self._check_room()
        mesh, d = self._mesh, self._mesh.dim
        u = np.zeros((mesh.n_nodes, 3))
        v = np.zeros((mesh.n_nodes, 3))
        u[:, :d] = s.U.reshape(-1, d)
        v[:, :d] = s.V.reshape(-1, d)
        p = np.zeros(mesh.n_nodes)
        p[self._nodes] = -s.lam / self._weights
        cell_data = self._cell_data
        elastic = self._elastic
        if elastic is not None and elastic.finite:  # the current configuration's stress (finite strain)
            from ..fem.hyperelastic import von_mises_of

            f = elastic.cell_fields(s.U)
            vm = nodal_average(mesh, von_mises_of(f["cauchy_stress"]))
            per_block = lambda a: [a[b.start : b.stop] for b in mesh.blocks]  # noqa: E731
            cell_data = {
                **cell_data,
                "cauchy_stress": per_block(f["cauchy_stress"].reshape(-1, 9)),
                "green_lagrange": per_block(f["green_lagrange"].reshape(-1, 9)),
                "strain_energy_density": per_block(f["strain_energy_density"]),
            }
        else:  # the small strain and the Cauchy stress of the linear model, cell means
            vm, eps, sig = cell_means(mesh, self._material, s.U)
            vm = nodal_average(mesh, vm)
            cell_data = {
                **cell_data,
                "cauchy_stress": [sig.reshape(-1, 9)[b.start : b.stop] for b in mesh.blocks],
                "strain": [eps.reshape(-1, 9)[b.start : b.stop] for b in mesh.blocks],
            }
        c = self._contact
        traction = np.zeros((mesh.n_nodes, 3))
        force = c.normals * s.lam[:, None]
        if s.lam_t is not None and s.lam_t.size:
            force = force + np.einsum("ik,ikd->id", s.lam_t, c.tangents)
        traction[self._nodes, :d] = force / self._weights[:, None]
        if self._master_weights is not None:
            self._add_master_side(p, traction, force, s.lam)
        status = np.full(mesh.n_nodes, -1.0)
        info_status = s.info.status if s.info is not None else None
        status[self._nodes] = info_status if info_status is not None else np.where(s.lam < 0, 2.0, 0.0)
        data = {
            "displacement": u,
            "velocity": v,
            "von_mises": vm,
            "contact_pressure": p,
            "contact_traction": traction,
            "contact_status": status,
        }
        data = {k: to_user_nodes(mesh, a) for k, a in data.items()}  # a renumbered mesh: the user's order
        try:
            self._writer.data(float(s.t), data, cell_data)
        except OSError:  # the child failed or died: it never touches the file again
            self._writer = None
            self._release_reserve()
            raise
        self.times.append(float(s.t))
        self._last = n

    def _add_master_side(self, p: np.ndarray, traction: np.ndarray, force: np.ndarray, lam: np.ndarray) -> None:
        """The pairs' master sides: node j of the master facet a slave row i faces carries
        -N_j(xi_i) f_i (the slave's force f_i = lambda_i nu_i + ..., the reaction), so its pressure
        is sum_i N_j(xi_i) (-lambda_i) / w_j and its traction -sum_i N_j(xi_i) f_i / w_j, with w_j
        the master surface's nodal weight (the pairing of the current level, after sliding)."""
        c, d = self._contact, self._mesh.dim
        rows = np.flatnonzero(c.pair >= 0)
        dofs = c.master_dofs[rows][:, :, 0]  # (r, nfv): the first dof of each master node
        ok = dofs >= 0
        nodes = self._dofmap.nodes_of(dofs[ok])
        share = c.master_shape[rows][ok]  # N_j(xi_i)
        lam = np.broadcast_to(lam[rows][:, None], dofs.shape)[ok]
        f = np.broadcast_to(force[rows][:, None, :], dofs.shape + (d,))[ok]
        w = self._master_weights[nodes]
        w = np.where(w > 0, w, 1.0)
        np.add.at(p, nodes, -share * lam / w)
        np.add.at(traction[:, :d], nodes, -share[:, None] * f / w[:, None])

    def record(self, run: Run, n: int, state: State) -> None:
        if n % self.every == 0:
            self._write(n, state)

    def copy_from(self, source: Path, times: np.ndarray | None, n: int) -> None:
        """Append the snapshots of another result's ``source`` (fields.xdmf) at the levels
        1..n that are multiples of ``every`` (a resumed run: the levels of the run it continues,
        whose times are ``times``; level 0 is this run's own, the same)."""
        import meshio

        if times is None or len(times) < n + 1:
            return
        times = np.asarray(times[: n + 1], dtype=float)
        tol = 1e-9 * max(float(np.abs(times).max()), 1e-300)
        with meshio.xdmf.TimeSeriesReader(str(source)) as reader:
            reader.read_points_cells()
            for k in range(reader.num_steps):
                t, point_data, cell_data = reader.read_data(k)
                level = int(np.argmin(np.abs(times - float(t))))
                if 0 < level <= n and level % self.every == 0 and abs(times[level] - float(t)) <= tol:
                    self._check_room()
                    self._writer.data(float(t), dict(point_data), {k: list(v) for k, v in cell_data.items()})
                    self.times.append(float(t))
                    self._last = level

    def close(self, run: Run, status: str, n_last: int, state: State) -> None:
        if self._writer is None:
            return
        try:
            if self._last != n_last:
                self._write(n_last, state)
        except BaseException:
            if self._writer is not None:
                self._writer.abandon()
            raise
        finally:
            self._release_reserve()
            if self._writer is not None and not self._writer.closed:
                self._writer.close()
            self._writer = None

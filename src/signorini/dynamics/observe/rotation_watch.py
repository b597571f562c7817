"""The linear model says when it is wrong: watch the rotation of its cells.

Linear elasticity measures strain by eps = sym(grad u): a rigid rotation by an angle theta
stretches the body by about theta^2 / 2 and a spin is not kept (a ring thrown spinning turns
its rotation into a stretch; measured: at 40 rad/s its spin reverses and it rebounds 25%
faster than the Neo-Hookean ring).  The theory holds while the rotations stay small; the
watch measures, at every level, each linear cell's mean infinitesimal rotation

    theta_e = |axial(W_e)|,   W_e = skew(grad u) averaged over the cell
            = 1/|e| int_e (grad u - grad u^T) / 2 dX                       [rad]

(2D: |W_12|; 3D: sqrt(W_12^2 + W_13^2 + W_23^2), the angle of the small rotation
I + W).  Above :data:`ROTATION_LIMIT` the run warns once in ``summary.json`` ``warnings``,
naming the rotation, its cell, the time it was first exceeded and the remedy
(``model = "neo-hookean"``); ``rotation_max``, ``rotation_cell`` and ``rotation_time``
report the largest rotation of the run and when.  Cells of a finite-strain model are not
watched (they rotate exactly); 1D bodies do not rotate.

Cost: one sparse product per level, R U (:func:`rotation_operator`, made once: 2 nv nonzeros per
cell and component).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import scipy.sparse as sp

from ...errors import InputError
from ...fem.assembly import geometry, gradient_operator
from ..schemes import State
from .observers import Observer, Run

#: rotations within this fraction of the largest are a tie for the cell (and level) a message names: mirror cells of
#: a symmetric body differ by the run's round-off, which a chattering contact amplifies (bar3d n = 4 with the lumped
#: mass: 5e-9 between SuperLU and 2 ranks' MUMPS, which named cells 3 and 0 with 1e-9)
TIE = 1e-6
#: the largest mean cell rotation [rad] within the small-rotation range of the linear model (the stretch it makes,
#: about theta^2 / 2, is then 1.25e-3); the solver option ``rotation_limit`` sets another
ROTATION_LIMIT = 0.05


def rotation_operator(mesh) -> sp.csr_matrix:
    """R (n_cells k, n_nodes d) [1/length], k = 1 (2D) or 3 (3D): R U gives every cell's mean infinitesimal rotation
    vector, w_e = axial(1/|e| int_e skew(grad u) dX), row e k + c its component c ((1, 2) in 2D; (2, 3), (1, 3),
    (1, 2) in 3D), from the cell-averaged shape gradients Gbar_ea = sum_q w_q |det J_eq| grad N_a(x_q) / |e|:
    w_(ij) = 1/2 sum_a (u_ai Gbar_eaj - u_aj Gbar_eai).  ``U`` node-major."""
    d = mesh.dim
    pairs = [(0, 1)] if d == 2 else [(1, 2), (0, 2), (0, 1)]
    blocks = []
    for part, _ in mesh.parts():
        wdet, G = geometry(part)
        Gbar = np.einsum("eq,eqad->ead", wdet, G) / wdet.sum(axis=1)[:, None, None]
        D = gradient_operator(part.cells, Gbar, mesh.n_nodes)  # the cells' mean grad u, rows (e, i, J)
        e = np.arange(part.n_cells)
        # rows (e, c): 1/2 (D_(e,i,j) - D_(e,j,i)) for the component c = (i, j), 2 nv nonzeros each
        ij = [np.ravel_multi_index((e, np.full_like(e, i), np.full_like(e, j)), (e.size, d, d)) for i, j in pairs]
        ji = [np.ravel_multi_index((e, np.full_like(e, j), np.full_like(e, i)), (e.size, d, d)) for i, j in pairs]
        blocks.append(0.5 * (D[np.column_stack(ij).ravel()] - D[np.column_stack(ji).ravel()]))
    return sp.vstack(blocks, format="csr")


def cell_rotations(R: sp.csr_matrix, U: np.ndarray, n_cells: int) -> np.ndarray:
    """(n_cells,) each cell's mean infinitesimal rotation |w_e| [rad] (module docstring; ``R`` from
    :func:`rotation_operator`)."""
    w = (R @ np.asarray(U, dtype=float)).reshape(n_cells, -1)
    return np.sqrt(np.einsum("ec,ec->e", w, w)) if w.shape[1] > 1 else np.abs(w[:, 0])


class RotationWatch(Observer):
    """The largest cell rotation of the linear cells per level, and the first level above
    :data:`ROTATION_LIMIT` (module docstring)."""

    checkpoint_key = "rotation"

    def __init__(self, limit: float = ROTATION_LIMIT):
        self.limit = limit
        self.active = False
        #: (rotation [rad], cell, t) of the largest rotation so far, and of the first level above the limit
        self.worst: tuple[float, int, float] = (0.0, -1, 0.0)
        self.first: tuple[float, int, float] = (0.0, -1, 0.0)

    def start(self, run: Run) -> None:
        mesh = run.ctx.disc.problem.mesh
        self.d, self.n_cells = mesh.dim, mesh.n_cells
        elastic = run.ctx.elastic
        linear = np.ones(mesh.n_cells, dtype=bool)
        if elastic.finite:
            mask = getattr(elastic, "hyperelastic", None)
            linear = np.zeros(mesh.n_cells, dtype=bool) if mask is None else ~np.asarray(mask, dtype=bool)
        self.active = self.d >= 2 and bool(linear.any())
        if not self.active:
            return
        self.R = rotation_operator(mesh)
        self.mesh = mesh
        self.linear = None if linear.all() else np.flatnonzero(linear)
        self._put(run.initial)

    def _put(self, s: State) -> None:
        theta = cell_rotations(self.R, s.U, self.n_cells)
        if self.linear is not None:
            theta, ids = theta[self.linear], self.linear
        else:
            ids = None
        value = float(theta.max(initial=0.0))
        tie = TIE * value
        # among the cells within a tie of the largest (mirror cells of a symmetric body: their round-off differs
        # between ranks and node orders) the first, so that the cell named does not depend on them
        k = int(np.flatnonzero(theta >= value - tie)[0])
        cell = int(k if ids is None else ids[k])
        if self.worst[1] < 0 or value > self.worst[0] + TIE * self.worst[0]:  # its cell and time beyond a tie only
            self.worst = (value, cell, float(s.t))
        elif value > self.worst[0]:
            self.worst = (value, *self.worst[1:])
        if value > self.limit and self.first[1] < 0:
            self.first = (value, cell, float(s.t))

    def record(self, run: Run, n: int, state: State) -> None:
        if self.active:
            self._put(state)

    def saved(self, n: int) -> dict[str, Any]:
        return {"worst": list(self.worst), "first": list(self.first)}

    def resume(self, run: Run, n: int, state: State, data: dict[str, Any]) -> None:
        # a checkpoint written before the watch: the rotations of its levels were not seen
        self.worst = self._checked(data.get("worst", [0.0, -1, 0.0]), "largest")
        self.first = self._checked(data.get("first", [0.0, -1, 0.0]), "first")

    def _checked(self, value: Any, what: str) -> tuple[float, int, float]:
        """A checkpoint's (rotation, cell, t), checked (a forged file: a one-line InputError)."""
        numbers = (
            isinstance(value, list)
            and len(value) == 3
            and all(isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x) for x in value)
        )
        if not (numbers and value[0] >= 0 and isinstance(value[1], int) and -1 <= value[1] < self.n_cells):
            raise InputError(
                f"checkpoint: the rotation watch's {what} rotation {value!r} is not [rotation >= 0 "
                "(rad), a cell of the mesh or -1, t]"
            )
        return float(value[0]), int(value[1]), float(value[2])

    def _centre(self, cell: int) -> str:
        """The reference centre of ``cell`` (its nodes' mean), for a message."""
        for part, cut in self.mesh.parts():
            if cut.start <= cell < cut.stop:
                x = self.mesh.points[part.cells[cell - cut.start]].mean(axis=0)
                return "(" + ", ".join(f"{v:.4g}" for v in x) + ")"
        return "?"

    def summary(self, meta: dict[str, Any]) -> None:
        """``rotation_max`` [rad], ``rotation_cell`` (its index in the mesh's cells), ``rotation_time`` [time] and,
        above the limit, the warning; nothing when no cell is watched."""
        if not self.active:
            return
        value, cell, t = self.worst
        meta.update(
            rotation_max=value, rotation_cell=cell if cell >= 0 else None, rotation_time=t if cell >= 0 else None
        )
        if self.first[1] >= 0:
            v1, c1, t1 = self.first
            meta["warnings"].append(
                f"the linear model (small strains) is outside its range: cell {c1} (centre {self._centre(c1)}) "
                f"rotated {v1:.3g} rad at t = {t1:.6g} (above rotation_limit = {self.limit:g} rad; the largest, "
                f"{value:.3g} rad, at t = {t:.6g}); a linear model takes a rotation for a stretch and does not keep a "
                'spin: use model = "neo-hookean" (finite strain, docs/finite_strain.md)'
            )

"""Columns of the Delassus matrix W = B K^-1 B^T, computed when a contact node needs them.

For the factorized operator K (n x n) and the contact matrix B (nc x n, one unit
normal per row), column j of Z = K^-1 B^T costs one forward/backward substitution and
gives column j of W = B Z.  :class:`DelassusColumns` computes them in blocks of 64
for the nodes asked for, keeps the W columns (nc per node) and, while they fit in a
byte budget, the Z columns (n per node), so that

* set-up costs one factorization, not nc solves;
* a contact solve costs solves only for nodes that come into contact for the first
  time, and memory O((nc + n) m) for the m nodes that ever did (nc m for W, n m for Z
  while it fits in the budget).

``eager=True`` computes every column at once (the classical full condensation).
"""

from __future__ import annotations

import hashlib
import time

import numpy as np
import scipy.sparse as sp

BLOCK = 64


class DelassusColumns:
    """W[:, j] (and Z[:, j] within ``budget`` bytes) for the contact nodes j asked for.

    Parameters
    ----------
    factor : a :class:`~signorini.linalg.Factor` of K.
    B : (nc, n) sparse contact matrix.
    budget : bytes allowed for the stored Z columns; beyond it Z is dropped and
        callers recover displacements with one more solve.
    """

    def __init__(self, factor, B: sp.csr_matrix, budget: float):
        self.factor = factor
        self.B = sp.csr_matrix(B)
        nc, n = self.B.shape
        self.Bt = self.B.T.tocsc()
        self.budget = float(budget)
        self.slot = np.full(nc, -1, dtype=np.intp)  # column slot of each node, -1: not computed
        self.count = 0  # slots in use (computed columns, and freed slots awaiting reuse)
        self.solved = 0  # columns solved (a column solved again after its row changed counts again)
        self._free: list[int] = []  # slots of columns dropped by replace_rows
        self._W = np.empty((nc, 0))
        # Z stored transposed, one row per computed column: gathering the active columns
        # then reads contiguous memory
        self._Zt: np.ndarray | None = np.empty((0, self._rows()))
        self.seconds = 0.0
        #: what changed the columns, in order (:meth:`replay` redoes it): ("solve", nodes, slots) of
        #: each block solved, ("rows", rows, B'[rows]) of each :meth:`replace_rows`
        self.log: list[tuple[str, np.ndarray, np.ndarray | sp.csr_matrix]] = []
        self.replayed = 0  # columns solved again by :meth:`replay`
        self._origin = _digest(self.B)  # the rows the log starts from (a replay needs the same)
        self._origin_B = self.B  # those rows (a system made after a re-pairing starts from them on resume)
        self._digest_B = self._origin  # the digest of the current B
        # K^-1 e_k of the dofs k that re-paired rows moved to or from (:meth:`replace_rows`),
        # stored transposed like Z: a re-paired row's column is updated from them, not solved
        self._dof_slot = np.full(n, -1, dtype=np.intp)
        self._Zd = np.empty((0, self._rows()))
        self.dof_columns = 0  # dof columns solved (counted in ``solved`` too)
        #: a rejected step's rollback (:class:`ColumnsUndo`)
        self.undo = ColumnsUndo(self)

    def _rows(self) -> int:
        """Rows of a stored Z column (n; a rank's own rows on a distributed factor)."""
        return self.B.shape[1]

    def _budget_rows(self) -> int:
        """Rows of a Z column as the byte budget counts them (the same figure on every rank
        of a distributed factor, so that all of them keep or drop Z together)."""
        return self._rows()

    def _solve_block(self, J: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(Z[:, J], W[:, J]) for the nodes J: one solve with |J| right-hand sides."""
        Zj = self.factor.solve(self.Bt[:, J].toarray()).reshape(self.B.shape[1], -1)
        return Zj, self.B @ Zj

    @property
    def keeps_Z(self) -> bool:
        """Whether the Z columns of every computed node are stored."""
        return self._Zt is not None

    #: whether :meth:`replace_rows` updates the stored columns of re-paired rows from cached
    #: dof columns (False: they are dropped and solved again when asked for)
    updates_columns = True

    @property
    def nbytes(self) -> int:
        return self._W.nbytes + (self._Zt.nbytes if self._Zt is not None else 0) + self._Zd.nbytes

    def _grow(self, need: int) -> None:
        """Room for ``need`` columns: W grows by doubling (at most nc); Z gets its own
        capacity, at most the columns that fit in the budget, and is dropped (W kept)
        when ``need`` exceeds that."""
        nc, n = self.B.shape[0], self._rows()
        cap = self._W.shape[1]
        if need > cap:
            cap = min(nc, max(need, 2 * cap, BLOCK))
            W = np.empty((nc, cap))
            W[:, : self.count] = self._W[:, : self.count]
            self._W = W
        if self._Zt is None or need <= self._Zt.shape[0]:
            return
        z_max = int(self.budget // (8 * max(self._budget_rows(), 1))) - self._Zd.shape[0]  # the dof columns' share
        if need > z_max:
            self._Zt = None  # does not fit: keep W only, one more solve per contact step
            self._Zd, self._dof_slot[:] = np.empty((0, n)), -1  # nor the dof columns (Z's updates)
            return
        Zt = np.empty((min(z_max, max(need, 2 * self._Zt.shape[0], BLOCK), nc), n))
        Zt[: self.count] = self._Zt[: self.count]
        self._Zt = Zt

    def ensure(self, nodes: np.ndarray, fill: np.ndarray | None = None) -> None:
        """Compute the columns of ``nodes`` (indices) that are not known yet.

        ``fill``: nodes in order of priority (e.g. nearest to contact first) used to top
        the last block up to 64 columns: a block of right-hand sides costs little more
        than one, so the nodes likely to be asked for next come almost for free.
        """
        new = np.asarray(nodes, dtype=np.intp)
        new = np.unique(new[self.slot[new] < 0])
        if new.size == 0:
            return
        if fill is not None and new.size % BLOCK:
            extra = np.asarray(fill, dtype=np.intp)
            extra = extra[(self.slot[extra] < 0) & ~np.isin(extra, new)]
            new = np.concatenate([new, extra[: BLOCK - new.size % BLOCK]])
        t0 = time.perf_counter()
        reuse = min(len(self._free), new.size)
        fresh = new.size - reuse
        self._grow(self.count + fresh)
        slots = np.concatenate(
            [np.asarray(self._free[:reuse], dtype=np.intp), np.arange(self.count, self.count + fresh, dtype=np.intp)]
        )
        del self._free[:reuse]
        self.count += fresh
        for k in range(0, new.size, BLOCK):
            J = new[k : k + BLOCK]
            Zj, Wj = self._solve_block(J)
            s = slots[k : k + BLOCK]
            self._W[:, s] = Wj
            if self._Zt is not None:
                self._Zt[s] = Zj.T
            self.slot[J] = s
            self.solved += J.size
            self.log.append(("solve", J.copy(), s.copy()))
        self.seconds += time.perf_counter() - t0

    def history(self, blocks: int | None = None) -> dict[str, np.ndarray]:
        """What changed the columns so far (or its first ``blocks`` entries), for a checkpoint:
        the blocks solved (nodes, slots, block sizes) and, when B's rows changed (re-pairing),
        each change in order (``kinds``: 0 a block, 1 a change; its rows and their new
        entries), and a digest of the rows the log starts from."""
        log = self.log if blocks is None else self.log[:blocks]
        solves = [e for e in log if e[0] == "solve"]
        changes = [e for e in log if e[0] == "rows"]

        def cat(items, dtype=np.int64):
            return np.concatenate(items).astype(dtype) if items else np.zeros(0, dtype)

        O = self._origin_B
        out = {
            "nodes": cat([e[1] for e in solves]),
            "slots": cat([e[2] for e in solves]),
            "sizes": np.array([e[1].size for e in solves], dtype=np.int64),
            "origin": np.frombuffer(self._origin, dtype=np.uint8).copy(),
            "origin_indptr": O.indptr.astype(np.int64),
            "origin_indices": O.indices.astype(np.int64),
            "origin_data": O.data.astype(np.float64),
        }
        if changes:
            out["kinds"] = np.array([e[0] == "rows" for e in log], dtype=np.int8)
            out["rows"] = cat([e[1] for e in changes])
            out["row_sizes"] = np.array([e[1].size for e in changes], dtype=np.int64)
            out["row_nnz"] = cat([np.diff(e[2].indptr) for e in changes])
            out["row_indices"] = cat([e[2].indices for e in changes])
            out["row_data"] = cat([e[2].data for e in changes], np.float64)
        return out

    def replay(self, data: dict[str, np.ndarray]) -> bool:
        """Redo the log of :meth:`history`: the same blocks of right-hand sides in the same slots,
        and B's row changes at the same moments, so that the columns, their slots and every
        product that sums over them are those of the run that wrote the checkpoint, bit for bit
        (a resumed run).  False (nothing done) when this run's columns start from other rows
        of B than the log's (an operator factorized after a re-pairing)."""
        nodes, slots, sizes = (np.asarray(data[k], dtype=np.intp) for k in ("nodes", "slots", "sizes"))
        origin = data.get("origin")
        if origin is not None and np.asarray(origin, dtype=np.uint8).tobytes() != self._origin:
            if not self._start_from(data, np.asarray(origin, dtype=np.uint8).tobytes()):
                return False
        nc, n = self.B.shape
        kinds = np.asarray(data.get("kinds", np.zeros(sizes.size, np.int8)), dtype=np.intp)
        rows_all, row_sizes, row_nnz, row_indices, row_data = (
            np.asarray(data.get(k, np.zeros(0)), dtype=float if k == "row_data" else np.intp)
            for k in ("rows", "row_sizes", "row_nnz", "row_indices", "row_data")
        )
        counts_ok = all(
            a.ndim == 1 and (a.size == 0 or a.min() >= low)
            for a, low in ((sizes, 1), (row_sizes, 1), (row_nnz, 0), (kinds, 0))
        )
        finite = bool(np.all(np.isfinite(row_data))) and (kinds.size == 0 or int(kinds.max()) <= 1)
        if not counts_ok or not finite:
            raise ValueError("the Delassus column log is inconsistent (negative counts or unknown entries)")
        if (
            nodes.shape != slots.shape
            or sizes.sum() != nodes.size
            or (nodes.size and (nodes.min() < 0 or nodes.max() >= nc or slots.min() < 0 or slots.max() >= nc))
            or (
                np.count_nonzero(kinds == 0) != sizes.size
                or np.count_nonzero(kinds == 1) != row_sizes.size
                or kinds.size != sizes.size + row_sizes.size
                or row_sizes.sum() != rows_all.size
                or row_nnz.size != rows_all.size
                or row_nnz.sum() != row_indices.size
                or row_indices.size != row_data.size
                or (rows_all.size and (rows_all.min() < 0 or rows_all.max() >= nc))
                or (row_indices.size and (row_indices.min() < 0 or row_indices.max() >= n))
            )
        ):
            raise ValueError("the Delassus column log is inconsistent")
        t0 = time.perf_counter()
        start = rstart = nzstart = 0
        blocks, changes = iter(sizes), iter(row_sizes)
        done = list(self.log)  # blocks this run solved already (the set-up's): not again
        for kind in kinds:
            if kind == 1:
                size = next(changes)
                rows = rows_all[rstart : rstart + size]
                nnz = row_nnz[rstart : rstart + size]
                rstart += size
                stop = nzstart + int(nnz.sum())
                R = sp.csr_matrix(
                    (row_data[nzstart:stop], row_indices[nzstart:stop], np.concatenate([[0], np.cumsum(nnz)])),
                    shape=(size, n),
                )
                R.check_format(full_check=True)  # a forged log must not reach scipy's C code malformed
                nzstart = stop
                if done:
                    raise ValueError("the Delassus column log does not start with this run's set-up columns")
                solved = self.solved
                self.replace_rows(rows, _with_rows(self.B, rows, R))
                self.replayed += self.solved - solved  # not in ``solved``: the run that wrote the log counted them
                self.solved = solved
                continue
            size = next(blocks)
            J, s = nodes[start : start + size], slots[start : start + size]
            start += size
            if done:
                k0, J0, s0 = done.pop(0)
                if k0 == "solve" and np.array_equal(J0, J) and np.array_equal(s0, s):
                    continue
                raise ValueError("the Delassus column log does not start with this run's set-up columns")
            self._grow(max(self.count, int(s.max()) + 1))
            self.count = max(self.count, int(s.max()) + 1)
            taken = set(s.tolist())
            self._free = [f for f in self._free if f not in taken]  # slots a block took back
            Zj, Wj = self._solve_block(J)
            self._W[:, s] = Wj
            if self._Zt is not None:
                self._Zt[s] = Zj.T
            self.slot[np.isin(self.slot, s)] = -1  # a slot reused by a later block
            self.slot[J] = s
            self.replayed += J.size  # not in ``solved``: the run that wrote the log counted them
            self.log.append(("solve", J.copy(), s.copy()))
        self.seconds += time.perf_counter() - t0
        return True

    def _start_from(self, data: dict[str, np.ndarray], origin: bytes) -> bool:
        """Take the log's starting rows of B (``origin_*``: a system made after a re-pairing, its
        columns not begun yet) when their digest is the log's; False when they cannot be taken."""
        if self.count or self.log or not all(f"origin_{k}" in data for k in ("indptr", "indices", "data")):
            return False
        nc, n = self.B.shape
        indptr, indices = (np.asarray(data[f"origin_{k}"], dtype=np.int64) for k in ("indptr", "indices"))
        values = np.asarray(data["origin_data"], dtype=np.float64)
        out_of_range = indices.size and (indices.min() < 0 or indices.max() >= n)
        if (
            indptr.shape != (nc + 1,)
            or indices.shape != values.shape
            or indices.ndim != 1
            or out_of_range
            or (not np.all(np.isfinite(values)))
        ):
            raise ValueError("the Delassus column log's starting rows are inconsistent")
        O = sp.csr_matrix((values, indices, indptr), shape=(nc, n))
        O.check_format(full_check=True)  # a forged log must not reach scipy's C code malformed
        if _digest(O) != origin:
            return False
        self.B, self._origin_B, self.Bt = O, O, O.T.tocsc()
        self._origin = self._digest_B = origin
        return True

    def replace_rows(self, rows: np.ndarray, B: sp.csr_matrix) -> None:
        """B's rows ``rows`` changed (a contact pair re-paired).

        With the Z columns stored: W's rows ``rows`` in every stored column are B'_rows Z (no
        solve), and the changed rows' own columns are dropped, to be solved again by
        :meth:`ensure` if the node becomes a candidate.  Without Z: their columns of Z and W
        are solved now (in their slots or new ones) and, K being symmetric, W's rows ``rows``
        in every stored column follow from them: W[i, j] = B_j K^-1 B_i^T = W[j, i]."""
        rows = np.unique(np.asarray(rows, dtype=np.intp))
        B = sp.csr_matrix(B)
        digest = _digest(B)
        if digest == self._digest_B:  # these rows already (a resumed run's pairing, its log replayed)
            return
        self.undo.before_change()
        B_before = self.B
        self.B, self._digest_B = B, digest
        self.Bt = self.B.T.tocsc()
        self.log.append(("rows", rows.copy(), self.B[rows]))
        t0 = time.perf_counter()
        if self._Zt is not None:
            kept = rows[self.slot[rows] >= 0]
            if kept.size and self.updates_columns and self._update_columns(kept, B_before):
                self._W[:, self.slot[kept]] = _products(self.B, self._Zt, self.slot[kept])
            elif kept.size:
                self._free.extend(self.slot[kept].tolist())
                self.slot[kept] = -1  # their columns: solved again when asked for
            known = np.flatnonzero(self.slot >= 0)
            if known.size:
                s = self.slot[known]
                self._W[rows[:, None], s[None, :]] = self._row_products(rows, s)
            self.seconds += time.perf_counter() - t0
            return
        new = rows[self.slot[rows] < 0]
        if new.size:
            self._grow(self.count + new.size)
            self.slot[new] = np.arange(self.count, self.count + new.size)
            self.count += new.size
        self.solved += rows.size
        for k in range(0, rows.size, BLOCK):
            J = rows[k : k + BLOCK]
            Zj, Wj = self._solve_block(J)
            s = self.slot[J]
            self._W[:, s] = Wj
            if self._Zt is not None:
                self._Zt[s] = Zj.T
            known = np.flatnonzero(self.slot >= 0)
            self._W[J[:, None], self.slot[known][None, :]] = Wj[known].T
        self.seconds += time.perf_counter() - t0

    def _update_columns(self, rows: np.ndarray, B_before: sp.csr_matrix) -> bool:
        """Z[:, rows] += K^-1 (B - B_before)[rows]^T from the cached columns K^-1 e_k of the
        dofs k where the rows changed (the master dofs of the facets left and reached, the
        slave node's when its frame turned), the missing ones solved in blocks of 64 right-hand
        sides.  Once a slide has visited a master region, its re-pairings cost no solve.
        False (nothing changed) when the cached dof columns would not fit in the budget."""
        D = (self.B[rows] - B_before[rows]).tocsr()
        D.eliminate_zeros()
        dofs = np.unique(D.indices)
        new = dofs[self._dof_slot[dofs] < 0]
        if new.size:
            need = self.dof_columns + new.size
            z_max = int(self.budget // (8 * max(self._budget_rows(), 1)))
            z_max -= self._Zt.shape[0] if self._Zt is not None else 0
            if need > z_max:
                return False
            if need > self._Zd.shape[0]:
                Zd = np.empty((min(max(need, 2 * self._Zd.shape[0], BLOCK), z_max), self._rows()))
                Zd[: self.dof_columns] = self._Zd[: self.dof_columns]
                self._Zd = Zd
            for k in range(0, new.size, BLOCK):
                J = new[k : k + BLOCK]
                E = np.zeros((self.B.shape[1], J.size))
                E[J, np.arange(J.size)] = 1.0
                Zj = self._solve_rhs(E)
                self._Zd[self.dof_columns : self.dof_columns + J.size] = Zj.T
                self._dof_slot[J] = np.arange(self.dof_columns, self.dof_columns + J.size)
                self.dof_columns += J.size
                self.solved += J.size
        if dofs.size:
            Dl = sp.csr_matrix((D.data, np.searchsorted(dofs, D.indices), D.indptr), shape=(rows.size, dofs.size))
            s = self.slot[rows]
            self._Zt[s] += np.asarray(Dl @ self._Zd[self._dof_slot[dofs]])
        return True

    def _solve_rhs(self, E: np.ndarray) -> np.ndarray:
        """K^-1 E for dense right-hand sides E (n, k), the rows this object stores."""
        return self.factor.solve(E).reshape(self.B.shape[1], -1)

    def _row_products(self, rows: np.ndarray, slots: np.ndarray) -> np.ndarray:
        """B[rows] Z[:, slots] from the stored Z (|rows|, |slots|)."""
        return _products(self.B[rows], self._Zt, slots)

    def W(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """W[rows][:, cols] (the columns must be known), shape (len(rows), len(cols))."""
        return self._W[np.asarray(rows)[:, None], self.slot[cols][None, :]]

    def block(self, nodes: np.ndarray) -> np.ndarray:
        """The symmetric block W[nodes][:, nodes] (symmetrized against round-off)."""
        Wb = self.W(nodes, nodes)
        return 0.5 * (Wb + Wb.T)

    def Z_times(self, nodes: np.ndarray, lam: np.ndarray) -> np.ndarray:
        """Z[:, nodes] @ lam (needs :attr:`keeps_Z`), shape (n,)."""
        slots = self.slot[nodes]
        if 4 * slots.size < self.count:  # a few columns: gather their rows
            return lam @ self._Zt[slots]
        # many: one product with every stored row, the others weighted 0, instead of copying
        # the selected rows first (bar3d n = 24, 625 active nodes: a 2.2 GB copy per step)
        c = np.zeros(self.count)
        c[slots] = lam
        return c @ self._Zt[: self.count]

    def free(self, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(x_free, B x_free) for x_free = K^-1 b (one solve)."""
        x = self.factor.solve(b)
        return x, self.B @ x

    def complete(self, x_free: np.ndarray, lam: np.ndarray) -> np.ndarray:
        """x = x_free + Z lambda: the stored Z columns of the nodes with lambda != 0, or
        one more solve when Z does not fit in the budget."""
        A = np.flatnonzero(lam)
        if A.size == 0:
            return x_free
        if self.keeps_Z:
            return x_free + self.Z_times(A, lam[A])
        return x_free + self.factor.solve(self.B.T @ lam)


class ColumnsUndo:
    """The in-memory rollback of a rejected step's changes to a :class:`DelassusColumns`.

    :meth:`mark` before a step that may be rejected; nothing is copied until the step changes B's rows
    (:meth:`DelassusColumns.replace_rows`: the current configuration's rows, moved by each Newton iterate), then
    everything those changes touch is copied once (:meth:`before_change`); :meth:`rollback` puts it back,
    :meth:`release` drops it after an accepted step.  The columns a step only adds stay valid for B and are
    kept.  Moving the rows back would not do: the moved rows' columns are updated incrementally, and the
    retried step would see another round-off (1e-13 of the contact force, measured on rings2d).
    """

    #: what a rollback leaves as it is: the work done (counted), the factor, this object; and the log, which a step
    #: only appends to (cut back to its length, not copied: it holds every change of the run)
    KEPT = ("factor", "solved", "seconds", "replayed", "undo", "log")

    def __init__(self, columns: DelassusColumns) -> None:
        self.columns = columns
        self.marked = False
        self.copy: dict[str, object] | None = None

    def mark(self) -> None:
        """The columns now are those a :meth:`rollback` puts back."""
        self.marked, self.copy = True, None

    def release(self) -> None:
        """The step was accepted: nothing to put back."""
        self.marked, self.copy = False, None

    def before_change(self) -> None:
        """A copy of everything :meth:`DelassusColumns.replace_rows` may change, once after :meth:`mark`."""
        if self.marked and self.copy is None:
            self.copy = {
                k: (v.copy() if isinstance(v, (np.ndarray, list)) else v)
                for k, v in vars(self.columns).items()
                if k not in self.KEPT
            }
            self.copy["log length"] = len(self.columns.log)

    def rollback(self) -> None:
        """The columns, their slots, B and the log as at :meth:`mark`, if the step changed B's rows since."""
        if self.copy is not None:
            del self.columns.log[self.copy.pop("log length") :]
            for k, v in self.copy.items():
                setattr(self.columns, k, v)
        self.copy = None


def _digest(B: sp.csr_matrix) -> bytes:
    """A digest of a CSR matrix's shape, structure and values (bit for bit)."""
    h = hashlib.blake2b(digest_size=16)
    h.update(np.asarray(B.shape, dtype=np.int64).tobytes())
    for a in (B.indptr.astype(np.int64), B.indices.astype(np.int64), B.data.astype(np.float64)):
        h.update(np.ascontiguousarray(a).tobytes())
    return h.digest()


def _products(B: sp.csr_matrix, Zt: np.ndarray, slots: np.ndarray) -> np.ndarray:
    """B Z[:, slots] with Z stored transposed (Zt, one row per slot), shape (B rows, |slots|):
    only the columns of Zt that B touches are read (a contact matrix touches a few hundred
    dofs of n), instead of copying the selected rows of Zt whole."""
    B = sp.csr_matrix(B)
    cols, local = np.unique(B.indices, return_inverse=True)
    Bc = sp.csr_matrix((B.data, local.reshape(-1), B.indptr), shape=(B.shape[0], cols.size))
    return np.asarray(Bc @ Zt[np.asarray(slots)[:, None], cols[None, :]].T)


def _with_rows(B: sp.csr_matrix, rows: np.ndarray, R: sp.csr_matrix) -> sp.csr_matrix:
    """B with its rows ``rows`` replaced by those of R (each row's entries in their order)."""
    order = np.arange(B.shape[0])
    order[rows] = B.shape[0] + np.arange(rows.size)
    return sp.vstack([sp.csr_matrix(B), R], format="csr")[order]

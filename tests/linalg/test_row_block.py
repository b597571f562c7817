"""Row blocks of the distributed backends (:mod:`signorini.linalg.row_block`): node-aligned
bounds, row views, and a :class:`RowBlock` on P ranks simulated by threads (each thread a
rank, its collectives through a barrier), against the whole matrix."""

from __future__ import annotations

import threading
from types import SimpleNamespace

import numpy as np
import pytest
import scipy.sparse as sp

from signorini.linalg.row_block import RowBlock, node_row_bounds, row_bounds, row_view
from signorini.parallel import SERIAL


class _ThreadComm:
    """One rank of P threads: the Comm/mpi4py calls RowBlock makes (Allgatherv, gather)."""

    def __init__(self, rank: int, world: SimpleNamespace):
        self.rank, self.size, self.world = rank, world.size, world
        self.comm, self.MPI = self, SimpleNamespace(DOUBLE=None)

    def _exchange(self, value):
        self.world.slots[self.rank] = value
        self.world.barrier.wait()
        out = list(self.world.slots)
        self.world.barrier.wait()
        return out

    def gather(self, value):
        return self._exchange(value)

    def Allgatherv(self, send, recv):  # noqa: N802 - mpi4py's name
        out, counts, displs, _ = recv
        for r, part in enumerate(self._exchange(np.array(send))):
            out[displs[r] : displs[r] + counts[r]] = part


def _on_ranks(size: int, work):
    """work(comm) on ``size`` simulated ranks; the results in rank order."""
    world = SimpleNamespace(size=size, slots=[None] * size, barrier=threading.Barrier(size, timeout=20))
    results, errors = [None] * size, []

    def run(r):
        try:
            results[r] = work(_ThreadComm(r, world))
        except BaseException as exc:  # noqa: BLE001 - reported below
            errors.append(exc)
            world.barrier.abort()

    threads = [threading.Thread(target=run, args=(r,)) for r in range(size)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    if errors:
        raise errors[0]
    return results


def _matrix(n: int, m: int, seed: int) -> sp.csr_matrix:
    A = sp.random(n, m, density=0.15, random_state=seed, format="csr")
    return (A + sp.eye(n, m)).tocsr()


@pytest.mark.parametrize("size", [1, 2, 3, 5])
def test_row_blocks_end_at_node_boundaries(size):
    rng = np.random.default_rng(size)
    per_node = rng.integers(1, 4, size=40)  # 1 to 3 free dofs per node (Dirichlet on some components)
    nodes = np.repeat(np.arange(40), per_node)
    b = node_row_bounds(nodes, size)
    assert b[0] == 0 and b[-1] == nodes.size and np.all(np.diff(b) >= 0) and b.size == size + 1
    starts = set(np.flatnonzero(np.r_[True, nodes[1:] != nodes[:-1]]).tolist()) | {nodes.size}
    assert set(b.tolist()) <= starts  # no node split between two ranks
    assert np.abs(np.diff(b) - nodes.size / size).max() <= per_node.max()  # about even


def test_row_blocks_refuse_nodes_whose_rows_are_not_consecutive():
    with pytest.raises(ValueError, match="consecutive"):
        node_row_bounds(np.array([0, 1, 0, 1]), 2)


@pytest.mark.parametrize(("lo", "hi"), [(0, 7), (3, 11), (11, 11), (5, 20)])
def test_a_row_view_is_the_rows_without_a_copy(lo, hi):
    A = _matrix(20, 13, 4)
    V = row_view(A, lo, hi)
    assert V.shape == (hi - lo, 13)
    np.testing.assert_array_equal(V.toarray(), A[lo:hi].toarray())
    if V.nnz:
        assert np.shares_memory(V.data, A.data) and np.shares_memory(V.indices, A.indices)


@pytest.mark.parametrize("size", [1, 2, 3, 4])
def test_a_row_block_on_simulated_ranks_gives_the_whole_matrix_results(size):
    n = 23
    A = _matrix(n, n, size)
    x = np.random.default_rng(size).standard_normal(n)
    idx = np.array([0, 4, 5, 12, 21, 22])
    bounds = row_bounds(n, size)

    def work(comm):
        K = RowBlock.of(A, bounds, comm)
        assert K.shape == (n, n) and K.local.shape == (K.hi - K.lo, n)
        return K @ x, K.diagonal(), K.rows(idx)

    for y, diag, rows in _on_ranks(size, work):
        np.testing.assert_allclose(y, A @ x, rtol=1e-14, atol=1e-14)
        np.testing.assert_array_equal(diag, A.diagonal())
        assert abs(rows - A[idx]).max() == 0.0


def test_a_rectangular_row_block_and_a_rank_without_rows():
    A = _matrix(6, 4, 7)  # K_fD: free rows, fixed columns
    bounds = np.array([0, 0, 6])  # rank 0 holds no row
    x = np.arange(4.0)
    out = _on_ranks(2, lambda comm: RowBlock.of(A, bounds, comm, copy=False) @ x)
    for y in out:
        np.testing.assert_allclose(y, A @ x, rtol=1e-14, atol=0.0)


def test_one_process_needs_no_communication():
    A = _matrix(9, 9, 3)
    K = RowBlock.of(A, row_bounds(9, 1), SERIAL)
    np.testing.assert_array_equal(K @ np.ones(9), A @ np.ones(9))
    np.testing.assert_array_equal(K.diagonal(), A.diagonal())

"""Cells partitioned over the ranks and nodes renumbered into contiguous owned ranges.

Every rank reads the whole mesh (the first step of issue 22: memory O(mesh) per rank,
reported by the self-test; DMPlex's distributed reading is what replaces it).  The cells
are split by PETSc's graph partitioner (``MatPartitioning``, PT-Scotch when the build has
it) on the dual graph (two cells adjacent when they share a node), each rank giving the
rows of a block of cells.  A node is owned by the lowest rank among its cells; the new
node numbering lists the nodes of rank 0, then of rank 1, ... (old order inside a rank),
so rank r owns the contiguous range [start_r, stop_r) and its d dofs per node
(:class:`~signorini.fem.dofmap.DofMap`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ...fem.dofmap import DofMap
from ...fem.mesh import Mesh


@dataclass
class Partition:
    """The partition seen from one rank.

    ``cell_rank`` (n_cells,) owner of every cell; ``node_rank`` (n_nodes,) owner of every node;
    ``new_of_old`` (n_nodes,) new global index of each node; ``dofmap`` this rank's owned range
    and ghosts (in the new numbering); ``cells`` the indices of this rank's cells.
    """

    cell_rank: np.ndarray
    node_rank: np.ndarray
    new_of_old: np.ndarray
    dofmap: DofMap
    cells: np.ndarray
    method: str


def dual_graph(mesh: Mesh) -> sp.csr_matrix:
    """Cell adjacency (cells sharing a node), without the diagonal, CSR (n_cells, n_cells)."""
    c = mesh.cells
    inc = sp.csr_matrix(
        (np.ones(c.size), c.ravel(), np.arange(0, c.size + 1, c.shape[1])), shape=(c.shape[0], mesh.n_nodes)
    )
    adj = (inc @ inc.T).tocsr()
    adj.setdiag(0)
    adj.eliminate_zeros()
    adj.sort_indices()
    return adj


def partition_mesh(mesh: Mesh, comm, PETSc) -> Partition:
    """Partition ``mesh`` (the same on every rank) over ``comm`` (see the module docstring)."""
    size, rank = comm.size, comm.rank
    n_cells = mesh.n_cells
    if size == 1:
        cell_rank = np.zeros(n_cells, dtype=np.int64)
        method = "none"
    else:
        adj = dual_graph(mesh)
        bounds = np.linspace(0, n_cells, size + 1).astype(np.int64)
        lo, hi = int(bounds[rank]), int(bounds[rank + 1])
        block = adj[lo:hi]
        A = PETSc.Mat().createAIJ(
            size=((hi - lo, n_cells), (hi - lo, n_cells)),
            csr=(block.indptr.astype(PETSc.IntType), block.indices.astype(PETSc.IntType),
                 np.ones(block.nnz, dtype=PETSc.ScalarType)),
            comm=comm,
        )  # fmt: skip
        part = PETSc.MatPartitioning().create(comm=comm)
        part.setAdjacency(A)
        method = "ptscotch"
        try:
            part.setType(PETSc.MatPartitioning.Type.PARTITIONINGPTSCOTCH)
        except PETSc.Error:  # pragma: no cover - a build without PT-Scotch
            method = "petsc default"
        part.setFromOptions()
        target = PETSc.IS().create(comm=comm)
        part.apply(target)  # the new rank of each of this rank's cells
        mine = target.getIndices().astype(np.int64)
        target.destroy()
        cell_rank = np.concatenate(comm.allgather(mine))
        part.destroy()
        A.destroy()
    # a node belongs to the lowest rank among its cells
    node_rank = np.full(mesh.n_nodes, size, dtype=np.int64)
    np.minimum.at(node_rank, mesh.cells.ravel(), np.repeat(cell_rank, mesh.cells.shape[1]))
    order = np.lexsort((np.arange(mesh.n_nodes), node_rank))  # by rank, then old index
    new_of_old = np.empty(mesh.n_nodes, dtype=np.int64)
    new_of_old[order] = np.arange(mesh.n_nodes)
    counts = np.bincount(node_rank, minlength=size)
    start = int(counts[:rank].sum())
    stop = start + int(counts[rank])
    cells = np.flatnonzero(cell_rank == rank)
    touched = np.unique(new_of_old[mesh.cells[cells]])
    ghosts = touched[(touched < start) | (touched >= stop)]
    dofmap = DofMap(mesh.n_nodes, mesh.dim, start, stop, ghosts)
    return Partition(cell_rank, node_rank, new_of_old, dofmap, cells, method)

"""S and the mass variant on P ranks by rows: each rank assembles the cells around its own nodes.

Rank r owns the nodes [a_r, a_{r+1}) (an even split of the node numbers,
:func:`~signorini.linalg.row_block.row_bounds`) and their d dofs each, the dof rows
[d a_r, d a_{r+1}) (node-major dofs).  It forms only those rows of S and M, as
:class:`~signorini.linalg.row_block.RowBlock` s, from the cells near its nodes:

* S and the local mass variants (standard, lumped, seed, seed-normal): the cells within
  :data:`LAYERS` layers of the owned nodes make a sub-mesh (the same points, a subset of
  the cells); the variant built on it has the whole mesh's rows at the owned nodes.  One
  layer holds every cell that contributes to an owned row; the second is a margin.
  tests/dynamics/test_owned_rows.py checks every variant's rows against the whole mesh's on
  several meshes and rank counts;
* ``moment-preserving`` (M = T^T M_c T, T the affine extrapolation of the contact
  nodes): T is built on the whole mesh on every rank (one sparse row per node); the
  owned rows are T[:, own]^T M_c T, with M_c's rows at the nodes that T[:, own] reaches,
  assembled from the cells touching them.  Exact by construction;
* the variants whose rows can depend on far cells (:data:`WHOLE`) are built on the whole
  mesh and their rows taken, then the whole matrix freed: a set-up peak of one whole M
  per rank, S still by rows.

A rank's memory for S and M is then about nnz / P plus its halo cells, instead of the
whole matrices on every rank, when the node numbers are local: a generated grid's are
slabs, and any other mesh is renumbered along the Z-order curve before a distributed run
(:mod:`signorini.fem.node_order`).  A mesh numbered at random would give every rank a
large halo (correct, but less memory saved).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ...errors import InputError
from ...fem.assembly import assemble_scalar, assemble_vector, element_stiffness_matrices, scalar_mass_matrix, vectorize
from ...fem.dofmap import block_of
from ...fem.material import CellMaterial, Material
from ...fem.mesh import Mesh
from ...linalg.row_block import RowBlock, row_bounds
from .extrapolation import extrapolation_operator
from .mass import EXTRAPOLATED, MASS_VARIANTS, Redistribution, _needs_contact
from .mixed_velocity import check_mesh

#: cell layers around a rank's nodes that determine its rows of a locally built variant
LAYERS = 2
#: the variants built on the whole mesh, their rows then taken: the tensor form reads the
#: generated grid; ``neighbour`` and ``mass-free-surface`` send the mass of a contact node
#: without a free neighbour to the nearest free nodes (``nearest_free_nodes``), a search of
#: unbounded reach, and on a sub-mesh a contact node cut off by its edge looks like one
#: (the cylinder's closed skin on 6 ranks was 0.8% of max|M| off with two layers)
WHOLE = ("moment-preserving-tensor", "neighbour", "mass-free-surface")


def dof_bounds(mesh: Mesh, size: int) -> np.ndarray:
    """Dof rows (size + 1,) of every rank: d times an even split of the nodes."""
    return mesh.dim * row_bounds(mesh.n_nodes, size)


def cells_near(mesh: Mesh, nodes: np.ndarray, layers: int) -> np.ndarray:
    """Indices of the cells within ``layers`` layers of ``nodes`` (bool mask or indices):
    layer 1 the cells touching them, layer k + 1 those touching layer k's nodes."""
    mark = np.zeros(mesh.n_nodes, dtype=bool)
    mark[nodes] = True
    near = np.zeros(mesh.n_cells, dtype=bool)
    for _ in range(layers):
        near = mark[mesh.cells].any(axis=1)
        mark[mesh.cells[near].ravel()] = True
    return np.flatnonzero(near)


def rank_cells(mesh: Mesh, size: int) -> list[int]:
    """Per rank, the cells touching its own nodes: those it assembles for S (summary.json
    ``rank_cells``; n_cells / P plus the interfaces when the node numbers are local)."""
    node_rank = np.searchsorted(row_bounds(mesh.n_nodes, size), np.arange(mesh.n_nodes), side="right") - 1
    pairs = np.unique(np.arange(mesh.n_cells)[:, None] * size + node_rank[mesh.cells])
    return np.bincount(pairs % size, minlength=size).astype(int).tolist()


def submesh(mesh: Mesh, cells: np.ndarray) -> Mesh:
    """The mesh of the cells ``cells`` on all of ``mesh``'s points (node numbers unchanged)."""
    return Mesh(mesh.points, mesh.cells[cells], mesh.cell_type)


def _rows(A: sp.spmatrix, lo: int, hi: int) -> sp.csr_matrix:
    return sp.csr_matrix(A)[lo:hi]


def _take(value, cells: np.ndarray):
    """A material datum of the sub-mesh of ``cells``: a number as it is, per-cell data restricted."""
    if isinstance(value, CellMaterial):
        return value.take(cells)
    return value if np.ndim(value) == 0 else np.asarray(value)[cells]


def stiffness_rows(mesh: Mesh, material: Material, comm) -> RowBlock:
    """This rank's rows of S (:func:`~signorini.fem.assembly.stiffness_matrix`), from the
    cells touching its nodes."""
    bounds = dof_bounds(mesh, comm.size)
    d, lo, hi = mesh.dim, int(bounds[comm.rank]), int(bounds[comm.rank + 1])
    cells = cells_near(mesh, np.arange(block_of(lo, d), block_of(hi, d)), 1)
    sub = submesh(mesh, cells)
    Ke = element_stiffness_matrices(sub, _take(material, cells))
    S = assemble_scalar(sub, Ke[..., 0, 0]) if d == 1 else assemble_vector(sub, Ke)
    return RowBlock(_rows(S, lo, hi), bounds, comm)


def mass_rows(
    name: str, mesh: Mesh, rho: float | np.ndarray, contact_nodes: np.ndarray | None, normals: np.ndarray | None, comm
) -> Redistribution:
    """The :class:`~signorini.dynamics.model.mass.Redistribution` of variant ``name`` with M as
    this rank's rows (see the module docstring)."""
    name = MASS_VARIANTS.resolve(name)
    if name == "mixed-velocity":  # the serial run's refusals first (a linear mesh is refused alike on any ranks)
        check_mesh(mesh, contact_nodes)
        raise InputError(
            "mass 'mixed-velocity' on several ranks is not done: its kernel (not a set of dofs) is projected with the "
            "whole velocity space; use one process, or 'moment-preserving' (the default)"
        )
    bounds = dof_bounds(mesh, comm.size)
    d, lo, hi = mesh.dim, int(bounds[comm.rank]), int(bounds[comm.rank + 1])
    own = np.arange(block_of(lo, d), block_of(hi, d))
    if name in EXTRAPOLATED:
        T = extrapolation_operator(mesh, _needs_contact(name, contact_nodes), name)
        Tc = T[:, own].tocsr()  # (n, m): T[:, own]^T is this rank's rows of T^T
        reached = np.flatnonzero(np.diff(Tc.indptr))
        near = cells_near(mesh, reached, 1)
        Mc = scalar_mass_matrix(submesh(mesh, near), _take(rho, near)).tocsr()
        m = (Tc[reached].T @ Mc[reached] @ T).tocsr()
        m.eliminate_zeros()
        return Redistribution(name, RowBlock(vectorize(m, d), bounds, comm), T)
    if name in WHOLE:
        M = MASS_VARIANTS.get(name).obj(mesh, rho, contact_nodes, normals)
    else:
        near = cells_near(mesh, own, LAYERS)
        M = MASS_VARIANTS.get(name).obj(submesh(mesh, near), _take(rho, near), contact_nodes, normals)
    return Redistribution(name, RowBlock(_rows(M, lo, hi), bounds, comm))

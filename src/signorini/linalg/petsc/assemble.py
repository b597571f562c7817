"""Operators assembled on each rank's own cells into distributed PETSc matrices.

Each rank computes the element blocks of its cells (:func:`~signorini.fem.assembly.element_stiffness_matrices`,
:func:`~signorini.fem.assembly.element_mass_matrices`) and hands them to PETSc as COO
triplets in the new global numbering (``MatSetPreallocationCOO`` / ``MatSetValuesCOO``,
the fast route from numpy: PETSc sums duplicates and sends the entries of ghost rows to
their owners).  The matrix is MPIAIJ with block size d and the owned rows of the
partition's dof map.
"""

from __future__ import annotations

import numpy as np

from ...fem.assembly import element_mass_matrices, element_stiffness_matrices
from ...fem.material import IsotropicElastic
from ...fem.mesh import Mesh
from .partition import Partition


def _coo(mesh: Mesh, part: Partition, Ke: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(rows, cols, values) of the blocks Ke (cells, nv, nv, d, d) of this rank's cells."""
    d = mesh.dim
    nodes = part.new_of_old[mesh.cells[part.cells]]  # (m, nv)
    dofs = (d * nodes[:, :, None] + np.arange(d)).reshape(nodes.shape[0], -1)  # (m, nv d), node-major
    m, nd = dofs.shape
    rows = np.repeat(dofs, nd, axis=1).ravel()
    cols = np.tile(dofs, (1, nd)).ravel()
    blocks = np.asarray(Ke[part.cells]).transpose(0, 1, 3, 2, 4).reshape(m, nd, nd)  # (a i) x (b j)
    return rows, cols, blocks.ravel()


def assemble(mesh: Mesh, part: Partition, Ke: np.ndarray, comm, PETSc):
    """The MPIAIJ matrix of the element blocks Ke (n_cells, nv, nv, d, d) over ``comm``."""
    d = mesh.dim
    lo, hi = part.dofmap.owned_dofs
    n = part.dofmap.n_dofs
    A = PETSc.Mat().create(comm=comm)
    A.setSizes(((hi - lo, n), (hi - lo, n)), bsize=d)
    A.setType(PETSc.Mat.Type.AIJ)
    rows, cols, values = _coo(mesh, part, Ke)
    A.setPreallocationCOO(rows.astype(PETSc.IntType), cols.astype(PETSc.IntType))
    A.setValuesCOO(values.astype(PETSc.ScalarType), addv=PETSc.InsertMode.ADD_VALUES)
    A.assemble()
    return A


def stiffness(mesh: Mesh, material: IsotropicElastic, part: Partition, comm, PETSc):
    """S on this rank's cells (the serial :func:`~signorini.fem.assembly.stiffness_matrix`)."""
    return assemble(mesh, part, element_stiffness_matrices(mesh, material), comm, PETSc)


def consistent_mass(mesh: Mesh, rho: float, part: Partition, comm, PETSc):
    """The consistent mass M (x) I_d on this rank's cells."""
    Me = element_mass_matrices(mesh, rho)
    Ke = Me[:, :, :, None, None] * np.eye(mesh.dim)
    return assemble(mesh, part, Ke, comm, PETSc)

"""The mixed velocity mass: the kinetic energy of the velocity's projection on a P1 space without the contact
vertices (Hauret's equivalent mass; GetFEM's ``singular_mass=2``; spec sections 2(c) and 16).

With the displacement space's shape functions phi_j (P1/Q1 or P2/Q2, every node) and a velocity space of the P1/Q1
functions psi_a of the cells' vertices that are not contact nodes, the pairing and the velocity space's own mass

    W_aj = rho int psi_a phi_j,        C_ab = rho int psi_a psi_b

give the mass M = W^T C^-1 W (scalar; the same for every component).  M is dense (C^-1 is): the variant is meant for
the comparisons of the literature on small meshes, and refuses meshes of more than :data:`MAX_NODES` nodes.
With C lumped M would be sparse, but the 1D exact bar's contact force was twice as far from the exact one (rates
0.31-0.34 against 0.40-0.42; docs/quadratic.md: measured, not taken).  Defined on quadratic cells only: on linear
cells the velocity space has about as many functions as the displacement has free nodes, M is non-singular and the
contact nodes keep their inertia (the 1D bar's energy grew 1e5-fold under Crank-Nicolson, as with the standard
mass).

M is symmetric positive semi-definite and its kernel is ker W: the displacement fields whose weighted means against
every psi_a vanish.  That kernel is not a set of dofs (on a 10-cell P2 bar, 11 of 21 directions, none of them a dof):
the run treats it as the massless directions of a rotated kernel (:class:`VelocitySpace`: V and A projected there,
the initial acceleration solved on range(M)).  M keeps the mass of the vertices' shares c_a only: the contact
vertices' share, O(h) of the body, is lost (the run's ``mass_effect`` says how much).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ...errors import InputError
from ...fem.assembly import geometry, part_value, per_cell
from ...fem.elements import linear_shapes, reference_element
from ...fem.mesh import Mesh, over_blocks

#: the largest mesh of ``mixed-velocity`` (its mass is dense: d n^2 entries, and so is the step operator's factor;
#: at 1,500 nodes in 3D a factor of about 4,500^2 entries)
MAX_NODES = 1500


def _pairings_one_type(mesh: Mesh, rho, n_nodes: int) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """(W, C) (n_nodes, n_nodes) rho int psi_a phi_j and rho int psi_a psi_b on a one-type mesh, rows (and C's
    columns) at the vertices."""
    ref = reference_element(mesh.cell_type)
    nv = ref.n_vertices
    psi = linear_shapes(mesh.cell_type, ref.points)  # (q, nv) the vertices' P1/Q1 functions at the points
    wdet = geometry(mesh)[0] * np.reshape(per_cell(rho, 2), (-1, 1))  # (e, q)
    vertices = mesh.cells[:, :nv]

    def assemble(right: np.ndarray, cols: np.ndarray) -> sp.csr_matrix:
        Ke = np.einsum("eq,qa,qb->eab", wdet, psi, right)
        r = np.repeat(vertices, cols.shape[1], axis=1).ravel()
        c = np.tile(cols, (1, nv)).ravel()
        return sp.csr_matrix((Ke.ravel(), (r, c)), shape=(n_nodes, n_nodes))

    return assemble(ref.N, mesh.cells), assemble(psi, vertices)


def velocity_nodes(mesh: Mesh, contact_nodes: np.ndarray) -> np.ndarray:
    """The nodes of the velocity space: the cells' vertices that are not contact nodes (sorted)."""
    vertex = np.zeros(mesh.n_nodes, dtype=bool)
    for b in mesh.blocks:
        vertex[b.cells[:, : reference_element(b.cell_type).n_vertices].ravel()] = True
    vertex[np.asarray(contact_nodes)] = False
    return np.flatnonzero(vertex)


def velocity_pairings(mesh: Mesh, rho, contact_nodes: np.ndarray) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """(W (n_v, n_nodes), C (n_v, n_v)): the velocity space's pairing with the displacements and its own mass
    (module docstring); ``rho`` a number or one per cell.  InputError on linear cells, without contact nodes, or
    on more than :data:`MAX_NODES` nodes."""
    check_mesh(mesh, contact_nodes)
    keep = velocity_nodes(mesh, contact_nodes)
    n = mesh.n_nodes
    W, C = over_blocks(
        mesh,
        lambda part, cut: _pairings_one_type(part, part_value(rho, cut), n),
        lambda parts: tuple(sum((p[k] for p in parts[1:]), parts[0][k]) for k in range(2)),
    )
    return W.tocsr()[keep], C.tocsr()[keep][:, keep]


def check_mesh(mesh: Mesh, contact_nodes: np.ndarray | None) -> None:
    """InputError, naming the variant, on linear cells, without contact nodes, or on more than :data:`MAX_NODES`
    nodes."""
    if contact_nodes is None or len(contact_nodes) == 0:
        raise InputError("mass 'mixed-velocity' needs contact nodes (a non-empty contact boundary)")
    if mesh.order != 2:
        raise InputError(
            "mass 'mixed-velocity' is defined on quadratic cells only: on linear cells its velocity space has about "
            "as many functions as the free nodes, the mass is not singular and the contact nodes keep their inertia; "
            "use '[mesh] order = 2' (or --set order=2), or 'moment-preserving' (the default)"
        )
    if mesh.n_nodes > MAX_NODES:
        raise InputError(
            f"mass 'mixed-velocity' on a mesh of {mesh.n_nodes} nodes (more than {MAX_NODES}): its mass W^T C^-1 W "
            "is dense; use a coarser mesh, or 'moment-preserving' (the default, sparse)"
        )


def mixed_velocity_scalar_mass(mesh: Mesh, rho, contact_nodes: np.ndarray) -> sp.csr_matrix:
    """M = W^T C^-1 W (n_nodes, n_nodes), symmetric positive semi-definite, ker M = ker W (module docstring)."""
    return mass_of(*velocity_pairings(mesh, rho, contact_nodes))


def mass_of(W: sp.csr_matrix, C: sp.csr_matrix) -> sp.csr_matrix:
    """W^T C^-1 W (n_nodes, n_nodes) of the pairings of :func:`velocity_pairings` (C by its dense Cholesky factor)."""
    L = np.linalg.cholesky(C.toarray())
    G = sla.solve_triangular(L, W.toarray(), lower=True)  # L^-1 W: M = G^T G
    M = sp.csr_matrix(G.T @ G)
    M.eliminate_zeros()
    return M


class VelocitySpace:
    """The kernel of a mixed velocity mass on the free dofs, ker M_ff = ker W_f (W_f the vector pairing's columns of
    the free dofs ``free``, its rows that reach them): the projection of a field's free part on it,
    x_f - W_f^T (W_f W_f^T)^-1 W_f x_f (Euclidean; W_f W_f^T factorized once)."""

    def __init__(self, W: sp.csr_matrix, free: np.ndarray) -> None:
        Wf = sp.csr_matrix(W)[:, free]
        self.W = Wf[np.flatnonzero(np.diff(Wf.indptr))]
        self.free = free
        refusal = InputError(
            "mass 'mixed-velocity': the velocity space restricted to the free dofs is rank deficient (the Dirichlet "
            "boundary fixes the nodes of some velocity functions); use 'moment-preserving'"
        )
        try:
            self._solve = spla.factorized(sp.csc_matrix(self.W @ self.W.T))
        except RuntimeError as e:  # exactly singular
            raise refusal from e
        # nearly singular (SuperLU factorizes a rank-deficient W W^T in round-off): the projection must annihilate W
        x = np.random.default_rng(0).standard_normal(free.size)
        k = x - self.W.T @ self._solve(self.W @ x)
        scale = float(abs(self.W).max()) * float(np.abs(x).max()) if self.W.nnz else 1.0
        if not np.all(np.isfinite(k)) or np.abs(self.W @ k).max(initial=0.0) > 1e-8 * scale:
            raise refusal

    def kernel_part(self, x: np.ndarray) -> np.ndarray:
        """The part of ``x`` (n,) in ker W_f: zero on the fixed dofs."""
        out = np.zeros_like(x)
        xf = x[self.free]
        out[self.free] = xf - self.W.T @ self._solve(self.W @ xf)
        return out

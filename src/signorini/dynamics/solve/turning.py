"""A kept Newton tangent turned with its bodies: the rigid rotation of each body since the tangent was made.

A Total Lagrangian internal force is objective: when a body's deformed configuration x = X + U turns rigidly,
x -> R x + c, its nodal forces turn with it and its tangent stiffness becomes

    K(R x + c) = Q K(x) Q^T,   Q = diag(R, ..., R) over the body's nodes,

and an isotropic mass (M = M_s (x) I_d: no coupling of two components) is unchanged, Q M Q^T = M.  A tangent kept
across levels (:mod:`~.newton`, ``tangent=modified``) that was made at U_k therefore serves the level U^n of a body
that has turned by R since as Q (c_M M + c_S K_k) Q^T, solved with the kept factor between two rotations:

    d = Q (c_M M + c_S K_k)^-1 Q^T b.

R is each body's best rotation between the two configurations (the Kabsch problem, mass-weighted, about the
centres; scipy's ``Rotation.align_vectors``):
exact for a rigid turn, the deformation's rotation part otherwise.  A spinning part keeps its tangent through its
flight instead of making one every few steps (measured in docs/finite_strain.md).

Applies when the run has no Dirichlet dof, its mass is isotropic, no damping enters the step (not needed for alpha M,
which turns; not done), no friction acts, no cell is of the linear model (its constant stiffness does not turn) and
the backend is serial; else :class:`BodyTurning` is not made.  A kept tangent may hold the contact rows' own turning
under their forces (the current configuration's rows, :mod:`~..rows.current_rows`): that part does not turn with the
bodies, and a step where it matters reaches a row, where the kept tangent is used as it is.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.spatial.transform import Rotation

from ...fem.dofmap import component, component_of
from ...fem.mesh import bodies

#: a turn below this angle [rad] is none (the kept tangent is used as it is)
NEGLIGIBLE_ANGLE = 1e-9


def isotropic(M: sp.spmatrix, dim: int) -> bool:
    """Whether M (n, n), dofs node-major (node i, component a at dim i + a), couples no two components and has the
    same block for each: M = M_s (x) I_dim."""
    C = sp.coo_matrix(M)
    cross = component_of(C.row, dim) != component_of(C.col, dim)
    if np.any(C.data[cross] != 0.0):
        return False
    Mc = sp.csr_matrix(M)
    first = Mc[component(0, dim), component(0, dim)]
    scale = float(np.max(np.abs(first.data), initial=0.0))
    return all(abs(Mc[component(a, dim), component(a, dim)] - first).max() <= 1e-14 * scale for a in range(1, dim))


class BodyTurning:
    """The rigid rotation of each body between two displacements, and the products with Q and Q^T.

    Parameters
    ----------
    points : (n_nodes, d) the reference positions [length].
    label : (n_nodes,) each node's body.
    weights : (n_nodes,) each node's weight in its body's fit (its row sum of M along x, floored at a small share of
        the body's mean so that a node without mass still counts) [mass].
    """

    def __init__(self, points: np.ndarray, label: np.ndarray, weights: np.ndarray):
        self.points = np.asarray(points, dtype=float)
        self.n_nodes, self.dim = self.points.shape
        self.label = np.asarray(label)
        self.n_bodies = int(self.label.max(initial=0)) + 1
        w = np.abs(np.asarray(weights, dtype=float))
        mean = np.bincount(self.label, w, self.n_bodies) / np.maximum(np.bincount(self.label, None, self.n_bodies), 1)
        self.weights = np.maximum(w, 1e-3 * mean[self.label])
        #: the nodes of each body
        self.members = [np.flatnonzero(self.label == k) for k in range(self.n_bodies)]

    def rotations(self, U_from: np.ndarray, U_to: np.ndarray) -> np.ndarray | None:
        """Each body's rotation R (n_bodies, d, d) from the configuration X + U_from to X + U_to (U: (n_nodes d,),
        node-major), or None when every body turned by less than :data:`NEGLIGIBLE_ANGLE` (or a configuration is
        beyond floating point).  Per body, scipy's weighted Kabsch fit (``Rotation.align_vectors``) of the nodes'
        positions about their centres; a 2D body in the plane z = 0."""
        d, w = self.dim, self.weights
        p = np.zeros((self.n_nodes, 3))
        q = np.zeros((self.n_nodes, 3))
        p[:, :d] = self.points + np.reshape(U_from, (-1, d))
        q[:, :d] = self.points + np.reshape(U_to, (-1, d))
        if not (np.all(np.isfinite(p)) and np.all(np.isfinite(q))):
            return None
        R = np.empty((self.n_bodies, d, d))
        with np.errstate(over="ignore", invalid="ignore"):  # beyond floating point: refused below
            for k, nodes in enumerate(self.members):  # a few bodies
                wk = w[nodes]
                P = p[nodes] - wk @ p[nodes] / wk.sum()
                Q = q[nodes] - wk @ q[nodes] / wk.sum()
                if not (np.all(np.isfinite(P)) and np.all(np.isfinite(Q))):
                    return None
                try:
                    R[k] = Rotation.align_vectors(Q, P, weights=wk)[0].as_matrix()[:d, :d]
                except (np.linalg.LinAlgError, ValueError):  # its covariance beyond floating point
                    return None
        # |R - I|_F = 2 sqrt(2) sin(angle / 2) in 2D and 3D: the angle, without arccos's loss near 1
        if np.all(np.linalg.norm(R - np.eye(d), axis=(1, 2)) / np.sqrt(2.0) < NEGLIGIBLE_ANGLE):
            return None
        return R

    def turn(self, R: np.ndarray, x: np.ndarray, transpose: bool = False) -> np.ndarray:
        """Q x (or Q^T x) for a nodal vector x (n_nodes d,): each node's block by its body's R."""
        Rn = R[self.label]
        sub = "kji,kj->ki" if transpose else "kij,kj->ki"
        return np.einsum(sub, Rn, np.reshape(x, (-1, self.dim))).ravel()


def body_turning(ctx) -> BodyTurning | None:
    """The turning of ``ctx``'s bodies, or None where it does not apply (module docstring): a Dirichlet dof in the
    run, a mass whose components differ or couple, damping, friction, cells of the linear model (their constant
    stiffness does not turn), a distributed backend (operators by rows, on any number of ranks)."""
    disc = ctx.disc
    mesh = disc.problem.mesh
    dim = mesh.points.shape[1]
    if dim < 2 or ctx.has_fixed or ctx.damping is not None or ctx.damping_matrix is not None:
        return None
    if ctx.distributed or ctx.comm.size > 1 or ctx.rows.components > 1:
        return None
    if ctx.elastic.S_linear is not None or not sp.issparse(disc.M):
        return None
    if disc.M.shape[0] != mesh.n_nodes * dim or not isotropic(disc.M, dim):
        return None
    along_x = component(0, dim)
    weights = np.asarray(sp.csr_matrix(disc.M)[along_x, along_x].sum(axis=1)).ravel()
    return BodyTurning(mesh.points, bodies(mesh), weights)

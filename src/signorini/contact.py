"""Rigid obstacles and the nodal Signorini contact set.

Sign conventions (seed paper, spec section 0.1)
------------------------------------------------
For every contact node i with outward unit normal nu_i and initial gap g_i::

    nu_i . u_i <= g_i,     lambda_i <= 0,     (nu_i . u_i - g_i) lambda_i = 0,

and the semi-discrete system is ``M U'' + S U = F + B^T lambda`` where row i of ``B``
picks ``nu_i . u(a_i)``.  ``lambda_i`` is the nodal contact force (negative =
compression); the contact pressure reported in outputs is ``-lambda_i / w_i`` with
``w_i = int_{Gamma_C} N_i ds`` (positive in compression).

The obstacle is described by a signed distance ``phi`` (positive outside the
obstacle).  Linearising ``phi(x_i + u_i) >= 0`` at the reference position gives
``nu_i = -grad phi / |grad phi|`` and ``g_i = phi(x_i) / |grad phi(x_i)|``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .assembly import facet_weights
from .errors import InputError
from .space import Constraints, VectorSpace


class RigidObstacle:
    """A rigid obstacle given by a signed distance function ``phi`` and its gradient.

    ``phi(x)`` > 0 outside the obstacle (where the body may be), in length units;
    ``grad(x)`` returns the gradient, shape (n, d).
    """

    def __init__(self, phi: Callable[[np.ndarray], np.ndarray], grad: Callable[[np.ndarray], np.ndarray]):
        self.phi = phi
        self.grad = grad

    def gaps_and_normals(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Initial gaps g (n,) and outward body normals nu (n, d) at points x (n, d)."""
        phi = np.asarray(self.phi(x), dtype=float).reshape(len(x))
        grad = np.asarray(self.grad(x), dtype=float).reshape(x.shape)
        norm = np.linalg.norm(grad, axis=1)
        if np.any(norm <= 0) or not np.all(np.isfinite(norm)):
            raise InputError("obstacle: the gradient of the signed distance vanishes at a contact node")
        return phi / norm, -grad / norm[:, None]


class PlaneObstacle(RigidObstacle):
    """Half-space obstacle {x : (x - point) . normal < 0}; ``normal`` points out of the
    obstacle, towards the body.  phi(x) = (x - point) . normal / |normal|."""

    def __init__(self, point, normal):
        p = np.asarray(point, dtype=float).ravel()
        n = np.asarray(normal, dtype=float).ravel()
        if p.shape != n.shape:
            raise InputError(f"obstacle point and normal must have the same length, got {p.size} and {n.size}")
        nn = np.linalg.norm(n)
        if nn == 0:
            raise InputError("obstacle normal must be a non-zero vector")
        self.point, self.normal = p, n / nn
        super().__init__(lambda x: (x - self.point) @ self.normal, lambda x: np.broadcast_to(self.normal, x.shape))


class SphereObstacle(RigidObstacle):
    """A rigid ball (disc in 2D) of centre c and radius R; the body stays outside:
    phi(x) = |x - c| - R, grad phi = (x - c)/|x - c|."""

    def __init__(self, center, radius: float):
        c = np.asarray(center, dtype=float).ravel()
        if not np.isfinite(radius) or radius <= 0:
            raise InputError(f"obstacle radius must be > 0, got {radius}")
        self.center, self.radius = c, float(radius)

        def grad(x):
            r = x - self.center
            return r / np.linalg.norm(r, axis=1, keepdims=True)

        super().__init__(lambda x: np.linalg.norm(x - self.center, axis=1) - self.radius, grad)


@dataclass
class ContactSet:
    """Contact nodes of a boundary tag facing a rigid obstacle.

    Attributes
    ----------
    nodes : (nc,) node indices on Gamma_C.
    normals : (nc, d) outward unit normals nu_i.
    gaps : (nc,) initial gaps g_i [length].
    weights : (nc,) w_i = int_{Gamma_C} N_i ds (1 per node in 1D).
    B : (nc, n_dofs) sparse, row i = nu_i^T on the dofs of node i.
    """

    nodes: np.ndarray
    normals: np.ndarray
    gaps: np.ndarray
    weights: np.ndarray
    B: sp.csr_matrix

    @classmethod
    def from_tag(
        cls, space: VectorSpace, tag: str, obstacle: RigidObstacle, constraints: Constraints | None = None
    ) -> ContactSet:
        mesh = space.mesh
        nodes = mesh.nodes_of(tag)
        gaps, normals = obstacle.gaps_and_normals(mesh.points[nodes])
        weights = facet_weights(mesh, tag)[nodes]
        dofs = space.dofs(nodes)
        rows = np.repeat(np.arange(nodes.size), space.dim)
        B = sp.csr_matrix((normals.ravel(), (rows, dofs.ravel())), shape=(nodes.size, space.n_dofs))
        if constraints is not None and constraints.fixed.size:
            fixed = np.zeros(space.n_dofs, dtype=bool)
            fixed[constraints.fixed] = True
            clash = (fixed[dofs] & (np.abs(normals) > 1e-12)).any(axis=1)
            if clash.any():
                raise InputError(
                    f"contact tag {tag!r}: {int(clash.sum())} contact node(s) are fixed by a Dirichlet "
                    f"condition in the normal direction (e.g. node {int(nodes[clash][0])}); "
                    "remove them from the Dirichlet or the contact tag"
                )
        return cls(nodes, normals, gaps, weights, B)

    @property
    def size(self) -> int:
        return self.nodes.size

    def gap(self, u: np.ndarray) -> np.ndarray:
        """Current gaps g_i - nu_i . u_i (>= 0 when admissible)."""
        return self.gaps - self.B @ u

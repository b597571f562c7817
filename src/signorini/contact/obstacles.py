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

import numpy as np

from ..errors import InputError


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

"""Rigid obstacles, fixed or moving, described by a signed distance.

Sign conventions (seed paper, spec section 0.1)
------------------------------------------------
For every contact node i with outward unit normal nu_i and gap g_i::

    nu_i . u_i <= g_i,     lambda_i <= 0,     (nu_i . u_i - g_i) lambda_i = 0,

and the semi-discrete system is ``M U'' + S U = F + B^T lambda`` where row i of ``B``
picks ``nu_i . u(a_i)``.  ``lambda_i`` is the nodal contact force (negative =
compression); the contact pressure reported in outputs is ``-lambda_i / w_i`` with
``w_i = int_{Gamma_C} N_i ds`` (positive in compression).

The obstacle is described by a signed distance ``phi(x, t)`` (positive outside the
obstacle, where the body may be).  Linearising ``phi(x_i + u_i, t) >= 0`` at the
reference position gives ``nu_i = -grad phi / |grad phi|`` and
``g_i(t) = phi(x_i, t) / |grad phi(x_i, t)|``.  The normals are those of t = 0 (the
operator B, hence the factorization, does not change during a run); a moving
obstacle changes the gaps only.  For a translating plane this is exact; for a moving
sphere it is the same small-displacement linearisation as the contact law itself.

Obstacles are entries of :data:`OBSTACLES`; a position (``point``, ``center``) may be a
constant vector or a function of t returning one (a prescribed motion).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from ..errors import InputError
from ..registry import Motion, Parameter, Registry, Vector

Position = Sequence[float] | np.ndarray | Callable[[float], Sequence[float]]


def _position(name: str, value: Position, dim: int | None = None) -> Callable[[float], np.ndarray]:
    """A function of t returning a finite vector, from a constant or a callable."""
    if callable(value):
        f = value
        moving = True
    else:
        const = np.asarray(value, dtype=float).ravel()
        moving = False

        def f(t: float, const=const) -> np.ndarray:
            return const

    def position(t: float) -> np.ndarray:
        p = np.asarray(f(t), dtype=float).ravel()
        if dim is not None and p.size != dim:
            raise InputError(f"obstacle {name} must have {dim} components, got {p.size}")
        if not np.all(np.isfinite(p)):
            raise InputError(f"obstacle {name} is not finite at t = {t:g}: {p}")
        return p

    position.moving = moving  # type: ignore[attr-defined]
    return position


class RigidObstacle:
    """A rigid obstacle given by a signed distance ``phi(x)`` and its gradient.

    ``phi(x)`` > 0 outside the obstacle (where the body may be), in length units;
    ``grad(x)`` returns the gradient, shape (n, d).  Subclasses with a motion override
    :meth:`gaps` and set ``moving = True``.
    """

    moving = False

    def __init__(self, phi: Callable[[np.ndarray], np.ndarray], grad: Callable[[np.ndarray], np.ndarray]):
        self.phi = phi
        self.grad = grad

    def gaps_and_normals(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Gaps g (n,) at t = 0 and outward body normals nu (n, d) at points x (n, d)."""
        phi = np.asarray(self.phi(x), dtype=float).reshape(len(x))
        grad = np.asarray(self.grad(x), dtype=float).reshape(x.shape)
        norm = np.linalg.norm(grad, axis=1)
        if np.any(norm <= 0) or not np.all(np.isfinite(norm)):
            raise InputError("obstacle: the gradient of the signed distance vanishes at a contact node")
        return phi / norm, -grad / norm[:, None]

    def gaps(self, x: np.ndarray, t: float) -> np.ndarray:
        """Gaps g(t) (n,) at the reference points x (n, d); constant for a fixed obstacle."""
        return self.gaps_and_normals(x)[0]

    def translation(self, t0: float, t1: float) -> np.ndarray:
        """The obstacle's rigid translation from t0 to t1 (d,) [length]; 0 for a fixed one.

        The tangential slip of a contact node is measured relative to it (obstacles
        translate, they do not rotate).
        """
        return np.zeros(0)


class PlaneObstacle(RigidObstacle):
    """Half-space obstacle {x : (x - point(t)) . normal < 0}; ``normal`` points out of
    the obstacle, towards the body.  phi(x, t) = (x - point(t)) . normal / |normal|."""

    def __init__(self, point: Position, normal: Sequence[float]):
        n = np.asarray(normal, dtype=float).ravel()
        self._point = _position("point", point, n.size)
        p = self._point(0.0)
        if p.shape != n.shape:
            raise InputError(f"obstacle point and normal must have the same length, got {p.size} and {n.size}")
        nn = np.linalg.norm(n)
        if nn == 0 or not np.isfinite(nn):
            raise InputError("obstacle normal must be a finite non-zero vector")
        self.point, self.normal = p, n / nn
        self.moving = self._point.moving
        super().__init__(lambda x: (x - self.point) @ self.normal, lambda x: np.broadcast_to(self.normal, x.shape))

    def gaps(self, x: np.ndarray, t: float) -> np.ndarray:
        return (x - self._point(t)) @ self.normal

    def translation(self, t0: float, t1: float) -> np.ndarray:
        return self._point(t1) - self._point(t0) if self.moving else np.zeros(self.normal.size)


class SphereObstacle(RigidObstacle):
    """A rigid ball (disc in 2D) of centre c(t) and radius R; the body stays outside:
    phi(x, t) = |x - c(t)| - R, grad phi = (x - c)/|x - c|."""

    def __init__(self, center: Position, radius: float):
        try:
            radius = float(radius)
        except (TypeError, ValueError):
            raise InputError(f"obstacle radius must be a number, got {radius!r}") from None
        if not np.isfinite(radius) or radius <= 0:
            raise InputError(f"obstacle radius must be > 0, got {radius}")
        self._center = _position("center", center)
        self.center, self.radius = self._center(0.0), radius
        self.moving = self._center.moving

        def grad(x):
            r = x - self.center
            return r / np.linalg.norm(r, axis=1, keepdims=True)

        super().__init__(lambda x: np.linalg.norm(x - self.center, axis=1) - self.radius, grad)

    def gaps(self, x: np.ndarray, t: float) -> np.ndarray:
        return np.linalg.norm(x - self._center(t), axis=1) - self.radius

    def translation(self, t0: float, t1: float) -> np.ndarray:
        return self._center(t1) - self._center(t0) if self.moving else np.zeros(self.center.size)


OBSTACLES = Registry("obstacle type")
OBSTACLES.register(
    "plane",
    PlaneObstacle,
    "half-space {(x - point) . normal < 0}; normal points from the obstacle towards the body",
    parameters=(
        Parameter("point", None, "a point of the plane; may depend on t (moving plane)", Motion),
        Parameter("normal", None, "normal pointing out of the obstacle, towards the body", Vector),
    ),
)
OBSTACLES.register(
    "sphere",
    SphereObstacle,
    "rigid ball (disc in 2D) the body stays outside of",
    parameters=(
        Parameter("center", None, "centre; may depend on t (moving ball)", Motion),
        Parameter("radius", None, "radius [length]", float, 0.0, open_low=True),
    ),
)

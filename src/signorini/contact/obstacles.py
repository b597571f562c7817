"""Rigid obstacles, fixed or moving (translating and rotating), described by a signed distance.

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
obstacle changes the gaps only.

Rigid motion
------------
Every obstacle of :data:`OBSTACLES` may move rigidly: a translation d(t) and a rotation
R(t) by an angle theta(t) [rad] about an axis through a point c, each a function of t.
A material point X of the obstacle as given (the plane through ``point`` at t = 0, the
ball of ``center`` at t = 0, the surface of the file) is at time t at

    Phi_t(X) = X + d(t) + (R(t) - I) (X - c),

a rotation about the axis through c + d(t): the axis moves with the translation.  For a
plane or a ball d(t) = p(t) - p(0) with p the given ``point`` or ``center`` (a constant
or a function of t, as before rotations existed); for a surface d(t) is its
``translation``.  R(t) turns by theta(t) counterclockwise about the unit ``axis`` (right-
hand rule; in 2D the axis is out of the plane, +z, and is not given):

    2D:  R = [[cos theta, -sin theta], [sin theta, cos theta]],
    3D:  R = cos theta I + sin theta [k]_x + (1 - cos theta) k k^T      (Rodrigues, k the axis).

The gaps follow the moved obstacle exactly: g_i(t) = phi_t(x_i) is the signed distance
of the obstacle at t at the *reference* position x_i of node i (a rotating plane:
g_i(t) = (x_i - p(t)) . n(t) with n(t) = R(t) n(0)), while B and the normals stay those of
t = 0.  This is the linearized (small displacement) condition, as for a moving ball: it
is exact for a translating plane and for a plane rotating about its own normal, and for a
tilting plane or a moving curved obstacle it is the condition of the contact law itself
linearized about the reference configuration, accurate while the nodes' motion along the
obstacle and the change of its normal over the run are small.

With friction, the reference slip of a step t0 -> t1 (:meth:`RigidObstacle.displacement`,
used by :meth:`~signorini.contact.contact_set.ContactSet.obstacle_slip`) is the rigid
motion's displacement of the obstacle's material point X_i that faced node i at t = 0
(the closest point of the obstacle to x_i, as a contact pair's master point is frozen at
t = 0), projected on the node's tangents t_ik:

    c_ik = t_ik . (Phi_t1(X_i) - Phi_t0(X_i)) = t_ik . (d(t1) - d(t0) + (R(t1) - R(t0)) (X_i - c)),

so a sticking node follows that material point exactly (the sum over the steps
telescopes to Phi_t(X_i) - Phi_0(X_i)).  Without rotation this is the translation
t_ik . (d(t1) - d(t0)) shared by every node.  A rotation angle that is exactly 0 at t is
no rotation at t: the arithmetic is the same as without one, bit for bit.

A surface obstacle (:class:`SurfaceObstacle`) is a triangulated (3D) or polygonal (2D)
rigid surface whose facet orientation says which side is outside (see the class).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from ..errors import InputError, MeshError, not_a_file
from ..registry import FilePath, Motion, Parameter, Registry, RotationTable, Vector

Position = Sequence[float] | np.ndarray | Callable[[float], Sequence[float]]
Angle = float | Callable[[float], float]


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


def _angle(value: Angle) -> Callable[[float], float]:
    """theta(t) [rad] as a function returning a finite float, from a number or a callable."""
    if callable(value):
        f, moving = value, True
    else:
        try:
            const = float(value)
        except (TypeError, ValueError):
            raise InputError(f"obstacle rotation angle must be a number or a function of t, got {value!r}") from None
        moving = False

        def f(t: float, const=const) -> float:
            return const

    def angle(t: float) -> float:
        a = np.asarray(f(t), dtype=float).ravel()
        if a.size != 1:
            raise InputError(f"obstacle rotation angle must be one number at t = {t:g}, got {a.size}")
        if not np.isfinite(a[0]):
            raise InputError(f"obstacle rotation angle is not finite at t = {t:g}: {a[0]}")
        return float(a[0])

    angle.moving = moving  # type: ignore[attr-defined]
    return angle


#: the keys of a ``rotation`` table (case files) and of :class:`Rotation` (Python)
ROTATION_KEYS = (
    Parameter(
        "angle",
        None,
        "angle theta(t) [rad], counterclockwise about the axis (right-hand rule); a number or an expression of t",
        Motion,
    ),
    Parameter("axis", None, "direction of the axis (3D only: in 2D the axis is out of the plane, +z)", Vector),
    Parameter(
        "center",
        None,
        "a point of the axis, in the obstacle's own coordinates (the axis moves with its "
        "translation); default the plane's point or the ball's centre at t = 0; required for a surface",
        Vector,
    ),
)


@dataclass(frozen=True)
class Rotation:
    """The rotation of a rigid obstacle: ``angle`` theta(t) [rad] (a number or a function of t)
    about the axis through ``center`` along ``axis`` (3D; None in 2D, where the axis is out of
    the plane).  ``center`` (d,) None: the plane's ``point`` or the ball's ``center`` at t = 0
    (a surface needs one).  A dict with these keys is accepted wherever a Rotation is."""

    angle: Angle
    axis: Sequence[float] | None = None
    center: Sequence[float] | None = None


def _rotation_spec(rotation: Rotation | Mapping | None) -> Rotation | None:
    if rotation is None or isinstance(rotation, Rotation):
        return rotation
    if isinstance(rotation, Mapping):
        allowed = {p.name for p in ROTATION_KEYS}
        unknown = sorted(set(rotation) - allowed)
        if unknown:
            raise InputError(f"obstacle rotation: unknown key(s) {unknown}; allowed: {', '.join(sorted(allowed))}")
        if "angle" not in rotation:
            raise InputError("obstacle rotation: 'angle' is required (a number or a function of t, in radians)")
        return Rotation(**dict(rotation))
    raise InputError(f"obstacle rotation must be a Rotation or a dict (angle, axis, center), got {rotation!r}")


class RigidMotion:
    """The rigid motion Phi_t(X) = X + d(t) + (R(t) - I)(X - c) of an obstacle (module docstring).

    ``position`` p(t) (d,) gives the translation: d(t) = p(t) - p(0) when ``relative`` (a
    plane's point, a ball's centre), d(t) = p(t) otherwise (a surface's translation).
    """

    def __init__(
        self,
        dim: int,
        position: Callable[[float], np.ndarray],
        rotation: Rotation | Mapping | None,
        center: np.ndarray | None,
        relative: bool,
    ):
        self.dim = dim
        self.position = position
        self.relative = relative
        self._p0 = position(0.0) if relative else None
        spec = _rotation_spec(rotation)
        self.rotates = spec is not None
        self.angle = None
        if spec is not None:
            if dim == 1:
                raise InputError("obstacle rotation: a 1D obstacle cannot rotate")
            self.angle = _angle(spec.angle)
            if dim == 2:
                if spec.axis is not None:
                    raise InputError(
                        "obstacle rotation: in 2D the axis is out of the plane (angles counterclockwise); omit 'axis'"
                    )
                self.axis = None
            else:
                if spec.axis is None:
                    raise InputError("obstacle rotation: 'axis' is required in 3D (the direction of the axis)")
                k = np.asarray(spec.axis, dtype=float).ravel()
                nk = float(np.linalg.norm(k)) if k.size == 3 else 0.0
                if k.size != 3 or not np.isfinite(nk) or nk == 0.0:
                    raise InputError(
                        f"obstacle rotation axis must be a finite non-zero vector of 3 components, "
                        f"got {np.asarray(spec.axis).tolist()}"
                    )
                self.axis = k / nk
            c = center if spec.center is None else spec.center
            if c is None:
                raise InputError("obstacle rotation: 'center' is required for a surface (a point of the axis)")
            c = np.asarray(c, dtype=float).ravel()
            if c.size != dim or not np.all(np.isfinite(c)):
                raise InputError(f"obstacle rotation center must be {dim} finite numbers, got {c.tolist()}")
            self.center = c
        self.moving = bool(getattr(position, "moving", False) or (self.rotates and self.angle.moving))

    def matrix(self, t: float) -> np.ndarray | None:
        """R(t) (d, d); None when the obstacle does not rotate or theta(t) == 0 (no rotation at t)."""
        if not self.rotates:
            return None
        a = self.angle(t)
        if a == 0.0:
            return None
        c, s = np.cos(a), np.sin(a)
        if self.dim == 2:
            return np.array([[c, -s], [s, c]])
        k = self.axis
        K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
        return c * np.eye(3) + s * K + (1.0 - c) * np.outer(k, k)

    def turns(self, *times: float) -> bool:
        """Whether R(t) is not the identity at one of ``times``."""
        return any(self.matrix(t) is not None for t in times)

    def shift(self, t: float) -> np.ndarray:
        """d(t) (d,) [length]."""
        return self.position(t) - self._p0 if self.relative else self.position(t)

    def translation(self, t0: float, t1: float) -> np.ndarray:
        """d(t1) - d(t0) (d,) [length]."""
        return self.position(t1) - self.position(t0)

    def to_data(self, x: np.ndarray, t: float) -> np.ndarray:
        """Phi_t^{-1}(x) (n, d): the obstacle's own coordinates of points x (n, d) at time t,
        c + R(t)^T (x - c - d(t)) (x - d(t) without rotation at t)."""
        R = self.matrix(t)
        if not self.moving and R is None and not self.relative and not np.any(self.position(t)):
            return x
        if R is None:
            return x - self.shift(t)
        return self.center + (x - self.center - self.shift(t)) @ R

    def to_world(self, v: np.ndarray, t: float) -> np.ndarray:
        """Directions v (n, d) of the obstacle's own coordinates turned to those of time t: R(t) v."""
        R = self.matrix(t)
        return v if R is None else v @ R.T

    def displacement(self, X: np.ndarray, t0: float, t1: float) -> np.ndarray:
        """Phi_t1(X) - Phi_t0(X) (n, d) [length] of material points X (n, d) (own coordinates):
        d(t1) - d(t0) + (R(t1) - R(t0)) (X - c)."""
        d = self.translation(t0, t1)
        R0, R1 = self.matrix(t0), self.matrix(t1)
        if R0 is None and R1 is None:
            return np.broadcast_to(d, X.shape).copy()
        eye = np.eye(self.dim)
        A = (eye if R1 is None else R1) - (eye if R0 is None else R0)
        return d + (X - self.center) @ A.T


class RigidObstacle:
    """A rigid obstacle given by a signed distance ``phi(x)`` and its gradient.

    ``phi(x)`` > 0 outside the obstacle (where the body may be), in length units;
    ``grad(x)`` returns the gradient, shape (n, d).  Subclasses with a motion override
    :meth:`gaps`, set ``moving = True`` and a :class:`RigidMotion` ``motion``.
    """

    moving = False
    motion: RigidMotion | None = None
    #: a node inside the obstacle at t = 0 is first explained by the body's side of it (a flipped
    #: surface puts most of the body "inside"): :meth:`body_inside_message` before the node's own
    side_first = False

    def __init__(self, phi: Callable[[np.ndarray], np.ndarray], grad: Callable[[np.ndarray], np.ndarray]):
        self.phi = phi
        self.grad = grad

    def body_normals(self, x: np.ndarray, t: float) -> np.ndarray | None:
        """The outward body normals nu = -grad phi_t / |grad phi_t| (n, d) at the points x (n, d) of the
        current configuration at time t (finite strain's contact rows), or None when the obstacle does not
        give them (its contact in the current configuration is not done: refused by name)."""
        return None

    def distance_scale(self, x: np.ndarray, t: float) -> float:
        """The size of the numbers phi_t(x) is computed from (its round-off's scale) [length]: the largest
        coordinate of x by default."""
        return float(np.max(np.abs(x), initial=0.0))

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
        """The obstacle's rigid translation d(t1) - d(t0) from t0 to t1 (d,) [length]; an empty
        array for an obstacle without motion.  With a rotation at t0 or t1 (:meth:`turns`) the
        material points move differently: :meth:`displacement`."""
        return self.motion.translation(t0, t1) if self.motion is not None and self.moving else np.zeros(0)

    def turns(self, t0: float, t1: float) -> bool:
        """Whether the obstacle is rotated (theta != 0) at t0 or at t1."""
        return self.motion is not None and self.motion.turns(t0, t1)

    def material_points(self, x: np.ndarray) -> np.ndarray:
        """The obstacle's material points X (n, d) (its own coordinates) facing the points x (n, d)
        at t = 0: the closest points x + g nu of the obstacle at t = 0, mapped by Phi_0^{-1}."""
        g, nu = self.gaps_and_normals(x)
        p = x + g[:, None] * nu
        return p if self.motion is None else self.motion.to_data(p, 0.0)

    def displacement(self, X: np.ndarray, t0: float, t1: float) -> np.ndarray:
        """Displacement Phi_t1(X) - Phi_t0(X) (n, d) [length] of material points X (n, d) from
        :meth:`material_points` (zero for an obstacle without motion)."""
        if self.motion is None:
            return np.zeros_like(X)
        return self.motion.displacement(X, t0, t1)

    # -- what a user reads when the body starts inside (the set-up's refusals) ------------------
    def body_inside_message(self, share: float) -> str:
        """Why a body with the fraction ``share`` (> 1/2) of its nodes inside the obstacle is refused."""
        return f"{100 * share:.0f}% of the body's nodes start inside the obstacle"

    def node_inside_message(self, where: str, gap: float, points: np.ndarray, point: np.ndarray) -> str:
        """Why the contact node ``where`` (at ``point``, of a body with nodes ``points``) starting at
        the negative gap ``gap`` is refused."""
        return f"{where} starts inside the obstacle (gap {gap:.3g} < 0)"


class PlaneObstacle(RigidObstacle):
    """Half-space obstacle {x : (x - point(t)) . normal < 0}; ``normal`` points out of
    the obstacle, towards the body.  phi(x, t) = (x - p(t)) . n(t) with n = normal / |normal|.

    ``rotation`` (:class:`Rotation` or a dict): the plane turns by theta(t) about the axis
    through ``rotation.center`` (default: ``point`` at t = 0) moving with the point:
    p(t) = point(t) + (R(t) - I)(point(0) - c), n(t) = R(t) n.  ``point``, ``normal`` (the
    attributes) are those of the plane at t = 0.
    """

    def __init__(self, point: Position, normal: Sequence[float], rotation: Rotation | Mapping | None = None):
        n = np.asarray(normal, dtype=float).ravel()
        self._point = _position("point", point, n.size)
        p = self._point(0.0)
        if p.shape != n.shape:
            raise InputError(f"obstacle point and normal must have the same length, got {p.size} and {n.size}")
        nn = np.linalg.norm(n)
        if nn == 0 or not np.isfinite(nn):
            raise InputError("obstacle normal must be a finite non-zero vector")
        self.dim = n.size
        self._p0, self._n0 = p, n / nn
        self.motion = RigidMotion(n.size, self._point, rotation, p, relative=True)
        self.moving = self.motion.moving
        self.point, self.normal = self._at(0.0)
        super().__init__(lambda x: (x - self.point) @ self.normal, lambda x: np.broadcast_to(self.normal, x.shape))

    def _at(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(p(t), n(t)): a point and the unit normal of the moved plane."""
        R = self.motion.matrix(t)
        if R is None:
            return self._point(t), self._n0
        return self._point(t) + (R - np.eye(self.dim)) @ (self._p0 - self.motion.center), R @ self._n0

    def gaps(self, x: np.ndarray, t: float) -> np.ndarray:
        p, n = self._at(t)
        return (x - p) @ n

    def distance_scale(self, x: np.ndarray, t: float) -> float:
        """|x| and |p(t)| ((x - p) . n)."""
        return float(max(np.max(np.abs(x), initial=0.0), np.max(np.abs(self._at(t)[0]))))

    def body_normals(self, x: np.ndarray, t: float) -> np.ndarray:
        """-n(t) at every point (the plane's normal, turned with it)."""
        return np.broadcast_to(-self._at(t)[1], np.shape(x)).copy()

    def body_inside_message(self, share: float) -> str:
        return (
            f"the body lies on the obstacle's side of the plane ({100 * share:.0f}% of its nodes): the plane's "
            f"normal must point out of the obstacle, towards the body; flip 'normal' (now "
            f"{np.round(self.normal, 6).tolist()}) or move 'point'"
        )

    def node_inside_message(self, where: str, gap: float, points: np.ndarray, point: np.ndarray) -> str:
        inside = np.mean(self.gaps(points, 0.0) < 0)
        if inside > 0.5:
            return (
                f"the body lies on the obstacle's side of the plane ({100 * inside:.0f}% of its nodes, "
                f"e.g. {where}, gap {gap:.3g} < 0): the plane's normal must point out of the obstacle, "
                f"towards the body; flip 'normal' (now {np.round(self.normal, 6).tolist()}) or move 'point'"
            )
        return (
            f"{where} starts inside the obstacle (gap {gap:.3g} < 0): move the plane's 'point' so that the "
            "body starts on the side its 'normal' points to"
        )


class SphereObstacle(RigidObstacle):
    """A rigid ball (disc in 2D) of centre c(t) and radius R; the body stays outside:
    phi(x, t) = |x - c(t)| - R, grad phi = (x - c)/|x - c|.

    ``rotation``: the ball turns about the axis through ``rotation.center`` (default: its
    own centre at t = 0, a spinning ball: the gaps do not change, the friction slip does),
    moving with the centre: c(t) = center(t) + (R(t) - I)(center(0) - c_axis).
    """

    def __init__(self, center: Position, radius: float, rotation: Rotation | Mapping | None = None):
        try:
            radius = float(radius)
        except (TypeError, ValueError):
            raise InputError(f"obstacle radius must be a number, got {radius!r}") from None
        if not np.isfinite(radius) or radius <= 0:
            raise InputError(f"obstacle radius must be > 0, got {radius}")
        self._center = _position("center", center)
        c0 = self._center(0.0)
        self.dim = c0.size
        self._c0 = c0
        self.motion = RigidMotion(c0.size, self._center, rotation, c0, relative=True)
        self.center, self.radius = self._at(0.0), radius
        self.moving = self.motion.moving

        def grad(x):
            r = x - self.center
            return r / np.linalg.norm(r, axis=1, keepdims=True)

        super().__init__(lambda x: np.linalg.norm(x - self.center, axis=1) - self.radius, grad)

    def _at(self, t: float) -> np.ndarray:
        """The centre c(t) of the moved ball."""
        R = self.motion.matrix(t)
        if R is None:
            return self._center(t)
        return self._center(t) + (R - np.eye(self.dim)) @ (self._c0 - self.motion.center)

    def gaps(self, x: np.ndarray, t: float) -> np.ndarray:
        return np.linalg.norm(x - self._at(t), axis=1) - self.radius

    def distance_scale(self, x: np.ndarray, t: float) -> float:
        """|x - c(t)| and |c(t)| (the distance to the centre, less the radius)."""
        c = self._at(t)
        return float(max(np.max(np.linalg.norm(x - c, axis=1), initial=0.0), np.max(np.abs(c)), self.radius))

    def body_normals(self, x: np.ndarray, t: float) -> np.ndarray:
        """-(x - c(t)) / |x - c(t)|: towards the ball's centre."""
        r = np.asarray(x, dtype=float) - self._at(t)
        return -r / np.linalg.norm(r, axis=1)[:, None]

    def body_inside_message(self, share: float) -> str:
        return (
            f"{100 * share:.0f}% of the body's nodes lie inside the ball (radius {self.radius:.6g}): the body must "
            "start outside the sphere obstacle; move 'center' or reduce 'radius'"
        )

    def node_inside_message(self, where: str, gap: float, points: np.ndarray, point: np.ndarray) -> str:
        d = float(np.linalg.norm(point - self.center))
        return (
            f"{where} starts inside the ball (distance {d:.6g} from the centre < radius {self.radius:.6g}): "
            "the body must start outside the sphere obstacle; move 'center' or reduce 'radius'"
        )


# ----------------------------------------------------------------------------- surfaces
#: nearest facet centres tried first per point and size class; then x4 per round up to
#: MAX_CANDIDATES for the points whose closest facet is not yet certain
CANDIDATES = 8
MAX_CANDIDATES = 32
#: a point whose closest point on the surface lies on its open boundary, laterally off it by
#: more than this x the surface's size, faces nothing (the value of pairs.OFF_SURFACE)
OFF_SURFACE = 1e-6
#: facets of length (2D) or area (3D) below this x size^(d-1) are degenerate
DEGENERATE = 1e-12
#: vertices closer than this x the surface's size are one (:func:`_weld`)
WELD = 1e-10
#: cell types of a surface: 2D segments, 3D triangles (quadrilaterals are split in two)
SURFACE_CELLS = {2: ("line",), 3: ("triangle", "quad")}


def read_surface(source: Any, dim: int | None = None, where: str = "surface obstacle") -> tuple[np.ndarray, np.ndarray]:
    """The vertices (nv, d) and facets (nf, d) of a rigid surface, checked.

    ``source``: a file name meshio reads (STL, OBJ, Gmsh ``.msh``, VTK, ...), a
    ``meshio.Mesh``, or ``(points, cells)`` arrays.  In 3D the facets are the triangles
    (and quadrilaterals, split along their 0-2 diagonal) of the file, its lines and points
    ignored; in 2D the line segments (the points must lie in one plane z = const).  ``dim``
    None: 3D if the file has triangles or quadrilaterals, else 2D.  A facet keeps the order
    of its vertices (its orientation, :class:`SurfaceObstacle`); vertices within 1e-10 of the
    surface's size of each other are merged (a triangle soup becomes a connected surface).  Refused with an
    :class:`InputError` that starts with ``where``: a missing or unreadable file, no facet of
    the dimension, out-of-range vertex numbers, non-finite points, degenerate facets.
    """
    if isinstance(source, (str, os.PathLike)):
        mesh = _read_file(Path(source), where)
        points = np.asarray(mesh.points, dtype=float)
        blocks = [(b.type, np.asarray(b.data)) for b in mesh.cells]
        what = f"{where}: {str(source)!r}"
    elif hasattr(source, "points") and hasattr(source, "cells"):  # a meshio.Mesh
        points = np.asarray(source.points, dtype=float)
        blocks = [(b.type, np.asarray(b.data)) for b in source.cells]
        what = where
    elif isinstance(source, (tuple, list)) and len(source) == 2:
        points = np.asarray(source[0], dtype=float)
        cells = np.asarray(source[1])
        kinds = {2: "line", 3: "triangle", 4: "quad"}
        if cells.ndim != 2 or cells.shape[1] not in kinds:
            raise InputError(
                f"{where}: cells must be an (nf, 2) array of segments or (nf, 3) of triangles, got shape {cells.shape}"
            )
        blocks = [(kinds[cells.shape[1]], cells)]
        what = where
    else:
        raise InputError(f"{where}: give a file name, a meshio.Mesh or (points, cells) arrays, got {source!r:.60}")
    if points.ndim != 2 or points.shape[1] not in (2, 3) or not len(points):
        raise InputError(f"{what}: the points must be an (n, 2) or (n, 3) array, got shape {points.shape}")
    kinds = {t for t, _ in blocks}
    if dim is None:
        dim = 3 if kinds & set(SURFACE_CELLS[3]) else 2
    if dim not in SURFACE_CELLS:
        raise InputError(f"{what}: a surface obstacle needs a 2D or 3D body, not {dim}D (use a plane)")
    wanted = SURFACE_CELLS[dim]
    found = [(t, c) for t, c in blocks if t in wanted and len(c)]
    if not found:
        other = sorted(kinds) or ["none"]
        need = "line segments" if dim == 2 else "triangles or quadrilaterals"
        raise InputError(
            f"{what}: no facets for a {dim}D body (it needs {need}; the file has cells {', '.join(other)})"
        )
    parts = []
    for t, c in found:  # one block per cell type (at most two)
        c = np.asarray(c)
        if not np.issubdtype(c.dtype, np.integer):
            raise InputError(f"{what}: the {t} cells must hold vertex numbers (integers)")
        parts.append(np.concatenate([c[:, [0, 1, 2]], c[:, [0, 2, 3]]]) if t == "quad" else c)
    facets = np.concatenate(parts).astype(np.int64)
    out = (facets < 0) | (facets >= len(points))
    if out.any():
        raise InputError(
            f"{what}: facet {int(np.flatnonzero(out.any(axis=1))[0])} refers to vertex "
            f"{int(facets[out][0])}, out of 0 .. {len(points) - 1}"
        )
    if not np.all(np.isfinite(points)):
        raise InputError(f"{what}: non-finite point coordinates")
    if points.shape[1] < dim:
        raise InputError(f"{what}: wrong dimension: {points.shape[1]}D points for a {dim}D body")
    if points.shape[1] > dim:
        extra = points[:, dim:]
        scale = float(np.abs(points).max()) or 1.0
        if np.ptp(extra, axis=0).max() > 1e-12 * scale:
            raise InputError(
                f"{what}: wrong dimension: the points of a 2D surface must lie in one plane z = const "
                f"(z spans {float(extra.min()):.6g} .. {float(extra.max()):.6g})"
            )
        points = np.ascontiguousarray(points[:, :dim])
    size = float(np.linalg.norm(np.ptp(points[np.unique(facets)], axis=0))) or 1.0
    facets = _weld(points, facets, WELD * size)
    P = points[facets]
    measure = _facet_normals(P)[1]
    bad = measure <= DEGENERATE * size ** (dim - 1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        what_m = "length" if dim == 2 else "area"
        raise InputError(
            f"{what}: {int(bad.sum())} degenerate facet(s) of zero {what_m}, e.g. facet {i} with vertices "
            f"{np.round(P[i], 6).tolist()}"
        )
    return points, facets


def _weld(points: np.ndarray, facets: np.ndarray, r: float) -> np.ndarray:
    """Facets (nf, d) renumbered so that points within r of each other (chains of them) are one
    vertex, the first of them: a triangle soup (every facet with its own vertices, as in STL
    files) becomes a connected surface whose open boundary is its real one."""
    pairs = cKDTree(points).query_pairs(r, output_type="ndarray")
    if not len(pairs):
        return facets
    n = len(points)
    graph = sp.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    label = connected_components(graph, directed=False)[1]
    first = np.full(label.max() + 1, n)
    np.minimum.at(first, label, np.arange(n))
    return first[label][facets]


def _read_file(path: Path, where: str):
    from ..fem.mesh import meshio_read

    if not path.is_file():
        raise InputError(f"{where}: {str(path)!r} {not_a_file(path, 'a surface mesh file')}")
    if path.stat().st_size == 0:
        raise InputError(f"{where}: {str(path)!r} is empty (0 bytes)")
    try:
        return meshio_read(path, "surface mesh file")
    except MeshError as exc:
        raise InputError(f"{where}: {str(exc).strip().splitlines()[0]}") from None


def _facet_normals(P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit normals (nf, d) and lengths / areas (nf,) of facets P (nf, d, d).

    2D segment (a, b): n = (b - a) turned clockwise by 90 degrees, (t_y, -t_x) / |t|, the
    outward normal of a counterclockwise polygon; 3D triangle (a, b, c): (b - a) x (c - a)
    normalized, outward when the vertices turn counterclockwise seen from outside (STL).
    """
    if P.shape[1] == 2:
        t = P[:, 1] - P[:, 0]
        n = np.column_stack([t[:, 1], -t[:, 0]])
        measure = np.linalg.norm(t, axis=1)
    else:
        n = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
        measure = 0.5 * np.linalg.norm(n, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return n / np.linalg.norm(n, axis=1)[:, None], measure


class SurfaceObstacle(RigidObstacle):
    """A rigid triangulated (3D) or polygonal (2D) surface, moving rigidly.

    Parameters
    ----------
    file : a file meshio reads (STL, OBJ, ``.msh``, VTK, ...), a ``meshio.Mesh`` or
        ``(points, cells)``: points (nv, d) (or (nv, 3) with z constant in 2D), cells (nf, 2)
        segments (2D) or (nf, 3) triangles (3D); :func:`read_surface`.
    translation : d(t) (d,) [length], a constant or a function of t (default 0): the surface
        is at Phi_t(X) = X + d(t) + (R(t) - I)(X - c) (module docstring).
    rotation : :class:`Rotation` (or a dict); its ``center`` is required.
    flip : reverse every facet's orientation (the other side is outside).
    dim : the body's dimension (None: from the file).

    Orientation: a facet's normal n_f points out of the obstacle, towards the body: in 3D
    (b - a) x (c - a) for the triangle (a, b, c) (counterclockwise seen from the body, STL's
    rule), in 2D the segment (a, b) turned clockwise, (t_y, -t_x) with t = b - a (the
    outward normal of a polygon around the obstacle listed counterclockwise).  ``flip``
    reverses them; a body that starts mostly on the side the normals do not point to is
    refused (:func:`~signorini.dynamics.model.problem.discretize`).

    Signed distance (in the surface's own coordinates y = Phi_t^{-1}(x)): the closest point
    p of the surface (candidates: the nearest facet centres in a KD-tree per class of facet
    size, then the exact closest point on each, :func:`~signorini.contact.pairs._closest_on_facets`;
    more candidates until no unseen facet can be closer: certainly exact within about 3 facet
    sizes of the surface on a uniform triangulation (measured), beyond that the closest of the
    :data:`MAX_CANDIDATES` nearest centres per class, an upper bound of the distance that is
    exact in practice on smooth surfaces; a few 10 us per point), and

        phi = (y - p) . n_f                     p inside facet f (laterally on it, to 1e-6 x size)
        phi = s |y - p|, s = sign((y - p) . n_f) p on an edge or corner shared by facets
        phi = +inf                              p on the open boundary of the surface: the point
                                                is laterally beyond the surface's edge and faces
                                                nothing

    with grad phi = n_f, resp. s (y - p) / |y - p|.  At an edge or corner, of the facets at
    the same distance the one whose plane is farthest, max |(y - p) . n_f|, gives the sign
    (right for every convex or concave edge).  Contact nodes beyond the edge at t = 0 get no
    row (:meth:`~signorini.contact.contact_set.ContactSet.from_tag`, counted in
    ``summary.json`` ``obstacle``); a row whose node the moving surface leaves (its gap
    becomes infinite) stops the run (``ConvergenceError``: extend the surface).
    """

    side_first = True

    def __init__(
        self,
        file: Any,
        translation: Position | None = None,
        rotation: Rotation | Mapping | None = None,
        flip: bool = False,
        dim: int | None = None,
    ):
        vertices, facets = read_surface(file, dim)
        if not isinstance(flip, (bool, np.bool_)):
            raise InputError(f"surface obstacle flip must be true or false, got {flip!r}")
        d = vertices.shape[1]
        self.dim = d
        if flip:
            facets = facets[:, ::-1].copy()
        self.vertices, self.facets, self.flipped = vertices, facets, bool(flip)
        P = vertices[facets]
        self._P = P
        self.normals = _facet_normals(P)[0]
        self._kind = "line" if d == 2 else "triangle"
        self.size = float(np.linalg.norm(np.ptp(vertices[np.unique(facets)], axis=0))) or 1.0
        self._off = OFF_SURFACE * self.size
        self._tie = 1e-12 * max(self.size, float(np.abs(vertices).max()))
        centres = P.mean(axis=1)
        reach = np.linalg.norm(P - centres[:, None, :], axis=2).max(axis=1)
        self._reach, self._centres = reach, centres
        # size classes (factors of 4 of the reach): a large facet does not make the search of
        # the small ones exhaustive
        level = np.floor(np.log(reach / reach.min()) / np.log(4.0)).astype(np.int64)
        self._classes = []
        for lv in np.unique(level):  # a few classes, not facets
            ids = np.flatnonzero(level == lv)
            self._classes.append((cKDTree(centres[ids]), ids, float(reach[ids].max())))
        self._boundary_flags(vertices.shape[0])
        shift = _position("translation", np.zeros(d) if translation is None else translation, d)
        self.motion = RigidMotion(d, shift, rotation, None, relative=False)
        self.moving = self.motion.moving
        super().__init__(lambda x: self.gaps_and_normals(x)[0], lambda x: -self.gaps_and_normals(x)[1])

    def _boundary_flags(self, nv: int) -> None:
        """Which facet edges (3D) and vertices lie on the open boundary of the surface (used by one facet)."""
        f = self.facets
        if self.dim == 2:
            self._edge_open = None
            self._vertex_open = np.bincount(f.ravel(), minlength=nv) == 1
            return
        edges = np.stack([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]], axis=1)  # (nf, 3, 2): edge j = (j, j + 1)
        key = np.sort(edges, axis=2)
        key = key[..., 0] * nv + key[..., 1]
        _, inverse, counts = np.unique(key.ravel(), return_inverse=True, return_counts=True)
        self._edge_open = (counts[inverse] == 1).reshape(key.shape)
        vertex_open = np.zeros(nv, dtype=bool)
        vertex_open[edges[self._edge_open].ravel()] = True
        self._vertex_open = vertex_open

    def _pick(self, y: np.ndarray, rows: np.ndarray, facets: np.ndarray):
        """The closest of candidate pairs (rows (E,), facets (E,)) per row of y (m, d), every row
        having one pair at least: facet, point p, shape functions, distance and (y - p) . n_f,
        each (m, ...); ties (to 1e-12 x size) broken by the largest |(y - p) . n_f|."""
        from .pairs import _closest_on_facets

        p, N = _closest_on_facets(y[rows], self._P[facets], self._kind)
        r = y[rows] - p
        dist = np.linalg.norm(r, axis=1)
        dot = np.einsum("md,md->m", r, self.normals[facets])
        dmin = np.full(len(y), np.inf)
        np.minimum.at(dmin, rows, dist)
        score = np.where(dist <= dmin[rows] + self._tie, np.abs(dot), -1.0)
        order = np.lexsort((-score, rows))  # by row, the best score first
        first = order[np.r_[True, rows[order][1:] != rows[order][:-1]]]
        return facets[first], p[first], N[first], dist[first], dot[first]

    def _nearest(self, y: np.ndarray):
        """The closest facet of every point y (m, d) (own coordinates): facet (m,), p (m, d),
        N (m, d), distance (m,), (y - p) . n_f (m,).

        Per round, the k nearest facet centres of each size class are candidates; a candidate is
        evaluated exactly only if its lower bound (the distance to the disc of its plane, of radius
        its reach about its centre, that holds it) is at most the best distance so far (plus the tie
        tolerance, so that the facets at an edge all compete for the sign).  A row is done when, in
        every class, the facets not tried are farther than its best (the k-th centre distance less
        the class's reach); k x 4 per round up to :data:`MAX_CANDIDATES` (then the best found: an
        upper bound of the distance, exact in practice on smooth surfaces)."""
        m, d = y.shape
        facet = np.zeros(m, dtype=np.int64)
        p, N = np.zeros((m, d)), np.zeros((m, d))
        dist, dot = np.full(m, np.inf), np.zeros(m)
        rows, k = np.arange(m), CANDIDATES
        while rows.size:
            yr = y[rows]
            cols, dists, limits = [], [], []
            for tree, ids, reach in self._classes:  # a few size classes, not facets
                kc = min(k, ids.size)
                dk, ik = tree.query(yr, k=kc)
                dk, ik = np.asarray(dk).reshape(rows.size, kc), np.asarray(ik).reshape(rows.size, kc)
                cols.append(ids[ik])
                dists.append(dk)
                limits.append((kc == ids.size, dk[:, -1], reach))
            cand, dc = np.hstack(cols), np.hstack(dists)
            # facet f lies in its plane within the disc of radius reach_f about its centre c_f: the
            # distance to that disc, sqrt(h^2 + max(0, rho - reach_f)^2), is a lower bound
            h = np.einsum("mkd,mkd->mk", yr[:, None, :] - self._centres[cand], self.normals[cand])
            rho = np.sqrt(np.maximum(dc * dc - h * h, 0.0))
            lower = np.hypot(h, np.maximum(rho - self._reach[cand], 0.0))
            if not np.isfinite(dist[rows]).any():  # first round: the nearest centre of the first class sets a bound
                f0, p0, N0, d0, t0 = self._pick(yr, np.arange(rows.size), cand[:, 0])
                facet[rows], p[rows], N[rows], dist[rows], dot[rows] = f0, p0, N0, d0, t0
            r_loc, c_loc = np.nonzero(lower <= dist[rows][:, None] + self._tie)
            r_loc = np.concatenate([np.arange(rows.size), r_loc])  # the best so far competes again
            f_all = np.concatenate([facet[rows], cand[r_loc[rows.size :], c_loc]])
            f, pp, NN, dd, tt = self._pick(yr, r_loc, f_all)
            facet[rows], p[rows], N[rows], dist[rows], dot[rows] = f, pp, NN, dd, tt
            sure = np.ones(rows.size, dtype=bool)
            for complete, kth, reach in limits:
                if not complete:
                    sure &= kth - reach >= dd
            rows = rows[~sure]
            k *= 4
            if k > MAX_CANDIDATES:
                break
        return facet, p, N, dist, dot

    def _signed(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """phi (m,), unit grad phi (m, d) and closest points p (m, d) at points y (m, d) in the
        surface's own coordinates (class docstring); phi = +inf beyond the open boundary."""
        y = np.asarray(y, dtype=float).reshape(-1, self.dim)
        finite = np.isfinite(y).all(axis=1)
        if not finite.all():  # a state that is not finite: nan where it is (as a plane's distance)
            out = (np.full(len(y), np.nan), np.full(y.shape, np.nan), np.full(y.shape, np.nan))
            for a, b in zip(out, self._signed(y[finite]), strict=True):
                a[finite] = b
            return out
        if not len(y):
            return np.zeros(0), np.zeros((0, self.dim)), np.zeros((0, self.dim))
        facet, p, N, dist, dot = self._nearest(y)
        n = self.normals[facet]
        r = y - p
        lateral = np.linalg.norm(r - dot[:, None] * n, axis=1)
        phi, grad = dot.copy(), n.copy()
        edge = lateral > self._off
        if edge.any():
            open_ = self._on_open_boundary(facet[edge], N[edge])
            off = np.flatnonzero(edge)[open_]
            inner = np.flatnonzero(edge)[~open_]
            s = np.where(dot[inner] < 0.0, -1.0, 1.0)
            phi[inner] = s * dist[inner]
            grad[inner] = (s / dist[inner])[:, None] * r[inner]
            phi[off] = np.inf
        return phi, grad, p

    def _on_open_boundary(self, facet: np.ndarray, N: np.ndarray) -> np.ndarray:
        """Whether closest points on the boundary of their facet (shape functions N with exact
        zeros) lie on the surface's open boundary: a vertex used by one segment (2D), an edge
        of one triangle or a vertex of such an edge (3D)."""
        zero = N == 0.0
        if self.dim == 2:
            v = np.where(zero[:, 1], self.facets[facet, 0], self.facets[facet, 1])
            return self._vertex_open[v]
        nz = zero.sum(axis=1)
        k = np.argmax(zero, axis=1)  # the zero vertex: the point is on edge (k + 1, k + 2) = edge k + 1
        on_edge = self._edge_open[facet, (k + 1) % 3]
        v = self.facets[facet, np.argmax(N, axis=1)]
        return np.where(nz >= 2, self._vertex_open[v], on_edge & (nz == 1))

    def gaps_and_normals(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Gaps g (n,) (+inf beyond the surface's edge) and body normals nu = -grad phi (n, d) at t = 0."""
        phi, grad, _ = self._signed(self.motion.to_data(np.asarray(x, dtype=float), 0.0))
        return phi, -self.motion.to_world(grad, 0.0)

    def gaps(self, x: np.ndarray, t: float) -> np.ndarray:
        """phi(x, t) (n,) of the surface at time t at points x (n, d); +inf beyond its edge."""
        return self._signed(self.motion.to_data(np.asarray(x, dtype=float), t))[0]

    def body_normals(self, x: np.ndarray, t: float) -> np.ndarray:
        """-grad phi at the points x at time t: the facet's normal, or the direction to the closest edge or
        vertex (turned with the surface)."""
        return -self.motion.to_world(self._signed(self.motion.to_data(np.asarray(x, dtype=float), t))[1], t)

    def material_points(self, x: np.ndarray) -> np.ndarray:
        return self._signed(self.motion.to_data(np.asarray(x, dtype=float), 0.0))[2]

    def body_inside_message(self, share: float) -> str:
        return (
            f"the body lies on the obstacle's side of the surface ({100 * share:.0f}% of the nodes that face it): "
            "the facets' normals must point out of the obstacle, towards the body (3D: triangles counterclockwise "
            "seen from the body; 2D: segments a -> b with the body on their right); set "
            f"flip = {'false' if self.flipped else 'true'} or move the surface"
        )

    def node_inside_message(self, where: str, gap: float, points: np.ndarray, point: np.ndarray) -> str:
        return (
            f"{where} starts inside the surface obstacle (gap {gap:.3g} < 0): the body must start on the side "
            "its facets' normals point to; move the surface ('translation') or the body"
        )


OBSTACLES = Registry("obstacle type")
_ROTATION_DOC = (
    "rigid rotation { angle = theta(t), axis = [...] (3D), center = [...] } (see the rotation keys); none: no rotation"
)
OBSTACLES.register(
    "plane",
    PlaneObstacle,
    "half-space {(x - point) . normal < 0}; normal points from the obstacle towards the body",
    parameters=(
        Parameter("point", None, "a point of the plane; may depend on t (moving plane)", Motion),
        Parameter("normal", None, "normal pointing out of the obstacle, towards the body", Vector),
        Parameter(
            "rotation",
            "none",
            _ROTATION_DOC + "; the axis passes through center (default point at t = 0) and moves with point",
            RotationTable,
        ),
    ),
)
OBSTACLES.register(
    "sphere",
    SphereObstacle,
    "rigid ball (disc in 2D) the body stays outside of",
    parameters=(
        Parameter("center", None, "centre; may depend on t (moving ball)", Motion),
        Parameter("radius", None, "radius [length]", float, 0.0, open_low=True),
        Parameter(
            "rotation",
            "none",
            _ROTATION_DOC + "; the axis passes through center (default the ball's centre "
            "at t = 0: a spinning ball) and moves with it",
            RotationTable,
        ),
    ),
)
OBSTACLES.register(
    "surface",
    SurfaceObstacle,
    "rigid triangulated (3D) or polygonal (2D: segments) surface from a mesh file; facet normals point out of "
    "the obstacle, towards the body; nodes beyond its edge face nothing",
    parameters=(
        Parameter(
            "file",
            None,
            "mesh file meshio reads (STL, OBJ, .msh, VTK, ...), relative to the case file: "
            "triangles or quadrilaterals in 3D, line segments in 2D",
            FilePath,
        ),
        Parameter("translation", 0.0, "displacement d(t) of the surface, a vector; may depend on t", Motion),
        Parameter(
            "rotation", "none", _ROTATION_DOC + "; center required, the axis moves with the translation", RotationTable
        ),
        Parameter("flip", False, "reverse the facets' orientation (the other side is outside)", bool),
    ),
)

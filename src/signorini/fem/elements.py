"""Reference Lagrange elements and Gauss quadrature.

Every element is described by its reference nodes, shape functions ``N_a(xi)`` and
their gradients evaluated at a quadrature rule exact for the products needed by the
mass matrix (degree 2 per direction for Q1, degree 2 for P1 simplices).

Node orderings follow meshio / VTK:

``line``        0 --- 1 on [0, 1]
``quad``        (-1,-1), (1,-1), (1,1), (-1,1) on [-1, 1]^2
``hexahedron``  bottom face (z=-1) counter-clockwise, then top face (z=+1)
``triangle``    (0,0), (1,0), (0,1)
``tetra``       (0,0,0), (1,0,0), (0,1,0), (0,0,1)
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import cache

import numpy as np

_G2 = np.array([-1.0, 1.0]) / np.sqrt(3.0)


@dataclass(frozen=True)
class ReferenceElement:
    """A reference element with a quadrature rule.

    Attributes
    ----------
    name : meshio cell-type name.
    dim : topological dimension.
    nodes : (nv, dim) reference coordinates of the nodes.
    points : (nq, dim) quadrature points.
    weights : (nq,) quadrature weights (sum = reference volume).
    N : (nq, nv) shape functions at the quadrature points.
    dN : (nq, nv, dim) reference gradients at the quadrature points.
    facets : local node indices of each facet, ordered so that the facet normal
        computed from them points outwards (used when extracting boundaries).
    constant_gradients : whether the shape functions are linear (P1): their gradients, and so any
        deformation gradient, are constant on a cell, and one quadrature point integrates a function of
        them exactly (finite strain's force and tangent use it).
    """

    name: str
    dim: int
    nodes: np.ndarray
    points: np.ndarray
    weights: np.ndarray
    N: np.ndarray
    dN: np.ndarray
    facets: tuple[tuple[int, ...], ...]
    constant_gradients: bool = False

    @property
    def n_nodes(self) -> int:
        return self.nodes.shape[0]


def _tensor_gauss(dim: int) -> tuple[np.ndarray, np.ndarray]:
    grids = np.meshgrid(*([_G2] * dim), indexing="ij")
    pts = np.stack([g.ravel() for g in grids], axis=1)
    return pts, np.ones(pts.shape[0])


def _q1(nodes: np.ndarray, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Multilinear shape functions on [-1,1]^d: prod_k (1 + xi_k s_k)/2."""
    d = nodes.shape[1]
    fac = (1.0 + pts[:, None, :] * nodes[None, :, :]) / 2.0  # (nq, nv, d)
    N = np.prod(fac, axis=2)
    dN = np.empty(pts.shape[:1] + nodes.shape)
    for k in range(d):
        others = np.prod(np.delete(fac, k, axis=2), axis=2)
        dN[:, :, k] = nodes[None, :, k] / 2.0 * others
    return N, dN


def _p1(dim: int, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Barycentric shape functions N_0 = 1 - sum xi, N_k = xi_k."""
    N = np.column_stack([1.0 - pts.sum(axis=1), pts])
    g = np.vstack([-np.ones(dim), np.eye(dim)])
    dN = np.broadcast_to(g, (pts.shape[0], dim + 1, dim)).copy()
    return N, dN


def _vertex() -> ReferenceElement:
    return ReferenceElement("vertex", 0, np.zeros((1, 0)), np.zeros((1, 0)), np.ones(1), np.ones((1, 1)),
                            np.zeros((1, 1, 0)), (), True)  # fmt: skip


def _line() -> ReferenceElement:
    nodes = np.array([[0.0], [1.0]])
    pts = ((_G2 + 1.0) / 2.0)[:, None]
    N = np.column_stack([1.0 - pts[:, 0], pts[:, 0]])
    dN = np.broadcast_to(np.array([[-1.0], [1.0]]), (2, 2, 1)).copy()
    return ReferenceElement("line", 1, nodes, pts, np.full(2, 0.5), N, dN, ((0,), (1,)), True)


def _quad() -> ReferenceElement:
    nodes = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])
    pts, w = _tensor_gauss(2)
    N, dN = _q1(nodes, pts)
    return ReferenceElement("quad", 2, nodes, pts, w, N, dN, ((0, 1), (1, 2), (2, 3), (3, 0)), False)


def _hexahedron() -> ReferenceElement:
    b = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])
    nodes = np.vstack([np.column_stack([b, -np.ones(4)]), np.column_stack([b, np.ones(4)])])
    pts, w = _tensor_gauss(3)
    N, dN = _q1(nodes, pts)
    facets = ((0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7))
    return ReferenceElement("hexahedron", 3, nodes, pts, w, N, dN, facets, False)


def _triangle() -> ReferenceElement:
    nodes = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    pts = np.array([[1 / 6, 1 / 6], [2 / 3, 1 / 6], [1 / 6, 2 / 3]])
    N, dN = _p1(2, pts)
    return ReferenceElement("triangle", 2, nodes, pts, np.full(3, 1 / 6), N, dN, ((0, 1), (1, 2), (2, 0)), True)


def _tetra() -> ReferenceElement:
    nodes = np.vstack([np.zeros(3), np.eye(3)])
    a, b = 0.5854101966249685, 0.1381966011250105
    pts = np.array([[b, b, b], [a, b, b], [b, a, b], [b, b, a]])
    N, dN = _p1(3, pts)
    facets = ((0, 2, 1), (0, 1, 3), (1, 2, 3), (0, 3, 2))
    return ReferenceElement("tetra", 3, nodes, pts, np.full(4, 1 / 24), N, dN, facets, True)


@dataclass(frozen=True)
class CellKind:
    """A registered cell type: its reference element's builder and the type of its facets."""

    build: Callable[[], ReferenceElement]
    facet: str


#: the cell types signorini meshes (meshio names) -> builder and facet type: the only place that lists them (a
#: quadratic element is one more entry); ``vertex`` is the facet of a line
ELEMENTS: dict[str, CellKind] = {
    "line": CellKind(_line, "vertex"),
    "quad": CellKind(_quad, "line"),
    "triangle": CellKind(_triangle, "line"),
    "hexahedron": CellKind(_hexahedron, "quad"),
    "tetra": CellKind(_tetra, "triangle"),
}


@cache
def reference_element(name: str) -> ReferenceElement:
    """The reference element of a meshio cell-type name (:data:`ELEMENTS`, or ``vertex``); KeyError otherwise."""
    if name == "vertex":
        return _vertex()
    return ELEMENTS[name].build()


SUPPORTED_CELLS = tuple(ELEMENTS)
FACET_TYPES = {name: kind.facet for name, kind in ELEMENTS.items()}


def jacobians(dN: np.ndarray, X: np.ndarray) -> np.ndarray:
    """J[e, q, i, k] = dx_i / dxi_k = sum_a X[e, a, i] dN[q, a, k] for every element.

    ``dN`` (nq, nv, k) are the reference gradients, ``X`` (ne, nv, d) the element node
    coordinates.  One matrix product (ne d, nv) x (nv, nq k) instead of a batched
    ``einsum``: about 3x faster on 300k hexahedra.
    """
    ne, nv, d = X.shape
    nq, _, k = dN.shape
    prod = X.transpose(0, 2, 1).reshape(ne * d, nv) @ dN.transpose(1, 0, 2).reshape(nv, nq * k)
    return prod.reshape(ne, d, nq, k).transpose(0, 2, 1, 3)


def determinants(J: np.ndarray) -> np.ndarray:
    """det J over the last two axes (square, size 1, 2 or 3), by the cofactor formulas
    (faster than batched LU for many small matrices); other sizes through LAPACK."""
    n = J.shape[-1]
    if n == 1:
        return J[..., 0, 0].copy()
    if n == 2:
        return J[..., 0, 0] * J[..., 1, 1] - J[..., 0, 1] * J[..., 1, 0]
    if n == 3:
        a, b, c = J[..., 0, 0], J[..., 0, 1], J[..., 0, 2]
        d, e, f = J[..., 1, 0], J[..., 1, 1], J[..., 1, 2]
        g, h, i = J[..., 2, 0], J[..., 2, 1], J[..., 2, 2]
        return a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)
    return np.linalg.det(J)

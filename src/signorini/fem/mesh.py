"""Meshes: points, one block of cells, named boundary facets and named regions of cells.

Generators
----------
``interval(n, length)``            P1 segments on [x0, x0 + length]; tags ``xmin``, ``xmax``.
``rectangle(nx, ny, lx, ly)``       Q1 quads (``cell="quad"``) or P1 triangles
                                    (``cell="triangle"``, two per square); tags ``xmin``,
                                    ``xmax``, ``ymin``, ``ymax``.
``box(nx, ny, nz, lx, ly, lz)``     Q1 hexahedra or P1 tetrahedra (``cell="tetra"``, six
                                    per cube); tags ``xmin`` ... ``zmax``.

A tag names a set of boundary facets (points in 1D, segments in 2D, faces in 3D); the
nodes of a tag are the nodes of its facets.  A region names a set of cells (a part of
the body, or a whole body, with its own material or initial data).  :func:`read_mesh`
reads any format meshio knows and turns Gmsh physical groups of facets into tags and
physical groups of cells (volumes in 3D, surfaces in 2D) into regions.
"""

from __future__ import annotations

import contextlib
import io
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import MeshError, not_a_file
from .elements import (
    FACET_TYPES,
    QUADRATIC,
    SUPPORTED_CELLS,
    determinants,
    jacobians,
    node_parents,
    reference_element,
    shape_functions,
)


@dataclass(frozen=True)
class CellBlock:
    """The cells of one type: ``cells`` (k, nv) node indices, numbered ``start`` .. ``start + k - 1``
    in the mesh."""

    cell_type: str
    cells: np.ndarray
    start: int

    @property
    def stop(self) -> int:
        return self.start + self.cells.shape[0]


@dataclass
class Mesh:
    """An unstructured mesh: one cell type, or several (a mixed mesh).

    Attributes
    ----------
    points : (n_nodes, dim) float array, coordinates in length units.
    cells : (n_cells, nv) int array, node indices (meshio ordering); None for a mixed mesh,
        whose cells are in :attr:`blocks`.
    cell_type : ``line``, ``quad``, ``triangle``, ``hexahedron`` or ``tetra`` (quadratic: ``line3``,
        ``quad9``, ``triangle6``, ``hexahedron27``, ``tetra10``); ``mixed`` for several.  A mixed mesh
        is given as lists: ``Mesh(points, [tets, hexes], ["tetra", "hexahedron"])``; its cells are
        numbered block after block.
    facets : dict tag -> (n_facets, nfv) int array of boundary facets.
    grid : for structured tensor-product meshes made by the generators, the 1D node
        coordinates along x, y (, z); node ``i + (nx+1) (j + (ny+1) k)`` sits at
        ``(grid[0][i], grid[1][j], grid[2][k])``.  ``None`` for general meshes.
    node_ids : (n_nodes,) int array or None: the user's number of every node when the mesh
        was renumbered for a run on several ranks (:mod:`signorini.fem.node_order`);
        messages name nodes by it (:meth:`node_id`).  ``None``: the numbers are the user's.
    regions : dict tag -> (k,) int array of cell indices (sorted, each cell once per region);
        a cell may belong to several regions or to none.
    order : 1 (linear cells) or 2 (quadratic), from the cell types (set on construction).
    """

    points: np.ndarray
    cells: np.ndarray
    cell_type: str
    facets: dict[str, np.ndarray] = field(default_factory=dict)
    grid: tuple[np.ndarray, ...] | None = None
    node_ids: np.ndarray | None = None
    regions: dict[str, np.ndarray] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.points = np.ascontiguousarray(self.points, dtype=float)
        if self.points.ndim == 1:
            self.points = self.points[:, None]
        self._blocks: list[CellBlock] | None = None
        if isinstance(self.cell_type, (list, tuple)):  # blocks of cells, maybe of several types
            types, arrays = list(self.cell_type), list(self.cells)
            if len(types) != len(arrays) or not types:
                raise MeshError(
                    f"a mesh of blocks needs one cell type per block, got {len(types)} types for {len(arrays)} blocks"
                )
            if len(set(types)) == 1:  # one type after all: one block
                self.cell_type, self.cells = types[0], np.vstack([np.asarray(a) for a in arrays])
            else:
                self._blocks = self._make_blocks(types, arrays)
                self.cells, self.cell_type = None, "mixed"
                self._finish_post_init()
                return
        cells = np.asarray(self.cells)
        if cells.dtype.kind not in "iu":
            if cells.dtype.kind != "f" or not np.all(cells == np.round(cells)):
                raise MeshError(f"cells must be integer node indices, got {cells.dtype} such as {cells.flat[:3]}")
        self.cells = np.ascontiguousarray(cells, dtype=np.int64)
        if self.cell_type not in SUPPORTED_CELLS:
            raise MeshError(f"unsupported cell type {self.cell_type!r}; supported: {', '.join(SUPPORTED_CELLS)}")
        ref = reference_element(self.cell_type)
        if self.points.shape[1] != ref.dim:
            raise MeshError(f"cell type {self.cell_type!r} needs {ref.dim}D points, got {self.points.shape[1]}D")
        if self.cells.ndim != 2 or self.cells.shape[1] != ref.n_nodes:
            raise MeshError(f"cells of type {self.cell_type!r} need {ref.n_nodes} nodes each")
        if self.cells.size and (self.cells.min() < 0 or self.cells.max() >= len(self.points)):
            raise MeshError("cells reference nodes that do not exist")
        self._finish_post_init()

    def _finish_post_init(self) -> None:
        if not np.all(np.isfinite(self.points)) or np.abs(self.points).max(initial=0.0) > 1e100:
            i = int(np.flatnonzero(~(np.abs(self.points) <= 1e100).all(axis=1))[0])
            raise MeshError(f"mesh node {i} has a non-finite or huge (> 1e100) coordinate {self.points[i].tolist()}")
        self.facets = {k: np.asarray(v, dtype=np.int64) for k, v in self.facets.items()}
        self.regions = {k: _region_cells(k, v, self.n_cells) for k, v in self.regions.items()}
        self._cache: dict = {}
        #: the polynomial order of the cells (1: linear, 2: quadratic; one order per mesh)
        self.order: int = reference_element(self.blocks[0].cell_type).order

    def _make_blocks(self, types: list[str], arrays: list) -> list[CellBlock]:
        """The blocks of a mixed mesh, each validated as the cells of a one-type mesh."""
        blocks, start = [], 0
        dims = set()
        for t, a in zip(types, arrays, strict=True):
            part = Mesh(self.points, a, t)  # the checks of one type (integers, node count, range)
            dims.add(reference_element(t).dim)
            blocks.append(CellBlock(t, part.cells, start))
            start += part.cells.shape[0]
        if len(dims) > 1:
            raise MeshError(f"the cell types {sorted(set(types))} of a mesh must have one dimension")
        if len({reference_element(t).order for t in types}) > 1:
            raise MeshError(
                f"the cell types {sorted(set(types))} of a mesh must have one order (linear and quadratic "
                "cells do not conform: elevate the whole mesh, signorini.fem.mesh.elevate)"
            )
        return blocks

    def cached(self, key: str, build: Callable[[], Any]) -> Any:
        """The mesh's ``key`` data (geometry, pattern, bodies, ...), built by ``build()`` once:
        a mesh is not changed after it is made, so what is computed from it is kept with it."""
        if key not in self._cache:
            self._cache[key] = build()
        return self._cache[key]

    @property
    def mixed(self) -> bool:
        """Several cell types (:attr:`blocks`; ``cells`` is None)."""
        return self._blocks is not None

    @property
    def blocks(self) -> list[CellBlock]:
        """The cells by type: one block for a one-type mesh."""
        if self._blocks is not None:
            return self._blocks
        return [CellBlock(self.cell_type, self.cells, 0)]

    def parts(self) -> list[tuple[Mesh, slice]]:
        """One one-type mesh per block (the same points, no tags) and the slice of its cells in
        this mesh's numbering: the assembly of a mixed mesh is the sum over its parts."""
        if self._blocks is None:  # itself (not cached: the mesh would hold itself, freed only by a full collection)
            return [(self, slice(0, self.n_cells))]
        if "parts" not in self._cache:
            self._cache["parts"] = [
                (Mesh(self.points, b.cells, b.cell_type), slice(b.start, b.stop)) for b in self._blocks
            ]
        return self._cache["parts"]

    def cell_nodes(self, cells: np.ndarray | None = None) -> np.ndarray:
        """Sorted unique nodes of the cells ``cells`` (indices; None: every cell)."""
        if self._blocks is None:
            return np.unique(self.cells if cells is None else self.cells[cells])
        out = []
        for b in self._blocks:
            if cells is None:
                out.append(b.cells.ravel())
            else:
                c = np.asarray(cells)
                mine = c[(c >= b.start) & (c < b.stop)] - b.start
                out.append(b.cells[mine].ravel())
        return np.unique(np.concatenate(out))

    def first_nodes(self) -> np.ndarray:
        """The first node of every cell (n_cells,): a cell's body is that node's."""
        return np.concatenate([b.cells[:, 0] for b in self.blocks])

    def node_id(self, i: int) -> int:
        """The user's number of node ``i``: its index in the mesh as read (meshio's points,
        unused points dropped) or as generated, whatever order the run uses."""
        return int(i) if self.node_ids is None else int(self.node_ids[i])

    def first_by_id(self, nodes: np.ndarray) -> int:
        """The position in ``nodes`` (node indices) of the node with the lowest user's number:
        the example a message names, the same whatever the run's node order."""
        nodes = np.asarray(nodes)
        return int(np.argmin(nodes if self.node_ids is None else self.node_ids[nodes]))

    @property
    def dim(self) -> int:
        return self.points.shape[1]

    @property
    def n_nodes(self) -> int:
        return self.points.shape[0]

    @property
    def n_cells(self) -> int:
        if self._blocks is not None:
            return self._blocks[-1].stop
        return self.cells.shape[0]

    @property
    def tags(self) -> list[str]:
        return sorted(self.facets)

    def cells_of(self, region: str | Sequence[str]) -> np.ndarray:
        """Sorted cell indices of a region (or of the union of several); a clear error for an
        unknown or empty region."""
        if not isinstance(region, str):
            return np.unique(np.concatenate([self.cells_of(r) for r in region])) if region else np.zeros(0, int)
        if region not in self.regions:
            known = ", ".join(sorted(self.regions)) or "none"
            raise MeshError(f"unknown region {region!r}; this mesh has: {known}")
        c = self.regions[region]
        if c.size == 0:
            raise MeshError(f"region {region!r} is empty")
        return c

    def region_nodes(self, region: str | Sequence[str]) -> np.ndarray:
        """Sorted unique node indices of the cells of ``region``."""
        return self.cell_nodes(self.cells_of(region))

    def facets_of(self, tag: str | Sequence[str]) -> np.ndarray:
        """Facets of a tag, or the union of the facets of several tags of one facet type (each facet once);
        clear error for unknown or empty tags, and for tags of several facet types (triangles and quads of a
        mixed mesh: :func:`tags_by_facet_type` splits them)."""
        if not isinstance(tag, str):
            tags = list(tag)
            if not tags:
                raise MeshError("an empty list of boundary tags")
            parts = [self.facets_of(t) for t in tags]
            if len({f.shape[1] for f in parts}) > 1:
                kinds = ", ".join(f"{t!r}: {facet_type(f, self.dim)}" for t, f in zip(tags, parts, strict=True))
                raise MeshError(f"the tags hold facets of several types ({kinds}); take them one type at a time")
            f = np.vstack(parts)
            _, first = np.unique(np.sort(f, axis=1), axis=0, return_index=True)
            return f[np.sort(first)]
        if tag not in self.facets:
            raise MeshError(f"unknown boundary tag {tag!r}; this mesh has: {', '.join(self.tags) or 'none'}")
        f = self.facets[tag]
        if f.size == 0:
            raise MeshError(f"boundary tag {tag!r} is empty")
        return f

    def nodes_of(self, tag: str | Sequence[str]) -> np.ndarray:
        """Sorted unique node indices of the facets of ``tag`` (several tags: of their union, whatever their
        facet types)."""
        if isinstance(tag, str):
            return np.unique(self.facets_of(tag))
        return np.unique(np.concatenate([self.facets_of(group).ravel() for group in tags_by_facet_type(self, tag)]))

    def check_cells(self) -> None:
        """Raise :class:`MeshError` if an element is degenerate or inverted (det J <= 0)."""

        def check(part: Mesh, cut: slice) -> None:
            try:
                _check_one_type(part)
            except MeshError as exc:
                if part is self:
                    raise
                raise MeshError(f"{exc} (cells of the {part.cell_type} block, numbered from {cut.start})") from None

        over_blocks(self, check, lambda _: None)


def _check_one_type(mesh: Mesh) -> None:
    """:meth:`Mesh.check_cells` of a one-type mesh."""
    ref = reference_element(mesh.cell_type)
    # translates of one element (structured generators): checking the first suffices
    uniform = uniform_cells(mesh, cached=False)  # points may have moved since it was cached
    X = mesh.points[mesh.cells[:1] if uniform else mesh.cells]
    dN = ref.dN
    if ref.order == 2:  # a curved cell can fold near a node while positive at every quadrature point: its nodes too
        dN = np.concatenate([dN, shape_functions(ref.name, ref.nodes)[1]])
    J = jacobians(dN, X)
    det = J[..., 0, 0] if ref.dim == 1 else determinants(J)
    scale = np.abs(X - X.mean(axis=1, keepdims=True)).max(axis=(1, 2)) ** ref.dim
    bad = np.where((det <= 1e-12 * scale[:, None]).any(axis=1))[0]
    if bad.size:
        inverted = (det[bad] < -1e-12 * scale[bad, None]).all(axis=1)
        kind = "inverted" if inverted.all() else "degenerate or inverted"
        if uniform:  # the first cell stands for all
            bad = np.arange(mesh.n_cells)
        fix = "fix the node ordering or the geometry"
        if ref.order == 2:  # gmsh's curved cells: its high-order optimization untangles them
            fix += " (gmsh's curved cells: mesh with Mesh.HighOrderOptimize = 2, or move the mid-side nodes)"
        raise MeshError(f"{bad.size} {kind} element(s) (det J <= 0), e.g. cells {bad[:5].tolist()}; {fix}")


def over_blocks(mesh: Mesh, kernel: Callable[[Mesh, slice], Any], combine: Callable[[list[Any]], Any]) -> Any:
    """The one loop over a mesh's cell blocks: ``kernel(part, cells)`` on each one-type part
    (``cells``: the slice of its cells in the mesh's numbering, for per-cell data), the results
    combined by ``combine`` (a sum of matrices, a concatenation of per-cell values).  A
    one-type mesh is its own single part (its result as it is)."""
    parts = mesh.parts()
    if len(parts) == 1:
        return kernel(*parts[0])
    return combine([kernel(part, cut) for part, cut in parts])


def one_type(mesh: Mesh, what: str) -> None:
    """A MeshError unless ``mesh`` has one cell type (``what`` works on one type: per-cell
    arrays of one quadrature size); a mixed mesh goes through :func:`over_blocks`."""
    if len(mesh.blocks) > 1:
        raise MeshError(f"{what} of a mixed mesh: use the parts (Mesh.parts()), one cell type each")


def _region_cells(tag: str, cells, n_cells: int) -> np.ndarray:
    """The cell indices of region ``tag`` validated: integers in 0 .. n_cells - 1, sorted, unique."""
    c = np.asarray(cells)
    if c.size and (c.dtype.kind not in "iu" or c.ndim != 1):
        raise MeshError(f"region {tag!r} must be a 1D array of cell indices, got {c.dtype} of shape {c.shape}")
    c = np.unique(c.astype(np.int64))
    if c.size and (c[0] < 0 or c[-1] >= n_cells):
        raise MeshError(f"region {tag!r} references cell {int(c[0] if c[0] < 0 else c[-1])}, outside 0..{n_cells - 1}")
    return c


def uniform_cells(mesh: Mesh, cached: bool = True) -> bool:
    """True when every element is a translate of the first one (same Jacobians), as on
    the structured generators' meshes; assembly then computes one element matrix.
    ``cached=False`` recomputes it (and refreshes the cache)."""
    if cached and "uniform" in mesh._cache:
        return mesh._cache["uniform"]
    if mesh.mixed or mesh.cells.shape[0] == 0:
        return False
    first = mesh.points[mesh.cells[0]]
    scale = max(float(np.abs(first - first[:1]).max()), 1e-300)
    out = True
    for k in range(mesh.points.shape[1]):  # one coordinate at a time: small temporaries
        Xk = mesh.points[mesh.cells, k]
        Xk -= Xk[:, :1].copy()
        Xk -= Xk[0].copy()
        if np.abs(Xk).max() > 1e-12 * scale:
            out = False
            break
    mesh._cache["uniform"] = out
    return out


#: the meshio type of a facet of a ``dim``-dimensional mesh by its number of nodes
FACET_OF_WIDTH = {
    (2, 2): "line",
    (2, 3): "line3",
    (3, 3): "triangle",
    (3, 4): "quad",
    (3, 6): "triangle6",
    (3, 8): "quad8",
    (3, 9): "quad9",
}


def facet_type(facets: np.ndarray, dim: int) -> str:
    """The cell type of facets (n, nfv): a point in 1D, a line (``line3`` quadratic) in 2D, a triangle or a quad
    (``triangle6``, ``quad9``) in 3D."""
    return "vertex" if dim == 1 else FACET_OF_WIDTH[(dim, int(np.shape(facets)[1]))]


def facet_vertices(facets: np.ndarray, dim: int) -> np.ndarray:
    """The vertex columns of facets (n, nfv) (a quadratic facet's nodes list its vertices first): what tells
    two facets apart (two quadratic facets sharing an edge share three nodes)."""
    return facets if dim == 1 else facets[:, : reference_element(facet_type(facets, dim)).n_vertices]


# ----------------------------------------------------------------------------- boundary
def tags_by_facet_type(mesh: Mesh, tags: Sequence[str]) -> list[list[str]]:
    """``tags`` grouped by the facet type they hold (a mixed mesh's triangles and quads: two groups), in the
    order of first appearance; an empty list refused."""
    tags = list(tags)
    if not tags:
        raise MeshError("an empty list of boundary tags")
    groups: dict[int, list[str]] = {}
    for t in tags:
        groups.setdefault(mesh.facets_of(t).shape[1], []).append(t)
    return list(groups.values())


def face_keys(faces: np.ndarray, n_nodes: int) -> np.ndarray:
    """One sortable value per face (n, nfv) from its sorted first three nodes: enough to tell
    faces apart.  An integer (s0 n + s1) n + s2 while n^3 fits in int64 (below 2,097,152
    nodes: 3.6x faster to sort), else an opaque row value (no overflow at any size)."""
    s = np.sort(faces, axis=1)[:, :3]
    if float(n_nodes) ** s.shape[1] < 2.0**62:
        key = np.zeros(len(s), dtype=np.int64)
        for k in range(s.shape[1]):
            key = key * n_nodes + s[:, k]
        return key
    return _rows(s)


def boundary_facets(cells: np.ndarray, cell_type: str) -> np.ndarray:
    """All facets that belong to exactly one cell, as (n, nfv) node arrays."""
    ref = reference_element(cell_type)
    loc = np.array(ref.facets)
    faces = cells[:, loc].reshape(-1, loc.shape[1])
    key = face_keys(faces[:, : _facet_vertex_count(cell_type)], int(cells.max()) + 1)
    _, inv, counts = np.unique(key, return_inverse=True, return_counts=True)
    return faces[counts[inv] == 1]


def _facet_vertex_count(cell_type: str) -> int:
    """The number of vertices of a facet of ``cell_type`` (its facets list them first)."""
    return reference_element(FACET_TYPES[cell_type]).n_vertices


def mesh_boundary(mesh: Mesh) -> list[np.ndarray]:
    """The boundary facets of a mesh, one (n, nfv) array per facet type (a facet of a mixed
    mesh between two blocks, a 2D edge of a triangle and a quad, is inside)."""
    if len(mesh.blocks) == 1:
        return [boundary_facets(mesh.blocks[0].cells, mesh.blocks[0].cell_type)]
    faces, nv = [], []
    for b in mesh.blocks:
        loc = np.array(reference_element(b.cell_type).facets)
        faces.append(b.cells[:, loc].reshape(-1, loc.shape[1]))
        nv.append(_facet_vertex_count(b.cell_type))
    keys = [face_keys(f[:, :k], mesh.n_nodes) for f, k in zip(faces, nv, strict=True)]
    if len({k.dtype for k in keys}) > 1:  # the opaque row values of a huge mesh: compare as rows of 3
        keys = [_rows(np.sort(f[:, :k], axis=1)[:, :3]) for f, k in zip(faces, nv, strict=True)]
    _, inv, counts = np.unique(np.concatenate(keys), return_inverse=True, return_counts=True)
    once = counts[inv] == 1
    out, start = {}, 0
    for f in faces:
        mine = f[once[start : start + len(f)]]
        start += len(f)
        out.setdefault(f.shape[1], []).append(mine)
    return [np.vstack(v) for _, v in sorted(out.items())]


def join(parts: dict[str, Mesh]) -> Mesh:
    """One mesh of several bodies: the parts' nodes and cells side by side (no node shared),
    each part's facet tag ``t`` renamed ``<part>_<t>``; every part is a region ``<part>``
    (all its cells) and its own regions ``r`` become ``<part>_<r>``.  Parts of different cell
    types (of one dimension) make a mixed mesh."""
    meshes = list(parts.values())
    if not meshes:
        raise MeshError("join needs one or more meshes")
    if any(m.mixed for m in meshes) or len({m.cell_type for m in meshes}) > 1:
        return _join_blocks(parts)
    offsets = np.cumsum([0] + [m.n_nodes for m in meshes])
    first = np.cumsum([0] + [m.n_cells for m in meshes])
    facets = {
        f"{name}_{t}": f + off
        for (name, m), off in zip(parts.items(), offsets, strict=False)
        for t, f in m.facets.items()
    }
    regions = {}
    for (name, m), c0 in zip(parts.items(), first, strict=False):
        regions[name] = c0 + np.arange(m.n_cells)
        regions.update({f"{name}_{r}": c0 + c for r, c in m.regions.items()})
    return Mesh(
        np.vstack([m.points for m in meshes]),
        np.vstack([m.cells + o for m, o in zip(meshes, offsets, strict=False)]),
        meshes[0].cell_type,
        facets,
        regions=regions,
    )


def _join_blocks(parts: dict[str, Mesh]) -> Mesh:
    """:func:`join` of parts of several cell types: one block per part's block."""
    meshes = list(parts.values())
    offsets = np.cumsum([0] + [m.n_nodes for m in meshes])
    first = np.cumsum([0] + [m.n_cells for m in meshes])
    facets = {
        f"{name}_{t}": f + off
        for (name, m), off in zip(parts.items(), offsets, strict=False)
        for t, f in m.facets.items()
    }
    regions = {}
    types, arrays = [], []
    for (name, m), c0, off in zip(parts.items(), first, offsets, strict=False):
        regions[name] = c0 + np.arange(m.n_cells)
        regions.update({f"{name}_{r}": c0 + c for r, c in m.regions.items()})
        for b in m.blocks:
            types.append(b.cell_type)
            arrays.append(b.cells + off)
    return Mesh(np.vstack([m.points for m in meshes]), arrays, types, facets, regions=regions)


def sub_mesh(mesh: Mesh, cells: np.ndarray) -> Mesh:
    """The cells ``cells`` (sorted indices) of ``mesh`` on all its points (same node numbering, no tags):
    what an operator of those cells only is assembled on (a region of another material model)."""
    cells = np.asarray(cells)
    types, arrays = [], []
    for b in mesh.blocks:
        mine = cells[(cells >= b.start) & (cells < b.stop)] - b.start
        if mine.size:
            types.append(b.cell_type)
            arrays.append(b.cells[mine])
    if not arrays:
        raise MeshError("a sub-mesh needs at least one cell")
    return Mesh(mesh.points, arrays, types)


def bodies(mesh: Mesh) -> np.ndarray:
    """The body (connected component of the cells) of every node, (n_nodes,) int, numbered in
    the order of their first node; a node of no cell is a body of its own."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    rows = np.concatenate([np.repeat(b.cells[:, 0], b.cells.shape[1]) for b in mesh.blocks])
    cols = np.concatenate([b.cells.ravel() for b in mesh.blocks])
    A = coo_matrix((np.ones(rows.size), (rows, cols)), shape=(mesh.n_nodes, mesh.n_nodes))
    _, label = connected_components(A, directed=False)
    first = np.full(label.max(initial=-1) + 1, mesh.n_nodes)
    np.minimum.at(first, label, np.arange(mesh.n_nodes))
    return np.argsort(np.argsort(first))[label]


def resolution(mesh: Mesh) -> float:
    """h / L [-], what the mesh resolves of its bodies: for each body (:func:`bodies`) the median over its cells of
    the cell's shortest distance between two of its nodes (an edge on the cells signorini meshes) over the largest
    extent of the body's bounding box; the smallest over the bodies (the finest-meshed body sets it).  A bar of n
    cells along its length: 1 / n."""
    label = bodies(mesh)
    nb = int(label.max(initial=0)) + 1
    short = []
    for b in mesh.blocks:  # a few cell types; per type a loop over the pairs of a cell's nodes (at most 28)
        nv = reference_element(b.cell_type).n_vertices  # a quadratic cell's size is its vertices' (not h / 2)
        x = mesh.points[b.cells[:, :nv]]
        h = np.full(b.cells.shape[0], np.inf)
        for i in range(nv):
            for j in range(i + 1, nv):
                np.minimum(h, np.linalg.norm(x[:, i] - x[:, j], axis=1), out=h)
        short.append(h)
    h = np.concatenate(short)
    body = label[mesh.first_nodes()]
    order = np.lexsort((h, body))
    counts = np.bincount(body, minlength=nb)
    start = np.concatenate([[0], np.cumsum(counts)[:-1]])
    hs = h[order]
    median = 0.5 * (hs[start + (counts - 1) // 2] + hs[start + counts // 2])
    lo = np.full((nb, mesh.dim), np.inf)
    hi = np.full((nb, mesh.dim), -np.inf)
    np.minimum.at(lo, label, mesh.points)
    np.maximum.at(hi, label, mesh.points)
    extent = (hi - lo).max(axis=1)
    used = counts > 0
    return float(np.min(median[used] / extent[used]))


def region_ids(mesh: Mesh) -> np.ndarray:
    """The region number of every cell (n_cells,) int: k + 1 for the k-th region in sorted tag
    order (a cell in several regions: the first of them), 0 for a cell of no region."""
    ids = np.zeros(mesh.n_cells, dtype=np.int64)
    for k, tag in reversed(list(enumerate(sorted(mesh.regions)))):
        ids[mesh.regions[tag]] = k + 1
    return ids


def tag_sides(points: np.ndarray, facets: np.ndarray) -> dict[str, np.ndarray]:
    """Split boundary facets of an axis-aligned box into ``xmin``, ``xmax``, ... tags."""
    dim = points.shape[1]
    lo, hi = points.min(axis=0), points.max(axis=0)
    tol = 1e-9 * max(1.0, float(np.max(hi - lo)))
    tags = {}
    fx = points[facets]  # (nf, nfv, dim)
    for k, ax in enumerate("xyz"[:dim]):
        for name, val in (("min", lo[k]), ("max", hi[k])):
            on = np.all(np.abs(fx[:, :, k] - val) < tol, axis=1)
            tags[f"{ax}{name}"] = facets[on]
    return tags


# ----------------------------------------------------------------------------- generators
def _check_counts(**counts: int) -> None:
    for name, v in counts.items():
        if not isinstance(v, (int, np.integer)) or v < 1:
            raise MeshError(f"{name} must be a positive integer, got {v!r}")


def _check_lengths(**lengths: float) -> None:
    for name, v in lengths.items():
        if not np.isfinite(v) or v <= 0:
            raise MeshError(f"{name} must be a positive length, got {v!r}")


def _check_order(order: int) -> None:
    if not isinstance(order, (int, np.integer)) or isinstance(order, bool) or order not in (1, 2):
        raise MeshError(f"order must be 1 (linear cells) or 2 (quadratic cells), got {order!r}")


def interval(n: int, length: float = 1.0, x0: float = 0.0, order: int = 1) -> Mesh:
    """P1 (``order`` 2: P2, ``line3``) mesh of [x0, x0 + length] with ``n`` equal elements; tags ``xmin``, ``xmax``."""
    _check_counts(n=n)
    _check_lengths(length=length)
    _check_order(order)
    x = x0 + np.linspace(0.0, length, n + 1)
    cells = np.column_stack([np.arange(n), np.arange(1, n + 1)])
    mesh = Mesh(x[:, None], cells, "line", {"xmin": np.array([[0]]), "xmax": np.array([[n]])}, grid=(x,))
    return mesh if order == 1 else elevate(mesh)


def rectangle(nx: int, ny: int, lx: float = 1.0, ly: float = 1.0, cell: str = "quad", order: int = 1) -> Mesh:
    """Structured mesh of [0,lx]x[0,ly]: ``nx`` x ``ny`` quads, or twice as many triangles; ``order`` 2: the same
    cells quadratic (``quad9``, ``triangle6``: :func:`elevate`)."""
    _check_order(order)
    if order == 2:
        return elevate(rectangle(nx, ny, lx, ly, cell))
    _check_counts(nx=nx, ny=ny)
    _check_lengths(lx=lx, ly=ly)
    xs, ys = np.linspace(0, lx, nx + 1), np.linspace(0, ly, ny + 1)
    X, Y = np.meshgrid(xs, ys, indexing="xy")
    pts = np.column_stack([X.ravel(), Y.ravel()])
    idx = np.arange(pts.shape[0]).reshape(ny + 1, nx + 1)
    a, b, c, d = idx[:-1, :-1], idx[:-1, 1:], idx[1:, 1:], idx[1:, :-1]
    if cell == "quad":
        cells = np.stack([a, b, c, d], axis=-1).reshape(-1, 4)
        return Mesh(pts, cells, cell, tag_sides(pts, boundary_facets(cells, cell)), grid=(xs, ys))
    elif cell == "triangle":
        t1 = np.stack([a, b, c], axis=-1).reshape(-1, 3)
        t2 = np.stack([a, c, d], axis=-1).reshape(-1, 3)
        cells = np.vstack([t1, t2])
    else:
        raise MeshError(f"unknown 2D cell {cell!r}; allowed: quad, triangle")
    return Mesh(pts, cells, cell, tag_sides(pts, boundary_facets(cells, cell)))


# Kuhn subdivision of the unit cube (VTK hex node numbers) into 6 positively oriented tets
_KUHN = np.array([[0, 1, 2, 6], [0, 2, 3, 6], [0, 3, 7, 6], [0, 7, 4, 6], [0, 4, 5, 6], [0, 5, 1, 6]])


def box(
    nx: int,
    ny: int,
    nz: int,
    lx: float = 1.0,
    ly: float = 1.0,
    lz: float = 1.0,
    cell: str = "hexahedron",
    order: int = 1,
) -> Mesh:
    """Structured mesh of [0,lx]x[0,ly]x[0,lz]: hexahedra or six tetrahedra per cube; ``order`` 2: the same cells
    quadratic (``hexahedron27``, ``tetra10``: :func:`elevate`)."""
    _check_order(order)
    if order == 2:
        return elevate(box(nx, ny, nz, lx, ly, lz, cell))
    _check_counts(nx=nx, ny=ny, nz=nz)
    _check_lengths(lx=lx, ly=ly, lz=lz)
    xs, ys, zs = (np.linspace(0, L, m + 1) for L, m in ((lx, nx), (ly, ny), (lz, nz)))
    Z, Y, X = np.meshgrid(zs, ys, xs, indexing="ij")
    pts = np.column_stack([X.ravel(), Y.ravel(), Z.ravel()])
    idx = np.arange(pts.shape[0]).reshape(nz + 1, ny + 1, nx + 1)
    corners = [
        idx[:-1, :-1, :-1],
        idx[:-1, :-1, 1:],
        idx[:-1, 1:, 1:],
        idx[:-1, 1:, :-1],
        idx[1:, :-1, :-1],
        idx[1:, :-1, 1:],
        idx[1:, 1:, 1:],
        idx[1:, 1:, :-1],
    ]
    hexes = np.stack(corners, axis=-1).reshape(-1, 8)
    if cell == "hexahedron":
        cells = hexes
        facets = _structured_box_facets(idx)
        return Mesh(pts, cells, cell, facets, grid=(xs, ys, zs))
    if cell == "tetra":
        cells = hexes[:, _KUHN].reshape(-1, 4)
        return Mesh(pts, cells, cell, tag_sides(pts, boundary_facets(cells, cell)))
    raise MeshError(f"unknown 3D cell {cell!r}; allowed: hexahedron, tetra")


def elevate(mesh: Mesh) -> Mesh:
    """The quadratic mesh of a linear one (straight-sided: every new node at the centroid of the vertices of the
    edge, face or cell it belongs to; ``line3``, ``triangle6``, ``quad9``, ``tetra10``, ``hexahedron27``).

    A new node of the reference cell belongs to the vertices whose linear shape functions are positive there (an
    edge's two, a quadrilateral face's four, a hexahedron's eight); cells and tagged facets sharing those vertices
    share the node (numbered after the vertices, in the order of first appearance over the cells).  Tags and regions
    are kept; the structured ``grid`` is not (the nodes are no longer its tensor product)."""
    if any(reference_element(b.cell_type).order != 1 for b in mesh.blocks):
        raise MeshError("elevate needs a mesh of linear cells (this one is quadratic already)")
    parents: list[np.ndarray] = []  # per block: (ne, extra, k) vertices of each new node, -1 padded

    def owners(cell_type: str, cells: np.ndarray) -> np.ndarray:
        parents = node_parents(QUADRATIC[cell_type])
        k = max(v.size for v in parents)
        own = np.full((cells.shape[0], len(parents), k), -1, dtype=np.int64)
        for j, v in enumerate(parents):  # a few nodes per cell type (at most 19)
            own[:, j, : v.size] = np.sort(cells[:, v], axis=1)
        return own

    blocks = mesh.blocks
    k_max = 0
    for b in blocks:
        parents.append(owners(b.cell_type, b.cells))
        k_max = max(k_max, parents[-1].shape[2])
    facet_parents = {}
    for tag, f in mesh.facets.items():
        if mesh.dim == 1:
            continue
        facet_parents[tag] = owners(facet_type(f, mesh.dim), f)
        k_max = max(k_max, facet_parents[tag].shape[2])

    def padded(own: np.ndarray) -> np.ndarray:
        out = np.full(own.shape[:2] + (k_max,), -1, dtype=np.int64)
        out[..., : own.shape[2]] = np.sort(np.where(own < 0, np.iinfo(np.int64).max, own), axis=2)
        return np.where(out == np.iinfo(np.int64).max, -1, out)

    rows = [padded(o).reshape(-1, k_max) for o in parents]
    allrows = np.vstack(rows)
    keys, first, inverse = np.unique(_rows(allrows), return_index=True, return_inverse=True)
    order_ = np.argsort(first, kind="stable")  # numbered in the order of first appearance
    number = np.empty(keys.size, dtype=np.int64)
    number[order_] = mesh.n_nodes + np.arange(keys.size)
    new_of = number[inverse.ravel()]
    owner_rows = allrows[first[order_]]
    valid = owner_rows >= 0
    coords = np.where(valid[..., None], mesh.points[np.maximum(owner_rows, 0)], 0.0).sum(axis=1)
    coords /= valid.sum(axis=1, keepdims=True)
    points = np.vstack([mesh.points, coords])
    cells_out, start = [], 0
    for b, own in zip(blocks, parents, strict=True):
        m = own.shape[0] * own.shape[1]
        cells_out.append(np.hstack([b.cells, new_of[start : start + m].reshape(own.shape[:2])]))
        start += m
    facets = {}
    for tag, f in mesh.facets.items():
        if mesh.dim == 1:
            facets[tag] = f
            continue
        fr = padded(facet_parents[tag]).reshape(-1, k_max)
        pos = np.searchsorted(keys, _rows(fr))
        if not np.all(keys[np.minimum(pos, keys.size - 1)] == _rows(fr)):
            raise MeshError(f"elevate: tag {tag!r} has facets that are not faces of the cells")
        facets[tag] = np.hstack([f, number[pos].reshape(f.shape[0], -1)])
    types = [QUADRATIC[b.cell_type] for b in blocks]
    if len(types) == 1:
        return Mesh(points, cells_out[0], types[0], facets, regions=dict(mesh.regions))
    return Mesh(points, cells_out, types, facets, regions=dict(mesh.regions))


def _structured_box_facets(idx: np.ndarray) -> dict[str, np.ndarray]:
    """Boundary quads of a structured hexahedral grid ``idx[z, y, x]``, by side."""

    def quads(face: np.ndarray) -> np.ndarray:
        return np.stack([face[:-1, :-1], face[:-1, 1:], face[1:, 1:], face[1:, :-1]], axis=-1).reshape(-1, 4)

    return {
        "xmin": quads(idx[:, :, 0]),
        "xmax": quads(idx[:, :, -1]),
        "ymin": quads(idx[:, 0, :]),
        "ymax": quads(idx[:, -1, :]),
        "zmin": quads(idx[0]),
        "zmax": quads(idx[-1]),
    }


# ----------------------------------------------------------------------------- files
_DIM_OF = {t: reference_element(t).dim for t in SUPPORTED_CELLS}


def _tagged_facets(m, ftype: str, names: dict[int, str], fdim: int) -> dict[str, list[np.ndarray]]:
    """Facet arrays per physical group: every group of a facet, not only the first.

    ``gmsh:physical`` holds one group per element; a Gmsh 4 file attaches groups to
    entities, and meshio lists every group's elements per block in ``cell_sets``.
    """
    facets: dict[str, list[np.ndarray]] = {}
    phys = m.cell_data.get("gmsh:physical")
    if phys is not None:
        for block, tags in zip(m.cells, phys, strict=True):
            if block.type != ftype:
                continue
            t = np.asarray(tags, dtype=float)
            if t.size and (not np.all(np.isfinite(t)) or np.any(t != np.round(t))):
                raise MeshError("physical tags of the facets must be integers (found NaN or a fraction)")
            for tag_id in np.unique(tags):
                name = names.get(int(tag_id), str(int(tag_id)))
                facets.setdefault(name, []).append(block.data[tags == tag_id])
    for name, per_block in (m.cell_sets or {}).items():
        fd = (m.field_data or {}).get(name)
        if name.startswith("gmsh:") or fd is None or len(fd) < 2 or int(fd[1]) != fdim:
            continue  # not a physical group of facets
        found = [
            block.data[np.asarray(idx, dtype=np.int64)]
            for block, idx in zip(m.cells, per_block, strict=False)
            if block.type == ftype and idx is not None and len(idx)
        ]
        if found:  # the entity-based sets are complete: they replace the first-group-only lists
            facets[name] = found
    return facets


def _tagged_cells(m, cell_type: str, names: dict[int, str], dim: int) -> dict[str, np.ndarray]:
    """Cell indices (into the stacked blocks of ``cell_type``) per physical group of cells:
    ``gmsh:physical`` cell data (one group per element) and the entity-based ``cell_sets``
    of Gmsh 4 files (every group; they replace the first-group-only lists)."""
    blocks = [b.type == cell_type for b in m.cells]
    starts = np.cumsum([0] + [len(b.data) if keep else 0 for b, keep in zip(m.cells, blocks, strict=True)])
    regions: dict[str, list[np.ndarray]] = {}
    phys = m.cell_data.get("gmsh:physical")
    if phys is not None:
        for k, (keep, tags) in enumerate(zip(blocks, phys, strict=True)):
            if not keep:
                continue
            t = np.asarray(tags, dtype=float)
            if t.size and (not np.all(np.isfinite(t)) or np.any(t != np.round(t))):
                raise MeshError("physical tags of the cells must be integers (found NaN or a fraction)")
            for tag_id in np.unique(tags):
                if int(tag_id) in names:  # a named group of cells; unnamed ids (gmsh's default 0) are not regions
                    regions.setdefault(names[int(tag_id)], []).append(starts[k] + np.flatnonzero(tags == tag_id))
    for name, per_block in (m.cell_sets or {}).items():
        fd = (m.field_data or {}).get(name)
        if name.startswith("gmsh:") or fd is None or len(fd) < 2 or int(fd[1]) != dim:
            continue
        found = [
            starts[k] + np.asarray(idx, dtype=np.int64)
            for k, (keep, idx) in enumerate(zip(blocks, per_block, strict=False))
            if keep and idx is not None and len(idx)
        ]
        if found:
            regions[name] = found
    return {k: np.concatenate(v) for k, v in regions.items()}


def meshio_read(p: Path, what: str):
    """``meshio.read(p)`` quietly (meshio raises many types, prints to stdout and may call
    sys.exit on unknown formats): a :class:`MeshError` "cannot read <what> 'p': <reason>" for a
    file it cannot read, and for a header that declares far more data than the file holds (a
    corrupt file, not a mesh too large for the machine: a real MemoryError propagates)."""
    import meshio

    try:
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            with np.errstate(over="ignore"):  # meshio's binary-STL size test overflows on ASCII files
                return meshio.read(p)
    except MemoryError as exc:
        wanted, size = getattr(exc, "_total_size", None), p.stat().st_size
        if wanted is not None and wanted > CORRUPT_RATIO * max(size, 1):
            raise MeshError(
                f"cannot read {what} {str(p)!r}: it declares {wanted / 2**30:.3g} GiB of data in a file of "
                f"{size:,} bytes (a corrupt header or a truncated file)"
            ) from None
        raise
    except (Exception, SystemExit) as exc:
        reason = str(exc) if not isinstance(exc, SystemExit) else f"not a {what} in a format meshio reads"
        raise MeshError(f"cannot read {what} {str(p)!r}: {reason}") from None


def read_mesh(path: str | Path) -> Mesh:
    """Read a mesh with meshio; Gmsh physical groups of facets become tags.

    The cells of highest dimension form the mesh (mixed cell types are refused).
    Facets listed under a physical group named ``NAME`` (``gmsh:physical`` cell data
    plus ``field_data``, and meshio's ``cell_sets`` of Gmsh 4 files) become the tag
    ``NAME``, a facet in several groups carries every one; unnamed groups become
    ``"<id>"``.  Cells listed under a named physical group of the mesh's dimension
    (volumes in 3D, surfaces in 2D) become the region ``NAME``. Refused with a
    :class:`MeshError`: physical groups of facets that hold no facet, node references
    out of range, non-finite coordinates, a 2D (1D) mesh whose dropped coordinates vary,
    a facet listed twice in a tag, a tagged facet that is not a face of a cell, and non-
    integer physical tags. Points are truncated to the mesh dimension (Gmsh always
    writes 3D points).
    """

    p = Path(path)
    if not p.is_file():
        raise MeshError(f"mesh file {str(p)!r} {not_a_file(p, 'a mesh file')}")
    if p.stat().st_size == 0:
        raise MeshError(f"cannot read mesh file {str(p)!r}: the file is empty (0 bytes)")
    m = meshio_read(p, "mesh file")
    kinds = {b.type for b in m.cells}
    volume = [t for t in kinds if t in _DIM_OF]
    unsupported = [t for t in kinds if t not in _DIM_OF and t != "vertex"]
    if not volume:
        raise MeshError(
            f"{p.name}: no supported cells (found {sorted(kinds)}); supported: {', '.join(SUPPORTED_CELLS)}"
        )
    dim = max(_DIM_OF[t] for t in volume)
    top = sorted(t for t in volume if _DIM_OF[t] == dim)  # several: a mixed mesh, block by type
    if unsupported:
        raise MeshError(
            f"{p.name}: unsupported cell types {sorted(unsupported)}; supported: {', '.join(SUPPORTED_CELLS)}"
        )
    by_type = {t: np.vstack([b.data for b in m.cells if b.type == t]) for t in top}
    for t, c in by_type.items():
        _check_indices(p.name, f"{t} cells", c, len(m.points))
    _check_points(p.name, m.points, dim)
    # physical names per (id, dimension): "skin" (surface 1) and "body" (volume 1) may share an id
    names = {int(v[0]): k for k, v in (m.field_data or {}).items() if len(v) > 1 and int(v[1]) == dim - 1}
    facets: dict[str, list[np.ndarray]] = {}
    for ftype in sorted({FACET_TYPES[t] for t in top}):
        for k, v in _tagged_facets(m, ftype, names, dim - 1).items():
            if k in facets:
                raise MeshError(
                    f"{p.name}: tag {k!r} holds facets of two types (triangles and quads); a tag holds "
                    "one type: split it into two physical groups"
                )
            facets[k] = v
    for other in sorted({FACET_TYPES[t] for t in FACET_TYPES if _DIM_OF.get(t) == dim} - {FACET_TYPES[t] for t in top}):
        for k in _tagged_facets(m, other, names, dim - 1):  # facets no cell of this mesh has: never dropped
            raise MeshError(
                f"{p.name}: tag {k!r} holds {other} facets, but the mesh's cells ({', '.join(top)}) have "
                f"no {other} faces; remove them from the physical group (or mesh the part with cells "
                "that have them)"
            )
    ftype = " or ".join(sorted({FACET_TYPES[t] for t in top}))  # named in the message below
    for k, v in facets.items():
        _check_indices(p.name, f"facets of tag {k!r}", np.vstack(v), len(m.points))
    declared = sorted(k for k, v in (m.field_data or {}).items() if len(v) > 1 and int(v[1]) == dim - 1)
    if declared and not facets:
        raise MeshError(
            f"{p.name}: the physical groups {declared} of dimension {dim - 1} hold no {ftype} facets "
            "(no mesh entity is attached to them); add the surfaces to the groups in gmsh and mesh again"
        )
    # drop unused points (gmsh keeps geometry points)
    used = np.unique(np.concatenate([c.ravel() for c in by_type.values()]))
    renum = -np.ones(len(m.points), dtype=np.int64)
    renum[used] = np.arange(used.size)
    pts = m.points[used, :dim]
    tagged = {k: renum[np.vstack(v)] for k, v in facets.items()}
    for k, v in tagged.items():
        if (v < 0).any():
            raise MeshError(f"{p.name}: facets of tag {k!r} use nodes that belong to no cell")
    cell_names = {int(v[0]): k for k, v in (m.field_data or {}).items() if len(v) > 1 and int(v[1]) == dim}
    regions: dict[str, list[np.ndarray]] = {}
    start = 0
    for t, c in by_type.items():  # the cells numbered block after block, in sorted type order
        for k, v in _tagged_cells(m, t, cell_names, dim).items():
            regions.setdefault(k, []).append(start + v)
        start += len(c)
    regions = {k: np.concatenate(v) for k, v in regions.items()}
    if len(top) == 1:
        mesh = Mesh(pts, renum[by_type[top[0]]], top[0], tagged, regions=regions)
    else:
        mesh = Mesh(pts, [renum[c] for c in by_type.values()], list(by_type), tagged, regions=regions)
    try:
        mesh.check_cells()
    except MeshError as exc:
        raise MeshError(f"{p.name}: {exc}") from None
    _check_facets(p.name, mesh)
    _check_shared_nodes(p.name, mesh)
    return mesh


#: a mesh file whose arrays would need more than this times its size in memory is corrupt (an
#: ASCII Gmsh node takes ~30 bytes for 24 in memory; a binary one 8 bytes per value)
CORRUPT_RATIO = 64


def _check_indices(name: str, what: str, idx: np.ndarray, n_points: int) -> None:
    """Node references within 0 .. n_points - 1 (a gmsh tag 0 becomes -1 in meshio)."""
    if idx.size and (idx.min() < 0 or idx.max() >= n_points):
        bad = int(idx.min()) if idx.min() < 0 else int(idx.max())
        raise MeshError(f"{name}: {what} reference node {bad}, outside 0..{n_points - 1} (a corrupt mesh file)")


def _check_points(name: str, points: np.ndarray, dim: int) -> None:
    """Finite coordinates, and the dropped coordinates of a lower-dimensional mesh constant."""
    if not np.all(np.isfinite(points)):
        raise MeshError(f"{name}: non-finite node coordinates")
    extra = points[:, dim:]
    size = float(np.ptp(points[:, :dim], axis=0).max()) if len(points) else 0.0
    if extra.size and float(np.ptp(extra, axis=0).max()) > 1e-12 * max(size, 1.0):
        axes = "z" if dim == 2 else "y and z"
        raise MeshError(
            f"{name}: a {dim}D mesh ({'triangles or quads' if dim == 2 else 'lines'}) whose {axes} coordinate "
            f"varies (by {float(np.ptp(extra, axis=0).max()):.3g}): flat meshes only, in the plane {axes} = const"
        )


def _rows(a: np.ndarray) -> np.ndarray:
    """Rows of an int array as one opaque (void) value each, for set operations on rows."""
    a = np.ascontiguousarray(a, dtype=np.int64)
    return a.view(np.dtype((np.void, a.dtype.itemsize * a.shape[1]))).ravel()


def _check_facets(name: str, mesh: Mesh) -> None:
    """A conforming mesh whose tags hold boundary facets, each listed once.

    Refused: two cells with the same nodes, a face shared by more than two cells (a node
    index that wrapped or overlapping cells), a facet listed twice in a tag (it would
    count twice in the contact weights), a tagged facet that is not a face of a cell or
    that lies inside the body (shared by two cells).
    """
    faces_by_width: dict[int, list[np.ndarray]] = {}
    for b in mesh.blocks:
        cells = _rows(np.sort(b.cells, axis=1))
        if np.unique(cells).size != cells.size:
            raise MeshError(f"{name}: two cells have the same nodes (a duplicated or corrupt cell)")
        loc = np.array(reference_element(b.cell_type).facets)
        faces_by_width.setdefault(loc.shape[1], []).append(b.cells[:, loc].reshape(-1, loc.shape[1]))
    table = {}
    for width, parts in faces_by_width.items():
        known, counts = np.unique(_rows(np.sort(np.vstack(parts), axis=1)), return_counts=True)
        if (counts > 2).any():
            raise MeshError(
                f"{name}: {int((counts > 2).sum())} face(s) shared by more than two cells: the mesh does not "
                "conform (overlapping cells, or a node reference that wrapped)"
            )
        table[width] = (known, counts)
    if 3 in table and 4 in table:  # tetrahedra and hexahedra: they may meet across a pair, not in a body
        _check_no_glued_faces(name, table[3], table[4])
    for tag, f in mesh.facets.items():
        if f.shape[1] not in table:
            raise MeshError(f"{name}: tag {tag!r} has facets of {f.shape[1]} nodes, which no cell of the mesh has")
        known, counts = table[f.shape[1]]
        key, n = np.unique(_rows(np.sort(f, axis=1)), return_counts=True)
        if (n > 1).any():
            raise MeshError(
                f"{name}: tag {tag!r} lists {int((n > 1).sum())} facet(s) more than once "
                "(they would count twice in the contact weights); remove the duplicates"
            )
        pos = np.clip(np.searchsorted(known, key), 0, known.size - 1)
        missing = known[pos] != key
        if missing.any():
            raise MeshError(f"{name}: tag {tag!r} has {int(missing.sum())} facet(s) that are not faces of any cell")
        inside = counts[pos] > 1
        if inside.any():
            raise MeshError(
                f"{name}: tag {tag!r} has {int(inside.sum())} facet(s) inside the body (shared by two cells); "
                "boundary tags hold boundary facets only"
            )


def _check_shared_nodes(name: str, mesh: Mesh) -> None:
    """Quadratic cells that share an edge (or a quadrilateral face) share its mid-side (centre) node: two cells
    with the vertices of an edge in common but a node of their own at its middle do not conform (the
    displacement jumps along the edge)."""
    keys, mids = {2: [], 4: []}, {2: [], 4: []}
    for b in mesh.blocks:
        ref = reference_element(b.cell_type)
        if ref.order == 1:
            return
        for j, parents in enumerate(node_parents(b.cell_type)):  # a few nodes per cell type (at most 19)
            if parents.size in keys:
                keys[parents.size].append(np.sort(b.cells[:, parents], axis=1))
                mids[parents.size].append(b.cells[:, ref.n_vertices + j])
    for k, what in ((2, "edge"), (4, "face")):
        if not keys[k]:
            continue
        key, mid = _rows(np.vstack(keys[k])), np.concatenate(mids[k])
        _, inverse = np.unique(key, return_inverse=True)
        low = np.full(inverse.max() + 1, np.iinfo(np.int64).max)
        high = np.full(inverse.max() + 1, -1)
        np.minimum.at(low, inverse, mid)
        np.maximum.at(high, inverse, mid)
        apart = np.flatnonzero(low != high)
        if apart.size:
            i = int(np.flatnonzero(inverse == apart[0])[0])
            vertices = np.vstack(keys[k])[i]
            raise MeshError(
                f"{name}: {apart.size} {what}(s) of quadratic cells have two middle nodes (cells sharing "
                f"the {what} of nodes {vertices.tolist()} each have their own node {low[apart[0]]} / "
                f"{high[apart[0]]} at its middle): the mesh does not conform there; merge the "
                "duplicated nodes"
            )


def _check_no_glued_faces(name: str, triangles: tuple, quads: tuple) -> None:
    """Refuse tetrahedra glued to a hexahedron's face: the two triangles of the tetrahedra and
    the quadrilateral share their nodes but no face, so each side sees a free boundary there
    (the body would be cut in two along it).  A conforming mesh of both needs pyramids."""
    tri = triangles[0][triangles[1] == 1]  # boundary triangles (sorted node triples, as rows)
    quad = quads[0][quads[1] == 1]
    if tri.size == 0 or quad.size == 0:
        return
    q = np.frombuffer(quad.tobytes(), dtype=np.int64).reshape(-1, 4)  # sorted nodes of each quad
    t = np.frombuffer(tri.tobytes(), dtype=np.int64).reshape(-1, 3)
    triples = np.vstack([q[:, [0, 1, 2]], q[:, [0, 1, 3]], q[:, [0, 2, 3]], q[:, [1, 2, 3]]])
    glued = np.isin(_rows(t), _rows(triples))
    if glued.any():
        raise MeshError(
            f"{name}: {int(glued.sum())} face(s) of tetrahedra lie on a face of a hexahedron, sharing its nodes but "
            "not the face: the mesh does not conform there (a tetrahedral block glued to a hexahedral one needs "
            "pyramids, which are not supported); make them two bodies in contact through a pair, or mesh both "
            "parts with one cell type"
        )


def write_mesh(mesh: Mesh, path: str | Path) -> None:
    """Write ``mesh`` as a Gmsh 2.2 file with one physical group per tag and per region
    (readable by :func:`read_mesh`; cells of no region form ``domain``).  Regions that share
    cells are refused (:class:`MeshError`): Gmsh 2.2 holds one group per element."""
    import meshio

    blocks, phys, field_data = [], [], {}
    seen = np.full(mesh.n_cells, -1)
    names = sorted(mesh.regions)
    for k, name in enumerate(names):  # Gmsh 2.2 holds one group per element: nested regions cannot be kept
        c = mesh.regions[name]
        if (seen[c] >= 0).any():
            other = names[int(seen[c][seen[c] >= 0][0])]
            raise MeshError(
                f"write_mesh: regions {other!r} and {name!r} share cells, and a Gmsh 2.2 file holds one group per "
                f"cell; remove one of them (mesh.regions.pop({name!r})) before writing"
            )
        seen[c] = k
    group = np.zeros(mesh.n_cells, dtype=int)
    ids = 1
    for name, c in sorted(mesh.regions.items()):
        field_data[name] = np.array([ids, mesh.dim])
        free = c[group[c] == 0]
        group[free] = ids
        ids += 1
    if (group == 0).any() or not mesh.regions:
        field_data["domain"] = np.array([ids, mesh.dim])
        group[group == 0] = ids
        ids += 1
    for b in mesh.blocks:
        blocks.append((b.cell_type, b.cells))
        phys.append(group[b.start : b.stop])
    for name, f in sorted(mesh.facets.items()):
        blocks.append((facet_type(f, mesh.dim), f))
        phys.append(np.full(len(f), ids, dtype=int))
        field_data[name] = np.array([ids, mesh.dim - 1])
        ids += 1
    pts = np.zeros((mesh.n_nodes, 3))
    pts[:, : mesh.dim] = mesh.points
    out = meshio.Mesh(
        pts,
        blocks,
        cell_data={"gmsh:physical": phys, "gmsh:geometrical": phys},
        field_data=field_data,
    )
    meshio.write(path, out, file_format="gmsh22", binary=False)

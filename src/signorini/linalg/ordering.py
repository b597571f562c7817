"""Fill-reducing nested-dissection ordering of a sparse symmetric matrix (numpy/scipy only).

Minimum-degree orderings (SuperLU's MMD, AMD) fill 3D finite-element factors like
n^1.9; nested dissection (George 1973) orders a separator of the graph after the two
parts it splits, recursively, so that fill grows like n^(4/3) and the factorization
like n^2 on 3D meshes.  This implementation needs no graph partitioner:

1. *Supervariables*: the d dofs of a node (node-major numbering) are merged, so the
   graph is the node graph, d times smaller.
2. *Separators across the graph*: in each connected part, a pseudo-peripheral vertex a
   and the vertex b farthest from it are found by breadth-first search; the part is cut
   in halves along d_a - d_b (and along a second axis in the middle cross-section), whose
   level sets near the middle are close to planes across the body, and the smaller
   boundary of the two halves, thinned, is the separator (``separators="levels"``: a
   level set of d_a alone, a cap around a, the ordering before issue 31: SuperLU's
   factor of the 34k-dof Hertz ball holds 1,246 MB with it, 795 MB with the axes).
3. Parts with at most ``leaf`` vertices keep their order.

Its separators are larger than METIS's multilevel ones (SuperLU's factor of ``bar3d``
n = 16 held 3.5 GB with the level sets, 2.1 GB with METIS, 4.9 GB with MMD; the ball
above 526 MB with METIS), so
:func:`fill_reducing_order` uses METIS (``pymetis``, extra ``metis``) on the node graph
when it is installed (a core dependency on Linux x86-64 and macOS), this ordering
otherwise (see ``docs/performance.md``).

An ordering depends on the pattern alone, and a run factorizes many matrices of one pattern (each Newton tangent,
each step of an adaptive control's ladder): :func:`fill_reducing_order` keeps the last :data:`CACHED_PATTERNS`
orderings by pattern (its digest), so that a factorization after the first costs its analysis and numeric
factorization, not the ordering.
"""

from __future__ import annotations

import hashlib
from collections import OrderedDict

import numpy as np
import scipy.sparse as sp
from scipy.sparse import csgraph

from ..fem.dofmap import block_of, whole_blocks
from .base import module_loads


def supervariables(A: sp.spmatrix) -> np.ndarray:
    """Group index of every row: the dofs of one node share a group.

    Node-major numbering with d dofs per node is recognized when grouping consecutive
    rows by d (d = 3, then 2) leaves the blocks of the quotient pattern at least half
    full; otherwise consecutive rows with identical patterns are merged (compared by two
    random hashes of their column sets).  A poor grouping only costs fill, never
    correctness.
    """
    A = sp.csr_matrix(A)
    n = A.shape[0]
    for d in (3, 2):
        if whole_blocks(n, d) and n > 0:
            groups = block_of(np.arange(n), d)
            quotient = _pattern_graph(A, groups, diagonal=True)
            if A.nnz >= 0.5 * d * d * quotient.nnz:
                return groups
    if n == 0 or A.nnz == 0:
        return np.arange(n)
    w = np.random.default_rng(12345).random((2, n))
    lengths = np.diff(A.indptr)
    starts = np.minimum(A.indptr[:-1], A.indices.size - 1)
    h = np.stack([np.add.reduceat(wk[A.indices], starts) for wk in w])
    h[:, lengths == 0] = 0.0
    same = (lengths[1:] == lengths[:-1]) & np.all(h[:, 1:] == h[:, :-1], axis=0)
    return np.concatenate([[0], np.cumsum(~same)])


def _pattern_graph(A: sp.spmatrix, groups: np.ndarray, diagonal: bool = False) -> sp.csr_matrix:
    """Adjacency of the quotient graph of A's pattern by ``groups`` (with or without its
    diagonal), symmetrized."""
    A = sp.csr_matrix(A)
    m = int(groups[-1]) + 1 if groups.size else 0
    rows = np.repeat(groups, np.diff(A.indptr))
    cols = groups[A.indices]
    keep = np.ones(rows.size, dtype=bool) if diagonal else rows != cols
    G = sp.csr_matrix((np.ones(int(keep.sum()), dtype=np.int8), (rows[keep], cols[keep])), shape=(m, m))
    G = (G + G.T).tocsr()
    G.data[:] = 1
    return G


def _level_split(G: sp.csr_matrix) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """(part 1, part 2, separator) of a connected graph by a level set of BFS distances
    from a pseudo-peripheral vertex; None when no level splits it."""
    start, far = 0, -1.0
    for _ in range(4):  # a few sweeps: the farthest vertex of the farthest vertex ...
        d = csgraph.dijkstra(G, unweighted=True, indices=start)
        nxt = int(np.argmax(d))
        if d[nxt] <= far:
            break
        start, far = nxt, d[nxt]
    level = d.astype(np.int64)
    counts = np.bincount(level)
    if counts.size < 3:
        return None
    below = np.cumsum(counts) - counts  # vertices before each level
    above = counts.sum() - below - counts
    cut = int(np.argmin(np.abs(below - above) + counts))  # balance first, then a small separator
    cut = min(max(cut, 1), counts.size - 2)
    return np.flatnonzero(level < cut), np.flatnonzero(level > cut), np.flatnonzero(level == cut)


def _distances(G: sp.csr_matrix, start: int) -> np.ndarray:
    """Breadth-first distances from ``start`` (a connected graph)."""
    return csgraph.dijkstra(G, unweighted=True, indices=start)


def _vertex_separator(G: sp.csr_matrix, side: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(side, separator) of a split of a graph's vertices in two (boolean ``side``): the
    vertices of one side with a neighbour on the other (of the two sides, the one that
    gives fewer), less those with no neighbour left on their own side, which cross over."""
    rows = np.repeat(np.arange(G.shape[0]), np.diff(G.indptr))
    cross = side[rows] != side[G.indices]
    best = None
    for s in (False, True):
        sep = np.zeros(side.size, dtype=bool)
        sep[rows[cross & (side[rows] == s)]] = True
        own = np.zeros(side.size, dtype=bool)  # a neighbour on side s outside the separator
        own[rows[(side[G.indices] == s) & ~sep[G.indices]]] = True
        moved = sep & ~own
        new_side = np.where(moved, not s, side)
        sep &= own
        if best is None or sep.sum() < best[1].sum():
            best = (new_side, sep)
    return best


def _bisection_split(G: sp.csr_matrix) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """(part 1, part 2, separator) of a connected graph cut across an axis of the graph.

    The axes are differences of breadth-first distances, d_a - d_b, from two far-apart
    vertices a and b (a pseudo-peripheral vertex and the farthest from it; then two far
    vertices of the middle cross-section): their level sets near the middle are close to
    planes across the body, where a level set of d_a alone is a cap around a (larger in
    a ball or a block).  Each axis splits the vertices in halves by rank; the smaller of
    the resulting vertex separators (:func:`_vertex_separator`) is kept.
    """
    n = G.shape[0]
    start, far = 0, -1.0
    for _ in range(4):  # a few sweeps: the farthest vertex of the farthest vertex ...
        d = _distances(G, start)
        nxt = int(np.argmax(d))
        if d[nxt] <= far:
            break
        start, far = nxt, d[nxt]
    if far < 2:
        return None
    d_a = _distances(G, start)
    d_b = _distances(G, int(np.argmax(d_a)))
    axes = [d_a - d_b]
    middle = np.flatnonzero(np.abs(d_a - d_b) <= 1)  # the cross-section half-way between a and b
    if middle.size > 2:
        c = int(middle[np.argmax(_distances(G, int(middle[0]))[middle])])
        d_c = _distances(G, c)
        d_e = _distances(G, int(middle[np.argmax(d_c[middle])]))
        axes.append(d_c - d_e)
    best = None
    for f in axes:
        rank = np.empty(n, dtype=np.int64)
        rank[np.lexsort((d_a, f))] = np.arange(n)
        side, sep = _vertex_separator(G, rank >= n // 2)
        if best is None or sep.sum() < best[1].sum():
            best = (side, sep)
    side, sep = best
    left, right = np.flatnonzero(~side & ~sep), np.flatnonzero(side & ~sep)
    if left.size == 0 or right.size == 0:
        return None
    return left, right, np.flatnonzero(sep)


def _dissect(G: sp.csr_matrix, vertices: np.ndarray, leaf: int, out: list[np.ndarray], split_by=None) -> None:
    """Append the nested-dissection order of the subgraph ``G`` (ids ``vertices``) to out."""
    if vertices.size <= leaf:
        out.append(vertices)
        return
    ncomp, label = csgraph.connected_components(G, directed=False)
    if ncomp > 1:
        order = np.argsort(label, kind="stable")
        bounds = np.concatenate([[0], np.cumsum(np.bincount(label, minlength=ncomp))])
        for k in range(ncomp):
            idx = order[bounds[k] : bounds[k + 1]]
            _dissect(G[idx][:, idx], vertices[idx], leaf, out, split_by)
        return
    split = (split_by or _bisection_split)(G)
    if split is None:
        out.append(vertices)
        return
    left, right, sep = split
    for part in (left, right):
        _dissect(G[part][:, part], vertices[part], leaf, out, split_by)
    out.append(vertices[sep])


def nested_dissection(A: sp.spmatrix, leaf: int = 32, separators: str = "bisection") -> np.ndarray:
    """Fill-reducing permutation p of the symmetric matrix A (factor A[p][:, p]).

    Parameters
    ----------
    A : (n, n) sparse matrix with a symmetric pattern (values are ignored).
    leaf : parts of at most this many supervariables are not split further.
    separators : ``bisection`` (:func:`_bisection_split`, the default) or ``levels`` (a level
        set of the distances from one vertex, :func:`_level_split`: the ordering before).

    Returns
    -------
    p : (n,) permutation of range(n); the dofs of a supervariable stay together.
    """
    groups = supervariables(A)
    if groups.size == 0:
        return np.zeros(0, dtype=np.int64)
    G = _pattern_graph(A, groups)
    out: list[np.ndarray] = []
    split_by = {"bisection": _bisection_split, "levels": _level_split}[separators]
    _dissect(G, np.arange(G.shape[0]), leaf, out, split_by)
    group_order = np.concatenate(out)
    rank = np.empty_like(group_order)
    rank[group_order] = np.arange(group_order.size)
    return np.argsort(rank[groups], kind="stable")


def has_metis() -> bool:
    """Whether pymetis is installed and loads."""
    return module_loads("pymetis")


def metis_nested_dissection(A: sp.spmatrix) -> np.ndarray:
    """Nested-dissection permutation of A by METIS (pymetis) on the supervariable graph."""
    import pymetis

    groups = supervariables(A)
    if groups.size == 0:
        return np.zeros(0, dtype=np.int64)
    G = _pattern_graph(A, groups)
    if G.nnz == 0:
        return np.arange(groups.size)
    graph = pymetis.CSRAdjacency(G.indptr.astype(np.int64), G.indices.astype(np.int64))
    group_order, _ = pymetis.nested_dissection(graph)
    rank = np.empty(G.shape[0], dtype=np.int64)
    rank[np.asarray(group_order)] = np.arange(G.shape[0])
    return np.argsort(rank[groups], kind="stable")


#: the ordering :func:`fill_reducing_order` uses when not told: ``auto`` (METIS when pymetis
#: loads, else :func:`nested_dissection`), or one of :data:`ORDERINGS` (benchmarks set it)
ORDERING = "auto"
ORDERINGS = ("metis", "nd", "nd-levels")


#: the orderings kept by pattern (module docstring; a permutation is 8 bytes a row)
CACHED_PATTERNS = 8
_orderings: OrderedDict[tuple, np.ndarray] = OrderedDict()


def pattern_digest(A: sp.spmatrix) -> tuple:
    """(shape, digest of the CSC pattern) of A: equal for two matrices of one stored pattern (an explicitly stored
    zero counts as an entry, as it does for the ordering and for CHOLMOD's analysis)."""
    C = A if sp.isspmatrix_csc(A) and A.has_sorted_indices else sp.csc_matrix(A)
    if not C.has_sorted_indices:
        C = C.sorted_indices()
    return C.shape, compressed_digest(C.indptr, C.indices)


def compressed_digest(indptr: np.ndarray, indices: np.ndarray) -> bytes:
    """A digest of a compressed (CSR or CSC) structure: SHA-256 of its index arrays, in 32 bits where they hold
    (half the bytes), read in place: 4x BLAKE2's speed on x86-64's SHA instructions (docs/performance.md)."""
    itype = np.int32 if max(indptr.size, indices.size) < 2**31 else np.int64
    h = hashlib.sha256(np.ascontiguousarray(indptr, dtype=itype))
    h.update(np.ascontiguousarray(indices, dtype=itype))
    return h.digest()


def fill_reducing_order(
    A: sp.spmatrix, method: str | None = None, digest: tuple | None = None
) -> tuple[np.ndarray, str]:
    """(permutation, name of the ordering): ``method`` (default :data:`ORDERING`) ``auto`` is
    METIS nested dissection when pymetis is installed, else :func:`nested_dissection`; the same permutation again
    for a matrix of a pattern ordered lately (module docstring).  ``digest``: A's :func:`pattern_digest`, when the
    caller has it."""
    method = method or ORDERING
    if method == "auto":
        method = "metis" if has_metis() else "nd"
    if method not in ORDERINGS:
        raise ValueError(f"unknown ordering {method!r}; known: auto, {', '.join(ORDERINGS)}")
    key = (method, *(digest or pattern_digest(A)))
    perm = _orderings.get(key)
    if perm is None:
        if method == "metis":
            perm = metis_nested_dissection(A)
        else:
            perm = nested_dissection(A, separators="levels" if method == "nd-levels" else "bisection")
        perm.setflags(write=False)
        _orderings[key] = perm
        while len(_orderings) > CACHED_PATTERNS:
            _orderings.popitem(last=False)
    else:
        _orderings.move_to_end(key)
    return perm, method

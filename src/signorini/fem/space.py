"""Vector Lagrange space (P1/Q1) and Dirichlet conditions by elimination.

Dof numbering: node-major, ``dof = d * node + component`` (component 0 = x).

A Dirichlet condition fixes chosen components on the nodes of a boundary tag to
values that may be inhomogeneous (constants or functions of x).  Conditions are
applied by elimination: with free dofs f and fixed dofs D, ``A u = b`` becomes
``A_ff u_f = b_f - A_fD u_D``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from .dofmap import DofMap
from .fields import at_time, is_time_dependent
from .mesh import Mesh

Value = float | Sequence[float] | Callable[..., np.ndarray]


@dataclass(frozen=True)
class Dirichlet:
    """u_i = value_i on the nodes of ``tag`` for i in ``components``.

    ``value`` is a scalar (same for every listed component), a sequence with one value
    per listed component, or a function of the node coordinates x (n, d) -- or of
    (x, t) for a prescribed motion -- returning (n, len(components)).
    ``components=None`` means all components.
    """

    tag: str
    value: Value = 0.0
    components: tuple[int, ...] | None = None


class VectorSpace:
    """Continuous vector P1/Q1 space on ``mesh`` with ``dim`` = mesh dimension components."""

    def __init__(self, mesh: Mesh):
        self.mesh = mesh
        self.dim = mesh.dim
        #: the one-process dof map (:mod:`signorini.fem.dofmap`): node-major blocks of d dofs
        self.dofmap = DofMap.serial(mesh.n_nodes, mesh.dim)
        self.n_dofs = self.dofmap.n_dofs

    def dofs(self, nodes: np.ndarray, components: Sequence[int] | None = None) -> np.ndarray:
        """Dofs of ``nodes`` (array) for ``components``, shape (len(nodes), len(components))."""
        return self.dofmap.dofs(nodes, components)

    def rigid_body_modes(self, dofs: np.ndarray) -> np.ndarray:
        """The rigid motions restricted to ``dofs`` (n,), as orthonormal columns (n, k).

        k = 1, 3, 6 in 1D, 2D, 3D: the d translations e_c and the rotations about the
        centroid x_0 of those dofs' nodes, omega x (x - x_0) (2D: (-(y - y_0), x - x_0)),
        orthonormalized (QR); a column that vanishes on ``dofs`` (a motion that Dirichlet
        conditions hold) is dropped.  The near-null space of an algebraic multigrid.
        """
        dofs = np.asarray(dofs, dtype=np.int64)
        nodes = self.dofmap.nodes_of(dofs)
        c = dofs - self.dim * nodes
        x = self.mesh.points[nodes] - self.mesh.points[nodes].mean(axis=0) if dofs.size else np.zeros((0, self.dim))
        cols = [(c == k).astype(float) for k in range(self.dim)]
        if self.dim == 2:
            cols.append(np.where(c == 0, -x[:, 1], x[:, 0]))
        elif self.dim == 3:
            for a in range(3):  # rotation about axis a: (e_a x r)_c
                b, e = (a + 1) % 3, (a + 2) % 3
                cols.append(np.where(c == b, -x[:, e], np.where(c == e, x[:, b], 0.0)))
        Q, R = np.linalg.qr(np.column_stack(cols))
        diag = np.abs(np.diag(R))
        keep = diag > 1e-10 * max(float(diag.max(initial=0.0)), 1e-300)
        return np.ascontiguousarray(Q[:, keep])

    def interpolate(self, value: Value) -> np.ndarray:
        """Nodal interpolant of a constant vector or of a function (n, d) -> (n, d)."""
        x = self.mesh.points
        if not callable(value) and np.ndim(value) == 1 and np.size(value) == x.size != x.shape[1]:
            value = np.asarray(value, dtype=float).reshape(x.shape)  # nodal values, node-major dofs
        v = value(x) if callable(value) else np.broadcast_to(np.asarray(value, dtype=float), x.shape)
        v = np.asarray(v, dtype=float)
        if v.shape != x.shape:
            raise InputError(f"a vector field on this mesh must have shape {x.shape}, got {v.shape}")
        return v.ravel().copy()


class Constraints:
    """Fixed dofs with their values (possibly functions of t); reduction to free dofs."""

    def __init__(self, space: VectorSpace, conditions: Sequence[Dirichlet] = ()):
        self.space = space
        fixed = np.zeros(space.n_dofs, dtype=bool)
        self._parts: list[tuple[Dirichlet, np.ndarray, np.ndarray]] = []
        for bc in conditions:
            comps = tuple(range(space.dim)) if bc.components is None else tuple(bc.components)
            for c in comps:
                if not 0 <= c < space.dim:
                    raise InputError(
                        f"Dirichlet component {c} on tag {bc.tag!r} is out of range; allowed 0..{space.dim - 1}"
                    )
            nodes = space.mesh.nodes_of(bc.tag)
            dofs = space.dofs(nodes, comps)
            if not callable(bc.value):
                v = np.atleast_1d(np.asarray(bc.value, dtype=float))
                if v.size not in (1, len(comps)):
                    raise InputError(f"Dirichlet value on tag {bc.tag!r} needs 1 or {len(comps)} numbers, got {v.size}")
            fixed[dofs.ravel()] = True
            self._parts.append((bc, nodes, dofs))
        self.fixed = np.flatnonzero(fixed)
        self.free = np.flatnonzero(~fixed)
        self.time_dependent = any(is_time_dependent(bc.value) for bc, _, _ in self._parts)
        self.values = self.values_at(0.0)
        self._check_agreement(0.0)

    def _check_agreement(self, t: float) -> None:
        """Two conditions that prescribe one dof (a corner shared by two tags) must agree:
        otherwise the last one would win without a word."""
        if len(self._parts) < 2:
            return
        seen = np.full(self.space.n_dofs, np.nan)
        owner = np.full(self.space.n_dofs, -1)
        for k, (bc, nodes, dofs) in enumerate(self._parts):
            if callable(bc.value):
                vals = np.asarray(at_time(bc.value, t)(self.space.mesh.points[nodes]), dtype=float)
            else:
                vals = np.atleast_1d(np.asarray(bc.value, dtype=float))
            v = np.broadcast_to(vals.reshape(len(nodes), -1) if vals.ndim > 1 else vals, dofs.shape).ravel()
            d = dofs.ravel()
            both = ~np.isnan(seen[d])
            clash = both & ~np.isclose(seen[d], v, rtol=1e-12, atol=1e-300)
            if clash.any():
                cand = np.flatnonzero(clash)  # name the clash at the dof the user numbered first
                mesh = self.space.mesh
                dm = self.space.dofmap
                nodes_c, comps = dm.nodes_of(d[cand]), d[cand] - dm.dofs(dm.nodes_of(d[cand]), [0]).ravel()
                ids = nodes_c if mesh.node_ids is None else mesh.node_ids[nodes_c]
                i = int(cand[np.lexsort((comps, ids))[0]])  # the user's first node, then its first component
                j = int(owner[d[i]])
                node = int(dm.nodes_of(d[i]))
                c = int(d[i] - dm.dofs(np.array([node]), [0])[0, 0])
                user = mesh.node_id(node)
                raise InputError(
                    f"Dirichlet conditions on tags {self._parts[j][0].tag!r} and {bc.tag!r} prescribe different values "
                    f"({seen[d[i]]:g} and {v[i]:g}) on the dof {int(dm.dofs(np.array([user]), [c])[0, 0])} they "
                    f"share (node {user}); make them agree there"
                )
            seen[d], owner[d] = v, k

    def values_at(self, t: float) -> np.ndarray:
        """Prescribed values on the fixed dofs (in the order of ``fixed``) at time t."""
        values = np.zeros(self.space.n_dofs)
        for bc, nodes, dofs in self._parts:
            if callable(bc.value):
                g = at_time(bc.value, t)
                vals = np.asarray(g(self.space.mesh.points[nodes]), dtype=float).reshape(len(nodes), -1)
            else:
                vals = np.atleast_1d(np.asarray(bc.value, dtype=float))
            values[dofs.ravel()] = np.broadcast_to(vals, dofs.shape).ravel()
        out = values[self.fixed]
        if not np.all(np.isfinite(out)):
            raise InputError(f"a Dirichlet value is not finite at t = {t:g}")
        return out

    @property
    def n_free(self) -> int:
        return self.free.size

"""The nodal Signorini contact set: contact nodes, normals, gaps, weights and B.

Sign conventions: see :mod:`signorini.contact.obstacles`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..errors import ConvergenceError, InputError
from ..fem.assembly import facet_weights
from ..fem.space import Constraints, VectorSpace
from .frames import frame_rows, tangent_frames
from .obstacles import RigidObstacle


def check_pair_tags(mesh, pairs: Sequence) -> None:
    """InputError for pairs the node-to-facet method does not do: a pair listed in both
    directions (each pair is one-sided: list it once, the finer side as slave) and a pair
    whose two sides are on one body (self-contact, not supported: the pair would face the
    body's own far side from t = 0)."""
    from ..fem.mesh import bodies

    seen: dict[tuple[str, str], int] = {}
    label = bodies(mesh)
    for k, p in enumerate(pairs):
        j = seen.get((p.master, p.slave))
        if j is not None:
            raise InputError(
                f"contact pairs {j} ({pairs[j].slave!r} / {pairs[j].master!r}) and {k} ({p.slave!r} / {p.master!r}) "
                "are one pair listed in both directions: list it once (node to facet is one-sided; the finer or "
                "curved side as slave, docs/bodies.md)"
            )
        seen[(p.slave, p.master)] = k
        own = np.intersect1d(np.unique(label[mesh.nodes_of(p.slave)]), np.unique(label[mesh.nodes_of(p.master)]))
        if own.size:
            raise InputError(
                f"contact pair {k} ({p.slave!r} / {p.master!r}): both tags are on body {int(own[0])} (one connected "
                "part of the mesh): self-contact is not supported; a pair joins two bodies"
            )


@dataclass
class ContactSet:
    """Contact nodes of a boundary tag facing a rigid obstacle.

    Attributes
    ----------
    nodes : (nc,) node indices on Gamma_C.
    normals : (nc, d) outward unit normals nu_i.
    gaps : (nc,) gaps g_i at t = 0 [length].
    weights : (nc,) w_i = int_{Gamma_C} N_i ds (1 per node in 1D).
    B : (nc, n_dofs) sparse, row i = nu_i^T on the dofs of node i.
    dofs : (nc, d) the dofs of the contact nodes.
    tangents : (nc, d - 1, d) unit tangents of the nodal frames (:mod:`~.frames`).

    A contact pair's row (:mod:`~.pairs`, :meth:`with_pairs`) is the motion of its slave node
    relative to the master point it faces: B's row is nu_i^T u_i - sum_j N_j(xi_i) nu_i^T u_j
    over the master facet's nodes j (``master_dofs``, ``master_shape``), and so are its
    tangential rows (t_ik instead of nu_i) in :meth:`tangential_matrix` and :meth:`frame_matrix`.
    """

    nodes: np.ndarray
    normals: np.ndarray
    gaps: np.ndarray
    weights: np.ndarray
    B: sp.csr_matrix
    points: np.ndarray | None = None
    obstacle: RigidObstacle | None = None
    dofs: np.ndarray | None = None
    #: (nc,) the contact pair of each row (-1: the rigid obstacle), :mod:`~.pairs`
    pair: np.ndarray | None = None
    #: (nc,) the master facet of each pair row (-1 on obstacle rows)
    master_facet: np.ndarray | None = None
    #: every node whose inertia the mass variant redistributes: the obstacle's contact nodes,
    #: the slave nodes and the nodes of the master tags (None: ``nodes``)
    inertia_nodes: np.ndarray | None = None
    #: per pair: its tags, rows, inactive slave nodes and contact law (summary.json ``pairs``)
    pair_info: list | None = None
    #: (nc, nfv, d) the dofs of the master facet's nodes of each pair row (-1 on obstacle rows)
    master_dofs: np.ndarray | None = None
    #: (nc, nfv) the master facet's shape functions N_j(xi) at the point a pair row faces (0 on obstacle rows)
    master_shape: np.ndarray | None = None
    #: the rigid obstacle's rows and its tagged nodes beyond the edge of a surface obstacle (no row)
    obstacle_info: dict | None = None

    @property
    def tangents(self) -> np.ndarray:
        """Unit tangents (nc, d - 1, d) of the nodal frames (computed once, from the normals)."""
        if not hasattr(self, "_tangents"):
            self._tangents = tangent_frames(self.normals)
        return self._tangents

    @property
    def has_pair_rows(self) -> bool:
        """Whether some row is a contact pair's (a slave node against a master facet)."""
        return self.pair is not None and self.master_dofs is not None and bool((self.pair >= 0).any())

    def _row_frame(self, vectors: np.ndarray, n_dofs: int) -> sp.csr_matrix:
        """The rows of ``vectors`` (nc, k, d) per contact row: on the contact node's dofs alone
        (a rigid obstacle's row, :func:`~.frames.frame_rows` as for a set without pairs), and
        for a pair's row also on the master facet's dofs with coefficients -N_j(xi):

            row i k + l = v_il^T u_i - sum_j N_j(xi_i) v_il^T u_j.
        """
        if not self.has_pair_rows:
            return frame_rows(self.dofs, vectors, n_dofs)
        nc = self.size
        dofs = np.concatenate([self.dofs[:, None, :], self.master_dofs], axis=1)  # (nc, 1 + nfv, d)
        coef = np.concatenate([np.ones((nc, 1)), -self.master_shape], axis=1)  # (nc, 1 + nfv)
        return frame_rows(dofs, vectors, n_dofs, coef)

    def rebuild_rows(self, n_dofs: int) -> None:
        """B (nc, n_dofs) and the nodal frames again from the normals (after they changed)."""
        if hasattr(self, "_tangents"):
            del self._tangents
        self.B = self._row_frame(self.normals[:, None, :], n_dofs).tocsr()

    def tangential_matrix(self, n_dofs: int) -> sp.csr_matrix:
        """T (nc (d - 1), n_dofs): row i (d - 1) + k = t_ik^T on the dofs of node i; on a pair's
        row, the slip relative to the master: t_ik^T u_i - sum_j N_j(xi_i) t_ik^T u_j."""
        return self._row_frame(self.tangents, n_dofs)

    def frame_matrix(self, n_dofs: int) -> sp.csr_matrix:
        """H (nc d, n_dofs) node-major: row i d = nu_i^T, rows i d + k = t_ik^T (k >= 1), on the
        dofs of node i (and on a pair's row, minus N_j(xi_i) times them on master node j: row
        i d is then B's row i)."""
        return self._row_frame(np.concatenate([self.normals[:, None, :], self.tangents], axis=1), n_dofs)

    def obstacle_slip(self, t0: float, t1: float, positions: np.ndarray | None = None) -> np.ndarray:
        """Tangential components c_ik (nc, d - 1) of the obstacle's motion from t0 to t1 at each row
        [length]: the displacement of the obstacle's material point X_i that faced node i at t = 0,
        t_ik . (Phi_t1(X_i) - Phi_t0(X_i)) (:mod:`~.obstacles`); without rotation at t0 and t1 the
        translation t_ik . (d(t1) - d(t0)), the same for every row.  Zero on the rows of contact
        pairs (their slip is relative to the master body).  ``positions`` (nc, d): the nodes' positions
        x_i at t0 (finite strain, large sliding): X_i = Phi_t0^-1(x_i), the obstacle's point each node is at
        then, instead of the one it faced at t = 0."""
        ob = self.obstacle
        if ob is not None and ob.turns(t0, t1):
            rigid = np.ones(self.size, dtype=bool) if self.pair is None else self.pair < 0
            shift = np.zeros((self.size, self.normals.shape[1]))
            X = self.material_points if positions is None else ob.motion.to_data(positions[rigid], t0)
            shift[rigid] = ob.displacement(X, t0, t1)
            slip = np.einsum("ikd,id->ik", self.tangents, shift)
            slip[~rigid] = 0.0
            return slip
        shift = ob.translation(t0, t1) if ob is not None else np.zeros(0)
        if shift.size == 0 or not np.any(shift):
            return np.zeros(self.tangents.shape[:2])
        slip = np.einsum("ikd,d->ik", self.tangents, shift)
        if self.pair is not None:
            slip[self.pair >= 0] = 0.0
        return slip

    @property
    def material_points(self) -> np.ndarray:
        """The rigid obstacle's material points X_i (n_rigid, d) (its own coordinates) that face
        the obstacle's rows at t = 0 (:meth:`~.obstacles.RigidObstacle.material_points`; computed
        once)."""
        if not hasattr(self, "_material_points"):
            rigid = np.ones(self.size, dtype=bool) if self.pair is None else self.pair < 0
            self._material_points = self.obstacle.material_points(self.points[rigid])
        return self._material_points

    def force_components(self, lam: np.ndarray, lam_t: np.ndarray | None = None) -> np.ndarray:
        """Global components (d,) of the total contact force sum_i lambda_i nu_i + lambda_t,i . t_i [force]
        on the contact nodes (a pair's row: the force on its slave node; the master gets its opposite)."""
        F = self.normals.T @ lam
        if lam_t is not None and lam_t.size:
            F = F + np.einsum("ik,ikd->d", lam_t, self.tangents)
        return F

    @classmethod
    def from_tag(
        cls,
        space: VectorSpace,
        tag: str | Sequence[str],
        obstacle: RigidObstacle,
        constraints: Constraints | None = None,
        where: Callable[[np.ndarray], np.ndarray] | None = None,
    ) -> ContactSet:
        """The contact set of the nodes of ``tag`` (one tag or several: their union).

        ``where`` (points (m, d) -> (m,) true/false) keeps only the tagged nodes where it
        is true; their weights stay those of the tagged facets around them.
        """
        mesh = space.mesh
        nodes = mesh.nodes_of(tag)
        if where is not None:
            keep = np.asarray(where(mesh.points[nodes])).reshape(nodes.size) != 0
            if not keep.any():
                raise InputError(
                    f"contact.where selects none of the {nodes.size} node(s) of contact tag {tag!r} "
                    f"(they span {np.round(mesh.points[nodes].min(axis=0), 6).tolist()} .. "
                    f"{np.round(mesh.points[nodes].max(axis=0), 6).tolist()})"
                )
            nodes = nodes[keep]
        gaps, normals = obstacle.gaps_and_normals(mesh.points[nodes])
        facing = np.isfinite(gaps)  # a surface obstacle: nodes beyond its edge face nothing
        if not facing.all():
            if not facing.any():
                box = mesh.points[nodes]
                raise InputError(
                    f"contact tag {tag!r}: none of its {nodes.size} node(s) faces the surface obstacle (every one is "
                    f"beyond its edge; the nodes span {np.round(box.min(axis=0), 6).tolist()} .. "
                    f"{np.round(box.max(axis=0), 6).tolist()}): move or extend the surface"
                )
            nodes, gaps, normals = nodes[facing], gaps[facing], normals[facing]
        weights = facet_weights(mesh, tag, positive=True)[nodes]
        if not np.all(weights > 0) or not np.all(np.isfinite(weights)):
            bad = np.flatnonzero(~(weights > 0)) if not np.all(weights > 0) else np.arange(nodes.size)
            i = int(bad[mesh.first_by_id(nodes[bad])])
            raise InputError(
                f"contact tag {tag!r}: node {mesh.node_id(nodes[i])} at "
                f"{np.round(mesh.points[nodes[i]], 6).tolist()} has "
                "zero contact area (its tagged facets are degenerate: zero length or area); fix the mesh"
            )
        dofs = space.dofs(nodes)
        rows = np.repeat(np.arange(nodes.size), space.dim)
        B = sp.csr_matrix((normals.ravel(), (rows, dofs.ravel())), shape=(nodes.size, space.n_dofs))
        if constraints is not None and constraints.fixed.size:
            fixed = np.zeros(space.n_dofs, dtype=bool)
            fixed[constraints.fixed] = True
            clash = (fixed[dofs] & (np.abs(normals) > 1e-12)).any(axis=1)
            if clash.any():
                e = nodes[clash][mesh.first_by_id(nodes[clash])]
                raise InputError(
                    f"contact tag {tag!r}: {int(clash.sum())} contact node(s) are fixed by a Dirichlet "
                    f"condition in the normal direction (e.g. node {mesh.node_id(e)}); "
                    "remove them from the Dirichlet or the contact tag"
                )
        info = {"rows": int(nodes.size), "nodes_beyond_edge": int((~facing).sum())}
        return cls(nodes, normals, gaps, weights, B, mesh.points[nodes], obstacle, dofs, obstacle_info=info)

    @property
    def moving(self) -> bool:
        """Whether the gaps depend on time (a moving obstacle)."""
        return bool(self.obstacle is not None and self.obstacle.moving)

    def gaps_at(self, t: float) -> np.ndarray:
        """Gaps g_i(t) (nc,) for the obstacle's position at time t [length] (a pair's rows:
        their gaps at t = 0, the pairing is frozen)."""
        if not self.moving:
            return self.gaps
        if self.pair is None or not (self.pair >= 0).any():
            g = np.asarray(self.obstacle.gaps(self.points, t), dtype=float)
            rigid = slice(None)
        else:
            g = self.gaps.copy()
            rigid = self.pair < 0
            g[rigid] = np.asarray(self.obstacle.gaps(self.points[rigid], t), dtype=float)
        if not np.isfinite(g[rigid]).all():
            self._beyond_edge(g, t)
        return g

    def _beyond_edge(self, g: np.ndarray, t: float) -> None:
        """A moving surface obstacle left a row's node (its gap is +inf): the row cannot be dropped
        during the run; stop it (ConvergenceError: status failed, the levels computed kept)."""
        bad = np.flatnonzero(~np.isfinite(g))
        i = int(bad[0])
        raise ConvergenceError(
            f"the surface obstacle moved away from {bad.size} contact node(s) at t = {t:.6g}, e.g. the node at "
            f"{np.round(self.points[i], 6).tolist()}: it is beyond the surface's edge and faces nothing, which a "
            "contact row cannot do during a run; extend the surface (or restrict [contact] where)"
        )

    @property
    def mass_nodes(self) -> np.ndarray:
        """The nodes that carry no contact inertia under a redistributed mass (sorted)."""
        return self.nodes if self.inertia_nodes is None else self.inertia_nodes

    @classmethod
    def empty(cls, space: VectorSpace) -> ContactSet:
        """No rigid obstacle: a set of no rows, to which pairs are added."""
        d = space.dim
        z = np.zeros(0)
        B = sp.csr_matrix((0, space.n_dofs))
        none = np.zeros(0, dtype=np.int64)
        return cls(none, np.zeros((0, d)), z, z.copy(), B, np.zeros((0, d)), None, np.zeros((0, d), dtype=np.int64))

    def with_pairs(self, space: VectorSpace, pairs: Sequence, every: bool = False) -> ContactSet:
        """This set (the rigid obstacle's rows, maybe none) followed by the rows of ``pairs``
        (:class:`~.pairs.ContactPair`), pair k's rows tagged k in :attr:`pair`; ``every``: a row for every slave
        node, facing the master surface at t = 0 or not (finite strain)."""
        from .pairs import pair_rows, pair_side_warning

        mesh = space.mesh
        parts = [pair_rows(mesh, p, space.n_dofs, every) for p in pairs]
        check_pair_tags(mesh, pairs)
        for p, r in zip(pairs, parts, strict=True):
            if r.nodes.size == 0:
                n = mesh.nodes_of(p.slave).size
                raise InputError(
                    f"contact pair {p.slave!r} / {p.master!r}: none of its {n} slave node(s) faces the master surface "
                    "at t = 0 (each lies laterally off it), so the pair could never touch; check the tags or the "
                    "bodies' positions"
                )
        owner = np.concatenate([np.full(r.nodes.size, k) for k, r in enumerate(parts)])
        slaves = np.concatenate([r.nodes for r in parts])
        order = np.argsort(slaves, kind="stable")
        twice = np.flatnonzero(np.diff(slaves[order]) == 0)
        if twice.size:
            a, b = owner[order[twice[0]]], owner[order[twice[0] + 1]]
            node = int(slaves[order[twice[0]]])
            raise InputError(
                f"contact pairs {a} ({pairs[a].slave!r} / {pairs[a].master!r}) and {b} ({pairs[b].slave!r} / "
                f"{pairs[b].master!r}) share slave node {mesh.node_id(node)} at "
                f"{np.round(mesh.points[node], 6).tolist()} ({twice.size} in all): a node is the slave of one pair "
                "(list each pair once; tag each slave surface once)"
            )
        nr, d = self.nodes.size, space.dim
        nodes = np.concatenate([self.nodes] + [r.nodes for r in parts])
        nfv = parts[0].xi.shape[1]  # one cell type: the same facets for every pair
        master_dofs = np.concatenate(
            [np.full((nr, nfv, d), -1, dtype=np.int64)]
            + [space.dofs(r.facet_nodes.ravel()).reshape(-1, nfv, d) for r in parts]
        )
        master_shape = np.concatenate([np.zeros((nr, nfv))] + [r.xi for r in parts])
        info = [
            {
                "slave": p.slave,
                "master": p.master,
                "rows": int(r.nodes.size),
                "inactive_slave_nodes": r.inactive,
                "repaired_rows": 0,
                "warning": pair_side_warning(mesh, p),
            }
            for p, r in zip(pairs, parts, strict=True)
        ]
        # every node of the slave and master tags (a slave node facing nothing at t = 0 included)
        inertia = np.unique(
            np.concatenate(
                [self.nodes]
                + [np.concatenate([mesh.nodes_of(p.slave), r.master_nodes]) for p, r in zip(pairs, parts, strict=True)]
            )
        )
        return ContactSet(
            nodes,
            np.vstack([self.normals] + [r.normals for r in parts]),
            np.concatenate([self.gaps] + [r.gaps for r in parts]),
            np.concatenate([self.weights] + [r.weights for r in parts]),
            sp.vstack([self.B] + [r.B for r in parts]).tocsr(),
            mesh.points[nodes],
            self.obstacle,
            space.dofs(nodes),
            np.concatenate([np.full(nr, -1)] + [np.full(r.nodes.size, k) for k, r in enumerate(parts)]),
            np.concatenate([np.full(nr, -1)] + [r.facet for r in parts]),
            inertia,
            info,
            master_dofs,
            master_shape,
            self.obstacle_info,
        )

    def slide(self, space: VectorSpace, pairs: Sequence, U: np.ndarray) -> np.ndarray:
        """Small sliding (:func:`~.pairs.slid_rows`): re-pair, in place, the pair rows whose slave
        node left its master facet in the configuration X + U; returns the rows changed (sorted).

        Their normal, gap, master facet, facet dofs and shape functions, and B's rows change;
        the tangents (from the normals) are recomputed."""
        from .pairs import master_geometry, slid_rows

        if not self.has_pair_rows:
            return np.zeros(0, dtype=np.int64)
        mesh, d = space.mesh, space.dim
        if getattr(self, "_pair_geometry", None) is None:  # the master tags' facets: constant over a run
            self._pair_geometry = [master_geometry(mesh, p) for p in pairs]
            self._pair_rows = [np.flatnonzero(self.pair == k) for k in range(len(pairs))]
        changed = []
        for k, pair in enumerate(pairs):
            rows = self._pair_rows[k]
            r = slid_rows(mesh, pair, rows, self.nodes[rows], self.master_facet[rows], U, self._pair_geometry[k])
            if r is None:
                continue
            self.normals[r.rows] = r.normals
            self.gaps[r.rows] = r.gaps
            self.master_facet[r.rows] = r.facet
            self.master_shape[r.rows] = r.xi
            self.master_dofs[r.rows] = space.dofs(r.facet_nodes.ravel()).reshape(r.rows.size, -1, d)
            if self.pair_info is not None:
                self.pair_info[k]["repaired_rows"] += int(r.rows.size)
            changed.append(r.rows)
        if not changed:
            return np.zeros(0, dtype=np.int64)
        rows = np.sort(np.concatenate(changed))
        if hasattr(self, "_tangents"):
            del self._tangents
        self.B = self._row_frame(self.normals[:, None, :], space.n_dofs).tocsr()
        return rows

    @property
    def size(self) -> int:
        return self.nodes.size

    def gap(self, u: np.ndarray) -> np.ndarray:
        """Current gaps g_i - nu_i . u_i (>= 0 when admissible)."""
        return self.gaps - self.B @ u

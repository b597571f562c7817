"""Contact is enforced on the tagged nodes only: watch every other boundary node.

The Signorini condition is imposed at the contact nodes (the nodes of the facets tagged
``[contact] tag``, restricted by ``where``).  Every *other* node of the mesh boundary is
free to enter the obstacle, which is a silent wrong answer when the body touches the
obstacle where the user did not tag it.  :class:`UntaggedContact` measures, at every
level, the largest penetration of these nodes into the obstacle,

    p_n = max(0, max_j -phi(x_j + u_j^n, t_n))   over untagged boundary nodes j  [length],

(the ``untagged_penetration`` column of ``history.csv``; ``untagged_penetration_max`` in
``summary.json``).

Contact pairs (two deformable bodies): the boundary nodes of a pair's slave body that are
not slave nodes are watched against the master surface, and those of the master body that
are not master nodes against the slave surface, with the pair's own linearized gap (each
node projected at t = 0 on the facing surface, :func:`~signorini.contact.pairs.node_to_facet_rows`):
p = max(0, max_j -(g_j - B_j U)) over the nodes facing the surface.  With finite strain each
watched node is projected on the deformed facing surface at every level instead
(:class:`CurrentPairWatch`: the pairs slide and turn).  The master tag's own
nodes entering the slave surface between slave nodes are the node-to-facet method's known
limit (docs/bodies.md: choose the finer side as slave): they are watched the same way but only
reported (summary.json ``master_penetration_max``, with its node and time, and a line of the
one-screen summary; no warning, no failure: a master node on a curved or refined slave surface
enters it by the round-off of the discretization at every contact).

Above :data:`UNTAGGED_TOLERANCE` x the body's size the run warns, or, with the solver
option ``untagged_contact = fail``, stops with status ``failed`` (the levels computed are
kept).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ...errors import ConvergenceError, InputError
from ...fem.mesh import Mesh, bodies, mesh_boundary
from ..schemes import State
from .observers import Observer, Run

#: penetration of an untagged node, relative to the body's size, that is reported as contact
UNTAGGED_TOLERANCE = 1e-9
#: penetrations within this fraction of the body's size are a tie for the node a message names
TIE = 1e-12


def boundary_nodes(mesh: Mesh) -> np.ndarray:
    """(nb,) sorted indices of the nodes on the boundary of the mesh."""
    return np.unique(np.concatenate([f.ravel() for f in mesh_boundary(mesh)]))


def body_size(mesh: Mesh) -> float:
    """The diagonal of the body's bounding box [length] (1 for a single point)."""
    return float(np.linalg.norm(np.ptp(mesh.points, axis=0))) or 1.0


@dataclass
class PairWatch:
    """The linearized gaps of the watched nodes of every pair against the facing surface."""

    nodes: np.ndarray  # (m,) watched nodes (a node may face several surfaces)
    gaps: np.ndarray  # (m,) gaps at t = 0 [length]
    B: sp.csr_matrix  # (m, n_dofs) the rows of the gaps' change (node-to-facet, as a pair's)
    surface: np.ndarray  # (m,) index in ``names`` of the surface each row faces
    names: list[str]  # the surfaces, e.g. "'plate_ymax' (master of pair 0)"

    def gaps_at(self, U: np.ndarray) -> np.ndarray:
        """(m,) the watched nodes' gaps at U, linearized at t = 0 [length]."""
        return self.gaps - self.B @ U


@dataclass
class CurrentPairWatch:
    """With finite strain: the watched nodes projected on the facing surface in the current configuration at
    every level (:class:`~signorini.contact.pairs.CurrentPairing`: large sliding and rotation), a node beyond the
    surface's rim facing nothing."""

    nodes: np.ndarray  # (m,) watched nodes
    surface: np.ndarray  # (m,) index in ``names`` of the surface each node is watched against
    names: list[str]
    pairings: list  # per surface, its CurrentPairing

    def gaps_at(self, U: np.ndarray) -> np.ndarray:
        """(m,) the watched nodes' normal gaps at X + U [length]: +inf where a node faces nothing, and where it
        lies more than its facet's size behind the surface.  A surface is open: a node of the other body behind a
        part of it that has turned away has a negative signed distance without being through it (an adversarial
        review: a block flipped over above another, -0.25 m); a node that goes through is seen as it enters,
        levels before it is that deep."""
        out = np.full(self.nodes.size, np.inf)
        for k, pairing in enumerate(self.pairings):
            rows = np.flatnonzero(self.surface == k)
            proj = pairing(self.nodes[rows], U)
            x = pairing.mesh.points + np.asarray(U).reshape(-1, pairing.mesh.dim)
            size = np.linalg.norm(np.ptp(x[proj.facet_nodes], axis=1), axis=1)
            out[rows] = np.where(proj.facing & (proj.gaps > -size), proj.gaps, np.inf)
        return out


def _watched(mesh: Mesh, pairs) -> list[tuple[int, str, str, str, np.ndarray]]:
    """Per pair and side: (pair index, the watched body's own tag, the surface it is watched against, its role,
    the watched nodes: the boundary nodes of that body in neither tag)."""
    label = bodies(mesh)
    boundary = boundary_nodes(mesh)
    out = []
    for k, pair in enumerate(pairs):
        for own, other, role in ((pair.slave, pair.master, "master"), (pair.master, pair.slave, "slave")):
            mine = mesh.nodes_of(own)
            watched = boundary[np.isin(label[boundary], np.unique(label[mine])) & ~np.isin(boundary, mine)]
            watched = np.setdiff1d(watched, np.unique(mesh.facets_of(other)))
            if watched.size:
                out.append((k, own, other, role, watched))
    return out


def _masters(mesh: Mesh, pairs) -> list[tuple[int, str, str, str, np.ndarray]]:
    """Per pair: (pair index, its master tag, its slave tag, "slave", the master tag's nodes that are not slave
    nodes), watched against the slave surface (:func:`_watched`'s form)."""
    out = []
    for k, pair in enumerate(pairs):
        nodes = np.setdiff1d(mesh.nodes_of(pair.master), mesh.nodes_of(pair.slave))
        if nodes.size:
            out.append((k, pair.master, pair.slave, "slave", nodes))
    return out


def pair_watch(
    mesh: Mesh, pairs, n_dofs: int, current: bool = False, masters: bool = False
) -> PairWatch | CurrentPairWatch | None:
    """The untagged watch of the contact pairs (module docstring); None without pairs; ``current`` (finite
    strain): in the current configuration (:class:`CurrentPairWatch`); ``masters``: the master tags' own nodes
    against the slave surfaces instead of the untagged nodes."""
    from ...contact.pairs import ContactPair, CurrentPairing, node_to_facet_rows

    if not pairs:
        return None
    sides = (_masters if masters else _watched)(mesh, pairs)
    if current:
        if not sides:
            return None
        return CurrentPairWatch(
            np.concatenate([w for *_, w in sides]),
            np.concatenate([np.full(w.size, j) for j, (*_, w) in enumerate(sides)]),
            [f"{other!r} ({role} of pair {k})" for k, _, other, role, _ in sides],
            [CurrentPairing(mesh, ContactPair(own, other)) for _, own, other, _, _ in sides],
        )
    parts = []
    for k, _, other, role, watched in sides:
        r = node_to_facet_rows(mesh, watched, mesh.facets_of(other), n_dofs)
        if r.nodes.size:  # nodes laterally off the surface face nothing
            parts.append((r, f"{other!r} ({role} of pair {k})"))
    if not parts:
        return None
    return PairWatch(
        np.concatenate([r.nodes for r, _ in parts]),
        np.concatenate([r.gaps for r, _ in parts]),
        sp.vstack([r.B for r, _ in parts]).tocsr(),
        np.concatenate([np.full(r.nodes.size, k) for k, (r, _) in enumerate(parts)]),
        [name for _, name in parts],
    )


class UntaggedContact(Observer):
    """Penetration of the boundary nodes that are not contact nodes, per level."""

    def __init__(self, mode: str = "warn"):
        self.mode = mode
        self.series = np.zeros(0)
        #: per level, the largest penetration of the master tags' own nodes into the slave surfaces (0 without pairs)
        self.master_series = np.zeros(0)
        self.worst: tuple[float, int, float] = (0.0, -1, 0.0)  # (penetration, node, t)
        #: the master tags' own nodes through the slave surfaces (reported only): (penetration, node, t)
        self.master_worst: tuple[float, int, float] = (0.0, -1, 0.0)
        self.master_watch: PairWatch | CurrentPairWatch | None = None

    def start(self, run: Run) -> None:
        disc = run.ctx.disc
        mesh = disc.problem.mesh
        rigid = disc.contact.nodes if disc.contact.pair is None else disc.contact.nodes[disc.contact.pair < 0]
        # no rigid obstacle (contact pairs only): nothing to watch against it
        self.nodes = np.setdiff1d(boundary_nodes(mesh), rigid) if disc.problem.obstacle is not None else rigid[:0]
        self.pair_watch = pair_watch(mesh, disc.problem.pairs, disc.space.n_dofs, current=run.ctx.elastic.finite)
        self.master_watch = pair_watch(
            mesh, disc.problem.pairs, disc.space.n_dofs, current=run.ctx.elastic.finite, masters=True
        )
        extra = self.pair_watch.nodes if self.pair_watch is not None else self.nodes[:0]
        self.all_nodes = np.concatenate([self.nodes, extra])
        self._surface = ""  # the surface the worst node crossed (a pair's tag), "" for the rigid obstacle
        self.X = mesh.points[self.nodes]
        self.mesh = mesh
        self.d = mesh.dim
        self.tolerance = UNTAGGED_TOLERANCE * body_size(mesh)
        self.tie = TIE * body_size(mesh)
        self.obstacle = disc.problem.obstacle
        self.series = np.zeros(run.n_steps + 1)
        self.master_series = np.zeros(run.n_steps + 1)
        self._put(0, run.initial)

    def grow(self, size: int) -> None:
        """Room for levels 0 .. size - 1 (an adaptive run's levels are not known in advance)."""
        if self.series.size < size:
            self.series = np.concatenate([self.series, np.zeros(size - self.series.size)])
        if self.master_series.size < size:
            self.master_series = np.concatenate([self.master_series, np.zeros(size - self.master_series.size)])

    def _deepest(self, phi: np.ndarray, nodes: np.ndarray) -> tuple[float, int]:
        """(max(0, -min phi), the position of that node in ``nodes``) of the gaps ``phi`` (m,) of ``nodes``: at a
        tie (to TIE x the body's size: round-off differs between node orders and ranks) the node the user numbered
        first, so that a message does not depend on them; (0, -1) without gaps."""
        if phi.size == 0:
            return 0.0, -1
        ties = np.flatnonzero(phi <= phi.min() + self.tie)
        j = int(ties[self.mesh.first_by_id(nodes[ties])]) if ties.size else int(np.argmin(phi))  # NaN: argmin
        return max(0.0, -float(phi[j])), j

    def _put_masters(self, n: int, s: State) -> None:
        """The master tags' own nodes through the slave surfaces at the level ``s`` (reported only)."""
        w = self.master_watch
        if w is None:
            return
        p, j = self._deepest(w.gaps_at(s.U), w.nodes)
        self.master_series[n] = p
        worst, node = self.master_worst[:2]
        if j >= 0 and (p > worst + self.tie or (p > worst and node < 0)):  # beyond a tie only, as the untagged's
            self.master_worst = (p, int(w.nodes[j]), float(s.t))

    def _put(self, n: int, s: State) -> None:
        self._put_masters(n, s)
        if self.nodes.size == 0 and self.pair_watch is None:
            return
        if self.nodes.size:
            x = self.X + s.U.reshape(-1, self.d)[self.nodes]
            phi = self.obstacle.gaps(x, s.t)
        else:
            phi = np.zeros(0)
        if self.pair_watch is not None:
            w = self.pair_watch
            phi = np.concatenate([phi, w.gaps_at(s.U)])
        if phi.size == 0:
            return
        nodes = self.all_nodes
        p, j = self._deepest(phi, nodes)
        self.series[n] = p
        if p > self.worst[0]:  # the largest value; its node and time change beyond a tie only
            if p > self.worst[0] + self.tie or self.worst[1] < 0:
                self.worst = (p, int(nodes[j]), float(s.t))
                k = j - self.nodes.size
                w = self.pair_watch
                self._surface = w.names[int(w.surface[k])] if k >= 0 else ""
            else:
                self.worst = (p, *self.worst[1:])
        if self.mode == "fail" and p > self.tolerance:
            if n == 0:  # the data put it there: an input error, before anything is computed
                raise InputError(f"{self.message()} (at t = 0: the initial state)")
            raise ConvergenceError(self.message())

    def record(self, run: Run, n: int, state: State) -> None:
        self._put(n, state)

    checkpoint_key = "untagged"

    def saved(self, n: int) -> dict:
        return {
            "series": {"penetration": self.series[: n + 1], "master_penetration": self.master_series[: n + 1]},
            "worst": list(self.worst),
            "surface": self._surface,
            "master_worst": list(self.master_worst),
        }

    def resume(self, run: Run, n: int, state: State, data: dict) -> None:
        series = np.asarray(data.get("series", {}).get("penetration", []))
        if series.shape != (n + 1,) or series.dtype != self.series.dtype:
            raise InputError(f"checkpoint: the untagged series has shape {series.shape}, expected {(n + 1,)}")
        self.series[: n + 1] = series
        masters = np.asarray(data.get("series", {}).get("master_penetration", np.full(n + 1, np.nan)))
        if masters.shape != (n + 1,) or masters.dtype != self.master_series.dtype:  # (nan: a checkpoint of before it)
            raise InputError(
                f"checkpoint: the master penetration series has shape {masters.shape}, expected {(n + 1,)}"
            )
        self.master_series[: n + 1] = masters
        self.worst = self._checked(data.get("worst"), "untagged watch")
        self._surface = str(data["surface"])
        # a checkpoint written before the master watch: none seen before the resume
        self.master_worst = self._checked(data.get("master_worst", [0.0, -1, 0.0]), "master watch")

    def _checked(self, value, what: str) -> tuple[float, int, float]:
        """A checkpoint's (penetration, node, t) of a watch, checked (a forged file: a one-line InputError)."""
        numbers = (
            isinstance(value, list)
            and len(value) == 3
            and all(isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x) for x in value)
        )
        if not (numbers and value[0] >= 0 and isinstance(value[1], int) and -1 <= value[1] < self.mesh.n_nodes):
            raise InputError(
                f"checkpoint: the {what}'s worst {value!r} is not [penetration >= 0, a node of the mesh or -1, t]"
            )
        return float(value[0]), int(value[1]), float(value[2])

    def close(self, run: Run, status: str, n_last: int, state: State) -> None:
        self.series = self.series[: n_last + 1]
        self.master_series = self.master_series[: n_last + 1]

    def watched_nodes(self) -> int:
        """The number of distinct nodes watched (against the rigid obstacle or a pair's surface)."""
        return int(np.unique(getattr(self, "all_nodes", np.zeros(0, dtype=int))).size)

    def master_summary(self) -> dict | None:
        """summary.json ``master_penetration_max`` [length], ``master_penetration_node`` (the user's number) and
        ``master_penetration_time``; None without contact pairs."""
        if self.master_watch is None:
            return None
        p, node, t = self.master_worst
        return {
            "master_penetration_max": p,
            "master_penetration_node": self.mesh.node_id(node) if node >= 0 else None,
            "master_penetration_time": t if node >= 0 else None,
        }

    def exceeded(self) -> bool:
        return self.worst[0] > self.tolerance

    def message(self) -> str:
        p, node, t = self.worst
        where = np.round(self.mesh.points[node], 6).tolist()
        if self._surface:
            return (
                f"boundary node {self.mesh.node_id(node)} at {where}, not a contact node of its pair, is {p:.3g} "
                f"through the paired surface {self._surface} at t = {t:.6g} (tolerance {self.tolerance:.2g}): "
                "contact is enforced on the slave nodes only; tag this part of the boundary into the pair's slave "
                "tag, or add a pair for it"
            )
        return (
            f"boundary node {self.mesh.node_id(node)} at {where}, not a contact node, is {p:.3g} inside the "
            f"obstacle at t = {t:.6g} "
            f"(tolerance {self.tolerance:.2g}): contact is enforced on the tagged nodes only; tag this part of "
            "the boundary for contact ([contact] tag, where)"
        )

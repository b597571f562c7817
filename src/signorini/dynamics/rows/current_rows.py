"""Contact rows in the current configuration (finite strain against a rigid obstacle, and contact pairs).

With finite strain a contact node's gap is the signed distance of its current position x = X + u to the
obstacle, phi_t(x), and its row the obstacle's outward body normal there, nu(x, t).  A step's Newton
iterations (:mod:`~signorini.dynamics.solve.newton`) move the rows to every iterate U^k:

    nu_i^T u_i <= phi_t(x_i^k) + nu_i . u_i^k        (the signed distance linearized at U^k)

exact for a plane (nu constant), converging with the iterate for a sphere.  :class:`CurrentRows` owns
that motion of the rows (the contact set's normals, B and the frames follow; the solvers' rows through
:meth:`~signorini.dynamics.solve.context.Context.replace_rows`), keeps the rows a level's multipliers acted
through for its energy identity, puts them back before a rejected step is tried again, and is what a
checkpoint saves of them.  :func:`contact_bound` is what a scheme's finite-strain step passes as the
bound of its solve; :func:`level_gaps` the gaps of a level for the history.
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np
import scipy.sparse as sp

from ...contact.solver import ContactLaw
from ...errors import InputError

#: the gaps of the current configuration are the true ones to this many touch tolerances (1e-10 of the body)
GAP_TOLERANCE = 100.0
#: the gap given to a pair row whose slave node lies beyond the master surface's rim (faces nothing), in units
#: of the coordinates' size: large enough never to be reached in a step
OFF_RIM = 1e6
#: a pair's row whose facing (its slave node within the master surface's rim or beyond it) changed this many
#: times between the Newton iterates of a step faces its facet's line for the rest of the step: a node at the
#: rim that the support pushes out and its loss pulls back in has no consistent state otherwise (Newton cycled)
RIM_FLIPS = 2
#: the round-off of a distance relative to the numbers it is computed from (1e3 machine epsilons)
ROUNDOFF = 1e3 * np.finfo(float).eps

if TYPE_CHECKING:
    from ..solve.context import Context
    from .contact_rows import ContactRows


class CurrentRows:
    """The rigid obstacle's rows of the current configuration of one run (module docstring).

    Parameters
    ----------
    rows : the run's contact rows (their contact set's normals are moved, their blocks rebuilt).
    """

    def __init__(self, rows: ContactRows, own: np.ndarray | None = None):
        self.rows = rows
        self.contact = rows.disc.contact
        self.obstacle = rows.disc.problem.obstacle
        self.n_dofs = rows.disc.space.n_dofs
        #: the obstacle's rows (all rows but those of contact pairs, :class:`CurrentRowsAndPairs`)
        self.own = np.arange(self.contact.size) if own is None else np.asarray(own, dtype=np.int64)
        #: every row faces the obstacle (:attr:`CurrentPairRows.facing`)
        self.facing: np.ndarray | None = None

    def _points(self, U: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(x, u) (m, d) of the own rows' nodes at U."""
        c = self.contact
        u = U[c.dofs[self.own]]
        return c.points[self.own] + u, u

    def follow(self, U: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
        """The rows at the iterate U (n,) and time t: (bound (nc,; 0 on the rows of others), the rows whose
        normal changed)."""
        c = self.contact
        x, u = self._points(U)
        nu = self.obstacle.body_normals(x, t)
        bound = np.zeros(c.size)
        bound[self.own] = np.asarray(self.obstacle.gaps(x, t), dtype=float) + np.einsum("id,id->i", nu, u)
        moved = np.any(nu != c.normals[self.own], axis=1)
        changed = self.own[moved]
        self._set(changed, nu[moved])
        return bound, changed

    def contact_force(self, U: np.ndarray, t: float, lam: np.ndarray) -> np.ndarray:
        """B(U)^T lambda (n,) on the own rows: the force of the multipliers through the rows of the iterate U
        itself (the body normals at x = X + U), not through those a solve froze [force]."""
        c = self.contact
        out = np.zeros(self.n_dofs)
        if self.own.size:
            nu = self.obstacle.body_normals(self._points(U)[0], t)
            out[c.dofs[self.own]] = lam[self.own, None] * nu  # one row per contact node: no dof twice
        return out

    def geometric_stiffness(self, U: np.ndarray, t: float, lam: np.ndarray) -> sp.csr_matrix | None:
        """sum_i lambda_i d^2 phi_t / dx^2 (x_i) (n, n) on the pressed own rows: the turning of the obstacle's
        normal under a node that moves (a sphere's curvature; zero for a plane), which rows frozen at an
        iterate leave out of Newton's tangent.  The row is -nu = grad phi; its derivative -d nu / dx by central
        differences of the body normals (step 1e-7 of the coordinates' size), symmetrized.  None: nothing
        pressed."""
        c, d = self.contact, self.contact.dofs.shape[1]
        pressed = self.own[lam[self.own] < 0]
        if not pressed.size:
            return None
        x = c.points[pressed] + U[c.dofs[pressed]]
        h = 1e-7 * max(float(np.abs(x).max(initial=0.0)), 1e-300)
        H = np.zeros((pressed.size, d, d))
        for a in range(d):
            step = np.zeros(d)
            step[a] = h
            H[:, :, a] = -(self.obstacle.body_normals(x + step, t) - self.obstacle.body_normals(x - step, t)) / (2 * h)
        if not np.any(H):
            return None
        return _blocks_matrix(0.5 * (H + H.transpose(0, 2, 1)) * lam[pressed, None, None], c.dofs[pressed], self.n_dofs)

    def distance_scale(self, U: np.ndarray, t: float) -> float:
        """The size of the numbers the obstacle's distance is computed from at U (its round-off's scale)
        [length]: the obstacle's own (:meth:`~signorini.contact.obstacles.RigidObstacle.distance_scale`)."""
        if not self.own.size:
            return 0.0
        return float(self.obstacle.distance_scale(self._points(U)[0], t))

    def gaps(self, U: np.ndarray, t: float, outside: float | None = None) -> np.ndarray:
        """phi_t(X + U) (nc,) of the contact nodes [length] (0 on the rows of others; ``outside``: the pairs')."""
        out = np.zeros(self.contact.size)
        out[self.own] = np.asarray(self.obstacle.gaps(self._points(U)[0], t), dtype=float)
        return out

    def keep_level(self, t: float) -> None:
        """Before a step from the level at t moves the rows: they are that level's (kept for its identity,
        :meth:`ContactRows.keep_level`).  A rejected step's rows are put back by its rollback
        (:meth:`resume` of :meth:`saved`, :mod:`~signorini.dynamics.restart.protocol`)."""
        self.rows.keep_level(t)

    def saved(self) -> dict[str, Any]:
        """What a checkpoint holds of the rows: the normals the last level's multipliers acted through."""
        return {"normals": np.array(self.contact.normals, copy=True)}

    def resume(self, data: dict[str, Any]) -> np.ndarray:
        """Put back :meth:`saved` (a resumed run, before its first step); the rows it changed."""
        c = self.contact
        new = np.asarray(data.get("normals"), dtype=float)
        if new.shape != c.normals.shape:
            raise InputError(f"checkpoint: the contact normals have shape {new.shape}, expected {c.normals.shape}")
        if not np.all(np.isfinite(new)):
            raise InputError("checkpoint: the contact normals hold non-finite values")
        if not np.allclose(np.linalg.norm(new, axis=1), 1.0, rtol=0.0, atol=1e-9):
            raise InputError("checkpoint: the contact normals are not unit vectors")
        rows = np.flatnonzero(np.any(new != c.normals, axis=1))
        self._set(rows, new[rows])
        return rows

    def _set(self, rows: np.ndarray, normals: np.ndarray) -> None:
        if rows.size:
            self.contact.normals[rows] = normals
            self.contact.rebuild_rows(self.n_dofs)
            self.rows.rebuilt()


class CurrentPairRows:
    """Contact pairs' rows in the current configuration (finite strain: large sliding).

    At every Newton iterate U each slave node is projected on its pair's deformed master surface
    (:class:`~signorini.contact.pairs.CurrentPairing`): the closest facet, its shape functions N_j at the
    projection p and its current outward normal n_m there give the row and the bound

        -n_m . (u_s - sum_j N_j u_j) <= (x_s - p) . n_m - n_m . (u_s^k - sum_j N_j u_j^k)

    (the current normal gap linearized at U^k with n_m and N frozen): a slave node may travel across any
    number of facets.  The same interface as :class:`CurrentRows` (the rows a level acted through kept,
    put back and saved).  Frictionless; a rigid obstacle beside the pairs: :class:`CurrentRowsAndPairs`.
    """

    #: the contact set's arrays of a pair row's pairing
    ARRAYS = ("normals", "master_facet", "master_shape", "master_dofs")

    def __init__(self, rows: ContactRows):
        from ...contact.pairs import CurrentPairing

        self.rows = rows
        disc = rows.disc
        self.contact, self.space = disc.contact, disc.space
        self.n_dofs = disc.space.n_dofs
        pairs = disc.problem.pairs
        self.pairings = [CurrentPairing(disc.problem.mesh, p) for p in pairs]
        self.pair_rows = [np.flatnonzero(self.contact.pair == k) for k in range(len(pairs))]
        #: the gap of a row beyond the master surface's rim (one number for the run: the bound it gives is the
        #: same at every iterate) [length]
        X = disc.problem.mesh.points
        self.far = OFF_RIM * (float(np.abs(X).max(initial=0.0)) + float(np.ptp(X, axis=0).max(initial=0.0)) or 1.0)
        self._last: tuple[np.ndarray, np.ndarray, list] | None = None
        #: (nc,) whether each row faces something at the last :meth:`follow` (the rigid obstacle's rows do)
        self.facing = np.ones(self.contact.size, dtype=bool)
        #: (nc,) per step: how often a row's facing changed between iterates, and the rows that face their
        #: facet's line for the rest of the step (:data:`RIM_FLIPS`)
        self._flips = np.zeros(self.contact.size, dtype=np.int64)
        self._sticky = np.zeros(self.contact.size, dtype=bool)
        #: whether the next :meth:`follow` is a step's first (its facing the baseline the flips count from)
        self._first = True

    def _dofs(self, nodes: np.ndarray) -> np.ndarray:
        """The dofs (m, k, d) of nodes (m, k)."""
        return self.space.dofs(nodes.ravel()).reshape(*nodes.shape, -1)

    def _project(self, U: np.ndarray) -> list:
        """Each pair's rows and their projections at U, the rows' facets so far kept where they still hold.  The
        last one is reused for the same U and facets: a Newton iteration asks it three times (the convergence
        test's gaps and round-off scale, then the next iteration's rows)."""
        c = self.contact
        last = self._last
        if last is not None and np.array_equal(last[0], U) and np.array_equal(last[1], c.master_facet):
            return last[2]
        out = [
            (r, f(c.nodes[r], U, c.master_facet[r]))
            for r, f in zip(self.pair_rows, self.pairings, strict=True)
            if r.size
        ]
        self._last = (np.array(U, copy=True), c.master_facet.copy(), out)
        return out

    def follow(self, U: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
        """The rows at the iterate U: (bound (nc,), the rows that changed)."""
        c = self.contact
        new = {k: np.array(getattr(c, k), copy=True) for k in self.ARRAYS}
        gaps = np.zeros(c.size)
        for r, proj in self._project(U):
            new["normals"][r] = -proj.normals
            new["master_facet"][r] = proj.facet
            new["master_shape"][r] = proj.xi
            new["master_dofs"][r] = self._dofs(proj.facet_nodes)
            facing = proj.facing | self._sticky[r]
            if not self._first:  # the flips of this step's iterates only: a step depends on its level alone
                self._flips[r] += facing != self.facing[r]
            self._sticky[r] |= self._flips[r] >= RIM_FLIPS
            self.facing[r] = facing = proj.facing | self._sticky[r]
            gaps[r] = np.where(facing, proj.gaps, self.far)  # beyond the rim: never active
        self._first = False
        changed = self._set(new)
        return gaps + c.B @ U, changed

    def contact_force(self, U: np.ndarray, t: float, lam: np.ndarray) -> np.ndarray:
        """B(U)^T lambda (n,) on the pair rows: the force of the multipliers through the rows of the iterate U
        itself (each slave node's projection on the deformed master surface at U) [force]."""
        c = self.contact
        out = np.zeros(self.n_dofs)
        for r, proj in self._project(U):
            f = lam[r, None] * -proj.normals  # (m, d) on the slave node; -N_j of it on the master node j
            out[c.dofs[r]] += f
            np.add.at(out, self._dofs(proj.facet_nodes), -proj.xi[:, :, None] * f[:, None, :])
        return out

    def geometric_stiffness(self, U: np.ndarray, t: float, lam: np.ndarray) -> sp.csr_matrix | None:
        """sum_i lambda_i d^2 g_i / dU^2 (n, n) over the pressed pair rows at U: the derivative of the contact
        force's direction (the master facet's normal and the projection's shape functions move with the
        nodes), which the rows frozen at an iterate leave out of Newton's tangent (None: no row pressed).

        g_i(x_s, x_1..x_k) = (x_s - p) . n_m is the normal gap of row i on its facet, whose gradient is the
        row (n_m, -N_1 n_m, ..., -N_k n_m) at the closest point; its Hessian (the row's (1 + k) d local
        coordinates) is taken by central differences of that gradient (step 1e-6 of the facet's size:
        the rows' projection and normal computed again), symmetrized."""
        c, d = self.contact, self.space.dim
        pressed = np.flatnonzero(lam < 0)
        if not pressed.size:
            return None
        blocks, dofs, weights = [], [], []
        for k, r in enumerate(self.pair_rows):
            r = np.intersect1d(r, pressed)
            if not r.size:
                continue
            pairing = self.pairings[k]
            Xall = pairing.mesh.points + np.asarray(U).reshape(-1, d)
            facet = c.master_facet[r]
            local = np.concatenate([Xall[c.nodes[r]][:, None, :], Xall[pairing.oriented[facet]]], axis=1)
            m, nloc = local.shape[0], local.shape[1] * d
            h = 1e-6 * np.linalg.norm(np.ptp(local[:, 1:], axis=1), axis=1)[:, None]  # (m, 1)
            H = np.zeros((m, nloc, nloc))
            flat = local.reshape(m, nloc)
            for a in range(nloc):
                plus, minus = flat.copy(), flat.copy()
                plus[:, a] += h[:, 0]
                minus[:, a] -= h[:, 0]
                H[:, :, a] = (
                    pairing.gap_gradient(plus.reshape(local.shape), facet)
                    - pairing.gap_gradient(minus.reshape(local.shape), facet)
                ) / (2.0 * h)
            blocks.append(0.5 * (H + H.transpose(0, 2, 1)))
            dofs.append(self._dofs(np.concatenate([c.nodes[r][:, None], pairing.oriented[facet]], axis=1)))
            weights.append(lam[r])
        if not blocks:
            return None
        return _blocks_matrix(
            np.concatenate(blocks) * np.concatenate(weights)[:, None, None], np.concatenate(dofs), self.n_dofs
        )

    def distance_scale(self, U: np.ndarray, t: float) -> float:
        """The largest coordinate of the slave and master nodes at U (the gaps' round-off scale) [length]."""
        return max((proj.scale for _, proj in self._project(U)), default=0.0)

    def gaps(self, U: np.ndarray, t: float, outside: float | None = None) -> np.ndarray:
        """The current normal gaps (x_s - p) . n_m (nc,) at U [length]; a node beyond the master surface's rim
        (facing nothing) gets ``outside``, by default the bound :meth:`follow` gives it, so that it never counts
        as unsettled (the levels' outputs give it +inf: no gap)."""
        out = np.zeros(self.contact.size)
        for r, proj in self._project(U):
            out[r] = np.where(proj.facing | self._sticky[r], proj.gaps, self.far if outside is None else outside)
        return out

    def keep_level(self, t: float) -> None:
        """As :meth:`CurrentRows.keep_level`; this step's flips at the rim start from none."""
        self._flips[:] = 0
        self._sticky[:] = False
        self._first = True
        self.rows.keep_level(t)

    def saved(self) -> dict[str, Any]:
        """The pairing the last level's multipliers acted through (a checkpoint's)."""
        return {k: np.array(getattr(self.contact, k), copy=True) for k in self.ARRAYS}

    def resume(self, data: dict[str, Any]) -> np.ndarray:
        """Put back :meth:`saved` (a resumed run, before its first step); the rows it changed."""
        c = self.contact
        new = {}
        for k in self.ARRAYS:
            a = np.asarray(data.get(k))
            old = getattr(c, k)
            if a.shape != old.shape:
                raise InputError(f"checkpoint: the pairing field {k!r} has shape {a.shape}, expected {old.shape}")
            if a.dtype.kind not in "biuf" or (a.dtype.kind == "f" and not np.all(np.isfinite(a))):
                raise InputError(f"checkpoint: the pairing field {k!r} holds non-finite or non-numeric values")
            new[k] = a.astype(old.dtype, copy=True)
        return self._set(new)

    def _set(self, new: dict[str, np.ndarray]) -> np.ndarray:
        c = self.contact
        changed = np.zeros(c.size, dtype=bool)
        for k in self.ARRAYS:
            changed |= (np.asarray(new[k]) != getattr(c, k)).reshape(c.size, -1).any(axis=1)
        rows = np.flatnonzero(changed)
        if rows.size:
            for k in self.ARRAYS:
                getattr(c, k)[...] = new[k]
            c.rebuild_rows(self.n_dofs)
            self.rows.rebuilt()
        return rows


def _blocks_matrix(H: np.ndarray, dofs: np.ndarray, n: int) -> sp.csr_matrix:
    """The (n, n) sum of the dense blocks H (m, k, k) on the dofs (m, k) of each (duplicates summed)."""
    dofs = dofs.reshape(dofs.shape[0], -1)
    k = dofs.shape[1]
    rows = np.repeat(dofs, k, axis=1).ravel()
    cols = np.tile(dofs, (1, k)).ravel()
    return sp.csr_matrix((H.reshape(-1), (rows, cols)), shape=(n, n))


def current_rows(rows: ContactRows) -> CurrentRows | CurrentPairRows | CurrentRowsAndPairs | None:
    """The run's rows of the current configuration: :class:`CurrentPairRows` with contact pairs (with a rigid
    obstacle beside them, :class:`CurrentRowsAndPairs`), :class:`CurrentRows` when its rigid obstacle gives its
    normals at any point (plane, sphere), else None (no obstacle rows, or an obstacle refused with finite
    strain)."""
    disc = rows.disc
    if disc.space.dim == 1:  # refused with finite strain (check_finite_strain)
        return None
    ob = disc.problem.obstacle
    c = disc.contact
    obstacle_rows = np.flatnonzero(c.pair < 0) if c.has_pair_rows else np.arange(c.size)
    follows = ob is not None and obstacle_rows.size and ob.body_normals(c.points[obstacle_rows[:1]], 0.0) is not None
    if disc.problem.pairs and c.has_pair_rows:
        return CurrentRowsAndPairs(rows, obstacle_rows) if follows else CurrentPairRows(rows)
    return CurrentRows(rows) if follows else None


class CurrentRowsAndPairs:
    """A rigid obstacle's rows and contact pairs' rows in the current configuration together (two bodies
    that meet each other and a floor): each part moves its own rows (:class:`CurrentRows` the obstacle's,
    :class:`CurrentPairRows` the pairs'), in that order, and their bounds, gaps and changed rows are joined.
    What a checkpoint holds is the pairs' part (its arrays cover every row's normal)."""

    def __init__(self, rows: ContactRows, obstacle_rows: np.ndarray):
        self.obstacle = CurrentRows(rows, obstacle_rows)
        self.pairs = CurrentPairRows(rows)
        self.own = self.obstacle.own
        self.facing = self.pairs.facing  # the obstacle's rows: True

    def follow(self, U: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
        b_obstacle, moved = self.obstacle.follow(U, t)
        bound, changed = self.pairs.follow(U, t)
        bound[self.own] = b_obstacle[self.own]
        return bound, np.union1d(moved, changed)

    def distance_scale(self, U: np.ndarray, t: float) -> float:
        return max(self.obstacle.distance_scale(U, t), self.pairs.distance_scale(U, t))

    def contact_force(self, U: np.ndarray, t: float, lam: np.ndarray) -> np.ndarray:
        return self.obstacle.contact_force(U, t, lam) + self.pairs.contact_force(U, t, lam)

    def geometric_stiffness(self, U: np.ndarray, t: float, lam: np.ndarray) -> sp.csr_matrix | None:
        parts = [
            K
            for K in (self.obstacle.geometric_stiffness(U, t, lam), self.pairs.geometric_stiffness(U, t, lam))
            if K is not None
        ]
        return None if not parts else (parts[0] if len(parts) == 1 else (parts[0] + parts[1]).tocsr())

    def gaps(self, U: np.ndarray, t: float, outside: float | None = None) -> np.ndarray:
        out = self.pairs.gaps(U, t, outside)
        out[self.own] = self.obstacle.gaps(U, t)[self.own]
        return out

    def keep_level(self, t: float) -> None:
        self.obstacle.keep_level(t)
        self.pairs.keep_level(t)

    def saved(self) -> dict[str, Any]:
        return self.pairs.saved()

    def resume(self, data: dict[str, Any]) -> np.ndarray:
        return self.pairs.resume(data)


class FixedBound:
    """The bound of a step whose rows do not move (linear rows in the reference configuration): the gaps g(t).
    The same calls as :class:`FollowingBound` (Newton's one bound type): called with an iterate it returns the
    gaps, its law is the step's, the contact force is B^T lambda + T^T lambda_t through the rows of the solve,
    no geometric stiffness, the gaps always settled."""

    #: whether the rows move with the iterate (Newton then also waits for their gaps to settle)
    moves = False

    def __init__(self, ctx: Context, gaps: np.ndarray) -> None:
        self.ctx, self.gaps = ctx, gaps

    def __call__(self, U: np.ndarray) -> np.ndarray:
        return self.gaps

    def law(self, law: ContactLaw) -> ContactLaw:
        return law

    def contact_force(self, U: np.ndarray, lam: np.ndarray, lam_t: np.ndarray | None) -> np.ndarray:
        return self.ctx.rows.contact_force(lam, lam_t)

    def geometric_stiffness(self, U: np.ndarray, lam: np.ndarray) -> None:
        return None

    def converged(self, U: np.ndarray) -> bool:
        return True


class FollowingBound:
    """The bound of a step's rows in the current configuration at time t (:func:`contact_bound`): called with a
    Newton iterate U, it moves the rows to U and returns their bound; :meth:`gap_error` is how far the last
    rows' linearized gaps are from the true ones at a new iterate."""

    moves = True

    def __init__(self, ctx: Context, t: float, U0: np.ndarray | None = None, t0: float | None = None):
        self.ctx, self.t = ctx, t
        #: the level the step starts from (the slip of the step is measured from it)
        self.U0, self.t0 = U0, t0
        self.bound: np.ndarray | None = None

    def law(self, law: ContactLaw) -> ContactLaw:
        """``law`` with its slip reference c_t = T U^n + (the obstacle's tangential motion) in the frames of the
        rows now (they turn with the iterate: a sphere's normal at x, a pair's master facet), so that the slip of
        the step is v_t = T (U - U^n) - (obstacle motion) in one frame, the motion of a rotating obstacle taken at
        the points the nodes are at in U^n (large sliding); frictionless: ``law`` itself."""
        if law.reference is not None and self.U0 is not None:
            law = replace(law, reference=self.ctx.rows.friction_law(self.U0, self.t0, self.t).reference)
        facing = self.ctx.rows.current.facing
        if facing is not None and not facing.all():  # a pair's row beyond the rim: no constraint, lambda = 0
            law = replace(law, subset=facing.copy() if law.subset is None else law.subset & facing)
        return law

    def __call__(self, U: np.ndarray) -> np.ndarray:
        bound, changed = self.ctx.rows.current.follow(U, self.t)
        self.ctx.replace_rows(changed)
        self.bound = bound
        return bound

    def contact_force(self, U: np.ndarray, lam: np.ndarray, lam_t: np.ndarray | None) -> np.ndarray:
        """B(U)^T lambda + T^T lambda_t (n,): the multipliers' force through the rows of the iterate U itself
        (Newton's residual there; friction runs only against a plane that does not turn, whose T is fixed)."""
        f = self.ctx.rows.current.contact_force(U, self.t, lam)
        T = self.ctx.rows.T
        if lam_t is not None and T is not None:
            f = f + T.T @ lam_t.ravel()
        return f

    def geometric_stiffness(self, U: np.ndarray, lam: np.ndarray) -> sp.csr_matrix | None:
        """sum_i lambda_i d^2 g_i / dU^2 at U (the rows' own turning; None: none)."""
        return self.ctx.rows.current.geometric_stiffness(U, self.t, lam)

    def gap_error(self, U: np.ndarray) -> float:
        """max_i |phi_t(x_i) - (bound_i - nu_i . u_i)| at U [length]: the linearization's error of the gaps.  A
        pair's row beyond the master's rim both at the rows' iterate and at U is settled (it is out of the solve;
        its far bound's round-off, 1e-10 of 1e6 bodies, is not a gap); one that crossed the rim is not."""
        if self.bound is None or not self.bound.size:
            return 0.0
        current = self.ctx.rows.current
        g = current.gaps(U, self.t, outside=np.nan)  # nan beyond the rim at U
        err = np.abs(g - (self.bound - self.ctx.rows.B @ U))
        if current.facing is not None:
            now = ~np.isnan(g)
            err[current.facing != now] = np.inf  # crossed the rim between the rows' iterate and U
            err[~current.facing & ~now] = 0.0  # beyond it at both: out of the solve
        return float(np.max(err))

    def converged(self, U: np.ndarray) -> bool:
        """Whether the last rows' linearized gaps are the true ones at U: to :data:`GAP_TOLERANCE` touch
        tolerances (1e-10 of the body), or to the round-off of the obstacle's distance there (a ball of a
        large radius: one ulp of |x - c|)."""
        floor = ROUNDOFF * self.ctx.rows.current.distance_scale(U, self.t)
        return self.gap_error(U) <= max(GAP_TOLERANCE * self.ctx.touch_tolerance, floor)


def contact_bound(ctx: Context, U0: np.ndarray, t0: float, t: float) -> FixedBound | FollowingBound:
    """What a finite-strain step from (U0, t0) to t constrains ``B U`` by: the gaps g(t) (:class:`FixedBound`), or
    with rows in the current configuration a :class:`FollowingBound` (the level's rows kept first,
    :meth:`CurrentRows.keep_level`)."""
    current = ctx.rows.current
    if current is None:
        return FixedBound(ctx, ctx.gaps(t))
    current.keep_level(t0)
    return FollowingBound(ctx, t, U0, t0)


def level_gaps(ctx: Context, U: np.ndarray, t: float) -> np.ndarray:
    """The gaps (nc,) of a level: g(t) - B U, or phi_t(X + U) in the current configuration [length]; a pair's
    slave node beyond the master surface's rim (facing nothing) has none: +inf."""
    if ctx.rows.current is not None:
        return ctx.rows.current.gaps(U, t, outside=np.inf)
    return ctx.gaps(t) - ctx.rows.B @ U

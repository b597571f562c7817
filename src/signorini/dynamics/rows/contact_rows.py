"""The contact rows of a run: their only owner.

A run's contact rows are B (nc, n), one row nu_i^T per contact node (the rigid obstacle's rows,
then the contact pairs': :class:`~signorini.contact.contact_set.ContactSet`), and with friction
the nodal frames' rows T (nc (d - 1), n) and H (nc d, n).  :class:`ContactRows` holds them with
their blocks on the free and the fixed dofs (what the condensed solves use), the friction data
of each row, and what small sliding changes: :meth:`ContactRows.slide` re-pairs the slave nodes
that left their master facet and returns the rows it changed (the
:class:`~signorini.dynamics.solve.context.Context` then tells every factorized system), keeping the
rows the last level's multipliers acted through (:meth:`ContactRows.rows_of`) and what a
checkpoint must hold of the pairing (:meth:`ContactRows.pairing_state`).

The schemes read the rows as the Context's ``rows`` (``ctx.rows.B``, ``ctx.rows.T``,
``ctx.rows.friction_law(...)``, ``ctx.rows.contact_force(...)``).
"""

from __future__ import annotations

import functools
from dataclasses import replace
from typing import Any

import numpy as np
import scipy.sparse as sp

from ...contact.solver import SIGNORINI, ContactLaw
from ...errors import InputError
from ..model.problem import Discretization


class ContactRows:
    """B, T, H and their free/fixed blocks, the rows' friction and the pairing of one run.

    Parameters
    ----------
    disc : the discretization (its ``contact`` set builds the rows and changes them on a slide).
    solver_options : the run's solver options (``pairing``: small-sliding, the default, or frozen).
    """

    #: the contact set's arrays that small sliding changes (:meth:`ContactSet.slide`)
    PAIRING_ARRAYS = ("normals", "gaps", "master_facet", "master_shape", "master_dofs")

    def __init__(self, disc: Discretization, solver_options: dict[str, Any]):
        self.disc = disc
        self.solver_options = solver_options
        self.free, self.fixed = disc.free, disc.fixed
        self.has_fixed = self.fixed.size > 0
        self._blocks(disc.B)
        #: the contact law; with friction, T (nc (d - 1), n) the tangential rows of the nodal
        #: frames and H (nc d, n) all of them, node-major (:meth:`ContactSet.frame_matrix`; a
        #: contact pair's rows: the slave node relative to the master point it faces)
        self.friction = disc.friction
        self.components = self.friction.components(disc.space.dim)
        self.T = self.H = self.Hf = self.HD = None
        #: the coefficient (Coulomb) or threshold (Tresca) of each contact row (nc,): the run's
        #: law's, or a contact pair's own (:func:`~signorini.dynamics.model.problem.row_friction`)
        self.friction_rows: np.ndarray | None = None
        if self.components > 1:
            self.friction_rows = disc.friction_rows
            self._frame_rows()
        #: contact pair rows re-paired by small sliding over the run
        self.repaired = 0
        self._level_rows: tuple | None = None

    def _blocks(self, B: sp.csr_matrix) -> None:
        """B and its free and fixed blocks (BD None when no row touches a fixed dof)."""
        self.B = B
        self.Bf = B[:, self.free].tocsr() if self.has_fixed else B
        BD = B[:, self.fixed].tocsr() if self.has_fixed else None
        self.BD = BD if BD is not None and BD.nnz else None

    @property
    def solve_rows(self) -> sp.csr_matrix:
        """The rows of the condensed solve on the free dofs: the frames' H_f with friction, else B_f."""
        return self.Hf if self.components > 1 else self.Bf

    def friction_law(self, U: np.ndarray, t0: float, t1: float, base: ContactLaw = SIGNORINI) -> ContactLaw:
        """``base`` with the run's friction for a position-level step t0 -> t1 from U = U^n:
        the slip of the step is v_t = T U^{n+1} - c_t with c_t = T U^n + T (obstacle
        translation), the tangential part of U^{n+1} - U^n relative to the obstacle, in the frames of
        the rows now.  With rows of the current configuration (:attr:`current`: finite strain, large
        sliding) a rotating obstacle's motion is taken at the points the nodes are at in U^n, not at
        those they faced at t = 0.  ``base`` itself when the run is frictionless."""
        if self.components == 1:
            return base
        c = self.disc.contact
        at = c.points + np.asarray(U)[c.dofs] if self.current is not None else None
        ref = (self.T @ U).reshape(c.size, -1) + c.obstacle_slip(t0, t1, at)
        return replace(
            base, friction=self.friction, reference=ref, radius=self._radius(), coefficient=self._coefficients()
        )

    def friction_rate_law(self, t0: float, t1: float, base: ContactLaw = SIGNORINI) -> ContactLaw:
        """``base`` with the run's friction for a velocity-level step: the slip rate is
        v_t = T V^{n+1} - c_t with c_t the obstacle's tangential velocity over the step.
        The multipliers are impulses: the Tresca bound of a step is (t1 - t0) s w_i."""
        if self.components == 1:
            return base
        ref = self.disc.contact.obstacle_slip(t0, t1) / (t1 - t0)
        radius = self._radius()
        radius = None if radius is None else (t1 - t0) * radius
        return replace(base, friction=self.friction, reference=ref, radius=radius, coefficient=self._coefficients())

    def _radius(self) -> np.ndarray | None:
        """Tresca thresholds s_i w_i (nc,) [force] (s_i: the row's threshold); None for Coulomb."""
        if self.friction.law != "tresca":
            return None
        if self._uniform:
            return self.friction.threshold * self.disc.contact.weights
        return self.friction_rows * self.disc.contact.weights

    def _coefficients(self) -> np.ndarray | None:
        """Coulomb coefficients mu_i (nc,) when the rows' differ (contact pairs with their own
        laws); None: the run's ``friction.coefficient`` on every row."""
        if self.friction.law != "coulomb" or self._uniform:
            return None
        return self.friction_rows

    @functools.cached_property
    def _uniform(self) -> bool:
        """Every row has the run's law's coefficient or threshold (always without pairs)."""
        value = self.friction.coefficient if self.friction.law == "coulomb" else self.friction.threshold
        return self.friction_rows is None or bool(np.all(self.friction_rows == value))

    @functools.cached_property
    def sliding(self) -> bool:
        """Whether contact pairs are re-paired as their slave nodes slide (solver option
        ``pairing``: small-sliding, the default, or frozen)."""
        if not self.disc.problem.pairs or self.disc.space.dim == 1:
            return False
        return self.solver_options.get("pairing", "small-sliding") == "small-sliding"

    def _frame_rows(self) -> None:
        """T, H and H's free and fixed blocks from the contact set's frames (friction)."""
        n = self.disc.space.n_dofs
        self.T = self.disc.contact.tangential_matrix(n)
        self.H = self.disc.contact.frame_matrix(n)
        self.Hf = self.H[:, self.free].tocsr() if self.has_fixed else self.H
        HD = self.H[:, self.fixed].tocsr() if self.has_fixed else None
        self.HD = HD if HD is not None and HD.nnz else None

    def slide(self, U: np.ndarray, t: float) -> np.ndarray:
        """Small sliding after a level (:meth:`ContactSet.slide`): the pair rows whose slave node
        left its master facet in X + U are re-paired; B, its free and fixed blocks and the
        friction frames follow.  Returns the rows re-paired (counted in ``pair_rows_repaired``),
        whose solvers' rows the caller replaces (:meth:`Context.slide`)."""
        if not self.sliding or self.current is not None:  # (finite strain: the pairs follow in every iteration)
            return np.zeros(0, dtype=np.int64)
        disc = self.disc
        B_before, T_before = self.B, self.T
        rows = disc.contact.slide(disc.space, disc.problem.pairs, U)
        if rows.size == 0:
            return rows
        # the multipliers of the level just computed acted through the rows of before (in the
        # next step's balance and energy identity: :meth:`rows_of`)
        self._level_rows = (t, B_before, T_before)
        self._use_rows(rows)
        return rows

    def _use_rows(self, rows: np.ndarray) -> None:
        """B, its blocks and the frames after the contact set changed ``rows``."""
        self.rebuilt()
        self.repaired += int(rows.size)

    def rebuilt(self) -> None:
        """B's blocks and the frames again after the contact set rebuilt its rows."""
        disc = self.disc
        self._blocks(disc.B)
        if self.components > 1:
            self._frame_rows()

    #: finite strain against a rigid obstacle: the rows of the current configuration
    #: (:class:`~signorini.dynamics.rows.current_rows.CurrentRows`), None otherwise
    current: Any = None

    def keep_level(self, t: float) -> None:
        """The rows now are those the multipliers of the level at t acted through (:meth:`rows_of`), kept
        before a step changes them (the current configuration's rows)."""
        self._level_rows = (t, self.B, self.T)

    def pairing_state(self, t: float) -> dict[str, Any]:
        """The pairing after small sliding, for a checkpoint at time t: the contact set's
        changed arrays, the rows the level at t acted through (when a re-pairing followed it)
        and the counts of re-paired rows.  Empty without sliding pairs.  In the current configuration
        (finite strain against a rigid obstacle) the rows' normals: those the level's multipliers acted
        through."""
        if self.current is not None:
            return self.current.saved()
        if not self.sliding:
            return {}
        c = self.disc.contact
        out: dict[str, Any] = {k: np.array(getattr(c, k), copy=True) for k in self.PAIRING_ARRAYS}
        out["repaired"] = int(self.repaired)
        out["pair_repaired"] = [int(p["repaired_rows"]) for p in (c.pair_info or [])]
        if self._level_rows is not None and self._level_rows[0] == t:
            for name, M in (("level_B", self._level_rows[1]), ("level_T", self._level_rows[2])):
                if M is not None:
                    M = M.tocsr()
                    out.update({f"{name}_data": M.data, f"{name}_indices": M.indices, f"{name}_indptr": M.indptr})
        return out

    def restore_pairing(self, data: dict[str, Any], t: float) -> np.ndarray:
        """Put back the pairing of :meth:`pairing_state` (a resumed run, before its first step);
        the rows it changed, whose solvers' rows the caller replaces."""
        if self.current is not None and data:
            return self.current.resume(data)
        if not self.sliding or not data:
            return np.zeros(0, dtype=np.int64)
        c, n = self.disc.contact, self.disc.space.n_dofs
        changed = np.zeros(c.size, dtype=bool)
        for k in self.PAIRING_ARRAYS:
            new, old = np.asarray(data[k]), np.asarray(getattr(c, k))
            if new.shape != old.shape:
                raise InputError(f"checkpoint: pairing field {k!r} has shape {new.shape}, expected {old.shape}")
            changed |= (new != old).reshape(c.size, -1).any(axis=1)
            getattr(c, k)[...] = new
        rows = np.flatnonzero(changed)
        if rows.size:
            c.rebuild_rows(n)
            self._use_rows(rows)
        self.repaired = int(data["repaired"])
        for p, r in zip(c.pair_info or [], data["pair_repaired"], strict=False):
            p["repaired_rows"] = int(r)
        level = []
        for name in ("level_B", "level_T"):
            if f"{name}_data" in data:
                shape = (c.size * (1 if name == "level_B" else self.components - 1), n)
                level.append(
                    sp.csr_matrix((data[f"{name}_data"], data[f"{name}_indices"], data[f"{name}_indptr"]), shape=shape)
                )
            else:
                level.append(None)
        if level[0] is not None:
            self._level_rows = (t, level[0], level[1])
        return rows

    def rows_of(self, t: float) -> tuple[Any, Any]:
        """(B, T): the contact rows the multipliers of the level at time t act through: the
        current ones, or those before a re-pairing (:meth:`slide`) that followed that level."""
        if self._level_rows is not None and self._level_rows[0] == t:
            return self._level_rows[1], self._level_rows[2]
        return self.B, self.T

    def contact_on_fixed(
        self, lam: np.ndarray, lam_t: np.ndarray | None = None, t: float | None = None
    ) -> np.ndarray | float:
        """(B^T lambda + T^T lambda_t) on the Dirichlet dofs (the contact part of their reactions),
        0.0 when no contact row touches a fixed dof; ``t``: the multipliers of that level
        (:meth:`rows_of`)."""
        if self.BD is None and self.HD is None and self._level_rows is None:
            return 0.0
        return self.contact_force(lam, lam_t, t)[self.fixed]

    def contact_force(self, lam: np.ndarray, lam_t: np.ndarray | None = None, t: float | None = None) -> np.ndarray:
        """B^T lambda + T^T lambda_t (n,): the contact forces on the dofs [force]; ``t``: the
        multipliers of that level, through its rows (:meth:`rows_of`)."""
        B, T = (self.B, self.T) if t is None else self.rows_of(t)
        f = B.T @ lam
        if lam_t is not None and T is not None:
            f = f + T.T @ lam_t.ravel()
        return f

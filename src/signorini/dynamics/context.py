"""What a time scheme's step may use: operators, data at time t, and the contact solver.

A :class:`Context` is built once per run by :func:`~signorini.dynamics.simulate.simulate`.
It holds the full-space matrices ``M``, ``S``, ``B``, gives the loads ``load(t)``, the
prescribed values ``dirichlet(t)`` and the gaps ``gaps(t)``, and solves, for an
operator K = c_M M + c_S S declared by the scheme,

    K x = rhs + B^T lambda  on the free rows,   x = x_D on the fixed dofs,
    B x <= bound,  lambda <= 0,  (B x - bound) . lambda = 0,

with :meth:`Context.solve` (``bound`` per call: positions or velocities, any
combination of levels).  Operators are factorized once: two operators that are
multiples of each other (e.g. Paoli-Schatzman's M/dt^2 + S/4 and Crank-Nicolson's
4 M/dt^2 + S) share one factorization, ``K' = s K`` being solved as
``K x = rhs/s + B^T (lambda'/s)``.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import scipy.sparse as sp

from ..contact.solver import SIGNORINI, ContactLaw, ContactSolver, StepInfo, make_contact_solver
from ..errors import InputError, NonFiniteError
from ..linalg.base import CG_FRIENDLY_RATIO
from ..linalg.row_block import RowBlock, node_row_bounds, row_bounds
from ..linalg.sparse import linear_combination, principal_combination, principal_rows
from ..linalg.spmv import sparse_product
from ..parallel import DISTRIBUTED_BACKENDS, run_comm
from .factorizations import Factorizations
from .mass import massless_dofs
from .problem import Discretization

#: what a factorization raises for a singular or indefinite operator: SuperLU and MKL
#: Pardiso RuntimeError, numpy LinAlgError, CHOLMOD (cvxopt) ArithmeticError
FACTORIZATION_ERRORS = (RuntimeError, np.linalg.LinAlgError, ArithmeticError)


@dataclass(frozen=True)
class Operator:
    """The linear operator K = mass * M + stiffness * S of a scheme for a given dt."""

    mass: float
    stiffness: float

    def matrix(self, M: sp.spmatrix, S: sp.spmatrix) -> sp.csr_matrix:
        return linear_combination(self.mass, M, self.stiffness, S)

    def ratio_to(self, other: Operator) -> float | None:
        """s with self = s * other, or None when they are not proportional."""
        for a, b in ((self.stiffness, other.stiffness), (self.mass, other.mass)):
            if b != 0.0:
                s = a / b
                break
        else:  # pragma: no cover - a zero operator is rejected earlier
            return None
        ok = np.isclose(self.mass, s * other.mass, rtol=1e-13, atol=0.0) and np.isclose(
            self.stiffness, s * other.stiffness, rtol=1e-13, atol=0.0
        )
        return float(s) if ok and s > 0 else None


def stiffness_to_mass_ratio(op: Operator, ctx: Context) -> float:
    """max over the free dofs with mass of c_S S_ii / (c_M M_ii) (inf without mass).

    How far K = c_M M + c_S S is from its mass part: about (omega_max dt)^2 / 4 for the
    highest frequency resolved by the mesh.  Small (<= 1) when dt is about the time a
    wave takes to cross the smallest cell, and then Jacobi-CG converges in a few tens of
    iterations.  Massless dofs (redistributed masses) are a few rows and are left out.
    """
    m = ctx.M.diagonal()[ctx.free]
    s = ctx.S.diagonal()[ctx.free]
    has_mass = m > 0
    if op.mass == 0 or not has_mass.any():
        return float("inf")
    return float(np.max(op.stiffness * s[has_mass] / (op.mass * m[has_mass])))


def _row_blocks(op: Operator, ctx: Context) -> tuple[RowBlock, RowBlock]:
    """This rank's rows of K_ff and K_fD (the free rows in blocks of whole nodes, so that a
    contact node's rows and its projection stay on one rank)."""
    f, D = ctx.free, ctx.fixed
    if isinstance(ctx.M, RowBlock):  # M and S by rows: the free rows among this rank's own
        bounds = np.searchsorted(f, ctx.M.bounds).astype(np.int64)
        rows = f[bounds[ctx.comm.rank] : bounds[ctx.comm.rank + 1]]
        M, S, rows = ctx.M.local, ctx.S.local, rows - ctx.M.lo
    else:
        bounds = node_row_bounds(ctx.disc.space.dofmap.nodes_of(f), ctx.comm.size)
        rows = f[bounds[ctx.comm.rank] : bounds[ctx.comm.rank + 1]]
        M, S = ctx.M, ctx.S
    Kf, KD = principal_rows(op.mass, M, op.stiffness, S, f, D, rows)
    return RowBlock(Kf, bounds, ctx.comm), RowBlock(KD, bounds, ctx.comm)


class _System:
    """A factorized operator restricted to the free dofs, with its lifting block."""

    def __init__(self, op: Operator, ctx: Context, options: dict[str, Any]):
        f, D = ctx.free, ctx.fixed
        if ctx.sliding:  # the Schur complement is of the contact dofs of t = 0: lazy or full columns follow
            if options.get("condensation") == "schur":
                raise InputError("solver option condensation='schur' cannot follow contact pairs as they slide; "
                                 "use condensation='lazy' or 'full', or pairing='frozen'")  # fmt: skip
            options = {**options, "condensation": "lazy" if options.get("condensation", "auto") == "auto" else
                       options["condensation"]}  # fmt: skip
        # only the free block and its coupling to the fixed dofs are formed; on the ranks of
        # a distributed backend, only this rank's block of their rows (no rank holds all of K)
        if ctx.distributed:
            Kff, KfD = _row_blocks(op, ctx)
            local = (Kff.local, KfD.local)
            self.KfD = KfD if D.size else None
        elif D.size:
            Kff, self.KfD = principal_combination(op.mass, ctx.M, op.stiffness, ctx.S, f, D)
            local = (Kff, self.KfD)
        else:
            Kff, self.KfD = op.matrix(ctx.M, ctx.S), None
            local = (Kff,)
        if ctx.comm.any(not all(np.all(np.isfinite(A.data)) for A in local)):
            raise NonFiniteError(
                f"the operator {op} has non-finite entries (material, mesh or dt at the limits of double precision)"
            )
        self.op = op
        gap_scale = float(np.max(np.abs(ctx.disc.contact.gaps))) if ctx.disc.contact.size else 0.0
        try:
            dim = ctx.disc.space.dim
            nodes = ctx.disc.space.dofmap.nodes_of(f if D.size else np.arange(Kff.shape[0]))
            cg_friendly = ctx.iterative_ok and stiffness_to_mass_ratio(op, ctx) <= CG_FRIENDLY_RATIO
            B = ctx.Hf if ctx.components > 1 else ctx.Bf  # with friction: the nodal frames' rows
            free = f if D.size else np.arange(Kff.shape[0])
            self.solver: ContactSolver = make_contact_solver(
                Kff, B, gap_scale, dim, options, nodes, cg_friendly, ctx.components,
                lambda: ctx.disc.space.rigid_body_modes(free),
            )  # fmt: skip
        except FACTORIZATION_ERRORS as exc:  # a singular or indefinite operator; anything else is a bug
            raise InputError(
                f"the operator {op} on the free dofs cannot be factorized ({type(exc).__name__}: {exc}): it is "
                "singular or not positive definite.  Likely cause: rigid-body motions held neither by Dirichlet "
                "conditions nor by mass (a redistributed mass such as 'seed' on a mesh one cell thick has no mass "
                "left; add a Dirichlet condition or use the 'standard' mass), or material, mesh or dt values at "
                "the limits of double precision"
            ) from exc
        self._lift_key: np.ndarray | None = None
        self._lift = None
        self._lift_source: np.ndarray | None = None

    def lift(self, xD: np.ndarray) -> np.ndarray | float:
        """K_fD x_D (cached while x_D does not change)."""
        if self.KfD is None:
            return 0.0
        if xD is self._lift_source:  # the same (constant) array as last time
            return self._lift
        if self._lift_key is None or not np.array_equal(self._lift_key, xD):
            self._lift_key = np.array(xD, copy=True)
            self._lift = self.KfD @ xD
        self._lift_source = xD
        return self._lift


#: relative size of a gap that is contact (:attr:`Context.touch_tolerance`): 1e4 times the
#: round-off of a coordinate, 1e-12 of the body
TOUCH = 1e-12


class Context:
    """Operators, data of time t and the contact solver of one run (see module doc)."""

    def __init__(self, disc: Discretization, dt: float, solver_options: dict[str, Any] | None = None):
        self.disc = disc
        self.dt = float(dt)
        self.M, self.S, self.B = disc.M, disc.S, disc.B
        self.free, self.fixed = disc.free, disc.fixed
        self.solver_options = dict(solver_options or {})
        #: the ranks of the run (:mod:`signorini.parallel`): one process, or mpiexec's for ``petsc``
        self.comm = run_comm(self.solver_options.get("backend", "auto"))
        #: the operators of the contact solve and of the products are blocks of rows per rank
        #: (:class:`~signorini.linalg.row_block.RowBlock`): backends ``petsc`` and ``petsc-cg``
        self.distributed = self.solver_options.get("backend") in DISTRIBUTED_BACKENDS
        self.has_fixed = self.fixed.size > 0
        self.Bf = self.B[:, self.free].tocsr() if self.has_fixed else self.B
        BD = self.B[:, self.fixed].tocsr() if self.has_fixed else None
        self.BD = BD if BD is not None and BD.nnz else None
        #: the contact law; with friction, T (nc (d - 1), n) the tangential rows of the nodal
        #: frames and H (nc d, n) all of them, node-major (:meth:`ContactSet.frame_matrix`; a
        #: contact pair's rows: the slave node relative to the master point it faces)
        self.friction = disc.friction
        self.components = self.friction.components(disc.space.dim)
        self.T = self.H = self.Hf = self.HD = None
        #: the coefficient (Coulomb) or threshold (Tresca) of each contact row (nc,): the run's
        #: law's, or a contact pair's own (:func:`~signorini.dynamics.problem.row_friction`)
        self.friction_rows: np.ndarray | None = None
        if self.components > 1:
            self.friction_rows = disc.friction_rows
            self._frame_rows()
        #: whether the schemes of the run can use the CG contact solve (``auto`` may pick it;
        #: never with friction)
        self.iterative_ok = self.components == 1
        #: the factorized step operators, per step size (their only owner)
        self.factors = Factorizations(lambda op: _System(op, self, self.solver_options), self.dt)
        self.massless = massless_dofs(disc.M)
        #: Rayleigh damping C = alpha M + beta S (None: undamped), :mod:`~signorini.dynamics.damping`
        self.damping = disc.problem.damping
        #: the mass has massless directions that are not coordinate axes (``seed-normal`` on a
        #: tilted or curved contact): schemes that balance massless rows apart refuse it
        n = disc.contact.normals
        self.rotated_kernel = bool(
            disc.mass_name == "seed-normal"
            and n.size
            and not np.all(np.isclose(np.abs(n).max(axis=1), 1.0, atol=1e-12))
        )
        if self.massless.size == disc.M.shape[0]:
            raise InputError(
                f"mass {disc.mass_name!r} leaves the body without any mass (every cell touches the contact "
                "boundary): refine the mesh across the contact layer or use the 'standard' mass"
            )

    # -- products of a step's right-hand side and energy ------------------------------
    @functools.cached_property
    def Mop(self) -> Any:
        """``M @ x`` on all cores (large matrices; solver option ``spmv``)."""
        return self._product(self.M)

    @functools.cached_property
    def Sop(self) -> Any:
        """``S @ x`` on all cores (large matrices; solver option ``spmv``)."""
        return self._product(self.S)

    def _product(self, A: sp.spmatrix | RowBlock) -> Any:
        if isinstance(A, RowBlock):  # already by rows (a distributed backend)
            return A
        # general storage, A's own arrays: a symmetric copy (as CG's K) made bar3d n = 32's
        # steps 6% faster but its set-up 5 s longer and its peak 0.6 GB higher
        if self.comm.size > 1:  # each rank its block of rows (replicated vectors, no halo), views of A's
            return RowBlock.of(A, row_bounds(A.shape[0], self.comm.size), self.comm, copy=False)
        return sparse_product(A, self.solver_options.get("spmv", "auto"))

    # -- data of time t ------------------------------------------------------------
    #: the start of the current segment of the time grid (:mod:`~.time_grid`): levels at t0 + j dt
    t0 = 0.0

    def next_time(self, t: float) -> float:
        """t_{n+1} = t0 + (j + 1) dt for t = t_n = t0 + j dt (from j, without accumulated round-off)."""
        if self.t0 == 0.0:
            return (round(t / self.dt) + 1) * self.dt
        return self.t0 + (round((t - self.t0) / self.dt) + 1) * self.dt

    def change_dt(self, dt: float, t0: float, operators: list[Operator]) -> None:
        """Continue with the step ``dt`` from ``t0``: the factorizations of the old step are
        released (their counters kept) and ``operators`` (the scheme's for the new dt) are
        factorized (:meth:`Factorizations.replace`)."""
        self.dt, self.t0 = float(dt), float(t0)
        self.factors.replace(dt, operators)

    def use_step(self, dt: float, t0: float, operators: list[Operator], keep_bytes: float) -> None:
        """Continue with the step ``dt`` from ``t0`` keeping the factorizations of the steps used
        before (an adaptive control's ladder dt / 2^k, :mod:`~.step_control`;
        :meth:`Factorizations.use`)."""
        self.factors.use(dt, operators, keep_bytes)
        self.dt, self.t0 = float(dt), float(t0)

    def load(self, t: float) -> np.ndarray:
        """F(t) (n,), full space [force]."""
        return self.disc.load(t)

    def dirichlet(self, t: float) -> np.ndarray:
        """Prescribed displacements on the fixed dofs at time t."""
        return self.disc.dirichlet(t)

    def gaps(self, t: float) -> np.ndarray:
        """Gaps g(t) (nc,) of the obstacle at time t."""
        return self.disc.gaps(t)

    @functools.cached_property
    def touch_tolerance(self) -> float:
        """A gap within this of zero is contact [length]: :data:`TOUCH` times the largest of the
        body's size and its coordinates (round-off of a gap is ~1e-16 of those).  A decision
        taken on the sign of a gap (an index set) is taken against it, so that a node resting
        on the obstacle is in contact whatever the machine's round-off."""
        X = self.disc.problem.mesh.points
        return TOUCH * max(float(np.linalg.norm(np.ptp(X, axis=0))), float(np.max(np.abs(X), initial=0.0)), 1e-300)

    # -- linear algebra ------------------------------------------------------------
    def solve(
        self,
        op: Operator,
        rhs: np.ndarray,
        bound: np.ndarray,
        fixed_values: np.ndarray | None = None,
        law: ContactLaw = SIGNORINI,
        guess: np.ndarray | Callable[[], np.ndarray] | None = None,
    ) -> tuple[np.ndarray, np.ndarray, StepInfo]:
        """Solve ``K x = rhs + B^T lambda`` with contact ``B x <= bound``; x = fixed_values
        on the Dirichlet dofs.  Returns the full x (n,), lambda (nc,) and the step info.
        ``law`` restricts the constrained nodes or adds a compliance (:class:`ContactLaw`).
        ``guess`` (n,): an estimate of x (a scheme's predictor) that an iterative solve
        starts from, or a function returning it (called only by such a solve); direct
        solves ignore it.  The answer does not depend on it beyond the solver's tolerance."""
        sys, s = self.factors.system(op)
        if guess is not None and sys.solver.uses_guess:
            x0 = guess() if callable(guess) else guess
            sys.solver.set_guess(x0[self.free] if self.has_fixed else x0)
        if self.components > 1:
            if not law.friction.frictional or law.reference is None:
                raise InputError(
                    f"this step's contact solve has no friction data; the run's law is {self.friction.label} "
                    "(a scheme that carries friction passes Context.friction_law)"
                )
            bound = np.column_stack([bound, law.reference]).ravel()
        b, bnd = self._reduce(sys, s, rhs, bound, fixed_values)
        x, mu, info = sys.solver.solve(b / s if s != 1.0 else b, bnd, law.scaled(s))
        if s != 1.0 and info.lam_t is not None:
            info.lam_t = s * info.lam_t
        return self._expand(x, fixed_values), (s * mu if s != 1.0 else mu), info

    def friction_law(self, U: np.ndarray, t0: float, t1: float, base: ContactLaw = SIGNORINI) -> ContactLaw:
        """``base`` with the run's friction for a position-level step t0 -> t1 from U = U^n:
        the slip of the step is v_t = T U^{n+1} - c_t with c_t = T U^n + T (obstacle
        translation), the tangential part of U^{n+1} - U^n relative to the obstacle.
        ``base`` itself when the run is frictionless."""
        if self.components == 1:
            return base
        ref = (self.T @ U).reshape(self.disc.contact.size, -1) + self.disc.contact.obstacle_slip(t0, t1)
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

    def slide(self, U: np.ndarray, t: float) -> int:
        """Small sliding after a level (:meth:`ContactSet.slide`): the pair rows whose slave node
        left its master facet in X + U are re-paired; B, its free and fixed blocks, the friction
        frames and every contact solver's rows (their Delassus columns) follow.  Returns the
        number of rows re-paired (counted in ``pair_rows_repaired``)."""
        if not self.sliding:
            return 0
        disc = self.disc
        B_before, T_before = self.B, self.T
        rows = disc.contact.slide(disc.space, disc.problem.pairs, U)
        if rows.size == 0:
            return 0
        # the multipliers of the level just computed acted through the rows of before (in the
        # next step's balance and energy identity: :meth:`rows_of`)
        self._level_rows = (t, B_before, T_before)
        self._use_rows(rows)
        return int(rows.size)

    def _use_rows(self, rows: np.ndarray) -> None:
        """B, its blocks, the frames and the solvers' rows after the contact set changed ``rows``."""
        disc = self.disc
        self.B = disc.B = disc.contact.B
        self.Bf = self.B[:, self.free].tocsr() if self.has_fixed else self.B
        BD = self.B[:, self.fixed].tocsr() if self.has_fixed else None
        self.BD = BD if BD is not None and BD.nnz else None
        if self.components > 1:
            self._frame_rows()
        for sys in self.factors.every():  # the kept steps' too: they must use the current pairing
            sys.solver.replace_rows(rows, self.Hf if self.components > 1 else self.Bf)
        self.repaired += int(rows.size)

    #: the contact set's arrays that small sliding changes (:meth:`ContactSet.slide`)
    PAIRING_ARRAYS = ("normals", "gaps", "master_facet", "master_shape", "master_dofs")

    def pairing_state(self, t: float) -> dict[str, Any]:
        """The pairing after small sliding, for a checkpoint at time t: the contact set's
        changed arrays, the rows the level at t acted through (when a re-pairing followed it)
        and the counts of re-paired rows.  Empty without sliding pairs."""
        if not self.sliding:
            return {}
        c = self.disc.contact
        out: dict[str, Any] = {k: np.asarray(getattr(c, k)) for k in self.PAIRING_ARRAYS}
        out["repaired"] = int(self.repaired)
        out["pair_repaired"] = [int(p["repaired_rows"]) for p in (c.pair_info or [])]
        if self._level_rows is not None and self._level_rows[0] == t:
            for name, M in (("level_B", self._level_rows[1]), ("level_T", self._level_rows[2])):
                if M is not None:
                    M = M.tocsr()
                    out.update({f"{name}_data": M.data, f"{name}_indices": M.indices, f"{name}_indptr": M.indptr})
        return out

    def restore_pairing(self, data: dict[str, Any], t: float) -> None:
        """Put back the pairing of :meth:`pairing_state` (a resumed run, before its first step)."""
        if not self.sliding or not data:
            return
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
            if hasattr(c, "_tangents"):
                del c._tangents
            c.B = c._row_frame(c.normals[:, None, :], n).tocsr()
            self._use_rows(rows)
        self.repaired = int(data["repaired"])
        for p, r in zip(c.pair_info or [], data["pair_repaired"], strict=False):
            p["repaired_rows"] = int(r)
        level = []
        for name in ("level_B", "level_T"):
            if f"{name}_data" in data:
                shape = (c.size * (1 if name == "level_B" else self.components - 1), n)
                level.append(sp.csr_matrix((data[f"{name}_data"], data[f"{name}_indices"], data[f"{name}_indptr"]),
                                           shape=shape))  # fmt: skip
            else:
                level.append(None)
        if level[0] is not None:
            self._level_rows = (t, level[0], level[1])

    #: contact pair rows re-paired by small sliding over the run
    repaired = 0
    _level_rows: tuple | None = None

    def rows_of(self, t: float) -> tuple[Any, Any]:
        """(B, T): the contact rows the multipliers of the level at time t act through: the
        current ones, or those before a re-pairing (:meth:`slide`) that followed that level."""
        if self._level_rows is not None and self._level_rows[0] == t:
            return self._level_rows[1], self._level_rows[2]
        return self.B, self.T

    def massless_update(self, V: np.ndarray, A: np.ndarray, U: np.ndarray, U_old: np.ndarray) -> None:
        """On the massless directions, in place: V = (U - U_old)/dt and A = 0.

        Massless dofs (zero rows of M) and, for ``seed-normal`` on a tilted or curved
        contact, the contact nodes' normals nu_i (the rows of B, orthonormal): there the
        scheme's own V and A are not controlled by any inertia (CN's (-1)^n mode grows in
        them, and M A then carries their round-off)."""
        ml = self.massless
        if ml.size:
            V[ml] = (U[ml] - U_old[ml]) / self.dt
            A[ml] = 0.0
        if self.rotated_kernel:
            B = self.B
            V -= B.T @ (B @ V - (B @ (U - U_old)) / self.dt)
            A -= B.T @ (B @ A)

    def contact_on_fixed(self, lam: np.ndarray, lam_t: np.ndarray | None = None, t: float | None = None
                         ) -> np.ndarray | float:  # fmt: skip
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

    def solve_linear(self, op: Operator, rhs: np.ndarray, fixed_values: np.ndarray | None = None) -> np.ndarray:
        """Solve ``K x = rhs`` on the free rows without contact."""
        sys, s = self.factors.system(op)
        b, _ = self._reduce(sys, s, rhs, None, fixed_values)
        return self._expand(sys.solver.solve_linear(b / s), fixed_values)

    def _reduce(self, sys: _System, s: float, rhs, bound, fixed_values):
        if not self.has_fixed:
            return rhs, bound
        xD = np.zeros(self.fixed.size) if fixed_values is None else fixed_values
        b = rhs[self.free] - s * sys.lift(xD)
        rows = self.HD if self.components > 1 else self.BD
        if bound is not None and rows is not None:
            bound = bound - rows @ xD
        return b, bound

    def _expand(self, x: np.ndarray, fixed_values) -> np.ndarray:
        if not self.has_fixed:
            return x
        out = np.empty(self.M.shape[0])
        out[self.free] = x
        out[self.fixed] = 0.0 if fixed_values is None else fixed_values
        return out

    # -- bookkeeping ---------------------------------------------------------------
    @property
    def solvers(self) -> list[ContactSolver]:
        """The contact solvers of the current step's factorized operators."""
        return self.factors.solvers

    def counters(self) -> dict[str, int]:
        """Sum of the solvers' counters (factorizations, linear_solves, ...), with the pairs' re-paired rows."""
        out = self.factors.counters()
        if self.disc.problem.pairs:
            out["pair_rows_repaired"] = self.repaired
        return out

"""What a time scheme's step may use: operators, data at time t, and the contact solver.

A :class:`Context` is built once per run by :func:`~signorini.dynamics.stepping.simulate.simulate`.
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
from typing import Any

import numpy as np
import scipy.sparse as sp

from ...contact.solver import SIGNORINI, ContactLaw, ContactSolver, StepInfo, make_contact_solver
from ...errors import InputError, NonFiniteError
from ...linalg.base import CG_FRIENDLY_RATIO, backend_traits
from ...linalg.row_block import RowBlock, node_row_bounds, row_bounds
from ...linalg.sparse import principal_combination, principal_rows
from ...linalg.spmv import sparse_product
from ...parallel import DISTRIBUTED_BACKENDS, run_comm
from ..model.mass import massless_dofs
from ..model.mixed_velocity import VelocitySpace
from ..model.operator import Operator
from ..model.problem import Discretization
from ..rows.contact_rows import ContactRows
from ..rows.current_rows import current_rows
from .elasticity import elasticity
from .factorizations import Factorizations
from .turning import body_turning

#: what a factorization raises for a singular or indefinite operator: SuperLU and MKL
#: Pardiso RuntimeError, numpy LinAlgError, CHOLMOD (cvxopt) ArithmeticError
FACTORIZATION_ERRORS = (RuntimeError, np.linalg.LinAlgError, ArithmeticError)


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
    b, S = op.stiffness_part(ctx.S)  # S, or a Newton iterate's tangent (finite strain: whole rows, or by rows)
    if isinstance(ctx.M, RowBlock):  # M and S by rows: the free rows among this rank's own
        bounds = np.searchsorted(f, ctx.M.bounds).astype(np.int64)
        rows = f[bounds[ctx.comm.rank] : bounds[ctx.comm.rank + 1]]
        lo, hi = ctx.M.lo, ctx.M.hi
        S = S.local if isinstance(S, RowBlock) else sp.csr_matrix(S)[lo:hi]
        M, rows = ctx.M.local, rows - lo
    else:
        bounds = node_row_bounds(ctx.disc.space.dofmap.nodes_of(f), ctx.comm.size)
        rows = f[bounds[ctx.comm.rank] : bounds[ctx.comm.rank + 1]]
        M = ctx.M
    Kf, KD = principal_rows(op.mass, M, b, S, f, D, rows)
    return RowBlock(Kf, bounds, ctx.comm), RowBlock(KD, bounds, ctx.comm)


class _System:
    """A factorized operator restricted to the free dofs, with its lifting block."""

    def __init__(self, op: Operator, ctx: Context, options: dict[str, Any]):
        f, D = ctx.free, ctx.fixed
        if ctx.rows.sliding:  # the Schur complement is of the contact dofs of t = 0: lazy or full columns follow
            if options.get("condensation") == "schur":
                raise InputError(
                    "solver option condensation='schur' cannot follow contact pairs as they slide; "
                    "use condensation='lazy' or 'full', or pairing='frozen'"
                )
            options = {
                **options,
                "condensation": "lazy" if options.get("condensation", "auto") == "auto" else options["condensation"],
            }
        # only the free block and its coupling to the fixed dofs are formed; on the ranks of
        # a distributed backend, only this rank's block of their rows (no rank holds all of K)
        if ctx.distributed:
            Kff, KfD = _row_blocks(op, ctx)
            local = (Kff.local, KfD.local)
            self.KfD = KfD if D.size else None
        elif D.size:
            Kff, self.KfD = principal_combination(op.mass, ctx.M, *op.stiffness_part(ctx.S), f, D)
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
            B = ctx.rows.Hf if ctx.rows.components > 1 else ctx.rows.Bf  # with friction: the nodal frames' rows
            free = f if D.size else np.arange(Kff.shape[0])
            self.solver: ContactSolver = make_contact_solver(
                Kff,
                B,
                gap_scale,
                dim,
                options,
                nodes,
                cg_friendly,
                ctx.rows.components,
                lambda: ctx.disc.space.rigid_body_modes(free),
                refactorized=ctx.elastic.finite,
            )
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


class DirichletElimination:
    """The prescribed dofs D taken out of a solve on the free dofs f and put back in its answer."""

    def __init__(self, free: np.ndarray, fixed: np.ndarray, n: int):
        self.free, self.fixed, self.n = free, fixed, n

    def reduce(
        self,
        lift: Callable[[np.ndarray], Any],
        s: float,
        rhs: np.ndarray,
        bound: np.ndarray | None,
        fixed_values: np.ndarray | None,
        rows: ContactRows,
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """(rhs_f - s K_fD x_D, bound - (rows on D) x_D): a solve of K x = rhs with x_D = ``fixed_values``
        (0 when None) on the free dofs; ``lift`` is the system's K_fD x_D, ``rows`` the contact rows."""
        if not self.fixed.size:
            return rhs, bound
        xD = np.zeros(self.fixed.size) if fixed_values is None else fixed_values
        b = rhs[self.free] - s * lift(xD)
        on_fixed = rows.HD if rows.components > 1 else rows.BD
        if bound is not None and on_fixed is not None:
            bound = bound - on_fixed @ xD
        return b, bound

    def expand(self, x: np.ndarray, fixed_values: np.ndarray | None) -> np.ndarray:
        """The full vector (n,): x on the free dofs, ``fixed_values`` (0 when None) on D."""
        if not self.fixed.size:
            return x
        out = np.empty(self.n)
        out[self.free] = x
        out[self.fixed] = 0.0 if fixed_values is None else fixed_values
        return out


#: relative size of a gap that is contact (:attr:`Context.touch_tolerance`): 1e4 times the
#: round-off of a coordinate, 1e-12 of the body
TOUCH = 1e-12


class Context:
    """Operators, data of time t and the contact solver of one run (see module doc)."""

    def __init__(self, disc: Discretization, dt: float, solver_options: dict[str, Any] | None = None):
        self.disc = disc
        self.dt = float(dt)
        self.M, self.S = disc.M, disc.S
        self.free, self.fixed = disc.free, disc.fixed
        self.solver_options = dict(solver_options or {})
        #: the ranks of the run (:mod:`signorini.parallel`): one process, or mpiexec's for ``petsc``
        self.comm = run_comm(self.solver_options.get("backend", "auto"))
        #: the operators of the contact solve and of the products are blocks of rows per rank
        #: (:class:`~signorini.linalg.row_block.RowBlock`): backends ``petsc`` and ``petsc-cg``
        self.distributed = self.solver_options.get("backend") in DISTRIBUTED_BACKENDS
        self.has_fixed = self.fixed.size > 0
        #: the Dirichlet dofs eliminated from a solve and put back in its answer
        self.elimination = DirichletElimination(self.free, self.fixed, disc.space.n_dofs)
        #: the contact rows B, T, H, their blocks, friction data and pairing (their only owner):
        #: ``ctx.rows.B``, ``ctx.rows.friction_law(...)``
        self.rows = ContactRows(disc, self.solver_options)
        #: whether the schemes of the run can use the CG contact solve (``auto`` may pick it;
        #: never with friction)
        self.iterative_ok = self.rows.components == 1
        #: the factorized step operators, per step size (their only owner)
        self.factors = Factorizations(lambda op: _System(op, self, self.solver_options), self.dt)
        self.massless = massless_dofs(disc.M)
        #: the internal force, its energy and tangent: linear (S U) or finite strain (:mod:`~.elasticity`)
        self.elastic = elasticity(self)
        if self.elastic.finite:  # finite strain: the obstacle's rows in the current configuration, factors only
            self.rows.current = current_rows(self.rows)
            self.iterative_ok = False
        #: Rayleigh damping C = alpha M + beta S (None: undamped), :mod:`~signorini.dynamics.model.damping`
        self.damping = disc.problem.damping
        #: C per region (:class:`~signorini.dynamics.model.damping.RegionalRayleigh`): a third term of the step
        #: operators, factorized by the serial direct backends only; None otherwise
        self.damping_matrix = None
        if self.damping is not None and hasattr(self.damping, "regions"):
            backend = self.solver_options.get("backend", "auto")
            if self.distributed or not backend_traits(backend).finite_strain:
                raise InputError(
                    f"damping per region ([material] regions[k].damping) with backend {backend!r} is not done: its "
                    "step operator holds C as a third matrix beside M and S, which the serial direct backends "
                    "factorize; use superlu, cholmod, pardiso or auto (or one damping for the whole mesh)"
                )
            self.damping_matrix = self.damping.matrix(disc.problem.mesh, disc.material, disc.M, disc.S)
            self.iterative_ok = False
        #: the mass has massless directions that are not coordinate axes (``mixed-velocity``; ``seed-normal`` on a
        #: tilted or curved contact): schemes that balance massless rows apart refuse it
        n = disc.contact.normals
        #: ``mixed-velocity``'s kernel ker W (:class:`~..model.mixed_velocity.VelocitySpace`), else None
        self.velocity_space = None
        if disc.velocity_pairing is not None:
            self.velocity_space = VelocitySpace(disc.velocity_pairing, disc.free)
        self.rotated_kernel = self.velocity_space is not None or bool(
            disc.mass_name == "seed-normal"
            and n.size
            and not np.all(np.isclose(np.abs(n).max(axis=1), 1.0, atol=1e-12))
        )
        #: each body's rigid turn, for a kept Newton tangent (:mod:`~.turning`); None where it does not apply
        self.turning = body_turning(self) if self.elastic.finite and not self.rotated_kernel else None
        if self.massless.size == disc.M.shape[0]:
            raise InputError(
                f"mass {disc.mass_name!r} leaves the body without any mass (every cell touches the contact "
                "boundary): refine the mesh across the contact layer or use the 'standard' mass"
            )

    def slide(self, U: np.ndarray, t: float) -> int:
        """Small sliding after a level (:meth:`ContactRows.slide`); every factorized system, the
        kept steps' too, takes the re-paired rows (their Delassus columns follow).  Returns the
        number of rows re-paired."""
        return self.replace_rows(self.rows.slide(U, t))

    def restore_pairing(self, data: dict[str, Any], t: float) -> None:
        """Put back a checkpoint's pairing (:meth:`ContactRows.restore_pairing`) in the rows and
        the solvers (a resumed run, before its first step)."""
        self.replace_rows(self.rows.restore_pairing(data, t))

    def replace_rows(self, rows: np.ndarray) -> int:
        """Every factorized system, the kept steps' too, takes the contact rows ``rows`` changed in
        ``ctx.rows`` (their Delassus columns follow); returns their number."""
        if rows.size:
            for sys in self.factors.every():  # the kept steps' too: they must use the current pairing
                sys.solver.replace_rows(rows, self.rows.solve_rows)
        return int(rows.size)

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
        if self.rows.components > 1:
            if not law.friction.frictional or law.reference is None:
                raise InputError(
                    f"this step's contact solve has no friction data; the run's law is {self.rows.friction.label} "
                    "(a scheme that carries friction passes Context.friction_law)"
                )
            bound = np.column_stack([bound, law.reference]).ravel()
        b, bnd = self.elimination.reduce(sys.lift, s, rhs, bound, fixed_values, self.rows)
        x, mu, info = sys.solver.solve(b / s if s != 1.0 else b, bnd, law.scaled(s))
        if s != 1.0 and info.lam_t is not None:
            info.lam_t = s * info.lam_t
        return self.elimination.expand(x, fixed_values), (s * mu if s != 1.0 else mu), info

    def massless_update(self, V: np.ndarray, A: np.ndarray, U: np.ndarray, U_old: np.ndarray) -> None:
        """On the massless directions, in place: V = (U - U_old)/dt and A = 0.

        Massless dofs (zero rows of M), ``mixed-velocity``'s ker W and, for ``seed-normal`` on a tilted or curved
        contact, the contact nodes' normals nu_i (the rows of B, orthonormal): there the
        scheme's own V and A are not controlled by any inertia (CN's (-1)^n mode grows in
        them, and M A then carries their round-off)."""
        ml = self.massless
        if ml.size:
            V[ml] = (U[ml] - U_old[ml]) / self.dt
            A[ml] = 0.0
        if self.rotated_kernel:  # the massless directions that are not dofs (:meth:`kernel_part`)
            V -= self.kernel_part(V - (U - U_old) / self.dt)
            A -= self.kernel_part(A)

    def kernel_part(self, x: np.ndarray) -> np.ndarray:
        """The part of ``x`` (n,) along the massless directions that are not dofs (:attr:`rotated_kernel`), zero
        on the Dirichlet dofs: ``mixed-velocity``'s ker W_f, or ``seed-normal``'s normals B^T B x (B's rows
        orthonormal); zero when the kernel is made of dofs."""
        if self.velocity_space is not None:
            return self.velocity_space.kernel_part(x)
        if not self.rotated_kernel:
            return np.zeros_like(x)
        B = self.rows.B
        out = B.T @ (B @ x)
        out[self.fixed] = 0.0
        return out

    def solve_linear(self, op: Operator, rhs: np.ndarray, fixed_values: np.ndarray | None = None) -> np.ndarray:
        """Solve ``K x = rhs`` on the free rows without contact."""
        sys, s = self.factors.system(op)
        b, _ = self.elimination.reduce(sys.lift, s, rhs, None, fixed_values, self.rows)
        return self.elimination.expand(sys.solver.solve_linear(b / s), fixed_values)

    # -- bookkeeping ---------------------------------------------------------------
    @property
    def solvers(self) -> list[ContactSolver]:
        """The contact solvers of the current step's factorized operators."""
        return self.factors.solvers

    def counters(self) -> dict[str, int]:
        """Sum of the solvers' counters (factorizations, linear_solves, ...), with the pairs' re-paired rows."""
        out = self.factors.counters()
        if self.disc.problem.pairs:
            out["pair_rows_repaired"] = self.rows.repaired
        out.update(self.elastic.counters())
        return out

"""The per-step exact contact solve on an operator factorized once per run.

Each call solves, for the SPD operator K of the run and a right-hand side b,

    K x = b + B^T lambda,   B x <= c,   lambda <= 0,   (B x - c) . lambda = 0,

where x is whatever the scheme's unknown is (displacements for position-level
schemes, velocities for velocity-level ones) and the bound c is given per call
(gaps at t_{n+1}, a moving obstacle, a two-step scheme's combination of levels).

:class:`CondensedContactSolver` (direct backends): condensation onto the contact
dofs with the Delassus matrix W = B K^-1 B^T and Z = K^-1 B^T,

    x = x_free + Z lambda,     x_free = K^-1 b,

and mu = -lambda solves the LCP  r = (c - B x_free) + W mu >= 0, mu >= 0, r.mu = 0
(:mod:`signorini.contact.complementarity`).  W comes from one of

* :mod:`signorini.contact.schur` (``condensation = schur``, Pardiso): the Schur
  complement of K on the contact dofs, computed by the factorization itself; a call
  costs a forward and a backward substitution (one solve), the LCP and dense
  products with the contact dofs;
* :mod:`signorini.contact.delassus`: columns of W and Z computed by solves, lazily
  (a node's column when the node first nears contact; ``lazy``) or all at set-up
  (``full``); a call costs one solve, the LCP on the candidate nodes warm-started from
  the previous active set, and one product with the active columns of Z (one more solve
  instead when Z does not fit in ``condense_budget`` bytes).

``auto`` picks ``schur`` with Pardiso and many contact nodes, else ``lazy``
(:func:`choose_condensation`).

:class:`ActiveSetCGSolver` (backend ``cg``): semismooth Newton on the active set
with projected preconditioned CG, no factor and no Z.

Both keep counters (``factorizations``, ``linear_solves``, ``contact_iterations``,
``fallbacks``, ``krylov_iterations``) and raise
:class:`~signorini.errors.ConvergenceError` when they cannot converge.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import scipy.sparse as sp

from ..errors import ConvergenceError, InputError
from ..fem.dofmap import blocked, component, n_blocks, whole_blocks
from ..linalg import (
    BACKENDS,
    backend_traits,
    choose_backend,
    factor_class,
    factorize,
    has_pardiso,
    make_preconditioner,
    projected_cg,
    solver_options,
    total_memory,
)
from ..linalg.spmv import sparse_product
from .complementarity import complementarity_residual, solve_lcp
from .delassus import DelassusColumns
from .friction import FRICTIONLESS, Friction, solve_cone
from .schur import SchurDelassus, schur_dofs

#: the scaled complementarity residual of a contact solve above which a step has failed (the stepper's bound;
#: Newton waits for it before it ends its iterations)
MAX_CONTACT_RESIDUAL = 1e-6


def _best_time(op, n: int, repeats: int = 3) -> float:
    """Best of ``repeats`` timings of ``op`` on a random vector of length n [s]."""
    x = np.random.default_rng(0).normal(size=n)
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        op(x)
        best = min(best, time.perf_counter() - t0)
    return best


@dataclass(frozen=True)
class ContactLaw:
    """How one contact solve departs from the Signorini condition ``B x <= bound ⊥ lambda <= 0``.

    ``subset`` (bool, nc): only these contact nodes are constrained (the index set of a
    velocity-level scheme); lambda is zero elsewhere.  None: all of them.
    ``compliance`` c (nc,) >= 0: the constraint becomes ``B x + c lambda <= bound``, i.e. the
    penalty lambda_i = -max(0, (B x)_i - bound_i) / c_i.  None: exact contact.
    ``friction`` (:class:`~signorini.contact.friction.Friction`): a frictional law adds d - 1
    tangential multipliers per node (a solver built with d components); ``reference``
    (nc, d - 1) is c_t of the slip v_t = T x - c_t, ``radius`` (nc,) the Tresca
    thresholds s w_i [force] and ``coefficient`` (nc,) the Coulomb coefficients mu_i of the
    rows (contact pairs with their own laws; None: ``friction.coefficient`` on every row).
    Only the condensed (direct) solver supports these fields.
    """

    subset: np.ndarray | None = None
    compliance: np.ndarray | None = None
    friction: Friction = FRICTIONLESS
    reference: np.ndarray | None = None
    radius: np.ndarray | None = None
    coefficient: np.ndarray | None = None

    @property
    def exact(self) -> bool:
        """Plain Signorini contact on every node."""
        return (self.subset is None or bool(self.subset.all())) and self.compliance is None

    def scaled(self, s: float) -> ContactLaw:
        """The same law for the system divided by s (lambda = s mu: compliance times s,
        Tresca thresholds divided by s; Coulomb's cone is invariant)."""
        if s == 1.0 or (self.compliance is None and self.radius is None):
            return self
        compliance = None if self.compliance is None else np.asarray(self.compliance) * s
        radius = None if self.radius is None else np.asarray(self.radius) / s
        return replace(self, compliance=compliance, radius=radius)


SIGNORINI = ContactLaw()


@dataclass
class StepInfo:
    """What one contact solve did: active-set iterations, NNLS fallback, residual.

    With friction also ``lam_t`` (nc, d - 1) the tangential multipliers [force],
    ``slip`` (nc, d - 1) the slip v_t = T x - c_t at the solution [length] and ``status``
    (nc,) separated / stick / slip (codes 0, 1, 2: :data:`~signorini.contact.friction.SEPARATED`, ``STICK``, ``SLIP``).
    """

    iterations: int
    fallback: bool
    residual: float
    active: np.ndarray
    lam_t: np.ndarray | None = None
    slip: np.ndarray | None = None
    status: np.ndarray | None = None
    #: Newton iterations of a finite-strain step (:mod:`~signorini.dynamics.solve.newton`), 0 for a linear one
    nonlinear_iterations: int = 0
    #: the force residual r (n,) left by a finite-strain step's Newton iterations at its solution (0 on the Dirichlet
    #: dofs) [force], whose work is the step's ``solver_work``; None for a linear one
    force_residual: np.ndarray | None = None


class ContactSolver:
    """Common counters and interface; see the module docstring."""

    name = "contact-solver"
    #: whether :meth:`set_guess` is of use (iterative solves)
    uses_guess = False
    #: the attributes carried from one call to the next (warm starts: the previous active set,
    #: multipliers or solution), which a checkpoint saves so that a resumed run solves as the
    #: uninterrupted one
    warm_state: tuple[str, ...] = ()

    def __init__(self) -> None:
        self.counters = {
            "factorizations": 0,
            "linear_solves": 0,
            "contact_iterations": 0,
            "fallbacks": 0,
            "krylov_iterations": 0,
            "friction_iterations": 0,
            "friction_fallbacks": 0,
        }
        self.timings: dict[str, float] = {}
        self.factor_bytes = 0

    def release(self) -> None:
        """No longer of use (its counters read): its factor's resources go (``Factor.release``)."""
        factor = getattr(self, "factor", None)
        if factor is not None:
            factor.release()

    def solve(
        self, b: np.ndarray, bound: np.ndarray, law: ContactLaw = SIGNORINI
    ) -> tuple[np.ndarray, np.ndarray, StepInfo]:
        """(x, lambda, info) for the right-hand side ``b``, the bound and the :class:`ContactLaw`."""
        raise NotImplementedError  # pragma: no cover

    def solve_linear(self, b: np.ndarray) -> np.ndarray:
        """K^-1 b without contact."""
        raise NotImplementedError  # pragma: no cover

    def replace_rows(self, rows: np.ndarray, B: sp.csr_matrix) -> None:
        """The contact rows ``rows`` (nodes) of B changed (small sliding of a contact pair); B is
        the whole new matrix, on this solver's dofs."""
        raise NotImplementedError(f"{type(self).__name__} cannot change its contact rows during a run")

    def set_guess(self, x: np.ndarray) -> None:
        """An estimate (n,) of the next solve's x; a direct solve has no use for it."""

    def remeasure_bare(self) -> None:
        """Time the bare operation (a solve, or CG's SpMV) again after the loop, in the loop's
        conditions, and keep the best of both: a step that contains that operation is then
        never reported cheaper than it (measured at set-up only, under another run's load,
        compare showed a step of 0.77 x solve).  Serial solvers only (a distributed one's
        operation is collective)."""
        for key, (op, n) in getattr(self, "_bare", {}).items():
            self.timings[key] = min(self.timings[key], _best_time(op, n))


#: a frictional candidate must penetrate by more than this times the gap scale (round-off)
GRAZING = 1e-13
#: a frictional solve whose answer violates a constraint by more than this times the gap
#: scale is a failure (ConvergenceError), never a result
ADMISSIBLE = 1e-9

CONDENSATIONS = ("auto", "lazy", "full", "schur")
#: ``auto`` takes the Schur condensation from this many contact nodes: below, the lazy
#: columns (blocks of 64, each about 15 solves) cost less than Schur's slower solves
#: (MKL runs the forward/backward parts on one thread: 1.5-2x a plain solve on 2 cores)
SCHUR_MIN_NODES = 512


def choose_condensation(condensation: str, backend: str, B: sp.csr_matrix, budget: float) -> str:
    """The condensation of a run: ``auto`` takes ``schur`` when the backend computes Schur
    complements (pardiso), there are at least :data:`SCHUR_MIN_NODES` contact nodes, and
    the dense matrices (S, its Cholesky factor, S^-1 B_C^T, W and their temporaries: at
    most 8 (2 |C|^2 + 2 |C| nc + 3 nc^2) bytes) fit in ``budget``; else ``lazy``.  An explicit
    ``schur`` on another backend is an input error."""
    if condensation not in CONDENSATIONS:
        allowed = ", ".join(CONDENSATIONS)
        raise InputError(f"solver option 'condensation' must be one of {allowed}; got {condensation!r}")
    supported = factor_class(backend).supports_schur
    if condensation == "schur" and not supported:
        why = " (PETSc has no parallel MUMPS Schur complement)" if backend_traits(backend).distributed else ""
        raise InputError(
            f"solver option condensation='schur' needs the pardiso backend, not {backend!r}{why}; "
            "use condensation='lazy' or 'full' with this backend"
        )
    if condensation != "auto":
        return condensation
    nc, n = B.shape
    ns = schur_dofs(B).size if supported and nc else 0
    dense = 8.0 * (2 * ns * ns + 2 * ns * nc + 3 * nc * nc)
    return "schur" if nc >= SCHUR_MIN_NODES and 0 < ns < n // 2 and dense <= budget else "lazy"


class CondensedContactSolver(ContactSolver):
    """Factor ``K`` once; solve each call exactly on the Delassus matrix W = B K^-1 B^T.

    ``condensation`` (:func:`choose_condensation`): ``schur`` gets all of W from the
    Schur complement of K on the contact dofs, computed with the factorization
    (Pardiso); ``lazy`` computes the column of W of a contact node the first time the
    node is a candidate (violates its bound, or was active), so the set-up is one
    factorization and a step costs solves only for nodes touching for the first time;
    ``full`` computes all nc columns at set-up.  All give the same solution (the LCP
    with W SPD has a unique solution; see :meth:`solve`).
    """

    warm_state = ("active", "lam_prev")

    def __init__(
        self,
        K: sp.spmatrix,
        B: sp.csr_matrix,
        gap_scale: float,
        backend: str = "superlu",
        condense_budget: float = 2e9,
        lcp_max_iter: int = 50,
        condensation: str = "auto",
        components: int = 1,
        reproducible: bool = False,
    ):
        super().__init__()
        self.B = sp.csr_matrix(B)
        self.components = components  # rows of B per contact node (d with friction)
        nc, n = self.B.shape
        self.condensation = condensation = choose_condensation(condensation, backend, self.B, condense_budget)
        t0 = time.perf_counter()
        dofs = schur_dofs(self.B) if condensation == "schur" else None
        self.factor = factorize(K, backend, dofs, reproducible)
        self.counters["factorizations"] = 1
        t1 = time.perf_counter()
        self.name = self.factor.name
        self.lcp_max_iter = lcp_max_iter
        if condensation == "schur":
            self.delassus = SchurDelassus(self.factor, self.B)
        else:
            columns = DelassusColumns
            if getattr(self.factor, "distributed", False):  # each rank keeps its own rows of Z
                from .distributed_columns import DistributedColumns as columns
            self.delassus = columns(self.factor, self.B, condense_budget)
            if condensation == "full":
                self.delassus.ensure(np.arange(nc))
        self.active = np.zeros(n_blocks(nc, components), dtype=bool)
        self.lam_prev = np.zeros((n_blocks(nc, components), components))
        # frame rows with no free dof (a tangent whose motion a Dirichlet condition prescribes,
        # e.g. a symmetry plane through a contact node): the reaction carries that force
        self.dead = (np.asarray(abs(self.B).sum(axis=1)).ravel() == 0).reshape(-1, components)
        self.gap_scale = max(gap_scale, 1e-300)
        self.timings = {"factorization": t1 - t0, "condensation": time.perf_counter() - t1}
        self.timings["bare_solve"] = _best_time(self.factor.solve, n)
        self._bare = {"bare_solve": (self.factor.solve, n)}
        self._setup_solves = self.factor.solves
        self._setup_columns, self._setup_seconds = self.delassus.solved, self.delassus.seconds
        self.factor_bytes = self.factor.nbytes
        self.counters["delassus_columns"] = self.delassus.solved

    def replace_rows(self, rows: np.ndarray, B: sp.csr_matrix) -> None:
        """The Delassus columns of the changed rows (every component of their nodes) are
        solved again (:meth:`~signorini.contact.delassus.DelassusColumns.replace_rows`)."""
        if self.condensation == "schur":
            raise NotImplementedError("the Schur condensation cannot change its contact rows")
        c = self.components
        self.B = sp.csr_matrix(B)
        self.delassus.replace_rows((np.asarray(rows)[:, None] * c + np.arange(c)).ravel(), self.B)
        self.dead = (np.asarray(abs(self.B).sum(axis=1)).ravel() == 0).reshape(-1, c)
        self._sync()

    def _sync(self) -> None:
        """Counters and timings: ``linear_solves`` are the solves of the steps (the columns
        computed lazily are counted in ``delassus_columns``, their time in ``condensation``
        and, for the part inside the loop, ``condensation_in_loop``)."""
        in_loop = self.delassus.solved - self._setup_columns + getattr(self.delassus, "replayed", 0)
        self.counters["linear_solves"] = self.factor.solves - self._setup_solves - in_loop
        self.counters["delassus_columns"] = self.delassus.solved
        self.timings["condensation"] = self.delassus.seconds
        self.timings["condensation_in_loop"] = self.delassus.seconds - self._setup_seconds

    def solve_linear(self, b: np.ndarray) -> np.ndarray:
        x = self.factor.solve(b)
        self._sync()
        return x

    def solve(
        self, b: np.ndarray, bound: np.ndarray, law: ContactLaw = SIGNORINI
    ) -> tuple[np.ndarray, np.ndarray, StepInfo]:
        """Exact solve on a growing candidate set P of contact nodes.

        With x_free = K^-1 b and q = bound - B x_free, P starts as the nodes violated by
        x_free plus the previous active set; the LCP (W_PP + C_PP, q_P) is solved, and
        every node outside P with r_i = q_i + W_iP mu_P < 0 joins P, until none does.
        Then mu (zero outside P) solves the whole LCP: outside P, mu_i = 0 and r_i >= 0.
        P only grows, so this ends after at most nc rounds (one or two in practice).
        With friction (``components`` > 1) see :meth:`_solve_friction`.
        """
        if self.components > 1:
            return self._solve_friction(b, bound, law)
        state, BU = self.delassus.free(b)
        nc = self.B.shape[0]
        subset, compliance = law.subset, law.compliance
        if nc == 0 or (subset is not None and not subset.any()):
            U = self.delassus.complete(state, np.zeros(nc))
            self._sync()
            self.active = np.zeros(nc, dtype=bool)
            return U, np.zeros(nc), StepInfo(0, False, 0.0, self.active)
        q_all = bound - BU
        idx = np.arange(nc) if subset is None else np.flatnonzero(subset)
        q = q_all[idx]
        scale = max(self.gap_scale, float(np.max(np.abs(q))))
        cdiag = None if compliance is None else np.asarray(compliance, dtype=float)[idx]
        warm = self.active[idx]
        in_P = (q < 0) | warm
        iterations, fallback = 0, False
        mu = np.zeros(idx.size)
        active = np.zeros(idx.size, dtype=bool)
        residual = 0.0
        while in_P.any():
            P = np.flatnonzero(in_P)
            self.delassus.ensure(idx[P], fill=idx[np.argsort(q)])  # top up with the nearest nodes
            W = self.delassus.block(idx[P])
            if cdiag is not None:
                W[np.diag_indices_from(W)] += cdiag[P]
            res = solve_lcp(W, q[P], warm[P], max_iter=self.lcp_max_iter, scale=scale)
            iterations += res.iterations
            fallback |= res.fallback
            mu[:] = 0.0
            mu[P] = res.mu
            active[:] = False
            active[P] = res.active
            warm[P] = res.active
            residual = res.residual
            out = np.flatnonzero(~in_P)
            if out.size == 0:
                break
            r_out = q[out] + self.delassus.W(idx[out], idx[P]) @ res.mu
            joining = out[r_out < 0]
            if joining.size == 0:
                break
            in_P[joining] = True
        lam = np.zeros(nc)
        lam[idx] = -mu
        U = self.delassus.complete(state, lam)
        self.active = np.zeros(nc, dtype=bool)
        self.active[idx] = active
        self.counters["contact_iterations"] += iterations
        self.counters["fallbacks"] += int(fallback)
        self._sync()
        return U, lam, StepInfo(iterations, fallback, residual, self.active)

    def _solve_friction(
        self, b: np.ndarray, bound: np.ndarray, law: ContactLaw
    ) -> tuple[np.ndarray, np.ndarray, StepInfo]:
        """The frictional solve (:func:`~signorini.contact.friction.solve_cone`) on a growing
        candidate set P of nodes: ``bound`` (nc d,) holds, node-major, the normal bound and
        the tangential reference c_t of every node; v = H x - bound = v_free + W lambda.
        P starts as the nodes violated by x_free plus the previous active set, warm-started
        with the previous multipliers; a node outside P whose normal v_n > 0 joins P.
        Nodes outside P carry lambda = 0, which is the law's solution there (v_n <= 0 and
        radius 0).  Returns lambda (nc, d) in the nodal frames."""
        d = self.components
        state, HU = self.delassus.free(b)
        nc = n_blocks(self.B.shape[0], d)
        v_free = (HU - bound).reshape(nc, d)
        lam = np.zeros((nc, d))
        subset = law.subset
        idx = np.arange(nc) if subset is None else np.flatnonzero(subset)
        mu = law.friction.coefficient
        mus = None if law.coefficient is None else np.asarray(law.coefficient, dtype=float)  # per row
        radius = None if law.radius is None else np.asarray(law.radius, dtype=float)
        gap = -v_free[idx, 0]
        scale = max(self.gap_scale, float(np.max(np.abs(gap), initial=0.0)))
        # a penetration at round-off is no contact: such grazing nodes would pose the cone
        # problem with a normal force of round-off size, degenerate for a large mu
        touch = GRAZING * scale
        in_P = (gap < -touch) | self.active[idx]
        iterations, fallback, residual = 0, False, 0.0
        sol = None
        near = idx[np.argsort(gap)]
        fill = blocked(near, d).ravel()
        while in_P.any():
            P = idx[in_P]
            rows = blocked(P, d).ravel()
            self.delassus.ensure(rows, fill=fill)
            W, vP = self.delassus.block(rows), v_free[P]
            dead = self.dead[P].ravel()
            if dead.any():  # a decoupled unit row with no slip: its multiplier is exactly 0
                W[dead, :] = 0.0
                W[:, dead] = 0.0
                W[dead, dead] = float(np.mean(np.diag(W)[~dead]))
                vP = np.where(self.dead[P], 0.0, vP)
            try:
                mu_P = mu if mus is None else mus[P]
                sol = solve_cone(W, vP, mu_P, None if radius is None else radius[P], self.lam_prev[P], scale)
            except ConvergenceError:
                self.counters["fallbacks"] += 1
                self.counters["friction_fallbacks"] += 1
                raise
            iterations += sol.iterations
            fallback |= sol.fallback
            residual = sol.residual
            lam[:] = 0.0
            lam[P] = sol.lam
            out = idx[~in_P]
            if out.size == 0:
                break
            v_out = v_free[out, 0] + self.delassus.W(out * d, rows) @ sol.lam.ravel()
            joining = v_out > touch
            if not joining.any():
                break
            in_P[np.flatnonzero(~in_P)[joining]] = True
        x = self.delassus.complete(state, lam.ravel())
        v = (self.B @ x - bound).reshape(nc, d) if sol is not None else v_free
        # a solve (a fallback included) never returns a point that violates the constraints
        worst = float(np.max(v[idx, 0], initial=0.0))
        if worst > ADMISSIBLE * max(scale, float(np.max(np.abs(bound.reshape(nc, d)[idx, 0]), initial=0.0))):
            node = int(idx[np.argmax(v[idx, 0])])
            raise ConvergenceError(
                f"the frictional contact solve left contact node {node} {worst:.3g} beyond its constraint "
                f"(residual {residual:.3g}); reduce the time step"
            )
        status = np.zeros(nc, dtype=np.int8)
        if sol is not None:
            status[idx[in_P]] = sol.status
        self.active = lam[:, 0] < 0
        self.lam_prev = lam
        self.counters["contact_iterations"] += iterations
        self.counters["friction_iterations"] += iterations
        self.counters["fallbacks"] += int(fallback)
        self.counters["friction_fallbacks"] += int(fallback)
        self._sync()
        info = StepInfo(iterations, fallback, residual, self.active, lam[:, 1:].copy(), v[:, 1:].copy(), status)
        return x, lam[:, 0].copy(), info


#: an active-set cycle of the CG contact solve is accepted as a tie when the iterate's
#: complementarity residual, against the largest displacement, is below this (round-off)
TIE_TOLERANCE = 1e-10


class ActiveSetCGSolver(ContactSolver):
    """Active-set (semismooth Newton) contact solve on top of projected PCG, no factor.

    For an active set A the constraint B_A x = c_A is imposed exactly by writing
    x = x_p + P w with the particular solution and the orthogonal projector onto
    {B_A x = 0}

        x_p = B_A^T G^-1 c_A,    P = I - B_A^T G^-1 B_A,    G = B_A B_A^T  (|A| x |A|);

    ``P K P w = P (b - K x_p)`` is solved by CG warm-started from the previous call, and
    the multipliers are lambda_A = G^-1 B_A (K x - b) (the residual K x - b lies in the
    range of B_A^T at CG's convergence).  Rigid-obstacle rows (one node and a unit normal
    per row, no two rows on one node) are orthonormal, G = I, and the solve uses
    x_p = B_A^T c_A, P = I - B_A^T B_A, lambda_A = B_A (K x - b) as such
    (:func:`gram_factor` returns None); contact-pair rows (a slave node and a master
    facet's nodes, :mod:`~signorini.contact.pairs`) are not, and G is factored once per
    active set (:class:`GramFactor`).  The gaps are then checked and A is updated by the
    rule A = {i : -lambda_i - c gap_i > 0} until it no longer changes.  When A cycles,
    the iterate is accepted if it satisfies complementarity to round-off
    (:data:`TIE_TOLERANCE` of the largest displacement): nodes at zero gap and zero
    force, where either set solves the step (measured on bar3d n = 8 leaving the
    obstacle: 6e-14); otherwise the solve fails.
    """

    warm_state = ("active", "U_prev")

    uses_guess = True

    def __init__(
        self,
        K: sp.spmatrix,
        B: sp.csr_matrix,
        gap_scale: float,
        preconditioner: str = "jacobi",
        rtol: float = 1e-12,
        max_iter: int = 2000,
        max_newton: int = 30,
        nodes: np.ndarray | None = None,
        spmv_threads: int = 0,
        spmv: str = "auto",
    ):
        super().__init__()
        t0 = time.perf_counter()
        self.K = K.tocsr() if sp.issparse(K) else sp.csr_matrix(K)  # same object: keeps its format flags
        # the products of CG, on all cores (with MKL, from K's upper triangle, in blocks of a
        # node's dofs when they are whole: about half the bytes)
        block = _nodal_block_size(nodes, self.K.shape[0])
        self.Kop = sparse_product(self.K, spmv, spmv_threads, symmetric=True, block_size=block)
        self.B = sp.csr_matrix(B)
        # Jacobi by default: with dt ~ h, K = a M + S is spectrally close to a M and CG
        # needs a mesh-independent number of iterations (AMG was 4x slower per step here)
        self.precond = make_preconditioner(preconditioner, self.K, nodes)
        self.name = f"cg+{preconditioner}"
        self.condensation = "none"  # no Delassus matrix: the active set is imposed inside CG
        self.rtol = rtol
        self.max_iter = max_iter
        self.max_newton = max_newton
        self.c = float(np.mean(self.K.diagonal()))
        self.active = np.zeros(self.B.shape[0], dtype=bool)
        self.U_prev = np.zeros(self.K.shape[0])
        self.gap_scale = max(gap_scale, 1e-300)
        self.timings = {"factorization": time.perf_counter() - t0, "condensation": 0.0}
        self.timings["bare_spmv"] = _best_time(lambda x: self.Kop @ x, self.K.shape[0])
        self._bare = {"bare_spmv": (lambda x: self.Kop @ x, self.K.shape[0])}

    def set_guess(self, x: np.ndarray) -> None:
        """CG starts the next solve from x instead of the last solution (a scheme's
        predictor: bar3d n = 16, CN, 8% fewer iterations than from U^n)."""
        if x.shape != self.U_prev.shape:
            raise ValueError(f"a guess of shape {self.U_prev.shape} is needed, got {x.shape}")
        self.U_prev = np.array(x, dtype=np.float64, copy=True)

    def replace_rows(self, rows: np.ndarray, B: sp.csr_matrix) -> None:
        """The new B (its projector is formed per active set: nothing else to update)."""
        self.B = sp.csr_matrix(B)

    def _cg(self, rhs: np.ndarray, x0: np.ndarray, project) -> np.ndarray:
        w, n_cg = projected_cg(self.Kop, rhs, x0, project, self.precond, self.rtol, self.max_iter)
        self.counters["linear_solves"] += 1
        self.counters["krylov_iterations"] += n_cg
        return w

    def _projector(self, BA: sp.csr_matrix, gram: GramFactor | None = None) -> Any:
        """The projection onto {B_A x = 0} (``gram``: the factor of B_A B_A^T, None for
        orthonormal rows), as ``_cg`` applies it."""
        return _projector(BA, gram)

    def _rows_of_K(self, rows: np.ndarray) -> sp.csr_matrix:
        """The rows ``rows`` (sorted dofs of active contact nodes) of K."""
        return self.K[rows]

    def solve_linear(self, b: np.ndarray) -> np.ndarray:
        return self._cg(b, self.U_prev, self._projector(self.B[:0]))

    def solve(
        self, b: np.ndarray, bound: np.ndarray, law: ContactLaw = SIGNORINI
    ) -> tuple[np.ndarray, np.ndarray, StepInfo]:
        if not law.exact:  # the schemes that need it refuse cg at set-up (Scheme.check_context)
            raise InputError(
                "index sets and penalty compliances need the condensed contact solve of a direct backend "
                "(superlu, pardiso or cholmod), not cg"
            )
        A = self.active.copy()
        B, g = self.B, bound
        seen = set()
        for it in range(1, self.max_newton + 1):  # noqa: B007 (it is reported after the loop)
            BA = B[A]
            gram = gram_factor(BA)  # None: orthonormal rows (rigid obstacle), G = I
            project = self._projector(BA, gram)

            lam = np.zeros(g.size)
            if A.any():
                # up = B_A^T G^-1 g_A and lambda_A only touch the dofs of the active rows:
                # products with those rows of K (symmetric) instead of whole K products
                rows = np.unique(BA.indices)
                KA = self._rows_of_K(rows)
                up = BA.T @ (g[A] if gram is None else gram.solve(g[A]))
                U = up + self._cg(b - KA.T @ up[rows], self.U_prev - up, project)
                r_rows = KA @ U - b[rows]
                lam[A] = BA[:, rows] @ r_rows if gram is None else gram.solve(BA[:, rows] @ r_rows)
            else:
                U = self._cg(b, self.U_prev, project)
            gap = g - B @ U
            A_new = (-lam - self.c * gap) > 0
            if np.array_equal(A_new, A):
                break
            key = A_new.tobytes()
            if key in seen:
                # a tie: nodes at zero gap and zero force to CG's round-off (a whole face leaving
                # the obstacle at once), where either set solves the step; anything else fails
                length = max(self.gap_scale, float(np.max(np.abs(gap))), float(np.max(np.abs(U))))
                if complementarity_residual(-lam, gap, 1.0 / self.c, length) <= TIE_TOLERANCE:
                    break
                raise ConvergenceError("active-set iteration cycles; reduce the time step or use a direct backend")
            seen.add(key)
            A = A_new
        else:
            raise ConvergenceError(f"active-set iteration did not converge in {self.max_newton} iterations")
        self.counters["contact_iterations"] += it
        self.active = A
        self.U_prev = U
        # against the displacement's scale too: bodies that start touching (every gap 0, a block
        # resting on a plate) have gaps of round-off only, 1e-20 "of" nothing
        gap_scale = max(self.gap_scale, float(np.max(np.abs(gap))) if gap.size else 0.0, float(np.max(np.abs(U))))
        res = complementarity_residual(-lam, gap, 1.0 / self.c, gap_scale) if g.size else 0.0
        return U, lam, StepInfo(it, False, res, A)


def _nodal_block_size(nodes: np.ndarray | None, n: int) -> int:
    """d when the n rows come in consecutive groups of d rows of one mesh node each, else 1."""
    if nodes is None or len(nodes) != n or n == 0:
        return 1
    nodes = np.asarray(nodes)
    for d in (3, 2):
        first = nodes[component(0, d)]
        whole = whole_blocks(n, d) and all(np.array_equal(first, nodes[component(k, d)]) for k in range(1, d))
        if whole and np.all(np.diff(first) != 0):
            return d
    return 1


def _identity(v: np.ndarray) -> None:
    """The projector of an empty active set (v is left as it is)."""


#: rows whose Gram matrix G = B_A B_A^T has no off-diagonal entry and a diagonal within this
#: of 1 (or exactly 0: a row on clamped dofs only) are orthonormal: the projection is
#: I - B_A^T B_A as such (unit normals computed by a division: |nu|^2 - 1 ~ 1e-16)
ORTHONORMAL = 1e-12
#: a row whose squared norm is below this times the largest is dependent on nothing and
#: carries nothing (a contact row on clamped dofs only: B_A's row is zero)
DEAD_ROW = 1e-28


class GramFactor:
    """The factor of the Gram matrix G = B_A B_A^T (m x m, SPD for independent rows) of an
    active set's rows B_A (m, n), made once per active set and applied by :meth:`solve`
    in every application of the projector P = I - B_A^T G^-1 B_A.

    G is sparse (two rows share entries only when they share a node: pair rows on one
    master facet) and factored by SuperLU in symmetric mode (a minimum-degree ordering of
    G + G^T, diagonal pivots): for SPD G this is a Cholesky factorization up to scaling.
    Rows that are zero (a contact node whose dofs are all clamped) are left out: their
    entries of G^-1 y are 0.  Dependent rows (a node constrained twice along one
    direction) make G singular: :class:`~signorini.errors.ConvergenceError`.
    """

    def __init__(self, G: sp.spmatrix):
        from scipy.sparse.linalg import splu

        G = sp.csc_matrix(G)
        d = G.diagonal()
        self.m = G.shape[0]
        self.live = d > DEAD_ROW * float(np.max(d, initial=0.0))
        self.all_live = bool(self.live.all())
        Gl = G if self.all_live else G[self.live][:, self.live].tocsc()
        try:
            self.lu = splu(Gl, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
        except RuntimeError as exc:  # SuperLU: "Factor is exactly singular"
            raise ConvergenceError(
                f"the active contact rows are dependent (their Gram matrix B_A B_A^T is singular: {exc}); "
                "a node constrained twice along one direction"
            ) from None
        u = np.abs(self.lu.U.diagonal())
        if u.size and u.min() <= 1e-14 * u.max():
            raise ConvergenceError(
                f"the active contact rows are nearly dependent (pivots of B_A B_A^T from {u.min():.3g} to "
                f"{u.max():.3g}); a node constrained twice along one direction"
            )

    def solve(self, y: np.ndarray) -> np.ndarray:
        """G^-1 y for y (m,) (zero on zero rows), shape (m,)."""
        if self.all_live:
            return self.lu.solve(np.asarray(y, dtype=np.float64))
        out = np.zeros(self.m)
        out[self.live] = self.lu.solve(np.asarray(y, dtype=np.float64)[self.live])
        return out


def gram_factor(BA: sp.csr_matrix) -> GramFactor | None:
    """The factor of G = B_A B_A^T (:class:`GramFactor`), or None when the rows of B_A are
    orthonormal (G = I up to :data:`ORTHONORMAL`, zero rows allowed; an empty B_A too):
    the rows of a rigid obstacle, whose projection stays I - B_A^T B_A bit for bit.

    Parameters
    ----------
    BA : (m, n) the active rows of B.
    """
    if BA.shape[0] == 0:
        return None
    BA = sp.csr_matrix(BA)
    G = (BA @ BA.T).tocsr()
    d = G.diagonal()
    off = G - sp.diags(d)
    unit = (np.abs(d - 1.0) <= ORTHONORMAL) | (d == 0.0)
    if unit.all() and not np.any(off.data):
        return None
    return GramFactor(G)


def _projector(BA: sp.csr_matrix, gram: GramFactor | None = None) -> Callable[[np.ndarray], None]:
    """v <- P v in place, P = I - B_A^T G^-1 B_A with G = B_A B_A^T (``gram``: its factor;
    None: orthonormal rows, P = I - B_A^T B_A), on the dofs that B_A touches only.

    Parameters
    ----------
    BA : (m, n) the active rows of B.
    gram : :func:`gram_factor` of BA.
    """
    if BA.shape[0] == 0:
        return _identity
    rows = np.unique(BA.indices)
    Br = BA[:, rows].tocsr()
    BrT = Br.T.tocsr()

    if gram is None:

        def project(v: np.ndarray) -> None:
            v[rows] -= BrT @ (Br @ v[rows])

        return project

    def project_general(v: np.ndarray) -> None:
        v[rows] -= BrT @ gram.solve(Br @ v[rows])

    return project_general


def make_contact_solver(
    K: sp.spmatrix,
    B: sp.csr_matrix,
    gap_scale: float,
    dim: int = 3,
    options: dict[str, Any] | None = None,
    nodes: np.ndarray | None = None,
    cg_friendly: bool = False,
    components: int = 1,
    modes: Callable[[], np.ndarray] | None = None,
    refactorized: bool = False,
) -> ContactSolver:
    """The contact solver for ``options['backend']`` (``auto``: :func:`choose_backend`);
    ``nodes`` (n,) is the mesh node of each row of K (blocks of ``block-jacobi``, the row
    blocks of ``petsc-cg``); ``modes()`` gives the rigid-body motions of the rows (n, k)
    (``petsc-cg`` with ``gamg``: its near-null space);
    ``cg_friendly``: K is mass-dominated and the scheme can use the CG contact solve;
    ``components``: rows of B per contact node (d with friction: B is the frame matrix H);
    ``refactorized``: the run factorizes many operators of K's pattern (:func:`choose_backend`)."""
    opts = solver_options(options)
    backend = opts["backend"]
    traits = backend_traits(backend)
    if components > 1 and not traits.friction:
        direct = ", ".join(e.name for e in BACKENDS if e.traits.friction and e.traits.distributed == traits.distributed)
        raise InputError(f"friction needs the Delassus matrix of a direct backend ({direct}), not {backend}")
    if traits.chooses and opts["condensation"] == "schur":
        if not has_pardiso():
            raise InputError(
                "solver option condensation='schur' needs the pardiso backend, which is not installed "
                "(pip install '.[pardiso]'); use condensation='lazy' or 'full'"
            )
        backend = "pardiso"  # the only backend that computes the Schur complement
    if backend_traits(backend).chooses:
        budget = opts["memory_budget"] or 0.4 * total_memory()
        nc = B.shape[0]
        # the Delassus matrix (nc x nc, dense, at most) must fit beside the factor
        fits = 8.0 * nc * nc < budget
        backend = choose_backend(K.shape[0], dim, budget - 8.0 * nc * nc, cg_friendly, refactorized) if fits else "cg"
        if not backend_traits(backend).friction and components > 1:
            raise InputError(
                f"friction needs the dense Delassus matrix of {nc} x {nc} entries ({8.0 * nc * nc / 2**30:.3g} GiB), "
                "more than the memory budget; raise solver.memory_budget or coarsen the contact boundary"
            )
    traits = backend_traits(backend)

    def condensed() -> CondensedContactSolver:
        """A direct backend's solver (serial, or the petsc factor's)."""
        return CondensedContactSolver(
            K,
            B,
            gap_scale,
            backend,
            opts["condense_budget"],
            opts["lcp_max_iter"],
            opts["condensation"],
            components,
            opts["reproducible"],
        )

    if traits.distributed:
        from ..linalg.petsc.factor import check_options_used, clear_options, set_options

        set_options(opts)
        try:
            if traits.iterative:
                from .distributed_cg import DistributedCGSolver

                pc = opts["preconditioner"]
                why = f"preconditioner={pc}"
                if pc == "auto":  # Jacobi where CG converges in tens of iterations (docs/parallel.md)
                    pc = "jacobi" if cg_friendly else "gamg"
                    dominated = "mass" if cg_friendly else "stiffness"
                    why = f"preconditioner=auto, which took {pc}: the operator is {dominated}-dominated"
                rigid = modes() if modes is not None and pc == "gamg" else None
                nodes = np.arange(K.shape[0]) if nodes is None else nodes
                solver = DistributedCGSolver(
                    K,
                    B,
                    gap_scale,
                    nodes,
                    rigid,
                    pc,
                    opts["rtol"],
                    opts["max_iter"],
                    opts["max_newton"],
                )
                check_options_used(opts, f"petsc-cg's {pc} preconditioner ({why})")
                return solver
            solver = condensed()
            check_options_used(opts)
        finally:
            clear_options(opts)
        return solver
    if traits.iterative:
        return ActiveSetCGSolver(
            K,
            B,
            gap_scale,
            opts.get("preconditioner", "jacobi"),
            opts.get("rtol", 1e-12),
            opts.get("max_iter", 2000),
            opts.get("max_newton", 30),
            nodes,
            opts.get("spmv_threads", 0),
            opts["spmv"],
        )
    return condensed()

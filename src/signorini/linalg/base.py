"""Linear solvers for the SPD operator K = c_M M + c_S S, behind one interface.

A *direct* backend is a :class:`Factor` subclass: constructed from K (the
factorization, done once per run and operator), it provides ``solve(b)`` for a vector
or a matrix of right-hand sides, ``name``, ``nbytes`` (factor size) and counts its
right-hand sides in ``solves``.  The *iterative* backend ``cg`` has no factor: the
contact solver runs projected conjugate gradients with an active set
(:mod:`signorini.contact.solver`).

Backends are entries of :data:`BACKENDS` (name, description, options); a new one is a
module with a :class:`Factor` subclass and one ``BACKENDS.register`` call, imported
lazily by the entry's loader so the default path never needs it.  ``auto`` chooses by
estimated factor size (:func:`choose_backend`).

Solver options (``--solver-option NAME=VALUE``, ``[solver]`` in case files, the
``solver_options`` dict of :func:`~signorini.dynamics.stepping.simulate.simulate`) are the
generic :data:`SOLVER_OPTIONS` plus the chosen backend's own parameters.
"""

from __future__ import annotations

import functools
import importlib
import importlib.util
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp

from ..errors import InputError
from ..parallel import DISTRIBUTED_BACKENDS
from ..registry import Parameter, Registry
from .spmv import SPMV_KINDS


class Factor:
    """Base class of a direct factorization; subclasses implement ``_solve``.

    A backend with ``supports_schur`` also takes ``schur_dofs`` and then provides the
    dense Schur complement ``schur`` of K on those dofs and a solve split into
    ``forward`` / ``backward`` (:class:`~.pardiso.PardisoFactor`).
    """

    name = "factor"
    supports_schur = False

    def __init__(self) -> None:
        self.solves = 0

    @property
    def nbytes(self) -> int:
        return 0

    def release(self) -> None:
        """The factor is no longer of use: a backend may free or keep its resources (petsc keeps its MUMPS
        instance for the next factorization of the same pattern); the others leave it to the garbage collector."""

    def solve(self, b: np.ndarray) -> np.ndarray:
        """K^-1 b for b of shape (n,) or (n, k); counts k right-hand sides."""
        self.solves += 1 if np.ndim(b) == 1 else int(np.shape(b)[1])
        return self._solve(b)

    def _solve(self, b: np.ndarray) -> np.ndarray:  # pragma: no cover - interface
        raise NotImplementedError


#: a released factor holding more than this share of the machine's memory is not kept (its memory matters more
#: than the analysis it would spare)
KEPT_SHARE = 0.05


class KeptAnalyses:
    """Released factors' analyses, by key (a pattern's digest and a mode), for the next factorization of that key.

    A run's Newton tangents share one pattern and replace each other (Newton releases a tangent before it makes the
    next; a tangent kept across levels is released after its successor is made), so one kept analysis serves
    nearly every tangent, and :attr:`most` (1) bounds the memory held: one factor, below :data:`KEPT_SHARE` of the
    machine's memory.  A factorization of another key drops what is kept before it runs.  What is kept is the
    backend's own (a handle, a matrix), never shared with a factor still in use; :func:`clear_kept_analyses` frees
    every pool (the end of a run).
    """

    def __init__(self, most: int = 1):
        self.most = most
        self.entries: list[tuple[tuple, Any]] = []
        POOLS.append(self)

    def take(self, key: tuple) -> Any | None:
        """The analysis kept for ``key``, taken out (None: none); whatever else was kept is dropped."""
        found = next((kept for k, kept in self.entries if k == key), None)
        self.entries.clear()
        return found

    def keep(self, key: tuple, kept: Any, nbytes: int) -> bool:
        """Keep ``kept`` (whose factor holds ``nbytes``) for ``key``, unless it holds more than :data:`KEPT_SHARE`
        of the machine's memory; the oldest beyond :attr:`most` are dropped (freed by the garbage collector)."""
        if nbytes > KEPT_SHARE * total_memory():
            return False
        self.entries.append((key, kept))
        del self.entries[: -self.most]
        return True

    def holds(self, kept: Any) -> bool:
        return any(k is kept for _, k in self.entries)

    def clear(self) -> None:
        self.entries.clear()

    def __len__(self) -> int:
        return len(self.entries)


#: every :class:`KeptAnalyses` (one per backend)
POOLS: list[KeptAnalyses] = []


def clear_kept_analyses() -> None:
    """Free the analyses every backend keeps (a run that ends: the next one need not hold them)."""
    for pool in POOLS:
        pool.clear()


#: optional modules installed but failing to import: name -> the reason ("OSError: ...")
IMPORT_FAILURES: dict[str, str] = {}


@functools.cache
def module_loads(name: str) -> bool:
    """Whether the optional module ``name`` is installed and imports (a broken install,
    e.g. MKL libraries not found, counts as absent, and its reason is kept in
    :data:`IMPORT_FAILURES`: run summaries and tips name it)."""
    if importlib.util.find_spec(name.split(".")[0]) is None:
        return False
    try:
        importlib.import_module(name)
    except Exception as exc:  # noqa: BLE001 - any failure of a third-party import: absent, with its reason
        IMPORT_FAILURES[name] = f"{type(exc).__name__}: {str(exc)[:200]}"
        return False
    IMPORT_FAILURES.pop(name, None)
    return True


def has_pardiso() -> bool:
    """Whether pypardiso is installed and loads (its MKL libraries found)."""
    from .mkl import mkl_path_hint

    with mkl_path_hint():  # spares pypardiso's search of the installation tree (0.5 s)
        return module_loads("pypardiso")


def has_cholmod() -> bool:
    """Whether cvxopt (with its CHOLMOD module) is installed and loads."""
    return module_loads("cvxopt.cholmod")


#: assumed when the machine's memory cannot be read (reported as ``total_memory_assumed``)
ASSUMED_MEMORY = 8 * 2**30


def memory_info() -> tuple[int, str]:
    """(bytes this process may use, where the figure comes from).

    The physical memory (``sysconf``), lowered to the cgroup limit when the process runs
    in a container with one (``/sys/fs/cgroup/memory.max``, cgroup v2); ``ASSUMED_MEMORY``
    with the source ``"assumed"`` when neither can be read.
    """
    try:
        phys, source = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"), "sysconf"
    except (ValueError, OSError, AttributeError):
        phys, source = ASSUMED_MEMORY, "assumed"
    try:
        with open("/sys/fs/cgroup/memory.max") as fh:
            text = fh.read().strip()
        if text.isdigit() and 0 < int(text) < phys:
            return int(text), "cgroup"
    except OSError:
        pass
    return phys, source


def total_memory() -> int:
    """Memory this process may use [bytes] (:func:`memory_info`)."""
    return memory_info()[0]


PRECONDITIONERS = Registry("preconditioner")
PRECONDITIONERS.register(
    "jacobi", ".krylov:JacobiPreconditioner", "diagonal scaling (default: K = a M + S is close to a M when dt ~ h)"
)
PRECONDITIONERS.register(
    "block-jacobi", ".krylov:BlockJacobiPreconditioner", "inverse of the d x d diagonal block of each mesh node"
)
PRECONDITIONERS.register("amg", ".krylov:AMGPreconditioner", "smoothed-aggregation AMG (pyamg, extra 'amg')")

CG_PARAMETERS = (
    Parameter("preconditioner", "jacobi", "preconditioner of CG (a name of PRECONDITIONERS)", str),
    Parameter("rtol", 1e-12, "relative residual tolerance of CG", float, 0.0, 1.0, open_low=True, open_high=True),
    Parameter("max_iter", 2000, "CG iterations per solve", int, 1),
    Parameter("max_newton", 30, "active-set (semismooth Newton) iterations per step", int, 1),
    Parameter("spmv_threads", 0, "threads of the products K @ x in CG (0: one per usable core; 1: not split)", int, 0),
)

#: the node order of a distributed run (:mod:`signorini.fem.node_order`)
NODE_ORDER = Parameter(
    "node_order",
    "auto",
    "petsc and petsc-cg only: the node numbers whose even split gives each rank its rows: mesh (the mesh's own), "
    "morton (the Z-order "
    "curve of the coordinates: compact pieces per rank); auto: morton unless the mesh is a generated grid; the "
    "results are written in the mesh's own order",
    str,
    choices=("auto", "mesh", "morton"),
)


@dataclass(frozen=True)
class BackendTraits:
    """What a backend supports, read by the automatic choice and by every refusal that concerns
    it (adding a backend is adding one entry of :data:`BACKENDS` with its traits).

    ``factor``: a direct factorization (the entry's object is its :class:`Factor` class);
    ``iterative``: CG, no factor; ``distributed``: runs on the ranks of mpiexec;
    ``friction``: gives the Delassus matrix that friction needs; ``schur``: can compute the
    Schur complement on the contact dofs; ``mixed_meshes``: several cell types;
    ``chooses``: picks another backend (``auto``); ``finite_strain``: factorizes the tangent of
    every Newton iterate of a finite-strain step (a direct factor, serial or petsc's); ``fallback``: always
    there but slow on large 3D systems (a run's summary then names the faster factors)."""

    factor: bool = False
    iterative: bool = False
    distributed: bool = False
    friction: bool = True
    schur: bool = False
    mixed_meshes: bool = True
    chooses: bool = False
    finite_strain: bool = True
    fallback: bool = False


BACKENDS = Registry("linear solver backend")
BACKENDS.register(
    "auto",
    None,
    "in 3D from about 4k dofs pardiso, else cholmod (a core dependency where cvxopt has wheels); cholmod for "
    "finite strain in 3D below that (its ordering kept between the tangents); else superlu below 30k dofs; "
    "else, in 3D, cg when the operator is mass-dominated (and the scheme allows it), else superlu; cg when no "
    "factor fits memory_budget",
    (),
    CG_PARAMETERS,
    BackendTraits(chooses=True),
)
BACKENDS.register(
    "superlu",
    ".superlu:SuperLUFactor",
    "scipy SuperLU, symmetric mode, nested dissection on large 3D systems (always available)",
    traits=BackendTraits(factor=True, fallback=True),
)
BACKENDS.register(
    "pardiso",
    ".pardiso:PardisoFactor",
    "MKL Pardiso via pypardiso (extra 'pardiso'), nested dissection, SPD",
    traits=BackendTraits(factor=True, schur=True),
)
BACKENDS.register(
    "cholmod",
    ".cholmod:CholmodFactor",
    "supernodal Cholesky, CHOLMOD via cvxopt (core where it has wheels, else extra 'cholmod'), nested "
    "dissection (METIS with pymetis: core on Linux x86-64 and macOS, else extra 'metis')",
    traits=BackendTraits(factor=True),
)
BACKENDS.register(
    "petsc",
    ".petsc.factor:PetscFactor",
    "parallel MUMPS Cholesky through PETSc on the ranks of mpiexec (extra 'mpi', scripts/mpi-env.sh); "
    "options petsc.NAME=VALUE pass through as -signorini_NAME",
    (),
    (NODE_ORDER,),
    BackendTraits(factor=True, distributed=True, mixed_meshes=False),
)
BACKENDS.register(
    "cg",
    None,
    "no factor: projected CG with an active-set contact solve",
    (),
    CG_PARAMETERS,
    BackendTraits(iterative=True, friction=False, finite_strain=False),
)
PETSC_CG_PARAMETERS = (
    Parameter(
        "preconditioner",
        "auto",
        "preconditioner of PETSc's CG: jacobi, gamg (algebraic multigrid, rigid-body near-null space); auto: "
        "jacobi when the operator is mass-dominated (as auto picks cg), else gamg",
        str,
        choices=("auto", "jacobi", "gamg"),
    ),
    *CG_PARAMETERS[1:4],
    NODE_ORDER,
)
BACKENDS.register(
    "petsc-cg",
    None,
    "no factor: PETSc's projected CG on the ranks of mpiexec under the active-set contact solve (extra 'mpi', "
    "scripts/mpi-env.sh); options petsc.NAME=VALUE pass through to its preconditioner as -signorini_NAME",
    (),
    PETSC_CG_PARAMETERS,
    BackendTraits(iterative=True, distributed=True, friction=False, mixed_meshes=False, finite_strain=False),
)


SOLVER_OPTIONS = (
    Parameter("backend", "auto", "linear solver backend", str, choices=tuple(BACKENDS.names(aliases=False))),
    Parameter("memory_budget", 0.0, "bytes allowed for a factor (0: 40% of the RAM)", float, 0.0),
    Parameter("lcp_max_iter", 50, "primal-dual active-set iterations per contact solve (direct backends)", int, 1),
    Parameter(
        "reproducible",
        False,
        "pardiso: MKL's conditional numerical reproducibility, the same bits from run to run (its parallel "
        "factorization otherwise differs at round-off); its solves about 2x slower (docs/performance.md); "
        "the other backends always are",
        bool,
    ),
    Parameter(
        "condense_budget",
        2e9,
        "bytes allowed for the dense contact matrices: the computed columns of Z = K^-1 B^T (lazy, full), "
        "the Schur complement and W (schur)",
        float,
        0.0,
    ),
    Parameter(
        "condensation",
        "auto",
        "Delassus matrix (direct backends): schur (Schur complement of K on the contact dofs from the "
        "factorization; pardiso only), lazy (a node's column when it first nears contact), full (every column at "
        "set-up); auto: schur with pardiso and at least 512 contact nodes when its dense matrices fit in "
        "condense_budget, else lazy",
        str,
        choices=("auto", "lazy", "full", "schur"),
    ),
    Parameter(
        "spmv",
        "auto",
        "sparse matrix-vector products (CG, a step's right-hand side and energies): scipy (rows split over "
        "threads), mkl (MKL's sparse BLAS, extra 'pardiso'); auto: mkl when present",
        str,
        choices=SPMV_KINDS,
    ),
    Parameter(
        "untagged_contact",
        "warn",
        "boundary nodes outside the contact tag that enter the obstacle: warn (in summary.json and on stderr) or "
        "fail (the run stops with status failed, exit 3, keeping the levels computed)",
        str,
        choices=("warn", "fail"),
    ),
    Parameter(
        "rotation_limit",
        0.05,
        "linear model (small strains), 2D and 3D: the largest mean rotation of a cell [rad], |axial(skew grad u)|, "
        "within its range; the first level above it warns once (summary.json and stderr) naming the cell, the "
        'rotation, the time and model = "neo-hookean" (a linear model takes a rotation for a stretch of about '
        "rotation^2 / 2 and does not keep a spin); summary.json rotation_max, rotation_cell and rotation_time",
        float,
        0.0,
        open_low=True,
    ),
    Parameter(
        "energy_check",
        "warn",
        "the scheme's energy identity (E^{n+1} - E^n equals the work and dissipation it predicts), checked at every "
        "step: a residual above 1e-6 of the run's largest energy (operators too ill-conditioned for double "
        "precision: a unit mismatch, stiffnesses far apart) warns (summary.json and stderr) or, with fail, stops "
        "the run (status failed, exit 3, keeping the levels computed)",
        str,
        choices=("warn", "fail"),
    ),
    Parameter(
        "pairing",
        "small-sliding",
        "contact pairs: small-sliding (a slave node whose projection leaves its master facet is re-paired to the "
        "facet it then faces, its row of B and Delassus column recomputed) or frozen (the pairing "
        "of t = 0 for the whole run)",
        str,
        choices=("small-sliding", "frozen"),
    ),
    Parameter(
        "newton_tol",
        1e-10,
        "finite strain ([material] model not linear): a step's Newton iterations stop when the force residual on "
        "the free dofs is below newton_tol times the largest of the step's forces (inertia, internal force, loads, "
        "contact) plus its own round-off",
        float,
        1e-15,
        1e-2,
    ),
    Parameter(
        "newton_max",
        25,
        "finite strain: the most Newton iterations of a step; a step that has not converged then fails (or is "
        "rejected and halved under the energy control)",
        int,
        1,
        1000,
    ),
    Parameter(
        "tangent",
        "modified",
        "finite strain: modified (the default: the step's first tangent kept while the residual falls at least "
        "tenfold per iteration, refactorized where it does not; 0.6-0.7 of full's time, docs/finite_strain.md) "
        "or full (the tangent K(U) of every Newton iterate, factorized each time)",
        str,
        choices=("full", "modified"),
    ),
    Parameter(
        "acceleration",
        "anderson",
        "finite strain: anderson (the default: the Newton iterates of a kept operator, the scheme's own or a kept "
        "tangent, mixed with the last five by Anderson's method while the contact rows held stay the same and no "
        "friction acts: a Krylov method preconditioned by the factorized operator, one solve per iteration as before; "
        "docs/finite_strain.md) or none (the plain iterates)",
        str,
        choices=("anderson", "none"),
    ),
    Parameter(
        "momentum_projection",
        True,
        "energy-momentum with finite strain: after each step the velocities of the nodes with mass get the rigid "
        "motion (closest in M's norm, one per group of bodies in contact) that gives back the linear and angular "
        "momentum the massless contact rows and the contact pairs' forces took; the bodies' momenta then change "
        "only by the impulses from outside (obstacles, loads); off: the scheme's own velocities "
        "(docs/finite_strain.md)",
        bool,
    ),
    Parameter(
        "loop_blas_threads",
        1,
        "threads of the dense BLAS inside the time loop (0: the library's default); one is fastest for the "
        "small dense contact blocks of a step (docs/performance.md)",
        int,
        0,
    ),
)


def solver_options(given: Mapping[str, Any] | None = None, where: str = "solver") -> dict[str, Any]:
    """Validated solver options: generic ones plus the chosen backend's parameters."""
    given = dict(given or {})
    generic = {p.name: p for p in SOLVER_OPTIONS}
    backend = generic["backend"].convert(given.get("backend", "auto"), where)
    entry = BACKENDS.get(backend)
    own = {p.name: p for p in entry.parameters}
    out = {p.name: p.default for p in SOLVER_OPTIONS}
    out.update({p.name: p.default for p in entry.parameters})
    for k, v in given.items():
        if k.startswith("petsc.") and backend in DISTRIBUTED_BACKENDS:  # PETSc's own options, checked by PETSc
            out[k] = str(v)
            continue
        p = generic.get(k) or own.get(k)
        if p is None and k.startswith("petsc."):
            raise InputError(
                f"solver option {k!r} is a PETSc option: it needs backend 'petsc' or 'petsc-cg', not {backend!r}"
            )
        if p is None:
            allowed = ", ".join(sorted(set(generic) | set(own)))
            raise InputError(f"unknown solver option {k!r} for backend {backend!r}; allowed: {allowed}")
        out[k] = p.convert(v, where)
    if "preconditioner" in out and backend not in DISTRIBUTED_BACKENDS:
        try:
            out["preconditioner"] = PRECONDITIONERS.resolve(out["preconditioner"])
        except InputError as exc:
            raise InputError(f"'{where}.preconditioner': {exc}") from None
    out["backend"] = backend
    return out


def estimate_factor_bytes(n: int, dim: int, backend: str) -> float:
    """Rough size of a sparse factor of a P1/Q1 elasticity matrix with n dofs [bytes].

    Fitted on this project's bars (values + indices, 12 bytes per entry): in 3D, the
    Cholesky factors in nested-dissection order (Pardiso, CHOLMOD) like 16 n^(4/3)
    entries; SuperLU (L and U) below 15k dofs with MMD like n^1.9 (0.59e6 entries at
    3e3 dofs), above with its nested dissection like n^1.46 (16.4e6 at 1.9e4 dofs,
    290e6 at 1.4e5 dofs, built-in ordering; METIS fills less); all like ~40 n log n in 2D.
    """
    if dim <= 1:
        return 12.0 * 3 * n
    if dim == 2:
        return 12.0 * 40 * float(n) * max(math.log2(max(float(n), 1.0)), 1.0)
    if backend in ("pardiso", "cholmod"):
        return 12.0 * 16 * n ** (4 / 3)
    if n < 15_000:
        return 12.0 * 0.5925e6 * (n / 3000.0) ** 1.875
    return 12.0 * 16.4e6 * (n / 19440.0) ** 1.46


SMALL = 30_000  # below this many dofs (2D; 3D below about 4k dofs) SuperLU factors about as fast as the others
#: ``auto`` counts K = c_M M + c_S S as mass-dominated when c_S S_ii <= CG_FRIENDLY_RATIO
#: c_M M_ii on every free dof with mass: Jacobi-CG then needs 20-30 iterations per solve
#: (the bars with dt = h/2: ratio <= 0.85); the Hertz ball, with small cells at the pole
#: and dt = t_c/(25 n), has ratios up to 2,500 and needs about 290 (docs/design.md)
CG_FRIENDLY_RATIO = 4.0
#: the Cholesky backends ``auto`` considers, in this order (docs/performance.md, "A fast 3D
#: factor on the plain install": on the 34k-dof Hertz ball and the 35k-dof whole-skin bracket
#: their whole runs, set-up, steps and lazy Delassus columns, are within 6% of each other,
#: Pardiso's set-up being the more sensitive to a loaded machine; Pardiso alone also has the
#: Schur condensation)
CHOLESKY = ("pardiso", "cholmod")


def installed(backend: str) -> bool:
    """Whether the library of the Cholesky backend ``backend`` is installed and loads
    (:func:`has_pardiso`, :func:`has_cholmod`, looked up when called)."""
    return {"pardiso": has_pardiso, "cholmod": has_cholmod}[backend]()


def choose_backend(
    n: int, dim: int, budget: float | None = None, cg_friendly: bool = False, refactorized: bool = False
) -> str:
    """Direct solver when its estimated factor fits in ``budget`` bytes, else ``cg``.

    By estimated cost: the size of the factor (:func:`estimate_factor_bytes`) is the cost
    of every step's two triangular solves and the measure of its set-up.  A Cholesky
    backend of :data:`CHOLESKY` (Pardiso, then CHOLMOD), when installed, is chosen as soon
    as its nested-dissection factor is estimated smaller than SuperLU's: in 3D from about
    4,000 dofs (bar3d n = 8, 19,683 dofs: Pardiso 104 MB against 200 MB, set-up 1.2 s
    against 3.4 s; the Hertz ball at 13.5k dofs: CHOLMOD with METIS 0.99 s against 2.6 s,
    at 35.6k dofs 2.6 s against 40 s; docs/performance.md).  cvxopt (CHOLMOD) and pymetis
    (METIS) are core dependencies each where it has wheels (pyproject.toml), so the plain
    install has CHOLMOD on Linux x86-64/aarch64, Windows x86-64 and macOS up to Python 3.12.
    ``refactorized``: the run factorizes many operators of one pattern (finite strain's Newton
    tangents): in 3D, CHOLMOD at any size below Pardiso's, since its ordering is kept by pattern
    (:func:`~.ordering.fill_reducing_order`) and a tangent then costs its analysis and numeric factorization
    (bar3d n = 4, 3,075 dofs: a Neo-Hookean step 0.82 of SuperLU's, docs/performance.md).
    Else SuperLU for small systems (< 30k dofs: it has no start-up, and 2D
    factors are alike), then a Cholesky backend.  Without one, a large 3D system goes to
    CG when ``cg_friendly`` (the operator is mass-dominated, see :data:`CG_FRIENDLY_RATIO`,
    and the scheme can use the CG contact solve): SuperLU's LU of a 3D operator is slow and
    large (bar3d n = 16: 52 s, 3.5 GB, against 1.5 s of set-up and 0.6 GB for CG, whose
    steps are also faster).  Then SuperLU, and CG when no factor fits.
    """
    budget = 0.4 * total_memory() if not budget else budget
    superlu = estimate_factor_bytes(n, dim, "superlu")
    for name in CHOLESKY:
        size = estimate_factor_bytes(n, dim, name)
        # installed() last: it imports the library, which a small run must not load
        if size <= budget and size < superlu and installed(name):
            return name
    if refactorized and dim == 3 and estimate_factor_bytes(n, dim, "cholmod") <= budget and installed("cholmod"):
        return "cholmod"
    if n < SMALL and superlu <= budget:
        return "superlu"
    for name in CHOLESKY:
        if estimate_factor_bytes(n, dim, name) <= budget and installed(name):
            return name
    if cg_friendly and dim == 3:
        return "cg"
    if superlu <= budget:
        return "superlu"
    return "cg"


def backend_traits(backend: str) -> BackendTraits:
    """The :class:`BackendTraits` of a registered backend (or of an alias)."""
    return BACKENDS.get(backend).traits


def factor_class(backend: str) -> type[Factor]:
    """The :class:`Factor` subclass of the direct backend ``backend`` (imported now)."""
    entry = BACKENDS.get(backend)
    if not isinstance(entry.obj, str):
        direct = [e.name for e in BACKENDS if isinstance(e.obj, str)]
        raise InputError(f"backend {backend!r} is not a direct solver; allowed: {', '.join(direct)}")
    module, cls = entry.obj.split(":")
    return getattr(importlib.import_module(module, __package__), cls)


def factorize(
    K: sp.spmatrix, backend: str = "superlu", schur_dofs: np.ndarray | None = None, reproducible: bool = False
) -> Factor:
    """Factorize the SPD matrix ``K`` once with the direct backend ``backend``; with
    ``schur_dofs`` (a backend with ``supports_schur``) also its Schur complement there;
    ``reproducible``: a backend whose parallel factorization is not reproducible by default
    (``supports_reproducible``: pardiso) in its reproducible mode (the others always are)."""
    cls = factor_class(backend)
    kw: dict[str, Any] = {"reproducible": True} if reproducible and getattr(cls, "supports_reproducible", False) else {}
    if schur_dofs is None:
        return cls(K, **kw)
    if not cls.supports_schur:
        raise InputError(f"backend {backend!r} cannot compute a Schur complement; use pardiso")
    return cls(K, schur_dofs=schur_dofs, **kw)

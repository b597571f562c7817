"""Size of a run before it starts: steps and a memory estimate, checked against limits.

The estimate is deliberately simple and documented (docs/case-files.md, "Run size"):

* set-up: ``BASE + TRIPLET_BYTES * n_cells * (nodes_per_cell * dim)^2`` -- the element
  matrices of assembly dominate; fitted on this project's bars (2D Q1 n = 32, 64 and
  3D Q1 n = 8, 12, peak RSS with the CG backend: 24 to 40 bytes per triplet);
* factor: the sparse factor the ``auto`` backend would build
  (:func:`~signorini.linalg.base.estimate_factor_bytes` of the backend
  :func:`~signorini.linalg.base.choose_backend` picks; 0 when it picks CG, which keeps a
  few vectors only).  On a 3D box with SuperLU this was the largest term (0.55 GB of a
  0.67 GB peak);
* history: ``8 * (levels) * (2 * n_contact + 11)`` bytes (gaps and multipliers of every
  contact node at every level, plus the 11 scalar series: time, the energy recorder's
  six, residual, impulse, active-set size and iterations), exact up to the Python
  overhead;
* kept fields (``kept_fields=True``, studies and ``compare``, which measure errors from
  every level): ``16 * levels * dofs`` bytes, U and V of every level in float64, counted
  twice while the run is in progress (the recorder's list of levels is stacked into one
  array at the end of the run, a momentary copy).

``compare`` runs a matrix of such runs (:func:`estimate_compare`): its peak is the
``workers`` largest runs in progress at once (each with set-up, history and kept
fields) plus the fields the parent holds until the errors against a 2D/3D reference are
measured (every returned run's, the reference's included).  In a serial compare the run
in progress is counted in both terms: an upper estimate by one run's fields.

On P MPI ranks (backends ``petsc``, ``petsc-cg``; docs/parallel.md) every rank holds its
own copy of the mesh, the state and the history, and assembles S, M and K by rows (the
cells near its own nodes), and the factor is spread over the ranks.  The estimate is for
this machine, with the L ranks that run on it (the process manager's local count,
``MPI_LOCALNRANKS`` or ``OMPI_COMM_WORLD_LOCAL_SIZE``, else P): L times the history, the
base and 1/P of the assembly's triplets, plus L/P of MUMPS's factor (estimated as a
nested-dissection Cholesky, as Pardiso's; measured 4.0 GB on bar3d n = 24 against 6.6 GB
estimated) and of the lazy Delassus columns Z = K^-1 B^T (8 n x contact nodes bytes, at
most ``condense_budget`` per rank); nothing of either for ``petsc-cg``.  The kept fields are rank 0's only.

A run whose number of steps or estimated memory exceeds the limits is refused with the
estimate unless it is confirmed (``--yes`` or ``[limits] yes = true``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from ...errors import InputError
from ...linalg.base import BACKENDS, backend_traits, choose_backend, estimate_factor_bytes, total_memory

BASE_BYTES = 80e6
TRIPLET_BYTES = 32.0
SCALAR_SERIES = 11  # per-level scalar series of a History (see the module docstring)
#: the default solver option ``condense_budget`` [bytes per rank]: the Z rows a rank keeps
COLUMNS_BUDGET = 2e9
FIELD_BYTES = 16.0  # U and V of one dof at one level (float64), kept for error computation
DEFAULT_MAX_STEPS = 1_000_000


def default_max_memory() -> float:
    """80% of the machine's physical memory [bytes]."""
    return 0.8 * total_memory()


@dataclass(frozen=True)
class RunEstimate:
    """Steps and estimated peak memory [bytes] of a run."""

    steps: int
    dofs: int
    contact_nodes: int
    setup_bytes: float
    history_bytes: float
    fields_bytes: float = 0.0  # U and V of every level, when kept (studies, compare)
    factor_bytes: float = 0.0  # the sparse factor of the run's backend (``auto``: the one it would choose)
    ranks: int = 1  # MPI ranks of the run
    local_ranks: int = 1  # of them on this machine, each with its own set-up and history
    columns_bytes: float = 0.0  # petsc: the Delassus columns Z, spread over the ranks as the factor
    what: ClassVar[str] = "run"

    @property
    def total_bytes(self) -> float:
        """Peak on this machine while the run is in progress (kept fields twice: stacked at
        the end; per local rank its history, the base and 1/P of the assembly; the local
        share of the factor)."""
        share = self.local_ranks / self.ranks
        return (
            self.local_ranks * (self.rank_setup_bytes + self.history_bytes)
            + share * (self.factor_bytes + self.columns_bytes)
            + (2 * self.fields_bytes)
        )

    @property
    def rank_setup_bytes(self) -> float:
        """The set-up of one rank: the base and its share of the assembly (each rank
        assembles S and M from the cells near its own nodes, docs/parallel.md)."""
        base = min(BASE_BYTES, self.setup_bytes)
        return base + (self.setup_bytes - base) / self.ranks

    def describe(self) -> str:
        fields = f", kept fields {_gib(self.fields_bytes)} GiB" if self.fields_bytes else ""
        columns = f", Delassus columns {_gib(self.columns_bytes)} GiB" if self.columns_bytes else ""
        on = ""
        if self.ranks > 1:
            on = (
                f" on this machine for {self.local_ranks} of {self.ranks} MPI ranks, each with its own history and "
                f"1/{self.ranks} of the set-up{', the factor spread over the ranks' if self.factor_bytes else ''}"
            )
        return (
            f"{self.steps:,} steps, {self.dofs:,} dofs, {self.contact_nodes:,} contact nodes, "
            f"estimated memory {_gib(self.total_bytes)} GiB{on} (set-up {_gib(self.setup_bytes)} GiB, "
            f"factor {_gib(self.factor_bytes)} GiB{columns}, history {_gib(self.history_bytes)} GiB{fields})"
        )


def _gib(b: float) -> str:
    return f"{b / 2**30:.3g}"


def estimate_run(
    n_nodes: int,
    n_cells: int,
    nodes_per_cell: int,
    dim: int,
    n_contact: int,
    steps: int,
    kept_fields: bool = False,
    backend: str = "auto",
    ranks: tuple[int, int] = (1, 1),
    condense_budget: float = COLUMNS_BUDGET,
) -> RunEstimate:
    """The estimate of the module docstring from mesh counts, without building anything;
    ``ranks`` = (P, L): the run's MPI ranks and those on this machine (:func:`~signorini.parallel.local_ranks`);
    ``condense_budget``: the run's solver option [bytes per rank], which bounds petsc's Z rows."""
    k = nodes_per_cell * dim
    setup = BASE_BYTES + TRIPLET_BYTES * float(n_cells) * k * k
    history = 8.0 * (steps + 1) * (2 * n_contact + SCALAR_SERIES)
    fields = FIELD_BYTES * (steps + 1) * n_nodes * dim if kept_fields else 0.0
    n = int(n_nodes * dim)
    if backend not in BACKENDS:  # a misspelling, refused by the options' validation with its own message
        backend = "auto"
    backend = choose_backend(n, dim) if backend_traits(backend).chooses else backend
    traits = backend_traits(backend)
    if traits.iterative:
        factor = 0.0
    else:  # MUMPS (petsc): a nested-dissection Cholesky, as Pardiso's
        factor = estimate_factor_bytes(n, dim, "pardiso" if traits.distributed else backend)
    if not traits.distributed:
        ranks = (1, 1)
    P, L = max(1, int(ranks[0])), max(1, min(int(ranks[1]), int(ranks[0])))
    # petsc: the lazy Delassus columns Z = K^-1 B^T (n x contact nodes at most), each rank
    # its rows, up to condense_budget per rank (2.1 GiB of bar3d n = 24's 9.7 by default)
    columns = min(8.0 * n * n_contact, float(condense_budget) * P) if traits.distributed and traits.factor else 0.0
    return RunEstimate(int(steps), n, int(n_contact), setup, history, fields, factor, P, L, columns)


@dataclass(frozen=True)
class CompareEstimate:
    """Peak memory [bytes] of a matrix of runs (``signorini compare``), see the module docstring.

    ``steps`` is the largest run's number of steps (the per-run step limit applies to it).
    """

    runs: int
    workers: int
    steps: int
    dofs: int
    running_bytes: float  # the ``workers`` largest runs in progress at once
    held_bytes: float  # fields the parent holds for the errors (2D/3D)
    kept_fields_bytes: float  # all kept fields, of every run (part of the two terms above)
    what: ClassVar[str] = "comparison"

    @property
    def total_bytes(self) -> float:
        return self.running_bytes + self.held_bytes

    def describe(self) -> str:
        return (
            f"{self.runs} runs in {self.workers} process(es), the largest {self.steps:,} steps and {self.dofs:,} dofs, "
            f"estimated memory {_gib(self.total_bytes)} GiB (runs in progress {_gib(self.running_bytes)} GiB, "
            f"fields held for the errors {_gib(self.held_bytes)} GiB; kept fields of all runs "
            f"{_gib(self.kept_fields_bytes)} GiB)"
        )


def estimate_compare(runs: list[RunEstimate], returned: list[bool], workers: int) -> CompareEstimate:
    """Peak of ``runs`` executed ``workers`` at a time; ``returned[i]``: run i's fields go back
    to the parent and stay there until the errors are measured (2D/3D)."""
    if not runs:
        raise InputError("nothing to run")
    w = max(1, min(int(workers), len(runs)))
    largest = sorted((r.total_bytes for r in runs), reverse=True)[:w]
    held = sum(r.fields_bytes for r, back in zip(runs, returned, strict=True) if back)
    return CompareEstimate(
        len(runs),
        w,
        max(r.steps for r in runs),
        max(r.dofs for r in runs),
        float(sum(largest)),
        float(held),
        float(sum(r.fields_bytes for r in runs)),
    )


def check_run_size(
    est: RunEstimate | CompareEstimate,
    max_steps: int | None = None,
    max_memory: float | None = None,
    confirmed: bool = False,
) -> None:
    """Raise :class:`InputError` with the estimate when a limit is exceeded and not confirmed."""
    if confirmed:
        return
    max_steps = DEFAULT_MAX_STEPS if max_steps is None else max_steps
    max_memory = default_max_memory() if max_memory is None else max_memory
    over = []
    if est.steps > max_steps:
        over.append(f"more than --max-steps {max_steps:,} steps")
    if est.total_bytes > max_memory:
        over.append(f"more than --max-memory {max_memory / 2**30:.3g} GiB")
    if over:
        raise InputError(
            f"this {est.what} is large: {est.describe()}; that is {' and '.join(over)}. "
            "Pass --yes (case file: [limits] yes = true) to run it anyway, or raise the limit"
        )

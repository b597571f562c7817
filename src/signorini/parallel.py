"""The ranks of a run: one process (serial backends) or the ranks of ``mpiexec`` (``petsc``).

The distributed backend keeps the scheme contract unchanged by replicating what is
small or cheap on every rank (the mesh, the state vectors, the Delassus matrix, the
contact law) and distributing what is costly (the factorization and its solves,
:mod:`signorini.linalg.petsc.factor`); every rank then computes the same numbers in
the same order and takes the same branches.  What can still differ between ranks are
the signals that reach them and their timings: the time loop agrees on a stop with
:meth:`Comm.max` of the signal numbers once per step, and only rank 0 writes
(:attr:`Comm.is_root`); rank 0's own failures end every rank (:func:`mark_unshared`).

:func:`launched` reads the process manager's environment (MPICH/hydra ``PMI_RANK``,
Open MPI ``OMPI_COMM_WORLD_RANK``) without importing MPI, so that a serial run never
loads it and a command started by ``mpiexec -n P`` with P > 1 on a serial backend is
refused before it writes anything (P copies would race for one result directory).
"""

from __future__ import annotations

import os
import resource
import signal
import threading
from typing import Any

from . import signals as _signals
from .errors import InputError

INSTALL_HINT = (
    "the backends petsc and petsc-cg need petsc4py and mpi4py (Python >= 3.12): run `bash scripts/mpi-env.sh` from the "
    "repository root, then use .venv-mpi/bin/mpiexec -n P .venv-mpi/bin/signorini run ... --backend petsc"
)
#: the backends that run on the ranks of ``mpiexec`` (the others are one process)
DISTRIBUTED_BACKENDS = ("petsc", "petsc-cg")
_RANK_VARS = (("PMI_RANK", "PMI_SIZE"), ("OMPI_COMM_WORLD_RANK", "OMPI_COMM_WORLD_SIZE"))


def launched() -> tuple[int, int]:
    """(rank, size) given by the process manager that started this process, (0, 1) without one."""
    for r, s in _RANK_VARS:
        if r in os.environ and s in os.environ:
            try:
                return int(os.environ[r]), int(os.environ[s])
            except ValueError:
                return 0, 1
    return 0, 1


def local_ranks() -> tuple[int, int]:
    """(P, L): the ranks of the run and those on this machine (hydra's ``MPI_LOCALNRANKS``,
    Open MPI's ``OMPI_COMM_WORLD_LOCAL_SIZE``; P when neither says), (1, 1) without mpiexec."""
    size = launched()[1]
    for var in ("MPI_LOCALNRANKS", "OMPI_COMM_WORLD_LOCAL_SIZE"):
        try:
            return size, max(1, min(int(os.environ[var]), size))
        except (KeyError, ValueError):
            continue
    return size, size


def is_root() -> bool:
    """Whether this process prints and writes (rank 0, or not started by mpiexec)."""
    return launched()[0] == 0


#: set when this process ends in a way the other ranks may not share (a failure of rank 0's
#: own writing during the loop, a Ctrl-C during the set-up): the command line then ends
#: every rank with MPI_Abort instead of leaving them waiting in a collective
UNSHARED_END = [False]


def mark_unshared() -> None:
    """Record that this process is leaving on its own (see :data:`UNSHARED_END`)."""
    UNSHARED_END[0] = True


#: whether MPI has started in this process (the first :class:`MPIComm`): until then, on
#: several ranks, the command line defers SIGINT and SIGTERM (``signorini.signals.DEFERRED``),
#: since a rank that left then would leave the others spinning in MPI_Init forever
_STARTED = [False]


def deferring() -> bool:
    """Whether this process is one of several ranks whose MPI has not started yet."""
    return launched()[1] > 1 and not _STARTED[0]


def _interrupt(signum, frame) -> None:
    raise KeyboardInterrupt


class AgreedInterrupt(KeyboardInterrupt):
    """A signal that every rank raises at the same point, after a collective agreed on it: the
    ranks end together, each normally (no MPI_Abort, whose teardown can lose rank 0's line)."""


def _defer(signum, frame) -> None:
    """Several ranks, from MPI's start to the time loop: a rank may be inside a collective
    when the signal comes, so none leaves alone; the signal waits for :func:`agree_deferred`."""
    _signals.DEFERRED.append(int(signum))


def agree_deferred(comm: Comm) -> None:
    """Before the time loop (every rank at the same point, the loop's handlers in place): a
    signal deferred on any rank during the set-up stops every rank (:class:`AgreedInterrupt`)."""
    pending = max(_signals.DEFERRED, default=0)
    del _signals.DEFERRED[:]
    if comm.size > 1 and comm.max(pending):
        raise AgreedInterrupt


def peak_memory_bytes() -> int:
    """Peak resident memory of this process (``getrusage``, kilobytes on Linux) [bytes]."""
    return int(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss) * 1024


class Comm:
    """One process: every collective is the identity."""

    rank = 0
    size = 1

    @property
    def is_root(self) -> bool:
        return self.rank == 0

    def any(self, flag: bool) -> bool:
        """Whether ``flag`` is true on some rank."""
        return bool(flag)

    def max(self, value: int) -> int:
        """The largest ``value`` over the ranks."""
        return value

    def gather(self, value: Any) -> list[Any]:
        """``value`` of every rank, in rank order, on every rank."""
        return [value]

    def bcast(self, value: Any) -> Any:
        """Rank 0's ``value`` on every rank."""
        return value


class MPIComm(Comm):
    """The ranks of ``COMM_WORLD`` (mpi4py)."""

    def __init__(self) -> None:
        try:
            from mpi4py import MPI
        except ImportError as exc:
            raise InputError(f"{INSTALL_HINT} ({type(exc).__name__}: {exc})") from None
        self.MPI = MPI
        self.comm = MPI.COMM_WORLD
        self.rank, self.size = self.comm.rank, self.comm.size
        if not _STARTED[0]:
            _STARTED[0] = True
            self._start()

    def _start(self) -> None:
        """MPI has started (the first MPIComm, at the same point on every rank): the signals
        deferred until now stop every rank together (:class:`AgreedInterrupt`: exit 130,
        nothing written); later ones stay deferred until the time loop (:func:`agree_deferred`)."""
        deferred = list(_signals.DEFERRED)
        got = self.max(max(deferred, default=0))
        if threading.current_thread() is threading.main_thread():
            for s in (signal.SIGINT, signal.SIGTERM):
                if signal.getsignal(s) in _signals.STARTUP_HANDLERS:
                    signal.signal(s, _defer if self.size > 1 else _interrupt)
        if _signals.DEFERRED:  # one before or during the agreement set the start-up alarm
            signal.alarm(0)
        if got:
            del _signals.DEFERRED[:]
            raise AgreedInterrupt

    def any(self, flag: bool) -> bool:
        return bool(self.comm.allreduce(bool(flag), op=self.MPI.LOR))

    def max(self, value: int) -> int:
        return int(self.comm.allreduce(int(value), op=self.MPI.MAX))

    def gather(self, value: Any) -> list[Any]:
        return self.comm.allgather(value)

    def bcast(self, value: Any) -> Any:
        return self.comm.bcast(value, root=0)


SERIAL = Comm()


def run_comm(backend: str) -> Comm:
    """The ranks of a run on ``backend``: all of ``mpiexec``'s for ``petsc`` and ``petsc-cg``,
    else this process.

    A serial backend started as P > 1 ranks is an :class:`InputError` (on every rank)."""
    if backend in DISTRIBUTED_BACKENDS:
        return MPIComm()
    rank, size = launched()
    if size > 1:
        raise InputError(
            f"started as {size} MPI ranks with backend {backend!r}: only backends 'petsc' and 'petsc-cg' run on "
            "several ranks (add --backend petsc or petsc-cg, or run without mpiexec)"
        )
    return SERIAL

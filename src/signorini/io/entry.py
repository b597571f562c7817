"""``signorini`` and ``python -m signorini``: the command line, with signals handled from the start.

A Ctrl-C or SIGTERM that arrives while Python imports numpy, scipy and the package would
otherwise print a traceback (SIGINT) or kill the process without a word (SIGTERM).  The
handlers installed here, before any heavy import, end the process with one line and exit
code 130; nothing has been written at that point.  :func:`signorini.io.cli.main` installs
its own handlers once it runs.  On several MPI ranks a signal is deferred until MPI has
started, where every rank stops together (:data:`DEFERRED`): a rank that left alone
before would leave the others spinning in ``MPI_Init``.
"""

from __future__ import annotations

import os
import signal
import sys

#: the signals that reached one of several MPI ranks before MPI started; main() hands this
#: list to :mod:`signorini.signals` (imported after the handlers are in place)
DEFERRED: list[int] = []

#: a rank that deferred a signal and has not started MPI after this long ends (SIGALRM)
STARTUP_ALARM_SECONDS = 60


def _several_ranks() -> bool:
    """Started by mpiexec as one of several ranks: the process manager's size variables (those
    of :func:`signorini.parallel.launched`), read without importing anything."""
    for var in ("PMI_SIZE", "OMPI_COMM_WORLD_SIZE"):
        value = os.environ.get(var, "")
        if value.isdigit() and int(value) > 1:
            return True
    return False


def _early(signum, frame) -> None:
    if _several_ranks():  # a rank that left alone now would leave the others in MPI_Init forever
        DEFERRED.append(int(signum))
        # and if another rank died before it could defer (still in CPython's start-up), this
        # one may spin in MPI_Init: SIGALRM's default action ends it whatever MPI holds
        # (signorini.parallel cancels the alarm once MPI has started)
        signal.alarm(STARTUP_ALARM_SECONDS)
        return
    try:
        os.write(2, b"signorini: interrupted during start-up; nothing written\n")
    except OSError:
        pass
    os._exit(130)


#: the address space that loading numpy, scipy and their BLAS takes [bytes]: measured 350-400
#: MiB (below it OpenBLAS ends the process itself, exit 1, with its own message)
MIN_ADDRESS_SPACE = 512 * 2**20


def _address_space_too_small() -> str:
    """A one-line message when ``ulimit -v`` leaves less than :data:`MIN_ADDRESS_SPACE`, else ''."""
    try:
        import resource

        soft = resource.getrlimit(resource.RLIMIT_AS)[0]
    except (ImportError, OSError, ValueError):
        return ""
    if soft == resource.RLIM_INFINITY or soft >= MIN_ADDRESS_SPACE:
        return ""
    return (
        f"signorini: error: cannot start: the address-space limit (ulimit -v) is {soft / 2**20:.0f} MiB, "
        f"less than the {MIN_ADDRESS_SPACE / 2**20:.0f} MiB that loading numpy and scipy takes; raise it\n"
    )


def _interrupt(signum, frame) -> None:
    raise KeyboardInterrupt


def _quiet_followers() -> None:
    """Started by mpiexec as a rank other than 0: stdout and stderr go to /dev/null, so that
    every message (argparse's, --help, start-up interrupts, PETSc's own) comes once, from
    rank 0; the ranks compute the same things (docs/parallel.md).  SIGNORINI_TRACEBACK=1
    keeps them, to debug a rank."""
    from ..parallel import launched  # os and resource only: cheap before the handlers

    if launched()[0] == 0 or os.environ.get("SIGNORINI_TRACEBACK"):
        return
    try:
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, 1)
        os.dup2(null, 2)
        os.close(null)
    except OSError:
        pass


def main() -> int:
    """Install the start-up handlers, import the command line and run it.

    After the imports SIGINT and SIGTERM raise KeyboardInterrupt, which the command line
    turns into its own status and message; one that escapes it (while the arguments are
    parsed) ends here with one line and 130.
    """
    for s in (signal.SIGINT, signal.SIGTERM):
        signal.signal(s, _early)
    from .. import signals  # after the handlers: a signal during this import is handled

    signals.DEFERRED = DEFERRED
    signals.STARTUP_HANDLERS.append(_early)
    _quiet_followers()
    short = _address_space_too_small()
    if short:
        try:
            os.write(2, short.encode())
        except OSError:
            pass
        return 4
    try:
        from .cli import main as cli_main
    except (ImportError, OSError, MemoryError) as exc:  # numpy, scipy or a library failed to load
        from ..errors import is_memory_failure

        memory = is_memory_failure(exc)
        why = (
            "out of memory while loading its libraries (a memory or address-space limit: ulimit -v?)"
            if memory
            else f"a library failed to load ({type(exc).__name__}: {exc}); reinstall with pip install ."
        )
        try:
            os.write(2, f"signorini: error: cannot start: {' '.join(why.split())}\n".encode())
        except OSError:
            pass
        return 4 if memory else 1

    if not _several_ranks():  # several: _early defers until MPI starts (signorini.parallel)
        for s in (signal.SIGINT, signal.SIGTERM):
            signal.signal(s, _interrupt)
    try:
        code = cli_main()
    except KeyboardInterrupt:
        try:
            os.write(2, b"signorini: interrupted before the time loop; nothing written\n")
        except OSError:
            pass
        code = 130
    for s in (signal.SIGINT, signal.SIGTERM):  # the exit code is decided: a signal now changes nothing
        signal.signal(s, signal.SIG_IGN)
    return code


if __name__ == "__main__":
    sys.exit(main())

"""The ``signorini`` command line.

Exit codes: 0 success; 2 invalid input (nothing written); 3 numerical failure (a
non-finite value or a solver that did not converge: the levels computed are written,
with ``status = "failed"`` in summary.json); 4 the environment failed (out of memory,
disk full, an I/O error: what could be kept is kept); 130 interrupted by Ctrl-C or
SIGTERM (the levels computed are written, ``status = "interrupted"``); 1 an internal
error (a bug: one line, the traceback with ``SIGNORINI_TRACEBACK=1``).

On several MPI ranks (``mpiexec -n P ... --backend petsc``, docs/parallel.md) the codes are
the same; rank 0 alone prints, and a failure that rank 0 meets alone (its own writing, a
Ctrl-C during the set-up) ends every rank with ``MPI_Abort`` and that code.
"""

from __future__ import annotations

import argparse
import errno
import os
import signal
import sys
import time
import traceback
import warnings

import numpy as np

from ..errors import ConvergenceError, InputError, is_memory_failure
from ..parallel import UNSHARED_END, AgreedInterrupt, deferring, is_root, launched, mark_unshared
from .exit_codes import EXIT_CODES, EXIT_ENVIRONMENT
from .messages import one_line
from .parser import build_parser
from .results_dir import ResultConflict
from .streams import guarded_stdio
from .summary import factorization_tip  # noqa: F401 - used by tests and docs

#: on an interrupt, how long a rank other than 0 waits before MPI_Abort, so that rank 0
#: (which the signal reached too) prints its line first (its abort ends the wait)
ROOT_FIRST_SECONDS = 2.0


def _sigterm(signum, frame):
    raise KeyboardInterrupt


def main(argv: list[str] | None = None) -> int:
    with guarded_stdio():
        parser = build_parser()
        args = parser.parse_args(argv)
        if not getattr(args, "command", None):
            parser.print_help()
            return 2
        return _end_ranks(_dispatch(args))


def _end_ranks(code: int) -> int:
    """On several MPI ranks, an environment failure (exit 4: a disk that filled while rank 0
    wrote) or a Ctrl-C before the time loop is this rank's alone while the other ranks may
    wait in a collective solve: abort them all with that code instead of leaving them
    waiting.  The failures the ranks share (input errors, a failed or interrupted time
    loop, whose stop they agree on) end normally."""
    unshared = code == EXIT_ENVIRONMENT or UNSHARED_END[0]
    if unshared and launched()[1] > 1 and "mpi4py.MPI" in sys.modules:
        for stream in (sys.stdout, sys.stderr):
            stream.flush()
        if code == 130 and not is_root():  # Ctrl-C reaches every rank: let rank 0 say so and abort
            time.sleep(ROOT_FIRST_SECONDS)
        sys.modules["mpi4py.MPI"].COMM_WORLD.Abort(code)
    return code


def _print(text: str) -> None:
    """A message on stderr, from rank 0 only when started by mpiexec (every rank meets the
    same input errors and failures: one line, not P)."""
    if is_root():
        print(text, file=sys.stderr)


def _report_warnings(caught: list, interrupted: bool = False) -> None:
    """One line for the warnings a command raised (all of them with SIGNORINI_TRACEBACK=1).
    After an interruption, the ResourceWarnings it caused (a file an interrupted import or
    read left open) are not reported: the interruption is the one line to say."""
    if interrupted:
        caught = [w for w in caught if not issubclass(w.category, ResourceWarning)]
    if not caught or not is_root():
        return
    if os.environ.get("SIGNORINI_TRACEBACK"):
        for w in caught:
            print(f"signorini: warning: {w.category.__name__}: {one_line(w.message)}", file=sys.stderr)
        return
    first = caught[0]
    print(
        f"signorini: note: {len(caught)} library warning(s), the first {first.category.__name__}: "
        f"{one_line(first.message, 160)} (SIGNORINI_TRACEBACK=1 lists them)",
        file=sys.stderr,
    )


def _dispatch(args: argparse.Namespace) -> int:
    """Run the command; map every exception to its exit code and a one-line message."""
    # (on several ranks before MPI starts, SIGTERM stays deferred: signorini.parallel)
    old = signal.signal(signal.SIGTERM, _sigterm) if sys.platform != "win32" and not deferring() else None
    try:
        # every quantity is checked for finiteness where it matters, so numpy's floating-point
        # flags are off; Python warnings are collected and counted in one line (not hidden)
        with np.errstate(all="ignore"), warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                ranks = launched()[1]
                if ranks > 1 and args.command not in ("run", "resume"):
                    raise InputError(
                        f"started as {ranks} MPI ranks: only `signorini run ... --backend petsc` (and "
                        f"its resume) runs on several ranks, not `signorini {args.command}`"
                    )
                return args.func(args)
            finally:
                _report_warnings(caught, isinstance(sys.exc_info()[1], KeyboardInterrupt))
    except InputError as exc:
        _print(f"signorini: error: {one_line(exc)}")
        return 2
    except KeyboardInterrupt as exc:
        if not isinstance(exc, AgreedInterrupt):  # an agreed one: every rank is here, none waits
            mark_unshared()
        _print("signorini: interrupted before the time loop; nothing written")
        return 130
    except ResultConflict as exc:
        _print(f"signorini: error: {one_line(exc.strerror)}")
        return EXIT_ENVIRONMENT
    except ConvergenceError as exc:
        _print(f"signorini: failed: {one_line(exc)}")
        return EXIT_CODES["failed"]
    except (MemoryError, ImportError, OSError) as exc:
        if not is_memory_failure(exc) and not isinstance(exc, OSError):
            return _internal_error(exc)  # an ImportError that is not the memory limit: a bug
        if is_memory_failure(exc):  # MemoryError, ENOMEM, or a library that could not be mapped (ulimit -v)
            why = f" ({one_line(exc)})" if str(exc) else ""
            print(
                f"signorini: error: out of memory{why} (try a smaller size, --backend cg, or a larger machine)",
                file=sys.stderr,
            )
            return EXIT_ENVIRONMENT
        where = f" {exc.filename!r}" if exc.filename else ""
        if getattr(exc, "errno", None) in (errno.EMFILE, errno.ENFILE):
            print(f"signorini: error: too many open files: {open_files_hint()}", file=sys.stderr)
            return EXIT_ENVIRONMENT
        print(f"signorini: error: file system:{one_line(where)} {exc.strerror or exc}", file=sys.stderr)
        return EXIT_ENVIRONMENT
    except Exception as exc:  # a bug: one line, the traceback on request
        return _internal_error(exc)
    finally:
        if old is not None:
            signal.signal(signal.SIGTERM, old)


def open_files_hint() -> str:
    """The descriptor limit in words, for EMFILE/ENFILE."""
    try:
        import resource

        soft = resource.getrlimit(resource.RLIMIT_NOFILE)[0]
        return f"this process may open {soft} files (ulimit -n); signorini needs about 20: raise the limit"
    except (ImportError, OSError, ValueError):
        return "raise the limit of open files (ulimit -n)"


def _internal_error(exc: BaseException) -> int:
    """A bug: one line (the traceback with SIGNORINI_TRACEBACK=1), exit 1."""
    if os.environ.get("SIGNORINI_TRACEBACK"):
        traceback.print_exc()
    print(
        f"signorini: internal error: {type(exc).__name__}: {one_line(exc)} "
        "(please report it; SIGNORINI_TRACEBACK=1 shows the traceback)",
        file=sys.stderr,
    )
    return 1


if __name__ == "__main__":
    sys.exit(main())

"""Standard streams and signals that cannot change a command's exit code.

* :func:`guarded_stdio` gives the command valid file descriptors 0-2 (``2>&-`` closes
  stderr: without this the first file the run opens would get descriptor 2 and the
  HDF5 library's diagnostics would be written into it) and wraps ``sys.stdout`` and
  ``sys.stderr`` so that a closed pipe (``| head -c1``), a full device
  (``2>/dev/full``) or a closed stream only silences the output: the exit code stays
  the one of the computation.
* :func:`deferred_signals` holds SIGINT/SIGTERM while results are written: the
  handler only records the signal, the writing finishes, and the caller marks the
  result ``interrupted``.
"""

from __future__ import annotations

import io
import os
import signal
import sys
from collections.abc import Iterator
from contextlib import contextmanager

from ..signals import handled


def _reopen_closed_descriptors() -> None:
    """Open /dev/null on whichever of the descriptors 0, 1, 2 is closed."""
    for fd in (0, 1, 2):
        try:
            os.fstat(fd)
        except OSError:
            new = os.open(os.devnull, os.O_RDWR)  # the lowest free descriptor: ``fd``
            if new != fd:
                os.dup2(new, fd)
                os.close(new)


class GuardedStream(io.TextIOBase):
    """A text stream that turns write errors into silence.

    On the first :class:`OSError` (EPIPE, ENOSPC, EBADF, ...) the underlying
    descriptor is pointed at /dev/null, so that the interpreter's own flush at exit
    cannot fail either, and :attr:`failed` is set.
    """

    def __init__(self, stream, fd: int):
        self._stream = stream
        self._fd = fd
        self.failed = False

    def _silence(self) -> None:
        self.failed = True
        try:
            null = os.open(os.devnull, os.O_WRONLY)
            os.dup2(null, self._fd)
            os.close(null)
        except OSError:
            pass

    def write(self, s: str) -> int:
        if not self.failed:
            try:
                self._stream.write(s)
            except (OSError, ValueError):
                self._silence()
        return len(s)

    def flush(self) -> None:
        if not self.failed:
            try:
                self._stream.flush()
            except (OSError, ValueError):
                self._silence()

    def isatty(self) -> bool:
        try:
            return (not self.failed) and self._stream.isatty()
        except (OSError, ValueError):
            return False

    def fileno(self) -> int:
        return self._fd

    @property
    def encoding(self) -> str:
        return getattr(self._stream, "encoding", "utf-8")


@contextmanager
def guarded_stdio() -> Iterator[None]:
    """Valid descriptors 0-2 and error-proof ``sys.stdout``/``sys.stderr`` inside the block."""
    _reopen_closed_descriptors()
    saved = sys.stdout, sys.stderr
    for name, fd in (("stdout", 1), ("stderr", 2)):
        s = getattr(sys, name)
        if s is None:  # the descriptor was closed when Python started
            s = open(fd, "w", closefd=False, errors="backslashreplace")  # noqa: SIM115
        if not isinstance(s, GuardedStream):
            setattr(sys, name, GuardedStream(s, fd))
    try:
        yield
    finally:
        for s in (sys.stdout, sys.stderr):
            s.flush()
        sys.stdout, sys.stderr = saved
        for s in saved:
            if s is not None:
                try:
                    s.flush()
                except (OSError, ValueError):
                    pass


class SignalRecord:
    """The name of the first SIGINT/SIGTERM received inside :func:`deferred_signals`, if any."""

    def __init__(self) -> None:
        self.name: str | None = None

    def handler(self, signum, frame) -> None:
        if self.name is None:
            self.name = signal.Signals(signum).name


@contextmanager
def deferred_signals() -> Iterator[SignalRecord]:
    """Record SIGINT/SIGTERM instead of acting on them (main thread only)."""
    record = SignalRecord()
    with handled(record.handler):
        yield record

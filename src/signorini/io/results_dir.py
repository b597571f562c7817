"""Result directories that appear whole or not at all.

A command writes into a hidden temporary directory next to its ``--out`` path and
renames it into place only at the end (:meth:`ResultDirectory.commit`).  Guarantees:

* **Nothing is created for invalid input**: :func:`check_output_path` validates the
  path without touching the file system, and the directory is created only when the
  time loop starts (:meth:`ResultDirectory.create`, called lazily).
* **No leftovers**: on any exception the temporary directory and the parent
  directories this run created are removed (:meth:`ResultDirectory.abort`).  A run
  killed with SIGKILL cannot clean up after itself, so a tiny watchdog process holds
  the read end of a pipe whose write end only this process has: when this process
  ends for any reason the pipe closes and the watchdog removes what is left (after a
  commit nothing is left).
* A path that cannot be created (``/proc/x``, a path under a regular file, no write
  permission) is an :class:`~signorini.errors.InputError` naming it.
"""

from __future__ import annotations

import errno
import os
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

from ..errors import InputError

_WATCHDOG = (
    "import os, shutil, sys\n"
    "sys.stdin.buffer.read()\n"
    "shutil.rmtree(sys.argv[1], ignore_errors=True)\n"
    "for d in sys.argv[2:]:\n"
    "    try:\n"
    "        os.rmdir(d)\n"
    "    except OSError:\n"
    "        break\n"
)


def _nearest_existing(path: Path) -> Path:
    p = path
    while not p.exists() and p != p.parent:
        p = p.parent
    return p


def check_output_path(out: Path, overwrite: bool, flag: str = "--out") -> None:
    """Raise :class:`InputError` if ``out`` cannot become a result directory (nothing created)."""
    out = Path(out)
    if out.exists():
        if not out.is_dir():
            raise InputError(f"{flag} {str(out)!r} exists and is not a directory")
        if any(out.iterdir()) and not overwrite:
            raise InputError(f"output directory {str(out)!r} is not empty; pass --overwrite to replace it")
    base = _nearest_existing(out.absolute().parent)
    if not base.is_dir():
        raise InputError(f"{flag} {str(out)!r} cannot be created: {str(base)!r} is a file, not a directory")
    if not os.access(base, os.W_OK | os.X_OK):
        raise InputError(f"{flag} {str(out)!r} cannot be created: no write permission in {str(base)!r}")


class ResultDirectory:
    """A temporary directory next to ``out``, published by :meth:`commit`.

    Use as a context manager: an exception inside aborts (removes everything this
    object created) and propagates.
    """

    def __init__(self, out: Path, overwrite: bool, flag: str = "--out"):
        self.out = Path(out)
        self.overwrite = overwrite
        self.flag = flag
        check_output_path(self.out, overwrite, flag)
        self.tmp: Path | None = None
        self.created: list[Path] = []  # parent directories made by this run, deepest first
        self._watchdog: subprocess.Popen | None = None

    def create(self) -> Path:
        """Make the parents and the temporary directory (once); returns the latter."""
        if self.tmp is not None:
            return self.tmp
        try:
            missing = []
            p = self.out.absolute().parent
            while not p.exists():
                missing.append(p)
                p = p.parent
            for d in reversed(missing):
                d.mkdir()
                self.created.insert(0, d)
            self.tmp = Path(tempfile.mkdtemp(prefix=f".{self.out.name}.", dir=self.out.absolute().parent))
            self.tmp.chmod(0o755)
        except OSError as exc:
            self.abort()
            raise InputError(f"{self.flag} {str(self.out)!r} cannot be created: {exc.strerror or exc}") from None
        self._start_watchdog()
        return self.tmp

    def _start_watchdog(self) -> None:
        try:
            self._watchdog = subprocess.Popen(
                [sys.executable, "-I", "-S", "-c", _WATCHDOG, str(self.tmp), *map(str, self.created)],
                stdin=subprocess.PIPE,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
                start_new_session=True,  # a Ctrl-C in the terminal does not reach it
            )
        except OSError:  # no watchdog: cleanup on normal exits still happens
            self._watchdog = None

    def _stop_watchdog(self) -> None:
        if self._watchdog is not None:
            self._watchdog.stdin.close()
            try:
                self._watchdog.wait(timeout=10)
            except subprocess.TimeoutExpired:
                pass
            self._watchdog = None

    def commit(self) -> None:
        """Replace ``out`` by the temporary directory (the old one is removed only now)."""
        tmp = self.create()
        if self.out.exists():
            shutil.rmtree(self.out)
        tmp.rename(self.out)
        self.tmp = None
        self.created = []
        self._stop_watchdog()

    def abort(self) -> None:
        """Remove the temporary directory and the parents this run created."""
        if self.tmp is not None:
            shutil.rmtree(self.tmp, ignore_errors=True)
            self.tmp = None
        for d in self.created:
            try:
                d.rmdir()
            except OSError:
                break
        self.created = []
        self._stop_watchdog()

    def __enter__(self) -> ResultDirectory:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is not None:
            self.abort()


def run_into(out: Path, overwrite: bool, work: Callable[[Path], None]) -> None:
    """Run ``work(tmpdir)`` and publish the directory only if it returns."""
    with ResultDirectory(out, overwrite) as rd:
        work(rd.create())
        rd.commit()


def is_environment_error(exc: OSError) -> bool:
    """Disk full, quota, I/O errors: the machine's fault, not the input's."""
    return exc.errno in (errno.ENOSPC, errno.EDQUOT, errno.EIO, errno.EROFS, errno.EMFILE, errno.ENFILE)

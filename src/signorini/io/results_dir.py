"""Result directories that appear whole or not at all, and never replace what is not ours.

A command writes into a hidden temporary directory next to its ``--out`` path and
renames it into place only at the end (:meth:`ResultDirectory.commit`).  Guarantees:

* **Nothing is created for invalid input**: :func:`resolve_output` validates the path
  without touching the file system (NUL bytes, name and path lengths, symbolic links
  that dangle or loop, a regular file in the way, write permission), and the directory
  is created only when the time loop starts (:meth:`ResultDirectory.create`).
* **Never delete what is not ours.**  Every result directory holds a marker file,
  :data:`MARKER`.  ``--overwrite`` replaces only an empty directory or a directory that
  holds the marker, and never the working directory, one of its parents or a
  filesystem root; anything else is an :class:`~signorini.errors.InputError` (exit 2)
  before anything is computed or touched.
* **Atomic replacement.**  The old result is renamed aside (``.signorini-old.*``), the
  new one renamed in, and only then is the old one deleted: a kill at any moment leaves
  one complete result under ``--out``.
* **Concurrent runs.**  Without ``--overwrite`` the final rename succeeds only if
  ``--out`` is still missing or empty (``rename(2)`` refuses a non-empty target), so a
  run that finishes after another one wrote the same ``--out`` does not replace it: its
  own results are kept beside it (``<out>.kept-<time>-<pid>``) and
  :class:`ResultConflict` reports where (exit 4).  With ``--overwrite`` the last run to
  finish wins, as asked.
* **No leftovers**: on any exception the temporary directory and the parent
  directories this run created are removed (:meth:`ResultDirectory.abort`).  A run
  killed with SIGKILL cannot clean up after itself, so a tiny watchdog process holds
  the read end of a pipe whose write end only this process has: when this process
  ends for any reason the pipe closes and the watchdog finishes the job: before the
  commit it removes the temporary directory; during the commit it puts a complete
  result (the new one, else the old one) under ``--out`` and removes what is aside.
* **A killed run with a checkpoint is resumable** (:meth:`ResultDirectory.checkpointed`):
  once a complete checkpoint.h5 is in the temporary directory, a kill before the commit
  leaves ``--out`` holding that checkpoint, a summary.json with status ``killed`` and the
  marker (the partial fields and history are removed: the checkpoint holds the history up
  to its level); ``signorini resume`` continues it.  ``--out`` taken meanwhile: the
  directory is kept beside it as ``<out>.killed-<pid>``.
"""

from __future__ import annotations

import datetime
import errno
import json
import os
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

from .. import __version__
from ..errors import InputError

#: descriptors reserved for the clean-up of a failed run (rmtree of a shallow directory)
SPARE_FDS = 2
#: name of the marker file written in every result directory
MARKER = ".signorini"
_NEW_PREFIX = ".signorini-new."
_OLD_PREFIX = ".signorini-old."

_WATCHDOG = r"""
import json, os, shutil, sys
out = sys.argv[1]
tmp, created, aside, committing, done, killed = None, [], [], False, False, None
for line in sys.stdin.buffer:
    word, arg = json.loads(line)
    if word == "checkpoint":
        killed = arg
    elif word == "tmp":
        tmp = arg
    elif word == "made":
        created.insert(0, arg)
    elif word == "commit":
        committing = True
    elif word == "aside":
        aside.append(arg)
    elif word == "done":
        done = True
if done or tmp is None and not created:
    sys.exit(0)
if not committing and tmp is not None and killed is not None and os.path.isfile(os.path.join(tmp, "checkpoint.h5")):
    try:  # a run killed after a checkpoint: its result is that checkpoint, resumable
        for name in os.listdir(tmp):
            if name not in ("checkpoint.h5", "checkpoint.series", ".signorini"):
                path = os.path.join(tmp, name)
                shutil.rmtree(path) if os.path.isdir(path) and not os.path.islink(path) else os.remove(path)
        with open(os.path.join(tmp, "summary.json"), "w") as f:
            f.write(json.dumps(killed["summary"], indent=1))
        with open(os.path.join(tmp, ".signorini"), "w") as f:
            kept = sorted(set(os.listdir(tmp)) - {".signorini"})
            f.write(json.dumps(dict(killed["marker"], manifest=kept)) + "\n")
        try:
            os.rename(tmp, out)
        except OSError:
            os.rename(tmp, out + ".killed-" + str(os.getpid()))
        sys.exit(0)
    except OSError:
        pass
if committing and tmp is not None:
    if not os.path.lexists(out):
        for src in [tmp] + aside[::-1]:
            try:
                os.rename(src, out)
                break
            except OSError:
                pass
    for a in aside:
        shutil.rmtree(a, ignore_errors=True)
if tmp is not None:
    shutil.rmtree(tmp, ignore_errors=True)
if not committing:
    for d in created:
        try:
            os.rmdir(d)
        except OSError:
            break
"""


class ResultConflict(OSError):
    """The output directory changed under a run (another run wrote it meanwhile).

    The message says where this run's own results were kept; the command line exits 4.
    """


def _files(directory: Path) -> set[str]:
    """Relative paths of everything under ``directory`` (files, links and directories)."""
    out = set()
    for root, dirs, files in os.walk(directory):
        for name in dirs + files:
            out.add(os.path.relpath(os.path.join(root, name), directory))
    return out


def is_result_directory(path: Path) -> bool:
    """True when ``path`` holds this tool's marker (a regular file) and nothing that the
    marker's manifest does not list: a file the user put into a result directory makes it
    theirs again (``--overwrite`` refuses it)."""
    return not_a_result_directory(path) is None


def not_a_result_directory(path: Path) -> str | None:
    """Why ``--overwrite`` may not replace ``path`` (None: it may), in words for a message."""
    m = Path(path) / MARKER
    try:
        if not m.exists() and not m.is_symlink():
            return f"it has no {MARKER} marker"
        if not m.is_file() or m.is_symlink():
            return f"its {MARKER} is not a regular file"
        info = json.loads(m.read_text())
        if info.get("written_by") != "signorini":
            return f"its {MARKER} marker was not written by signorini"
        if not isinstance(info.get("manifest"), list):
            return f"its {MARKER} marker lists no files: a run was still writing it"
        extra = sorted(_files(Path(path)) - {MARKER} - set(info["manifest"]))
        if extra:
            more = f" and {len(extra) - 1} more" if len(extra) > 1 else ""
            return f"it holds {extra[0]!r}{more}, which signorini did not write there"
        return None
    except (OSError, ValueError, AttributeError, TypeError) as exc:
        return f"its {MARKER} marker cannot be read ({exc})"


def _is_empty_dir(path: Path) -> bool:
    try:
        with os.scandir(path) as it:
            return next(it, None) is None
    except OSError:
        return False


def _nearest_existing(path: Path) -> Path:
    p = path
    while not os.path.exists(p) and p != p.parent:  # os.path.exists: False on any OSError
        p = p.parent
    return p


def _limit(base: Path, name: str, default: int) -> int:
    try:
        return int(os.pathconf(base, name))
    except (OSError, ValueError):
        return default


def _resolve_link(out: Path, flag: str) -> Path:
    """The real path of ``out`` (symbolic links followed); dangling links and loops refused,
    on ``out`` itself and on every directory of its path (a dangling link in the middle would
    make the run create the link's target)."""
    for p in reversed(Path(os.path.abspath(out)).parents):
        if p.is_symlink() and not os.path.exists(p):
            raise InputError(
                f"{flag} {str(out)!r}: {str(p)!r} on its path is a symbolic link to {os.readlink(p)!r}, which does not "
                "exist or loops"
            )
    if out.is_symlink():
        try:
            return out.resolve(strict=True)
        except FileNotFoundError:
            raise InputError(
                f"{flag} {str(out)!r} is a symbolic link to {os.readlink(out)!r}, which does not exist"
            ) from None
        except (RuntimeError, OSError):  # a loop (RuntimeError before Python 3.13)
            raise InputError(f"{flag} {str(out)!r} is a symbolic link that loops") from None
    try:
        return out.resolve(strict=False)
    except (RuntimeError, OSError):
        raise InputError(f"{flag} {str(out)!r}: a symbolic link on the path loops") from None


def resolve_output(out: Path | str, overwrite: bool, flag: str = "--out") -> Path:
    """The real path where the result directory will be; :class:`InputError` if it cannot be.

    Nothing is created or changed.  Refused: an empty path or a NUL byte, a component
    longer than the file system allows, a dangling or looping symbolic link, a regular
    file, a non-empty directory without ``overwrite``, a non-empty directory without
    :data:`MARKER` (not written by this tool), the working directory, one of its parents,
    a filesystem root, and a parent where this process cannot write.
    """
    text = os.fspath(out)
    if not text:
        raise InputError(f"{flag} must be a directory path, got an empty string")
    if "\0" in text:
        raise InputError(f"{flag} must not contain a NUL byte")
    if any(ord(c) < 32 or ord(c) == 127 for c in text):
        raise InputError(f"{flag} {text!r} contains a control character (a newline, a tab, ...); rename it")
    if text.startswith("~"):
        raise InputError(f"{flag} {text!r} starts with '~', which is not expanded here; give the path in full")
    name_max = _limit(_nearest_existing(Path(os.path.abspath(text))), "PC_NAME_MAX", 255)
    if any(len(os.fsencode(p)) > name_max for p in Path(text).parts):
        raise InputError(f"{flag} {text[:80]!r}...: a path component is longer than {name_max} bytes")
    real = _resolve_link(Path(text), flag)
    shown = repr(text) if str(real) == os.path.abspath(text) else f"{text!r} (= {str(real)!r})"
    base = _nearest_existing(real.parent)
    path_max = _limit(base, "PC_PATH_MAX", 4096)
    if len(os.fsencode(str(real))) + len(_NEW_PREFIX) + 10 >= path_max:
        raise InputError(f"{flag} {shown} is longer than the {path_max} bytes a path may have here")
    cwd = Path.cwd().resolve()
    if real == cwd or real in cwd.parents or real == Path(real.anchor):
        raise InputError(
            f"{flag} {shown} is the working directory, one of its parents or a root; choose a new directory"
        )
    if real.exists():
        if not real.is_dir():
            raise InputError(f"{flag} {shown} exists and is not a directory")
        if os.path.ismount(real):
            raise InputError(
                f"{flag} {shown} is a mount point: results are written beside it and renamed onto it, which a "
                "mount point cannot be; give a directory inside it"
            )
        if not _is_empty_dir(real):
            if not overwrite:
                raise InputError(f"output directory {shown} is not empty; pass --overwrite to replace it")
            why = not_a_result_directory(real)
            if why:
                raise InputError(
                    f"--overwrite refused: {shown} is not a result of signorini ({why}); "
                    "remove it yourself or choose another --out"
                )
    if not base.is_dir():
        raise InputError(f"{flag} {shown} cannot be created: {str(base)!r} is a file, not a directory")
    if not os.access(base, os.W_OK | os.X_OK):
        raise InputError(f"{flag} {shown} cannot be created: no write permission in {str(base)!r}")
    try:  # root passes os.access everywhere: probe (/proc, /sys, read-only mounts), leaving nothing
        os.rmdir(tempfile.mkdtemp(prefix=_NEW_PREFIX, dir=base))
    except OSError as exc:
        raise InputError(f"{flag} {shown} cannot be created in {str(base)!r}: {exc.strerror or exc}") from None
    return real


def check_output_path(out: Path, overwrite: bool, flag: str = "--out") -> None:
    """Raise :class:`InputError` if ``out`` cannot become a result directory (nothing created)."""
    resolve_output(out, overwrite, flag)


def write_marker(directory: Path, manifest: bool = True) -> None:
    """Write :data:`MARKER` into ``directory``: who wrote it, when, and (``manifest``) the
    list of everything it holds, so that a file added later is recognized as not ours."""
    info = {
        "written_by": "signorini",
        "version": __version__,
        "created": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "pid": os.getpid(),
    }
    if manifest:
        info["manifest"] = sorted(_files(Path(directory)) - {MARKER})
    (Path(directory) / MARKER).write_text(json.dumps(info) + "\n")


class ResultDirectory:
    """A temporary directory next to ``out``, published by :meth:`commit`.

    Use as a context manager: an exception inside aborts (removes everything this
    object created, never ``out``) and propagates.
    """

    def __init__(self, out: Path, overwrite: bool, flag: str = "--out"):
        self.shown = Path(out)
        self.out = resolve_output(out, overwrite, flag)
        self.overwrite = overwrite
        self.flag = flag
        self.tmp: Path | None = None
        self.created: list[Path] = []  # parent directories made by this run, deepest first
        self._watchdog: subprocess.Popen | None = None
        #: descriptors held in reserve, released for the clean-up: under a tight descriptor
        #: limit (ulimit -n) the run may use them all, and rmtree needs some to remove the
        #: temporary directory (it was left behind)
        self._spare: list[int] = []

    def _reserve(self) -> None:
        for _ in range(SPARE_FDS - len(self._spare)):
            try:
                self._spare.append(os.open(os.devnull, os.O_RDONLY))
            except OSError:
                break

    def _release(self) -> None:
        for fd in self._spare:
            try:
                os.close(fd)
            except OSError:
                pass
        self._spare = []

    def create(self) -> Path:
        """Make the parents and the temporary directory with its marker (once); returns the latter."""
        if self.tmp is not None:
            return self.tmp
        # the watchdog first, told of each directory as soon as it exists: a SIGKILL at any
        # moment leaves nothing behind (it used to start after them, a window that a kill
        # right after the temporary directory appeared could hit on a loaded machine)
        self._reserve()
        self._start_watchdog()
        try:
            missing = []
            p = self.out.parent
            while not p.exists():
                missing.append(p)
                p = p.parent
            for d in reversed(missing):
                d.mkdir()
                self.created.insert(0, d)
                self._tell("made", os.fsdecode(d))
            self.tmp = Path(tempfile.mkdtemp(prefix=_NEW_PREFIX, dir=self.out.parent))
            self._tell("tmp", os.fsdecode(self.tmp))
            umask = os.umask(0)
            os.umask(umask)
            self.tmp.chmod(0o777 & ~umask)  # as a plain mkdir would (mkdtemp makes 0700)
            write_marker(self.tmp, manifest=False)  # being written: not replaceable until committed
        except OSError as exc:
            self.abort()
            if exc.errno in (errno.ENOSPC, errno.EDQUOT, errno.EIO, errno.EMFILE, errno.ENFILE):
                raise  # the machine's limits (exit 4), not the user's --out
            raise InputError(f"{self.flag} {str(self.shown)!r} cannot be created: {exc.strerror or exc}") from None
        return self.tmp

    def _start_watchdog(self) -> None:
        try:
            self._watchdog = subprocess.Popen(
                [sys.executable, "-I", "-S", "-c", _WATCHDOG, str(self.out)],
                stdin=subprocess.PIPE,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
                start_new_session=True,  # a Ctrl-C in the terminal does not reach it
            )
        except OSError:  # no watchdog: cleanup on normal exits still happens
            self._watchdog = None

    def _tell(self, word: str, arg: str | dict = "") -> None:
        """One message to the watchdog: a JSON line, so no path can split it."""
        if self._watchdog is not None:
            try:
                line = json.dumps([word, arg], ensure_ascii=True)
                self._watchdog.stdin.write(line.encode("ascii") + b"\n")
                self._watchdog.stdin.flush()
            except OSError:
                pass

    def checkpointed(self, summary: dict) -> None:
        """A complete checkpoint is in the temporary directory: if this process is killed
        before the commit, the watchdog publishes it with ``summary`` as summary.json (status
        ``killed``) instead of removing it, so that ``signorini resume`` can continue it."""
        marker = {
            "written_by": "signorini",
            "version": __version__,
            "pid": os.getpid(),
            "created": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        }
        self._tell("checkpoint", {"summary": summary, "marker": marker})

    def _stop_watchdog(self, done: bool) -> None:
        if self._watchdog is not None:
            if done:
                self._tell("done")
            try:
                self._watchdog.stdin.close()
            except OSError:
                pass
            try:
                self._watchdog.wait(timeout=10)
            except subprocess.TimeoutExpired:
                pass
            self._watchdog = None

    def _keep_aside(self, tmp: Path) -> Path:
        """Rename the finished temporary directory to a visible sibling of ``out``."""
        stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
        name = f"{self.out.name}.kept-{stamp}-{os.getpid()}"
        if len(os.fsencode(name)) > _limit(self.out.parent, "PC_NAME_MAX", 255):
            name = f"signorini-kept-{stamp}-{os.getpid()}"
        kept = self.out.parent / name
        tmp.rename(kept)
        return kept

    def commit(self) -> None:
        """Publish the temporary directory as ``out`` (see the module's guarantees)."""
        tmp = self.create()
        self._release()  # the descriptors kept for this moment (and for abort)
        write_marker(tmp)  # with the manifest of what this run wrote
        self._tell("commit")
        asides: list[Path] = []
        reason = ""
        for _ in range(8):
            try:
                os.rename(tmp, self.out)  # atomic; fails on a non-empty directory or a file
                break
            except OSError as exc:
                if exc.errno not in (errno.ENOTEMPTY, errno.EEXIST, errno.ENOTDIR, errno.EISDIR):
                    raise
            if not self.overwrite:
                reason = "was written by another run meanwhile (no --overwrite)"
            elif why := not_a_result_directory(self.out):
                reason = f"was replaced meanwhile by something that is not a result of signorini ({why})"
            if reason:
                break
            aside = Path(tempfile.mkdtemp(prefix=_OLD_PREFIX, dir=self.out.parent))
            self._tell("aside", os.fsdecode(aside))
            try:
                os.rename(self.out, aside)  # replaces the empty placeholder atomically
            except FileNotFoundError:  # another run moved it first: try again
                aside.rmdir()
                continue
            asides.append(aside)
        else:
            reason = "kept changing while this run tried to replace it"
        if reason:
            kept = self._keep_aside(tmp)
            self.tmp = None
            self.created = []
            self._stop_watchdog(done=True)
            raise ResultConflict(errno.EEXIST, f"{str(self.shown)!r} {reason}; this run's results are in {str(kept)!r}")
        self.tmp = None
        self.created = []
        for a in asides:
            shutil.rmtree(a, ignore_errors=True)
        self._stop_watchdog(done=not any(a.exists() for a in asides))

    def abort(self) -> None:
        """Remove the temporary directory and the parents this run created (never ``out``);
        what cannot be removed here is left to the watchdog (not told it is done)."""
        self._release()
        left = False
        if self.tmp is not None:
            shutil.rmtree(self.tmp, ignore_errors=True)
            left = self.tmp.exists()
            self.tmp = None
        for d in self.created:
            try:
                d.rmdir()
            except OSError:
                left = left or d.exists()
                break
        self.created = []
        self._stop_watchdog(done=not left)

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

"""The HDF5 side of the field output, in a child process.

HDF5 can crash the process it runs in (a segmentation fault, not an exception) when the
disk fills *during* a write, e.g. because another program filled it after the writer's
free-space check.  So the XDMF/HDF5 writer lives in a child process started with
``spawn`` (no fork of a process with BLAS threads): :class:`FieldProcess` sends it the
mesh, then each snapshot, and waits for its answer, so errors arrive at the step that
caused them.  If the child dies or reports a failed write, the run gets an
:class:`OSError` (exit 4, one line, as for a full disk) and the child never touches the
file again; the main process itself never runs HDF5 on the fields.
"""

from __future__ import annotations

import atexit
import contextlib
import errno
import multiprocessing
import os
import re
import signal
from pathlib import Path
from typing import Any

import numpy as np

STOP_SIGNALS = {signal.SIGINT, signal.SIGTERM}


def _serve(conn, path: str) -> None:
    """The child: write what the parent sends until "close" (or die trying, alone)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent decides when to stop
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, STOP_SIGNALS)  # blocked since the spawn: dropped now
    target = Path(path)
    try:
        os.chdir(target.parent)  # meshio names the HDF5 file relative to the working directory
        import meshio

        from .xdmf_index import one_grid
    except BaseException:  # noqa: BLE001 - the run stopped and removed its directory: nothing to do
        os._exit(0)  # silently: the parent reports what happened, never the child

    writer = None
    while True:
        try:
            msg = conn.recv()
        except (EOFError, OSError):
            os._exit(0)  # the parent is gone: leave the file as it is
        try:
            if msg[0] == "mesh":
                writer = meshio.xdmf.TimeSeriesWriter(target.name)
                writer.__enter__()
                writer.write_points_cells(msg[1], msg[2])  # [(cell type, cells), ...]: one block per type
            elif msg[0] == "data":
                writer.write_data(msg[1], point_data=msg[2], cell_data=msg[3] if len(msg) > 3 else None)
            elif msg[0] == "close":
                if writer is not None:
                    writer.__exit__(None, None, None)
                    one_grid(target)  # one mesh for ParaView/pyvista (:mod:`~.xdmf_index`)
                conn.send(("ok",))
                os._exit(0)
            conn.send(("ok",))
        except BaseException as exc:  # noqa: BLE001 (reported to the parent, which decides)
            space = _disk_full(exc)
            with contextlib.suppress(BaseException):
                conn.send(("error", type(exc).__name__, str(exc)[:500], space))
            os._exit(0)  # never close an HDF5 file after a failed write


def _disk_full(exc: BaseException) -> bool:
    """Whether ``exc`` is a full disk or quota: errno ENOSPC or EDQUOT, on the exception or,
    for HDF5's errors (an OSError whose errno is None), in its ``errno = N`` detail."""
    codes = {errno.ENOSPC, errno.EDQUOT}
    if not isinstance(exc, OSError):
        return False
    if exc.errno is not None:
        return exc.errno in codes
    return any(int(n) in codes for n in re.findall(r"errno = (\d+)", str(exc)))


@contextlib.contextmanager
def _quiet_stderr():
    """File descriptor 2 on /dev/null while a child is started, so that the child inherits it:
    a parent killed outright (SIGKILL) while the child's interpreter reads its start-up data
    from it makes that interpreter print an EOFError traceback into the user's terminal or
    log, before any code of ours runs in it.  The parent's own stderr is back right after."""
    import sys

    sys.stderr.flush()
    saved = os.dup(2)
    try:
        null = os.open(os.devnull, os.O_WRONLY)
        try:
            os.dup2(null, 2)
        finally:
            os.close(null)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)


class FieldProcess:
    """The parent's handle on the writer child (see the module docstring)."""

    def __init__(self, path: Path):
        ctx = multiprocessing.get_context("spawn")
        self._conn, child = ctx.Pipe()
        self.process = ctx.Process(target=_serve, args=(child, str(path)), daemon=True, name="signorini-fields")
        # the child starts with SIGINT/SIGTERM blocked (a Ctrl-C to the process group during its
        # interpreter start-up would print a KeyboardInterrupt traceback); here they stay
        # pending for the parent's handlers, never lost
        self.closed = True  # until the child runs
        previous = signal.pthread_sigmask(signal.SIG_BLOCK, STOP_SIGNALS)
        try:
            with _quiet_stderr():  # the child's stderr is /dev/null (the parent reports, never the child)
                self.process.start()
            child.close()
            self.closed = False
            # registered after multiprocessing's own exit hook, so it runs first (that hook joins a
            # daemon child after a SIGTERM, which this child ignores, and would wait for ever)
            atexit.register(self._at_exit)
        finally:
            try:
                signal.pthread_sigmask(signal.SIG_SETMASK, previous)  # a signal held since the spawn is raised here
            except BaseException:
                if not self.closed:  # nobody holds this handle yet: its child goes now
                    self.abandon()
                raise

    def _at_exit(self) -> None:
        """A child still serving at the interpreter's exit (a signal while the writer started):
        its pipe closed, it leaves on its own; one stuck in HDF5 is killed."""
        if self.process.is_alive():
            self._conn.close()
            self.process.join(2)
            if self.process.is_alive():
                self.process.kill()
                self.process.join(5)

    def _ask(self, msg: tuple) -> None:
        try:
            self._conn.send(msg)
            answer = self._conn.recv()
        except (EOFError, OSError, BrokenPipeError):
            self.process.join(5)
            code = self.process.exitcode
            how = f"signal {signal.Signals(-code).name}" if code is not None and code < 0 else f"exit {code}"
            self._end()
            raise OSError(
                errno.EIO,
                f"the field writer process died ({how}) while writing the fields' HDF5 file "
                "(a full disk or a crash inside HDF5)",
            ) from None
        if answer[0] == "error":
            self.process.join(5)
            self._end()
            if answer[3]:
                detail = f"{answer[1]}: {answer[2]}"
                raise OSError(errno.ENOSPC, f"No space left on device while streaming fields ({detail})")
            raise OSError(errno.EIO, f"the field writer failed: {answer[1]}: {answer[2]}")

    def mesh(self, points: np.ndarray, blocks: list[tuple[str, np.ndarray]]) -> None:
        """The points and the cell blocks (one per cell type) of the time series."""
        self._ask(("mesh", points, list(blocks)))

    def data(self, t: float, point_data: dict[str, Any], cell_data: dict[str, Any] | None = None) -> None:
        self._ask(("data", float(t), point_data, cell_data))

    def close(self) -> None:
        """Write the XDMF index and end the child (a dead child is left as it is)."""
        if self.closed:
            return
        self.closed = True
        try:
            self._ask(("close",))
        finally:
            self.process.join(10)
            if self.process.is_alive():  # pragma: no cover - a child stuck in HDF5
                self.process.kill()
            self._end()

    def abandon(self) -> None:
        """Stop the child without closing its file (after a failure elsewhere)."""
        if self.process.is_alive():
            self.process.kill()
        self.process.join(5)
        self._end()

    def _end(self) -> None:
        """Done with the child (it has left, or was killed): its pipe and exit hook go."""
        self.closed = True
        self._conn.close()
        atexit.unregister(self._at_exit)

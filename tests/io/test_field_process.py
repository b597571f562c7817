"""The field writer's child process never outlives its run, whatever interrupts the parent."""

import multiprocessing
import subprocess
import sys
import textwrap

import pytest

from signorini.dynamics.stepping.simulate import simulate
from signorini.io import field_process
from signorini.io.output import FieldWriter
from signorini.studies.benchmarks import get_benchmark


def test_a_parent_that_exits_without_closing_the_writer_exits(tmp_path):
    """An open writer at the interpreter's exit: multiprocessing's own exit hook sends its
    daemon child SIGTERM, which the child ignores, then joins it; the writer's hook ends the
    child first (it was a hang for ever, seen after a SIGTERM during the writer's start-up)."""
    script = textwrap.dedent(
        f"""
        from pathlib import Path
        import numpy as np
        from signorini.io.field_process import FieldProcess
        w = FieldProcess(Path({str(tmp_path / "f.xdmf")!r}))
        w.mesh(np.eye(3), [("triangle", np.array([[0, 1, 2]]))])  # answered: the child serves
        print(w.process.pid, flush=True)
        """
    )
    r = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=30)
    assert r.returncode == 0, r.stderr
    pid = int(r.stdout)
    assert not _alive(pid)


def _alive(pid: int) -> bool:
    import os

    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


@pytest.mark.parametrize("where", ["mesh", "data"])
def test_a_signal_while_the_writer_starts_ends_its_child(tmp_path, monkeypatch, where):
    """KeyboardInterrupt (the set-up's SIGINT/SIGTERM) inside the writer's start: the observer
    was not started, so the stepper does not close it; the writer ends its own child and
    removes its reserve."""

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(field_process.FieldProcess, where, interrupted)
    b = get_benchmark("bar2d")
    with pytest.raises(KeyboardInterrupt):
        simulate(b.problem(2), "cn", b.h(2), 0.1, observers=[FieldWriter(tmp_path / "f.xdmf", 1)])
    assert [p for p in multiprocessing.active_children() if p.name == "signorini-fields"] == []
    assert not any(p.name.endswith(".reserve") for p in tmp_path.iterdir())


def test_a_signal_held_since_the_spawn_ends_the_child(tmp_path, monkeypatch):
    """A SIGTERM that arrives while the child is spawned is held, and raised (the run's handler: a
    KeyboardInterrupt) when the constructor unblocks it: no handle is returned, so the constructor ends its child
    itself (the exit hook alone would leave it serving a library caller that goes on)."""
    import contextlib
    import signal
    import threading

    def interrupt(signum, frame):
        raise KeyboardInterrupt

    @contextlib.contextmanager
    def then_signalled():
        yield
        signal.pthread_kill(threading.main_thread().ident, signal.SIGTERM)  # blocked here: held

    monkeypatch.setattr(field_process, "_quiet_stderr", then_signalled)
    previous = signal.signal(signal.SIGTERM, interrupt)
    try:
        with pytest.raises(KeyboardInterrupt):
            field_process.FieldProcess(tmp_path / "f.xdmf")
    finally:
        signal.signal(signal.SIGTERM, previous)
    assert [p for p in multiprocessing.active_children() if p.name == "signorini-fields"] == []

"""The installed command under attack, as a subprocess: signals at random moments.

Whatever the moment (start-up, set-up, time loop, writing, commit) and the signal, the
output directory is either absent or one complete result (marker, summary.json with its
status, history.csv with one row per level; after SIGKILL past a checkpoint, that checkpoint
as a resumable "killed" result), no temporary directory is left once the watchdog has run,
and the exit code says what happened (0, 130, or -9 for SIGKILL).
A signal in the first milliseconds, while the interpreter imports its ``site`` or ``runpy``
module before any signorini code runs, gets Python's own report; from the entry point on
(``signorini/__main__.py``) the command handles it.
The default suite runs a few random moments; ``-m slow`` runs many.
"""

import json
import os
import random
import signal
import subprocess
import sys
import time

import pytest

from signorini.io.results_dir import MARKER

# CPython's own messages when a signal lands while it imports ``site`` or ``runpy``, before ``-m`` runs
_STARTUP = ("init_import_site", "Could not import runpy module")
CMD = [sys.executable, "-m", "signorini", "run", "bar2d", "--n", "8", "--T", "8", "--snapshot-every", "20"]


def _settle(parent, timeout=10.0):
    deadline = time.time() + timeout
    while time.time() < deadline and any(p.name.startswith(".signorini-") for p in parent.iterdir()):
        time.sleep(0.05)


def _check_outcome(tmp_path, rc, sig):
    out = tmp_path / "o"
    _settle(tmp_path)
    leftovers = [p.name for p in tmp_path.iterdir() if p.name.startswith(".signorini-")]
    assert not leftovers, leftovers
    if sig == signal.SIGKILL:
        assert rc in (0, -signal.SIGKILL)
    else:
        if rc == -sig and not out.exists():  # before the entry point's handlers: the interpreter's start-up
            return  # (a loaded machine stretches it; nothing was written, nothing is left: checked above)
        assert rc in (0, 130, 2), rc  # 2: interrupted before the output path was even checked is impossible
    if not out.exists():
        assert rc != 0
        return
    assert (out / MARKER).is_file()
    s = json.loads((out / "summary.json").read_text())
    if s["status"] == "killed":  # SIGKILL after the last checkpoint, before the commit: the watchdog publishes
        assert rc == -signal.SIGKILL and s["resumable"]  # that checkpoint as the result, resumable, no history
        assert (out / "checkpoint.h5").is_file() and not (out / "history.csv").exists()
        return
    rows = (out / "history.csv").read_text().strip().splitlines()
    assert len(rows) == s["steps"] + 2  # header + levels 0..steps
    assert s["status"] == ("finished" if rc == 0 else "interrupted") or (rc == -9 and s["status"] == "finished")
    if rc == 130:
        assert not s["success"]


def _attack(tmp_path, seed):
    rnd = random.Random(seed)
    sig = rnd.choice([signal.SIGINT, signal.SIGTERM, signal.SIGKILL])
    delay = rnd.uniform(0.0, 4.0)
    proc = subprocess.Popen([*CMD, "--out", str(tmp_path / "o"), "--quiet"], stderr=subprocess.PIPE, text=True)
    time.sleep(delay)
    if proc.poll() is None:
        os.kill(proc.pid, sig)
    err = proc.communicate(timeout=60)[1]
    if any(m in err for m in _STARTUP):  # the interpreter's own start-up, before any signorini code
        assert not (tmp_path / "o").exists()
        return
    lines = [x for x in err.strip().splitlines() if not x.startswith("signorini: warning:")]
    assert "Traceback" not in err and len(lines) <= 1, err
    _check_outcome(tmp_path, proc.returncode, sig)


@pytest.mark.parametrize("seed", range(4))
def test_signal_at_a_random_moment_leaves_one_result_or_none(tmp_path, seed):
    _attack(tmp_path, seed)


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(4, 40))
def test_signal_at_a_random_moment_many(tmp_path, seed):
    _attack(tmp_path, seed)


def _limited_run(tmp_path, resource_name: str, value: int, *extra: str) -> subprocess.CompletedProcess:
    import resource

    which = getattr(resource, resource_name)

    def limit() -> None:
        resource.setrlimit(which, (value, resource.getrlimit(which)[1]))

    cmd = [sys.executable, "-m", "signorini", "run", "bar2d", "--snapshot-every", "1", *extra, "--quiet"]
    return subprocess.run(cmd + ["--out", str(tmp_path / "o")], cwd=tmp_path, preexec_fn=limit, capture_output=True,
                          text=True, timeout=120)  # fmt: skip


@pytest.mark.parametrize("limit", [8, 11, 13])
def test_a_small_descriptor_limit_is_one_line_exit_4_and_leaves_nothing(tmp_path, limit):
    """ulimit -n too small for the run (the field writer's pipes, HDF5): one line naming the
    limit, exit 4, and no hidden temporary directory left behind (its clean-up had no
    descriptor left for rmtree)."""
    r = _limited_run(tmp_path, "RLIMIT_NOFILE", limit)
    assert r.returncode == 4, r.stderr
    assert r.stderr.count("\n") == 1 and "too many open files" in r.stderr and f"open {limit} files" in r.stderr
    time.sleep(0.5)  # the watchdog, if it had to
    assert sorted(p.name for p in tmp_path.iterdir()) == []


@pytest.mark.parametrize("mib", [64, 300])
def test_a_small_address_space_limit_is_one_line_exit_4_at_start_up(tmp_path, mib):
    """ulimit -v below what numpy and scipy take to load: one line, exit 4 (it was a 30-line
    ImportError traceback and exit 1, or OpenBLAS's own message)."""
    r = _limited_run(tmp_path, "RLIMIT_AS", mib * 2**20)
    assert r.returncode == 4, r.stderr
    assert r.stderr.count("\n") == 1 and "address-space limit" in r.stderr and "Traceback" not in r.stderr
    assert not (tmp_path / "o").exists()

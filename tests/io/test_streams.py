"""Exit codes that do not lie: closed or full standard streams, signals while writing, disk full."""

import json
import os
import shutil
import signal
import subprocess
import sys

import pytest

from signorini.io.cli import main

BAD = (
    '[mesh]\ngenerator = "interval"\ncells = [8]\nsize = [1.0]\n[material]\nrho = 1e100\nE = 1.0\n'
    '[[dirichlet]]\ntag = "xmax"\nvalue = [0.2]\n[contact]\ntag = "xmin"\n'
    'obstacle = { type = "plane", point = [0.0], normal = [1.0] }\n[initial]\ndisplacement = [0.2]\n'
    "velocity = [-0.5]\n[time]\ndt = 1e-150\nT = 1.6e-149\n"
)
CLI = [sys.executable, "-m", "signorini.io.cli"]


def _shell(cmd: str, cwd) -> int:
    return subprocess.run(["bash", "-c", cmd], cwd=cwd, capture_output=True, text=True).returncode


@pytest.mark.parametrize("sink", ["| true", "| head -c1 >/dev/null", "2>&-", "2>/dev/full", ">/dev/full 2>&-"])
def test_failed_run_keeps_exit_3_whatever_happens_to_the_output(tmp_path, sink):
    (tmp_path / "bad.toml").write_text(BAD)
    cmd = " ".join(CLI) + f" run bad.toml --out o {sink}; exit ${{PIPESTATUS[0]}}"
    assert _shell(cmd, tmp_path) == 3
    assert json.loads((tmp_path / "o" / "summary.json").read_text())["status"] == "failed"


@pytest.mark.parametrize("sink", ["| head -c1 >/dev/null", "2>&-", ">/dev/full 2>/dev/full"])
def test_finished_run_exits_0_with_closed_or_full_streams(tmp_path, sink):
    cmd = " ".join(CLI) + f" run bar1d --n 8 --T 1 --out o {sink}; exit ${{PIPESTATUS[0]}}"
    assert _shell(cmd, tmp_path) == 0
    assert json.loads((tmp_path / "o" / "summary.json").read_text())["status"] == "finished"


def test_closed_stderr_does_not_let_a_file_take_descriptor_2(tmp_path):
    """With fd 2 closed at start the HDF5 file must not become fd 2 (its diagnostics would land in it)."""
    cmd = " ".join(CLI) + " run bar2d --n 2 --T 1 --snapshot-every 1 --out o 2>&-"
    assert _shell(cmd, tmp_path) == 0
    assert (tmp_path / "o" / "fields.h5").stat().st_size > 0


def test_signal_while_results_are_written_keeps_every_step(tmp_path, monkeypatch, capsys):
    """SIGTERM after the time loop, during History.save: status interrupted, all steps kept, exit 130."""
    from signorini.dynamics.observe.history import History

    real_save = History.save
    sent = []

    def save(self, d):
        if not sent:
            sent.append(True)
            os.kill(os.getpid(), signal.SIGTERM)
        return real_save(self, d)

    monkeypatch.setattr(History, "save", save)
    rc = main(["run", "bar1d", "--n", "8", "--T", "1", "--out", str(tmp_path / "o"), "--quiet"])
    assert rc == 130
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert s["status"] == "interrupted" and "SIGTERM while the results were written" in s["message"]
    assert s["steps"] == s["counters"]["steps"] > 0
    assert "interrupted" in capsys.readouterr().err


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_signal_right_after_the_commit_keeps_a_finished_run_finished(tmp_path, monkeypatch, capsys, sig):
    """A signal once the result directory is published (the slow suite's random signal hit that
    moment once): the result stays finished, exit 0, and stderr says nothing was lost."""
    from signorini.io.results_dir import ResultDirectory

    real_exit = ResultDirectory.__exit__

    def exit_(self, *exc):
        real_exit(self, *exc)
        os.kill(os.getpid(), sig)

    monkeypatch.setattr(ResultDirectory, "__exit__", exit_)
    rc = main(["run", "bar1d", "--n", "8", "--T", "1", "--out", str(tmp_path / "o"), "--quiet"])
    assert rc == 0
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert s["status"] == "finished"
    assert f"{sig.name} received after the results were written; nothing lost" in capsys.readouterr().err


def test_signal_while_the_history_is_assembled_keeps_every_step(tmp_path, monkeypatch):
    import signorini.dynamics.stepping.setup as sim  # the History of the levels is assembled there

    real = sim.assemble_history

    def assemble(*a, **k):
        os.kill(os.getpid(), signal.SIGINT)
        return real(*a, **k)

    monkeypatch.setattr(sim, "assemble_history", assemble)
    rc = main(["run", "bar1d", "--n", "8", "--T", "1", "--out", str(tmp_path / "o"), "--quiet"])
    assert rc == 130
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert s["status"] == "interrupted" and "after the time loop" in s["message"]
    assert s["steps"] == round(s["T"] / s["dt"]) > 0


def _small_tmpfs(path) -> str | None:
    """Mount a 6 MiB tmpfs at ``path``; the reason when this machine does not allow it."""
    if shutil.which("mount") is None:
        return "no mount command"
    path.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=6m", "tmpfs", str(path)], capture_output=True, text=True)
    return None if r.returncode == 0 else f"cannot mount a tmpfs here: {r.stderr.strip()}"


def test_disk_full_while_streaming_fields_is_exit_4_in_one_line(tmp_path):
    mnt = tmp_path / "small"
    reason = _small_tmpfs(mnt)
    if reason:
        pytest.skip(reason)
    try:
        p = subprocess.run(
            [*CLI, "run", "bar2d", "--n", "8", "--T", "8", "--snapshot-every", "1", "--out", str(mnt / "o")],
            capture_output=True,
            text=True,
            cwd=tmp_path,
        )
        assert p.returncode == 4
        assert p.stderr.count("\n") == 1 and "No space left on device" in p.stderr
        assert list(mnt.iterdir()) == []
    finally:
        subprocess.run(["umount", str(mnt)])


def _children(pid: int) -> list[int]:
    out = []
    for task in os.listdir(f"/proc/{pid}/task"):
        with open(f"/proc/{pid}/task/{task}/children") as f:
            out += [int(c) for c in f.read().split()]
    return out


def test_crash_of_the_field_writer_is_exit_4_in_one_line(tmp_path):
    """HDF5 runs in a child process (io/field_process.py): a segmentation fault there (what a
    disk filled by another program during a write can do) ends the run with exit 4 and one
    line naming the signal, not with a crash of the run itself."""
    import time

    p = subprocess.Popen(
        [*CLI, "run", "bar2d", "--n", "8", "--T", "8", "--snapshot-every", "1", "--out", str(tmp_path / "o")],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path,
    )  # fmt: skip
    writer = None
    deadline = time.monotonic() + 60
    while writer is None and time.monotonic() < deadline and p.poll() is None:
        for child in _children(p.pid):
            with open(f"/proc/{child}/cmdline", "rb") as f:
                if b"spawn_main" in f.read():  # not the resource tracker
                    writer = child
        time.sleep(0.05)
    assert writer is not None, "the field writer process was not found"
    time.sleep(0.5)  # a few snapshots written
    os.kill(writer, signal.SIGSEGV)
    out, err = p.communicate(timeout=120)
    assert p.returncode == 4, err
    assert err.count("\n") == 1 and "field writer process died (signal SIGSEGV)" in err
    assert "Traceback" not in err

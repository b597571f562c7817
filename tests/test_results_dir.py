"""Result directories: nothing created for invalid input, no leftovers, clear errors."""

import json
import os
import signal
import subprocess
import sys
import time

import pytest

from signorini.errors import InputError
from signorini.io.cli import main
from signorini.io.results_dir import ResultDirectory, check_output_path


def _tree(root):
    return sorted(str(p.relative_to(root)) for p in root.rglob("*"))


@pytest.mark.parametrize("make_out", [lambda d: d / "afile" / "sub", lambda d: "/proc/signorini-test/x"])
def test_uncreatable_output_paths_exit_2_one_line(tmp_path, capsys, make_out):
    (tmp_path / "afile").write_text("")
    before = _tree(tmp_path)
    rc = main(["run", "bar1d", "--n", "4", "--T", "0.5", "--out", str(make_out(tmp_path)), "--quiet"])
    err = capsys.readouterr().err
    assert rc == 2
    assert err.count("\n") == 1 and err.startswith("signorini: error: --out") and "cannot be created" in err
    assert _tree(tmp_path) == before


def test_read_only_parent_is_an_input_error(tmp_path, monkeypatch):
    monkeypatch.setattr(os, "access", lambda path, mode: False)  # as an unprivileged user on a read-only dir
    with pytest.raises(InputError, match="no write permission"):
        check_output_path(tmp_path / "out", False)


REST = (
    '[mesh]\ngenerator = "interval"\ncells = [4]\nsize = [1.0]\n[material]\nrho = 1.0\nE = 1.0\n'
    '[[dirichlet]]\ntag = "xmax"\n[contact]\ntag = "xmin"\n'
    'obstacle = { type = "plane", point = [-0.1], normal = [1.0] }\n[time]\ndt = 0.25\nT = 1.0\n'
)


def test_invalid_input_found_in_set_up_creates_no_parent(tmp_path, capsys):
    """An error found during set-up (the plane's normal flipped) leaves no directory."""
    case = tmp_path / "flipped.toml"
    case.write_text(REST.replace("normal = [1.0]", "normal = [-1.0]"))
    rc = main(["run", str(case), "--out", str(tmp_path / "a" / "b" / "out"), "--quiet"])
    err = capsys.readouterr().err
    assert rc == 2 and "flip 'normal'" in err and err.count("\n") == 1
    assert _tree(tmp_path) == ["flipped.toml"]


def test_abort_removes_temporary_and_created_parents(tmp_path):
    rd = ResultDirectory(tmp_path / "x" / "y" / "out", overwrite=False)
    tmp = rd.create()
    (tmp / "file").write_text("partial")
    rd.abort()
    assert list(tmp_path.iterdir()) == []


def test_commit_replaces_only_at_the_end(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "old").write_text("old")
    with ResultDirectory(out, overwrite=True) as rd:
        (rd.create() / "new").write_text("new")
        assert (out / "old").exists()  # the old results stay until the commit
        rd.commit()
    assert _tree(tmp_path) == ["out", "out/new"]


def test_sigkilled_run_leaves_no_temporary_directory(tmp_path):
    out = tmp_path / "new" / "out"
    code = (
        "import sys; from signorini.io.cli import main; "
        f"sys.exit(main(['run', 'bar2d', '--n', '8', '--T', '40', '--snapshot-every', '50', '--out', {str(out)!r}, "
        "'--quiet']))"
    )
    proc = subprocess.Popen([sys.executable, "-c", code])
    deadline = time.time() + 60
    while time.time() < deadline and not any((tmp_path / "new").glob(".out.*")):
        time.sleep(0.05)
    assert any((tmp_path / "new").glob(".out.*")), "the run did not start"
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    deadline = time.time() + 10
    while time.time() < deadline and (tmp_path / "new").exists():
        time.sleep(0.05)
    assert not (tmp_path / "new").exists()  # temporary directory and the parent it created are gone


def test_zero_initial_energy_run(tmp_path, capsys):
    """A body at rest with no load: E(0) = 0, no relative drift, exit 0, finite JSON."""
    case = tmp_path / "rest.toml"
    case.write_text(REST)
    assert main(["run", str(case), "--out", str(tmp_path / "o")]) == 0
    assert "E0 = 0: no relative drift" in capsys.readouterr().out
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert s["energy_initial"] == 0.0 and s["energy_max_relative_drift"] is None

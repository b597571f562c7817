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
from signorini.io.results_dir import MARKER, ResultDirectory, check_output_path, is_result_directory, write_marker


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
    write_marker(out)
    with ResultDirectory(out, overwrite=True) as rd:
        (rd.create() / "new").write_text("new")
        assert (out / "old").exists()  # the old results stay until the commit
        rd.commit()
    assert _tree(tmp_path) == ["out", "out/.signorini", "out/new"]


def test_sigkilled_run_leaves_no_temporary_directory(tmp_path):
    out = tmp_path / "new" / "out"
    code = (
        "import sys; from signorini.io.cli import main; "
        f"sys.exit(main(['run', 'bar2d', '--n', '8', '--T', '40', '--snapshot-every', '50', '--out', {str(out)!r}, "
        "'--quiet']))"
    )
    proc = subprocess.Popen([sys.executable, "-c", code])
    deadline = time.time() + 60
    while time.time() < deadline and not any((tmp_path / "new").glob(".signorini-new.*")):
        time.sleep(0.05)
    assert any((tmp_path / "new").glob(".signorini-new.*")), "the run did not start"
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


# --- never delete what is not ours (issue 20, item 1) ---------------------------------------


def _run_quiet(out, *extra, cwd=None):
    args = ["run", "bar1d", "--n", "4", "--T", "0.5", "--out", str(out), "--quiet", *extra]
    return main(args)


def test_every_result_directory_carries_the_marker(tmp_path):
    assert _run_quiet(tmp_path / "o") == 0
    assert is_result_directory(tmp_path / "o")
    assert json.loads((tmp_path / "o" / MARKER).read_text())["written_by"] == "signorini"


def test_overwrite_refuses_a_directory_the_tool_did_not_write(tmp_path, capsys):
    victim = tmp_path / "project"
    victim.mkdir()
    (victim / "thesis.tex").write_text("precious")
    before = _tree(tmp_path)
    assert _run_quiet(victim, "--overwrite") == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "not a result of signorini (it has no .signorini marker)" in err
    assert _tree(tmp_path) == before


def test_a_forged_or_symlinked_marker_is_not_ours(tmp_path):
    d = tmp_path / "d"
    d.mkdir()
    (d / MARKER).write_text("not json")
    assert not is_result_directory(d)
    (d / MARKER).unlink()
    (tmp_path / "real").write_text(json.dumps({"written_by": "signorini"}))
    (d / MARKER).symlink_to(tmp_path / "real")
    assert not is_result_directory(d)


@pytest.mark.parametrize("target", [".", "..", "../..", "/"])
def test_overwrite_never_touches_the_working_directory_or_its_parents(tmp_path, monkeypatch, capsys, target):
    work = tmp_path / "a" / "b"
    work.mkdir(parents=True)
    write_marker(work)  # even a directory that looks like ours
    write_marker(tmp_path / "a")
    (work / "case.toml").write_text(REST)
    monkeypatch.chdir(work)
    before = _tree(tmp_path)
    assert _run_quiet(target, "--overwrite") == 2
    err = capsys.readouterr().err
    assert "working directory" in err and err.count("\n") == 1
    assert _tree(tmp_path) == before


def test_case_file_output_directory_dotdot_with_overwrite_deletes_nothing(tmp_path, monkeypatch, capsys):
    work = tmp_path / "w"
    work.mkdir()
    (tmp_path / "unrelated.txt").write_text("keep me")
    (work / "case.toml").write_text(REST + '[output]\ndirectory = ".."\n')
    monkeypatch.chdir(work)
    before = _tree(tmp_path)
    assert main(["run", "case.toml", "--overwrite", "--quiet"]) == 2
    assert _tree(tmp_path) == before


def test_overwrite_replaces_an_empty_directory_not_marked(tmp_path):
    (tmp_path / "o").mkdir()
    assert _run_quiet(tmp_path / "o", "--overwrite") == 0
    assert (tmp_path / "o" / "summary.json").exists()


@pytest.mark.parametrize("kind", ["dangling", "loop"])
def test_broken_symlinked_out_is_refused_before_computing(tmp_path, capsys, kind):
    link = tmp_path / "link"
    link.symlink_to(tmp_path / ("nowhere" if kind == "dangling" else "link"))
    assert _run_quiet(link) == 2
    err = capsys.readouterr().err
    assert "symbolic link" in err and err.count("\n") == 1
    assert _tree(tmp_path) == ["link"]


def test_symlinked_out_to_an_empty_directory_writes_into_the_target(tmp_path):
    (tmp_path / "target").mkdir()
    (tmp_path / "link").symlink_to(tmp_path / "target")
    assert _run_quiet(tmp_path / "link") == 0
    assert (tmp_path / "link").is_symlink() and (tmp_path / "target" / "summary.json").exists()


def test_symlink_to_a_full_directory_not_ours_is_refused_with_overwrite(tmp_path, capsys):
    (tmp_path / "target").mkdir()
    (tmp_path / "target" / "data").write_text("x")
    (tmp_path / "link").symlink_to(tmp_path / "target")
    assert _run_quiet(tmp_path / "link", "--overwrite") == 2
    assert (tmp_path / "target" / "data").read_text() == "x"


@pytest.mark.parametrize("length", [250, 255, 256, 300])
def test_path_length_limits_are_checked_before_computing(tmp_path, capsys, length):
    """A name the file system cannot hold is exit 2 whatever its length; one it can is written."""
    out = tmp_path / ("x" * length)
    rc = _run_quiet(out)
    err = capsys.readouterr().err
    if length <= 255:
        assert rc == 0 and out.is_dir()
    else:
        assert rc == 2 and "longer than" in err
        assert list(tmp_path.iterdir()) == []


def test_nul_byte_in_out_is_an_input_error(tmp_path, capsys):
    assert _run_quiet(str(tmp_path / "a\0b")) == 2
    assert "NUL" in capsys.readouterr().err


def _marked_result(path, files):
    path.mkdir()
    for i in range(files):
        (path / f"f{i}").write_text("old")
    write_marker(path)


def test_kill_during_commit_leaves_one_complete_result(tmp_path):
    """SIGKILL after the old result was moved aside: the watchdog puts the new one in place."""
    out = tmp_path / "out"
    _marked_result(out, 3)
    code = (
        "import os, signal, sys\n"
        "from pathlib import Path\n"
        "from signorini.io.results_dir import ResultDirectory\n"
        f"rd = ResultDirectory(Path({str(out)!r}), overwrite=True)\n"
        "(rd.create() / 'new').write_text('new')\n"
        "real_rename = os.rename\n"
        "def rename(a, b):\n"
        "    real_rename(a, b)\n"
        "    if '.signorini-old.' in str(b):\n"
        "        os.kill(os.getpid(), signal.SIGKILL)\n"
        "os.rename = rename\n"
        "rd.commit()\n"
    )
    proc = subprocess.run([sys.executable, "-c", code])
    assert proc.returncode == -signal.SIGKILL
    deadline = time.time() + 10
    while time.time() < deadline and len(list(tmp_path.iterdir())) > 1:
        time.sleep(0.05)
    assert _tree(tmp_path) == ["out", "out/.signorini", "out/new"]


def test_commit_moves_the_old_result_aside_before_deleting_it(tmp_path, monkeypatch):
    """The old directory is renamed, the new one renamed in, and only then the old one removed."""
    import shutil

    out = tmp_path / "out"
    _marked_result(out, 2)
    seen = []
    real_rmtree = shutil.rmtree

    def rmtree(p, *a, **k):
        seen.append((str(p), (out / "new").exists()))
        real_rmtree(p, *a, **k)

    monkeypatch.setattr(shutil, "rmtree", rmtree)
    with ResultDirectory(out, overwrite=True) as rd:
        (rd.create() / "new").write_text("new")
        rd.commit()
    assert seen and all(".signorini-old." in p and new_in_place for p, new_in_place in seen)
    assert _tree(tmp_path) == ["out", "out/.signorini", "out/new"]


# --- concurrent runs (issue 20, item 2) -----------------------------------------------------


def test_second_run_to_finish_does_not_replace_the_first(tmp_path):
    """Both started on an empty --out without --overwrite: the later commit keeps its results beside."""
    out = tmp_path / "out"
    first = ResultDirectory(out, overwrite=False)
    second = ResultDirectory(out, overwrite=False)
    (first.create() / "who").write_text("first")
    (second.create() / "who").write_text("second")
    first.commit()
    from signorini.io.results_dir import ResultConflict

    with pytest.raises(ResultConflict, match="written by another run meanwhile") as info:
        second.commit()
    assert (out / "who").read_text() == "first"
    kept = [p for p in tmp_path.iterdir() if p.name.startswith("out.kept-")]
    assert len(kept) == 1 and (kept[0] / "who").read_text() == "second" and str(kept[0]) in str(info.value)


def test_concurrent_cli_runs_never_replace_each_other(tmp_path):
    """Two runs started together on one --out: one writes it (exit 0); the other either finds it
    taken at start (exit 2, when the first finished before it looked) or at the end (exit 4, its
    results kept beside).  Never two exit 0, never a lost result."""
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "signorini.io.cli", "run", "bar2d", "--n", "4", "--T", "20", "--out", str(out)]
    procs = [subprocess.Popen([*cmd, "--quiet"], stderr=subprocess.PIPE, text=True) for _ in range(2)]
    results = sorted((p.wait(), p.stderr.read()) for p in procs)
    assert results[0][0] == 0 and results[1][0] in (2, 4) and results[1][1].count("\n") == 1
    kept = [p for p in tmp_path.iterdir() if p.name.startswith("out.kept-")]
    if results[1][0] == 4:
        assert "this run's results are in" in results[1][1] and len(kept) == 1 and is_result_directory(kept[0])
    else:
        assert "is not empty" in results[1][1] and not kept
    assert is_result_directory(out) and (out / "summary.json").exists()


def test_a_file_added_to_a_result_directory_makes_it_not_ours(tmp_path, capsys):
    """The marker lists what signorini wrote: a user's notes added later are never deleted by --overwrite."""
    out = tmp_path / "proj"
    assert _run_quiet(out) == 0
    assert is_result_directory(out)
    (out / "notes.md").write_text("mine")
    assert not is_result_directory(out)
    assert _run_quiet(out, "--overwrite") == 2
    err = capsys.readouterr().err  # the real reason: the marker is there, the notes are not listed in it
    assert "it holds 'notes.md', which signorini did not write there" in err and "no .signorini marker" not in err
    assert (out / "notes.md").read_text() == "mine"


@pytest.mark.parametrize("name", ["a\nb", "tab\there", "~/x", "~"])
def test_control_characters_and_tilde_in_out_are_refused(tmp_path, monkeypatch, capsys, name):
    monkeypatch.chdir(tmp_path)
    assert _run_quiet(name) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and ("control character" in err or "'~'" in err)
    assert list(tmp_path.iterdir()) == []


def test_result_directory_follows_the_umask(tmp_path):
    old = os.umask(0o077)
    try:
        assert _run_quiet(tmp_path / "o") == 0
    finally:
        os.umask(old)
    assert (tmp_path / "o").stat().st_mode & 0o777 == 0o700


def test_a_dangling_link_in_the_middle_of_out_is_refused(tmp_path, capsys):
    (tmp_path / "dl").symlink_to(tmp_path / "nowhere")
    assert _run_quiet(tmp_path / "dl" / "sub") == 2
    assert "symbolic link" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dl"]


def test_an_empty_out_is_refused(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert _run_quiet("") == 2
    assert "must not be empty" in capsys.readouterr().err
    (tmp_path / "c.toml").write_text(REST + '[output]\ndirectory = ""\n')
    assert main(["run", "c.toml", "--quiet"]) == 2
    assert list(p.name for p in tmp_path.iterdir()) == ["c.toml"]

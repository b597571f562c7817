"""A checkpoint is data: `signorini resume` never imports or executes anything it names
(issue 38, item 1).  A scheme of the user's own is named again with ``--scheme`` and checked
against the checkpoint's record; every kept argument is type-checked; the checksum is
verified before any field is used; ``--T`` defaults to the run's own final time."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

import signorini.dynamics.restart.checkpoint as ckpt

ROOT = Path(__file__).parents[2]
#: code that leaves a marker file when it runs (what an attacker would put in a named file)
EVIL = "from pathlib import Path\nPath(__file__).with_name('EXECUTED').write_text('yes')\n"


def _cli(*args, cwd):
    return subprocess.run(
        [sys.executable, "-m", "signorini", *args], cwd=cwd, capture_output=True, text=True, timeout=300
    )


def _forge(path: Path, edit) -> None:
    """Edit a checkpoint's attributes and recompute its checksum (a forged file, not a corrupt one)."""
    contents = ckpt.read(path)
    edit(contents["attrs"])
    ckpt.write(path, {"arrays": contents["arrays"], "attrs": contents["attrs"]})


def _refused(r, tmp_path: Path, out: str = "b") -> None:
    assert r.returncode == 2, r.stderr
    assert "Traceback" not in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert not (tmp_path / out).exists() and not list(tmp_path.rglob("EXECUTED"))


@pytest.fixture
def plugin_run(tmp_path):
    """A run of bar2d with the scheme of examples/my_schemes.py, to T = 0.3 (checkpointed)."""
    (tmp_path / "my_schemes.py").write_text((ROOT / "examples" / "my_schemes.py").read_text())
    args = ["run", "bar2d", "--n", "2", "--scheme", "my_schemes.py:MyTheta", "--scheme-option", "theta=0.6"]
    r = _cli(*args, "--T", "0.3", "--quiet", "--out", "a", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    return args


def test_a_plugin_scheme_is_never_imported_from_the_checkpoint(tmp_path, plugin_run):
    """The file the checkpoint names is replaced by hostile code: resume without --scheme is
    refused (naming --scheme) and runs nothing; the checkpoint's path is never imported."""
    (tmp_path / "my_schemes.py").write_text(EVIL + (ROOT / "examples" / "my_schemes.py").read_text())
    r = _cli("resume", "a", "--T", "0.6", "--out", "b", cwd=tmp_path)
    _refused(r, tmp_path)
    assert "--scheme" in r.stderr and "never imports code" in r.stderr


def test_a_plugin_scheme_named_again_resumes_bit_for_bit(tmp_path, plugin_run):
    r = _cli("resume", "a", "--scheme", "my_schemes.py:MyTheta", "--T", "0.6", "--quiet", "--out", "b", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert _cli(*plugin_run, "--T", "0.6", "--quiet", "--out", "c", cwd=tmp_path).returncode == 0
    assert (tmp_path / "b/history.csv").read_text() == (tmp_path / "c/history.csv").read_text()


def test_another_scheme_named_on_resume_is_refused_by_name(tmp_path, plugin_run):
    r = _cli("resume", "a", "--scheme", "theta", "--T", "0.6", "--out", "b", cwd=tmp_path)
    _refused(r, tmp_path)
    assert "scheme differs" in r.stderr and "my-theta" in r.stderr


def _set_invocation(key, value):
    def edit(attrs):
        attrs["meta"]["invocation"][key] = value

    return edit


#: every attribute of a checkpoint that names a file, a module or an expression, edited to
#: hostile code (with the checksum recomputed), and what the refusal says
HOSTILE_EDITS = {
    "scheme-file": (_set_invocation("scheme", "{dir}/evil.py:Evil"), "--scheme"),
    "scheme-module": (_set_invocation("scheme", "evil:Evil"), "--scheme"),
    "scheme-dotted": (_set_invocation("scheme", "evil.Evil"), "--scheme"),
    "target-python-file": (_set_invocation("target", "{dir}/evil.py"), "evil.py"),
    "target-module": (_set_invocation("target", "evil:Evil"), "evil:Evil"),
    "backend-module": (_set_invocation("backend", "evil:Evil"), "backend"),
    "solver-option": (_set_invocation("solver_option", ["backend=evil:Evil"]), "backend"),
    "preconditioner": (_set_invocation("solver_option", ["backend=cg", "preconditioner=evil:Evil"]), "evil"),
    "stop-at": (_set_invocation("stop_at", "__import__('evil')"), "stop"),
    "set-expression": (_set_invocation("set", ["gap=__import__('evil')"]), "gap"),
    "mass": (_set_invocation("mass", "evil:Evil"), "mass"),
    "scheme-not-a-string": (_set_invocation("scheme", ["evil.py", "Evil"]), "scheme"),
    "n-not-an-integer": (_set_invocation("n", "__import__('evil')"), "'n'"),
    "unknown-argument": (_set_invocation("exec", "evil"), "exec"),
    "invocation-not-a-table": (lambda a: a["meta"].__setitem__("invocation", "evil.py"), "signorini run"),
    "meta-not-a-table": (lambda a: a.__setitem__("meta", ["evil.py"]), "signorini run"),
}


@pytest.mark.parametrize("how", sorted(HOSTILE_EDITS))
def test_a_forged_checkpoint_never_executes_code(tmp_path, how):
    """Each attribute that names a file, a module or an expression is edited to a hostile one
    (evil.py beside the result and importable from the working directory, its checksum
    recomputed): exit 2 in one line naming what is wrong, nothing written, nothing executed."""
    assert _cli("run", "bar2d", "--n", "2", "--T", "0.3", "--quiet", "--out", "a", cwd=tmp_path).returncode == 0
    (tmp_path / "evil.py").write_text(EVIL + "class Evil:\n    pass\n")
    edit, says = HOSTILE_EDITS[how]

    def with_dir(attrs):
        edit(attrs)
        inv = attrs["meta"].get("invocation") if isinstance(attrs.get("meta"), dict) else None
        if isinstance(inv, dict):
            for k, v in inv.items():
                if isinstance(v, str):
                    inv[k] = v.replace("{dir}", str(tmp_path))

    _forge(tmp_path / "a/checkpoint.h5", with_dir)
    r = _cli("resume", "a", "--T", "0.6", "--out", "b", cwd=tmp_path)
    _refused(r, tmp_path)
    assert says in r.stderr, r.stderr


def test_an_edited_invocation_without_its_checksum_is_refused_before_use(tmp_path):
    """The invocation edited in place (checksum not recomputed): refused as an edited file
    before any field is used, even though the scheme it names would run."""
    import h5py

    assert _cli("run", "bar2d", "--n", "2", "--T", "0.3", "--quiet", "--out", "a", cwd=tmp_path).returncode == 0
    (tmp_path / "evil.py").write_text(EVIL)
    with h5py.File(tmp_path / "a/checkpoint.h5", "a") as f:
        meta = json.loads(f.attrs["meta"])
        meta["invocation"]["scheme"] = str(tmp_path / "evil.py") + ":Evil"
        f.attrs["meta"] = json.dumps(meta)
    r = _cli("resume", "a", "--T", "0.6", "--out", "b", cwd=tmp_path)
    _refused(r, tmp_path)
    assert "checksum" in r.stderr


def test_resume_without_T_finishes_the_interrupted_run(tmp_path):
    """A run stopped early (here by --stop-at first-contact, status finished at the event) is
    resumed without --T to the T it was started with; a run that reached its T asks for one."""
    args = ["run", "bar2d", "--n", "2", "--T", "0.6"]
    assert _cli(*args, "--stop-at", "first-contact", "--quiet", "--out", "a", cwd=tmp_path).returncode == 0
    stopped = json.loads((tmp_path / "a/summary.json").read_text())
    assert stopped["steps"] < 48
    _forge(tmp_path / "a/checkpoint.h5", _set_invocation("stop_at", None))  # as if interrupted there
    r = _cli("resume", "a", "--quiet", "--out", "b", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert _cli(*args, "--quiet", "--out", "c", cwd=tmp_path).returncode == 0
    assert (tmp_path / "b/history.csv").read_text() == (tmp_path / "c/history.csv").read_text()
    r = _cli("resume", "c", "--out", "d", cwd=tmp_path)
    _refused(r, tmp_path, "d")
    assert "already reached its final time T = 0.6" in r.stderr and "--T" in r.stderr


def test_dt_and_T_override_a_case_file_and_the_summary_says_so(tmp_path):
    case = ROOT / "examples" / "bar2d.toml"
    r = _cli("run", str(case), "--dt", "0.025", "--T", "0.5", "--dt-control", "fixed", "--out", "a", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    s = json.loads((tmp_path / "a/summary.json").read_text())
    assert s["steps"] == 20 and s["dt"] == 0.025 and s["T"] == 0.5
    assert s["overrides"] == {"dt": {"case_file": 0.0125, "command_line": 0.025},
                              "T": {"case_file": 1.0, "command_line": 0.5}}  # fmt: skip
    assert "over the case file: dt 0.025 (the file's 0.0125), T 0.5 (the file's 1)" in r.stdout
    r = _cli("run", str(case), "--dt", "0.3", "--T", "0.5", "--out", "b", cwd=tmp_path)
    assert r.returncode == 2 and "not an integer multiple" in r.stderr and not (tmp_path / "b").exists()


@pytest.mark.parametrize("damage", ["missing-h5", "truncated-h5", "garbage-xdmf"])
def test_damaged_fields_of_the_source_run_are_refused_before_the_resume_starts(tmp_path, damage):
    """The earlier fields a resume copies are read first: missing, truncated or edited, exit 2 in
    one line naming them (the checkpoint is intact; --snapshot-every 0 leaves them out), nothing
    written; they used to fail midway (an internal error, or a machine failure, exit 4)."""
    r = _cli("run", "bar2d", "--n", "2", "--T", "0.3", "--snapshot-every", "4", "--quiet", "--out", "a", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    h5, xdmf = tmp_path / "a/fields.h5", tmp_path / "a/fields.xdmf"
    if damage == "missing-h5":
        h5.unlink()
    elif damage == "truncated-h5":
        h5.write_bytes(h5.read_bytes()[: h5.stat().st_size // 2])
    else:
        xdmf.write_text("garbage")
    r = _cli("resume", "a", "--T", "0.6", "--out", "b", cwd=tmp_path)
    _refused(r, tmp_path)
    assert "the fields of the run to resume" in r.stderr and "--snapshot-every 0" in r.stderr
    r = _cli("resume", "a", "--T", "0.6", "--snapshot-every", "0", "--quiet", "--out", "b", cwd=tmp_path)
    assert r.returncode == 0, r.stderr


def _set(path_in_attrs, value):
    def edit(attrs):
        node = attrs
        for k in path_in_attrs[:-1]:
            node = node[k]
        node[path_in_attrs[-1]] = value

    return edit


#: forged attributes (checksum recomputed) that used to crash, allocate without bound or be
#: copied into the result: each is now a one-line refusal
FORGED = {
    "n-huge": (_set(["meta", "invocation", "n"], 10**6), "estimated memory"),
    "n-absurd": (_set(["meta", "invocation", "n"], 10**30), "estimated memory"),
    "segment-huge-level": (_set(["segment"], [0.0, 1e-300, 10**30]), "segment"),
    "series-records": (_set(["series", "records"], 10**18), "series file"),
    "series-layout": (lambda a: a["series"]["layout"][0].__setitem__(2, [10**15]), "series file"),
    "negative-counter": (lambda a: a["counters"].__setitem__("linear_solves", -5), "counter"),
    "untagged-worst-node": (_set(["observers/untagged/worst"], [1.0, 999999, 0.1]), "untagged watch"),
    "untagged-worst-text": (_set(["observers/untagged/worst"], ["a", 3, 0.0]), "untagged watch"),
    "master-worst-short": (_set(["observers/untagged/master_worst"], [1.0, 2]), "master watch"),
    "master-worst-nested": (_set(["observers/untagged/master_worst"], [[1], 3, 0.0]), "master watch"),
}


@pytest.mark.parametrize("how", sorted(FORGED))
def test_forged_sizes_and_indices_are_refused_before_the_run(tmp_path, how):
    assert _cli("run", "bar2d", "--n", "2", "--T", "0.3", "--quiet", "--out", "a", cwd=tmp_path).returncode == 0
    edit, says = FORGED[how]
    _forge(tmp_path / "a/checkpoint.h5", edit)
    r = _cli("resume", "a", "--T", "0.6", "--out", "b", cwd=tmp_path)
    _refused(r, tmp_path)
    assert says in r.stderr, r.stderr


def test_a_forged_delassus_log_is_refused_not_run(tmp_path):
    """A sliding pair's re-pairing log with a negative row count (the sum kept): the resume used
    to build a malformed sparse matrix and corrupt the heap (double free); now exit 2."""
    text = (ROOT / "examples" / "block_on_block.toml").read_text()
    text = text.replace('"meshes/block_on_block.msh"', repr(str(ROOT / "examples/meshes/block_on_block.msh")))
    text = text.replace("velocity = [0.2, 0.0]", "velocity = [1.0, 0.0]")
    (tmp_path / "slide.toml").write_text(text)
    r = _cli("run", "slide.toml", "--T", "0.012", "--quiet", "--out", "a", cwd=tmp_path)
    assert r.returncode == 0, r.stderr

    def edit(arrays):
        x = arrays["solvers/0/delassus/row_nnz"].copy()
        x[0], x[1] = -6, x[1] + x[0] + 6
        arrays["solvers/0/delassus/row_nnz"] = x

    c = ckpt.read(tmp_path / "a/checkpoint.h5")
    edit(c["arrays"])
    ckpt.write(tmp_path / "a/checkpoint.h5", {"arrays": c["arrays"], "attrs": c["attrs"]})
    r = _cli("resume", "a", "--T", "0.024", "--out", "b", cwd=tmp_path)
    _refused(r, tmp_path)
    assert "the Delassus column log is inconsistent" in r.stderr


def test_a_fifo_in_the_fields_is_refused_not_waited_on(tmp_path):
    import os

    r = _cli("run", "bar2d", "--n", "2", "--T", "0.3", "--snapshot-every", "4", "--quiet", "--out", "a", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    (tmp_path / "a/fields.h5").unlink()
    os.mkfifo(tmp_path / "a/fields.h5")
    r = _cli("resume", "a", "--T", "0.6", "--out", "b", cwd=tmp_path)
    _refused(r, tmp_path)
    assert "not a regular file" in r.stderr


def test_a_changed_scheme_file_is_refused_on_resume(tmp_path, plugin_run):
    """Same class name and options, other code: the checkpoint's identity holds the source
    file's hash, so the resumed run would not be the uninterrupted one: refused by name."""
    (tmp_path / "alt").mkdir()
    (tmp_path / "alt/my_schemes.py").write_text((ROOT / "examples" / "my_schemes.py").read_text() + "# changed\n")
    r = _cli("resume", "a", "--scheme", "alt/my_schemes.py:MyTheta", "--T", "0.6", "--out", "b", cwd=tmp_path)
    _refused(r, tmp_path)
    assert "the source file of the scheme of your own" in r.stderr


def test_a_dt_schedule_under_the_energy_control_resumes_bit_for_bit(tmp_path):
    """Issue 52: a case with a dt schedule under the energy control could not be resumed ("internal error:
    TypeError": the resume's step count divided by the schedule).  Run to T = 3e-5 (inside the second piece of the
    schedule, after the impact), resumed to 6e-5: the history of one run to 6e-5, byte for byte."""
    text = (ROOT / "examples" / "steel_block_drop.toml").read_text()
    text = text.replace("dt = 5e-6", "dt = [{until = 2e-5, dt = 5e-6}, {until = 1e-4, dt = 2.5e-6}]")
    text = text.replace("T = 5e-5", "T = 6e-5")
    (tmp_path / "case.toml").write_text(text)
    assert _cli("run", "case.toml", "--T", "3e-5", "--quiet", "--out", "a", cwd=tmp_path).returncode == 0
    r = _cli("resume", "a", "--T", "6e-5", "--quiet", "--out", "b", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert _cli("run", "case.toml", "--quiet", "--out", "c", cwd=tmp_path).returncode == 0
    assert json.loads((tmp_path / "b/summary.json").read_text())["time_control"]["control"] == "energy"
    assert (tmp_path / "b/history.csv").read_text() == (tmp_path / "c/history.csv").read_text()


def _time_control(key, value):
    def edit(attrs):
        if value is _DELETE:
            del attrs[key]
        else:
            attrs["time_control"][key] = value(attrs["time_control"][key]) if callable(value) else value

    return edit


_DELETE = object()
#: forged states of the energy control (re-signed checkpoints) and what the refusal names (issue 52)
FORGED_CONTROL = {
    "plan-string": (_time_control("plan_dt", "5e-6"), "plan_dt '5e-6' is not a positive number"),
    "plan-list": (_time_control("plan_dt", [5e-6]), "is not a positive number"),
    "plan-true": (_time_control("plan_dt", True), "is not a positive number"),
    "plan-doubled": (_time_control("plan_dt", lambda v: 2 * v), "is not the energy control's largest step"),
    "state-deleted": (_time_control("time_control", _DELETE), "the energy control's state is missing"),
    "accepted-beyond-levels": (_time_control("accepted", 10**6), "'accepted' = 1000000 is more than its"),
    # the resting-contact memory and the spurious energy's cycles (added by the same issue)
    "prev-sum-string": (_time_control("prev_sum", "1.0"), "'prev_sum' must be a finite number or null"),
    "persistent-int": (_time_control("persistent", 1), "'persistent' must be true or false"),
    # the growth's backoff (growths rejected in a row)
    "backoff-beyond": (_time_control("backoff", 7), "'backoff' must be an integer in [0, 6], got 7"),
    "backoff-float": (_time_control("backoff", 1.0), "'backoff' must be an integer in"),
    "just-grown-string": (_time_control("just_grown", "yes"), "'just_grown' must be true or false"),
    "created-negative": (
        lambda a: a.__setitem__("observers/energy/cycles_created", -1.0),
        "the energy's created must be a finite number >= 0",
    ),
    "destroyed-string": (
        lambda a: a.__setitem__("observers/energy/cycles_destroyed", "x"),
        "the energy's destroyed must be a finite number >= 0",
    ),
    "first-beyond-levels": (lambda a: a.__setitem__("observers/energy/cycles_first", 10**6), "is not a level"),
}


@pytest.mark.parametrize("forge", FORGED_CONTROL, ids=list(FORGED_CONTROL))
def test_a_forged_energy_control_state_is_refused(tmp_path, forge):
    """Issue 52: a re-signed checkpoint whose control's largest step was a string, a list, true or another number, or
    whose control state was deleted, was accepted and the resume computed another history."""
    edit, words = FORGED_CONTROL[forge]
    (tmp_path / "case.toml").write_text((ROOT / "examples" / "steel_block_drop.toml").read_text())
    assert _cli("run", "case.toml", "--T", "3e-5", "--quiet", "--out", "a", cwd=tmp_path).returncode == 0
    _forge(tmp_path / "a/checkpoint.h5", edit)
    r = _cli("resume", "a", "--T", "6e-5", "--quiet", "--out", "b", cwd=tmp_path)
    _refused(r, tmp_path)
    assert words in r.stderr, r.stderr

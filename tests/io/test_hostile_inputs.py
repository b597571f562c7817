"""Inputs that used to be accepted silently, split or end in an internal error (issue 38,
item 6): each is now a one-line refusal naming what is wrong, or does what it says."""

import dataclasses

import pytest

from signorini.contact.pairs import ContactPair
from signorini.dynamics.observe.events import Event
from signorini.dynamics.stepping.simulate import simulate
from signorini.errors import InputError
from signorini.io.cli import main
from test_pairs import bars


def test_one_event_name_is_one_event_not_its_characters():
    """``simulate(events="separation")`` (a string, not a list) stops at the separation, as
    ``events=["separation"]`` does (it was split into 's', 'e', ...)."""
    p, dt = bars(1, 2, 2), 0.025
    H = simulate(p, "cn", dt, 3.0, events="separation")
    H_list = simulate(p, "cn", dt, 3.0, events=["separation"])
    assert H.meta["events"] == H_list.meta["events"] and H.meta["events"][0]["name"] == "separation"
    one = Event("x > 0", lambda t, s: 1.0, terminal=False)
    assert simulate(p, "cn", dt, 0.1, events=one).status == "finished"
    with pytest.raises(InputError, match="events: 3 is neither an event name"):
        simulate(p, "cn", dt, 0.1, events=[3])


@pytest.mark.parametrize("observer, says", [(3, "int object is not an observer"), ("x", "str object is not")])
def test_an_observer_of_the_wrong_type_is_refused_by_name(observer, says):
    with pytest.raises(InputError, match=says):
        simulate(bars(1, 2, 2), "cn", 0.025, 0.1, observers=[observer])


def test_a_checkpoint_path_that_is_a_directory_says_so(tmp_path):
    with pytest.raises(InputError, match="is a directory, not a checkpoint file"):
        simulate(bars(1, 2, 2), "cn", 0.025, 0.1, resume=tmp_path)


def test_a_pair_listed_in_both_directions_is_refused():
    p = bars(2, 1, 1)
    pairs = [ContactPair("right_ymin", "left_ymax"), ContactPair("left_ymax", "right_ymin")]
    with pytest.raises(InputError, match="one pair listed in both directions: list it once"):
        simulate(dataclasses.replace(p, pairs=pairs), "cn", 0.01, 0.02)


def test_a_pair_on_one_body_is_refused_as_self_contact():
    """A pair whose slave and master tags are on one body (the faces of a U-shaped part): the
    pair faced the body's own far side from t = 0 (a penetration reported at t = 0)."""
    from signorini.contact.obstacles import PlaneObstacle
    from signorini.dynamics.model.problem import Problem
    from signorini.fem.material import IsotropicElastic
    from signorini.fem.mesh import rectangle

    m = rectangle(2, 6, 0.2, 0.6)
    p = Problem(m, IsotropicElastic.from_young(1.0, 0.3, 1.0), "xmin", PlaneObstacle([-0.1, 0.0], [1.0, 0.0]),
                pairs=[ContactPair("ymax", "ymin")])  # fmt: skip
    with pytest.raises(InputError, match=r"both tags are on body 0 .*self-contact is not supported"):
        simulate(p, "cn", 0.01, 0.02)


def test_contact_where_with_pairs_only_is_refused(tmp_path, capsys):
    """``[contact] where`` restricts the rigid obstacle's nodes; with pairs only it was never
    applied (silently)."""
    from pathlib import Path

    case = (Path(__file__).parents[1] / "contact" / "test_pairs_backends.py").read_text()
    text = case[case.index('CASE_FILE = """') + len('CASE_FILE = """') :]
    text = text[: text.index('"""')]
    from signorini.fem.mesh import write_mesh
    from test_pairs_backends import block_on_plate

    write_mesh(block_on_plate().mesh, tmp_path / "block_on_plate.msh")
    bad = tmp_path / "case.toml"
    bad.write_text(text.replace("[contact]\n", '[contact]\nwhere = "x < 0.5"\n'))
    assert main(["run", str(bad), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "'contact.where'" in err and "contact pairs only" in err and err.count("\n") == 1
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("stiffness", ["1e9", "1e12"])
def test_an_energy_identity_that_does_not_close_warns_or_fails(tmp_path, capsys, stiffness):
    """A unit mismatch (the bar's Lame constants 1e9 to 1e12 times too large for its density):
    the identity's residual (1.8e-4 and 0.16 of the largest energy, measured) warns; with
    energy_check=fail the run stops at the first such step (exit 3) and keeps its levels.
    The same bar in consistent units closes to 1e-14 and says nothing."""
    import json
    from pathlib import Path

    text = (Path(__file__).parents[2] / "examples" / "bar2d.toml").read_text()
    case = tmp_path / "units.toml"
    case.write_text(text.replace("lam = 0.25", f"lam = {stiffness}").replace("mu = 0.5", f"mu = {stiffness}"))
    assert main(["run", str(case), "--T", "0.25", "--out", str(tmp_path / "a"), "--quiet"]) == 0
    s = json.loads((tmp_path / "a" / "summary.json").read_text())
    assert any("the energy identity does not close" in w for w in s["warnings"])
    assert "check the units" in capsys.readouterr().err
    out = str(tmp_path / "b")
    assert main(["run", str(case), "--T", "0.25", "--out", out, "--quiet", "--solver-option", "energy_check=fail"]) == 3
    s = json.loads((tmp_path / "b" / "summary.json").read_text())
    assert s["status"] == "failed" and "energy identity does not close" in s["message"] and s["steps"] == 0
    assert (tmp_path / "b" / "history.csv").read_text().count("\n") == 2  # the header and level 0, kept
    case.write_text(text)
    out = str(tmp_path / "c")
    assert main(["run", str(case), "--T", "0.25", "--out", out, "--quiet", "--solver-option", "energy_check=fail"]) == 0
    s = json.loads((tmp_path / "c" / "summary.json").read_text())
    assert not any("energy identity" in w for w in s["warnings"])


def test_a_file_size_limit_at_the_final_write_keeps_a_resumable_result(tmp_path):
    """ulimit -f between the checkpoint.s files (91 KiB at most) and history.csv (128 KiB): the run
    used to lose everything, its complete checkpoint included, with a message naming no file.
    Now exit 4 naming history.csv; --out holds the checkpoint and a summary saying what failed,
    and `signorini resume` continues it."""
    import json
    import resource
    import subprocess
    import sys

    def limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (110 * 1024, 110 * 1024))

    args = [sys.executable, "-m", "signorini", "run", "bar2d", "--n", "4", "--T", "4", "--quiet", "--out"]
    r = subprocess.run([*args, str(tmp_path / "a")], capture_output=True, text=True, preexec_fn=limit, timeout=300)
    assert r.returncode == 4, r.stderr
    assert "writing history.csv failed: File too large" in r.stderr and "resumable" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1
    s = json.loads((tmp_path / "a" / "summary.json").read_text())
    assert s["status"] == "failed" and s["resumable"] and "writing history.csv failed" in s["message"]
    assert not (tmp_path / "a" / "history.csv").exists() and (tmp_path / "a" / "checkpoint.h5").is_file()
    r = subprocess.run([sys.executable, "-m", "signorini", "resume", str(tmp_path / "a"), "--T", "4.5", "--quiet",
                        "--out", str(tmp_path / "b")], capture_output=True, text=True, timeout=300)  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "b" / "history.csv").read_text().count("\n") == 1 + 361  # levels 0..360 (dt = 0.0125)


def test_a_pair_with_the_worse_slave_side_warns_naming_the_better_choice():
    """Node to facet is one-sided: a slave side coarser than the master (two bars, the slave's
    face in one cell against two) or flat against a curved master (the plate's top as slave
    under the ball's skin) gets a warning naming the swap; the right choice gets none."""
    from pathlib import Path

    from signorini.contact.pairs import pair_side_warning
    from signorini.io.config import load_case

    H = simulate(bars(2, 2, 1), "cn", 0.025, 0.05)  # slave right_ymin: 1 cell across, master: 2
    (w,) = [w for w in H.meta["warnings"] if "contact pair" in w]
    assert "the slave side is the coarser one" in w and "slave = 'left_ymax', master = 'right_ymin'" in w
    assert H.meta["pairs"][0]["warning"] == w
    H = simulate(bars(2, 1, 2), "cn", 0.025, 0.05)  # the finer side as slave
    assert not any("contact pair" in w for w in H.meta["warnings"]) and H.meta["pairs"][0]["warning"] == ""
    case = load_case(Path(__file__).parents[2] / "examples" / "ball_on_plate.toml")
    (p,) = case.problem.pairs
    assert pair_side_warning(case.problem.mesh, p) == ""  # the ball's skin is the slave
    w = pair_side_warning(case.problem.mesh, ContactPair(p.master, p.slave))
    assert "the slave side is flat and the master curved" in w and f"slave = {p.slave!r}" in w


def test_a_body_falling_from_rest_has_no_identity_warning(tmp_path):
    """E = 0 at every level while the block falls (kinetic energy and load potential cancel):
    the identity's residual is measured against its parts, not against |E| (which is round-off)."""
    from signorini.contact.obstacles import PlaneObstacle
    from signorini.dynamics.model.problem import Problem
    from signorini.fem.material import IsotropicElastic
    from signorini.fem.mesh import rectangle

    p = Problem(rectangle(4, 4, 0.1, 0.1), IsotropicElastic.from_young(1e6, 0.3, 1000.0), "ymin",
                PlaneObstacle([0.0, -0.01], [0.0, 1.0]), gravity=[0.0, -9.81])  # fmt: skip
    H = simulate(p, "cn", 1e-3, 0.1, solver_options={"energy_check": "fail"})
    assert H.status == "finished" and H.lam.min() < 0
    assert not any("energy identity" in w for w in H.meta["warnings"])

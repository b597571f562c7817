"""Boundary nodes outside the contact tag are watched: reported, warned about, or a failure."""

import json

import numpy as np
import pytest

from cases import falling_rectangle
from signorini.contact.obstacles import PlaneObstacle
from signorini.dynamics.problem import Problem
from signorini.dynamics.simulate import simulate
from signorini.dynamics.untagged import UNTAGGED_TOLERANCE, boundary_nodes
from signorini.fem.material import IsotropicElastic
from signorini.fem.mesh import rectangle
from signorini.io.cli import main

CASE = falling_rectangle(tag="xmin")


def _problem(tag="xmin"):
    mesh = rectangle(4, 4)
    floor = PlaneObstacle([0.0, -0.01], [0.0, 1.0])
    return Problem(mesh, IsotropicElastic.from_young(1.0, 0.3, 1.0), tag, floor, v0=[0.0, -1.0])


def test_boundary_nodes_of_a_rectangle():
    assert boundary_nodes(rectangle(4, 4)).size == 16


def test_a_single_tagged_side_touching_elsewhere_is_reported_per_level():
    H = simulate(_problem(), "cn", 0.005, 0.05, mass="standard")
    pen = H.columns()["untagged_penetration"]
    assert pen[0] == 0.0 and pen[-1] > 0.02  # the bottom side went ~0.04 into the floor
    s = H.summary()
    assert s["untagged_penetration_max"] == pytest.approx(pen.max(), rel=0, abs=0)
    assert s["penetration_max"] < 1e-14  # the tagged nodes respect the constraint; measured 0
    assert any("not a contact node" in w for w in s["warnings"])


def test_tagging_the_whole_skin_removes_the_warning():
    H = simulate(_problem(("xmin", "ymin", "xmax", "ymax")), "cn", 0.005, 0.05, mass="standard")
    s = H.summary()
    assert s["untagged_penetration_max"] == 0.0 and s["untagged_boundary_nodes"] == 0
    assert not any("not a contact node" in w for w in s["warnings"])


def test_untagged_contact_fail_stops_with_exit_3_and_keeps_the_levels(tmp_path, capsys):
    case = tmp_path / "c.toml"
    case.write_text(CASE)
    out = tmp_path / "o"
    rc = main(["run", str(case), "--out", str(out), "--quiet", "--solver-option", "untagged_contact=fail"])
    err = capsys.readouterr().err
    assert rc == 3 and "not a contact node" in err
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "failed" and 0 < s["steps"] < 10
    rows = np.loadtxt(out / "history.csv", delimiter=",", skiprows=1)
    header = (out / "history.csv").read_text().splitlines()[0].split(",")
    col = rows[:, header.index("untagged_penetration")]
    tol = UNTAGGED_TOLERANCE * np.sqrt(2.0)
    assert rows.shape[0] == s["steps"] + 1 and np.all(col <= tol)  # the levels kept were within tolerance


def test_untagged_contact_warn_is_the_default_and_prints_a_warning(tmp_path, capsys):
    case = tmp_path / "c.toml"
    case.write_text(CASE)
    assert main(["run", str(case), "--out", str(tmp_path / "o"), "--quiet"]) == 0
    err = capsys.readouterr().err
    assert "signorini: warning: boundary node" in err
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert s["untagged_penetration_max"] > 0.02 and s["warnings"]


def test_where_restricts_the_contact_nodes(tmp_path):
    case = tmp_path / "c.toml"
    case.write_text(CASE.replace('tag = "xmin"', 'tag = ["xmin", "ymin"]\nwhere = "y < 0.3 and x < 0.6"'))
    out = tmp_path / "o"
    assert main(["run", str(case), "--out", str(out), "--quiet"]) == 0
    s = json.loads((out / "summary.json").read_text())
    # xmin: y = 0, 0.25; ymin: x = 0 (shared), 0.25, 0.5 -> 4 nodes
    assert s["contact_nodes"] == 4 and s["untagged_penetration_max"] > 0.02

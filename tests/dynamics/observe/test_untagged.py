"""Boundary nodes outside the contact tag are watched: reported, warned about, or a failure."""

import json

import numpy as np
import pytest

from cases import falling_rectangle
from signorini.contact.obstacles import PlaneObstacle
from signorini.dynamics.model.problem import Problem
from signorini.dynamics.observe.untagged import UNTAGGED_TOLERANCE, boundary_nodes
from signorini.dynamics.stepping.simulate import simulate
from signorini.errors import InputError
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


def _block_on_plate(slave: str):
    from signorini.contact.pairs import ContactPair
    from signorini.dynamics.model.problem import Problem, RegionInitial
    from signorini.fem.material import IsotropicElastic
    from signorini.fem.mesh import join, rectangle
    from signorini.fem.space import Dirichlet

    a, b = rectangle(8, 2, 2.0, 0.5), rectangle(4, 4, 0.6, 0.6)
    b.points = b.points + [0.7, 0.55]
    m = join({"plate": a, "block": b})
    return Problem(m, IsotropicElastic.from_young(100, 0.3, 1), None, None, dirichlet=[Dirichlet("plate_ymin")],
                   initial_regions=[RegionInitial("block", velocity=[0, -1.0])],
                   pairs=[ContactPair(slave, "plate_ymax")])  # fmt: skip


def test_pairs_watch_the_nodes_of_either_body_against_the_other_surface(tmp_path):
    """A block falling on a plate with the wrong slave tag (its left side): its bottom nodes go
    through the plate's top, which the watch measures and ``fail`` stops; with the right tag
    nothing crosses (0 exactly: no watched node faces the plate through the enforced ones)."""
    H = simulate(_block_on_plate("block_xmin"), "cn", 0.01, 0.2)
    assert H.status == "finished" and H.untagged_penetration.max() > 0.1  # measured 0.164 (the block's fall)
    H = simulate(_block_on_plate("block_xmin"), "cn", 0.01, 0.2, solver_options={"untagged_contact": "fail"})
    assert H.status == "failed" and "through the paired surface 'plate_ymax' (master of pair 0)" in H.message
    assert H.untagged_penetration.size == H.t.size  # the levels computed are kept
    H = simulate(_block_on_plate("block_ymin"), "cn", 0.01, 0.2)
    assert H.lam.min() < 0 and H.untagged_penetration.max() == 0.0


def test_the_count_of_watched_nodes_includes_the_pairs_watch():
    """``untagged_boundary_nodes`` counts every node watched, against the rigid obstacle and
    against a pair's surface (it was 0 in every pair run)."""
    from signorini.dynamics.observe.untagged import pair_watch

    p = _block_on_plate("block_ymin")
    watch = pair_watch(p.mesh, p.pairs, 2 * p.mesh.n_nodes)
    H = simulate(p, "cn", 0.01, 0.02)
    assert H.meta["untagged_boundary_nodes"] == np.unique(watch.nodes).size > 0


def test_contact_npz_says_the_pair_and_master_facet_of_each_row(tmp_path):
    from signorini.contact.obstacles import PlaneObstacle

    p = _block_on_plate("block_ymin")
    import dataclasses

    p = dataclasses.replace(p, contact_tag="plate_ymin", obstacle=PlaneObstacle([0.0, -1.0], [0.0, 1.0]),
                            dirichlet=[])  # fmt: skip
    # the plate's top (master) and bottom (rigid contact) leave its 9 middle nodes, on a line:
    # moment-preserving cannot extrapolate the plate from them, and says so naming the body
    # (it used to borrow the block's nodes, coupling the two bodies)
    with pytest.raises(InputError, match=r"contact node\(s\) of body 0 \(regions plate\).*body's 9 non-contact"):
        simulate(p, "cn", 0.01, 0.05)
    H = simulate(p, "cn", 0.01, 0.05, mass="standard")
    H.write_contact_npz(tmp_path / "c.npz")
    z = np.load(tmp_path / "c.npz")
    rigid = p.mesh.nodes_of("plate_ymin").size
    assert z["pair"].tolist() == [-1] * rigid + [0] * (z["pair"].size - rigid)
    f = z["master_facet"][rigid:]
    assert np.all(z["master_facet"][:rigid] == -1) and f.min() >= 0
    top = p.mesh.facets_of("plate_ymax")
    x = z["coordinates"][rigid:, 0]  # each slave node faces a master facet whose x-range holds it
    lo, hi = p.mesh.points[top[f], 0].min(axis=1), p.mesh.points[top[f], 0].max(axis=1)
    assert np.all((lo <= x + 1e-12) & (x <= hi + 1e-12))


def test_the_pair_watch_of_finite_strain_follows_the_current_configuration():
    """With finite strain the watched nodes are projected on the deformed facing surface at every level
    (``CurrentPairWatch``).  At U = 0 its gaps are the linearized watch's (the same projections); the upper
    block pushed 1 cm into the lower one through its sides (nodes of neither tag) is seen 1 cm through, and
    so it is after the whole scene turns by 90 degrees, where the gaps linearized at t = 0 are wrong by the
    rotation (a watch that cannot fail to see it would pass this test only by luck)."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parent))
    from signorini.dynamics.observe.untagged import CurrentPairWatch, PairWatch, pair_watch
    from test_finite_strain import two_neo_hookean_blocks

    p = two_neo_hookean_blocks()
    mesh = p.mesh
    n = mesh.points.size
    lin, cur = pair_watch(mesh, p.pairs, n), pair_watch(mesh, p.pairs, n, current=True)
    assert isinstance(lin, PairWatch) and isinstance(cur, CurrentPairWatch)
    common = np.isin(cur.nodes, lin.nodes)
    at_rest = cur.gaps_at(np.zeros(n))
    order = np.argsort(lin.nodes)
    both = cur.nodes[common]
    lin_rest = lin.gaps_at(np.zeros(n))[order][np.searchsorted(lin.nodes[order], both)]
    assert np.allclose(at_rest[common], lin_rest, rtol=0.0, atol=1e-12)
    X = mesh.points
    upper = X[:, 1] > 0.101
    down = np.zeros_like(X)
    down[upper, 1] = -0.062  # the upper block's bottom 6 cm into the lower one: its sides' middle nodes 1 cm
    c, s = np.cos(np.pi / 2), np.sin(np.pi / 2)
    R = np.array([[c, -s], [s, c]])
    for turn in (np.eye(2), R):
        U = ((X + down) @ turn.T + [0.3, -0.2] - X).ravel()
        assert cur.gaps_at(U).min() == pytest.approx(-0.01, rel=0.0, abs=1e-9)
    assert abs(lin.gaps_at(U).min() + 0.01) > 1e-3  # linearized at t = 0: not what the turned scene shows


def test_the_current_pair_watch_sees_no_penetration_behind_a_surface_turned_away():
    """The upper block turned over and lifted clear of the lower one: its tagged bottom now faces up, and the
    lower block's nodes lie behind it at a negative signed distance without being through it; the watch counts
    only nodes within a facet's size behind the surface (an adversarial review measured -0.25 m here)."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parent))
    from signorini.dynamics.observe.untagged import pair_watch
    from test_finite_strain import two_neo_hookean_blocks

    p = two_neo_hookean_blocks()
    X = p.mesh.points
    cur = pair_watch(p.mesh, p.pairs, X.size, current=True)
    upper = X[:, 1] > 0.101
    c = X[upper].mean(axis=0)
    Y = X.copy()
    Y[upper] = 2 * c - X[upper] + [0.0, 0.05]  # turned by 180 degrees about its centre, 5 cm up
    assert Y[upper, 1].min() > X[~upper, 1].max() + 0.04
    assert cur.gaps_at((Y - X).ravel()).min() > 0.0

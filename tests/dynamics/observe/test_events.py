"""Events watched after every level (dynamics/observe/events.py): terminal built-ins end the run as
finished, every event met is listed.  Closed form: bar1d-impact's exact contact and release
times (studies/exact.py); measured (CN, default mass) first contact at t = 0.4 exactly and
separation at 1.0125 (n = 40, dt = 0.0125) and 1.0 (n = 80) against the exact 0.4 and 1.0."""

import json

import numpy as np
import pytest

from signorini.dynamics.observe.events import Event, parse_stop_at
from signorini.dynamics.stepping.simulate import simulate
from signorini.errors import InputError
from signorini.studies.benchmarks import get_benchmark


def _impact(n: int, scheme: str = "cn", **kw):
    b = get_benchmark("bar1d-impact")
    p = b.params({})
    dt, T = b.run_times(n)
    exact = dict((kind, t) for t, kind in reversed(b.exact(p, T)._events))  # the first of each kind
    return simulate(b.problem(n), scheme, dt, T, **kw), exact, dt


@pytest.mark.parametrize("scheme", ["cn", "be"])
@pytest.mark.parametrize("n", [40, 80])
def test_separation_ends_the_run_within_one_step_of_the_exact_release(n, scheme):
    H, exact, dt = _impact(n, scheme, events=["separation"])
    assert H.status == "finished" and "stopped at event separation" in H.message
    (e,) = H.meta["events"]
    assert e["name"] == "separation" and e["terminal"] and e["level"] == H.t.size - 1
    assert exact["release"] <= e["t"] + 1e-12 and e["t"] - exact["release"] <= dt + 1e-12
    assert H.lam[-1].max() == 0.0 and H.lam[-2].min() < 0  # free at the last level, in contact before
    assert H.meta["stop_at"] == ["separation"]


def test_first_contact_and_a_custom_event_that_is_not_terminal():
    """A user's event (direction 0, not terminal) is listed at every crossing of its function;
    the built-in first-contact ends the run at the first level with a contact force."""
    half = Event("tip at half its initial gap", lambda t, s: float(s.U[0]) - 0.1)  # u_0 = 0.2 at t = 0
    H, exact, dt = _impact(40, events=[half, "first-contact"])
    assert [e["name"] for e in H.meta["events"]] == ["tip at half its initial gap", "first-contact"]
    assert H.meta["events"][-1]["terminal"] and not H.meta["events"][0]["terminal"]
    assert abs(H.meta["events"][-1]["t"] - exact["contact"]) <= dt + 1e-12
    seen: list[float] = []
    half = Event("tip at half its initial gap", lambda t, s: seen.append(float(s.U[0]) - 0.1) or seen[-1])
    H2, _, _ = _impact(40, events=[half])
    assert H2.status == "finished" and H2.t[-1] == pytest.approx(6.0, rel=1e-12, abs=0)  # not terminal: to T
    met = H2.meta["events"]
    g = np.array(seen)  # the function at t = 0 and after every level
    crossings = int(np.sum((g[:-1] * g[1:] < 0) | ((g[1:] == 0) & (g[:-1] != 0))))
    assert len(met) == crossings >= 2 and all(not e["terminal"] for e in met)


def test_rest_is_the_kinetic_energy_below_its_fraction():
    H, _, _ = _impact(40, "be", events=["rest:0.5"])
    (e,) = H.meta["events"]
    assert e["name"] == "rest:0.5" and H.status == "finished"
    KE = H.kinetic_energy
    peak = KE[:-1].max()  # the largest so far (the bar speeds up under its release before it rests)
    assert KE[-1] < 0.5 * peak <= KE[-2]


def test_rest_of_a_body_released_from_rest():
    """A block dropped from rest under gravity onto a plane (BE): no event at t = 0 (no motion
    yet), then rest when its kinetic energy falls below the fraction of its peak."""
    from signorini.contact.obstacles import PlaneObstacle
    from signorini.dynamics.model.problem import Problem
    from signorini.fem.material import IsotropicElastic
    from signorini.fem.mesh import rectangle

    p = Problem(rectangle(2, 2, 1.0, 1.0), IsotropicElastic.from_young(100.0, 0.3, 1.0), "ymin",
                PlaneObstacle([0.0, -0.05], [0.0, 1.0]), gravity=[0.0, -9.81])  # fmt: skip
    H = simulate(p, "be", 0.01, 3.0, events=["rest:0.001"])
    (e,) = H.meta["events"]
    KE = H.kinetic_energy
    assert e["level"] > 1 and KE[0] == 0.0 and KE[-1] < 1e-3 * KE.max() <= KE[-2] and H.t[-1] < 3.0


@pytest.mark.parametrize(
    "spec, message",
    [("sepration", "unknown event 'sepration'"), ("first-contact:2", "takes no value"),
     ("rest:2", "rest"), ("", "non-empty"), (3, "an event name or a list")],
)  # fmt: skip
def test_bad_event_names_are_refused(spec, message):
    with pytest.raises(InputError, match=message):
        parse_stop_at(spec if spec != "" else [""])


def test_command_line_and_case_file(tmp_path):
    from signorini.io.cli import main

    assert main(["run", "bar1d-impact", "--stop-at", "first-contact", "--out", str(tmp_path / "a"), "--quiet"]) == 0
    s = json.loads((tmp_path / "a" / "summary.json").read_text())
    assert s["status"] == "finished" and [e["name"] for e in s["events"]] == ["first-contact"]
    assert main(["run", "bar1d-impact", "--stop-at", "nope", "--out", str(tmp_path / "b"), "--quiet"]) == 2
    assert not (tmp_path / "b").exists()
    case = tmp_path / "c.toml"
    case.write_text('[mesh]\ngenerator = "interval"\ncells = [20]\nsize = [1.0]\n[material]\nE = 1.0\nrho = 1.0\n'
                    '[[dirichlet]]\ntag = "xmax"\n[contact]\ntag = "xmin"\n'
                    'obstacle = { type = "plane", point = [0.0], normal = [1.0] }\n'
                    '[initial]\ndisplacement = ["0.2 * (1 - x)"]\n'
                    '[time]\ndt = 0.025\nT = 6.0\nstop_at = "separation"\n')  # fmt: skip
    assert main(["run", str(case), "--out", str(tmp_path / "c"), "--quiet"]) == 0
    s = json.loads((tmp_path / "c" / "summary.json").read_text())
    assert s["stop_at"] == ["separation"] and s["events"][0]["name"] == "separation" and s["steps"] < 240
    h = np.genfromtxt(tmp_path / "c" / "history.csv", delimiter=",", names=True)
    assert h["t"][-1] == pytest.approx(s["events"][0]["t"], rel=1e-12, abs=0)

"""collision2d / collision3d: two balls (discs) of their own radii and materials against
Hertz's two-body impact (studies/collision_balls.py).

Measured (CN, moment-preserving, E2 = 3, R2 = 1.5, rho2 = 0.5, nu2 = 0.2): 3D n = 2: duration
-8.0%, peak force +6.7% of Hertz's values; 2D n = 8: -6.5%, +2.0% (the line-contact law itself
is a few per cent off an impacting disc, as for hertz2d); min gap of the slave rows -7e-18,
complementarity 1.4e-16, momentum kept to 9e-13 (3D) and 1.3e-11 (2D) of the moving ball's.
"""

import math

import numpy as np
import pytest

from backends import needs_gmsh
from signorini.errors import InputError
from signorini.studies import collision_balls as cb
from signorini.studies import hertz
from signorini.studies.benchmarks import get_benchmark

OTHER = {"E2": 3.0, "R2": 1.5, "rho2": 0.5, "nu2": 0.2}


def _p(**kw) -> dict:
    return get_benchmark("collision3d").params(kw)


def test_a_rigid_flat_partner_gives_the_one_ball_prediction():
    """R2, E2 -> infinity: the pair's figures become those of one ball on a rigid plane (3D closed
    form, 2D Johnson's law); measured 1.6e-12 (3D) and 3.3e-12 (2D) at R2 = E2 = 1e12."""
    p = _p(R2=1e12, E2=1e12, R1=1.3, E1=2.0, nu1=0.25, rho1=0.7, velocity=0.001)
    for dim, rel in ((3, 1e-10), (2, 1e-9)):
        two = cb.prediction(dim, p)
        one = hertz.hertz_prediction(dim, 1.3, 2.0, 0.25, 0.7, 0.001)
        # the partner's mass is infinite only in the limit: m = m1 m2 / (m1 + m2) = m1 (1 - O(1e-36))
        for k in ("max_approach", "peak_force", "duration"):
            assert getattr(two, k) == pytest.approx(getattr(one, k), rel=rel, abs=0), (dim, k)


def test_two_equal_balls_are_one_ball_of_half_the_radius_and_mass():
    p = _p(velocity=0.003)
    R, Es, m = cb.effective(3, p)
    assert (R, Es) == pytest.approx((0.5, 1.0 / (2 * (1 - 0.3**2))), rel=1e-15, abs=0)
    assert m == pytest.approx(0.5 * 4 / 3 * math.pi, rel=1e-15, abs=0)
    pred = cb.prediction(3, p)
    d = (15 * m * 0.003**2 / (16 * Es * math.sqrt(R))) ** 0.4
    assert pred.max_approach == pytest.approx(d, rel=1e-15, abs=0)


def test_line_law_inverts_and_its_work_is_the_kinetic_energy():
    p = get_benchmark("collision2d").params(OTHER)
    for P in (1e-6, 1e-3):
        assert cb.line_force(cb.line_approach(P, p), p) == pytest.approx(P, rel=1e-13, abs=0)  # measured 2e-15
    pred = cb.prediction(2, p)
    d = np.linspace(0, pred.max_approach, 4001)
    F = np.array([cb.line_force(x, p) for x in d])
    work = float(np.sum((F[1:] + F[:-1]) / 2 * np.diff(d)))
    assert work == pytest.approx(0.5 * pred.mass * p["velocity"] ** 2, rel=5e-7, abs=0)  # trapezoid: ~1e-8


@pytest.mark.parametrize("bad, field", [({"nu2": 0.5}, "nu2"), ({"R1": 0}, "R1"), ({"velocity": -1}, "velocity"),
                                        ({"cap": 1}, "cap"), ({"velocity": 0.5}, "velocity")])  # fmt: skip
def test_bad_parameters_are_refused(bad, field):
    with pytest.raises(InputError, match=field):
        cb.prediction(3, get_benchmark("collision3d").params(bad))


def _run(dim: int, n: int, overrides: dict, mass: str = "moment-preserving"):
    from signorini.dynamics.stepping.simulate import simulate

    b = get_benchmark(f"collision{dim}d")
    p = b.params(overrides)
    dt, T = b.run_times(n, overrides)
    measure = b.measure(p)
    H = simulate(b.problem(n, overrides), "cn", dt, T, mass=mass, observers=measure.observers())
    assert H.status == "finished", H.message
    return H, measure.summary(H)["hertz"]


@needs_gmsh
@pytest.mark.parametrize("dim, n", [(2, 8), (3, 2)])
def test_two_balls_of_different_materials_meet_as_hertz_says(dim, n):
    H, h = _run(dim, n, OTHER)
    dev = h["relative_deviation"]
    assert abs(dev["duration"]) <= 0.10 and abs(dev["peak_force"]) <= 0.10, dev
    assert h["computed"]["contact_ended"]
    size = 2 * (1.0 + 1.5)
    assert H.gap.min() >= -1e-9 * size
    assert float(np.max(H.residual)) <= 1e-10
    P = H.momentum[:, -1]
    assert np.abs(P - P[0]).max() <= 1e-9 * abs(P[0])  # measured 9e-13 (3D), 1.3e-11 (2D)
    bodies = H.meta["bodies"]
    assert [b["regions"] for b in bodies] == [["a"], ["b"]]


@needs_gmsh
def test_the_run_prints_hertz_beside_the_computed(tmp_path, capsys):
    from signorini.io.cli import main

    assert main(["run", "collision2d", "--n", "4", "--out", str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out
    assert "Hertz (two discs" in out and "contact duration" in out and "restitution" in out

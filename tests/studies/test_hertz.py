"""Hertz impact benchmarks: the quasi-static predictions, the pole-refined meshes, and the
computed contact duration, peak force and approach against them (docs/verification.md)."""

import json
import math
import sys

import numpy as np
import pytest

from backends import needs_gmsh
from signorini.errors import InputError
from signorini.studies import hertz
from signorini.studies.benchmarks import get_benchmark

OTHER = {"R": 0.5, "E": 2.0, "velocity": 0.001}  # a non-default (R, E, velocity)


def test_sphere_closed_form_equals_the_integrated_impact():
    """delta*, F*, t_c of the closed form = the 1-dof impact integrated numerically."""
    p = hertz.hertz_prediction(3, 1.3, 2.0, 0.25, 0.7, 0.03)
    d, F, tc = hertz.impact_ode(lambda x: float(hertz.sphere_force(x, 1.3, p.E_star)), p.mass, 0.03)
    # docs/verification.md: agree to 1e-8 (measured 3.2e-12, 4.9e-12, 8e-13: solve_ivp's rtol 1e-11);
    # bounds about 50x the measured
    assert d == pytest.approx(p.max_approach, rel=2e-10, abs=0)
    assert F == pytest.approx(p.peak_force, rel=2e-10, abs=0)
    assert tc == pytest.approx(p.duration, rel=5e-11, abs=0)
    # the classical coefficient: t_c = 2.868 (m^2 / (R E*^2 v))^(1/5), to its printed digits (measured 2.7e-4)
    assert p.duration / (p.mass**2 / (1.3 * p.E_star**2 * 0.03)) ** 0.2 == pytest.approx(2.868, rel=0, abs=5e-4)


def test_disc_law_inverts_and_conserves_energy():
    R, Es = 1.0, 1.1
    for P in (1e-6, 1e-3, 0.05):
        # measured 2.1e-15 (brentq's rtol 1e-14)
        assert hertz.cylinder_force(hertz.cylinder_approach(P, R, Es), R, Es) == pytest.approx(P, rel=1e-13, abs=0)
    p = hertz.hertz_prediction(2, R, 1.0, 0.3, 1.0, 0.01)
    # work of the force up to delta* = initial kinetic energy
    d = np.linspace(0, p.max_approach, 4001)
    F = np.array([hertz.cylinder_force(x, R, p.E_star) for x in d])
    work = float(np.sum((F[1:] + F[:-1]) / 2 * np.diff(d)))
    assert work == pytest.approx(0.5 * p.mass * 0.01**2, rel=5e-7, abs=0)  # trapezoid rule: measured 9.8e-9


def test_missing_gmsh_is_an_input_error_naming_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "gmsh", None)  # import gmsh -> ImportError
    with pytest.raises(InputError, match=r'pip install "\.\[mesh\]"'):
        get_benchmark("hertz2d").problem(2)


def test_bad_parameters_are_refused():
    b = get_benchmark("hertz3d")
    for bad, field in (({"nu": 0.5}, "nu"), ({"velocity": 0}, "velocity"), ({"cap": 1}, "cap"), ({"R": -1}, "R")):
        with pytest.raises(InputError, match=field):
            b.params(bad)


@needs_gmsh
@pytest.mark.parametrize("dim", [2, 3])
def test_pole_refined_mesh(dim):
    """Node at the pole, cap within its angle, measure of the body, refinement towards the pole."""
    from signorini.fem.meshing import pole_refined_ball

    R, theta = 2.0, math.radians(30)
    mesh = pole_refined_ball(dim, R, theta, 0.1, 0.6, 0.5)
    assert np.min(np.linalg.norm(mesh.points, axis=1)) < 1e-14  # the pole is a node (measured 1.2e-16)
    cap = mesh.points[mesh.nodes_of("cap")]
    polar = np.arctan2(np.linalg.norm(cap[:, :-1], axis=1), R - cap[:, -1])
    assert polar.max() == pytest.approx(theta, rel=1e-14, abs=0)  # measured 2.1e-16
    # the nodes lie on the sphere: measured 1.1e-16 relative
    assert np.allclose(np.linalg.norm(cap - np.eye(dim)[-1] * R, axis=1), R, rtol=1e-14, atol=0)
    X = mesh.points[mesh.cells]
    vol = np.abs(np.linalg.det(X[:, 1:] - X[:, :1])) / math.factorial(dim)
    exact = math.pi * R**2 if dim == 2 else 4 / 3 * math.pi * R**3
    assert 0.97 * exact < vol.sum() < exact  # an inscribed polygon/polyhedron
    size = vol ** (1 / dim)
    centre = X.mean(axis=1)
    near = np.linalg.norm(centre, axis=1) < 0.5
    far = np.linalg.norm(centre, axis=1) > 2.5
    assert np.median(size[far]) > 3 * np.median(size[near])


def _deviations(name, n, overrides):
    from signorini.dynamics.stepping.simulate import simulate

    b = get_benchmark(name)
    dt, T = b.run_times(n, overrides)
    measure = b.measure(b.params(overrides))
    H = simulate(b.problem(n, overrides), "cn", dt, T, mass="seed", observers=measure.observers())
    h = measure.summary(H)["hertz"]
    assert h["computed"]["contact_ended"]
    # the contact zone stays well inside the cap of candidates
    assert h["computed"]["contact_radius"] < 0.75 * b.params(overrides)["R"] * math.sin(
        math.radians(h["cap_angle_degrees"])
    )
    return h["relative_deviation"]


@pytest.mark.parametrize("overrides", [{}, OTHER], ids=["default", "R-E-velocity"])
@needs_gmsh
def test_hertz2d_within_10_percent_and_mesh_converged(overrides):
    """Duration and peak force within 10% of Hertz (Johnson's line-contact law) on three
    levels; the two finest levels agree to 1% (what is left is the law's, not the mesh's)."""
    dev = {n: _deviations("hertz2d", n, overrides) for n in (4, 8, 16)}
    for d in dev.values():
        for key in ("duration", "peak_force", "max_approach"):
            assert abs(d[key]) < 0.10, (key, dev)
    for key in ("duration", "peak_force", "max_approach"):
        assert abs(dev[16][key] - dev[8][key]) < 0.01
        assert abs(dev[16][key]) <= abs(dev[4][key]) + 0.005


@needs_gmsh
def test_hertz3d_coarse_within_10_percent():
    d = _deviations("hertz3d", 2, {})
    for key in ("duration", "peak_force", "max_approach"):
        assert abs(d[key]) < 0.10, d


@needs_gmsh
@pytest.mark.slow
@pytest.mark.parametrize("overrides", [{}, OTHER], ids=["default", "R-E-velocity"])
def test_hertz3d_converges_towards_hertz(overrides):
    """Levels 2, 3, 4: within 10%, and the peak force and approach deviations shrink."""
    dev = {n: _deviations("hertz3d", n, overrides) for n in (2, 3, 4)}
    for d in dev.values():
        for key in ("duration", "peak_force", "max_approach"):
            assert abs(d[key]) < 0.10, dev
    for key in ("peak_force", "max_approach"):
        assert abs(dev[4][key]) < abs(dev[2][key]), dev


@needs_gmsh
def test_cli_run_reports_hertz(tmp_path, capsys):
    from signorini.io.cli import main

    out = tmp_path / "h2"
    assert main(["run", "hertz2d", "--n", "4", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "contact duration" in text and "peak force" in text and "max approach" in text
    s = json.loads((out / "summary.json").read_text())
    h = s["hertz"]
    assert set(h["predicted"]) >= {"duration", "peak_force", "max_approach"}
    # measured 0
    assert h["predicted"]["duration"] == pytest.approx(
        hertz.hertz_prediction(2, 1, 1, 0.3, 1, 0.002).duration, rel=1e-14, abs=0
    )
    assert s["steps"] == math.ceil(1.5 * 25 * 4)


REFUSED = [["compare", "hertz2d", "--schemes", "cn", "--masses", "seed"], ["study", "hertz3d"]]


@pytest.mark.parametrize("command", REFUSED)
def test_compare_and_study_refuse_hertz(command, tmp_path, capsys):
    from signorini.io.cli import main

    assert main([*command, "--out", str(tmp_path / "o")]) == 2
    assert "signorini run hertz" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


@needs_gmsh
@pytest.mark.parametrize("R", [2.0, 0.05, 1e-3])
@pytest.mark.parametrize("dim", [2, 3])
def test_the_cap_is_found_whatever_the_ball_size(dim, R):
    """The cap is told from the rest by the middle of each boundary entity's box: OpenCASCADE pads the boxes by an
    absolute tolerance, and the former test (the top within 1e-6 R of the cut) found no cap on a 5 cm ball."""
    from signorini.fem.meshing import pole_refined_ball

    theta = math.radians(30)
    mesh = pole_refined_ball(dim, R, theta, 0.1 * R, 0.4 * R, 0.25 * R)
    cap = mesh.points[mesh.nodes_of("cap")]
    assert cap.shape[0] >= 5
    assert cap[:, -1].max() <= R * (1 - math.cos(theta)) * (1 + 1e-9)
    on_sphere = np.linalg.norm(cap - np.eye(dim)[-1] * R, axis=1)
    assert np.allclose(on_sphere, R, rtol=1e-9, atol=0)


@needs_gmsh
@pytest.mark.parametrize("dim", [2, 3])
def test_quadratic_pole_refined_mesh_is_curved_and_positive(dim):
    """``order`` 2: gmsh puts the mid-side nodes of the cap on the circle or sphere; every cell positive."""
    from signorini.fem.meshing import pole_refined_ball

    R, theta = 2.0, math.radians(30)
    mesh = pole_refined_ball(dim, R, theta, 0.2, 0.8, 0.5, order=2)
    assert mesh.cell_type == ("tetra10" if dim == 3 else "triangle6")
    mesh.check_cells()
    cap = mesh.points[mesh.nodes_of("cap")]
    assert np.allclose(np.linalg.norm(cap - np.eye(dim)[-1] * R, axis=1), R, rtol=1e-12, atol=0)
    from signorini.fem.assembly import cell_volumes

    exact = math.pi * R**2 if dim == 2 else 4 / 3 * math.pi * R**3
    linear = pole_refined_ball(dim, R, theta, 0.2, 0.8, 0.5)
    # the curved cells take most of the inscribed polygon's missing area or volume
    assert abs(cell_volumes(mesh).sum() - exact) < 0.1 * abs(cell_volumes(linear).sum() - exact)


def _quadratic_deviations(name, n, overrides):
    from signorini.dynamics.stepping.simulate import simulate

    b = get_benchmark(name)
    dt, T = b.run_times(n, overrides)
    measure = b.measure(b.params(overrides))
    H = simulate(b.problem(n, overrides), "cn", dt, T, observers=measure.observers())
    h = measure.summary(H)["hertz"]
    assert h["computed"]["contact_ended"]
    return h["relative_deviation"]


@needs_gmsh
def test_hertz3d_quadratic_within_two_percent_where_hertz_holds():
    """Quadratic tetrahedra at the default level, the default mass, a*/R = 0.035 (velocity 1.25e-4): duration,
    peak force and approach within 2% of Hertz (measured -1.33%, +1.40%, -1.15%); the linear cells of the same
    level stay at their floor (-6.67%, +4.48%, -5.73%).  At the default velocity (a*/R = 0.107) the quadratic
    cells give -4.0%, +5.0%, -3.4%: Hertz's half-space theory itself is O(a*/R) off there (docs/verification.md)."""
    slow = {"velocity": 1.25e-4}
    quadratic = _quadratic_deviations("hertz3d", 3, {**slow, "order": 2})
    for key in ("duration", "peak_force", "max_approach"):
        assert abs(quadratic[key]) < 0.02, quadratic
    linear = _quadratic_deviations("hertz3d", 3, slow)
    assert abs(linear["peak_force"]) > 0.035 and abs(linear["max_approach"]) > 0.045, linear


@needs_gmsh
@pytest.mark.slow
def test_hertz3d_quadratic_is_converged_where_hertz_is_off():
    """Issue 54's Hertz line at the default velocity (a*/R = 0.107): the quadratic cells at levels 2, 3, 4 (dt =
    t_c / (25 n): space and time refined together) converge to a peak force 5% above Hertz's and an approach 3.3%
    short (measured +4.88%, +5.00%, +5.08% and -3.47%, -3.37%, -3.34%), so the distance is Hertz's, not the
    mesh's; and at level 3 the peak force's deviation falls with a*/R as Hertz's half-space error does, about
    linearly (a*/R = 0.107, 0.062, 0.035 at velocities 2e-3, 5e-4, 1.25e-4: +5.0%, +2.8%, +1.4%; the exponent,
    measured 1.1, asserted within 0.7-1.5)."""
    default = {n: _quadratic_deviations("hertz3d", n, {"order": 2}) for n in (2, 3, 4)}
    for key in ("peak_force", "max_approach"):
        assert abs(default[4][key] - default[3][key]) < 0.003, default
        assert abs(default[3][key] - default[2][key]) < 0.003, default
    assert 0.04 < default[4]["peak_force"] < 0.06 and -0.045 < default[4]["max_approach"] < -0.025, default
    ratio = {2e-3: 0.107, 5e-4: 0.062, 1.25e-4: 0.035}  # a*/R of each velocity (Hertz: a* ~ v^(2/5))
    peak = {v: (default[3] if v == 2e-3 else _quadratic_deviations("hertz3d", 3, {"order": 2, "velocity": v}))
            ["peak_force"] for v in ratio}  # fmt: skip
    slope = np.polyfit(np.log(list(ratio.values())), np.log([peak[v] for v in ratio]), 1)[0]
    assert 0.7 < slope < 1.5, (slope, peak)
    assert peak[1.25e-4] < 0.02, peak

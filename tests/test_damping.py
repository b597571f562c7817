"""Rayleigh damping C = alpha M + beta S (issue 38, spec 14): the scheme's order on a damped mode
against its exact solution, the energy identity with its damping term through impacts, resume,
refusals and case-file errors."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg as sl

from signorini.contact.obstacles import PlaneObstacle
from signorini.dynamics.damping import Rayleigh, make_damping
from signorini.dynamics.problem import discretize
from signorini.dynamics.schemes import SCHEMES, damping_schemes
from signorini.dynamics.simulate import simulate
from signorini.errors import InputError
from signorini.io.cli import main
from signorini.studies.benchmarks import get_benchmark

DAMPING = Rayleigh(alpha=0.3, beta=0.02)


def _damped_mode(n: int = 10):
    """bar1d (clamped at x = L, E = rho = L = 1) with the obstacle out of reach, started in its first
    mode phi (standard mass) at rest: U(t) = phi q(t), q'' + (alpha + beta w^2) q' + w^2 q = 0 exactly
    (the semi-discrete solution: no spatial error in the comparison)."""
    b = get_benchmark("bar1d")
    p = dataclasses.replace(b.problem(n, {}), obstacle=PlaneObstacle([-10.0], [1.0]))
    disc = discretize(p, "standard")
    f = disc.free
    w2, vec = sl.eigh(disc.S[f][:, f].toarray(), disc.M[f][:, f].toarray())
    phi = np.zeros(disc.S.shape[0])
    phi[f] = vec[:, 0] / np.abs(vec[:, 0]).max()
    return dataclasses.replace(p, u0=phi.reshape(-1, 1), damping=DAMPING), phi, float(np.sqrt(w2[0]))


def _modal(omega: float, t: float) -> float:
    """q(t) with q(0) = 1, q'(0) = 0 for the damping ratio zeta = alpha/(2 w) + beta w/2 < 1."""
    z = DAMPING.ratio(omega)
    wd = omega * np.sqrt(1 - z * z)
    return float(np.exp(-z * omega * t) * (np.cos(wd * t) + z * omega / wd * np.sin(wd * t)))


@pytest.mark.parametrize(
    "scheme, options, order, finest",
    [
        ("crank-nicolson", {}, 2, 3e-5),
        ("generalized-alpha", {"rho_inf": 0.8}, 2, 3e-5),
        ("hht", {"alpha": 0.1}, 2, 1e-4),
        ("moreau-jean", {}, 2, 3e-5),
        ("backward-euler", {}, 1, 4e-2),
        ("newmark", {"beta": 0.3, "gamma": 0.6}, 1, 5e-3),
    ],
)
def test_a_damped_mode_converges_at_the_schemes_order(scheme, options, order, finest):
    """max |U(T) - phi q(T)| at T = 4 (about one period, zeta = 0.11) for dt = T/40 .. T/320: the
    observed rates (measured CN 1.96, 1.99, 2.00; BE 0.83, 0.91, 0.95; Newmark gamma = 0.6 0.95, 0.97,
    0.99) within [order - 0.2, order + 0.15] on the two finest pairs, and a bound on the finest error."""
    p, phi, omega = _damped_mode()
    T = 4.0
    errors = []
    for N in (40, 80, 160, 320):
        H = simulate(p, scheme, T / N, T, mass="standard", snapshot_every=N, scheme_options=options)
        errors.append(np.abs(H.snapshots["u"][-1] - phi * _modal(omega, T)).max())
    rates = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(rates[1:] > order - 0.2) and np.all(rates[1:] < order + 0.15), rates
    assert errors[-1] < finest, errors
    assert H.meta["damping"] == {"model": "rayleigh", "alpha": 0.3, "beta": 0.02}


def _identity_residual(H) -> float:
    """max_n |E^n - E^0 - (cumulative works)| relative to the run's largest energy part (history columns)."""
    c = H.columns()
    works = (c["external_work"] + c["contact_work"] + c["numerical_dissipation"] - c["friction_dissipation"]
             - c["damping_dissipation"])  # fmt: skip
    scale = max(np.abs(c["kinetic_energy"]).max(), np.abs(c["elastic_energy"]).max(), np.abs(works).max())
    return float(np.abs(c["energy"] - c["energy"][0] - works).max() / scale)


@pytest.mark.parametrize("scheme", damping_schemes())
@pytest.mark.parametrize("mass", ["standard", "moment-preserving"])
def test_the_energy_identity_closes_with_damping_through_impacts(scheme, mass):
    """bar2d falling on the plane, damped: E^n - E^0 = the works of the identity, damping included, to
    round-off at every level; the damping dissipates (its column grows) and the undamped run of the
    same case keeps more energy.  With the moment-preserving mass the contact nodes are massless: the
    damping force there is the one the balance used (Newmark's velocity before dU/dt replaced it)."""
    b = get_benchmark("bar2d")
    p = b.problem(4, {})
    dt, T = b.run_times(4, {})
    damped = dataclasses.replace(p, damping={"alpha": 0.2, "beta": 0.01})
    try:
        H = simulate(damped, scheme, dt, T, mass=mass)
    except InputError as exc:  # a scheme that refuses this mass refuses it undamped too
        with pytest.raises(InputError):
            simulate(p, scheme, dt, T, mass=mass)
        assert "damping" not in str(exc)
        return
    assert H.lam.min() < 0  # impacts happened
    assert _identity_residual(H) < 1e-11
    dd = H.columns()["damping_dissipation"]
    assert dd[-1] > 0 and np.all(np.diff(dd) >= -1e-12 * dd[-1]), np.diff(dd).min()
    free = simulate(p, scheme, dt, T, mass=mass)
    assert np.all(free.columns()["damping_dissipation"] == 0.0)
    assert H.columns()["energy"][-1] < free.columns()["energy"][-1]


def test_zero_damping_is_no_damping():
    """alpha = beta = 0 is the undamped run, bit for bit (make_damping gives None)."""
    b = get_benchmark("bar2d")
    p = b.problem(2, {})
    dt, T = b.run_times(2, {})
    assert make_damping({"alpha": 0.0, "beta": 0.0}) is None
    a = simulate(p, "cn", dt, T)
    z = simulate(dataclasses.replace(p, damping={"alpha": 0, "beta": 0.0}), "cn", dt, T)
    assert np.array_equal(a.columns()["energy"], z.columns()["energy"]) and z.meta["damping"]["model"] == "none"


@pytest.mark.parametrize("scheme", ["crank-nicolson", "generalized-alpha", "moreau-jean"])
def test_resume_of_a_damped_run_is_bit_for_bit(tmp_path, scheme):
    """The level's damping force is state (``extra['damping_force']``): T/2 + resume = T; a resume
    with other damping coefficients is refused by name."""
    b = get_benchmark("bar2d")
    p = dataclasses.replace(b.problem(4, {}), damping=Rayleigh(0.2, 0.01))
    dt, T = b.run_times(4, {})
    mass = "standard" if scheme == "moreau-jean" else "moment-preserving"
    full = simulate(p, scheme, dt, T, mass=mass)
    half = (round(T / dt) // 2) * dt
    simulate(p, scheme, dt, half, mass=mass, checkpoint=tmp_path / "c.h5")
    r = simulate(p, scheme, dt, T, mass=mass, resume=tmp_path / "c.h5")
    for k in ("energy", "damping_dissipation", "lambda_sum", "numerical_dissipation"):
        assert np.array_equal(full.columns()[k], r.columns()[k]), k
    other = dataclasses.replace(p, damping=Rayleigh(0.2, 0.02))
    with pytest.raises(InputError, match="the damping"):
        simulate(other, scheme, dt, T, mass=mass, resume=tmp_path / "c.h5")
    with pytest.raises(InputError, match="the damping"):
        simulate(dataclasses.replace(p, damping=None), scheme, dt, T, mass=mass, resume=tmp_path / "c.h5")


@pytest.mark.parametrize("scheme", [e.name for e in SCHEMES if e.obj.damping_refusal])
def test_schemes_without_damping_refuse_it_by_name(scheme):
    b = get_benchmark("bar2d")
    p = dataclasses.replace(b.problem(2, {}), damping={"beta": 0.01})
    dt, T = b.run_times(2, {})
    with pytest.raises(InputError, match=f"scheme {scheme} cannot carry damping.*schemes that do: crank-nicolson"):
        simulate(p, scheme, dt, T, mass="standard")


def _case(damping: str) -> str:
    """examples/bar2d.toml with ``damping`` as the first line of its [material] section."""
    text = (Path(__file__).parents[1] / "examples" / "bar2d.toml").read_text()
    assert "[material]\n" in text
    return text.replace("[material]\n", f"[material]\n{damping}\n", 1)


@pytest.mark.parametrize(
    "damping, message",
    [
        ("damping = { alpha = -1.0 }", "'material.damping.alpha': damping alpha must be a finite number >= 0"),
        ("damping = { gamma = 1.0 }", "'material.damping': unknown key 'gamma'; allowed: alpha, beta"),
        ("damping = 0.1", "'material.damping' must be a table"),
        ('damping = { beta = "x" }', "'material.damping.beta': damping beta must be a number >= 0"),
        ("damping = { alpha = 1e300 }", "'material.damping.alpha': damping alpha = 1e+300 is outside 1e-100"),
        ("damping = { beta = 1e-320 }", "'material.damping.beta': damping beta = 9.99989e-321 is outside"),
        (
            "damping = { alpha = 99999999999999999999999999999999999999999999999999999999999999999999999999999999999"
            "999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999"
            "999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999"
            "99999999999999999999999999999999999999999 }",
            "'material.damping.alpha': damping alpha must be a finite",
        ),
    ],
)
def test_bad_damping_in_a_case_file_exits_2_naming_the_field(tmp_path, capsys, damping, message):
    case = tmp_path / "c.toml"
    case.write_text(_case(damping))
    assert main(["run", str(case), "--out", str(tmp_path / "o"), "--quiet"]) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_damping_in_a_case_file_reaches_the_summary_and_history(tmp_path, capsys):
    case = tmp_path / "c.toml"
    case.write_text(_case("damping = { alpha = 0.5, beta = 0.01 }"))
    assert main(["run", str(case), "--out", str(tmp_path / "o"), "--quiet"]) == 0
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert s["damping"] == {"model": "rayleigh", "alpha": 0.5, "beta": 0.01}
    header = (tmp_path / "o" / "history.csv").read_text().splitlines()[0].split(",")
    assert header[header.index("dt") + 1] == "damping_dissipation"
    assert main(["run", str(case), "--scheme", "ps", "--mass", "standard", "--out", str(tmp_path / "p")]) == 2
    assert "scheme paoli-schatzman cannot carry damping" in capsys.readouterr().err


@pytest.mark.parametrize("scheme", ["crank-nicolson", "hht", "newmark"])
def test_stiffness_damping_never_creates_energy_with_massless_contact_nodes(tmp_path, scheme):
    """examples/damped_block_drop.toml with beta = 1e-2 (100 times its own) at fixed steps, the
    default mass (massless contact nodes): the damping column never decreases and the energy never
    rises above E0.  Before the damping velocity kept its own update on the massless dofs (their V
    is replaced by dU/dt after each step), this run doubled its energy with a negative damping
    dissipation (an adversarial test's find, 2026-12-04)."""
    text = (Path(__file__).parents[1] / "examples" / "damped_block_drop.toml").read_text()
    case = tmp_path / "c.toml"
    case.write_text(text.replace("damping = { alpha = 5.0, beta = 5.0e-5 }", "damping = { alpha = 0.0, beta = 1e-2 }"))
    out = tmp_path / "o"
    assert main(["run", str(case), "--scheme", scheme, "--dt-control", "fixed", "--out", str(out), "--quiet"]) == 0
    rows = (out / "history.csv").read_text().splitlines()
    head = rows[0].split(",")
    cols = {k: np.array([float(r.split(",")[i]) for r in rows[1:]]) for i, k in enumerate(head)}
    dd, E = cols["damping_dissipation"], cols["energy"]
    assert dd[-1] > 0.02 * E[0] and np.all(np.diff(dd) >= -1e-12 * dd[-1]), np.diff(dd).min()
    assert E.max() <= E[0] * (1 + 1e-6), E.max() / E[0]

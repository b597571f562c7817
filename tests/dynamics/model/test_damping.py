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
from signorini.dynamics.model.damping import UNDAMPED, Rayleigh, RegionalRayleigh, make_damping, regional_damping
from signorini.dynamics.model.problem import discretize
from signorini.dynamics.schemes import SCHEMES, damping_schemes
from signorini.dynamics.stepping.simulate import simulate
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


def test_the_drift_without_the_dampings_work_is_the_schemes_own():
    """A damped mode (no contact) with Crank-Nicolson loses its energy to damping only: the drift
    max|E - E0|/|E0| is the damping's (a large fraction), the drift less the damping's work
    (``energy_max_relative_drift_undamped``, which ``compare`` ranks by) is round-off; undamped, the two are one."""
    p, _, w = _damped_mode()
    dt = 0.05 / w
    H = simulate(p, "crank-nicolson", dt, 200 * dt, mass="standard")
    s = H.summary()
    assert s["energy_max_relative_drift"] >= 0.1 and s["energy_max_relative_drift_undamped"] <= 1e-12
    b = get_benchmark("bar2d")
    dt, T = b.run_times(2, {})
    u = simulate(b.problem(2, {}), "cn", dt, T).summary()
    assert u["energy_max_relative_drift_undamped"] == u["energy_max_relative_drift"]


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
    text = (Path(__file__).parents[3] / "examples" / "bar2d.toml").read_text()
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
    text = (Path(__file__).parents[3] / "examples" / "damped_block_drop.toml").read_text()
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


# ----------------------------------------------------------------------------- damping per region
def _two_blocks(gap: float = 0.0, damping=None):
    """A block 0.2 x 0.1 (E 1e6, rho 1000) above a clamped one 0.5 x 0.1 (E 5e6, rho 2000), ``gap`` [m]
    apart; the upper one pushed down at 0.5 m/s and stretched along x by 1% (so that it vibrates)."""
    from signorini.contact.pairs import ContactPair
    from signorini.dynamics.model.problem import Problem, RegionInitial
    from signorini.fem.material import IsotropicElastic
    from signorini.fem.mesh import join, rectangle
    from signorini.fem.space import Dirichlet

    upper, lower = rectangle(4, 2, 0.2, 0.1), rectangle(10, 2, 0.5, 0.1)
    upper.points = upper.points + [0.15, 0.1 + gap]
    m = join({"upper": upper, "lower": lower})
    u0 = np.zeros((m.n_nodes, 2))
    up = m.region_nodes("upper")
    u0[up, 0] = 0.01 * (m.points[up, 0] - 0.25)
    return Problem(m, IsotropicElastic.from_young(5e6, 0.3, 2000.0), None, None, dirichlet=[Dirichlet("lower_ymin")],
                   pairs=[ContactPair("upper_ymin", "lower_ymax")], u0=u0,
                   materials={"upper": IsotropicElastic.from_young(1e6, 0.45, 1000.0)},
                   initial_regions=[RegionInitial("upper", velocity=[0.0, -0.5])], damping=damping)  # fmt: skip


UPPER_ONLY = RegionalRayleigh(UNDAMPED, (("upper", Rayleigh(alpha=20.0, beta=2e-4)),))


def test_damping_per_body_is_each_bodys_rayleigh_matrix():
    """Where the regions are bodies, C = sum_b (alpha_b M_b + beta_b S_b) exactly (M_b the mass in use on
    body b's dofs, S_b the stiffness of its cells); one coefficient pair on every region is Rayleigh."""
    from signorini.fem.assembly import stiffness_matrix
    from signorini.fem.material import CellMaterial

    both = RegionalRayleigh(Rayleigh(alpha=3.0, beta=1e-5), (("upper", Rayleigh(alpha=20.0, beta=2e-4)),))
    p = _two_blocks(0.05, both)
    disc = discretize(p, "moment-preserving")
    C = both.matrix(p.mesh, disc.material, disc.M, disc.S)
    up = np.zeros(p.mesh.n_nodes, dtype=bool)
    up[p.mesh.region_nodes("upper")] = True
    on = np.repeat(up, 2).astype(float)
    Mu = disc.M.multiply(np.outer(on, on))
    mat = disc.material
    cell_up = np.zeros(p.mesh.n_cells, dtype=bool)
    cell_up[p.mesh.regions["upper"]] = True
    Su = stiffness_matrix(p.mesh, CellMaterial(mat.lam * cell_up, mat.mu * cell_up, mat.rho))
    expected = 20.0 * Mu + 3.0 * (disc.M - Mu) + 2e-4 * Su + 1e-5 * (disc.S - Su)
    assert abs(C - expected).max() <= 1e-13 * abs(expected).max()
    same = regional_damping(Rayleigh(alpha=3.0), {"upper": Rayleigh(alpha=3.0)})
    assert same == Rayleigh(alpha=3.0)


def test_a_damped_body_beside_an_undamped_one_moves_as_if_alone():
    """Two blocks 5 cm apart (they do not meet), only the upper damped: its motion is that of the upper block
    alone with the same Rayleigh damping over the whole mesh (to round-off of the two orderings)."""
    from signorini.dynamics.model.problem import Problem
    from signorini.dynamics.stepping.stepper import Stepper
    from signorini.fem.mesh import rectangle

    def final(problem, **options):
        s = Stepper(problem, "cn", (dt, T), {"mass": "standard", **options})
        while s.status == "running":
            s.step()
        return s.state.U, s.finish()

    p = _two_blocks(0.05, UPPER_ONLY)
    dt, T = 2e-4, 0.02
    U, H = final(p, solver_options={"energy_check": "fail"})
    block = rectangle(4, 2, 0.2, 0.1)
    block.points = block.points + [0.15, 0.15]
    nodes = p.mesh.region_nodes("upper")
    order = [int(np.argmin(np.abs(p.mesh.points[nodes] - x).sum(axis=1))) for x in block.points]
    nodes = nodes[order]
    assert np.abs(p.mesh.points[nodes] - block.points).max() < 1e-14
    alone = Problem(block, p.materials["upper"], "ymin", PlaneObstacle([0.0, -10.0], [0.0, 1.0]), u0=p.u0[nodes],
                    v0=np.array([0.0, -0.5]), damping=Rayleigh(alpha=20.0, beta=2e-4))  # fmt: skip
    UA, A = final(alone)
    dofs = np.stack([2 * nodes, 2 * nodes + 1], axis=1).ravel()
    assert np.abs(U[dofs] - UA).max() <= 1e-9 * np.abs(UA).max()
    dd = H.columns()["damping_dissipation"]
    assert np.isclose(dd[-1], A.columns()["damping_dissipation"][-1], rtol=1e-9, atol=0.0)
    assert dd[-1] > 0.05 * H.columns()["energy"][0]


@pytest.mark.parametrize("scheme", damping_schemes())
def test_damping_per_region_closes_the_energy_identity_through_impacts(scheme):
    """The upper block damped, the lower not, falling onto it (a pair, the default mass): the identity closes
    to round-off at every level with the damping term, the damping dissipates."""
    p = _two_blocks(0.002, UPPER_ONLY)
    try:
        H = simulate(p, scheme, 1e-4, 0.02, solver_options={"energy_check": "fail"})
    except InputError as exc:  # a scheme that refuses this case refuses it undamped too
        with pytest.raises(InputError):
            simulate(_two_blocks(0.002), scheme, 1e-4, 0.02)
        assert "damping" not in str(exc)
        return
    assert H.lam.min() < 0
    assert _identity_residual(H) < 1e-11
    dd = H.columns()["damping_dissipation"]
    assert dd[-1] > 0 and np.all(np.diff(dd) >= -1e-12 * dd[-1]), np.diff(dd).min()


def test_damping_per_region_resumes_bit_for_bit_and_is_refused_where_not_done(tmp_path):
    p = _two_blocks(0.002, UPPER_ONLY)
    dt, T = 1e-4, 0.01
    full = simulate(p, "cn", dt, T)
    simulate(p, "cn", dt, T / 2, checkpoint=tmp_path / "c.h5")
    r = simulate(p, "cn", dt, T, resume=tmp_path / "c.h5")
    for k in ("energy", "damping_dissipation", "lambda_sum"):
        assert np.array_equal(full.columns()[k], r.columns()[k]), k
    with pytest.raises(InputError, match="the damping"):
        simulate(_two_blocks(0.002, Rayleigh(alpha=20.0, beta=2e-4)), "cn", dt, T, resume=tmp_path / "c.h5")
    with pytest.raises(InputError, match="damping per region .* with backend 'cg' is not done"):
        simulate(p, "cn", dt, T, solver_options={"backend": "cg"})


def test_damping_per_region_in_a_case_file(tmp_path, capsys):
    """``regions = [{ tag, ..., damping }]``: the summary lists each region's, the one-screen summary says
    so; an entry without damping takes the section's; two regions sharing cells with different damping are
    refused (exit 2, nothing written)."""
    text = (Path(__file__).parents[3] / "examples" / "block_on_block.toml").read_text()
    text = text.replace('"meshes/', f'"{Path(__file__).parents[3] / "examples" / "meshes"}/')
    text = text.replace("T = 0.12", "T = 0.01")
    own = text.replace("rho = 1000.0 }", "rho = 1000.0, damping = { alpha = 20.0 } }")
    case = tmp_path / "c.toml"
    case.write_text(own.replace("[material]   # the default: the lower block", "[material]\ndamping = { beta = 1e-5 }"))
    assert main(["run", str(case), "--out", str(tmp_path / "o")]) == 0
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert s["damping"] == {"model": "rayleigh", "alpha": 0.0, "beta": 1e-5,
                            "regions": [{"tag": "upper", "alpha": 20.0, "beta": 0.0}]}  # fmt: skip
    assert (
        "damping rayleigh upper alpha 20, beta 0; cells in no listed region alpha 0, beta 1e-05"
        in capsys.readouterr().out
    )
    shared = own.replace("{ tag = \"upper\",", "{ tag = \"upper\", damping = { alpha = 1.0 }, E = 1.0e6, nu = 0.45, "
                         "rho = 1000.0 },\n    { tag = \"upper\",")  # fmt: skip
    case.write_text(shared)
    assert main(["run", str(case), "--out", str(tmp_path / "p"), "--quiet"]) == 2
    assert "material.regions" in capsys.readouterr().err
    assert not (tmp_path / "p").exists()


def test_damping_per_region_edge_cases():
    """A 1D bar with beta on one region only (the scaled element matrices: no 0/0 Young modulus where beta = 0);
    overlapping regions that disagree on any shared cell are refused, not only on the first; a region
    entry of a case file with damping and no constants takes the section's material."""
    from signorini.fem.assembly import stiffness_matrix
    from signorini.fem.material import IsotropicElastic
    from signorini.fem.mesh import interval, rectangle

    bar = interval(10)
    bar.regions["soft"] = np.arange(4)
    mat = IsotropicElastic.from_young(2.0, 0.3, 1.0)
    d = RegionalRayleigh(UNDAMPED, (("soft", Rayleigh(beta=0.01)),))
    from signorini.dynamics.model.mass import mass_matrix

    M, S = mass_matrix("standard", bar, 1.0), stiffness_matrix(bar, mat)
    C = d.matrix(bar, mat, M, S)
    assert np.all(np.isfinite(C.data)) and abs(C).max() > 0 and abs(C[6:, 6:]).max() == 0.0
    m = rectangle(4, 1)
    m.regions.update({"A": np.array([0, 1]), "B": np.array([2, 3]), "C": np.array([1, 2])})
    clash = RegionalRayleigh(UNDAMPED, (("A", Rayleigh(alpha=5.0)), ("B", Rayleigh(alpha=9.0)),
                                        ("C", Rayleigh(alpha=5.0))))  # fmt: skip
    with pytest.raises(InputError, match="damping regions 'B' and 'C' share 1 cell"):
        clash.cell_coefficients(m)


def test_a_damping_only_region_entry_takes_the_sections_material(tmp_path):
    text = (Path(__file__).parents[3] / "examples" / "block_on_block.toml").read_text()
    text = text.replace('"meshes/', f'"{Path(__file__).parents[3] / "examples" / "meshes"}/').replace(
        "T = 0.12", "T = 0.005"
    )
    case = tmp_path / "c.toml"
    case.write_text(text.replace('{ tag = "upper", E = 1.0e6, nu = 0.45, rho = 1000.0 },',
                                 '{ tag = "upper", E = 1.0e6, nu = 0.45, rho = 1000.0 },\n'
                                 '    { tag = "lower", damping = { alpha = 3.0 } },'))  # fmt: skip
    assert main(["run", str(case), "--out", str(tmp_path / "o"), "--quiet"]) == 0
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert s["damping"]["regions"] == [{"tag": "lower", "alpha": 3.0, "beta": 0.0}]


def test_a_resume_with_the_damped_cells_changed_is_refused(tmp_path):
    """The checkpoint's identity has figures of C itself: the same tag and coefficients on other cells is
    another run."""
    zone = RegionalRayleigh(UNDAMPED, (("zone", Rayleigh(alpha=20.0)),))
    p = _two_blocks(0.002, zone)
    p.mesh.regions["zone"] = p.mesh.regions["upper"].copy()
    simulate(p, "cn", 1e-4, 5e-4, checkpoint=tmp_path / "c.h5")
    q = _two_blocks(0.002, zone)
    q.mesh.regions["zone"] = q.mesh.regions["upper"][:4]  # fewer damped cells, same tag and coefficients
    with pytest.raises(InputError, match="damping_matrix"):
        simulate(q, "cn", 1e-4, 1e-3, resume=tmp_path / "c.h5")

"""The scheme contract: registry entries, schemes written outside the package, equivalences."""

import dataclasses
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from distinct_schemes import REPEATS
from signorini.dynamics.schemes import SCHEMES, make_scheme
from signorini.dynamics.stepping.simulate import simulate
from signorini.errors import InputError
from signorini.fem.material import NeoHookean
from signorini.io.cli import main
from signorini.io.plugins import load_scheme
from signorini.studies.benchmarks import get_benchmark

#: the scheme of your own of the README and docs/schemes.md, imported from its file
EXAMPLE = Path(__file__).parents[3] / "examples" / "my_schemes.py"
MyTheta = load_scheme(f"{EXAMPLE}:MyTheta")
MyThetaAnyModel = load_scheme(f"{EXAMPLE}:MyThetaAnyModel")


def _bar2d(n=2):
    b = get_benchmark("bar2d")
    return b.problem(n), b.h(n) / 2


def _same(H1, H2, tol=1e-11):
    scale = max(np.abs(H2.lam).max(), 1e-300)
    assert np.abs(H1.lam - H2.lam).max() <= tol * scale
    assert np.abs(H1.gap - H2.gap).max() <= tol * 0.2
    assert np.abs(H1.energy - H2.energy).max() <= tol * H2.energy[0]


@pytest.mark.parametrize("mass", ["seed", "standard"])
def test_external_scheme_matches_builtin_theta(mass):
    p, dt = _bar2d()
    H_ext = simulate(p, MyTheta, dt, 1.0, mass=mass, scheme_options={"theta": 0.6})
    H_reg = simulate(p, "theta", dt, 1.0, mass=mass, scheme_options={"theta": 0.6})
    _same(H_ext, H_reg)
    assert H_ext.lam.min() < 0  # there was contact


@pytest.mark.parametrize("model", ["linear", "neo-hookean"])
def test_a_scheme_of_your_own_stated_as_a_step_problem_runs_any_material_model(model):
    """The example's theta stated as a StepProblem: the package's solver runs it linear (one solve) and with
    finite strain (Newton) and it reproduces the registered theta, which states its step the same way."""
    p, dt = _bar2d()
    if model != "linear":
        b = get_benchmark("bar2d")
        prm = b.params()
        p = dataclasses.replace(p, material=NeoHookean(prm["lam"], prm["mu"], prm["rho"]))
    T = 40 * dt  # into the contact
    H_ext = simulate(p, MyThetaAnyModel, dt, T, scheme_options={"theta": 0.6})
    H_reg = simulate(p, "theta", dt, T, scheme_options={"theta": 0.6})
    assert H_ext.status == H_reg.status == "finished"
    _same(H_ext, H_reg, tol=1e-13)
    assert H_ext.lam.min() < 0  # there was contact
    iterations = H_ext.columns()["nonlinear_iterations"]
    assert (iterations.max() > 1) == (model != "linear")  # Newton iterated only with finite strain


# What the installed ``signorini`` console script does: its own directory, not the working
# directory, is sys.path[0] (unlike ``python -m``/``-c``, which would hide a missing cwd).
CONSOLE_SCRIPT = "import sys\nfrom signorini.io.cli import main\nsys.exit(main())\n"


def _signorini_cli(tmp_path: Path) -> list[str]:
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    (bin_dir / "signorini_cli.py").write_text(CONSOLE_SCRIPT)
    return [sys.executable, str(bin_dir / "signorini_cli.py")]


def test_external_scheme_by_import_path_on_the_cli(tmp_path):
    """``--scheme module:Class`` finds ./module.py, ``--scheme dir/file.py:Class`` a file."""
    import signorini

    cli = _signorini_cli(tmp_path)
    work = tmp_path / "work"
    work.mkdir()
    (work / "my_schemes.py").write_text(EXAMPLE.read_text())
    src = str(Path(signorini.__file__).parents[2])  # the package under test, not the cwd
    env = {**os.environ, "PYTHONPATH": src, "OMP_NUM_THREADS": "1"}
    args = ["run", "bar2d", "--n", "2", "--T", "0.6", "--quiet", "--scheme-option", "theta=0.6"]
    runs = {"module": ("my_schemes:MyTheta", work), "file": ("work/my_schemes.py:MyTheta", tmp_path)}
    for label, (scheme, cwd) in runs.items():
        r = subprocess.run(cli + args + ["--scheme", scheme, "--out", str(tmp_path / label)],
                           cwd=cwd, env=env, capture_output=True, text=True, timeout=120)  # fmt: skip
        assert r.returncode == 0, r.stderr
        s = json.loads((tmp_path / label / "summary.json").read_text())
        assert s["scheme"] == "my-theta(theta=0.6)" and s["status"] == "finished"
    out = tmp_path / "registered"
    assert main(args + ["--scheme", "theta", "--out", str(out)]) == 0
    b = np.loadtxt(out / "history.csv", delimiter=",", skiprows=1)
    cols = [0, 1, 2, 3, 4, 6, 7, 8, 9, 10, 11]  # all but the identity columns (MyTheta declares none)
    for label in runs:
        a = np.loadtxt(tmp_path / label / "history.csv", delimiter=",", skiprows=1)
        assert np.allclose(a[:, cols], b[:, cols], rtol=1e-10, atol=1e-14, equal_nan=True)


@pytest.mark.parametrize(
    "scheme, says",
    [
        ("no_such_module:MyTheta", "cannot import"),
        ("missing/dir/x.py:MyTheta", "no file"),
        ("json:dumps", "not a subclass"),
    ],
)
def test_bad_scheme_import_path_is_input_error(tmp_path, capsys, scheme, says):
    out = tmp_path / "o"
    assert main(["run", "bar2d", "--n", "2", "--T", "0.6", "--quiet", "--scheme", scheme, "--out", str(out)]) == 2
    assert says in capsys.readouterr().err and not out.exists()


def test_registered_at_runtime_then_removed():
    SCHEMES.register("my-theta", MyTheta, MyTheta.description, ("mt",), MyTheta.parameters)
    try:
        p, dt = _bar2d()
        H = simulate(p, "mt", dt, 0.5, scheme_options={"theta": 0.7})
        assert H.meta["scheme"] == "my-theta(theta=0.7)"
    finally:
        SCHEMES.unregister("my-theta")
    with pytest.raises(InputError, match="unknown scheme 'mt'; allowed: crank-nicolson, cn"):
        simulate(p, "mt", dt, 0.5)


@pytest.mark.parametrize(
    "name, options, same_as",
    [
        ("newmark", {"beta": 0.25, "gamma": 0.5}, "crank-nicolson"),
        ("theta", {"theta": 0.5}, "crank-nicolson"),
        ("theta", {"theta": 1.0}, "backward-euler"),
        *((name, {}, same_as) for name, same_as in REPEATS.items()),  # the defaults, left out of the sweeps
    ],
)
def test_parametrized_entries_reproduce_named_schemes(name, options, same_as):
    p, dt = _bar2d()
    _same(simulate(p, name, dt, 1.0, scheme_options=options), simulate(p, same_as, dt, 1.0))


@pytest.mark.parametrize(
    "name, options, message",
    [
        ("newmark", {"beta": 0.0}, "'scheme newmark.beta' must satisfy 0.0 < beta <= 0.5"),
        ("newmark", {"gamma": 0.4}, "gamma"),
        ("theta", {"theta": 0.3}, "theta"),
        ("newmark", {"alpha": 0.1}, "unknown option 'alpha' for 'newmark'; allowed: beta, gamma"),
        ("ps", {"restitution": "x"}, "must be a number"),
        ("cn", {"beta": 0.3}, "allowed: none"),
    ],
)
def test_bad_scheme_options(name, options, message):
    with pytest.raises(InputError, match=message.replace("(", r"\(").replace(")", r"\)")):
        make_scheme(name, options)


@pytest.mark.parametrize("entry", [e for e in SCHEMES if e.name not in REPEATS], ids=lambda e: e.name)
def test_every_registered_scheme_identity_and_complementarity(entry):
    """Every registry entry: complementarity and its own energy identity to round-off."""
    p, dt = _bar2d()
    H = simulate(p, entry.name, dt, 1.2, mass="seed" if entry.obj.massless_dofs_allowed else "standard")
    assert H.status == "finished" and H.lam.max() <= 0
    if entry.obj.exact_contact:
        assert H.gap.min() > -1e-14  # measured -2.1e-17
    else:  # velocity-level or penalized contact: penetration of the order of v dt
        assert H.gap.min() > -dt
    ok = np.isfinite(H.predicted_increment)
    assert ok[1:].all()  # every step has an identity (Paoli-Schatzman's start-up step too)
    err = np.abs(H.energy_increment - H.predicted_increment)[ok]
    assert err.max() <= 2e-12 * H.energy[0]  # measured 3.0e-14 of E0
    # cumulative parts add up to the energy change from level 0
    total = H.external_work + H.contact_work + H.numerical_dissipation
    # docs/verification.md: 1e-11 of the energy scale (measured 6.8e-14 E0)
    assert np.allclose(H.energy - H.energy[0], total, rtol=0, atol=5e-12 * H.energy[0])  # measured 8.3e-14 of E0
    assert H.meta["energy_definition"]


def test_newmark_general_energy_identity_and_dissipation():
    p, dt = _bar2d()
    H = simulate(p, "newmark", dt, 2.0, mass="standard", scheme_options={"beta": 0.3025, "gamma": 0.6})
    ok = np.isfinite(H.predicted_increment)
    assert np.abs(H.energy_increment - H.predicted_increment)[ok].max() <= 2e-12 * H.energy[0]  # measured 2.5e-14 of E0
    assert H.numerical_dissipation[-1] < 0  # gamma > 1/2 damps


def _paoli_schatzman_reference(disc, dt, N, e=0.0):
    """The previous implementation's loop (separate factor, CN start), for comparison."""
    import scipy.sparse.linalg as spla

    from signorini.contact.complementarity import solve_lcp

    H1 = simulate(disc, "cn", dt, dt, snapshot_every=1)
    f = disc.free
    M, S, B = disc.M[f][:, f], disc.S[f][:, f], disc.B[:, f].toarray()
    K = (M / dt**2 + 0.25 * S).tocsc()
    lu = spla.splu(K)
    F = disc.load(0.0)[f] - (disc.S[f][:, disc.fixed] @ disc.dirichlet(0.0))
    g = disc.contact.gaps
    Z = lu.solve(B.T.copy())
    W = B @ Z
    U_prev, U = disc.U0[f], H1.snapshots["u"][1][f]
    lams = [H1.lam[0], H1.lam[1]]
    for _ in range(1, N):
        rhs = M @ (2 * U - U_prev) / dt**2 - 0.25 * (S @ (2 * U + U_prev)) + F
        Uf = lu.solve(rhs)
        res = solve_lcp(0.5 * (W + W.T), (1 + e) * g - e * (B @ U_prev) - B @ Uf)
        U_prev, U = U, Uf - Z @ res.mu
        lams.append(-res.mu)
    return np.array(lams)


@pytest.mark.parametrize("backend", ["superlu", "cg"])
def test_paoli_schatzman_same_history_one_factorization(backend):
    from signorini.dynamics.model.problem import discretize

    b = get_benchmark("bar1d")
    disc = discretize(b.problem(40), "standard")
    dt = b.h(40) / 2
    H = simulate(disc, "ps", dt, 3.0, backend=backend)
    ref = _paoli_schatzman_reference(disc, dt, H.steps)
    tol = 1e-10 if backend == "superlu" else 1e-7
    assert np.abs(H.lam - ref).max() <= tol * np.abs(ref).max()
    assert H.meta["backend"].startswith(backend)
    assert H.counters["factorizations"] == (1 if backend == "superlu" else 0)
    assert H.counters["steps"] == H.steps == 240
    assert H.counters["linear_solves"] >= H.steps
    assert H.counters["fallbacks"] == int(H.fallbacks.sum())

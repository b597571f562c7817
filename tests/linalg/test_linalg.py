"""Every linear-algebra backend gives the default's solution; the automatic choice."""

import numpy as np
import pytest
from packaging.version import Version

from backends import DIRECT
from signorini.dynamics.stepping.simulate import simulate
from signorini.linalg import choose_backend, estimate_factor_bytes, has_cholmod, has_metis, has_pardiso, has_pyamg
from signorini.studies.benchmarks import get_benchmark

# SuperLU gives the reference: comparing it with itself would be bit-identical, so it is not
# among the backends compared (its factor is checked against SuperLU with MMD below)
BACKENDS = [*(b for b in DIRECT if b != "superlu"), "cg"]


@pytest.fixture(scope="module")
def reference():
    b = get_benchmark("bar3d")
    H = simulate(b.problem(3), "cn", b.h(3) / 2, 1.0, mass="seed", backend="superlu")
    assert H.meta["backend"].startswith("superlu")
    return H


@pytest.mark.parametrize("backend", BACKENDS)
def test_backends_agree_with_default(reference, backend):
    b = get_benchmark("bar3d")
    H = simulate(b.problem(3), "cn", b.h(3) / 2, 1.0, mass="seed", backend=backend)
    assert H.meta["backend"].startswith(backend)
    scale = np.abs(reference.lam).max()
    assert np.abs(H.lam - reference.lam).max() <= 1e-8 * scale
    assert np.abs(H.gap - reference.gap).max() <= 1e-8 * 0.2
    assert np.abs(H.energy - reference.energy).max() <= 1e-8 * reference.energy[0]
    assert H.residual.max() <= 1e-10


@pytest.mark.skipif(not has_pyamg(), reason="pyamg not installed (extra 'amg')")
def test_amg_preconditioned_active_set_agrees(reference):
    from signorini.contact.solver import ActiveSetCGSolver, CondensedContactSolver
    from signorini.dynamics.model.problem import discretize

    b = get_benchmark("bar3d")
    d = discretize(b.problem(3), "seed")
    dt = b.h(3) / 2
    f = d.free
    K = (4 / dt**2 * d.M + d.S).tocsr()[f][:, f]
    B = d.B[:, f]
    st = ActiveSetCGSolver(K, B, 0.2, preconditioner="amg")
    # one contact step from a state pressed into the obstacle
    rhs = 4 / dt**2 * (d.M @ (d.U0 - 0.25 * np.tile([0, 0, 1.0], d.M.shape[0] // 3)))[f]
    U, lam, info = st.solve(rhs, d.contact.gaps)
    U2, lam2, _ = CondensedContactSolver(K, B, 0.2).solve(rhs, d.contact.gaps)
    assert lam.min() < 0
    assert np.abs(lam - lam2).max() <= 1e-8 * np.abs(lam2).max()
    assert np.abs(U - U2).max() <= 1e-8 * np.abs(U2).max()


def test_automatic_choice_uses_budget():
    n = 20_000
    assert choose_backend(n, 3, budget=1e3) == "cg"
    big = 10 * estimate_factor_bytes(n, 3, "superlu")
    # the first Cholesky installed (Pardiso, then CHOLMOD, which the plain install has where
    # cvxopt has wheels), else SuperLU; the test pinned "superlu or pardiso" before CHOLMOD was core
    expected = "pardiso" if has_pardiso() else "cholmod" if has_cholmod() else "superlu"
    assert choose_backend(n, 3, budget=big) == expected
    b = get_benchmark("bar3d")
    H = simulate(b.problem(2), "cn", b.h(2) / 2, 0.5, mass="seed", memory_budget=1.0)
    assert H.meta["backend"].startswith("cg")


def test_auto_prefers_cg_for_large_mass_dominated_3d_without_a_cholesky(monkeypatch):
    import signorini.linalg.base as base

    n, big = 140_000, 1e15
    monkeypatch.setattr(base, "has_pardiso", lambda: False)
    monkeypatch.setattr(base, "has_cholmod", lambda: False)
    assert choose_backend(n, 3, big, cg_friendly=True) == "cg"
    assert choose_backend(n, 3, big, cg_friendly=False) == "superlu"
    assert choose_backend(n, 2, big, cg_friendly=True) == "superlu"  # SuperLU is fine in 2D
    assert choose_backend(20_000, 3, big, cg_friendly=True) == "superlu"  # small: SuperLU first
    monkeypatch.setattr(base, "has_cholmod", lambda: True)
    assert choose_backend(n, 3, big, cg_friendly=True) == "cholmod"  # a Cholesky beats both


def test_auto_takes_a_cholesky_in_3d_from_a_few_thousand_dofs(monkeypatch):
    """With CHOLMOD installed (the plain install where cvxopt has wheels) and no Pardiso:
    3D from about 4k dofs, 2D from 30k; a small run never imports cvxopt; Pardiso first."""
    import signorini.linalg.base as base

    asked = []

    def spy(name, value):
        return lambda: asked.append(name) or value

    big = 1e15
    monkeypatch.setattr(base, "has_pardiso", spy("pardiso", False))
    monkeypatch.setattr(base, "has_cholmod", spy("cholmod", True))
    assert choose_backend(2_000, 3, big) == "superlu" and asked == []  # cvxopt not even imported
    assert choose_backend(20_000, 2, big) == "superlu" and asked == []  # 2D: SuperLU below 30k
    for n in (6_000, 20_000, 35_000, 140_000):
        asked.clear()
        assert choose_backend(n, 3, big) == "cholmod"
        assert choose_backend(n, 3, big, cg_friendly=True) == "cholmod"
        assert asked == ["pardiso", "cholmod"] * 2
    assert choose_backend(100_000, 2, big) == "cholmod"
    assert choose_backend(35_000, 3, 1e3) == "cg"  # no factor fits
    monkeypatch.setattr(base, "has_pardiso", spy("pardiso", True))
    assert choose_backend(20_000, 3, big) == "pardiso"
    # where the crossing is: the first 3D size whose Cholesky estimate is below SuperLU's
    first = next(n for n in range(1_000, 10_000, 100) if choose_backend(n, 3, big) != "superlu")
    assert 3_000 <= first <= 5_000


def _requirements(extra: str | None = None) -> list:
    import tomllib
    from pathlib import Path

    from packaging.requirements import Requirement

    project = tomllib.loads((Path(__file__).parents[2] / "pyproject.toml").read_text())["project"]
    listed = project["optional-dependencies"][extra] if extra else project["dependencies"]
    return [Requirement(r) for r in listed]


#: the releases on PyPI when the markers were written, each with the platforms of its wheels
#: (pip download --only-binary=:all: --platform ... --python-version ...); cvxopt 1.3.3 has an
#: sdist and no macOS wheel: pip takes the newest release its specifier allows, sdist or not
RELEASES = {
    "cvxopt": ["1.2.7", "1.3.0", "1.3.1", "1.3.2", "1.3.3"],
    "pymetis": ["2023.1.1", "2025.1.1", "2025.2", "2025.2.1", "2025.2.2"],
}

PLATFORMS = {  # (sys_platform, platform_machine, python_version): the (cvxopt, pymetis) release pip takes
    ("linux", "x86_64", "3.11"): ("1.3.3", "2025.2.2"),
    ("linux", "x86_64", "3.14"): ("1.3.3", "2025.2.2"),
    ("linux", "aarch64", "3.12"): ("1.3.3", None),  # no pymetis wheel for Linux aarch64
    ("win32", "AMD64", "3.13"): ("1.3.3", None),  # nor for Windows
    ("darwin", "arm64", "3.12"): ("1.3.2", "2025.2.2"),  # the last cvxopt with macOS wheels
    ("darwin", "arm64", "3.13"): (None, "2025.2.2"),  # no cvxopt wheel for macOS from Python 3.13
    ("darwin", "x86_64", "3.11"): ("1.3.2", "2025.2.2"),
    ("linux", "x86_64", "3.15"): (None, None),  # no wheels yet: never a source build
    ("linux", "ppc64le", "3.12"): (None, None),
    ("win32", "ARM64", "3.12"): (None, None),
}


@pytest.mark.parametrize("platform", PLATFORMS, ids="-".join)
def test_plain_install_has_cholmod_and_metis_where_wheels_exist(platform):
    env = dict(zip(("sys_platform", "platform_machine", "python_version"), platform, strict=True))
    core = _requirements()
    got = []
    for name in ("cvxopt", "pymetis"):
        applies = [r for r in core if r.name == name and r.marker.evaluate(env)]
        assert len(applies) <= 1, applies
        got.append(max(applies[0].specifier.filter(RELEASES[name]), key=Version) if applies else None)
    assert tuple(got) == PLATFORMS[platform]


def test_extras_cholmod_and_metis_still_install_them_anywhere():
    (cvxopt,) = _requirements("cholmod")
    (pymetis,) = _requirements("metis")
    assert cvxopt.marker is None and pymetis.marker is None
    assert str(pymetis.specifier) == next(str(r.specifier) for r in _requirements() if r.name == "pymetis")


def test_fill_reducing_order_says_which(monkeypatch, bar3d_operator):
    import signorini.linalg.ordering as ordering

    monkeypatch.setattr(ordering, "has_metis", lambda: False)
    assert ordering.fill_reducing_order(bar3d_operator)[1] == "nd"
    monkeypatch.setattr(ordering, "ORDERING", "nd-levels")
    assert ordering.fill_reducing_order(bar3d_operator)[1] == "nd-levels"
    with pytest.raises(ValueError, match="unknown ordering 'amd'"):
        ordering.fill_reducing_order(bar3d_operator, "amd")


def test_factors_record_their_ordering(bar3d_operator):
    from signorini.linalg import factorize

    expected = "metis" if has_metis() else "nd"
    assert factorize(bar3d_operator, "superlu").ordering == expected
    if has_cholmod():
        assert factorize(bar3d_operator, "cholmod").ordering == expected


def test_stiffness_to_mass_ratio_scales_with_dt_squared():
    from signorini.dynamics.model.problem import discretize
    from signorini.dynamics.schemes import make_scheme
    from signorini.dynamics.solve.context import Context, stiffness_to_mass_ratio
    from signorini.linalg.base import CG_FRIENDLY_RATIO

    b = get_benchmark("bar3d")
    disc = discretize(b.problem(2), "seed")
    ctx = Context(disc, b.h(2) / 2)
    cn = make_scheme("cn")
    r = stiffness_to_mass_ratio(cn.operator(b.h(2) / 2), ctx)
    assert 0 < r <= CG_FRIENDLY_RATIO  # the bars with dt = h/2 are mass-dominated
    assert stiffness_to_mass_ratio(cn.operator(b.h(2)), ctx) == pytest.approx(4 * r, rel=1e-14, abs=0)  # measured 0
    assert stiffness_to_mass_ratio(cn.operator(10 * b.h(2)), ctx) > CG_FRIENDLY_RATIO


RUNS = [("cn", 0.5, True), ("cn", 10.0, False), ("moreau-jean", 0.5, False), ("penalty", 0.5, False)]


@pytest.mark.parametrize(("scheme", "dt_factor", "friendly"), RUNS)
def test_auto_is_told_whether_cg_suits_the_run(monkeypatch, scheme, dt_factor, friendly):
    """The run passes cg_friendly = mass-dominated operator and a scheme that can use cg."""
    import signorini.contact.solver as solver

    seen = []
    real = solver.choose_backend

    def spy(n, dim, budget=None, cg_friendly=False, refactorized=False):
        seen.append(cg_friendly)
        return real(n, dim, budget, cg_friendly, refactorized)

    monkeypatch.setattr(solver, "choose_backend", spy)
    b = get_benchmark("bar3d")
    dt = dt_factor * b.h(2)
    mass = "standard" if scheme == "moreau-jean" else "seed"
    H = simulate(b.problem(2), scheme, dt, 4 * dt, mass=mass)
    assert H.status == "finished" and seen and all(f == friendly for f in seen)


def test_unknown_backend_is_an_error():
    from signorini.errors import InputError

    b = get_benchmark("bar1d")
    with pytest.raises(InputError, match="unknown solver.backend 'mumps'"):
        simulate(b.problem(4), "cn", 0.1, 1.0, backend="mumps")


@pytest.fixture(scope="module")
def bar3d_operator():
    """K = 4/dt^2 M + S on the free dofs of bar3d n = 8 (seed mass, dt = h/2): 19,440 dofs."""
    import scipy.sparse as sp

    from signorini.dynamics.model.problem import discretize

    b = get_benchmark("bar3d")
    d = discretize(b.problem(8), "seed")
    dt = b.h(8) / 2
    return sp.csc_matrix((4 / dt**2 * d.M + d.S).tocsr()[d.free][:, d.free])


ORDERINGS = [
    "nd",
    "nd-levels",
    pytest.param("metis", marks=pytest.mark.skipif(not has_metis(), reason="pymetis not installed (extra 'metis')")),
]


@pytest.mark.parametrize("ordering", ORDERINGS)
def test_nested_dissection_is_a_nodal_permutation_that_fills_less(bar3d_operator, ordering):
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    from signorini.linalg.ordering import fill_reducing_order, supervariables

    K = bar3d_operator
    n = K.shape[0]
    assert np.array_equal(supervariables(K), np.arange(n) // 3)  # node-major dof triplets found
    p, name = fill_reducing_order(K, ordering)
    assert name == ordering
    assert np.array_equal(np.sort(p), np.arange(n))
    assert np.array_equal(p.reshape(-1, 3) % 3, np.tile([0, 1, 2], (n // 3, 1)))  # nodes stay together
    opts = dict(diag_pivot_thresh=0.0, options={"SymmetricMode": True})
    mmd = spla.splu(K, permc_spec="MMD_AT_PLUS_A", **opts)
    nd = spla.splu(sp.csc_matrix(K[p][:, p]), permc_spec="NATURAL", **opts)
    # METIS fills 0.72 x MMD here; the level-set ordering no longer beats MMD at this size with
    # scipy 1.17 (16.8M vs 15.2M entries; 85.4M vs 85.2M at n = 12): docs/performance.md
    assert nd.nnz < (0.9 if ordering == "metis" else 1.15) * mmd.nnz


def test_supervariables_without_node_blocks():
    import scipy.sparse as sp

    from signorini.linalg.ordering import nested_dissection, supervariables

    # a path graph of 7 vertices with 2x2 blocks except the last vertex: groups by pattern
    path = np.array([[4.0, 1, 0], [1, 4, 1], [0, 1, 4]])
    A = sp.lil_matrix(np.kron(path, np.ones((2, 2))))
    A.resize((7, 7))
    A[6, 6] = 1.0
    A[5, 6] = A[6, 5] = 1.0
    g = supervariables(A)
    assert g[0] == g[1] and g[2] == g[3] and g[4] != g[5] != g[6]
    assert np.array_equal(np.sort(nested_dissection(A, leaf=1)), np.arange(7))


@pytest.mark.parametrize("backend", DIRECT)
def test_direct_factors_agree_in_3d(bar3d_operator, backend):
    """Each backend (SuperLU in nested-dissection order here) against SuperLU with MMD."""
    import scipy.sparse.linalg as spla

    from signorini.linalg import factorize
    from signorini.linalg.superlu import use_nested_dissection

    K = bar3d_operator
    assert use_nested_dissection(K)
    ref = spla.splu(K, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
    rng = np.random.default_rng(3)
    b = rng.standard_normal((K.shape[0], 5))
    F = factorize(K, backend)
    X, Y = F.solve(b), ref.solve(b)
    assert np.abs(X - Y).max() <= 1e-10 * np.abs(Y).max()
    x = F.solve(b[:, 0])
    assert x.shape == (K.shape[0],) and np.abs(x - Y[:, 0]).max() <= 1e-10 * np.abs(Y[:, 0]).max()
    assert F.solves == 6 and F.nbytes >= 0


@pytest.mark.skipif(not has_cholmod(), reason="cvxopt not installed (extra 'cholmod')")
def test_cholmod_solves_a_block_of_columns_in_one_call(bar3d_operator, monkeypatch):
    """A block of Delassus columns (a few nonzeros each) reaches CHOLMOD in one
    ``cholmod.spsolve`` call, not one ``cholmod.solve`` per column (cvxopt's loop); the
    same numbers as column by column (measured 1.7e-16 here, 1.3e-16..3.3e-16 over three
    draws, 5e-16 on the 35.6k-dof ball)."""
    import cvxopt.cholmod
    import scipy.sparse as sp

    from signorini.linalg import factorize

    K = bar3d_operator
    F = factorize(K, "cholmod")
    rng = np.random.default_rng(5)
    b = sp.random(K.shape[0], 64, density=3 / K.shape[0], random_state=rng, format="csc").toarray()
    one_by_one = np.column_stack([F.solve(b[:, j]) for j in range(b.shape[1])])
    calls = []
    for name in ("solve", "spsolve"):
        real = getattr(cvxopt.cholmod, name)
        monkeypatch.setattr(
            cvxopt.cholmod, name, lambda *a, real=real, name=name, **k: calls.append(name) or real(*a, **k)
        )
    X = F.solve(b)
    assert calls == ["spsolve"]
    assert np.abs(X - one_by_one).max() <= 1e-14 * np.abs(one_by_one).max()


def test_superlu_keeps_minimum_degree_in_2d():
    import scipy.sparse as sp

    from signorini.dynamics.model.problem import discretize
    from signorini.linalg.superlu import use_nested_dissection

    b = get_benchmark("bar2d")
    d = discretize(b.problem(32), "seed")
    K = sp.csc_matrix((d.M + d.S).tocsr()[d.free][:, d.free])
    assert K.shape[0] > 15_000 and not use_nested_dissection(K)


def test_an_optional_module_that_fails_to_import_says_why(monkeypatch, tmp_path):
    """module_loads: installed but failing (a broken MKL, a missing shared library) counts as
    absent, and the reason is kept for the run's summary (optional_import_failures)."""
    import sys

    from signorini.linalg.base import IMPORT_FAILURES, module_loads

    (tmp_path / "broken_optional_mod.py").write_text("raise OSError('libmkl_rt.so.2: cannot open shared object file')")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, "broken_optional_mod", raising=False)
    assert not module_loads("broken_optional_mod")
    assert IMPORT_FAILURES["broken_optional_mod"] == "OSError: libmkl_rt.so.2: cannot open shared object file"
    IMPORT_FAILURES.pop("broken_optional_mod")

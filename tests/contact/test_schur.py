"""Schur condensation: W from the Schur complement of K on the contact dofs (Pardiso)."""

import numpy as np
import pytest
import scipy.sparse as sp

from signorini.contact.schur import SchurDelassus, schur_dofs
from signorini.contact.solver import SCHUR_MIN_NODES, choose_condensation
from signorini.dynamics.stepping.simulate import simulate
from signorini.errors import InputError
from signorini.linalg import factorize, has_pardiso
from test_delassus import CASES, _agree, _curved

needs_pardiso = pytest.mark.skipif(not has_pardiso(), reason="pypardiso not installed (extra 'pardiso')")


def _spd(n: int, seed: int = 1) -> sp.csr_matrix:
    A = sp.random(n, n, density=0.15, random_state=seed)
    return sp.csr_matrix(A @ A.T + 4 * sp.eye(n))


def _normals(rng, nc: int, n: int, dim: int = 3) -> sp.csr_matrix:
    """nc rows, each a unit normal on the dim dofs of a distinct node (curved contact)."""
    nodes = rng.choice(n // dim, nc, replace=False)
    nu = rng.normal(size=(nc, dim))
    nu /= np.linalg.norm(nu, axis=1, keepdims=True)
    rows = np.repeat(np.arange(nc), dim)
    cols = (dim * nodes[:, None] + np.arange(dim)).ravel()
    return sp.csr_matrix((nu.ravel(), (rows, cols)), shape=(nc, n))


@needs_pardiso
def test_pardiso_schur_complement_and_split_solve(rng):
    n = 60
    K = _spd(n)
    C = np.sort(rng.choice(n, 9, replace=False))
    F = factorize(K, "pardiso", schur_dofs=C)
    Kinv = np.linalg.inv(K.toarray())
    S_exact = np.linalg.inv(Kinv[np.ix_(C, C)])  # (K^-1)_CC = S^-1
    assert np.abs(F.schur - S_exact).max() <= 5e-14 * np.abs(S_exact).max()  # measured 7.7e-16 relative
    b = rng.normal(size=n)
    y = F.forward(b)
    interior = np.setdiff1d(np.arange(n), C)
    Kd = K.toarray()
    reduced = b[C] - Kd[np.ix_(C, interior)] @ np.linalg.solve(Kd[np.ix_(interior, interior)], b[interior])
    assert np.allclose(y[C], reduced, rtol=0, atol=2e-14 * np.abs(reduced).max())  # measured 3.2e-16 of max
    x = Kinv @ b
    y[C] = x[C]
    assert np.allclose(F.backward(y), x, rtol=0, atol=2e-14 * np.abs(x).max())  # measured 3.1e-16 of max
    assert np.allclose(F.solve(b), x, rtol=0, atol=2e-14 * np.abs(x).max())  # plain solves still work (3.1e-16)


def test_schur_needs_a_backend_that_computes_it():
    with pytest.raises(InputError, match="cannot compute a Schur complement"):
        factorize(_spd(10), "superlu", schur_dofs=np.array([1, 2]))


@needs_pardiso
def test_schur_delassus_matches_the_dense_delassus_and_the_constrained_solve(rng):
    """Normals on 3 dofs per node (curved contact): W = B K^-1 B^T, and free/complete
    give x_free = K^-1 b and x = K^-1 (b + B^T lambda)."""
    n, nc = 90, 6
    K = _spd(n, seed=3)
    B = _normals(rng, nc, n)
    dofs = schur_dofs(B)
    assert dofs.size == 3 * nc
    D = SchurDelassus(factorize(K, "pardiso", schur_dofs=dofs), B)
    Kinv = np.linalg.inv(K.toarray())
    W = B @ Kinv @ B.T.toarray()
    assert np.abs(D.W(np.arange(nc), np.arange(nc)) - W).max() <= 2e-14 * np.abs(W).max()  # measured 4.5e-16
    P = np.array([4, 0, 2])
    assert np.allclose(D.block(P), W[np.ix_(P, P)], rtol=2e-13, atol=0)  # measured 4.1e-15
    b, lam = rng.normal(size=n), -np.abs(rng.normal(size=nc))
    state, Bx = D.free(b)
    assert np.allclose(Bx, B @ Kinv @ b, rtol=0, atol=1e-14)  # measured 1.1e-16 (|Bx| <= 0.41)
    x = D.complete(state, lam)
    x_exact = Kinv @ (b + B.T @ lam)
    assert np.abs(x - x_exact).max() <= 5e-14 * np.abs(x_exact).max()  # measured 8.6e-16 relative
    assert D.count == nc  # every column known from the set-up, no solve per column


@needs_pardiso
@pytest.mark.parametrize("case", sorted(CASES))
def test_schur_equals_full_condensation(case):
    problem, dt = CASES[case]()
    T = 80 * dt if case != "bar1d" else 2.0
    runs = {
        c: simulate(problem, "cn", dt, T, solver_options={"backend": "pardiso", "condensation": c})
        for c in ("schur", "full")
    }
    assert np.abs(runs["full"].lam).max() > 0  # there was contact
    _agree(runs["schur"], runs["full"])
    assert runs["schur"].meta["condensation"] == "schur" and runs["full"].meta["condensation"] == "full"
    # one forward/backward pair per step: as many solves as steps
    assert runs["schur"].counters["linear_solves"] == runs["schur"].steps


@needs_pardiso
@pytest.mark.parametrize("scheme", ["moreau-jean", "penalty", "hht", "paoli-schatzman"])
def test_schur_equals_lazy_with_index_sets_compliance_and_two_step_schemes(scheme):
    problem, dt = _curved(3, 3)
    opts = {"theta": 1.0} if scheme == "moreau-jean" else {}
    mass = "standard" if scheme == "paoli-schatzman" else "seed"
    runs = [
        simulate(
            problem,
            scheme,
            dt,
            60 * dt,
            mass=mass,
            scheme_options=opts,
            solver_options={"backend": "pardiso", "condensation": c},
        )  # fmt: skip
        for c in ("schur", "lazy")
    ]
    assert np.abs(runs[1].lam).max() > 0
    _agree(*runs)


def _contact_matrix(nc: int, n: int) -> sp.csr_matrix:
    return sp.csr_matrix((np.ones(nc), (np.arange(nc), 3 * np.arange(nc) + 2)), shape=(nc, n))


@needs_pardiso
def test_auto_takes_schur_with_pardiso_and_many_contact_nodes():
    n = 3 * 4 * SCHUR_MIN_NODES
    many, few = _contact_matrix(SCHUR_MIN_NODES, n), _contact_matrix(SCHUR_MIN_NODES - 1, n)
    assert choose_condensation("auto", "pardiso", many, 2e9) == "schur"
    assert choose_condensation("auto", "pardiso", few, 2e9) == "lazy"
    assert choose_condensation("auto", "pardiso", many, 1e6) == "lazy"  # the dense matrices do not fit
    assert choose_condensation("auto", "pardiso", sp.csr_matrix((0, n)), 2e9) == "lazy"
    assert choose_condensation("full", "pardiso", many, 2e9) == "full"


def test_auto_is_lazy_without_pardiso_and_an_explicit_schur_is_refused():
    B = _contact_matrix(SCHUR_MIN_NODES, 3 * 4 * SCHUR_MIN_NODES)
    assert choose_condensation("auto", "superlu", B, 2e9) == "lazy"
    with pytest.raises(InputError, match="condensation='schur' needs the pardiso backend"):
        choose_condensation("schur", "superlu", B, 2e9)
    with pytest.raises(InputError, match="must be one of auto, lazy, full, schur"):
        choose_condensation("dense", "superlu", B, 2e9)


@needs_pardiso
def test_an_explicit_schur_with_backend_auto_takes_pardiso():
    problem, dt = CASES["bar2d"]()
    H = simulate(problem, "cn", dt, 10 * dt, solver_options={"condensation": "schur"})  # small: auto alone -> superlu
    assert H.meta["backend"] == "pardiso" and H.meta["condensation"] == "schur"


@needs_pardiso
def test_schur_dofs_in_any_order_and_out_of_range(rng):
    n = 30
    K = _spd(n, seed=5)
    C = np.array([7, 2, 19, 2, 11])
    S = factorize(K, "pardiso", schur_dofs=C).schur
    F = factorize(K, "pardiso", schur_dofs=np.unique(C))
    assert np.array_equal(F.schur_dofs, np.unique(C)) and np.allclose(S, F.schur, rtol=1e-14, atol=0)  # measured 0
    with pytest.raises(ValueError, match="must lie in"):
        factorize(K, "pardiso", schur_dofs=np.array([-1, 3]))


def test_summary_names_the_condensation_of_every_backend():
    problem, dt = CASES["bar2d"]()
    for backend, expected in (("superlu", "lazy"), ("cg", "none")):
        H = simulate(problem, "cn", dt, 5 * dt, solver_options={"backend": backend})
        assert H.meta["condensation"] == expected

"""The analyses of released factors shared by the next factorization of their pattern (linalg/base.py's
KeptAnalyses, used by linalg/cholmod.py and linalg/pardiso.py)."""

import numpy as np
import pytest
import scipy.sparse as sp

from signorini.linalg import factorize, has_cholmod, has_pardiso
from signorini.studies.benchmarks import get_benchmark

cholmod_only = pytest.mark.skipif(not has_cholmod(), reason="cvxopt not installed (extra 'cholmod')")
pardiso_only = pytest.mark.skipif(not has_pardiso(), reason="pypardiso not installed (extra 'pardiso')")


@pytest.fixture(scope="module")
def operators():
    """Two SPD matrices of one pattern (bar3d n = 3, K = c M + S, two values of c), and a third of another."""
    from signorini.dynamics.model.problem import discretize

    b = get_benchmark("bar3d")
    d = discretize(b.problem(3), "seed")
    M, S = d.M.tocsr()[d.free][:, d.free], d.S.tocsr()[d.free][:, d.free]
    K1, K2 = (sp.csc_matrix(c * M + S) for c in (1e3, 4e5))
    assert (K1.indptr == K2.indptr).all() and (K1.indices == K2.indices).all()
    other = sp.csc_matrix(S[:-3][:, :-3] + 1e3 * M[:-3][:, :-3])
    return K1, K2, other


@pytest.fixture(autouse=True)
def empty_pools():
    from signorini.linalg import cholmod, pardiso

    for module in (cholmod, pardiso):
        module.KEPT.clear()
    yield
    for module in (cholmod, pardiso):
        module.KEPT.clear()


def test_kept_analyses_hold_at_most_their_bound():
    from signorini.linalg.base import KEPT_SHARE, KeptAnalyses, clear_kept_analyses, total_memory

    kept = KeptAnalyses()
    a, b, c = object(), object(), object()
    assert kept.keep(("p",), a, 0) and kept.keep(("q",), b, 0)
    assert len(kept) == 1 and not kept.holds(a) and kept.holds(b)
    assert kept.take(("q",)) is b and len(kept) == 0
    kept.keep(("q",), b, 0)
    assert kept.take(("p",)) is None and len(kept) == 0  # another pattern's factorization: the kept one is freed
    assert not kept.keep(("q",), c, int(KEPT_SHARE * total_memory()) + 1) and len(kept) == 0  # too large to hold
    kept.keep(("q",), c, 0)
    clear_kept_analyses()
    assert len(kept) == 0


@cholmod_only
def test_a_released_cholmod_analysis_factorizes_the_next_bit_for_bit(operators, monkeypatch):
    """The second factorization of a pattern runs CHOLMOD's numeric phase only, and solves exactly as a fresh
    factorization of the same matrix (so a resumed run, which analyses again, stays bit for bit)."""
    import cvxopt.cholmod

    K1, K2, _ = operators
    b = np.random.default_rng(3).random(K1.shape[0])
    fresh = factorize(K2, "cholmod").solve(b)
    first = factorize(K1, "cholmod")
    first.release()
    analyses = []
    real = cvxopt.cholmod.symbolic
    monkeypatch.setattr(cvxopt.cholmod, "symbolic", lambda *a, **k: analyses.append(1) or real(*a, **k))
    second = factorize(K2, "cholmod")
    assert analyses == []
    assert np.array_equal(second.solve(b), fresh)
    assert second.nbytes >= first.nbytes  # at least the memory its factor held when it was made
    with pytest.raises(RuntimeError, match="released"):
        first.solve(b)


@cholmod_only
def test_an_analysis_serves_only_its_own_pattern_and_only_once_released(operators, monkeypatch):
    import cvxopt.cholmod

    from signorini.linalg import cholmod

    K1, K2, other = operators
    analyses = []
    real = cvxopt.cholmod.symbolic
    monkeypatch.setattr(cvxopt.cholmod, "symbolic", lambda *a, **k: analyses.append(1) or real(*a, **k))
    a = factorize(K1, "cholmod")
    b = factorize(K2, "cholmod")  # a is alive: its analysis is not shared
    assert len(analyses) == 2
    a.release()
    c = factorize(other, "cholmod")  # another pattern: analysed anew, the kept one freed before
    assert len(analyses) == 3 and len(cholmod.KEPT) == 0
    x = np.ones(other.shape[0])
    assert np.abs(other @ c.solve(x) - x).max() <= 1e-10
    b.release()
    c.release()
    assert len(cholmod.KEPT) == cholmod.KEPT.most  # the pool holds at most KEPT.most analyses (their memory)


@cholmod_only
def test_a_failed_factorization_drops_the_analysis_and_the_next_one_is_right(operators):
    """An indefinite matrix (a Newton tangent beyond stability) fails on a kept analysis as on a fresh one; the
    analysis goes with it and the next matrix is factorized right."""
    K1, K2, _ = operators
    factorize(K1, "cholmod").release()
    indefinite = sp.csc_matrix(K1 - 2 * float(K1.diagonal().max()) * sp.eye(K1.shape[0]))
    with pytest.raises(ArithmeticError):
        factorize(indefinite, "cholmod")
    from signorini.linalg import cholmod

    assert len(cholmod.KEPT) == 0
    b = np.random.default_rng(4).random(K2.shape[0])
    x = factorize(K2, "cholmod").solve(b)
    assert np.abs(K2 @ x - b).max() <= 1e-12 * np.abs(b).max() * float(abs(K2).sum(axis=1).max())


@pardiso_only
def test_a_released_pardiso_handle_factorizes_the_next(operators):
    """The second factorization of a pattern is MKL's numeric phase alone; in the reproducible mode it solves bit
    for bit as a fresh factorization of the same matrix (a resumed run analyses again)."""
    from signorini.linalg import pardiso

    K1, K2, _ = operators
    b = np.random.default_rng(3).random(K1.shape[0])
    fresh = factorize(K2, "pardiso", reproducible=True).solve(b)
    first = factorize(K1, "pardiso", reproducible=True)
    first.release()
    phases = []
    real = pardiso.PardisoFactor._call
    pardiso.PardisoFactor._call = lambda self, phase, *a: phases.append(phase) or real(self, phase, *a)
    try:
        second = factorize(K2, "pardiso", reproducible=True)
    finally:
        pardiso.PardisoFactor._call = real
    assert phases == [pardiso.NUMERIC]
    assert np.array_equal(second.solve(b), fresh)
    assert second.nbytes > 0
    with pytest.raises(RuntimeError, match="released"):
        first.solve(b)
    assert len(pardiso.KEPT) == 0
    second.release()
    third = factorize(K1, "pardiso")  # another key (not the reproducible mode): analysed anew, the kept one freed
    assert len(pardiso.KEPT) == 0
    assert np.abs(K1 @ third.solve(b) - b).max() <= 1e-9 * np.abs(b).max()
    third.release()
    assert len(pardiso.KEPT) == 1
    with pytest.raises(RuntimeError, match="released"):
        third.solve(b)


@pardiso_only
def test_a_schur_factor_is_never_shared(operators):
    from signorini.linalg import pardiso

    K1, _, _ = operators
    f = factorize(K1, "pardiso", schur_dofs=np.arange(6))
    f.release()
    assert len(pardiso.KEPT) == 0

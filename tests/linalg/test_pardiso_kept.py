"""Pardiso's analysis shared by the factorizations of one pattern (linalg/pardiso.py)."""

import numpy as np
import pytest
import scipy.sparse as sp

from signorini.linalg import factorize, has_pardiso
from signorini.studies.benchmarks import get_benchmark

pytestmark = pytest.mark.skipif(not has_pardiso(), reason="pypardiso not installed (extra 'pardiso')")


@pytest.fixture(scope="module")
def operators():
    """Two SPD matrices of one pattern (bar3d n = 3, K = c M + S, two values of c)."""
    from signorini.dynamics.model.problem import discretize

    b = get_benchmark("bar3d")
    d = discretize(b.problem(3), "seed")
    M, S = d.M.tocsr()[d.free][:, d.free], d.S.tocsr()[d.free][:, d.free]
    return tuple(sp.csr_matrix(c * M + S) for c in (1e3, 4e5))


@pytest.fixture(autouse=True)
def empty_pool():
    from signorini.linalg import pardiso

    pardiso.KEPT.clear()
    yield
    pardiso.KEPT.clear()


def test_a_released_factors_analysis_factorizes_the_next(operators):
    """The second factorization of a pattern is MKL's numeric phase alone; in the reproducible mode it solves bit
    for bit as a fresh factorization of the same matrix (a resumed run analyses again)."""
    from signorini.linalg import pardiso

    K1, K2 = operators
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
    assert pardiso.KEPT == []
    second.release()
    third = factorize(K1, "pardiso")  # another key (not the reproducible mode): analysed anew
    assert len(pardiso.KEPT) == 1
    assert np.abs(K1 @ third.solve(b) - b).max() <= 1e-9 * np.abs(b).max()


def test_a_schur_factor_is_never_shared(operators):
    from signorini.linalg import pardiso

    K1, _ = operators
    f = factorize(K1, "pardiso", schur_dofs=np.arange(6))
    f.release()
    assert pardiso.KEPT == []

"""linalg/spmv.py: products split over threads equal the plain product bit for bit."""

import numpy as np
import pytest
import scipy.sparse as sp

import signorini.linalg.spmv as spmv
from signorini.dynamics.simulate import simulate
from signorini.linalg.spmv import ThreadedCSR
from signorini.studies.benchmarks import get_benchmark


@pytest.fixture(scope="module")
def matrix():
    rng = np.random.default_rng(7)
    A = sp.random(120_000, 120_000, density=1e-4, format="csr", random_state=rng)
    keep = np.ones(A.shape[0])
    keep[5_000:6_000] = 0.0  # a band of empty rows
    A = (sp.diags(keep) @ A).tocsr()
    A.eliminate_zeros()
    return A


@pytest.mark.parametrize("threads", [1, 2, 3, 7])
def test_threaded_product_is_the_plain_product(matrix, threads):
    assert matrix.nnz >= spmv.MIN_NNZ
    T = ThreadedCSR(matrix, threads)
    assert T.threads == threads
    x = np.random.default_rng(1).standard_normal(matrix.shape[1])
    assert np.array_equal(T @ x, matrix @ x)
    # blocks cover the rows in order and hold about the same number of non-zeros
    assert [b[0] for b in T.blocks][0] == 0 and T.blocks[-1][1] == matrix.shape[0]
    assert all(T.blocks[k][1] == T.blocks[k + 1][0] for k in range(threads - 1))
    assert all(np.shares_memory(b[2].data, matrix.data) for b in T.blocks)  # views, no copy
    counts = [b[2].nnz for b in T.blocks]
    assert max(counts) - min(counts) <= 2 * np.diff(matrix.indptr).max()
    T.close()


def test_small_matrices_are_not_split():
    A = sp.identity(100, format="csr")
    assert ThreadedCSR(A, 4).threads == 1


def test_cg_path_with_split_products_is_bitwise_the_same(monkeypatch):
    """The whole CG run with products split over 3 threads equals the unsplit run exactly."""
    monkeypatch.setattr(spmv, "MIN_NNZ", 0)
    b = get_benchmark("bar3d")
    runs = [
        simulate(b.problem(3), "cn", b.h(3) / 2, 0.6, backend="cg", solver_options={"spmv_threads": t}) for t in (1, 3)
    ]
    assert runs[0].counters["contact_iterations"] > runs[0].steps  # the active set changed on the way
    for key in ("lam", "gap", "energy"):
        assert np.array_equal(getattr(runs[0], key), getattr(runs[1], key))

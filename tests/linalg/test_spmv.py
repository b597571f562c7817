"""linalg/spmv.py: products split over threads equal the plain product bit for bit; MKL's
product equals it to round-off and gives the same histories."""

import numpy as np
import pytest
import scipy.sparse as sp

import signorini.linalg.spmv as spmv
from signorini.dynamics.stepping.simulate import simulate
from signorini.errors import InputError
from signorini.linalg import solver_options
from signorini.linalg.mkl import has_mkl
from signorini.linalg.spmv import MKLProduct, ThreadedCSR, sparse_product
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
        simulate(b.problem(3), "cn", b.h(3) / 2, 0.6, backend="cg", solver_options={"spmv_threads": t, "spmv": "scipy"})
        for t in (1, 3)
    ]
    assert runs[0].counters["contact_iterations"] > runs[0].steps  # the active set changed on the way
    for key in ("lam", "gap", "energy"):
        assert np.array_equal(getattr(runs[0], key), getattr(runs[1], key))


needs_mkl = pytest.mark.skipif(not has_mkl(), reason="MKL's runtime (extra 'pardiso') not installed")


@needs_mkl
@pytest.mark.parametrize("threads", [0, 1, 2])
def test_mkl_product_equals_scipy_to_round_off(matrix, threads):
    P = MKLProduct(matrix, threads)
    Sym = MKLProduct(matrix + matrix.T, threads, symmetric=True)
    x = np.random.default_rng(2).standard_normal(matrix.shape[1])
    y = matrix @ x
    assert np.abs(P @ x - y).max() <= 1e-14 * np.abs(y).max()
    out = np.full(matrix.shape[0], np.nan)
    assert P.matvec(x, out=out) is out and np.abs(out - y).max() <= 1e-14 * np.abs(y).max()
    assert np.shares_memory(P._data, matrix.data)  # MKL reads the matrix's own arrays
    ys = (matrix + matrix.T) @ x
    assert np.abs(Sym @ x - ys).max() <= 1e-14 * np.abs(ys).max()
    assert Sym.A.nnz < 0.6 * (matrix + matrix.T).nnz  # the upper triangle only
    with pytest.raises(ValueError, match="shape"):
        P @ x[:-1]
    P.close()
    P.close()  # twice is harmless


@needs_mkl
def test_mkl_product_of_a_rectangular_integer_matrix():
    A = sp.csr_matrix(np.array([[1, 0, 2], [0, 0, 0], [0, 3, 0], [4, 0, 5]]))
    x = np.array([1.0, -2.0, 0.5])
    assert np.array_equal(MKLProduct(A) @ x, A @ x)
    with pytest.raises(ValueError, match="square"):
        MKLProduct(A, symmetric=True)


def test_auto_takes_mkl_for_large_matrices_when_present(matrix):
    small = sp.identity(10, format="csr")
    assert isinstance(sparse_product(small), ThreadedCSR)
    assert isinstance(sparse_product(matrix, "scipy"), ThreadedCSR)
    assert isinstance(sparse_product(matrix), MKLProduct if has_mkl() else ThreadedCSR)
    with pytest.raises(InputError, match="spmv"):
        sparse_product(matrix, "cuda")
    with pytest.raises(InputError, match="allowed: auto, scipy, mkl"):
        solver_options({"spmv": "cuda"})


def test_explicit_mkl_without_mkl_is_an_input_error(monkeypatch):
    monkeypatch.setattr(spmv, "mkl_runtime", lambda: None)
    with pytest.raises(InputError, match="extra 'pardiso'"):
        MKLProduct(sp.identity(3, format="csr"))


@needs_mkl
def test_cg_path_with_mkl_products_gives_the_same_histories(monkeypatch):
    """MKL's products sum in another order: the histories agree to the CG tolerance."""
    monkeypatch.setattr(spmv, "MIN_NNZ", 0)
    b = get_benchmark("bar3d")
    runs = {
        kind: simulate(b.problem(3), "cn", b.h(3) / 2, 0.6, backend="cg", solver_options={"spmv": kind})
        for kind in ("scipy", "mkl")
    }
    assert runs["mkl"].meta["solver_options"]["spmv"] == "mkl"
    assert runs["scipy"].counters["contact_iterations"] > runs["scipy"].steps
    for key in ("lam", "gap", "energy"):
        a, c = getattr(runs["scipy"], key), getattr(runs["mkl"], key)
        # measured 8.3e-12 relative; kept at 1e-9: CG (rtol 1e-12) iterates differ with the product's round-off
        assert np.abs(a - c).max() <= 1e-9 * np.abs(a).max()


@needs_mkl
@pytest.mark.parametrize("b", [2, 3])
def test_mkl_block_storage_of_a_symmetric_matrix(b):
    """Nodal blocks (BSR, upper triangle) give the product to round-off; a matrix whose
    blocks would be mostly explicit zeros keeps the CSR storage."""
    rng = np.random.default_rng(b)
    nodes = 400
    G = sp.random(nodes, nodes, density=0.02, random_state=rng, format="csr")
    G = (G + G.T + sp.identity(nodes)).tocsr()
    G.data[:] = 1.0
    A = sp.kron(G, np.ones((b, b)), format="csr")  # whole b x b blocks
    A.data = rng.standard_normal(A.nnz)
    A = (A + A.T).tocsr()
    x = rng.standard_normal(A.shape[0])
    P = MKLProduct(A, symmetric=True, block_size=b)
    assert P.storage == "bsr-upper"
    assert np.abs(P @ x - A @ x).max() <= 2e-14 * np.abs(A @ x).max()  # measured 4.8e-16 relative
    Q = MKLProduct(sp.diags(np.arange(1.0, 3 * b * 10 + 1)).tocsr(), symmetric=True, block_size=b)
    assert Q.storage == "csr-upper"  # diagonal: blocks b times fuller than the matrix
    y = np.ones(Q.shape[0])
    assert np.array_equal(Q @ y, np.arange(1.0, 3 * b * 10 + 1))
    assert MKLProduct(A, block_size=b).storage == "csr"  # blocks only for symmetric storage


def test_nodal_block_size():
    from signorini.contact.solver import _nodal_block_size

    assert _nodal_block_size(np.repeat(np.arange(5), 3), 15) == 3
    assert _nodal_block_size(np.repeat(np.arange(5), 2), 10) == 2
    assert _nodal_block_size(np.array([0, 0, 0, 1, 1, 2]), 6) == 1  # a node with fixed components
    assert _nodal_block_size(None, 6) == 1

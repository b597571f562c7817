"""linalg/sparse.py: the set-up operations give the matrices of the scipy expressions."""

import numpy as np
import pytest
import scipy.sparse as sp

from signorini.linalg.sparse import linear_combination, principal_blocks, subpattern_positions, upper_triangle


def symmetric(n, density, rng):
    A = sp.random(n, n, density=density, format="csr", random_state=rng)
    return (A + A.T).tocsr()


@pytest.mark.parametrize("seed", range(40))
def test_against_scipy_on_random_matrices(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 60))
    A, B = symmetric(n, rng.uniform(0, 0.5), rng), symmetric(n, 0.2, rng)
    assert (linear_combination(2.0, A, -3.0, B) != (2 * A - 3 * B)).nnz == 0
    same = linear_combination(2.0, A, -3.0, A)
    assert (same != (2 * A - 3 * A)).nnz == 0 and (A.nnz == 0 or np.shares_memory(same.indices, A.indices))
    fixed = np.sort(rng.choice(n, int(rng.integers(0, n + 1)), replace=False))
    free = np.setdiff1d(np.arange(n), fixed)
    Kff, KfD = principal_blocks(A, free, fixed)
    assert Kff.shape == (free.size, free.size) and KfD.shape == (free.size, fixed.size)
    assert (Kff != A[free][:, free]).nnz == 0 and (KfD != A[free][:, fixed]).nnz == 0
    assert Kff.has_sorted_indices
    U = upper_triangle(A)
    assert (U != sp.triu(A)).nnz == 0 and U.has_sorted_indices


@pytest.mark.parametrize("seed", range(20))
@pytest.mark.parametrize("chunk", [1, 7, 1 << 22])
def test_pattern_inside_the_other(seed, chunk):
    """A pattern inside B's (the vector mass in the stiffness pattern): the positions are
    B's entries of the same row and column, the sum keeps B's index arrays; a pattern
    with one entry outside gives None.  Small ``chunk`` values cut the rows in blocks."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 40))
    B = symmetric(n, rng.uniform(0.05, 0.6), rng) + sp.identity(n, format="csr")
    C = B.tocoo()
    keep = rng.random(C.nnz) < 0.5
    A = sp.csr_matrix((rng.standard_normal(int(keep.sum())), (C.row[keep], C.col[keep])), shape=B.shape)
    pos = subpattern_positions(A, B, chunk=chunk)
    rows = np.repeat(np.arange(n), np.diff(A.indptr))
    assert np.array_equal(B.indices[pos], A.indices)
    assert np.all((pos >= B.indptr[rows]) & (pos < B.indptr[rows + 1]))
    for K in (linear_combination(2.0, A, -3.0, B), linear_combination(-3.0, B, 2.0, A)):
        assert abs(K - (2 * A - 3 * B)).max() == 0 and np.shares_memory(K.indices, B.indices)
    missing = sp.csr_matrix(np.ones((n, n))) - sp.csr_matrix((np.ones(B.nnz), B.indices, B.indptr), shape=B.shape)
    if missing.nnz:
        outside = (A + abs(missing)).tocsr()
        assert subpattern_positions(outside, B, chunk=chunk) is None
        assert (linear_combination(1.0, outside, 1.0, B) != outside + B).nnz == 0


@pytest.mark.parametrize("d", [2, 3])
def test_vector_mass_in_the_stiffness_pattern(d):
    """m (x) I_d inside the full d x d blocks of the same node pattern: the positions come
    without a search (B's entry d k + (r mod d)) and equal the searched ones."""
    from signorini.linalg.sparse import _block_diagonal_positions

    rng = np.random.default_rng(d)
    m = symmetric(12, 0.3, rng) + sp.identity(12, format="csr")
    S = sp.kron(m, rng.random((d, d)), format="csr")
    M = sp.kron(m, sp.identity(d), format="csr")
    S.sort_indices()
    M.sort_indices()
    pos = _block_diagonal_positions(M, S)
    assert pos is not None and np.array_equal(pos, subpattern_positions(M, S, chunk=5))
    assert abs(linear_combination(2.0, M, -1.0, S) - (2 * M - S)).max() < 1e-14
    part = M.copy()
    part.data[::2] = 0.0
    part.eliminate_zeros()  # a smaller pattern: the guess fails, the search finds it
    assert _block_diagonal_positions(part, S) is None and subpattern_positions(part, S) is not None


def test_rows_without_entries_and_unsorted_input():
    A = sp.csr_matrix(np.array([[0, 0, 0, 0], [0, 2.0, 1.0, 0], [0, 1.0, 0, 0], [0, 0, 0, 0]]))
    assert (upper_triangle(A) != sp.triu(A)).nnz == 0
    U = sp.csr_matrix((np.array([1.0, 2.0]), np.array([1, 0]), np.array([0, 2, 2])), shape=(2, 2))  # unsorted
    assert (upper_triangle(U) != sp.triu(U)).nnz == 0
    assert (linear_combination(1.0, U, 1.0, sp.identity(2)) != U + sp.identity(2)).nnz == 0


@pytest.mark.parametrize(
    "free, fixed", [([3, 1, 2], [0]), ([0, 2, 4], [1, 3]), ([0, 1], [1, 2, 3, 4]), ([0, 1, 2, 3, 4], [])]
)
def test_principal_blocks_of_any_index_sets(free, fixed):
    """Unsorted or overlapping sets fall back to scipy's indexing: the same result."""
    A = symmetric(5, 0.6, np.random.default_rng(3))
    free, fixed = np.array(free, dtype=int), np.array(fixed, dtype=int)
    Kff, KfD = principal_blocks(A, free, fixed)
    assert (Kff != A[free][:, free]).nnz == 0 and (KfD != A[free][:, fixed]).nnz == 0


def test_errors():
    with pytest.raises(ValueError, match="shapes"):
        linear_combination(1.0, sp.identity(2), 1.0, sp.identity(3))
    with pytest.raises(ValueError, match="square"):
        upper_triangle(sp.csr_matrix((2, 3)))


def test_upper_block_triangle():
    from signorini.linalg.sparse import upper_block_triangle

    rng = np.random.default_rng(5)
    G = sp.random(30, 30, density=0.1, random_state=rng, format="csr")
    A = sp.kron(G + G.T + sp.identity(30), np.ones((3, 3)), format="csr")
    A.data = rng.standard_normal(A.nnz)
    A = (A + A.T).tocsr()
    U = upper_block_triangle(A, 3)
    assert U.blocksize == (3, 3)
    dense, blocks = A.toarray(), U.toarray()
    rows, cols = np.indices(dense.shape)
    keep = cols // 3 >= rows // 3
    assert np.array_equal(blocks[keep], dense[keep]) and not blocks[~keep].any()
    assert upper_block_triangle(A, 4) is None  # 90 is not a multiple of 4
    assert upper_block_triangle(sp.identity(9, format="csr"), 3) is None  # blocks 3x emptier


def _dense_upper_blocks(A, b):
    dense = A.toarray()
    rows, cols = np.indices(dense.shape)
    return np.where(cols // b >= rows // b, dense, 0.0)


def test_upper_block_triangle_of_whole_and_partial_blocks():
    """Whole blocks (the vector assembly's pattern) go through run gathers; patterns that
    are not made of whole blocks (an entry missing, rows of a block row listing other
    block columns) through the mask route: both give A's upper block triangle."""
    from signorini.linalg.sparse import _upper_of_whole_blocks, upper_block_triangle

    rng = np.random.default_rng(8)
    G = sp.random(20, 20, density=0.15, random_state=rng, format="csr")
    A = sp.kron(G + G.T + sp.identity(20), np.ones((2, 2)), format="csr")
    A.data = rng.standard_normal(A.nnz)
    A.sort_indices()
    whole = _upper_of_whole_blocks(A, 2)
    assert whole is not None and np.array_equal(whole.toarray(), _dense_upper_blocks(A, 2))
    partial = A.tolil()
    partial[0, 1] = 0.0
    partial = partial.tocsr()
    partial.eliminate_zeros()
    assert _upper_of_whole_blocks(partial, 2) is None
    assert np.array_equal(upper_block_triangle(partial, 2).toarray(), _dense_upper_blocks(partial, 2))
    # rows 0 and 1 of block row 0 list different block columns (1 and 2)
    P = sp.csr_matrix(np.kron(np.eye(3), np.ones((2, 2))))
    P = (P + sp.csr_matrix(([1.0] * 4, ([0, 0, 1, 1], [2, 3, 4, 5])), shape=(6, 6))).tocsr()
    assert _upper_of_whole_blocks(P, 2) is None
    assert np.array_equal(upper_block_triangle(P, 2, max_fill=2.0).toarray(), _dense_upper_blocks(P, 2))


@pytest.mark.parametrize("seed", range(10))
def test_principal_combination_is_the_blocks_of_the_combination(seed):
    """The free and coupling blocks of a A + b B, formed from the blocks of A and B (the
    vector mass inside the stiffness pattern, and random patterns), leave A and B as
    they were."""
    from signorini.linalg.sparse import principal_combination

    rng = np.random.default_rng(seed)
    m = symmetric(10, 0.3, rng) + sp.identity(10, format="csr")
    pairs = [
        (sp.kron(m, sp.identity(3), format="csr"), sp.kron(m, np.ones((3, 3)), format="csr")),
        (symmetric(30, 0.2, rng), symmetric(30, 0.3, rng)),
    ]
    for A, B in pairs:
        A.sort_indices()
        B.sort_indices()
        B.data = rng.standard_normal(B.nnz)
        A0, B0 = A.copy(), B.copy()
        fixed = np.sort(rng.choice(30, 6, replace=False))
        free = np.setdiff1d(np.arange(30), fixed)
        Kff, KfD = principal_combination(2.0, A, -0.5, B, free, fixed)
        K = (2.0 * A - 0.5 * B).tocsr()
        assert abs(Kff - K[free][:, free]).max() < 1e-14 and abs(KfD - K[free][:, fixed]).max() < 1e-14
        assert (A != A0).nnz == 0 and (B != B0).nnz == 0


@pytest.mark.parametrize("seed", range(6))
def test_principal_rows_are_the_blocks_rows(seed):
    """A rank's block of free rows of a A + b B (the distributed backends), split into its
    free and fixed columns, equals those rows of the whole blocks; A and B are unchanged
    and no fixed row is taken."""
    from signorini.linalg.sparse import principal_rows

    rng = np.random.default_rng(seed)
    m = symmetric(10, 0.3, rng) + sp.identity(10, format="csr")
    A, B = sp.kron(m, sp.identity(3), format="csr"), symmetric(30, 0.3, rng)
    A0, B0 = A.copy(), B.copy()
    fixed = np.sort(rng.choice(30, int(rng.integers(0, 8)), replace=False))
    free = np.setdiff1d(np.arange(30), fixed)
    lo, hi = np.sort(rng.integers(0, free.size + 1, 2))
    Kf, KD = principal_rows(1.5, A, 0.25, B, free, fixed, free[lo:hi])
    K = (1.5 * A + 0.25 * B).tocsr()
    assert Kf.shape == (hi - lo, free.size) and KD.shape == (hi - lo, fixed.size)
    np.testing.assert_allclose(Kf.toarray(), K[free[lo:hi]][:, free].toarray(), rtol=0, atol=1e-14)
    np.testing.assert_allclose(KD.toarray(), K[free[lo:hi]][:, fixed].toarray(), rtol=0, atol=1e-14)
    assert Kf.has_canonical_format and (A != A0).nnz == 0 and (B != B0).nnz == 0


def test_a_zero_coefficient_keeps_the_other_pattern_and_complex_coefficients_work():
    """A mass-only operator 1 M + 0 S keeps M's pattern (not S's zeros); complex
    coefficients give complex matrices."""
    m = sp.csr_matrix(np.array([[2.0, 1.0], [1.0, 2.0]]))
    M = sp.kron(m, sp.identity(3), format="csr")
    S = sp.kron(m, np.ones((3, 3)), format="csr")
    for K in (linear_combination(1.0, M, 0.0, S), linear_combination(0.0, S, 1.0, M)):
        assert K.nnz == M.nnz and abs(K - M).max() == 0
    C = linear_combination(1j, M, 1.0, S)
    assert C.dtype == np.complex128 and abs(C - (1j * M + S)).max() < 1e-15

"""Lazy Delassus columns: the same histories as the full condensation, fewer solves."""

import dataclasses

import numpy as np
import pytest
import scipy.sparse as sp

from backends import DIRECT
from signorini.contact.delassus import DelassusColumns
from signorini.contact.obstacles import SphereObstacle
from signorini.dynamics.model.problem import discretize
from signorini.dynamics.stepping.simulate import simulate
from signorini.linalg import factorize
from signorini.studies.benchmarks import get_benchmark

BACKENDS = DIRECT


def _curved(dim: int, n: int, R: float = 0.2):
    """The bar of `bar{dim}d` dropped on a ball (disc in 2D) of radius R touching the
    middle of its bottom face (width 0.1) first: a contact zone that grows from the centre."""
    b = get_benchmark(f"bar{dim}d")
    p = b.problem(n)
    centre = [0.05] * (dim - 1) + [-R]
    return dataclasses.replace(p, obstacle=SphereObstacle(centre, R), name="curved"), b.h(n) / 2


def _bar(name: str, n: int):
    b = get_benchmark(name)
    return b.problem(n), b.h(n) / 2


CASES = {
    "bar1d": lambda: _bar("bar1d", 20),
    "bar2d": lambda: _bar("bar2d", 2),
    "bar3d": lambda: _bar("bar3d", 2),
    "disc-on-bar2d": lambda: _curved(2, 4),
    "ball-on-bar3d": lambda: _curved(3, 2),
}


def _agree(a, c, what=("lam", "gap", "kinetic_energy", "elastic_energy")):
    for f in what:
        x, y = getattr(a, f), getattr(c, f)
        # measured 8.2e-13 relative (round-off of the two condensations, carried over the steps)
        assert np.abs(x - y).max() <= 5e-11 * max(np.abs(x).max(), 1e-300), f


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("case", sorted(CASES))
def test_lazy_equals_full_condensation(case, backend):
    problem, dt = CASES[case]()
    T = 80 * dt if case != "bar1d" else 2.0
    runs = {
        c: simulate(problem, "cn", dt, T, solver_options={"backend": backend, "condensation": c})
        for c in ("lazy", "full")
    }
    lazy, full = runs["lazy"], runs["full"]
    assert np.abs(full.lam).max() > 0  # there was contact
    _agree(lazy, full)
    nc = full.lam.shape[1]
    assert full.counters["delassus_columns"] == nc
    assert lazy.counters["delassus_columns"] <= nc


@pytest.mark.parametrize("scheme", ["moreau-jean", "penalty", "hht"])
def test_lazy_equals_full_with_index_sets_and_compliance(scheme):
    problem, dt = _curved(2, 4)
    opts = {"theta": 1.0} if scheme == "moreau-jean" else {}
    runs = [
        simulate(
            problem, scheme, dt, 80 * dt, scheme_options=opts, solver_options={"backend": "superlu", "condensation": c}
        )
        for c in ("lazy", "full")
    ]
    assert np.abs(runs[1].lam).max() > 0
    _agree(*runs)


def test_lazy_computes_only_the_columns_of_nodes_near_contact():
    """A ball touching the middle of the bottom face: until the contact zone has spread,
    only the nodes that came near contact have a column (no set-up solves at all)."""
    problem, dt = _curved(3, 8, R=0.05)  # narrower than the face: the corners never touch
    H = simulate(problem, "cn", dt, 0.45, solver_options={"backend": "superlu"})
    nc = H.lam.shape[1]  # 81
    touched = int((H.lam != 0).any(axis=0).sum())
    assert 0 < touched < nc
    # columns come in blocks of 64, topped up with the nodes nearest to contact
    assert touched <= H.counters["delassus_columns"] == 64 < nc


def test_columns_equal_the_dense_delassus_matrix_and_budget_drops_Z(rng):
    n, nc = 40, 7
    A = sp.random(n, n, density=0.2, random_state=1)
    K = sp.csr_matrix(A @ A.T + 5 * sp.eye(n))
    rows = rng.choice(n, nc, replace=False)
    B = sp.csr_matrix((np.ones(nc), (np.arange(nc), rows)), shape=(nc, n))
    W_dense = (B @ np.linalg.solve(K.toarray(), B.T.toarray())).astype(float)
    for budget, keeps in ((1e9, True), (0.0, False)):
        cols = DelassusColumns(factorize(K, "superlu"), B, budget)
        cols.ensure(np.array([3, 1]))
        cols.ensure(np.array([1, 5, 0, 2, 4, 6]))  # known columns are not recomputed
        assert cols.count == nc and cols.factor.solves == nc
        assert cols.keeps_Z is keeps
        P = np.array([6, 0, 3])
        assert np.allclose(cols.block(P), W_dense[np.ix_(P, P)], rtol=5e-13, atol=0)  # measured 8.4e-15
        assert np.allclose(cols.W(np.arange(nc), P), W_dense[:, P], rtol=5e-13, atol=0)
        if keeps:
            lam = rng.normal(size=P.size)
            Zp = np.linalg.solve(K.toarray(), B.T.toarray()[:, P])
            assert np.allclose(cols.Z_times(P, lam), Zp @ lam, rtol=0, atol=5e-15)  # measured 5.6e-17 (|Z lam| <= 0.26)


def test_a_block_is_topped_up_with_the_nearest_nodes():
    n, nc = 12, 5
    K = sp.csr_matrix(sp.eye(n) * 2.0)
    B = sp.csr_matrix((np.ones(nc), (np.arange(nc), np.arange(nc))), shape=(nc, n))
    cols = DelassusColumns(factorize(K, "superlu"), B, 1e9)
    cols.ensure(np.array([2]), fill=np.array([4, 2, 0, 1, 3]))
    assert cols.count == nc and cols.factor.solves == nc  # one block of right-hand sides
    assert np.allclose(cols.block(np.arange(nc)), 0.5 * np.eye(nc), rtol=0, atol=1e-15)  # measured 0


def test_Z_dropped_mid_run_when_the_budget_is_reached():
    """A budget for 100 Z columns: the first block (64) is stored, the second does not
    fit, so Z is dropped and contact steps make one more solve; same history."""
    from test_active_set_cg import plate

    p, dt = plate(12)  # 169 contact nodes
    free = discretize(p, "seed").free.size
    full = simulate(p, "cn", dt, 16 * dt, solver_options={"backend": "superlu", "condensation": "full"})
    lazy = simulate(p, "cn", dt, 16 * dt, solver_options={"backend": "superlu", "condense_budget": 8.0 * free * 100})
    assert lazy.counters["delassus_columns"] > 100
    assert lazy.counters["linear_solves"] > full.counters["linear_solves"]  # the extra solves without Z
    _agree(lazy, full)


def test_lazy_columns_are_not_counted_as_step_solves_or_step_time():
    problem, dt = _curved(3, 2)
    H = simulate(problem, "cn", dt, 80 * dt, solver_options={"backend": "superlu"})
    assert H.counters["linear_solves"] == H.steps  # one solve per CN step, Z kept
    assert H.counters["delassus_columns"] > 0
    m = H.meta
    assert m["in_loop_condensation_seconds"] > 0
    # an identity between the recorded times (not a bound on a time): measured 0
    assert (
        abs(m["step_seconds"] * H.steps + m["in_loop_condensation_seconds"] - m["loop_seconds"])
        <= 1e-14 * m["loop_seconds"]
    )

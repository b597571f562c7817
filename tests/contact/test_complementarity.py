import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from signorini.contact.complementarity import solve_lcp


def _check(W, q, res):
    r = q + W @ res.mu
    scale = max(np.abs(q).max(), 1e-300)
    assert res.mu.min() >= 0
    # round-off of a direct solve with cond(W) up to ~1e3 (hypothesis draws new W each run): measured
    # -6.2e-15 and 9.1e-14 (3.9e-15 relative) over 60 draws; bounds 1e-12 relative
    assert r.min() >= -1e-12 * scale
    assert np.max(np.abs(r * res.mu)) <= 1e-12 * scale * max(res.mu.max(), 1.0)


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 12), st.integers(0, 10_000))
def test_random_spd_lcp(n, seed):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, n))
    W = A @ A.T + 0.1 * np.eye(n)
    q = rng.normal(size=n)
    res = solve_lcp(W, q)
    _check(W, q, res)
    assert res.residual < 1e-12  # relative; measured 7.5e-15 max over 60 draws
    # warm start from the solution converges in one iteration
    again = solve_lcp(W, q, active=res.active)
    assert again.iterations == 1 and np.allclose(again.mu, res.mu, rtol=1e-12, atol=0)  # the same solve: measured 0


def test_fallback_when_budget_exhausted():
    rng = np.random.default_rng(3)
    A = rng.normal(size=(30, 30))
    W = A @ A.T + np.eye(30)
    q = rng.normal(size=30)
    res = solve_lcp(W, q, max_iter=1)
    assert res.fallback
    _check(W, q, res)

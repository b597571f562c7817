"""Every linear-algebra backend gives the default's solution; the automatic choice."""

import numpy as np
import pytest

from signorini.dynamics.simulate import simulate
from signorini.linalg import choose_backend, estimate_factor_bytes, has_pardiso, has_pyamg
from signorini.studies.benchmarks import get_benchmark

BACKENDS = [
    "superlu",
    pytest.param(
        "pardiso", marks=pytest.mark.skipif(not has_pardiso(), reason="pypardiso not installed (extra 'pardiso')")
    ),
    "cg",
]


@pytest.fixture(scope="module")
def reference():
    b = get_benchmark("bar3d")
    return simulate(b.problem(3), "cn", b.h(3) / 2, 1.0, mass="seed", backend="superlu")


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
    from signorini.dynamics.problem import discretize

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
    assert choose_backend(n, 3, budget=big) in ("superlu", "pardiso")
    b = get_benchmark("bar3d")
    H = simulate(b.problem(2), "cn", b.h(2) / 2, 0.5, mass="seed", memory_budget=1.0)
    assert H.meta["backend"].startswith("cg")


def test_unknown_backend_is_an_error():
    from signorini.errors import InputError

    b = get_benchmark("bar1d")
    with pytest.raises(InputError, match="unknown solver.backend 'mumps'"):
        simulate(b.problem(4), "cn", 0.1, 1.0, backend="mumps")

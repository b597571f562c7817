"""Anderson's mixing of Newton's iterates with a kept operator (``dynamics/solve/anderson.py``, issue 51 item 3)."""

from __future__ import annotations

import numpy as np

from signorini.contact.obstacles import PlaneObstacle
from signorini.dynamics.model.problem import Problem
from signorini.dynamics.solve.anderson import Anderson
from signorini.dynamics.stepping.simulate import simulate
from signorini.fem.material import NeoHookean
from signorini.fem.mesh import box


def linear_map(n: int = 40, spread: float = 0.8, seed: int = 2):
    """(J, A, b): an SPD J (n, n) and the operator A that approximates it, A^-1 J with eigenvalues in
    [1 - spread, 1 + spread] (a chord iteration contracting at ``spread``), and a right-hand side."""
    rng = np.random.default_rng(seed)
    Q = np.linalg.qr(rng.standard_normal((n, n)))[0]
    A = Q @ np.diag(rng.uniform(1.0, 10.0, n)) @ Q.T
    R = np.linalg.qr(rng.standard_normal((n, n)))[0]
    E = R @ np.diag(rng.uniform(-spread, spread, n)) @ R.T
    L = np.linalg.cholesky(A)
    return L @ (np.eye(n) + E) @ L.T, A, rng.standard_normal(n)


def iterations(J, A, b, accel: Anderson | None, tol: float = 1e-10, most: int = 500) -> int:
    """The chord iterations X <- X + d, d = A^-1 (b - J X), mixed by ``accel``, until |b - J X| <= tol |b|."""
    X, lam = np.zeros(b.size), np.zeros(0)
    for k in range(1, most + 1):
        d = np.linalg.solve(A, b - J @ X)
        mixed = None if accel is None else accel.mix(X, d, lam)
        X = X + (d if mixed is None else mixed[0])
        if np.linalg.norm(b - J @ X) <= tol * np.linalg.norm(b):
            return k
    return most + 1


def test_mixing_a_linear_chord_iteration_is_a_krylov_method():
    """On a linear map the mixing is GMRES preconditioned by A: with a history as deep as the space it ends in at
    most n + 1 iterations (finite termination), and with the default depth it takes a fraction of the plain
    chord iteration's (which contracts at 0.8 per iteration).  Measured: 25 and 33 iterations against 91."""
    J, A, b = linear_map()
    n = b.size
    free = np.arange(n)
    plain = iterations(J, A, b, None)
    deep = iterations(J, A, b, Anderson(free, depth=n))
    default = iterations(J, A, b, Anderson(free))
    assert deep <= n + 1
    assert default <= 0.5 * plain, (default, plain)
    assert plain > n  # the plain chord iteration does not terminate in n steps: the comparison means something


def test_a_change_of_the_active_set_starts_the_history_again():
    """The mixed iterate is an affine combination of iterates that hold the same rows at their bound: the history
    restarts where the set of pressing rows changes (no mix returned), and mixes again from the next iterate."""
    acc = Anderson(np.arange(3))
    X, d = np.zeros(3), np.ones(3)
    assert acc.mix(X, d, np.array([-1.0, 0.0])) is None  # the first point
    assert acc.mix(X + d, 0.5 * d, np.array([-2.0, 0.0])) is not None
    assert acc.mix(X + 1.5 * d, 0.2 * d, np.array([-2.0, -1.0])) is None  # a row started pressing
    out = acc.mix(X + 1.7 * d, 0.1 * d, np.array([-2.5, -1.2]))
    assert out is not None
    # one difference: dX = 0.2, dF = 0.1 - 0.2 per dof, so gamma = argmin |0.1 + 0.1 gamma| = -1: the step
    # d - gamma (dX + dF) = 0.2 per dof (the fixed point's linear extrapolation) and the multipliers mixed with the
    # same weight, lambda - gamma (lambda_k - lambda_k-1)
    step, lam = out
    assert np.allclose(step, 0.2, rtol=1e-14, atol=0.0)
    assert np.allclose(lam, [-3.0, -1.4], rtol=1e-14, atol=0.0)


def pressed_block() -> Problem:
    """A soft Neo-Hookean block 1 x 1 x 0.5 landing at 2 m/s on a plane it touches (strains of 10-20% at its
    contact face, which has no inertia with the default mass), sliding at 0.1 m/s."""
    return Problem(box(4, 4, 2, 1.0, 1.0, 0.5), NeoHookean.from_young(1e3, 0.3, 1.0), "zmin",
                   PlaneObstacle([0, 0, 0.0], [0, 0, 1.0]), v0=np.array([0.1, 0.0, -2.0]))  # fmt: skip


def test_the_mixed_iterates_converge_to_the_same_steps_in_fewer_iterations():
    """Crank–Nicolson through the block's impact, 20 steps: with the mixing (the default) the Newton iterations
    fall (measured: 153 -> 130) and every step's contact force and energy are the plain iterates' to the Newton
    tolerance (measured 7e-11 of the force); the energy identity closes as before."""
    runs = {
        acc: simulate(pressed_block(), "crank-nicolson", 0.005, 0.1, solver_options={"acceleration": acc})
        for acc in ("none", "anderson")
    }
    plain, mixed = runs["none"], runs["anderson"]
    assert plain.status == mixed.status == "finished"
    assert mixed.counters["accelerated_iterations"] > 0 and plain.counters["accelerated_iterations"] == 0
    assert mixed.nonlinear_iterations[1:].sum() <= 0.9 * plain.nonlinear_iterations[1:].sum()
    force = np.abs(plain.lambda_sum).max()
    assert force > 0.0
    assert np.abs(mixed.lambda_sum - plain.lambda_sum).max() <= 1e-8 * force
    assert np.abs(mixed.energy - plain.energy).max() <= 1e-8 * np.abs(plain.energy).max()
    assert mixed.summary()["energy_identity_residual"] <= 1e-9

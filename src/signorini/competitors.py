"""Competing time schemes of the literature, for head-to-head comparisons.

``paoli_schatzman(problem, dt, T, mass, restitution=0)``
    Paoli–Schatzman (SIAM J. Numer. Anal. 40, 2002) two-step scheme with exact contact:

        M (U^{n+1} - 2 U^n + U^{n-1}) + dt^2/4 S (U^{n+1} + 2 U^n + U^{n-1})
            = dt^2 F + dt^2 B^T lambda^n,
        0 >= B (U^{n+1} + e U^{n-1}) / (1 + e) - g  _|_  lambda^n <= 0,

    with restitution coefficient e in [0, 1] (e = 0 for the wave equation).  Divided by
    dt^2 it is ``(M/dt^2 + S/4) U^{n+1} = rhs + B^T lambda`` with the constraint
    ``B U^{n+1} <= (1 + e) g - e B U^{n-1}``: the same factor-once exact contact
    stepper as the one-step schemes, with a per-step gap.  U^1 comes from one
    Crank–Nicolson step.  The energy reported at t_{n+1} is the scheme's conserved
    quantity without contact, E^{n+1/2} = 1/2 |(U^{n+1} - U^n)/dt|_M^2
    + 1/2 |(U^{n+1} + U^n)/2|_S^2 - (U^{n+1} + U^n)/2 . F (+ the Dirichlet constant);
    ``predicted_increment`` is nan (no identity is claimed).
"""

from __future__ import annotations

import time

import numpy as np

from .contact.solver import make_stepper
from .dynamics.history import History, empty_series
from .dynamics.mass import massless_dofs
from .dynamics.problem import Discretization, Problem, discretize
from .dynamics.simulate import number_of_steps, run_meta, simulate
from .errors import InputError


def paoli_schatzman(
    problem: Problem | Discretization,
    dt: float,
    T: float,
    mass: str = "standard",
    restitution: float = 0.0,
    backend: str = "auto",
) -> History:
    """Integrate with the Paoli–Schatzman scheme (see the module docstring)."""
    if not 0.0 <= restitution <= 1.0:
        raise InputError(f"restitution must satisfy 0 <= e <= 1, got {restitution}")
    N = number_of_steps(dt, T)
    t0 = time.perf_counter()
    disc = problem if isinstance(problem, Discretization) else discretize(problem, mass)
    M, S, F, B = disc.M, disc.S, disc.F, disc.B
    g = disc.contact.gaps
    e = float(restitution)
    stepper = make_stepper((M / dt**2 + 0.25 * S).tocsr(), B, g, backend, disc.space.dim)
    # first step: one Crank-Nicolson step from the initial data
    first = simulate(disc, "crank-nicolson", dt, dt, snapshot_every=1)
    U_prev, U = disc.U0.copy(), first.snapshots["u"][1][disc.constraints.free]
    setup = time.perf_counter() - t0
    nc = disc.contact.size
    series = empty_series(N + 1, nc)
    gap, lam, kin, ela = series["gap"], series["lam"], series["kinetic_energy"], series["elastic_energy"]
    active, iters, residual = series["active"], series["iterations"], series["residual"]
    gap[:2], lam[:2] = first.gap, first.lam
    kin[:2], ela[:2] = first.kinetic_energy, first.elastic_energy
    active[:2], iters[:2], residual[:2] = first.active, first.iterations, first.residual
    off = disc.energy_offset

    def half_energy(Ua, Ub):
        D = (Ub - Ua) / dt
        Ubar = 0.5 * (Ua + Ub)
        return 0.5 * float(D @ (M @ D)), 0.5 * float(Ubar @ (S @ Ubar)) - float(Ubar @ F) + off

    t_loop = time.perf_counter()
    for n in range(1, N):
        rhs = M @ (2 * U - U_prev) / dt**2 - 0.25 * (S @ (2 * U + U_prev)) + F
        U_new, lam_n, info = stepper.solve(rhs, gaps=(1 + e) * g - e * (B @ U_prev))
        U_prev, U = U, U_new
        gap[n + 1] = g - B @ U
        lam[n + 1] = lam_n
        kin[n + 1], ela[n + 1] = half_energy(U_prev, U)
        active[n + 1] = int(np.count_nonzero(lam_n))
        iters[n + 1] = info.iterations
        residual[n + 1] = info.residual
    loop = time.perf_counter() - t_loop
    meta = run_meta(disc, stepper, f"paoli-schatzman(e={e})", dt, N, massless_dofs(M).size, setup, loop, N - 1)
    return History(
        t=np.arange(N + 1) * dt,
        **series,
        coordinates=disc.problem.mesh.points[disc.contact.nodes],
        weights=disc.contact.weights,
        meta=meta,
    )

"""The time loop: ``simulate(problem, scheme, dt, T, mass=...) -> History``."""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np
import scipy.sparse.linalg as spla

from ..contact.solver import make_stepper
from ..dynamics.history import History, empty_series
from ..dynamics.mass import massless_dofs
from ..dynamics.problem import Discretization, Problem, discretize
from ..dynamics.schemes import TimeScheme, get_scheme
from ..errors import InputError, check_positive


def number_of_steps(dt: float, T: float) -> int:
    """N = T/dt rounded to the nearest integer; T must be a multiple of dt to 1e-9."""
    dt = check_positive("dt", dt)
    T = check_positive("T", T)
    if T < dt * (1 - 1e-12):
        raise InputError(f"T must be >= dt, got T={T} < dt={dt}")
    n = round(T / dt)
    if abs(n * dt - T) > 1e-9 * T:
        n = math.ceil(T / dt - 1e-9)
    return int(n)


def initial_acceleration(disc: Discretization, massless: np.ndarray) -> np.ndarray:
    """A0 from equilibrium, M A0 = F - S U0 (lambda_0 = 0), with A0 = 0 on massless dofs.

    Solved by Jacobi-preconditioned CG on the massive block (a mass matrix has a
    mesh-independent condition number); skipped when F - S U0 vanishes to round-off
    (e.g. a rigidly translated body at rest).
    """
    n = disc.M.shape[0]
    A0 = np.zeros(n)
    SU0 = disc.S @ disc.U0
    r = disc.F - SU0
    keep = np.ones(n, dtype=bool)
    keep[massless] = False
    idx = np.flatnonzero(keep)
    smax = float(abs(disc.S).max()) if disc.S.nnz else 0.0
    scale = np.abs(disc.F).max(initial=0.0) + smax * np.abs(disc.U0).max(initial=0.0)
    if idx.size == 0 or np.abs(r[idx]).max(initial=0.0) <= 1e-13 * scale:
        return A0
    Mrr = disc.M[idx][:, idx].tocsr()
    d = Mrr.diagonal()
    pre = spla.LinearOperator(Mrr.shape, matvec=lambda x: x / d)
    sol, info = spla.cg(Mrr, r[idx], rtol=1e-14, atol=0.0, M=pre, maxiter=5000)
    if info != 0:  # fall back to a direct solve
        sol = spla.spsolve(Mrr.tocsc(), r[idx])
    A0[idx] = sol
    return A0


def run_meta(
    disc: Discretization,
    stepper,
    scheme: str,
    dt: float,
    N: int,
    n_massless: int,
    setup: float,
    loop: float,
    timed_steps: int,
) -> dict:
    """The inputs, sizes and timings of a run, as stored in ``History.meta`` / summary.json."""
    return {
        "problem": disc.problem.name,
        "scheme": scheme,
        "mass": disc.mass_name,
        "dt": dt,
        "T": N * dt,
        "dofs": int(disc.space.n_dofs),
        "free_dofs": int(disc.M.shape[0]),
        "contact_nodes": int(disc.contact.size),
        "massless_dofs": int(n_massless),
        "backend": stepper.name,
        "factor_bytes": int(stepper.factor_bytes),
        "setup_seconds": setup,
        "loop_seconds": loop,
        "step_seconds": loop / max(timed_steps, 1),
        **{f"{k}_seconds": v for k, v in {**disc.timings, **stepper.timings}.items()},
    }


def simulate(
    problem: Problem | Discretization,
    scheme: str | TimeScheme = "crank-nicolson",
    dt: float = 0.01,
    T: float = 1.0,
    mass: str = "seed",
    snapshot_every: int = 0,
    backend: str = "auto",
    memory_budget: float | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> History:
    """Integrate ``problem`` in time with exact nodal contact at every step.

    Parameters
    ----------
    problem : a :class:`Problem` or an already assembled :class:`Discretization`.
    scheme : ``crank-nicolson`` / ``cn``, ``backward-euler`` / ``be`` or a TimeScheme.
    dt, T : time step and final time [s]; N = T/dt steps (T must be >= dt).
    mass : mass variant (ignored when a Discretization is given).
    snapshot_every : store full displacement/velocity fields every k steps (0 = never).
    backend : ``auto`` (default: a direct factor if its estimated size fits in
        ``memory_budget`` bytes, else CG), ``superlu``, ``pardiso`` or ``cg``.
    memory_budget : bytes allowed for a factor (default 40% of the RAM).
    progress : callback(step, n_steps) called after every step.
    """
    sch = get_scheme(scheme)
    N = number_of_steps(dt, T)
    if not isinstance(snapshot_every, int) or snapshot_every < 0:
        raise InputError(f"snapshot_every must be a non-negative integer, got {snapshot_every!r}")
    t_setup = time.perf_counter()
    disc = problem if isinstance(problem, Discretization) else discretize(problem, mass)
    M, S, F, B = disc.M, disc.S, disc.F, disc.B
    a = sch.a(dt)
    stepper = make_stepper((a * M + S).tocsr(), B, disc.contact.gaps, backend, disc.space.dim, memory_budget)
    massless = massless_dofs(M)
    U = disc.U0.copy()
    V = disc.V0.copy()
    A = initial_acceleration(disc, massless)
    setup_seconds = time.perf_counter() - t_setup

    nc = disc.contact.size
    series = empty_series(N + 1, nc)
    gap, lam, kin, ela = series["gap"], series["lam"], series["kinetic_energy"], series["elastic_energy"]
    pred, active, iters = series["predicted_increment"], series["active"], series["iterations"]
    fallbacks, residual = series["fallbacks"], series["residual"]
    offset = disc.energy_offset

    MV, SU = M @ V, S @ U
    R0 = F - SU - M @ A  # equilibrium residual of the initial state (massless rows)

    def energies(U, V, MV, SU):
        return 0.5 * float(V @ MV), 0.5 * float(U @ SU) - float(U @ F) + offset

    gap[0] = disc.contact.gaps - B @ U
    kin[0], ela[0] = energies(U, V, MV, SU)
    snaps_t, snaps_u, snaps_v = [], [], []

    def snapshot(n, U, V):
        snaps_t.append(n * dt)
        snaps_u.append(disc.constraints.expand(U))
        snaps_v.append(disc.constraints.expand(V, fixed_values=0.0))

    if snapshot_every:
        snapshot(0, U, V)
    t_loop = time.perf_counter()
    for n in range(1, N + 1):
        rhs = M @ sch.predictor(U, V, A, dt) + F
        U_new, lam_new, info = stepper.solve(rhs)
        V_new, A_new = sch.update(U, V, A, U_new, dt)
        if massless.size:
            V_new[massless] = (U_new[massless] - U[massless]) / dt
            A_new[massless] = 0.0
        MV_new, SU_new = M @ V_new, S @ U_new
        dU = U_new - U
        R_old = R0 if n == 1 else None
        pred[n] = sch.energy_increment(dU, V_new - V, lam[n - 1], lam_new, B @ dU, MV_new - MV, SU_new - SU, R_old)
        U, V, A, MV, SU = U_new, V_new, A_new, MV_new, SU_new
        gap[n] = disc.contact.gaps - B @ U
        lam[n] = lam_new
        kin[n], ela[n] = energies(U, V, MV, SU)
        active[n] = int(np.count_nonzero(lam_new))
        iters[n] = info.iterations
        fallbacks[n] = info.fallback
        residual[n] = info.residual
        if snapshot_every and n % snapshot_every == 0:
            snapshot(n, U, V)
        if progress is not None:
            progress(n, N)
    loop_seconds = time.perf_counter() - t_loop

    meta = run_meta(disc, stepper, sch.name, dt, N, massless.size, setup_seconds, loop_seconds, N)
    snaps = {}
    if snapshot_every:
        snaps = {"t": np.array(snaps_t), "u": np.array(snaps_u), "v": np.array(snaps_v)}
    return History(
        t=np.arange(N + 1) * dt,
        **series,
        coordinates=disc.problem.mesh.points[disc.contact.nodes],
        weights=disc.contact.weights,
        snapshots=snaps,
        meta=meta,
    )

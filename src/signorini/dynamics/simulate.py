"""The time loop: ``simulate(problem, scheme, dt, T, mass=...) -> History``.

The only loop of the package.  :func:`simulate` is set-up + loop + result:
the options are validated (:func:`run_options`), :func:`set_up` discretizes, builds the
:class:`~.context.Context`, factorizes the scheme's operator (and its starter's, unless
proportional) and computes the initial state; :func:`make_observers` lists the
observers; :func:`advance` runs the loop, calling them; :func:`assemble_history` makes
the result.  Every exit
returns a :class:`~.history.History` with a status:

``finished``     the final time was reached;
``interrupted``  SIGINT (Ctrl-C) or SIGTERM arrived: the loop stops after the step in
                 progress (a second Ctrl-C aborts that step);
``failed``       a non-finite value appeared in the state, or a solver did not
                 converge; the message names the step and the time.

The levels computed before the stop are kept; observers are closed in every case.
"""

from __future__ import annotations

import math
import signal
import time
from collections.abc import Callable, Iterable, Mapping
from contextlib import contextmanager
from typing import Any

import numpy as np
import scipy.sparse.linalg as spla

from ..errors import ConvergenceError, InputError, check_positive
from ..fem.node_order import choose_order
from ..linalg import solver_options as validate_solver_options
from ..linalg.base import IMPORT_FAILURES, memory_info, total_memory
from ..linalg.row_block import RowBlock
from ..linalg.threads import blas_threads
from ..parallel import DISTRIBUTED_BACKENDS, peak_memory_bytes, run_comm
from ..signals import handled, interrupts_must_raise
from .bodies import body_summaries, region_summaries
from .context import Context
from .events import StopRun
from .history import COUNTER_KEYS, History
from .mass import DEFAULT_MASS, GRID_MASSES, MASS_VARIANTS
from .mass_effect import effect_warning
from .observers import EnergyRecorder, HistoryRecorder, Observer, ProgressCallback, Run, SnapshotRecorder
from .owned_rows import rank_cells
from .problem import Discretization, Problem, discretize, friction_summary, in_node_order
from .schemes import Scheme, State, friction_schemes, make_scheme
from .untagged import UntaggedContact

DT_RANGE = (1e-150, 1e150)
MAX_CONTACT_RESIDUAL = 1e-6  # scaled complementarity residual above which a step has failed
MAX_STEPS_EVER = 1e15


def number_of_steps(dt: float, T: float) -> int:
    """N = T/dt; T must be an integer multiple of dt to a relative 1e-9.

    Otherwise an :class:`InputError` names both and the two nearest valid time steps
    T/floor(T/dt) and T/ceil(T/dt) (a run never silently ends after T).
    """
    for name, v in (("dt", dt), ("T", T)):
        if isinstance(v, np.floating) and np.finfo(v).bits < 64:  # its decimal form is not its value
            short = np.format_float_positional(v)
            raise InputError(f"{name} must be a double (a Python float or numpy.float64), got {type(v).__name__} "
                             f"{short}, which is {float(v)!r} in double; pass the intended value, "
                             f"e.g. {short}")  # fmt: skip
    dt = check_positive("dt", dt)
    T = check_positive("T", T)
    if not DT_RANGE[0] <= dt <= DT_RANGE[1]:
        raise InputError(
            f"dt must be between {DT_RANGE[0]:g} and {DT_RANGE[1]:g} (dt^2 must be a normal double), got {dt:g}"
        )
    if T < dt * (1 - 1e-9):
        raise InputError(f"T must be >= dt, got T={T:g} < dt={dt:g}")
    ratio = T / dt
    if not ratio <= MAX_STEPS_EVER:
        raise InputError(f"T/dt = {ratio:.3g} steps is more than any run can take ({MAX_STEPS_EVER:.0e})")
    n = round(ratio)
    if abs(n * dt - T) > 1e-9 * T:
        lo, hi = math.floor(ratio), math.ceil(ratio)
        raise InputError(
            f"T = {T:g} is not an integer multiple of dt = {dt:g} (T/dt = {ratio:.6g}); "
            f"nearest valid dt: {T / hi:.10g} ({hi} steps) or {T / lo:.10g} ({lo} steps)"
        )
    return int(n)


def check_history_fits(steps: int) -> None:
    """InputError before any set-up when the per-level series alone cannot fit in memory.

    The command line refuses large runs with its estimate (``--max-steps``); this guard
    is for the Python API: ``dt = 1e-12, T = 1`` must not fail with a MemoryError after
    the set-up.  Lower bound: the 11 scalar series of a History, 8 bytes per level.
    """
    need = 8.0 * (steps + 1) * 11
    have = total_memory()
    if need > have:
        raise InputError(
            f"T/dt = {steps:,} steps: the history alone needs {need / 2**30:.3g} GiB, more than this machine's "
            f"{have / 2**30:.3g} GiB; increase dt or shorten T"
        )


def initial_state(ctx: Context) -> State:
    """Level 0: U0, V0 and A0 from equilibrium, M A0 = F(0) - S U0 (lambda_0 = 0).

    On Dirichlet dofs V and A are the prescribed motion's rates at t = 0; A0 = 0 on
    massless dofs.  The free block is solved by Jacobi-preconditioned CG on the massive
    dofs (a mass matrix has a mesh-independent condition number), skipped when the
    residual vanishes to round-off.  ``extra['R0']`` keeps the residual of the
    massless free dofs, which start out of equilibrium when F - S U0 is not zero there.
    """
    disc = ctx.disc
    U, V = disc.U0.copy(), disc.V0.copy()
    n = U.size
    A = np.zeros(n)
    if ctx.has_fixed:
        vD, aD = disc.dirichlet_rates(ctx.dt / 4)
        V[ctx.fixed], A[ctx.fixed] = vD, aD
    F = ctx.load(0.0)
    r = F - ctx.S @ U - ctx.M @ A
    keep = np.ones(n, dtype=bool)
    keep[ctx.massless] = False
    keep[ctx.fixed] = False
    idx = np.flatnonzero(keep)
    by_rows = isinstance(ctx.S, RowBlock)  # a distributed backend: S and M by rows
    if by_rows:
        smax = ctx.S.abs_max()
    else:
        smax = float(max(ctx.S.data.max(), -ctx.S.data.min())) if ctx.S.nnz else 0.0  # |S|_max, no copy of S
    scale = np.abs(F).max(initial=0.0) + smax * np.abs(U).max(initial=0.0)
    zero = disc.problem.initial_acceleration == "zero"
    if zero:  # A0 = 0 as given (GetFEM's start): the imbalance of the free dofs is R0 below
        ctx.initial_acceleration = "zero (initial_acceleration = 'zero')"
    elif idx.size and np.abs(r[idx]).max(initial=0.0) > 1e-13 * scale:
        Mrr = ctx.M.principal(idx) if by_rows else ctx.M[idx][:, idx].tocsr()
        d = Mrr.diagonal()
        pre = spla.LinearOperator(Mrr.shape, matvec=lambda x: x / d)
        op = spla.LinearOperator(Mrr.shape, matvec=lambda x: Mrr @ x) if by_rows else Mrr
        if ctx.rotated_kernel:  # singular: the least-squares solution of least norm
            sol = spla.minres(op, r[idx], rtol=1e-14, maxiter=20000)[0]
            ctx.initial_acceleration = "minres (massless normal directions)"
        else:
            sol, info = spla.cg(op, r[idx], rtol=1e-14, atol=0.0, M=pre, maxiter=5000)
            ctx.initial_acceleration = "cg"
            if info != 0:  # fall back to a direct solve (reported in summary.json: initial_acceleration)
                sol = spla.spsolve((Mrr.whole() if by_rows else Mrr).tocsc(), r[idx])
                ctx.initial_acceleration = "spsolve (cg did not converge)"
        A[idx] = sol
    lam_t = np.zeros((disc.contact.size, ctx.components - 1)) if ctx.components > 1 else None
    state = State(0.0, U, V, A, np.zeros(disc.contact.size), lam_t=lam_t)
    R0 = np.zeros(n)
    ml = np.setdiff1d(ctx.massless, ctx.fixed)
    R0[ml] = -r[ml]
    if ctx.rotated_kernel and idx.size:  # out of equilibrium along the massless normals
        R0[idx] = ctx.M[idx] @ A - r[idx]
    if zero:
        R0[idx] = -r[idx]
    if np.any(R0 != 0.0):
        state.extra["R0"] = R0
    return state


class _Interrupts:
    """SIGINT/SIGTERM set a flag (the loop stops after the step); a second SIGINT raises."""

    def __init__(self) -> None:
        self.signal_name: str | None = None
        self.signum = 0
        #: a second SIGINT aborts the step in progress; never on several ranks, where one rank
        #: leaving a collective solve would leave the others waiting in it
        self.abort_on_second = True
        #: a step is in progress (only a step can be aborted: between steps, in the observers
        #: and while the history is assembled a second SIGINT must not lose the levels computed)
        self.in_step = False

    def handler(self, signum, frame) -> None:
        if self.signal_name is not None and signum == signal.SIGINT and self.abort_on_second and self.in_step:
            raise KeyboardInterrupt
        self.signal_name = signal.Signals(signum).name
        self.signum = int(signum)

    def agree(self, comm) -> None:
        """On several ranks: every rank stops when a signal reached any of them (one
        reduction per step), with the name of the highest signal number received."""
        if comm.size == 1:
            return
        signum = comm.max(self.signum)
        if signum and not self.signum:
            self.signum, self.signal_name = signum, signal.Signals(signum).name


@contextmanager
def _catch_signals(enabled: bool):
    flag = _Interrupts()
    with handled(flag.handler, enabled):
        yield flag


#: an extrapolation weight |w|_1 above this is reported (<= 12 on every part we measured)
MAX_QUIET_WEIGHT = 20.0


def run_warnings(disc: Discretization) -> list[str]:
    """Warnings about what the run computes: a mass variant that changes the body's inertia."""
    out = []
    text = effect_warning(disc.mass_effect) if disc.mass_effect else None
    if text:
        out.append(f"mass {disc.mass_name!r} {text}: the run does not simulate the body's own inertia")
    w = disc.mass_effect.get("max_extrapolation_weight", 0.0) if disc.mass_effect else 0.0
    if w > MAX_QUIET_WEIGHT:
        out.append(
            f"mass {disc.mass_name!r}: a contact node is extrapolated with weights of |w|_1 = {w:.3g} "
            f"(> {MAX_QUIET_WEIGHT:g}): the redistributed mass may add spurious low-frequency modes; refine the mesh "
            "next to the contact boundary"
        )
    return out


def run_meta(disc: Discretization, ctx: Context, scheme: Scheme, dt: float, N: int, timings: dict) -> dict:
    """The inputs, sizes and timings of a run, as stored in ``History.meta`` / summary.json."""
    main = ctx.solvers[0]
    return {
        "problem": disc.problem.name,
        "scheme": scheme.label,
        "scheme_options": dict(scheme.options),
        "energy_definition": scheme.energy_definition,
        "energy_parts": "energy = kinetic_energy + elastic_energy + load_potential (history.csv)",
        "mass": disc.mass_name,
        "mass_effect": dict(disc.mass_effect),
        "friction": friction_summary(disc.problem),
        "warnings": run_warnings(disc),
        "dt": dt,
        "T": N * dt,
        "dim": int(disc.space.dim),
        "dofs": int(disc.space.n_dofs),
        "free_dofs": int(disc.free.size),
        "contact_nodes": int(disc.contact.size),
        "massless_dofs": int(ctx.massless.size),
        "backend": main.name,
        # how the Delassus matrix was obtained: schur, lazy or full (direct backends), none (cg)
        "condensation": getattr(main, "condensation", "none"),
        # optional modules installed but failing to import (a backend auto could not take), with why
        "optional_import_failures": dict(IMPORT_FAILURES),
        "solver_options": dict(ctx.solver_options),
        "total_memory_bytes": memory_info()[0],
        "total_memory_source": memory_info()[1],
        "initial_acceleration": getattr(ctx, "initial_acceleration", "none"),
        "conventions": {
            "follow_mass": bool(disc.problem.follow_mass),
            "body_force": _body_force_convention(disc),
            "gravity": "M_used g (follows the mass variant)"
            if disc.problem.follow_mass
            else "consistent int rho g phi (whatever the mass)",
            "initial_acceleration": disc.problem.initial_acceleration,
        },
        "factor_bytes": int(sum(s.factor_bytes for s in ctx.solvers)),
        **timings,
        **rank_contact_dofs(main),
        **(distributed_meta(disc) if isinstance(disc.S, RowBlock) else {}),
        **{f"{k}_seconds": v for k, v in {**disc.timings, **main.timings}.items()},
    }


def distributed_meta(disc: Discretization) -> dict:
    """``node_order`` (the numbers split over the ranks: ``mesh`` or ``morton``) and
    ``rank_cells`` of a run whose S is assembled by rows on each rank."""
    mesh = disc.space.mesh
    return {
        "node_order": "mesh" if mesh.node_ids is None else "morton",
        "rank_cells": rank_cells(mesh, disc.S.comm.size),
    }


def rank_contact_dofs(solver) -> dict:
    """``rank_contact_dofs``: per rank, the contact dofs among its rows of the distributed
    factor or operator (backends ``petsc``, ``petsc-cg``); nothing for a serial backend."""
    bounds = getattr(solver, "bounds", getattr(getattr(solver, "factor", None), "bounds", None))
    if bounds is None:
        return {}
    cols = np.unique(solver.B.indices)
    return {"rank_contact_dofs": np.histogram(cols, bounds)[0].astype(int).tolist()}


def run_options(
    snapshot_every: int, backend: str | None, memory_budget: float | None, solver_options: Mapping[str, Any] | None
) -> dict[str, Any]:
    """The validated solver options, with the ``backend``/``memory_budget`` shortcuts."""
    if not isinstance(snapshot_every, int) or isinstance(snapshot_every, bool) or snapshot_every < 0:
        raise InputError(f"snapshot_every must be a non-negative integer, got {snapshot_every!r}")
    opts = dict(solver_options or {})
    if backend is not None:
        opts["backend"] = backend
    if memory_budget is not None:
        opts["memory_budget"] = memory_budget
    return validate_solver_options(opts)


def prepare_context(disc: Discretization, dt: float, opts: dict, schemes: Iterable[Scheme | None]) -> Context:
    """The run's Context with the operators of ``schemes`` factorized (each scheme's
    ``check_context`` called before and after, so a refusal comes before any output)."""
    ctx = Context(disc, dt, opts)
    schemes = [s for s in schemes if s is not None]
    ctx.iterative_ok = ctx.iterative_ok and not any(s.needs_condensed_solve for s in schemes)
    if ctx.friction.frictional:
        for s in schemes:
            if s.friction_refusal:
                raise InputError(
                    f"scheme {s.name} cannot carry friction ({ctx.friction.label}): {s.friction_refusal}; "
                    f"schemes that do: {', '.join(friction_schemes())}"
                )
    for s in schemes:
        s.check_context(ctx)
    for s in schemes:
        op = s.operator(dt)
        if op is not None:
            ctx.prepare(op)
            s.check_context(ctx, prepared=True)
    ctx.Mop, ctx.Sop  # noqa: B018 - built now (set-up), after the factors: a lower peak of memory
    return ctx


def set_up(
    problem: Problem | Discretization, mass: str, scheme: Scheme, dt: float, T: float, opts: dict
) -> tuple[Run, Scheme | None]:
    """Everything before the loop that costs time: discretization, factorization and
    level 0 (``opts`` from :func:`run_options`).  Returns the run and the starter of a
    two-step scheme (None for one-step schemes)."""
    starter = make_scheme(scheme.starter) if scheme.starter else None
    N = number_of_steps(dt, T)
    check_history_fits(N)
    # a distributed backend: S and M by rows, each rank its own (docs/parallel.md)
    comm = run_comm(opts["backend"]) if opts.get("backend") in DISTRIBUTED_BACKENDS else None
    if comm is not None and not isinstance(problem, Discretization):  # rows of nearby nodes per rank
        order = choose_order(opts.get("node_order", "auto"), problem.mesh)
        if order != "mesh" and problem.mesh.grid is not None and MASS_VARIANTS.resolve(mass) in GRID_MASSES:
            raise InputError(
                f"mass {MASS_VARIANTS.resolve(mass)!r} reads the generated grid's node numbering: it cannot run with "
                f"solver option node_order={order!r}; use node_order=mesh or auto"
            )
        problem = in_node_order(problem, order)
    disc = problem if isinstance(problem, Discretization) else discretize(problem, mass, comm)
    ctx = prepare_context(disc, dt, opts, (scheme, starter))
    return Run(ctx, scheme, N, float(dt), initial_state(ctx), disc.problem), starter


def make_observers(
    snapshot_every: int, energy: bool, progress: Callable[[int, int], None] | None, extra: Iterable[Observer]
) -> tuple[HistoryRecorder, EnergyRecorder | None, SnapshotRecorder | None, list[Observer]]:
    """The recorders of the history, the energies and the snapshots, then ``extra``."""
    recorder, energies = HistoryRecorder(), EnergyRecorder() if energy else None
    snaps = SnapshotRecorder(snapshot_every) if snapshot_every else None
    obs: list[Observer] = [recorder] + [o for o in (energies, snaps) if o is not None] + list(extra)
    if progress is not None:
        obs.append(ProgressCallback(progress))
    return recorder, energies, snaps, obs


def simulate(
    problem: Problem | Discretization,
    scheme: str | type[Scheme] | Scheme = "crank-nicolson",
    dt: float = 0.01,
    T: float = 1.0,
    mass: str = DEFAULT_MASS,
    snapshot_every: int = 0,
    backend: str | None = None,
    memory_budget: float | None = None,
    progress: Callable[[int, int], None] | None = None,
    *,
    scheme_options: Mapping[str, Any] | None = None,
    solver_options: Mapping[str, Any] | None = None,
    observers: Iterable[Observer] = (),
    energy: bool = True,
    handle_signals: bool = True,
    events: Iterable[Any] = (),
) -> History:
    """Integrate ``problem`` in time with exact nodal contact at every step.

    Parameters
    ----------
    problem : a :class:`Problem` or an already assembled :class:`Discretization`.
    scheme : a name or alias of :data:`~signorini.dynamics.schemes.SCHEMES`
        (``crank-nicolson``/``cn``, ``backward-euler``/``be``, ``newmark``, ``theta``,
        ``paoli-schatzman``/``ps``), a :class:`Scheme` subclass, or an instance.
    dt, T : time step and final time [s]; N = T/dt steps (T must be >= dt).
    mass : mass variant (ignored when a Discretization is given).
    snapshot_every : keep full displacement/velocity fields in memory every k steps
        and at the last level (0 = never); for large runs stream them with
        :class:`signorini.io.output.FieldWriter` instead.
    backend, memory_budget : shortcuts for ``solver_options['backend']`` and
        ``solver_options['memory_budget']`` [bytes].
    progress : callback(step, n_steps) called after every step.
    scheme_options : the scheme's parameters, e.g. ``{"beta": 0.3, "gamma": 0.6}``.
    solver_options : backend, preconditioner, rtol, max_iter, max_newton, memory_budget,
        lcp_max_iter, condense_budget (see :data:`signorini.linalg.SOLVER_OPTIONS`).
    observers : extra :class:`~.observers.Observer` objects (e.g. a field writer).
    energy : record the scheme's energy and its identity (a few products per step).
    handle_signals : turn SIGINT/SIGTERM into ``status = "interrupted"``.
    events : :class:`~.events.Event` s (a function g(t, state), ``terminal``, ``direction``) or
        names of built-in events (``"separation"``, ``"first-contact"``, ``"rest:0.01"``: each
        terminal) watched after every level (:mod:`~.events`); a terminal one ends the run
        after its level, status ``finished``; ``meta['events']`` lists every event met.

    Returns
    -------
    History with ``status``, ``message``, ``counters`` and the levels computed.
    """
    if not isinstance(problem, (Problem, Discretization)):
        raise InputError(f"simulate's problem must be a signorini Problem or Discretization, got "
                         f"{type(problem).__name__}")  # fmt: skip
    number_of_steps(dt, T)  # dt and T first: a one-line error before anything is built
    sch = make_scheme(scheme, scheme_options)
    opts = run_options(snapshot_every, backend, memory_budget, solver_options)
    t0 = time.perf_counter()
    run, starter = set_up(problem, mass, sch, dt, T, opts)
    setup_seconds = time.perf_counter() - t0
    recorder, energies, snaps, obs = make_observers(snapshot_every, energy, progress, observers)
    untagged = UntaggedContact(run.ctx.solver_options.get("untagged_contact", "warn"))
    obs.insert(1, untagged)
    watch = None
    events = list(events)
    if events:
        from .events import EventWatch, parse_stop_at

        parse_stop_at([e for e in events if isinstance(e, str)], "events")  # names checked before the loop
        watch = EventWatch(events)
        obs.append(watch)  # last: the level is recorded before a terminal event ends the run
    with _catch_signals(handle_signals) as interrupts:
        interrupts.abort_on_second = run.ctx.comm.size == 1
        t_loop = time.perf_counter()
        status, message, n_last = advance(run, starter, obs, interrupts)
        loop = time.perf_counter() - t_loop
        H = _finish(run, n_last, recorder, energies, snaps, setup_seconds, loop)
        if watch is not None:
            H.meta["events"] = watch.met
            H.meta["stop_at"] = [e.name for e in getattr(watch, "events", []) if e.terminal]
        H.untagged_penetration = untagged.series
        H.meta["untagged_boundary_nodes"] = int(untagged.nodes.size)
        H.meta["untagged_worst_penetration"] = untagged.worst[0]  # the failing level of untagged_contact=fail too
        if untagged.exceeded():
            H.meta["warnings"].append(untagged.message())
        interrupts.agree(run.ctx.comm)
        if interrupts.signal_name and status == "finished":  # after the last step: every step kept
            status, message = "interrupted", f"{interrupts.signal_name} after the time loop (all {n_last} steps kept)"
    H.status, H.message = status, message
    if status == "interrupted" and interrupts_must_raise():  # a study of many runs: not a truncated one
        raise KeyboardInterrupt(message)
    return H


def _finish(run: Run, n_last: int, recorder, energies, snaps, setup_seconds: float, loop: float) -> History:
    # contact columns computed inside the loop (lazy condensation) are set-up work: reported
    # apart (in_loop_condensation_seconds), not in the time per step
    columns = sum(s.timings.get("condensation_in_loop", 0.0) for s in run.ctx.solvers)
    if run.ctx.comm.size == 1:
        for s in run.ctx.solvers:
            s.remeasure_bare()
    timings = {
        "setup_seconds": setup_seconds,
        "loop_seconds": loop,
        "step_seconds": (loop - columns) / max(n_last, 1),
        "in_loop_condensation_seconds": columns,
    }
    H = assemble_history(run, n_last, recorder, energies, snaps, timings)
    disc = run.ctx.disc
    last = getattr(recorder, "last", None)
    H.meta["regions"] = region_summaries(disc.space.mesh, disc.problem.material, disc.problem.materials)
    H.meta["bodies"] = body_summaries(disc.space.mesh, disc.M, disc.material.rho,
                                      None if last is None else last.V)  # fmt: skip
    bodies = H.meta["bodies"]
    if len(bodies) > 1:  # what the variant does to each body (the whole's figures can hide it)
        for k, b in enumerate(bodies):
            text = effect_warning(b["mass_effect"]) if b.get("mass_effect") else None
            if text:
                regions = f" (regions {', '.join(b['regions'])})" if b["regions"] else ""
                H.meta["warnings"].append(f"mass {disc.mass_name!r} on body {k}{regions} {text}")
    if disc.contact.pair_info is not None:  # per pair: tags, rows, inactive slave nodes, contact law
        H.meta["pairs"] = [dict(p) for p in disc.contact.pair_info]
    if disc.contact.obstacle_info and disc.contact.obstacle_info["nodes_beyond_edge"]:
        H.meta["obstacle"] = dict(disc.contact.obstacle_info)  # a surface obstacle: tagged nodes that face nothing
    H.to_user_order(run.ctx.disc.space.mesh, run.ctx.disc.contact.nodes)  # a renumbered mesh's results
    H.meta.update(rank_figures(run.ctx.comm, timings))
    return H


def _body_force_convention(disc) -> str:
    """How ``body_force`` is applied (summary.json ``conventions``)."""
    if not disc.problem.follow_mass:
        return "consistent int f phi (whatever the mass)"
    if disc.material is not None and np.ndim(disc.material.rho):
        return ("regions of different densities: f is a force density applied as it is (T^T int f phi for the "
                "extrapolated variants), not M_used f / rho; give an acceleration as [loads] gravity")  # fmt: skip
    return "M_used f / rho (follows the mass variant)"


def rank_figures(comm, timings: dict) -> dict:
    """``ranks`` and, per rank in rank order, the set-up and step times [s] and the peak
    resident memory [bytes] (``getrusage``: the process's own peak, whatever its cgroup)."""
    mine = (timings["setup_seconds"], timings["step_seconds"], peak_memory_bytes())
    every = comm.gather(mine)
    return {
        "ranks": comm.size,
        "rank_setup_seconds": [float(v[0]) for v in every],
        "rank_step_seconds": [float(v[1]) for v in every],
        "rank_peak_memory_bytes": [int(v[2]) for v in every],
        "rank_peak_memory_source": "getrusage(RUSAGE_SELF).ru_maxrss of each rank's process",
    }


def _one_step(run: Run, starter: Scheme | None, state: State, n: int) -> State:
    if n == 1 and starter is not None:
        return run.scheme.start(run.ctx, state, starter.step(run.ctx, state))
    return run.scheme.step(run.ctx, state)


def advance(
    run: Run, starter: Scheme | None, observers: list[Observer], interrupts: _Interrupts
) -> tuple[str, str, int]:
    """The time loop: (status, message, last level reached); observers closed on any exit.

    ``interrupts`` is the flag set by SIGINT/SIGTERM (:func:`_catch_signals`): the loop
    stops after the step in progress.
    """
    status, message, n_last = "finished", "", 0
    state, N, dt = run.initial, run.n_steps, run.dt
    started = []
    try:
        for o in observers:
            o.start(run)
            started.append(o)
        threads = run.ctx.solver_options.get("loop_blas_threads", 1)
        with blas_threads(threads):
            for n in range(1, N + 1):
                interrupts.agree(run.ctx.comm)
                if interrupts.signal_name:
                    status, message = "interrupted", f"{interrupts.signal_name} after step {n - 1} of {N}"
                    break
                try:
                    interrupts.in_step = True
                    new = _one_step(run, starter, state, n)
                except (ConvergenceError, InputError, np.linalg.LinAlgError, FloatingPointError) as exc:
                    status, message = "failed", f"step {n} (t = {n * dt:.6g}): {exc}"
                    break
                except KeyboardInterrupt:
                    status, message = "interrupted", f"SIGINT during step {n} of {N}"
                    break
                finally:
                    interrupts.in_step = False
                if not new.is_finite():
                    status, message = "failed", f"step {n} (t = {n * dt:.6g}): non-finite value in the state"
                    break
                if new.info is not None and not new.info.residual <= MAX_CONTACT_RESIDUAL:
                    status = "failed"
                    message = (
                        f"step {n} (t = {n * dt:.6g}): the contact solve did not reach complementarity "
                        f"(residual {new.info.residual:.3g} > {MAX_CONTACT_RESIDUAL:g})"
                    )
                    break
                try:
                    for o in observers:
                        o.record(run, n, new)
                except ConvergenceError as exc:  # e.g. an energy that overflows
                    status, message = "failed", f"step {n} (t = {n * dt:.6g}): {exc}"
                    break
                except StopRun as exc:  # a terminal event after this level (the last observer): it is kept
                    state, n_last = new, n
                    status, message = "finished", str(exc)
                    break
                state, n_last = new, n
                run.ctx.slide(new.U, new.t)  # contact pairs: slave nodes that left their master facet re-paired
    finally:
        for o in started:
            o.close(run, status, n_last, state)
    return status, message, n_last


def assemble_history(run: Run, n_last: int, recorder, energies, snaps, timings: dict) -> History:
    """The :class:`History` of the levels 0..n_last from the observers' series."""
    ctx, disc = run.ctx, run.ctx.disc
    series = dict(recorder.series)
    work = {}
    if energies is not None:
        E = energies.series
        series.update(kinetic_energy=E["kinetic_energy"], elastic_energy=E["elastic_energy"])
        series["load_potential"] = E["load_potential"]
        series["predicted_increment"] = E["predicted_increment"]
        work = {"external_work": E["external"], "contact_work": E["contact"], "numerical_dissipation": E["numerical"]}
        work["friction_work"] = E["friction"]  # zeros without friction
    else:
        nan = np.full(n_last + 1, np.nan)
        series.update(kinetic_energy=nan, elastic_energy=nan.copy(), predicted_increment=nan.copy())
        series["load_potential"] = nan.copy()
    return History(
        t=np.arange(n_last + 1) * run.dt,
        **series,
        **work,
        coordinates=disc.problem.mesh.points[disc.contact.nodes],
        weights=disc.contact.weights,
        nodes=np.asarray(disc.contact.nodes, dtype=np.int64),
        pair=None if disc.contact.pair is None else np.asarray(disc.contact.pair, dtype=np.int64),
        master_facet=None if disc.contact.master_facet is None else np.asarray(disc.contact.master_facet, np.int64),
        tangents=disc.contact.tangents if ctx.components > 1 else None,
        snapshots=snaps.snapshots() if snaps is not None else {},
        meta=run_meta(disc, ctx, run.scheme, run.dt, run.n_steps, timings),
        counters={**dict.fromkeys(COUNTER_KEYS, 0), **ctx.counters(), "steps": n_last},
    )

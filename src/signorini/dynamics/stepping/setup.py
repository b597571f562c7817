"""Everything around the time loop: options, set-up, level 0, the run's summary figures.

:func:`set_up` discretizes, builds the :class:`~.context.Context`, factorizes the
scheme's operator (and its starter's, unless proportional) and computes the initial
state (:func:`initial_state`); :func:`make_observers` lists the built-in observers;
:func:`finish_history` makes the :class:`~.history.History` of the levels computed.
The loop itself is :class:`~.stepper.Stepper`; :func:`~.simulate.simulate` drives it.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping
from typing import Any

import numpy as np
import scipy.sparse.linalg as spla

from ...contact.solver import MAX_CONTACT_RESIDUAL  # noqa: F401  (the stepper's bound, read here)
from ...errors import InputError, check_positive
from ...fem.node_order import choose_order
from ...linalg import solver_options as validate_solver_options
from ...linalg.base import BACKENDS, IMPORT_FAILURES, backend_traits, memory_info, total_memory
from ...linalg.row_block import RowBlock
from ...parallel import DISTRIBUTED_BACKENDS, peak_memory_bytes, run_comm
from ..model.bodies import body_summaries, region_summaries
from ..model.damping import UNDAMPED
from ..model.mass import GRID_MASSES, MASS_VARIANTS
from ..model.mass_effect import effect_warning
from ..model.owned_rows import rank_cells
from ..model.problem import Discretization, Problem, discretize, friction_summary, in_node_order
from ..observe.history import COUNTER_KEYS, History
from ..observe.observers import EnergyRecorder, HistoryRecorder, Observer, ProgressCallback, Run, SnapshotRecorder
from ..schemes import Scheme, State, damping_schemes, make_scheme
from ..schemes.checks import check_finite_strain, check_finite_strain_solvers, check_friction_schemes
from ..schemes.momentum_projection import applies as momentum_projection_applies
from ..solve.context import Context

DT_RANGE = (1e-150, 1e150)
MAX_STEPS_EVER = 1e15


def number_of_steps(dt: float, T: float) -> int:
    """N = T/dt; T must be an integer multiple of dt to a relative 1e-9.

    Otherwise an :class:`InputError` names both and the two nearest valid time steps
    T/floor(T/dt) and T/ceil(T/dt) (a run never silently ends after T).
    """
    for name, v in (("dt", dt), ("T", T)):
        if isinstance(v, np.floating) and np.finfo(v).bits < 64:  # its decimal form is not its value
            short = np.format_float_positional(v)
            raise InputError(
                f"{name} must be a double (a Python float or numpy.float64), got {type(v).__name__} "
                f"{short}, which is {float(v)!r} in double; pass the intended value, "
                f"e.g. {short}"
            )
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


def _initial_force(ctx: Context, U: np.ndarray) -> np.ndarray:
    """f(U0) of finite strain; an initial displacement that inverts a cell is input to refuse (InputError)."""
    from ...fem.hyperelastic import InvertedCellError

    try:
        return ctx.elastic.force(U)
    except InvertedCellError as exc:
        raise InputError(f"the initial displacement inverts a cell: {exc.what}") from None


def initial_state(ctx: Context) -> State:
    """Level 0: U0, V0 and A0 from equilibrium, M A0 = F(0) - S U0 - C V0 (lambda_0 = 0; C the
    damping, when given, whose force C V0 is the level's damping force).

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
    lam0 = np.zeros(disc.contact.size)
    if disc.problem.initial_equilibrium:  # the held bodies' U0 in static equilibrium, lambda_0 its multipliers
        from ..solve.initial_equilibrium import static_equilibrium

        U, lam0, ctx.initial_equilibrium = static_equilibrium(ctx, U, F)
    r = F - (_initial_force(ctx, U) if ctx.elastic.finite else ctx.S @ U) - ctx.M @ A
    if lam0.any():
        r += ctx.rows.contact_force(lam0, None, 0.0)
    Fd = ctx.damping.force(ctx, V) if ctx.damping is not None else None
    if Fd is not None:  # damped: M A0 = F(0) - S U0 - C V0
        r -= Fd
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
        if ctx.rotated_kernel:  # singular: r's part along the kernel is the level's imbalance (R0 below), the rest
            # is in range(M) (M symmetric), a consistent system whose least-norm solution MINRES finds; A0 kept off
            # the kernel (MINRES on the whole r grew A0 there 1e13-fold: M A0 then carried its round-off)
            sol = spla.minres(op, (r - ctx.kernel_part(r))[idx], rtol=1e-14, maxiter=20000)[0]
            kernel = "mixed-velocity's kernel" if ctx.velocity_space is not None else "massless normal directions"
            ctx.initial_acceleration = f"minres ({kernel})"
        else:
            sol, info = spla.cg(op, r[idx], rtol=1e-14, atol=0.0, M=pre, maxiter=5000)
            ctx.initial_acceleration = "cg"
            if info != 0:  # fall back to a direct solve (reported in summary.json: initial_acceleration)
                sol = spla.spsolve((Mrr.whole() if by_rows else Mrr).tocsc(), r[idx])
                ctx.initial_acceleration = "spsolve (cg did not converge)"
        A[idx] = sol
        if ctx.rotated_kernel:
            A -= ctx.kernel_part(A)
    lam_t = np.zeros((disc.contact.size, ctx.rows.components - 1)) if ctx.rows.components > 1 else None
    state = State(0.0, U, V, A, lam0, lam_t=lam_t)
    R0 = np.zeros(n)
    ml = np.setdiff1d(ctx.massless, ctx.fixed)
    R0[ml] = -r[ml]
    if ctx.rotated_kernel and idx.size:  # out of equilibrium along the massless normals
        R0[idx] = ctx.M[idx] @ A - r[idx]
    if zero:
        R0[idx] = -r[idx]
    if np.any(R0 != 0.0):
        state.extra["R0"] = R0
    if Fd is not None:
        state.cache["CVd"] = Fd  # (:func:`~.schemes.base.damping_force` of level 0: C V0)
    return state


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
    # the current step's first system, or (a step whose factorization failed: the run failed there) the last made
    main = ctx.solvers[0] if ctx.solvers else ctx.factors.main
    return {
        "problem": disc.problem.name,
        "scheme": scheme.label,
        "scheme_options": dict(scheme.options),
        "energy_definition": scheme.energy_definition,
        "energy_parts": "energy = kinetic_energy + elastic_energy + load_potential (history.csv)",
        "mass": disc.mass_name,
        "mass_effect": dict(disc.mass_effect),
        "friction": friction_summary(disc.problem),
        # Rayleigh damping C = alpha M + beta S (model "none", zeros: undamped)
        "damping": (ctx.damping or UNDAMPED).describe(),
        # the material models of the cells: linear, or finite strain (Newton in every step)
        "material_model": list(ctx.elastic.models),
        "finite_strain": bool(ctx.elastic.finite),
        # energy-momentum with finite strain: the velocities corrected by the rigid motion that keeps the momenta
        # (docs/finite_strain.md; solver option momentum_projection)
        "momentum_projection": momentum_projection_applies(scheme, ctx),
        "warnings": run_warnings(disc),
        "dt": dt,
        "T": N * dt,
        "dim": int(disc.space.dim),
        "dofs": int(disc.space.n_dofs),
        # the cells: their types, their order (1 linear, 2 quadratic: docs/quadratic.md) and count
        "cells": cells_summary(disc.problem.mesh),
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
        # [initial] equilibrium = true: the static solve of the held bodies at t = 0 (what was held, solved, left)
        "initial_equilibrium": getattr(ctx, "initial_equilibrium", {"solved": False, "reason": "not asked"}),
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
    check_friction_schemes(ctx.rows.friction, schemes, finite=ctx.elastic.finite)
    check_finite_strain(ctx, schemes)
    for s in schemes:
        s.check_context(ctx)
    if ctx.damping is not None:
        for s in schemes:
            if s.damping_refusal:
                raise InputError(
                    f"scheme {s.name} cannot carry damping ([material] damping, regions[k].damping): "
                    f"{s.damping_refusal}; "
                    f"schemes that do: {', '.join(damping_schemes())}"
                )
    for s in schemes:
        op = s.step_operator(ctx, dt)
        if op is not None:
            ctx.factors.system(op)
            s.check_context(ctx, prepared=True)
    check_finite_strain_solvers(ctx)
    ctx.Mop, ctx.Sop  # noqa: B018 - built now (set-up), after the factors: a lower peak of memory
    return ctx


def set_up(
    problem: Problem | Discretization, mass: str, scheme: Scheme, grid, opts: dict, dt_initial: float | None = None
) -> tuple[Run, Scheme | None]:
    """Everything before the loop that costs time: discretization, factorization and
    level 0 (``opts`` from :func:`run_options`; ``grid`` a :class:`~.time_grid.TimeGrid`;
    ``dt_initial``: the step of level 0 when it is not the grid's first, a resumed run).
    Returns the run and the starter of a two-step scheme (None for one-step schemes)."""
    starter = make_scheme(scheme.starter) if scheme.starter else None
    N = grid.n_steps
    dt = grid.segments[0].dt if dt_initial is None else dt_initial
    check_history_fits(N)
    # a distributed backend: S and M by rows, each rank its own (docs/parallel.md)
    comm = run_comm(opts["backend"]) if opts.get("backend") in DISTRIBUTED_BACKENDS else None
    mesh = problem.mesh if isinstance(problem, Problem) else problem.problem.mesh
    if mesh.mixed and opts.get("backend") in BACKENDS and not backend_traits(opts["backend"]).mixed_meshes:
        types = ", ".join(sorted({b.cell_type for b in mesh.blocks}))
        able = ", ".join(e.name for e in BACKENDS if e.traits.mixed_meshes)
        raise InputError(
            f"backend {opts['backend']!r} does not run meshes of several cell types ({types}) yet; use "
            f"one that does ({able})"
        )
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
    extra = list(extra)
    for o in extra:  # duck typing allowed, but the three calls the loop makes must be there
        missing = [m for m in ("start", "record", "close") if not callable(getattr(o, m, None))]
        if missing:
            raise InputError(
                f"observers: {type(o).__name__} object is not an observer (no {', '.join(missing)}); give "
                "instances of signorini.dynamics.observe.observers.Observer (override start, record, close)"
            )
    if progress is not None and not callable(progress):
        raise InputError(f"progress must be a callable progress(step, n_steps), got {type(progress).__name__}")
    recorder, energies = HistoryRecorder(), EnergyRecorder() if energy else None
    snaps = SnapshotRecorder(snapshot_every) if snapshot_every else None
    obs: list[Observer] = [recorder] + [o for o in (energies, snaps) if o is not None] + list(extra)
    if progress is not None:
        obs.append(ProgressCallback(progress))
    return recorder, energies, snaps, obs


def finish_history(
    run: Run,
    n_last: int,
    recorder,
    energies,
    snaps,
    setup_seconds: float,
    loop: float,
    counters: dict | None = None,
    steps: int | None = None,
) -> History:
    """The :class:`History` of a run that ended at level ``n_last``, with its summary figures
    (timings, regions, bodies, pairs, per-rank figures); ``counters``: the run's counters when
    they are not the context's own (a resumed run adds those of the run it continues);
    ``steps``: the steps the loop time ``loop`` covers (default ``n_last``)."""
    # contact columns computed inside the loop (lazy condensation) are set-up work: reported
    # apart (in_loop_condensation_seconds), not in the time per step
    columns = sum(s.timings.get("condensation_in_loop", 0.0) for s in run.ctx.solvers)
    if run.ctx.comm.size == 1:
        for s in run.ctx.solvers:
            s.remeasure_bare()
    timings = {
        "setup_seconds": setup_seconds,
        "loop_seconds": loop,
        "step_seconds": (loop - columns) / max(n_last if steps is None else steps, 1),
        "in_loop_condensation_seconds": columns,
    }
    H = assemble_history(run, n_last, recorder, energies, snaps, timings, counters)
    disc = run.ctx.disc
    last = getattr(recorder, "last", None)
    H.meta["regions"] = region_summaries(disc.space.mesh, disc.problem.material, disc.problem.materials)
    H.meta["bodies"] = body_summaries(disc.space.mesh, disc.M, disc.material.rho, None if last is None else last.V)
    bodies = H.meta["bodies"]
    if len(bodies) > 1:  # what the variant does to each body (the whole's figures can hide it)
        for k, b in enumerate(bodies):
            text = effect_warning(b["mass_effect"]) if b.get("mass_effect") else None
            if text:
                regions = f" (regions {', '.join(b['regions'])})" if b["regions"] else ""
                H.meta["warnings"].append(f"mass {disc.mass_name!r} on body {k}{regions} {text}")
    if disc.contact.pair_info is not None:  # per pair: tags, rows, inactive slave nodes, contact law
        H.meta["pairs"] = [dict(p) for p in disc.contact.pair_info]
        H.meta["warnings"] += [p["warning"] for p in disc.contact.pair_info if p.get("warning")]
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
        return (
            "regions of different densities: f is a force density applied as it is (T^T int f phi for the "
            "extrapolated variants), not M_used f / rho; give an acceleration as [loads] gravity"
        )
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


def assemble_history(
    run: Run, n_last: int, recorder, energies, snaps, timings: dict, counters: dict | None = None
) -> History:
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
        work["damping_work"] = E["damping"]  # zeros without damping
        work["solver_work"] = E["solver"]  # zeros when linear
    else:
        nan = np.full(n_last + 1, np.nan)
        series.update(kinetic_energy=nan, elastic_energy=nan.copy(), predicted_increment=nan.copy())
        series["load_potential"] = nan.copy()
    reactions = getattr(recorder, "reactions", None)
    return History(
        t=recorder.times[: n_last + 1].copy(),
        reaction_columns=tuple(reactions.columns()) if reactions is not None else (),
        **series,
        **work,
        coordinates=disc.problem.mesh.points[disc.contact.nodes],
        weights=disc.contact.weights,
        nodes=np.asarray(disc.contact.nodes, dtype=np.int64),
        pair=None if disc.contact.pair is None else np.asarray(disc.contact.pair, dtype=np.int64),
        master_facet=None if disc.contact.master_facet is None else np.asarray(disc.contact.master_facet, np.int64),
        tangents=disc.contact.tangents if ctx.rows.components > 1 else None,
        snapshots=snaps.snapshots() if snaps is not None else {},
        meta=run_meta(disc, ctx, run.scheme, run.dt, run.n_steps, timings),
        counters={
            **dict.fromkeys(COUNTER_KEYS, 0),
            **(ctx.counters() if counters is None else counters),
            "steps": n_last,
        },
    )


def cells_summary(mesh) -> dict:
    """``summary.json`` ``cells``: the mesh's cell types, their order (1 linear, 2 quadratic) and count."""
    return {"types": sorted({b.cell_type for b in mesh.blocks}), "order": int(mesh.order), "count": int(mesh.n_cells)}

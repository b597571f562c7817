"""``signorini compare``: a matrix of time schemes x mass variants on one problem, ranked.

Pure functions, in the order the command calls them:

1. :func:`parse_schemes` / :func:`parse_masses`: ``cn,generalized-alpha[rho_inf=0.5]``
   and ``standard,seed`` into validated :class:`SchemeSpec` and mass names (registry
   names and options; an unknown one is an :class:`InputError` listing the allowed ones).
2. :func:`plan_benchmark` / :func:`plan_case`: the runs (pairs x levels, plus the
   reference run of a 2D/3D benchmark), every level's dt checked (T must be an integer
   multiple of it) before anything runs.
3. :func:`run_plan`: runs them, serially or in ``jobs`` processes
   (:class:`concurrent.futures.ProcessPoolExecutor`; every run is a pure function of its
   job, so the numbers do not depend on ``jobs``), measures the errors (1D: exact
   solution, :func:`~signorini.studies.study.errors_1d`; 2D/3D: the reference,
   :func:`~signorini.studies.reference_study.relative_errors`), the least-squares rates
   and the per-run diagnostics of :meth:`History.summary`, and ranks the pairs
   (:func:`rank_pairs`).  A pair that cannot run on this problem (a mass variant that
   refuses the mesh, a scheme that refuses a mass: an :class:`InputError` raised by the
   run itself) is kept as "n/a: <reason>".
4. :func:`write_report`: ``compare.md`` (one ranking table), ``compare.json`` and the
   figures with their CSVs (:mod:`signorini.studies.plots`).

Ranking rule (:data:`RANK_KEYS`, :func:`rank_pairs`): lexicographic with tolerance
bands.  Pairs are sorted by the error of the displacement in L2(0,T; H1) at the finest
level; pairs whose errors lie within 10% of the best error of their band are tied on
that key and ordered by the next key: the energy drift max |E - E0| / E0 (10%, or both
below 1e-9), then the oscillation index of the first impact (within 0.05), then the
maximum penetration (10%, or both below 1e-12 x the body's size).  Pairs tied on every
key share a rank.  A missing value (n/a) sorts after every number.  Case files have no
error: the ranking starts at the energy drift.  The time per step is reported, never
ranked (it depends on the machine and its load, so the ranking would not be
reproducible).  Why not a rank sum: it gives the same weight to a round-off
penetration of 1e-17 vs 2e-17 as to a factor 10 in the error, and its result changes
when a pair is added or removed; the lexicographic rule puts accuracy first and uses
the diagnostics only to separate pairs that are equally accurate.
"""

from __future__ import annotations

import json
import math
import os
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..dynamics.budget import CompareEstimate, estimate_compare, estimate_run
from ..dynamics.history import _json_default, finite_json
from ..dynamics.mass import MASS_VARIANTS
from ..dynamics.schemes import SCHEMES, make_scheme
from ..dynamics.simulate import number_of_steps, simulate
from ..errors import ConvergenceError, InputError, check_positive
from ..registry import parse_assignments
from .benchmarks import get_benchmark
from .reference_study import DEFAULT_REFERENCE_FACTOR, Reference, check_levels, describe_reference, relative_errors

DEFAULT_RATIO = 0.5
DEFAULT_LEVELS = 3
DEFAULT_N0 = {1: 20, 2: 1, 3: 1}
DEFAULT_T = {1: 3.0, 2: 1.0, 3: 1.0}  # 1D: one period 3L/c of bar1d; 2D/3D: the first impact
ERROR_NORMS = {"u_H1": "u L2(0,T; H1)", "v_L2": "v L2(0,T; L2)"}
CONTACT_NORM = {1: "stress", 2: "force", 3: "force"}  # contact error of errors_1d / relative_errors

# (metric, relative tolerance, absolute tolerance, where the absolute one is x the length scale)
RANK_KEYS = (
    ("violates_contact", 0.0, 0.0, False),
    ("error_u", 0.10, 0.0, False),
    ("energy_drift", 0.10, 1e-9, False),
    ("oscillation_index", 0.0, 0.05, False),
    ("penetration_max", 0.10, 1e-12, True),
)
#: a penetration (contact or untagged boundary nodes) above this x the body's size violates
#: the contact constraint: such a run ranks below every run that respects it
CONTACT_TOLERANCE = 1e-6
RANK_LABELS = {
    "violates_contact": "penetration beyond the contact tolerance",
    "error_u": "error",
    "energy_drift": "energy drift",
    "oscillation_index": "oscillation index",
    "penetration_max": "penetration",
}
RANKING_RULE = (
    "First, a run whose contact or untagged boundary nodes penetrate the obstacle by more than 1e-6 x the body's size "
    "violates the constraint and ranks below every run that respects it. Then lexicographic with tolerance bands: "
    "sort by the error of u in L2(0,T; H1) at the finest level; pairs within "
    "10% of the best error of their band are tied and ordered by the energy drift max|E - E0|/E0 (tied within 10% "
    "or both below 1e-9), then by the oscillation index of the first impact (tied within 0.05), then by the maximum "
    "penetration (tied within 10% or both below 1e-12 x the body's size); pairs tied on every key share a rank and "
    "n/a sorts last. Accuracy comes first because it is the only figure measured against the solution itself; the "
    "diagnostics only separate pairs that are equally accurate. A rank sum was rejected: it weighs a round-off "
    "penetration difference like a factor 10 in the error and changes when a pair is added. The time per step is "
    "shown but not ranked (it depends on the machine and its load, so the ranking would not be reproducible)."
)
RANKING_RULE_CASE = (
    "Case file (one level, no error): the same rule without the error key, i.e. runs that penetrate the obstacle "
    "by more than 1e-6 x the body's size (contact or untagged boundary nodes) last, then lexicographic with "
    "tolerance bands on "
    "the energy drift max|E - E0|/E0 (tied within 10% or both below 1e-9), the oscillation index of the first impact "
    "(tied within 0.05) and the maximum penetration (tied within 10% or both below 1e-12 x the body's size); ties "
    "share a rank, n/a sorts last, the time per step is shown but not ranked."
)
SUMMARY_FIELDS = (
    "status",
    "message",
    "scheme",
    "mass",
    "dt",
    "T",
    "steps",
    "mass_effect",
    "untagged_penetration_max",
    "dofs",
    "contact_nodes",
    "backend",
    "impacts",
    "energy_definition",
    "energy_initial",
    "energy_final",
    "energy_max_relative_drift",
    "penetration_max",
    "penetration_time_integral",
    "oscillation_index",
    "impact_oscillation_indices",
    "impulse",
    "impact_impulses",
    "energy_identity_residual",
    "max_complementarity_residual",
    "setup_seconds",
    "loop_seconds",
    "step_seconds",
    "bare_solve_seconds",
    "bare_spmv_seconds",
    "counters",
)
TIMING_FIELDS = ("setup_seconds", "loop_seconds", "step_seconds", "bare_solve_seconds", "bare_spmv_seconds")


# ----------------------------------------------------------------------------- names
@dataclass(frozen=True)
class SchemeSpec:
    """A registry scheme with the options the user gave (validated, converted)."""

    name: str
    options: tuple[tuple[str, Any], ...] = ()

    @property
    def label(self) -> str:
        """``name`` or ``name[opt=value,...]`` (canonical name, options as given)."""
        if not self.options:
            return self.name
        return f"{self.name}[{','.join(f'{k}={_num(v)}' for k, v in self.options)}]"

    @property
    def option_dict(self) -> dict[str, Any]:
        return dict(self.options)


def _num(v: Any) -> str:
    return f"{v:g}" if isinstance(v, float) else str(v)


def _split_top_level(text: str, flag: str) -> list[str]:
    """Split on commas outside brackets; unbalanced brackets are an InputError."""
    parts, depth, cur = [], 0, []
    for ch in text:
        if ch == "[":
            depth += 1
            if depth > 1:
                raise InputError(f"{flag}: nested '[' in {text!r}")
        elif ch == "]":
            depth -= 1
            if depth < 0:
                raise InputError(f"{flag}: unbalanced ']' in {text!r}")
        if ch == "," and depth == 0:
            parts.append("".join(cur).strip())
            cur = []
        else:
            cur.append(ch)
    if depth:
        raise InputError(f"{flag}: missing ']' in {text!r}")
    parts.append("".join(cur).strip())
    if any(not p for p in parts):
        raise InputError(f"{flag}: empty entry in {text!r} (entries are separated by commas)")
    return parts


def parse_scheme(text: str, flag: str = "--schemes") -> SchemeSpec:
    """``name`` or ``name[opt=val,opt2=val]``, validated by :data:`SCHEMES`."""
    text = text.strip()
    name, opts = text, {}
    if "[" in text or "]" in text:
        if not (text.endswith("]") and text.count("[") == 1 and text.count("]") == 1 and text.index("[") > 0):
            raise InputError(f"{flag}: expected name or name[option=value,...], got {text!r}")
        name, inner = text[:-1].split("[", 1)
        opts = parse_assignments([s for s in inner.split(",") if s.strip()], f"{flag} {name.strip()}[...]")
    entry = SCHEMES.get(name.strip())  # unknown name: InputError listing the allowed ones
    converted = entry.options(opts, where=f"scheme {entry.name}")  # unknown option: lists the allowed ones
    make_scheme(entry.name, converted)  # cross-parameter checks
    return SchemeSpec(entry.name, tuple((k, converted[k]) for k in opts))


def parse_schemes(text: str) -> list[SchemeSpec]:
    specs = [parse_scheme(p) for p in _split_top_level(text, "--schemes")]
    seen = set()
    for s in specs:
        if s in seen:
            raise InputError(f"--schemes lists {s.label} twice")
        seen.add(s)
    return specs


def parse_masses(text: str) -> list[str]:
    names = [MASS_VARIANTS.resolve(p) for p in _split_top_level(text, "--masses")]
    if len(set(names)) != len(names):
        raise InputError(f"--masses lists a mass variant twice: {text!r}")
    return names


@dataclass(frozen=True)
class Pair:
    scheme: SchemeSpec
    mass: str

    @property
    def label(self) -> str:
        return f"{self.scheme.label} / {self.mass}"


def make_pairs(schemes: Sequence[SchemeSpec], masses: Sequence[str]) -> list[Pair]:
    """schemes x masses, scheme-major."""
    return [Pair(s, m) for s in schemes for m in masses]


def parse_reference(text: str) -> tuple[SchemeSpec, str, int]:
    """``LEVEL`` (CN + seed) or ``scheme:mass:LEVEL``."""
    parts = text.rsplit(":", 2)
    if len(parts) not in (1, 3):
        raise InputError(f"--reference expects LEVEL or scheme:mass:LEVEL, got {text!r}")
    scheme = parse_scheme(parts[0], "--reference") if len(parts) == 3 else SchemeSpec("crank-nicolson")
    mass = MASS_VARIANTS.resolve(parts[1]) if len(parts) == 3 else "seed"
    try:
        level = int(parts[-1])
    except ValueError:
        raise InputError(f"--reference: the level must be an integer, got {parts[-1]!r}") from None
    if level < 1:
        raise InputError(f"--reference: the level must be positive, got {level}")
    return scheme, mass, level


# ----------------------------------------------------------------------------- targets
@dataclass(frozen=True)
class BenchmarkTarget:
    """A registered benchmark with parameter overrides; levels are its ``n``."""

    name: str
    overrides: tuple[tuple[str, float], ...] = ()
    kind: str = "benchmark"

    @property
    def label(self) -> str:
        return self.name

    @property
    def bench(self):
        return get_benchmark(self.name)

    @property
    def params(self) -> dict:
        return dict(self.overrides)

    def problem(self, level: int | None):
        return self.bench.problem(level, self.params)


@dataclass(frozen=True)
class CaseTarget:
    """A case file: ``load()`` (picklable, e.g. a module-level function bound with
    :func:`functools.partial`) returns its Problem; one level, the file's dt and T."""

    label: str
    load: Callable[[], Any]
    dt: float
    T: float
    solver_options: tuple[tuple[str, Any], ...] = ()
    kind: str = "case"

    def problem(self, level: int | None):
        return self.load()


# ----------------------------------------------------------------------------- jobs
@dataclass(frozen=True)
class Job:
    """One simulation: pure function of these fields (so serial == parallel)."""

    key: tuple  # (pair index, level index) or ("reference",)
    target: Any
    level: int | None
    scheme: SchemeSpec
    mass: str
    dt: float
    T: float
    solver_options: tuple[tuple[str, Any], ...] = ()
    snapshots: bool = False  # keep fields at every step (errors)
    exact_errors: bool = False  # 1D: errors against the exact solution, in the worker
    return_history: bool = False  # 2D/3D errors and the reference: the parent needs the fields
    keep_series: bool = False  # finest level: time series for the figures
    cost: float = 0.0  # for scheduling only (largest first)


@dataclass
class Outcome:
    key: tuple
    status: str  # finished | failed | interrupted | n/a
    reason: str = ""
    summary: dict = field(default_factory=dict)
    errors: dict | None = None
    series: dict | None = None
    history: Any = None


def execute_job(job: Job) -> Outcome:
    """Run one job; an InputError of the run itself (a mass the mesh refuses, a scheme
    that refuses a mass) or a failure before the first step is an ``n/a`` outcome."""
    try:
        problem = job.target.problem(job.level)
        H = simulate(
            problem,
            job.scheme.name,
            job.dt,
            job.T,
            mass=job.mass,
            snapshot_every=1 if job.snapshots else 0,
            scheme_options=job.scheme.option_dict,
            solver_options=dict(job.solver_options),
        )
    except InputError as exc:
        return Outcome(job.key, "n/a", str(exc))
    except ConvergenceError as exc:
        return Outcome(job.key, "n/a", f"failed before the first step: {exc}")
    s = H.summary()
    out = Outcome(job.key, H.status, H.message, {k: s.get(k) for k in SUMMARY_FIELDS})
    out.summary["counters"] = dict(s["counters"])
    if H.status == "finished" and job.exact_errors:
        from .study import errors_1d

        b = job.target.bench
        out.errors = errors_1d(H, problem, b.exact(b.params(job.target.params), job.T))
    if job.keep_series:
        out.series = {
            "t": H.t,
            "energy": H.energy,
            "force": -H.lambda_sum + 0.0,
            "penetration": H.columns()["penetration"],
        }
    if job.return_history:
        out.history = H
    return out


def default_jobs(runs: int) -> int:
    """min(available cores, runs); 1 on a single core."""
    try:
        cores = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        cores = os.cpu_count() or 1
    return max(1, min(cores, runs))


def _watch_parent(parent: int) -> None:
    """Worker initializer: ignore Ctrl-C between runs (a run in progress still stops
    cleanly, ``simulate`` has its own handler) and exit as soon as the parent is gone
    (a SIGKILLed parent must not leave workers behind, nor keep the result
    directory's watchdog pipe open)."""
    import signal
    import threading

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(0.2)
        os._exit(1)

    threading.Thread(target=watch, daemon=True).start()


def _context():
    import multiprocessing as mp

    methods = mp.get_all_start_methods()
    # fork: no re-import in the workers, and their parent is this process (for _watch_parent)
    return mp.get_context("fork" if "fork" in methods else "spawn")


def run_jobs(jobs: Sequence[Job], workers: int) -> list[Outcome]:
    """Outcomes in the order of ``jobs``; in ``workers`` processes when > 1 (largest first).

    An interrupted run (Ctrl-C, SIGTERM) raises KeyboardInterrupt: the remaining jobs are
    cancelled.
    """
    if workers <= 1 or len(jobs) <= 1:
        out = []
        for j in jobs:
            out.append(execute_job(j))
            if out[-1].status == "interrupted":
                raise KeyboardInterrupt
        return out
    order = sorted(range(len(jobs)), key=lambda i: -jobs[i].cost)
    ex = ProcessPoolExecutor(min(workers, len(jobs)), _context(), _watch_parent, (os.getpid(),))
    try:
        results = list(ex.map(execute_job, [jobs[i] for i in order]))
    except BrokenProcessPool as exc:
        ex.shutdown(wait=True, cancel_futures=True)
        raise RuntimeError(f"a worker process died ({exc}; out of memory?); rerun with --jobs 1") from None
    except BaseException:
        ex.shutdown(wait=True, cancel_futures=True)
        raise
    ex.shutdown(wait=True)
    if any(r.status == "interrupted" for r in results):
        raise KeyboardInterrupt
    out: list[Outcome | None] = [None] * len(jobs)
    for i, r in zip(order, results, strict=True):
        out[i] = r
    return out  # type: ignore[return-value]


# ----------------------------------------------------------------------------- plans
@dataclass
class Plan:
    """Validated inputs of a comparison (nothing has run yet)."""

    target: Any
    pairs: list[Pair]
    levels: list[int | None]
    dts: list[float]
    T: float
    ratio: float | None = None
    hs: list[float] | None = None
    reference: Any = None  # (SchemeSpec, mass, level) to run, or a Reference to reuse, or None (exact / case)
    solver_options: tuple[tuple[str, Any], ...] = ()
    length_scale: float = 1.0
    counts: tuple[int, int, int, int, int] | None = None  # case file: (nodes, cells, per cell, dim, contact)

    @property
    def kind(self) -> str:
        return self.target.kind

    @property
    def has_errors(self) -> bool:
        return self.kind == "benchmark"

    @property
    def exact(self) -> bool:
        return self.kind == "benchmark" and self.target.bench.dim == 1


def _steps(dt: float, T: float, where: str) -> int:
    try:
        return number_of_steps(dt, T)
    except InputError as exc:
        raise InputError(f"{where}: {exc}") from None


def plan_benchmark(
    name: str,
    pairs: list[Pair],
    levels: int = DEFAULT_LEVELS,
    n0: int | None = None,
    T: float | None = None,
    ratio: float = DEFAULT_RATIO,
    overrides: dict | None = None,
    reference: tuple | Reference | None = None,
) -> Plan:
    """Levels n0 2^k (k < levels), dt = ratio h; a 2D/3D reference (default CN + seed
    ``DEFAULT_REFERENCE_FACTOR`` x finer than the finest level).  Raises InputError."""
    b = get_benchmark(name)
    b.require_nested("signorini compare")
    params = b.params(overrides)
    target = BenchmarkTarget(b.name, tuple(sorted((k, float(v)) for k, v in (overrides or {}).items())))
    if not pairs:
        raise InputError("nothing to compare: give at least one scheme and one mass")
    if int(levels) != levels or levels < 1:
        raise InputError(f"--levels must be a positive integer, got {levels}")
    n0 = DEFAULT_N0[b.dim] if n0 is None else n0
    if int(n0) != n0 or n0 < 1:
        raise InputError(f"--n0 must be a positive integer, got {n0}")
    T = check_positive("--T", DEFAULT_T[b.dim] if T is None else T)
    ratio = check_positive("--ratio", ratio)
    ns = [int(n0) * 2**k for k in range(int(levels))]
    hs = [b.h(n, params) for n in ns]
    dts = [ratio * h for h in hs]
    for n, dt in zip(ns, dts, strict=True):
        _steps(dt, T, f"level n = {n} (dt = {ratio:g} h = {dt:.6g})")
    ref: Any = None
    if b.dim == 1:
        if reference is not None:
            raise InputError(f"{name!r} is compared with its exact solution; --reference does not apply")
    elif isinstance(reference, Reference):
        ref = reference
        check_levels(ns, ref.level)
        if ref.t_end < T * (1 - 1e-9):
            raise InputError(f"the reference (n = {ref.level}) ends at t = {ref.t_end:.6g}, before T = {T:g}")
    else:
        scheme, mass, level = reference or (SchemeSpec("crank-nicolson"), "seed", DEFAULT_REFERENCE_FACTOR * ns[-1])
        check_levels(ns, level)
        _steps(ratio * b.h(level, params), T, f"reference level n = {level}")
        ref = (scheme, mass, level)
    problem = b.problem(ns[0], params)  # parameters and mesh valid before anything runs
    return Plan(target, list(pairs), ns, dts, T, ratio, hs, ref, (), _length_scale(problem))


def plan_case(target: CaseTarget, pairs: list[Pair], problem=None) -> Plan:
    """One level (the case file's mesh, dt and T), no errors."""
    if not pairs:
        raise InputError("nothing to compare: give at least one scheme and one mass")
    _steps(target.dt, target.T, f"case file {target.label}")
    problem = problem if problem is not None else target.load()
    m = problem.mesh
    counts = (m.n_nodes, m.n_cells, m.cells.shape[1], m.dim, m.nodes_of(problem.contact_tag).size)
    return Plan(target, list(pairs), [None], [target.dt], target.T, solver_options=target.solver_options,
                length_scale=_length_scale(problem), counts=counts)  # fmt: skip


def _length_scale(problem) -> float:
    pts = problem.mesh.points
    return float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0))) or 1.0


def _cost(target, level: int | None, dt: float, T: float) -> float:
    if target.kind != "benchmark":
        return T / dt
    nodes = target.bench.mesh_counts(level)[0]
    return nodes * target.bench.dim * T / dt


def make_jobs(plan: Plan) -> list[Job]:
    jobs = []
    finest = len(plan.levels) - 1
    two_d = plan.has_errors and not plan.exact
    for i, pair in enumerate(plan.pairs):
        for k, (n, dt) in enumerate(zip(plan.levels, plan.dts, strict=True)):
            jobs.append(
                Job(
                    (i, k), plan.target, n, pair.scheme, pair.mass, dt, plan.T, plan.solver_options,
                    snapshots=plan.has_errors, exact_errors=plan.exact, return_history=two_d,
                    keep_series=k == finest, cost=_cost(plan.target, n, dt, plan.T),
                )
            )  # fmt: skip
    if isinstance(plan.reference, tuple):
        scheme, mass, level = plan.reference
        dt = plan.ratio * plan.target.bench.h(level, plan.target.params)
        jobs.append(Job(("reference",), plan.target, level, scheme, mass, dt, plan.T, plan.solver_options,
                        snapshots=True, return_history=True, cost=_cost(plan.target, level, dt, plan.T)))  # fmt: skip
    return jobs


def estimate_plan(plan: Plan, jobs: int | None = None) -> CompareEstimate:
    """Peak memory of the whole matrix (:func:`~signorini.dynamics.budget.estimate_compare`):
    every run with the fields it keeps for the errors (every level of every run), the
    ``jobs`` largest at once, plus the 2D/3D fields held by this process until the errors
    against the reference are measured.  Built from mesh counts: nothing is meshed."""
    job_list = make_jobs(plan)
    workers = default_jobs(len(job_list)) if jobs is None else int(jobs)
    runs = []
    for j in job_list:
        if plan.kind == "benchmark":
            b = plan.target.bench
            counts = (*b.mesh_counts(j.level), b.dim, b.contact_count(j.level))
        else:
            counts = plan.counts
        runs.append(estimate_run(*counts, number_of_steps(j.dt, j.T), kept_fields=j.snapshots))
    return estimate_compare(runs, [j.return_history for j in job_list], workers)


# ----------------------------------------------------------------------------- run + collect
def run_plan(plan: Plan, jobs: int | None = None) -> tuple[dict, dict]:
    """Run every job and collect: (result for compare.json, {pair label: finest-level series})."""
    t0 = time.perf_counter()
    job_list = make_jobs(plan)
    workers = default_jobs(len(job_list)) if jobs is None else int(jobs)
    if workers < 1:
        raise InputError(f"--jobs must be a positive integer, got {jobs}")
    outcomes = {o.key: o for o in run_jobs(job_list, workers)}
    reference = _reference(plan, outcomes.pop(("reference",), None))
    result = collect(plan, outcomes, reference)
    result["jobs"] = workers
    result["runs"] = len(job_list)
    result["seconds"] = time.perf_counter() - t0
    series = {plan.pairs[i].label: o.series for (i, k), o in outcomes.items() if o.series is not None}
    return result, series


def _reference(plan: Plan, outcome: Outcome | None) -> Reference | None:
    if isinstance(plan.reference, Reference):
        return plan.reference
    if outcome is None:
        return None
    scheme, mass, level = plan.reference
    if outcome.status != "finished":
        raise ConvergenceError(f"the reference run ({scheme.label} + {mass} at n = {level}) did not finish: "
                               f"{outcome.status} ({outcome.reason})")  # fmt: skip
    b = plan.target.bench
    p = plan.target.problem(level)
    return Reference(b.name, level, scheme.label, mass, outcome.history, p, b.h(level, plan.target.params),
                     plan.target.params)  # fmt: skip


def fitted_rate(hs: Sequence[float], errors: Sequence[float | None]) -> float | None:
    """Least-squares slope of log(error) against log(h) over the levels with a positive
    finite error (None with fewer than two)."""
    pts = [(h, e) for h, e in zip(hs, errors, strict=True) if e is not None and np.isfinite(e) and e > 0]
    if len(pts) < 2:
        return None
    x, y = np.log([p[0] for p in pts]), np.log([p[1] for p in pts])
    return float(np.polyfit(x, y, 1)[0])


def collect(plan: Plan, outcomes: dict, reference: Reference | None) -> dict:
    """compare.json's content (without the ranking, added by :func:`rank_result`)."""
    dim = plan.target.bench.dim if plan.kind == "benchmark" else None
    contact_norm = CONTACT_NORM.get(dim) if dim else None
    finest = len(plan.levels) - 1
    ref_info = None
    if reference is not None:
        ref_info = reference.info(plan.levels[-1], plan.dts[-1])
        grids = {}
    elif plan.exact:
        ref_info = {"kind": "exact", "description": "exact solution"}
    pairs = []
    for i, pair in enumerate(plan.pairs):
        runs = []
        for k, n in enumerate(plan.levels):
            o = outcomes[(i, k)]
            errors = o.errors
            if reference is not None and o.status == "finished":
                if n not in grids:
                    grids[n] = plan.target.problem(n).mesh
                errors = relative_errors(o.history, grids[n], reference, plan.T)
            o.history = None  # fields no longer needed
            runs.append(
                {
                    "n": n,
                    "h": plan.hs[k] if plan.hs else None,
                    "dt": plan.dts[k],
                    "status": o.status,
                    "reason": o.reason,
                    "summary": o.summary,
                    "errors": errors,
                }
            )
        pairs.append(_pair_entry(plan, pair, runs, finest, contact_norm))
    result = {
        "target": plan.target.label,
        "kind": plan.kind,
        "dim": dim,
        "levels": plan.levels,
        "h": plan.hs,
        "dt": plan.dts,
        "T": plan.T,
        "ratio": plan.ratio,
        "parameters": plan.target.bench.params(plan.target.params) if plan.kind == "benchmark" else None,
        "reference": ref_info,
        "contact_norm": contact_norm,
        "length_scale": plan.length_scale,
        "pairs": pairs,
    }
    return rank_result(result)


def _pair_entry(plan: Plan, pair: Pair, runs: list[dict], finest: int, contact_norm: str | None) -> dict:
    top = runs[finest]
    entry = {
        "label": pair.label,
        "scheme": pair.scheme.name,
        "scheme_label": pair.scheme.label,
        "scheme_options": pair.scheme.option_dict,
        "mass": pair.mass,
        "runs": runs,
    }
    if top["status"] != "finished":
        why = top["reason"] if top["status"] == "n/a" else f"run {top['status']}: {top['reason']}"
        where = f" (n = {top['n']})" if top["n"] is not None else ""
        entry.update(available=False, reason=f"{why}{where}", metrics={}, rates={})
        return entry
    s = top["summary"]
    bare = s.get("bare_solve_seconds") or s.get("bare_spmv_seconds")
    metrics = {
        "energy_drift": s["energy_max_relative_drift"],
        "oscillation_index": s["oscillation_index"],
        "penetration_max": s["penetration_max"],
        "mass_kept": (s.get("mass_effect") or {}).get("mass_ratio"),
        "untagged_penetration_max": s.get("untagged_penetration_max"),
        "changes_physics": bool((s.get("mass_effect") or {}).get("changes_physics")),
        "energy_final": s["energy_final"],
        "step_ms": 1e3 * s["step_seconds"],
        "step_over_bare": s["step_seconds"] / bare if bare else None,
        "bare_op": ("solve" if s.get("bare_solve_seconds") else "SpMV") if bare else None,
    }
    rates = {}
    if plan.has_errors:
        errs = top["errors"] or {}
        norms = {"u_H1": "error_u", "v_L2": "error_v", contact_norm: "error_contact"}
        metrics.update({name: errs.get(k) for k, name in norms.items()})
        for k in norms:
            rates[k] = fitted_rate(plan.hs, [(r["errors"] or {}).get(k) for r in runs])
    notes = [f"n = {r['n']}: {r['reason'] or r['status']}" for r in runs if r["status"] != "finished"]
    entry.update(available=True, reason="; ".join(notes), metrics=metrics, rates=rates)
    return entry


# ----------------------------------------------------------------------------- ranking
def _finite(v) -> bool:
    return v is not None and isinstance(v, (int, float)) and math.isfinite(v)


def rank_pairs(items: list[dict], keys=RANK_KEYS, length_scale: float = 1.0) -> list[dict]:
    """Rank ``items`` (dicts of metrics) lexicographically with tolerance bands.

    ``keys``: (metric, rtol, atol, atol_is_relative_to_length).  On each key the
    values are sorted; a band starts at its smallest value v and holds every value
    <= v (1 + rtol) + atol; within a band the next key decides.  Missing values form
    a last band.  Returns ``[{"index", "rank", "decided_by"}]`` in ranked order:
    equal ranks for items in the same band on every key; ``decided_by`` is the
    first key that separates an item from the next one (None for the last item,
    "tie" when nothing does).
    """

    def bands(idx: list[int], depth: int) -> list[tuple[int, tuple]]:
        if depth == len(keys) or len(idx) <= 1:
            return [(i, ()) for i in idx]
        name, rtol, atol, scaled = keys[depth]
        atol = atol * (length_scale if scaled else 1.0)
        have = sorted((i for i in idx if _finite(items[i].get(name))), key=lambda i: (items[i][name], i))
        missing = [i for i in idx if not _finite(items[i].get(name))]
        groups, cur = [], []
        for i in have:
            if cur and items[i][name] > items[cur[0]][name] * (1 + rtol) + atol:
                groups.append(cur)
                cur = []
            cur.append(i)
        groups += [g for g in (cur, missing) if g]
        out = []
        for b, g in enumerate(groups):
            out += [(i, (b, *path)) for i, path in bands(g, depth + 1)]
        return out

    ordered = bands(list(range(len(items))), 0)
    out, rank = [], 0
    for j, (i, path) in enumerate(ordered):
        if j == 0 or path != ordered[j - 1][1]:
            rank = j + 1
        decided = None
        if j + 1 < len(ordered):
            nxt = ordered[j + 1][1]
            diff = [d for d in range(min(len(path), len(nxt))) if path[d] != nxt[d]]
            decided = keys[diff[0]][0] if diff else "tie"
        out.append({"index": i, "rank": rank, "decided_by": decided})
    return out


def rank_result(result: dict) -> dict:
    """Add ``rank``/``decided_by`` to every available pair and the rule to ``result``."""
    keys = RANK_KEYS if result["kind"] == "benchmark" else tuple(k for k in RANK_KEYS if k[0] != "error_u")
    avail = [p for p in result["pairs"] if p["available"]]
    for p in avail:
        m = p["metrics"]
        worst = max(m.get("penetration_max") or 0.0, m.get("untagged_penetration_max") or 0.0)
        m["violates_contact"] = float(worst > CONTACT_TOLERANCE * result["length_scale"])
    ranking = rank_pairs([p["metrics"] for p in avail], keys, result["length_scale"])
    order = []
    for r in ranking:
        p = avail[r["index"]]
        p["rank"], p["decided_by"] = r["rank"], r["decided_by"]
        order.append(p["label"])
    for p in result["pairs"]:
        if not p["available"]:
            p["rank"], p["decided_by"] = None, None
    result["ranking"] = {
        "rule": RANKING_RULE if result["kind"] == "benchmark" else RANKING_RULE_CASE,
        "keys": [{"metric": k, "rtol": r, "atol": a, "atol_times_length_scale": s} for k, r, a, s in keys],
        "order": order + [p["label"] for p in result["pairs"] if not p["available"]],
    }
    return result


def ranked_pairs(result: dict) -> list[dict]:
    """The pairs in ranking order (unavailable ones last, in input order)."""
    by = {p["label"]: p for p in result["pairs"]}
    return [by[label] for label in result["ranking"]["order"]]


# ----------------------------------------------------------------------------- text
def _f(x, spec: str = ".3g") -> str:
    return format(float(x) + 0.0, spec) if _finite(x) else "n/a"  # + 0.0: no "-0"


def reference_text(result: dict) -> str:
    ref = result["reference"]
    if result["kind"] != "benchmark":
        return "Case file: one level, no error measurement (per-run diagnostics only)."
    if ref["kind"] == "exact":
        return "Errors against the exact solution."
    return f"Errors against the reference {describe_reference(ref)}."


def setup_text(result: dict) -> str:
    if result["kind"] != "benchmark":
        return f"Case file `{result['target']}`: dt = {result['dt'][0]:.6g}, T = {result['T']:g}."
    levels = ", ".join(str(n) for n in result["levels"])
    return (
        f"Benchmark `{result['target']}`, levels n = {levels} (h = {result['h'][0]:.4g} .. {result['h'][-1]:.4g}, "
        f"dt = {result['ratio']:g} h), T = {result['T']:g}; diagnostics at the finest level n = {result['levels'][-1]}."
    )


def table_markdown(result: dict) -> list[str]:
    """The ranking table: one row per pair, in ranking order."""
    errors = result["kind"] == "benchmark"
    cols = ["rank", "scheme", "mass"]
    if errors:
        cols += ["u error L2(H1)", "u rate", "v error L2(L2)", "v rate"]
    cols += ["energy drift", "oscillation index", "max penetration", "mass kept", "ms / step", "step / bare op"]
    cols += ["decided by", "note"]
    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for p in ranked_pairs(result):
        m, r = p["metrics"], p["rates"]
        if not p["available"]:
            cells = ["n/a", p["scheme_label"], p["mass"]] + ["n/a"] * (len(cols) - 4) + [f"n/a: {p['reason']}"]
            lines.append("| " + " | ".join(_cell(c) for c in cells) + " |")
            continue
        cells = [str(p["rank"]), p["scheme_label"], p["mass"]]
        if errors:
            cells += [_f(m.get("error_u"), ".3e"), _f(r.get("u_H1"), ".2f"), _f(m.get("error_v"), ".3e"),
                      _f(r.get("v_L2"), ".2f")]  # fmt: skip
        drift = _f(m["energy_drift"], ".2e") if _finite(m["energy_drift"]) else "n/a (E0 = 0)"
        bare = f"{m['step_over_bare']:.2f} x {m['bare_op']}" if _finite(m["step_over_bare"]) else "n/a (not measured)"
        decided = RANK_LABELS.get(p["decided_by"], p["decided_by"] or "(last)")
        kept = f"{100 * m['mass_kept']:.4g}%" if _finite(m.get("mass_kept")) else "n/a"
        note = "; ".join(
            x for x in (p["reason"], "the mass changes the body's inertia" if m.get("changes_physics") else "") if x
        )
        cells += [drift, _f(m["oscillation_index"], ".3f"), _f(m["penetration_max"], ".2e"), kept,
                  _f(m["step_ms"], ".3g"), bare, decided, note or "-"]  # fmt: skip
        lines.append("| " + " | ".join(_cell(c) for c in cells) + " |")
    return lines


def _cell(text: str) -> str:
    return str(text).replace("|", "/").replace("\n", " ")


COLUMN_NOTES = (
    "Columns: errors are relative, at the finest level (u in L2(0,T; H1), v in L2(0,T; L2)); rates are the "
    "least-squares slopes of log(error) against log(h) over the levels (n/a with fewer than two levels); energy "
    "drift = max_n |E^n - E^0| / |E^0| with the scheme's own energy (summary.json `energy_definition`); oscillation "
    "index of the first impact (1 = one monotone rise and fall of the total contact force, 0 = no contact); max "
    "penetration = max over levels and contact nodes of max(0, -gap); ms / step = loop time per step at the finest "
    "level (contact columns computed lazily are set-up work, left out), and its ratio to one bare solve with the "
    "same factor (SpMV for CG); decided by = the first ranking key "
    "that separates the pair from the next one."
)


def report_markdown(result: dict, figures: Sequence[tuple[str, str]] = ()) -> str:
    lines = [f"# signorini compare: {result['target']}", "", setup_text(result), "", reference_text(result)]
    ref = result["reference"] or {}
    if ref.get("kind") == "run" and ref.get("factor_h", DEFAULT_REFERENCE_FACTOR) < DEFAULT_REFERENCE_FACTOR:
        lines += ["", f"Warning: the reference is only {ref['factor_h']:g}x finer than the finest level."]
    lines += [
        "",
        f"{result['runs']} runs in {result['jobs']} process(es), {result['seconds']:.1f} s.",
        "",
        "## Ranking",
        "",
        f"Rule: {result['ranking']['rule']}",
        "",
        *table_markdown(result),
        "",
        COLUMN_NOTES,
        "",
    ]
    if figures:
        lines += ["## Figures", ""]
        for name, caption in figures:
            lines += [f"![{caption}]({name})", "", f"*{caption}* (`{name}`, numbers in `{Path(name).stem}.csv`)", ""]
    return "\n".join(lines)


def write_report(result: dict, series: dict, out: Path) -> dict:
    """compare.md, compare.json and the figures with their CSVs into ``out`` (existing)."""
    import matplotlib

    matplotlib.use("Agg")
    from . import plots

    out = Path(out)
    figures = plots.compare_figures(result, series, out)
    (out / "compare.md").write_text(report_markdown(result, figures))
    (out / "compare.json").write_text(json.dumps(finite_json(result), indent=1, default=_json_default))
    return result


def strip_timings(result: dict) -> dict:
    """``result`` without the fields that depend on the machine's speed (for comparisons)."""
    r = json.loads(json.dumps(finite_json(result), default=_json_default))
    for k in ("seconds", "jobs"):
        r.pop(k, None)
    for p in r["pairs"]:
        for k in ("step_ms", "step_over_bare"):
            p["metrics"].pop(k, None)
        for run in p["runs"]:
            for k in TIMING_FIELDS:
                run["summary"].pop(k, None)
    return r

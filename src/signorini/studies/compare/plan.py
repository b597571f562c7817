"""Planning ``signorini compare``: targets, levels, every run's dt checked, jobs and the memory estimate."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...dynamics.model.mass import DEFAULT_MASS
from ...dynamics.model.problem import (
    contact_node_count,
    friction_summary,
    run_friction,
    with_friction,
)
from ...dynamics.schemes.checks import check_friction_schemes
from ...dynamics.stepping.budget import CompareEstimate, estimate_compare, estimate_run
from ...dynamics.stepping.simulate import number_of_steps
from ...errors import InputError, check_positive
from ..benchmarks import STUDY_T, get_benchmark
from ..reference_study import DEFAULT_REFERENCE_FACTOR, Reference, check_levels
from .names import Pair, SchemeSpec
from .pool import Job, default_jobs

DEFAULT_RATIO = 0.5
DEFAULT_LEVELS = 3
DEFAULT_N0 = {1: 20, 2: 1, 3: 1}
DEFAULT_T = dict(STUDY_T)  # 1D: one period 3L/c of bar1d; 2D/3D: the first impact
CONTACT_NORM = {1: "stress", 2: "force", 3: "force"}  # contact error of errors_1d / relative_errors


@dataclass(frozen=True)
class BenchmarkTarget:
    """A registered benchmark with parameter overrides; levels are its ``n``."""

    name: str
    overrides: tuple[tuple[str, float], ...] = ()
    kind: str = "benchmark"
    friction: str | None = None  # --friction (e.g. "coulomb:0.3"), None: the benchmark's own

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
        return with_friction(self.bench.problem(level, self.params), self.friction)

    def control(self, scheme_label: str, mass: str) -> Any:
        """The time control of a pair's run: None (fixed; the paper's benchmarks keep their grids, as ``run``)."""
        return None


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
    friction: str | None = None  # --friction, None: the case file's
    #: ((scheme label, mass), control) of every pair: the control ``signorini run`` takes for the file with that
    #: scheme and mass (its ``[time] control``, else the energy control, else fixed where that cannot run)
    controls: tuple = ()

    def problem(self, level: int | None):
        return with_friction(self.load(), self.friction)

    def control(self, scheme_label: str, mass: str) -> Any:
        """The time control of the pair's run (:attr:`controls`; fixed for a pair not listed)."""
        return dict(self.controls).get((scheme_label, mass))


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
    friction: dict = field(default_factory=lambda: {"law": "frictionless"})  # the contact law of every run

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


def reference_mass(params: dict) -> str:
    """The default mass of a 2D/3D reference run: ``seed`` (the paper's) on linear cells; the default mass
    (``moment-preserving``) on quadratic cells, where ``seed`` is refused (it would leave interior mid-side
    nodes without mass)."""
    return "seed" if params.get("order", 1.0) == 1.0 else DEFAULT_MASS


def plan_benchmark(
    name: str,
    pairs: list[Pair],
    levels: int = DEFAULT_LEVELS,
    n0: int | None = None,
    T: float | None = None,
    ratio: float = DEFAULT_RATIO,
    overrides: dict | None = None,
    reference: tuple | Reference | None = None,
    friction: str | None = None,
    solver_options: dict | None = None,
) -> Plan:
    """Levels n0 2^k (k < levels), dt = ratio h; a 2D/3D reference (default CN + :func:`reference_mass`
    ``DEFAULT_REFERENCE_FACTOR`` x finer than the finest level); ``solver_options`` (the
    backend among them) for every run.  Raises InputError."""
    b = get_benchmark(name)
    b.require_nested("signorini compare", overrides)
    params = b.params(overrides)
    target = BenchmarkTarget(
        b.name, tuple(sorted((k, float(v)) for k, v in (overrides or {}).items())), friction=friction
    )
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
        scheme, mass, level = reference or (SchemeSpec("crank-nicolson"), None, DEFAULT_REFERENCE_FACTOR * ns[-1])
        mass = mass or reference_mass(params)
        check_levels(ns, level)
        _steps(ratio * b.h(level, params), T, f"reference level n = {level}")
        ref = (scheme, mass, level)
    problem = target.problem(ns[0])  # parameters, mesh and friction valid before anything runs
    _check_friction(problem, pairs)
    return Plan(
        target,
        list(pairs),
        ns,
        dts,
        T,
        ratio,
        hs,
        ref,
        tuple(sorted((solver_options or {}).items())),
        _length_scale(problem),
        friction=friction_summary(problem),
    )


def plan_case(target: CaseTarget, pairs: list[Pair], problem=None) -> Plan:
    """One level (the case file's mesh, dt and T), no errors."""
    if not pairs:
        raise InputError("nothing to compare: give at least one scheme and one mass")
    if not isinstance(target.dt, (int, float)):
        raise InputError(
            f"compare runs every pair with one time step; case file {target.label} gives a schedule "
            "([time] dt = [{until, dt}, ...]): give one dt for the comparison"
        )
    _steps(target.dt, target.T, f"case file {target.label}")
    problem = target.problem(None) if problem is None or target.friction else problem
    _check_friction(problem, pairs)
    m = problem.mesh
    counts = (m.n_nodes, m.n_cells, max(b.cells.shape[1] for b in m.blocks), m.dim, contact_node_count(problem))
    return Plan(
        target,
        list(pairs),
        [None],
        [target.dt],
        target.T,
        solver_options=target.solver_options,
        length_scale=_length_scale(problem),
        counts=counts,
        friction=friction_summary(problem),
    )


def _check_friction(problem, pairs: list[Pair]) -> None:
    """Refuse the comparison (InputError) only when no compared scheme carries the run's friction; a scheme that
    cannot is kept as "n/a: <its refusal>" by its own run, like a scheme that refuses a mass."""
    law, refusals = run_friction(problem), []
    for p in pairs:
        try:
            check_friction_schemes(law, [p.scheme.name])
        except InputError as exc:
            refusals.append(exc)
    if refusals and len(refusals) == len(pairs):
        raise refusals[0]


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
                    (i, k),
                    plan.target,
                    n,
                    pair.scheme,
                    pair.mass,
                    dt,
                    plan.T,
                    plan.solver_options,
                    snapshots=plan.has_errors,
                    exact_errors=plan.exact,
                    return_history=two_d,
                    keep_series=k == finest,
                    cost=_cost(plan.target, n, dt, plan.T),
                )
            )
    if isinstance(plan.reference, tuple):
        scheme, mass, level = plan.reference
        dt = plan.ratio * plan.target.bench.h(level, plan.target.params)
        jobs.append(
            Job(
                ("reference",),
                plan.target,
                level,
                scheme,
                mass,
                dt,
                plan.T,
                plan.solver_options,
                snapshots=True,
                return_history=True,
                cost=_cost(plan.target, level, dt, plan.T),
            )
        )
    return jobs


def estimate_plan(plan: Plan, jobs: int | None = None) -> CompareEstimate:
    """Peak memory of the whole matrix (:func:`~signorini.dynamics.stepping.budget.estimate_compare`):
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

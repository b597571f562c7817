"""Running the jobs of ``signorini compare``: one pure function per run, a process pool with a watchdog."""

from __future__ import annotations

import os
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from typing import Any

from ...dynamics.stepping.simulate import simulate
from ...errors import ConvergenceError, InputError
from .names import SchemeSpec

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
    "energy_max_relative_drift_undamped",
    "penetration_max",
    "penetration_time_integral",
    "oscillation_index",
    "impact_oscillation_indices",
    "impulse",
    "impact_impulses",
    "energy_identity_residual",
    "max_complementarity_residual",
    "warnings",
    "time_control",
    "spurious_energy",
    "setup_seconds",
    "loop_seconds",
    "step_seconds",
    "bare_solve_seconds",
    "bare_spmv_seconds",
    "counters",
)
TIMING_FIELDS = ("setup_seconds", "loop_seconds", "step_seconds", "bare_solve_seconds", "bare_spmv_seconds")


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
            control=job.target.control(job.scheme.label, job.mass),
        )
    except InputError as exc:
        return Outcome(job.key, "n/a", str(exc))
    except ConvergenceError as exc:
        return Outcome(job.key, "n/a", f"failed before the first step: {exc}")
    s = H.summary()
    out = Outcome(job.key, H.status, H.message, {k: s.get(k) for k in SUMMARY_FIELDS})
    out.summary["counters"] = dict(s["counters"])
    if H.status == "finished" and job.exact_errors:
        from ..study import errors_1d

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
        raise MemoryError(  # the environment's failure (exit 4), not a bug
            f"a worker process of compare died ({exc}): most likely the out-of-memory killer; rerun with --jobs 1"
        ) from None
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

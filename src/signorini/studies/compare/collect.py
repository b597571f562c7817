"""Collecting the runs of ``signorini compare``: errors against the reference, rates, per-pair metrics."""

from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np

from ...errors import ConvergenceError, InputError
from ..reference_study import Reference, relative_errors
from .names import Pair
from .plan import CONTACT_NORM, Plan, make_jobs
from .pool import Outcome, default_jobs, run_jobs
from .ranking import rank_result


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
        raise ConvergenceError(
            f"the reference run ({scheme.label} + {mass} at n = {level}) did not finish: "
            f"{outcome.status} ({outcome.reason})"
        )
    b = plan.target.bench
    p = plan.target.problem(level)
    return Reference(
        b.name, level, scheme.label, mass, outcome.history, p, b.h(level, plan.target.params), plan.target.params
    )


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
        "friction": plan.friction,
        "solver_options": dict(plan.solver_options),
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
        # the drift less the damping's work (physical dissipation is not the scheme's drift)
        "energy_drift": s.get("energy_max_relative_drift_undamped", s["energy_max_relative_drift"]),
        "oscillation_index": s["oscillation_index"],
        "penetration_max": s["penetration_max"],
        "mass_kept": (s.get("mass_effect") or {}).get("mass_ratio"),
        "untagged_penetration_max": s.get("untagged_penetration_max"),
        "changes_physics": bool((s.get("mass_effect") or {}).get("changes_physics")),
        "inertia_change": (s.get("mass_effect") or {}).get("inertia_change"),
        "energy_final": s["energy_final"],
        "step_ms": 1e3 * s["step_seconds"],
        "step_over_bare": s["step_seconds"] / bare if bare else None,
        "bare_op": ("solve" if s.get("bare_solve_seconds") else "SpMV") if bare else None,
        "time_control": (s.get("time_control") or {}).get("control", "fixed"),
        "warnings": list(s.get("warnings") or []),
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

"""The report of ``signorini compare``: setup and reference text, the table, compare.md and compare.json."""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

from ...dynamics.observe.history import _json_default, finite_json
from ..reference_study import DEFAULT_REFERENCE_FACTOR, describe_reference
from .pool import TIMING_FIELDS
from .ranking import RANK_LABELS, _finite, ranked_pairs


def _f(x, spec: str = ".3g") -> str:
    return format(float(x) + 0.0, spec) if _finite(x) else "n/a"  # + 0.0: no "-0"


def reference_text(result: dict) -> str:
    ref = result["reference"]
    if result["kind"] != "benchmark":
        return "Case file: one level, no error measurement (per-run diagnostics only)."
    if ref["kind"] == "exact":
        return "Errors against the exact solution."
    return f"Errors against the reference {describe_reference(ref)}."


def _law_value(v) -> str:
    """A contact law's parameter (a number), or the per-pair laws (a list of labels) of a run with pairs."""
    return f"{v:g}" if isinstance(v, int | float) else " ".join(v) if isinstance(v, list) else str(v)


def setup_text(result: dict) -> str:
    law = result.get("friction") or {"law": "frictionless"}
    friction = (
        ""
        if law["law"] == "frictionless"
        else (
            f"  Contact law: {law['law']} ({', '.join(f'{k} {_law_value(v)}' for k, v in law.items() if k != 'law')}) "
            "in every run."
        )
    )
    given = result.get("solver_options") or {}
    if given:
        friction += "  Solver: " + ", ".join(f"{k} = {v}" for k, v in sorted(given.items())) + " in every run."
    if result["kind"] != "benchmark":
        return (
            f"Case file `{result['target']}`: dt = {result['dt'][0]:.6g}, T = {result['T']:g}, fixed steps in "
            f"every run (a comparison is on one grid; `signorini run` takes dt as the largest step of its energy "
            f"control).{friction}"
        )
    levels = ", ".join(str(n) for n in result["levels"])
    return (
        f"Benchmark `{result['target']}`, levels n = {levels} (h = {result['h'][0]:.4g} .. {result['h'][-1]:.4g}, "
        f"dt = {result['ratio']:g} h), T = {result['T']:g}; diagnostics at the finest level n = {result['levels'][-1]}."
        + friction
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
            cells += [
                _f(m.get("error_u"), ".3e"),
                _f(r.get("u_H1"), ".2f"),
                _f(m.get("error_v"), ".3e"),
                _f(r.get("v_L2"), ".2f"),
            ]
        drift = _f(m["energy_drift"], ".2e") if _finite(m["energy_drift"]) else "n/a (E0 = 0)"
        bare = f"{m['step_over_bare']:.2f} x {m['bare_op']}" if _finite(m["step_over_bare"]) else "n/a (not measured)"
        decided = RANK_LABELS.get(p["decided_by"], p["decided_by"] or "(last)")
        kept = f"{100 * m['mass_kept']:.4g}%" if _finite(m.get("mass_kept")) else "n/a"
        untagged = m.get("untagged_penetration_max") or 0.0
        warned = m.get("warnings") or []
        notes = (
            p["reason"],
            f"{m['time_control']} steps" if m.get("time_control", "fixed") != "fixed" else "",
            f"{len(warned)} warning(s), in the section Warnings" if warned else "",
            "the mass changes the body's inertia" if m.get("changes_physics") else "",
            f"untagged boundary nodes {untagged:.3g} inside the obstacle"
            if m.get("violates_contact") and untagged
            else "",
        )
        note = "; ".join(x for x in notes if x)
        cells += [
            drift,
            _f(m["oscillation_index"], ".3f"),
            _f(m["penetration_max"], ".2e"),
            kept,
            _f(m["step_ms"], ".3g"),
            bare,
            decided,
            note or "-",
        ]
        lines.append("| " + " | ".join(_cell(c) for c in cells) + " |")
    return lines


def _cell(text: str) -> str:
    return str(text).replace("|", "/").replace("\n", " ")


COLUMN_NOTES = (
    "Columns: errors are relative, at the finest level (u in L2(0,T; H1), v in L2(0,T; L2)); rates are the "
    "least-squares slopes of log(error) against log(h) over the levels (n/a with fewer than two levels); energy "
    "drift = max_n |E^n - E^0| / |E^0| with the scheme's own energy (summary.json `energy_definition`), less the "
    "damping's work when the run is damped (`energy_max_relative_drift_undamped`: physical dissipation is not "
    "drift); oscillation "
    "index of the first impact (1 = one monotone rise and fall of the total contact force, 0 = no contact); max "
    "penetration = max over levels and contact nodes of max(0, -gap); ms / step = loop time per step at the finest "
    "level (contact columns computed lazily are set-up work, left out), and its ratio to one bare solve with the "
    "same factor (SpMV for CG); decided by = the first ranking key "
    "that separates the pair from the next one.  A case file's pair runs with the time control `signorini run` "
    "takes for the file with that scheme and mass (its `[time] control`, else the energy control, else the steps "
    "asked for; the note says `energy steps`); what a run warned of is listed under Warnings."
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
    warned = [(p["label"], w) for p in ranked_pairs(result) if p["available"] for w in p["metrics"].get("warnings", [])]
    if warned:  # what each run warned of, as `signorini run` prints it
        lines += ["## Warnings", ""] + [f"- {label}: {w}" for label, w in warned] + [""]
    if figures:
        lines += ["## Figures", ""]
        for name, caption in figures:
            lines += [f"![{caption}]({name})", "", f"*{caption}* (`{name}`, numbers in `{Path(name).stem}.csv`)", ""]
    return "\n".join(lines)


def write_report(result: dict, series: dict, out: Path) -> dict:
    """compare.md, compare.json and the figures with their CSVs into ``out`` (existing)."""
    import matplotlib

    matplotlib.use("Agg")
    from .. import plots

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

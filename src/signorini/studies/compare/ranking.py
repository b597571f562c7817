"""The ranking rule of ``signorini compare`` (see the package docstring)."""

from __future__ import annotations

import math

# (metric, relative tolerance, absolute tolerance, where the absolute one is x the length scale)
RANK_KEYS = (
    ("violates_contact", 0.0, 0.0, False),
    ("changes_body", 0.0, 0.0, False),
    ("error_u", 0.10, 0.0, False),
    ("energy_drift", 0.10, 1e-9, False),
    ("oscillation_index", 0.0, 0.05, False),
    ("penetration_max", 0.10, 1e-12, True),
)
#: a penetration (contact or untagged boundary nodes) above this x the body's size violates
#: the contact constraint: such a run ranks below every run that respects it
CONTACT_TOLERANCE = 1e-6
#: a mass variant that keeps less (or more) than 1 -+ this of the body's mass, or changes
#: its inertia tensor by more than INERTIA_BOUND, models another body: its runs rank below
#: every run within both bounds (the paper's bar, where ``seed`` removes 1 layer of 80
#: cells, 1.25% of the mass, keeps its ranking; a whole-skin bracket where it keeps 32.8%
#: does not)
MASS_BOUND, INERTIA_BOUND = 0.05, 0.10
RANK_LABELS = {
    "violates_contact": "penetration beyond the contact tolerance",
    "changes_body": "mass variant that changes the body (mass > 5% or inertia > 10%)",
    "error_u": "error",
    "energy_drift": "energy drift",
    "oscillation_index": "oscillation index",
    "penetration_max": "penetration",
}
RANKING_RULE = (
    "First, a run whose contact or untagged boundary nodes penetrate the obstacle by more than 1e-6 x the body's size "
    "violates the constraint and ranks below every run that respects it. Next, a run whose mass variant changes the "
    "body (keeps less than 95% or more than 105% of its mass, or changes its inertia tensor by more than 10%: "
    "summary.json mass_effect) ranks below every run whose mass models the body. Then lexicographic with tolerance "
    "bands: "
    "sort by the error of u in L2(0,T; H1) at the finest level; pairs within "
    "10% of the best error of their band are tied and ordered by the energy drift max|E - E0|/E0, less the damping's "
    "work when the run is damped (tied within 10% or both below 1e-9), then by the oscillation index of the first "
    "impact (tied within 0.05), then by the maximum "
    "penetration (tied within 10% or both below 1e-12 x the body's size); pairs tied on every key share a rank and "
    "n/a sorts last. Accuracy comes first because it is the only figure measured against the solution itself; the "
    "diagnostics only separate pairs that are equally accurate. A rank sum was rejected: it weighs a round-off "
    "penetration difference like a factor 10 in the error and changes when a pair is added. The time per step is "
    "shown but not ranked (it depends on the machine and its load, so the ranking would not be reproducible)."
)
RANKING_RULE_CASE = (
    "Case file (one level, no error): the same rule without the error key, i.e. runs that penetrate the obstacle "
    "by more than 1e-6 x the body's size (contact or untagged boundary nodes) last, then the runs whose mass changes "
    "the body (mass outside 95-105% or inertia changed by more than 10%), then lexicographic with "
    "tolerance bands on "
    "the energy drift max|E - E0|/E0, less the damping's work when damped (tied within 10% or both below 1e-9), the "
    "oscillation index of the first impact "
    "(tied within 0.05) and the maximum penetration (tied within 10% or both below 1e-12 x the body's size); ties "
    "share a rank, n/a sorts last, the time per step is shown but not ranked."
)


def changes_body(metrics: dict) -> bool:
    """Whether a run's mass variant models another body (:data:`MASS_BOUND`, :data:`INERTIA_BOUND`)."""
    kept, inertia = metrics.get("mass_kept"), metrics.get("inertia_change")
    return bool((_finite(kept) and abs(kept - 1.0) > MASS_BOUND) or (_finite(inertia) and inertia > INERTIA_BOUND))


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
        m["changes_body"] = float(changes_body(m))
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

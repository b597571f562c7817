"""``signorini reproduce``: the seed paper's study as a self-contained report.

Contents (all numbers computed in the run; times and lengths come from the benchmarks'
parameters or from the computed histories, never from literals):

1. 1D exact benchmark ``bar1d`` over one period 3L/c: errors and observed rates for
   CN/BE with the standard, ``seed`` and ``moment-preserving`` masses (spec 3.3).
2. 2D bar: contact-node histories and energies for CN/BE x standard/``seed``
   (paper Fig. 1, 2, 6, 7), the oscillation index of the contact force (see
   :func:`oscillation_index`: 1 for one monotone rise and fall) and the energy drift.
3. 2D bar convergence of the four pairs against one shared reference run (CN + ``seed``
   at least 4x finer in h and dt than the finest level), the same rates against
   references of other fineness, and whether they agree (paper Fig. 2, 3, 7, 8).
   3b: the same for the 3D bar (CN, both masses).
4. 3D bar: von Mises stress on the face x = 0 at several times, standard (Fig. 4) vs
   ``seed`` (Fig. 5) on one colour scale.
5. Beyond the paper: more redistributed masses and Paoli-Schatzman on ``bar1d``.
6. ``signorini compare`` (:mod:`signorini.studies.compare`): CN, BE, generalized-alpha
   (rho_inf = 0.5) and Paoli-Schatzman x standard/``seed``, ranked, on ``bar1d-impact``
   (exact solution) and on the 2D bar (section 3's reference).

The figure files are named after the paper's figures (``plots.PAPER_FIGURES``), and the
report starts with the mapping.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from ..dynamics.observe.diagnostics import impact_windows, oscillation_index  # noqa: F401 (re-exported)
from ..dynamics.observe.history import _json_default, finite_json
from ..dynamics.stepping.simulate import simulate
from ..signals import interrupts_raise
from .benchmarks import get_benchmark
from .reference_study import (
    DEFAULT_REFERENCE_FACTOR,
    convergence_study,
    rate_comparison,
    rate_rows,
    rate_trend,
    reference_levels,
    reference_run,
)
from .study import errors_1d, observed_rates

PAIRS = [
    ("crank-nicolson", "standard"),
    ("crank-nicolson", "seed"),
    ("backward-euler", "standard"),
    ("backward-euler", "seed"),
]
# levels*: nested refinement levels; ref*: the shared reference level (>= 4x the finest
# level); checks*: further reference levels the rates are recomputed against.
# T2d: length of the 2D histories (two impacts); Tconv: horizon of the convergence
# studies (first impact and release); T3d: horizon of the von Mises snapshots;
# Tcmp1d: horizon of the bar1d-impact comparison (first impact and release).
SIZES = {
    "tiny": {
        "hertz2d": [4],
        "hertz3d": [2],
        "levels1d": [10, 20, 40],
        "n2d": 2,
        "T2d": 4.0,
        "Tconv": 1.0,
        "levels2d": [1, 2],
        "ref2d": 8,
        "checks2d": [4],
        "n3d": 1,
        "T3d": 1.2,
        "levels3d": [1],
        "ref3d": 4,
        "checks3d": [2],
        "ratio": 0.5,
        "Tcmp1d": 1.2,
    },
    "quick": {
        "hertz2d": [4, 8],
        "hertz3d": [2],
        "levels1d": [20, 40, 80, 160],
        "n2d": 8,
        "T2d": 4.0,
        "Tconv": 1.0,
        "levels2d": [1, 2, 4, 8],
        "ref2d": 32,
        "checks2d": [8, 16],
        "n3d": 4,
        "T3d": 1.2,
        "levels3d": [1, 2],
        "ref3d": 8,
        "checks3d": [4],
        "ratio": 0.5,
        "Tcmp1d": 1.2,
    },
    "full": {
        "hertz2d": [4, 8, 16],
        "hertz3d": [2, 3, 4],
        "levels1d": [20, 40, 80, 160, 320, 640],
        "n2d": 16,
        "T2d": 4.0,
        "Tconv": 1.0,
        "levels2d": [1, 2, 4, 8, 16],
        "ref2d": 64,
        "checks2d": [16, 32],
        "n3d": 8,
        "T3d": 1.2,
        "levels3d": [1, 2],
        "ref3d": 8,
        "checks3d": [4],
        "ratio": 0.5,
        "Tcmp1d": 1.2,
    },
}
AGREE_TOL = 0.1  # rates against two references "agree" when they differ by at most this
SNAPSHOTS_3D = 12  # von Mises snapshots after t = 0 (intervals of T3d / SNAPSHOTS_3D)

CONV_COLUMNS_2D = [
    ("u_H1", "u L2(H1)"),
    ("v_L2", "v L2(L2)"),
    ("v_Linf", "v Linf(L2)"),
    ("force", "force L2"),
    ("energy_L2", "energy L2"),
    ("energy_Linf", "energy Linf"),
]
CONV_COLUMNS_3D = [("u_H1", "u L2(H1)"), ("v_L2", "v L2(L2)"), ("force", "force L2"), ("energy_Linf", "energy Linf")]
RATE_CHECK_NORMS = ("u_H1", "force", "energy_L2")


def fmt(x, spec: str = ".4f") -> str:
    """``format(x, spec)``, or "n/a" for a missing or non-finite value."""
    if x is None:
        return "n/a"
    try:
        xf = float(x)
    except (TypeError, ValueError):
        return str(x)
    return format(xf, spec) if np.isfinite(xf) else "n/a"


def fmt_rates(values, spec: str = ".2f") -> str:
    return "/".join(fmt(v, spec) for v in values) if len(values) else "n/a (one level)"


def mean_rate(values) -> float:
    """Mean of the observed rates; nan (printed n/a) if there is none or one is undefined."""
    v = np.asarray(values, float)
    return float(v.mean()) if v.size and np.all(np.isfinite(v)) else float("nan")


def convergence_table(conv: dict, columns: list[tuple[str, str]]) -> list[str]:
    """Markdown rows: one line per (scheme/mass, level) with the chosen error columns."""
    lines = ["| scheme / mass | n | " + " | ".join(h for _, h in columns) + " |", "|---" * (len(columns) + 2) + "|"]
    for name, c in conv.items():
        for r in c["rows"]:
            lines.append(f"| {name} | {r['n']} | " + " | ".join(fmt(r[k]) for k, _ in columns) + " |")
    return lines


def _first_impact(force: np.ndarray, separation: int = 20) -> tuple[int, int] | None:
    """First and last level with a non-zero force in the first impact (see oscillation_index)."""
    windows = impact_windows(force, separation)
    return windows[0] if windows else None


def first_impact_times(H, separation: int = 20) -> tuple[float, float]:
    """Times of the first and last non-zero total contact force of the first impact (nan if none)."""
    window = _first_impact(H.lambda_sum, separation)
    return (float(H.t[window[0]]), float(H.t[window[1]])) if window else (float("nan"), float("nan"))


def first_contact_time(H) -> float:
    """Time of the first level at which a contact node reaches the obstacle (gap <= tol).

    tol is 1e-9 of the largest initial gap; nan if the obstacle is never reached.
    """
    tol = 1e-9 * max(float(np.abs(H.gap[0]).max()), 1e-300)
    idx = np.flatnonzero(H.gap.min(axis=1) <= tol)
    return float(H.t[idx[0]]) if idx.size else float("nan")


def period_1d(bench) -> float:
    """One period 3L/c of the 1D clamped bar ``bar1d`` (spec 3.1), from its parameters."""
    p = bench.params()
    return 3.0 * p["L"] / float(np.sqrt(p["E"] / p["rho"]))


def _case_1d(b, ex, scheme: str, mass: str, n: int, T: float, ratio: float, cache: dict | None) -> dict:
    """Errors (:func:`errors_1d`), E(T) and max |E - E0|/E0 of one ``bar1d`` run (memoized)."""
    key = (scheme, mass, n, T, ratio)
    if cache is not None and key in cache:
        return cache[key]
    p = b.problem(n)
    H = simulate(p, scheme, ratio * b.h(n), T, mass=mass, snapshot_every=1)
    out = {
        **errors_1d(H, p, ex),
        "E_T": float(H.energy[-1]),
        "drift": float(np.max(np.abs(H.energy - ex.energy0)) / ex.energy0),
    }
    if cache is not None:
        cache[key] = out
    return out


def study_1d(levels: list[int], T: float | None = None, ratio: float = 0.5, cache: dict | None = None) -> list[dict]:
    b = get_benchmark("bar1d")
    T = period_1d(b) if T is None else T
    ex = b.exact(b.params(), T)
    out = []
    for scheme, mass in [
        ("crank-nicolson", "standard"),
        ("crank-nicolson", "seed"),
        ("crank-nicolson", "moment-preserving"),
        ("backward-euler", "standard"),
        ("backward-euler", "seed"),
    ]:
        rows = []
        for n in levels:
            e = _case_1d(b, ex, scheme, mass, n, T, ratio, cache)
            rows.append({"n": n, **{k: v for k, v in e.items() if k != "drift"}})
        hs = [b.h(r["n"]) for r in rows]
        rates = {k: observed_rates([r[k] for r in rows], hs) for k in ("u_H1", "u_L2", "v_L2", "stress")}
        out.append({"scheme": scheme, "mass": mass, "rows": rows, "rates": rates})
    return out


def study_beyond(
    levels: list[int], T: float | None = None, ratio: float = 0.5, cache: dict | None = None
) -> list[dict]:
    """CN with every redistributed mass, and Paoli-Schatzman (e = 0) with the standard
    mass, on ``bar1d``: H1 and stress errors per level, rates, energy drift.

    Paoli-Schatzman's displacement is defined at the time levels like the others', so
    its H1 error is measured the same way (its stored velocity is the backward
    difference (U^n - U^{n-1})/dt and its energy the half-step energy, see
    docs/schemes.md)."""
    b = get_benchmark("bar1d")
    T = period_1d(b) if T is None else T
    ex = b.exact(b.params(), T)
    out = []
    cases = [
        (f"crank-nicolson / {m}", "crank-nicolson", m)
        for m in ("seed", "seed-normal", "moment-preserving", "neighbour", "mass-free-surface")
    ]
    cases.append(("paoli-schatzman / standard", "paoli-schatzman", "standard"))
    for label, scheme, mass in cases:
        h1, st, drift = [], [], 0.0
        for n in levels:
            e = _case_1d(b, ex, scheme, mass, n, T, ratio, cache)
            h1.append(e["u_H1"])
            st.append(e["stress"])
            drift = e["drift"]
        hs = [b.h(n) for n in levels]
        out.append(
            {
                "label": label,
                "levels": levels,
                "u_H1": h1,
                "stress": st,
                "energy_drift": drift,
                "rate_u_H1": observed_rates(h1, hs),
                "rate_stress": observed_rates(st, hs),
            }
        )
    return out


def table_start(title: str, columns: list[str], intro: tuple[str, ...] = ()) -> list[str]:
    """A report section's heading, optional intro lines and the header of its table."""
    lines = [f"## {title}", ""]
    for text in intro:
        lines += [text, ""]
    return lines + ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]


def figure_md(number: int) -> list[str]:
    """The markdown image of paper figure ``number`` with its caption."""
    from .plots import PAPER_FIGURES

    name, text = PAPER_FIGURES[number]
    return [f"![Paper Fig. {number}]({name}.png)", "", f"*Paper Fig. {number}* (`{name}.png`): {text}.", ""]


def _header(size: str, cfg: dict) -> list[str]:
    from .plots import PAPER_FIGURES

    p1, p2 = get_benchmark("bar1d").params(), get_benchmark("bar2d").params()
    lines = [
        "# signorini: reproduction of the mass redistribution study",
        "",
        f"Size: `{size}`. Every number below is computed by `signorini reproduce --{size}`. "
        f"The benchmarks are nondimensional (2D/3D: rho = {p2['rho']:g}, Lame parameters lambda = "
        f"{p2['lam']:g}, mu = {p2['mu']:g}, bar length {p2['length']:g}, width {p2['width']:g}; "
        f"1D: E = {p1['E']:g}, rho = {p1['rho']:g}, L = {p1['L']:g}), so times, lengths, forces and "
        "energies carry no units.",
        "",
        "## Paper figures in this report",
        "",
        "| paper figure | file | content |",
        "|---|---|---|",
    ]
    for number, (name, text) in PAPER_FIGURES.items():
        lines.append(f"| Fig. {number} | `{name}.png` (+ `{name}.csv`) | {text} |")
    return lines + [
        "",
        "Every figure's title starts with the paper figure it stands for; the CSV next to "
        "it holds the plotted numbers.",
        "",
    ]


def section_1d(cfg: dict, out: Path, summary: dict, ctx: dict) -> list[str]:
    """1. The 1D exact benchmark: errors and rates for CN/BE with three masses."""
    b = get_benchmark("bar1d")
    T = period_1d(b)
    ratio = cfg["ratio"]
    ex = b.exact(b.params(), T)
    s1 = study_1d(cfg["levels1d"], T, ratio, ctx.setdefault("runs1d", {}))
    summary["bar1d"] = s1
    p = b.params()
    md = table_start(
        f"1. 1D clamped bar against the exact solution (T = 3L/c = {T:g}, one period; dt = {ratio:g} h)",
        ["scheme", "mass", "n", "H1 u", "L2 u", "L2 v", "stress", f"E(T) (exact {ex.energy0:.4g})"],
        (
            "No paper figure (the seed's 1D results are in its reference [2]); spec 3.3's table. "
            f"Exact energy E g^2/(2L) = {ex.energy0:.4g} with L = {p['L']:g}, E = {p['E']:g}, "
            f"gap = {p['gap']:g}.",
        ),
    )
    for s in s1:
        for r in s["rows"]:
            md.append(
                f"| {s['scheme']} | {s['mass']} | {r['n']} | {fmt(r['u_H1'])} | {fmt(r['u_L2'])} | "
                f"{fmt(r['v_L2'])} | {fmt(r['stress'])} | {fmt(r['E_T'])} |"
            )
    md += ["", "Observed rates (successive levels):", ""]
    for s in s1:
        rr = ", ".join(f"{k} {fmt_rates(vals)}" for k, vals in s["rates"].items())
        md.append(f"- {s['scheme']} + {s['mass']}: {rr}")
    md.append("")
    return md


def _history_stats(H) -> dict:
    E = H.energy
    return {
        "oscillation_index": oscillation_index(H.t, H.lambda_sum),
        "energy_initial": float(E[0]),
        "energy_final": float(E[-1]),
        "energy_ratio_final": float(E[-1] / E[0]),
        "energy_max_ratio": float(E.max() / E[0]),
        "energy_max_drift": float(np.max(np.abs(E - E[0])) / E[0]),
        "first_contact_time": first_contact_time(H),
        "impacts": H.impacts,
        "max_complementarity_residual": float(H.residual.max()),
    }


def section_2d_histories(cfg: dict, out: Path, summary: dict, ctx: dict) -> list[str]:
    """2. The 2D bar's contact and energy histories for the four scheme/mass pairs (Fig. 1, 6)."""
    from . import plots

    b2 = get_benchmark("bar2d")
    n2, ratio = cfg["n2d"], cfg["ratio"]
    p = b2.params()
    runs = {
        (scheme, mass): simulate(b2.problem(n2), scheme, ratio * b2.h(n2), cfg["T2d"], mass=mass)
        for scheme, mass in PAIRS
    }
    ctx["runs2d"] = runs
    hist = {f"{scheme}/{mass}": _history_stats(H) for (scheme, mass), H in runs.items()}
    summary["bar2d_histories"] = hist
    figs = {}
    for scheme, number in (("crank-nicolson", 1), ("backward-euler", 6)):
        name = plots.PAPER_FIGURES[number][0]
        pair = {m: runs[(scheme, m)] for m in ("standard", "seed")}
        figs[name] = plots.contact_figure(pair, scheme, number, out / f"{name}.png", out / f"{name}.csv")
    summary["bar2d_contact_figures"] = figs
    H0 = runs[PAIRS[0]]
    nodes = next(iter(figs.values()))["nodes"]
    weights = ", ".join(f"{H0.weights[i]:.4g} (x = {H0.coordinates[i, 0]:.4g})" for i in nodes)
    t_free = p["gap"] / p["velocity"] if p["velocity"] > 0 else float("nan")
    t_wave = p["length"] / b2.wave_speed()
    mesh = b2.problem(n2).mesh
    cells = "x".join(str(g.size - 1) for g in mesh.grid)
    md = table_start(
        f"2. 2D bar, n = {n2} ({cells} Q1), dt = {ratio:g} h, T = {cfg['T2d']:g} (paper Fig. 1, 2, 6, 7)",
        [
            "scheme / mass",
            "oscillation index",
            "E(T)/E(0)",
            "max E/E(0)",
            "max abs(E - E(0))/E(0)",
            "first contact t",
            "impacts",
        ],
        (
            f"Free flight predicts the first contact at gap/velocity = {p['gap']:g}/{p['velocity']:g} = "
            f"{t_free:.4g} (before the clamp's wave reaches the contact face at length/c_p = "
            f"{t_wave:.4g}); the table gives the first time level with a zero gap.",
        ),
    )
    for k, v in hist.items():
        md.append(
            f"| {k} | {fmt(v['oscillation_index'], '.2f')} | {fmt(v['energy_ratio_final'])} | "
            f"{fmt(v['energy_max_ratio'])} | {fmt(v['energy_max_drift'], '.2e')} | "
            f"{fmt(v['first_contact_time'])} | {v['impacts']} |"
        )
    md += [
        "",
        "Oscillation index = total variation of the total contact force over the first impact "
        "/ (2 x its peak): 1 for one monotone rise and fall, 1 + a for an extra dip of a x peak.",
        "",
        "Contact nodes plotted: from the corner to the centre of the contact face (the bar is symmetric "
        f"about its axis); their contact-area weights are {weights}, so the corner node carries "
        "a smaller share of the force.",
        "",
        *figure_md(1),
        *figure_md(6),
    ]
    return md


def _rates_block(conv: dict, title: str, check_title: str, summary: dict, key: str) -> list[str]:
    """Observed rates of every study, then the rates-vs-reference table (agreement into summary[key])."""
    md = ["", title, ""]
    for k, c in conv.items():
        md.append(f"- {k}: " + ", ".join(f"{m} {fmt_rates(r)}" for m, r in c["rates"].items()))
    lines, summary[key] = _rate_check_lines(conv)
    return md + ["", check_title, ""] + lines + _rate_check_text(summary[key])


def _rate_check_lines(conv: dict) -> tuple[list[str], dict]:
    """The rate-vs-reference table and the agreement statements of a set of studies."""
    refs = reference_levels(conv.values())
    lines = [
        "| scheme / mass | norm | levels | " + " | ".join(f"ref n = {r}" for r in refs) + " |",
        "|---" * (len(refs) + 3) + "|",
    ]
    agreement = {}
    for name, c in conv.items():
        lines += [f"| {name} | {row} |" for row in rate_rows(c, RATE_CHECK_NORMS, refs, "n/a (not finer)")]
        agreement[name] = rate_comparison(c, RATE_CHECK_NORMS)
    if len(lines) == 2:
        return ["n/a: a single level has no rate to compare."], agreement
    statements = []
    for name, comps in agreement.items():
        parts = []
        for cmp_ in comps:
            f, g = cmp_["factors"]
            verdict = "agree" if cmp_["max_diff"] <= AGREE_TOL else "do NOT agree"
            pr, k, a, bb = cmp_["worst"]
            parts.append(
                f"{f:g}x vs {g:g}x: {verdict}, max |difference| {cmp_['max_diff']:.2f} over {cmp_['count']} rates "
                f"(largest: {k} {pr[0]}->{pr[1]}, {a:.2f} vs {bb:.2f})"
            )
        tr = rate_trend(conv[name], RATE_CHECK_NORMS)
        total = sum(tr.values())
        if total:
            parts.append(
                f"as the reference gets finer the rate falls in {tr['falls']}, rises in {tr['rises']} and "
                f"moves both ways in {tr['mixed']} of {total} (level pair, norm) cases"
            )
        statements.append(f"- {name}: " + ("; ".join(parts) if parts else "n/a (only one reference per level pair)"))
    return lines + [""] + statements, agreement


def _reference_intro(c: dict, T: float) -> str:
    checks = ", ".join(f"n = {blk['reference']['level']}" for blk in c["checks"]) or "none"
    return (
        f"Reference: {c['reference']['description']} (T = {T:g}), shared by every scheme/mass pair. "
        f"Rates recomputed against further CN + seed references at {checks}."
    )


def _rate_check_text(agreement: dict) -> list[str]:
    verdicts = [cmp_ for comps in agreement.values() for cmp_ in comps]
    fine = [c for c in verdicts if c["factors"][0] >= DEFAULT_REFERENCE_FACTOR]
    coarse = [c for c in verdicts if c["factors"][0] < DEFAULT_REFERENCE_FACTOR]
    if not verdicts:
        return [""]
    out = [
        "",
        f"How to read it: a rate between levels n and 2n measured against a reference r is listed with "
        f"r/2n (how many times finer the reference is than level 2n). Rates against two references "
        f"are said to agree when they differ by at most {AGREE_TOL:g}.",
    ]
    if fine:
        worst = max(c["max_diff"] for c in fine)
        verdict = (
            "they agree"
            if worst <= AGREE_TOL
            else "they do NOT all agree: those rates still depend on the reference; where they fall as the "
            "reference gets finer, the rates against the finest reference are the least biased, and if the "
            "trend continues they still overestimate"
        )
        out.append(
            f"References at least {DEFAULT_REFERENCE_FACTOR}x finer vs twice as fine again: max |rate "
            f"difference| {worst:.2f} over all pairs and norms above ({verdict})."
        )
    if coarse:
        worst = max(c["max_diff"] for c in coarse)
        out.append(
            f"References only 2x finer vs 4x: max |rate difference| {worst:.2f} "
            f"({'agree' if worst <= AGREE_TOL else 'a 2x reference biases the rates'})."
        )
    return out + [""]


def section_2d_convergence(cfg: dict, out: Path, summary: dict, ctx: dict) -> list[str]:
    """3. 2D convergence of the four pairs against one shared CN + seed reference (Fig. 2, 3, 7, 8)."""
    from . import plots

    T, ratio, levels = cfg["Tconv"], cfg["ratio"], cfg["levels2d"]
    ref = reference_run("bar2d", cfg["ref2d"], "crank-nicolson", "seed", T, ratio)
    checks = [reference_run("bar2d", r, "crank-nicolson", "seed", T, ratio) for r in cfg["checks2d"]]
    conv = {
        f"{scheme}/{mass}": convergence_study(
            "bar2d", scheme, mass, levels, T=T, ratio=ratio, reference=ref, check_references=checks
        )
        for scheme, mass in PAIRS
    }
    ctx["ref2d"] = ref  # shared with the scheme comparison (section 6), released there
    del ref, checks
    summary["bar2d_convergence"] = conv
    runs = ctx["runs2d"]
    for scheme, (fe, fc) in (("crank-nicolson", (2, 3)), ("backward-euler", (7, 8))):
        pair_conv = {m: conv[f"{scheme}/{m}"] for m in ("standard", "seed")}
        pair_runs = {m: runs[(scheme, m)] for m in ("standard", "seed")}
        ne, nc = plots.PAPER_FIGURES[fe][0], plots.PAPER_FIGURES[fc][0]
        plots.energy_figure(pair_runs, pair_conv, scheme, fe, out / f"{ne}.png", out / f"{ne}.csv")
        plots.convergence_figure(pair_conv, scheme, fc, out / f"{nc}.png", out / f"{nc}.csv")
    first = next(iter(conv.values()))
    t_on, t_off = first_impact_times(runs[("crank-nicolson", "seed")])
    md = [f"## 3. 2D convergence, T = {T:g}, dt = {ratio:g} h (paper Fig. 2, 3, 7, 8)", ""]
    md += [
        _reference_intro(first, T),
        "",
        f"The horizon T = {T:g} covers the first impact: in the CN + seed history of section 2 the total "
        f"contact force is non-zero from t = {fmt(t_on)} to t = {fmt(t_off)}"
        + ("." if t_off < T else " (the impact is not over at T)."),
        "",
    ]
    md += convergence_table(conv, CONV_COLUMNS_2D)
    md += _rates_block(
        conv,
        "Observed rates (successive levels, against the reference above):",
        "### Do the rates depend on the reference?",
        summary,
        "bar2d_rate_agreement",
    )
    md += [*figure_md(2), *figure_md(3), *figure_md(7), *figure_md(8)]
    return md


def section_3d_convergence(cfg: dict, out: Path, summary: dict, ctx: dict) -> list[str]:
    """3b. 3D convergence (CN, both masses) against a shared CN + seed reference."""
    T, ratio = cfg["Tconv"], cfg["ratio"]
    ref3 = reference_run("bar3d", cfg["ref3d"], "crank-nicolson", "seed", T, ratio)
    checks = [reference_run("bar3d", r, "crank-nicolson", "seed", T, ratio) for r in cfg["checks3d"]]
    conv3 = {
        f"crank-nicolson/{m}": convergence_study(
            "bar3d", "crank-nicolson", m, cfg["levels3d"], T=T, ratio=ratio, reference=ref3, check_references=checks
        )
        for m in ("standard", "seed")
    }
    del ref3, checks
    summary["bar3d_convergence"] = conv3
    first = next(iter(conv3.values()))
    md = [f"## 3b. 3D convergence, T = {T:g}, dt = {ratio:g} h (no paper figure)", "", _reference_intro(first, T), ""]
    md += convergence_table(conv3, CONV_COLUMNS_3D)
    return md + _rates_block(
        conv3, "Observed rates:", "Rates against references of different fineness:", summary, "bar3d_rate_agreement"
    )


def section_3d_von_mises(cfg: dict, out: Path, summary: dict, ctx: dict) -> list[str]:
    """4. The 3D bar's von Mises stress on the face x = 0, standard vs seed (Fig. 4, 5)."""
    from . import plots

    b3 = get_benchmark("bar3d")
    p = b3.params()
    n3, ratio = cfg["n3d"], cfg["ratio"]
    dt3 = ratio * b3.h(n3)
    every = max(1, int(round(cfg["T3d"] / SNAPSHOTS_3D / dt3)))
    runs3 = {}
    for mass in ("standard", "seed"):
        p3 = b3.problem(n3)
        runs3[mass] = (p3, simulate(p3, "crank-nicolson", dt3, cfg["T3d"], mass=mass, snapshot_every=every))
    t_contact = min(first_contact_time(H) for _, H in runs3.values())
    layer = p["width"]
    figures = {m: (k, out / f"{plots.PAPER_FIGURES[k][0]}.png") for m, k in (("standard", 4), ("seed", 5))}
    vm = plots.von_mises_figures(runs3, figures, t_contact, layer)
    vm.update({"first_contact_time": t_contact, "near_contact_layer": layer})
    summary["bar3d_von_mises"] = vm
    md = table_start(
        f"4. 3D bar, n = {n3}, CN, dt = {ratio:g} h: von Mises stress on the face x = 0 (paper Fig. 4, 5)",
        ["mass", "max von Mises near contact after first contact", "roughness (mean abs jump along z)"],
        (
            f"Near contact = within one bar width (width = {layer:g}) of the contact face; after first "
            f"contact = snapshots at t >= {t_contact:.4g} (first time level with a zero gap in these runs; "
            f"with the seed mass the first impact lasts until t = {fmt(first_impact_times(runs3['seed'][1])[1])}, "
            f"T = {cfg['T3d']:g}). "
            "Roughness = mean over those snapshots of the mean |jump| between successive node rows of the "
            f"width-averaged stress. Both figures share the colour scale [0, {vm['clim'][1]:.4g}] "
            "(the largest value of both runs).",
        ),
    )
    for mass, v in vm["masses"].items():
        md.append(f"| {mass} | {fmt(v['max_near_contact'])} | {fmt(v['roughness'])} |")
    return md + ["", *figure_md(4), *figure_md(5)]


def section_beyond(cfg: dict, out: Path, summary: dict, ctx: dict) -> list[str]:
    """5. Beyond the paper: more redistributions and Paoli-Schatzman on the 1D benchmark."""
    b = get_benchmark("bar1d")
    T, ratio = period_1d(b), cfg["ratio"]
    beyond = study_beyond(cfg["levels1d"], T, ratio, ctx.setdefault("runs1d", {}))
    summary["bar1d_beyond"] = beyond
    md = table_start(
        "5. Beyond the paper: mass variants and Paoli-Schatzman on the 1D exact benchmark",
        ["scheme / mass", "H1 u", "rate", "stress", "rate", "max abs(E - E0)/E0"],
        (
            f"Relative L2(0,T) errors at the finest level n = {cfg['levels1d'][-1]} (T = {T:g}, "
            f"dt = {ratio:g} h) and mean observed rates over the levels {cfg['levels1d']}. "
            "Paoli-Schatzman's energy is its half-step energy E^(n-1/2).",
        ),
    )
    for r in beyond:
        md.append(
            f"| {r['label']} | {fmt(r['u_H1'][-1])} | {fmt(mean_rate(r['rate_u_H1']), '.2f')} | "
            f"{fmt(r['stress'][-1])} | {fmt(mean_rate(r['rate_stress']), '.2f')} | {fmt(r['energy_drift'])} |"
        )
    return md + [""]


def section_hertz(cfg: dict, out: Path, summary: dict, ctx: dict) -> list[str]:
    """7. Hertz impact of a disc and a ball on a rigid plane (gmsh meshes; skipped without gmsh)."""
    import importlib.util

    from . import hertz
    from .plots import hertz_figure

    title = "## 7. Hertz impact: disc and ball on a rigid plane (no paper figure)"
    if importlib.util.find_spec("gmsh") is None:
        summary["hertz"] = None
        return [title, "", 'Skipped: gmsh is not installed (`pip install ".[mesh]"`).', ""]
    md = [
        title,
        "",
        "CN + seed, default parameters (R = E = rho = 1, nu = 0.3, v = 0.002), dt = t_c/(25 n); "
        "deviation = computed / Hertz - 1 (docs/verification.md discusses what limits it).",
        "",
        "| benchmark | n | dofs | contact nodes | duration | dev | peak force | dev | max approach | dev |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    rows, curves = [], []
    for name in ("hertz2d", "hertz3d"):
        b = get_benchmark(name)
        p = b.params()
        for n in cfg[name]:
            dt, T = b.run_times(n)
            measure = b.measure(p)
            H = simulate(b.problem(n), "cn", dt, T, mass="seed", observers=measure.observers())
            h = measure.summary(H)["hertz"]
            c, d = h["computed"], h["relative_deviation"]
            rows.append({"benchmark": name, "n": n, "dofs": H.meta["dofs"], "computed": c, "deviation": d})
            md.append(
                f"| {name} | {n} | {H.meta['dofs']} | {H.meta['contact_nodes']} | {c['duration']:.4g} | "
                f"{100 * d['duration']:+.1f}% | {c['peak_force']:.4g} | {100 * d['peak_force']:+.1f}% | "
                f"{c['max_approach']:.4g} | {100 * d['max_approach']:+.1f}% |"
            )
        pred = h["predicted"]
        curves.append(
            {
                "label": f"{name} n = {n}",
                "t": H.t,
                "force": -H.lambda_sum,
                "t_c": pred["duration"],
                "F": pred["peak_force"],
                "hertz": hertz.force_curve(b.dim, p, H.t),
            }
        )
        md.append(
            f"| {name} Hertz | | | | {pred['duration']:.4g} | | {pred['peak_force']:.4g} | | "
            f"{pred['max_approach']:.4g} | |"
        )
    summary["hertz"] = rows
    hertz_figure(curves, out / "hertz_impact.png", out / "hertz_impact.csv")
    md += [
        "",
        "![Hertz impact](hertz_impact.png)",
        "",
        "*Hertz impact* (`hertz_impact.png`): total contact force of the finest runs against time, "
        "scaled by Hertz's duration and peak force, with Hertz's quasi-static 1-dof model dotted.",
        "",
    ]
    return md


COMPARE_SCHEMES = "crank-nicolson,backward-euler,generalized-alpha[rho_inf=0.5],paoli-schatzman"
COMPARE_MASSES = "standard,seed"


def _exact_impact(bench, T: float) -> tuple[float, float]:
    """First and last time of the exact solution's first impact (stress below -1e-9 max|stress|)."""
    ex = bench.exact(bench.params(), T)
    t = np.linspace(0.0, T, 4001)
    s = ex.contact_stress(t)
    on = np.flatnonzero(s < -1e-9 * max(float(np.abs(s).max()), 1e-300))
    if not on.size:
        return float("nan"), float("nan")
    end = on[int(np.argmax(np.diff(np.concatenate([on, [on[-1] + 2]])) > 1))]
    return float(t[on[0]]), float(t[end])


def section_compare(cfg: dict, out: Path, summary: dict, ctx: dict) -> list[str]:
    """6. ``signorini compare`` on bar1d-impact (exact) and the 2D bar (section 3's reference).

    Runs right after section 3 (so its reference can be released); the text is placed
    at the end by :func:`section_compare_text`.
    """
    from . import compare as cmp

    pairs = cmp.make_pairs(cmp.parse_schemes(COMPARE_SCHEMES), cmp.parse_masses(COMPARE_MASSES))
    ratio = cfg["ratio"]
    l1, l2 = cfg["levels1d"], cfg["levels2d"]
    plan1 = cmp.plan_benchmark("bar1d-impact", pairs, len(l1), l1[0], cfg["Tcmp1d"], ratio)
    r1, _ = cmp.run_plan(plan1)
    ref = ctx.pop("ref2d")
    plan2 = cmp.plan_benchmark("bar2d", pairs, len(l2), l2[0], cfg["Tconv"], ratio, reference=ref)
    r2, _ = cmp.run_plan(plan2)
    del ref, plan2
    summary["compare"] = {"bar1d-impact": finite_json(r1), "bar2d": finite_json(r2)}
    b1 = get_benchmark("bar1d-impact")
    t_on, t_off = _exact_impact(b1, cfg["Tcmp1d"])
    p1 = b1.params()
    schemes, masses = COMPARE_SCHEMES, COMPARE_MASSES
    cmd1 = (
        f"signorini compare bar1d-impact --schemes '{schemes}' --masses {masses} --n0 {l1[0]} "
        f"--levels {len(l1)} --T {cfg['Tcmp1d']:g} --ratio {ratio:g}"
    )
    cmd2 = (
        f"signorini compare bar2d --schemes '{schemes}' --masses {masses} --n0 {l2[0]} --levels {len(l2)} "
        f"--T {cfg['Tconv']:g} --ratio {ratio:g} --reference {r2['reference']['level']}"
    )
    md = [
        "## 6. Scheme x mass comparison (`signorini compare`)",
        "",
        f"Every pair of {schemes.replace(',', ', ')} x {masses.replace(',', ', ')}, ranked by the rule of "
        f"`signorini compare` (docs/design.md): {cmp.RANKING_RULE}",
        "",
        f"### 6a. 1D impact `bar1d-impact` against the exact solution (T = {cfg['Tcmp1d']:g})",
        "",
        f"{cmp.setup_text(r1)} The exact first impact (gap/velocity = {p1['gap']:g}/{p1['velocity']:g}) lasts "
        f"from t = {fmt(t_on, '.3g')} to t = {fmt(t_off, '.3g')}. Same table with figures: `{cmd1}`.",
        "",
        *cmp.table_markdown(r1),
        "",
        "### 6b. 2D bar against the reference of section 3",
        "",
        f"{cmp.setup_text(r2)} {cmp.reference_text(r2)} Same table with figures: `{cmd2}`.",
        "",
        *cmp.table_markdown(r2),
        "",
        cmp.COLUMN_NOTES,
        "",
    ]
    ctx["compare_md"] = md
    return []


def section_compare_text(cfg: dict, out: Path, summary: dict, ctx: dict) -> list[str]:
    """The text of :func:`section_compare`, at the end of the report."""
    return ctx.pop("compare_md", [])


def findings(summary: dict) -> list[str]:
    """The paper's claims, with the numbers of this run."""
    hist, s1 = summary["bar2d_histories"], summary["bar1d"]
    conv = summary["bar2d_convergence"]
    cs, cst = hist["crank-nicolson/seed"], hist["crank-nicolson/standard"]
    cfg = summary["config"]
    ref = conv["crank-nicolson/seed"]["reference"]
    s1_seed = next(s for s in s1 if s["scheme"] == "crank-nicolson" and s["mass"] == "seed")
    return [
        "## Findings (numbers from this run)",
        "",
        f"- CN + standard mass: oscillation index {fmt(cst['oscillation_index'], '.2f')} vs "
        f"{fmt(cs['oscillation_index'], '.2f')} with the seed mass; energy grows to "
        f"{fmt(cst['energy_max_ratio'], '.3f')} E(0).",
        f"- CN + seed stays within max |E - E(0)| = {cs['energy_max_drift']:.2e} E(0) "
        f"(2D, n = {cfg['n2d']}, T = {cfg['T2d']:g}).",
        f"- BE dissipates: E(T)/E(0) = {fmt(hist['backward-euler/standard']['energy_ratio_final'], '.3f')} "
        f"(standard), {fmt(hist['backward-euler/seed']['energy_ratio_final'], '.3f')} (seed).",
        "- 1D rates of CN + seed (mean): "
        + ", ".join(f"{k} {fmt(mean_rate(v), '.2f')}" for k, v in s1_seed["rates"].items())
        + ".",
        f"- 2D rates of CN + seed (mean, reference n = {ref['level']}, {ref['factor_h']:g}x finer than "
        f"n = {ref['finest_level']}): "
        + ", ".join(f"{k} {fmt(mean_rate(v), '.2f')}" for k, v in conv["crank-nicolson/seed"]["rates"].items())
        + ".",
        "",
    ]


SECTIONS = (
    section_1d,
    section_2d_histories,
    section_2d_convergence,
    section_compare,
    section_3d_convergence,
    section_3d_von_mises,
    section_beyond,
    section_compare_text,
    section_hertz,
)


def reproduce(out: Path, size: str = "quick", progress=None) -> dict:
    """Run the study into ``out`` (which must exist and be empty); return the summary."""
    import matplotlib

    matplotlib.use("Agg")
    t0 = time.perf_counter()
    cfg = SIZES[size]
    summary: dict = {"size": size, "config": cfg, "section_seconds": {}, "status": "finished"}
    ctx: dict = {}
    md = _header(size, cfg)
    current = "the start"
    try:
        with interrupts_raise():  # an interrupted run stops the study: no section uses a truncated history
            for section in SECTIONS:
                ts = time.perf_counter()
                current = section.__name__
                md += section(cfg, out, summary, ctx)
                summary["section_seconds"][current] = time.perf_counter() - ts
    except KeyboardInterrupt:
        done = list(summary["section_seconds"])
        summary.update(status="interrupted", interrupted_in=current, sections_done=done)
        md += [
            "",
            f"**Interrupted** (SIGINT or SIGTERM) during `{current}`: this report holds the "
            f"{len(done)} section(s) finished before it ({', '.join(done) or 'none'}); files that section "
            "had written are left as they were.",
            "",
        ]
        (out / "report.md").write_text("\n".join(md))
        (out / "summary.json").write_text(json.dumps(summary, indent=1, default=_json_default))
        return summary
    md += findings(summary)
    summary["seconds"] = time.perf_counter() - t0
    md += [
        f"Computed in {summary['seconds']:.1f} s ("
        + ", ".join(f"{k.removeprefix('section_')} {v:.1f} s" for k, v in summary["section_seconds"].items())
        + ").",
        "",
    ]
    (out / "report.md").write_text("\n".join(md))
    (out / "summary.json").write_text(json.dumps(summary, indent=1, default=_json_default))
    return summary

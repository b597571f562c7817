"""Figures of the report (matplotlib, no display needed); each writes the CSV it plots.

One figure per figure of the seed paper (``PAPER_FIGURES``): contact-node histories
(Fig. 1 CN, Fig. 6 BE), energies and energy error norms (Fig. 2 CN, Fig. 7 BE),
error curves (Fig. 3 CN, Fig. 8 BE) and the 3D von Mises stress with the standard
(Fig. 4) and the modified mass (Fig. 5) on one shared colour scale.  The benchmarks
are nondimensional (rho = 1, Lame parameters of order 1, bar length 1), so axes say
"nondimensional" instead of units.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from ..fem.assembly import von_mises

PAPER_FIGURES = {
    1: (
        "fig1_cn_contact",
        "Crank-Nicolson: normal displacement and Lagrange multiplier at the contact nodes, "
        "standard mass (left) vs modified mass `seed` (right), each with its own scale",
    ),
    2: (
        "fig2_cn_energy",
        "Crank-Nicolson: energy history, standard vs modified mass, and energy error norms against the reference",
    ),
    3: (
        "fig3_cn_convergence",
        "Crank-Nicolson: error curves for U (displacement, velocity) and lambda "
        "(contact force) against the refinement level",
    ),
    4: ("fig4_von_mises_standard", "3D bar, Crank-Nicolson, standard mass: von Mises stress on the face x = 0"),
    5: (
        "fig5_von_mises_seed",
        "3D bar, Crank-Nicolson, modified mass `seed`: von Mises stress on the face x = 0 "
        "(same colour scale as Fig. 4)",
    ),
    6: (
        "fig6_be_contact",
        "backward Euler: normal displacement and Lagrange multiplier at the contact nodes, "
        "standard mass (left) vs modified mass `seed` (right), each with its own scale",
    ),
    7: ("fig7_be_energy", "backward Euler: energy history, standard vs modified mass, and energy error norms"),
    8: ("fig8_be_convergence", "backward Euler: error curves for U and lambda against the refinement level"),
}

T_LABEL = "t (nondimensional)"
SCHEME_TITLE = {"crank-nicolson": "Crank-Nicolson", "backward-euler": "backward Euler"}
MASS_TITLE = {"standard": "standard mass", "seed": "modified mass (seed)"}
NORM_TITLE = {
    "u_H1": "U: L2(0,T; H1) (energy norm)",
    "v_L2": "velocity: L2(0,T; L2)",
    "v_Linf": "velocity: Linf(0,T; L2)",
    "force": "lambda: total contact force, L2(0,T)",
    "energy_L2": "energy: L2(0,T) / E(0)",
    "energy_Linf": "energy: Linf(0,T) / E(0)",
}


def _fig(rows: int, cols: int, size=(10, 6), **kw):
    import matplotlib.pyplot as plt

    return plt.subplots(rows, cols, figsize=size, squeeze=False, **kw)


def _save(fig, path: Path, title: str | None = None) -> None:
    """Suptitle ``title``, lay out (tight unless the figure has its own layout engine) and write ``path``."""
    import matplotlib.pyplot as plt

    if title:
        fig.suptitle(title, fontsize=10)
    if fig.get_layout_engine() is None:
        fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _write_csv(path: Path, header: list[str], columns: list[np.ndarray]) -> None:
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows(zip(*[np.asarray(c).tolist() for c in columns], strict=True))


def _paper_title(number: int, text: str) -> str:
    return f"Paper Fig. {number}: {text}"


def representative_nodes(coordinates: np.ndarray, count: int = 3) -> np.ndarray:
    """Indices of up to ``count`` contact nodes from a corner to the centre of the contact face.

    The benchmarks are symmetric about the bar's axis, so nodes of one half (first
    coordinate <= its midpoint) are enough; they are taken evenly from the corner to the
    centre.
    """
    x = coordinates[:, 0]
    mid = 0.5 * (x.min() + x.max())
    half = np.flatnonzero(x <= mid + 1e-12 * max(1.0, float(np.ptp(x))))
    half = half[np.argsort(np.abs(x[half] - x.min()))]
    if half.size <= count:
        return half
    pick = np.unique(np.round(np.linspace(0, half.size - 1, count)).astype(int))
    return half[pick]


def contact_figure(runs: dict, scheme: str, number: int, png: Path, csv_path: Path) -> dict:
    """Fig. 1 (CN) / Fig. 6 (BE): per-node normal gap and multiplier, standard | seed.

    ``runs`` maps ``"standard"`` and ``"seed"`` to Histories.  Each panel has its own y
    scale (the multiplier of the standard mass is several times larger, as in the paper).
    Returns the nodes plotted and the y limits of every panel.
    """
    masses = [m for m in ("standard", "seed") if m in runs]
    fig, ax = _fig(2, len(masses), (11, 6.5))
    header, cols, limits = [], [], {}
    for j, mass in enumerate(masses):
        H = runs[mass]
        nodes = representative_nodes(H.coordinates)
        for k, i in enumerate(nodes):
            # coinciding histories stay visible: a wide solid line under narrower dashed/dotted ones
            style = {"color": f"C{k}", "ls": LINESTYLES[k % len(LINESTYLES)], "lw": max(2.4 - 0.7 * k, 0.8)}
            lab = f"node x = {H.coordinates[i, 0]:.3g}"
            ax[0, j].plot(H.t, H.gap[:, i], label=lab, **style)
            ax[1, j].plot(H.t, H.lam[:, i], label=lab, **style)
            header += [f"t_{mass}_node{i}", f"gap_{mass}_node{i}", f"lambda_{mass}_node{i}"]
            cols += [H.t, H.gap[:, i], H.lam[:, i]]
        ax[0, j].set_title(f"{MASS_TITLE[mass]}: normal displacement (gap to the obstacle)", fontsize=9)
        ax[1, j].set_title(f"{MASS_TITLE[mass]}: Lagrange multiplier (nodal contact force)", fontsize=9)
        ax[0, j].set_ylabel(r"gap $g_i - \nu_i \cdot u_i$ (nondim. length)")
        ax[1, j].set_ylabel(r"$\lambda_i$ (nondim. force; $<0$: compression)")
        for a in ax[:, j]:
            a.set_xlabel(T_LABEL)
            a.legend(fontsize=7)
            a.grid(alpha=0.3)
        limits[mass] = {"gap": list(ax[0, j].get_ylim()), "lambda": list(ax[1, j].get_ylim())}
    name = SCHEME_TITLE.get(scheme, scheme)
    _save(
        fig,
        png,
        _paper_title(
            number, f"{name}, contact nodes; standard (left) vs modified mass (right), each with its own y scale"
        ),
    )
    _write_csv(csv_path, header, cols)
    return {"nodes": [int(i) for i in nodes], "ylim": limits}


def energy_figure(runs: dict, conv: dict | None, scheme: str, number: int, png: Path, csv_path: Path) -> None:
    """Fig. 2 (CN) / Fig. 7 (BE): E(t)/E(0) for each mass on its own axis, and the
    energy error norms of the convergence study against the level (``conv`` maps the
    mass to a :func:`convergence_study` result; None leaves the panel out).

    The legend of the error panel sits below it, off the data; L2 norms are drawn as
    large filled circles under small open squares (Linf), so equal norms stay visible.
    """
    masses = [m for m in ("standard", "seed") if m in runs]
    ncols = len(masses) + (1 if conv else 0)
    fig, ax = _fig(1, ncols, (4.6 * ncols, 4.6 if conv else 4.2), layout="constrained")
    header, cols = [], []
    for j, mass in enumerate(masses):
        H = runs[mass]
        ratio = H.energy / H.energy[0]
        ax[0, j].plot(H.t, ratio, color=f"C{j}")
        ax[0, j].set_title(f"{MASS_TITLE[mass]}: E(t)/E(0)", fontsize=9)
        ax[0, j].set_xlabel(T_LABEL)
        ax[0, j].set_ylabel("E(t) / E(0)")
        ax[0, j].grid(alpha=0.3)
        ax[0, j].ticklabel_format(axis="y", useOffset=False)
        header += [f"t_{mass}", f"energy_{mass}", f"energy_ratio_{mass}"]
        cols += [H.t, H.energy, ratio]
    if conv:
        a = ax[0, len(masses)]
        levels = set()
        for j, (mass, c) in enumerate(conv.items()):
            n = np.array([r["n"] for r in c["rows"]])
            levels |= set(n.tolist())
            for key, style in (
                ("energy_L2", {"ls": "-", "marker": "o", "ms": 8, "lw": 2.2}),
                ("energy_Linf", {"ls": "--", "marker": "s", "ms": 5, "lw": 1.2, "mfc": "white"}),
            ):
                a.loglog(n, [r[key] for r in c["rows"]], color=f"C{j}", label=f"{mass}: {NORM_TITLE[key]}", **style)
        c0 = next(iter(conv.values()))
        _level_axis(a, sorted(levels), c0["rows"], c0.get("ratio"))
        a.set_ylabel("relative error")
        a.set_title(f"energy error norms over [0, {c0['T']:g}] vs refinement", fontsize=9)
        a.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.17), ncol=2, frameon=False)
    name = SCHEME_TITLE.get(scheme, scheme)
    _save(
        fig,
        png,
        _paper_title(
            number,
            f"{name} energy; standard vs modified mass" + (", error norms against the reference" if conv else ""),
        ),
    )
    _write_csv(csv_path, header, cols)


def _level_axis(a, levels: list[int], rows: list[dict] | None = None, ratio: float | None = None) -> None:
    """Log x axis with exactly the level values as (non-overlapping) tick labels and a
    log y axis with plain decimal labels."""
    from matplotlib.ticker import FixedLocator, FuncFormatter, NullFormatter, NullLocator

    a.set_xscale("log")
    a.xaxis.set_major_locator(FixedLocator(levels))
    a.xaxis.set_minor_locator(NullLocator())
    a.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    a.set_xlim(levels[0] / 1.3, levels[-1] * 1.3)
    label = "n (elements across the width)"
    if rows:
        width = rows[0]["h"] * rows[0]["n"]
        label = f"n (h = {width:g}/n" + (f", dt = {ratio:g} h)" if ratio else ")")
    a.set_xlabel(label)
    a.grid(alpha=0.3, which="both")
    lo, hi = a.get_ylim()
    plain = FuncFormatter(lambda v, _: f"{v:.3g}")
    a.yaxis.set_major_formatter(plain)
    decades = np.log10(hi / lo)
    marks = (2, 3, 5) if decades <= 1.2 else (2, 5) if decades <= 2.2 else ()  # label minor ticks too
    if marks:
        a.yaxis.set_minor_formatter(
            FuncFormatter(lambda v, _: f"{v:.2g}" if round(v / 10 ** np.floor(np.log10(v)), 6) in marks else "")
        )
    else:
        a.yaxis.set_minor_formatter(NullFormatter())


def convergence_figure(conv: dict, scheme: str, number: int, png: Path, csv_path: Path, keys=None) -> None:
    """Fig. 3 (CN) / Fig. 8 (BE): relative errors against the level, one panel per norm,
    with slopes 1/2 and 1 for reading the rates.  ``conv`` maps labels (the masses) to
    :func:`convergence_study` results against the same reference."""
    keys = keys or ("u_H1", "force", "v_L2", "v_Linf")
    fig, ax = _fig(1, len(keys), (4.1 * len(keys), 4.6), layout="constrained")
    rows = []
    first = next(iter(conv.values()))
    for j, k in enumerate(keys):
        a = ax[0, j]
        levels = set()
        for i, (label, c) in enumerate(conv.items()):
            n = np.array([r["n"] for r in c["rows"]])
            e = np.array([r[k] for r in c["rows"]])
            levels |= set(n.tolist())
            a.loglog(n, e, "o-", color=f"C{i}", label=MASS_TITLE.get(label, label))
            rows += [(label, k, int(x), float(y), c["reference"]["level"]) for x, y in zip(n, e, strict=True)]
        n = np.array(sorted(levels), float)
        anchor = conv.get("seed", list(conv.values())[-1])["rows"][0][k]
        a.loglog(n, anchor * (n / n[0]) ** -0.5, "k:", lw=1, label="slope 1/2")
        a.loglog(n, anchor * (n / n[0]) ** -1.0, "k--", lw=1, label="slope 1")
        _level_axis(a, sorted(levels), first["rows"], first.get("ratio"))
        a.set_title(NORM_TITLE.get(k, k), fontsize=9)
        a.set_ylabel("relative error")
    handles, labels = ax[0, 0].get_legend_handles_labels()  # one legend for every panel, below them
    fig.legend(handles, labels, fontsize=8, loc="outside lower center", ncol=len(labels), frameon=False)
    ref = first["reference"]
    name = SCHEME_TITLE.get(scheme, scheme)
    _save(
        fig,
        png,
        _wrap(
            _paper_title(
                number, f"{name} error curves, T = {first['T']:g}; reference: {ref.get('description', 'exact')}"
            ),
            40 * len(keys),
        ),
    )
    with open(csv_path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["mass", "norm", "n", "relative_error", "reference_level"])
        w.writerows(rows)


def _face_grid(points: np.ndarray, values: np.ndarray):
    """Reshape nodal values on a structured face (y, z) into 2D arrays Y, Z, V."""
    y, z = points[:, 0], points[:, 1]
    order = np.lexsort((y, z))
    ny = np.unique(y).size
    shape = (-1, ny)
    return y[order].reshape(shape), z[order].reshape(shape), values[order].reshape(shape)


def von_mises_figures(runs: dict, figures: dict, t_contact: float, near_layer: float, levels: int = 21) -> dict:
    """Fig. 4 / 5: von Mises stress on the face x = 0 of the 3D bar at the snapshot times.

    ``runs`` maps the mass to (problem, History with snapshots); ``figures`` maps the
    mass to (paper figure number, png path); the plotted values go to the png's name
    with ``.csv``.  Both figures use **one** colour scale,
    [0, max over both runs], so that equal fields have equal colours.  Statistics after
    the first contact ``t_contact``: the maximum in the layer z <= ``near_layer`` above
    the contact face and the roughness (mean |jump| along z of the width-averaged
    stress).  Returns ``{"clim": [0, vmax], "masses": {mass: stats}}``.
    """
    from matplotlib.ticker import MaxNLocator

    fields, faces = {}, {}
    for mass, (p, H) in runs.items():
        mesh = p.mesh
        on_face = np.isclose(mesh.points[:, 0], mesh.points[:, 0].min())
        faces[mass] = mesh.points[on_face][:, 1:]
        fields[mass] = [von_mises(mesh, p.material, u)[on_face] for u in H.snapshots["u"]]
    vmax = max(float(f.max()) for fs in fields.values() for f in fs)
    vmax = vmax if vmax > 0 else 1.0
    clim = [0.0, vmax]
    bounds = np.linspace(0.0, vmax, levels)
    stats = {}
    for mass, (_, H) in runs.items():
        rows = []
        number, png = figures[mass]
        times = H.snapshots["t"]
        fig, ax = _fig(1, len(times), (1.05 * len(times) + 1.6, 4.8), sharey=True, layout="constrained")
        vmax_near, rough = 0.0, []
        tc = None
        for j, t in enumerate(times):
            vm = fields[mass][j]
            Y, Z, V = _face_grid(faces[mass], vm)
            tc = ax[0, j].contourf(Y, Z, V, levels=bounds, cmap="viridis", vmin=clim[0], vmax=clim[1])
            ax[0, j].set_title(f"t = {t:.2f}", fontsize=8)
            ax[0, j].set_xticks([Y.min(), Y.max()])
            ax[0, j].tick_params(labelsize=7)
            ax[0, j].set_xlabel("y", fontsize=8)
            rows += [(mass, float(t), *map(float, abc)) for abc in zip(Y.ravel(), Z.ravel(), V.ravel(), strict=True)]
            if t >= t_contact:
                vmax_near = max(vmax_near, float(V[Z <= near_layer + 1e-12].max()))
                rough.append(float(np.mean(np.abs(np.diff(V.mean(axis=1))))))
        ax[0, 0].set_ylabel("z (nondimensional; contact face z = 0)")
        cb = fig.colorbar(tc, ax=ax[0, :].tolist(), fraction=0.02, pad=0.01)
        cb.set_ticks(MaxNLocator(6).tick_values(*clim))
        cb.ax.set_ylim(*clim)
        cb.set_label("von Mises stress (nondimensional)")
        fig.suptitle(
            _paper_title(
                number,
                f"3D bar, Crank-Nicolson, {MASS_TITLE[mass]}: von Mises stress on the face "
                f"x = 0 (y horizontal, z vertical); colour scale [0, {vmax:.3g}] shared "
                "with the other mass",
            ),
            fontsize=9,
        )
        import matplotlib.pyplot as plt

        fig.savefig(png, dpi=110)
        plt.close(fig)
        stats[mass] = {
            "max_near_contact": vmax_near,
            "roughness": float(np.mean(rough)) if rough else float("nan"),
            "clim": clim,
        }
        with open(Path(png).with_suffix(".csv"), "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["mass", "t", "y", "z", "von_mises"])
            w.writerows(rows)
    return {"clim": clim, "masses": stats}


# ----------------------------------------------------------------------------- compare
LINESTYLES = ("-", "--", ":", "-.", (0, (5, 1)), (0, (3, 1, 1, 1, 1, 1)))
DRIFT_FLOOR = 1e-16  # |E - E0|/|E0| below round-off is drawn at this floor on the log axis
MARKERS = ("o", "s", "^", "D", "v", "P")


def _pair_styles(pairs: list[dict]) -> dict[str, dict]:
    """Colour per scheme, line style and marker per mass (same look in every figure)."""
    schemes = list(dict.fromkeys(p["scheme_label"] for p in pairs))
    masses = list(dict.fromkeys(p["mass"] for p in pairs))
    return {
        p["label"]: {
            "color": f"C{schemes.index(p['scheme_label']) % 10}",
            "ls": LINESTYLES[masses.index(p["mass"]) % len(LINESTYLES)],
            "marker": MARKERS[masses.index(p["mass"]) % len(MARKERS)],
        }
        for p in pairs
    }


def _units(result: dict) -> str:
    return "nondimensional" if result["kind"] == "benchmark" else "units of the case file"


def _where(result: dict) -> str:
    if result["kind"] == "benchmark":
        return f"{result['target']}, n = {result['levels'][-1]}, dt = {result['dt'][-1]:.4g}"
    return f"{result['target']}, dt = {result['dt'][0]:.4g}"


def _unavailable_note(result: dict) -> str:
    missing = [p["label"] for p in result["pairs"] if not p["available"]]
    return f"; not plotted (n/a, see compare.md): {', '.join(missing)}" if missing else ""


def _wrap(title: str, width: int = 115) -> str:
    import textwrap

    return textwrap.fill(title, width)


def _legend_right(fig, ax) -> None:
    handles, labels = ax.get_legend_handles_labels()
    if handles:
        ax.legend(handles, labels, fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)


def compare_time_figure(result: dict, series: dict, quantity: str, png: Path, csv_path: Path) -> str:
    """One line per pair of ``quantity`` (energy, force, penetration) against t at the finest level."""
    units = _units(result)
    spec = {
        "energy": ("energy", "scheme energy E(t) / E(0)", "energy"),
        "force": (
            "force",
            rf"total contact force $-\sum_i \lambda_i$ ({units})",
            "total contact force (> 0: compression)",
        ),
        "penetration": ("penetration", f"max penetration, max(0, -gap) ({units})", "penetration"),
    }[quantity]
    pairs = [p for p in result["pairs"] if p["label"] in series]
    styles = _pair_styles(result["pairs"])
    E0s = {p["label"]: float(series[p["label"]]["energy"][0]) for p in pairs}
    relative = quantity == "energy" and all(e != 0 and np.isfinite(e) for e in E0s.values())
    ylabel = spec[1] if relative or quantity != "energy" else f"scheme energy E(t) ({units})"
    drift_panel = relative  # energy: also |E - E0|/|E0| on a log scale, where small drifts differ
    fig, ax = _fig(1, 2, (14, 4.8), layout="constrained") if drift_panel else _fig(1, 1, (9.5, 4.6))
    a = ax[0, 0]
    rows = []
    for p in pairs:
        s = series[p["label"]]
        y = np.asarray(s[spec[0]], float)
        if relative:
            y = y / E0s[p["label"]]
        st = styles[p["label"]]
        a.plot(s["t"], y, color=st["color"], ls=st["ls"], lw=1.2, label=p["label"])
        extra = [()] * y.size
        if drift_panel:
            d = np.abs(y - 1.0)
            ax[0, 1].plot(s["t"][1:], np.maximum(d[1:], DRIFT_FLOOR), color=st["color"], ls=st["ls"], lw=1.2)
            extra = [(float(v),) for v in d]
        rows += [
            (p["label"], p["scheme_label"], p["mass"], float(t), float(v), float(w), *e)
            for t, v, w, e in zip(s["t"], s[spec[0]], y, extra, strict=True)
        ]
    for b in ax[0]:
        b.set_xlabel(f"t ({units})")
        b.grid(alpha=0.3)
    a.set_ylabel(ylabel)
    if quantity == "energy":
        a.ticklabel_format(axis="y", useOffset=False)
    if drift_panel:
        b = ax[0, 1]
        b.set_yscale("log")
        b.set_ylabel("energy drift |E(t) - E(0)| / |E(0)|")
        b.set_title(f"drift on a log scale (values below {DRIFT_FLOOR:g} drawn at {DRIFT_FLOOR:g})", fontsize=9)
        a.set_title("E(t) / E(0)", fontsize=9)
    if quantity == "penetration":
        _penetration_axis(a, [float(np.max(series[p["label"]]["penetration"], initial=0.0)) for p in pairs], result)
    if drift_panel:  # one legend for both panels, below them (constrained layout makes room)
        handles, labels = a.get_legend_handles_labels()
        fig.legend(
            handles, labels, fontsize=7, loc="outside lower center", ncol=min(4, max(1, len(labels))), frameon=False
        )
    else:
        _legend_right(fig, a)
    what = spec[2][0].upper() + spec[2][1:]
    title = f"{what} vs time, one line per scheme / mass pair ({_where(result)}){_unavailable_note(result)}"
    _save(fig, png, _wrap(title, 140 if drift_panel else 115))
    value = {"energy": "energy", "force": "total_contact_force", "penetration": "penetration"}[quantity]
    header = [value, "energy_over_E0", "energy_drift"] if relative else [value, f"plotted_{value}"]
    _write_csv_rows(csv_path, ["pair", "scheme", "mass", "t", *header], rows)
    return title


def _penetration_axis(a, peaks: list[float], result: dict) -> None:
    """Penetration is >= 0; say so when every pair keeps it at zero or round-off."""
    top = max(peaks, default=0.0)
    tiny = 1e-12 * result.get("length_scale", 1.0)
    if top <= tiny:
        a.set_ylim(0.0, max(10 * top, tiny))
        what = "0" if top == 0 else f"at most {top:.2g} (round-off)"
        a.text(
            0.5,
            0.5,
            f"penetration {what} at every time step for every pair:\ncontact enforced exactly",
            transform=a.transAxes,
            ha="center",
            va="center",
            fontsize=9,
            color="0.3",
        )
    else:
        a.set_ylim(bottom=0.0)


def _write_csv_rows(path: Path, header: list[str], rows: list[tuple]) -> None:
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows(rows)


ERROR_PANELS = {
    "u_H1": "displacement u: L2(0,T; H1)",
    "v_L2": "velocity v: L2(0,T; L2)",
    "stress": "contact stress at x = 0: L2(0,T)",
    "force": "total contact force: L2(0,T)",
}


def compare_error_figure(result: dict, png: Path, csv_path: Path) -> str:
    """Relative errors against the level, one panel per norm, with the least-squares slopes."""
    norms = ["u_H1", "v_L2", result["contact_norm"]]
    pairs = [p for p in result["pairs"] if p["available"]]
    styles = _pair_styles(result["pairs"])
    ncol = min(4, max(1, len(pairs)))
    height = 4.4 + 0.2 * (-(-len(pairs) // 3)) + 0.2 * (-(-len(pairs) // ncol))
    fig, ax = _fig(1, len(norms), (4.6 * len(norms), height), layout="constrained")
    rows = []
    levels = [int(n) for n in result["levels"]]
    for j, k in enumerate(norms):
        a = ax[0, j]
        for p in pairs:
            pts = [(r["n"], r["h"], (r["errors"] or {}).get(k)) for r in p["runs"]]
            pts = [(n, h, e) for n, h, e in pts if e is not None and np.isfinite(e) and e > 0]
            rate = p["rates"].get(k)
            for n, h, e in pts:
                rows.append((p["label"], p["scheme_label"], p["mass"], n, h, k, e, rate if rate is not None else ""))
            if not pts:
                continue
            st = styles[p["label"]]
            n = np.array([q[0] for q in pts], float)
            e = np.array([q[2] for q in pts])
            a.plot(n, e, marker=st["marker"], ls="none", color=st["color"], ms=5)
            if rate is not None:
                h = np.array([q[1] for q in pts])
                c = np.exp(np.mean(np.log(e) - rate * np.log(h)))
                a.plot(
                    n, c * h**rate, ls=st["ls"], color=st["color"], lw=1, marker=st["marker"], ms=0, label=f"{rate:.2f}"
                )
        a.set_yscale("log")
        if a.has_data():
            _level_axis(a, levels, [{"n": levels[0], "h": result["h"][0]}], result["ratio"])
        a.set_ylabel("relative error")
        a.set_title(ERROR_PANELS.get(k, k), fontsize=9)
        if any(line.get_label()[0] != "_" for line in a.get_lines()):  # below the panel, off the data
            a.legend(
                fontsize=6.5,
                title="fitted slope (same line style as the pair)",
                title_fontsize=7,
                loc="upper center",
                bbox_to_anchor=(0.5, -0.16),
                ncol=3,
                frameon=False,
            )
    from matplotlib.lines import Line2D

    handles = [
        Line2D(
            [],
            [],
            ls=styles[p["label"]]["ls"],
            color=styles[p["label"]]["color"],
            marker=styles[p["label"]]["marker"],
            ms=5,
        )
        for p in pairs
    ]
    labels = [p["label"] for p in pairs]
    if handles:
        fig.legend(handles, labels, fontsize=7, loc="outside lower center", ncol=ncol, frameon=False)
    ref = result["reference"]
    against = "the exact solution" if ref["kind"] == "exact" else f"the reference {ref['description']}"
    title = (
        f"Relative error vs refinement, markers = runs, lines = least-squares fits; {result['target']}, "
        f"T = {result['T']:g}, against {against}{_unavailable_note(result)}"
    )
    import matplotlib.pyplot as plt

    fig.suptitle(_wrap(title, 150), fontsize=9)
    fig.savefig(png, dpi=110)
    plt.close(fig)
    _write_csv_rows(csv_path, ["pair", "scheme", "mass", "n", "h", "norm", "relative_error", "fitted_rate"], rows)
    return title


def compare_cost_figure(result: dict, png: Path, csv_path: Path) -> str:
    """Time per step of every pair at the finest level (bars), annotated with the ratio to a bare solve."""
    pairs = [p for p in result["pairs"] if p["available"]]
    styles = _pair_styles(result["pairs"])
    fig, ax = _fig(1, 1, (8.5, 0.45 * max(len(pairs), 2) + 1.6))
    a = ax[0, 0]
    ms = [p["metrics"]["step_ms"] for p in pairs]
    y = np.arange(len(pairs))[::-1]
    a.barh(y, ms, color=[styles[p["label"]]["color"] for p in pairs], alpha=0.8)
    a.set_yticks(y)
    a.set_yticklabels([p["label"] for p in pairs], fontsize=8)
    rows = []
    for yi, p, v in zip(y, pairs, ms, strict=True):
        m = p["metrics"]
        ratio = m["step_over_bare"]
        text = f" {v:.3g} ms" + (f" = {ratio:.2f} x bare {m['bare_op']}" if ratio is not None else "")
        a.text(v, yi, text, va="center", fontsize=7)
        bare = v / ratio if ratio else None
        rows.append(
            (
                p["label"],
                p["scheme_label"],
                p["mass"],
                result["levels"][-1],
                v,
                m["bare_op"] or "",
                bare if bare is not None else "",
                ratio if ratio is not None else "",
            )
        )
    a.set_xlim(0, max(ms, default=1.0) * 1.6 or 1.0)
    a.set_xlabel("wall time per time step (ms)")
    a.grid(alpha=0.3, axis="x")
    where = f"n = {result['levels'][-1]}" if result["kind"] == "benchmark" else "the case file's mesh"
    title = (
        f"Cost per step at {where} ({result['target']}; {result['jobs']} process(es) ran concurrently), "
        f"with its ratio to one bare solve of the same factor{_unavailable_note(result)}"
    )
    _save(fig, png, _wrap(title))
    _write_csv_rows(
        csv_path, ["pair", "scheme", "mass", "n", "ms_per_step", "bare_op", "bare_ms", "step_over_bare"], rows
    )
    return title


def compare_figures(result: dict, series: dict, out: Path) -> list[tuple[str, str]]:
    """Every figure of ``signorini compare`` into ``out``: [(png name, caption)]."""
    out = Path(out)
    figs = []
    for name, q in (("energy", "energy"), ("contact_force", "force"), ("penetration", "penetration")):
        figs.append((f"{name}.png", compare_time_figure(result, series, q, out / f"{name}.png", out / f"{name}.csv")))
    if result["kind"] == "benchmark":
        figs.append(("errors.png", compare_error_figure(result, out / "errors.png", out / "errors.csv")))
    figs.append(("cost.png", compare_cost_figure(result, out / "cost.png", out / "cost.csv")))
    return figs


def hertz_figure(curves: list[dict], png: Path, csv_path: Path) -> None:
    """Contact force against time of the Hertz runs, scaled by Hertz's t_c and F*, beside
    the 1-dof Hertz curve; ``curves``: label, t, force, t_c, F, hertz (force of the model)."""
    fig, ax = _fig(1, 1, size=(7, 4.2))
    a = ax[0, 0]
    cols, header = [], []
    for i, c in enumerate(curves):
        s = np.asarray(c["t"]) / c["t_c"]
        a.plot(s, np.asarray(c["force"]) / c["F"], color=f"C{i}", label=c["label"])
        a.plot(s, np.asarray(c["hertz"]) / c["F"], ":", color=f"C{i}", lw=1.5)
        cols += [s, np.asarray(c["force"]) / c["F"], np.asarray(c["hertz"]) / c["F"]]
        header += [f"{c['label']} t/t_c", f"{c['label']} F/F*", f"{c['label']} Hertz F/F*"]
    a.plot([], [], "k:", label="Hertz, quasi-static (dotted)")
    a.set_xlabel("t / t_c (Hertz)")
    a.set_ylabel("total contact force / F* (Hertz)")
    a.set_xlim(0, 1.3)
    a.legend(fontsize=8)
    _save(fig, png, "Hertz impact: computed contact force (solid) vs Hertz's 1-dof model (dotted)")
    n = max(len(x) for x in cols)
    _write_csv(csv_path, header, [np.pad(np.asarray(x, float), (0, n - len(x)), constant_values=np.nan) for x in cols])

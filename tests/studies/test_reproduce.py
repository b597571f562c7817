"""``signorini reproduce`` run once through the CLI, its report and figures checked for
content (issue 24, item 8).

``--tiny`` in the default run (measured 2026-12-01: 21 s of CPU for the reproduction, 1-2 s
for the recomputations here), ``--quick`` (the README's main job) with ``-m slow`` (61 s of
CPU for the reproduction, about 20 s here).  What is checked:

* every figure the report references exists, is a PNG (signature and a non-empty IHDR)
  and has its CSV next to it, holding finite numbers; no PNG in the directory is left
  unreferenced;
* the report states its references and mesh sizes / time steps: the 1D tables against
  the exact solution with dt = ratio h, the 2D mesh (n x 10n Q1), the 2D/3D reference
  runs with h, dt and how much finer they are (recomputed here from the benchmarks'
  parameters, not read back from the summary);
* the ranking tables of section 6 have every scheme x mass pair exactly once, ranked
  1, 2, ... (ties allowed) with the pair the scheme refuses last, as n/a with its reason;
  the u error of CN + seed on the exact 1D impact is recomputed with ``errors_1d``;
* the figures' data are the histories they plot: Fig. 1/6 (gap and multiplier of the
  contact nodes) and Fig. 2/7 (energies) equal runs recomputed here with ``simulate``;
  Fig. 3/8's force errors equal errors recomputed here from a CN + seed reference run
  (linear interpolation in time, rectangle sums); Fig. 4/5 (von Mises on the face
  x = 0) equal the stress of a recomputed 3D run; the Hertz figure's force equals a
  recomputed hertz2d run, scaled by Hertz's t_c and F*; section 1's table equals
  ``errors_1d`` of a recomputed run to its printed digits.
"""

import csv
import itertools
import json
import math
import re
import struct

import numpy as np
import pytest

from signorini.dynamics.stepping.simulate import simulate
from signorini.fem.assembly import von_mises
from signorini.io.cli import main
from signorini.studies import report
from signorini.studies.benchmarks import get_benchmark
from signorini.studies.hertz import hertz_prediction
from signorini.studies.plots import PAPER_FIGURES
from signorini.studies.study import errors_1d

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
SAME = 1e-12  # recomputed series vs the CSV: relative to the series' largest value (CSV holds repr(float))


@pytest.fixture(scope="module", params=["tiny", pytest.param("quick", marks=pytest.mark.slow)])
def reproduced(request, tmp_path_factory):
    size = request.param
    if size == "tiny":  # shared with test_report.py: one run per session
        out = request.getfixturevalue("reproduced_tiny")
    else:
        out = tmp_path_factory.mktemp(f"reproduce_{size}") / "out"
        assert main(["reproduce", f"--{size}", "--out", str(out), "--quiet"]) == 0
    text = (out / "report.md").read_text()
    return size, out, text, report.SIZES[size]


def _read_csv(path):
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    return rows[0], rows[1:]


def _column(path, name) -> np.ndarray:
    header, rows = _read_csv(path)
    j = header.index(name)
    return np.array([float(r[j]) for r in rows])


def _same(got, want):
    got, want = np.asarray(got, float), np.asarray(want, float)
    assert got.shape == want.shape, (got.shape, want.shape)
    scale = max(float(np.max(np.abs(want))), 1e-300)
    assert np.max(np.abs(got - want)) <= SAME * scale, np.max(np.abs(got - want)) / scale


def _section(text, start, end="\n## "):
    i = text.index(start)
    j = text.find(end, i + len(start))
    return text[i : j if j >= 0 else len(text)]


# ----------------------------------------------------------------------------- figures
def test_every_referenced_figure_is_a_png_with_its_csv(reproduced):
    _, out, text, _ = reproduced
    embedded = set(re.findall(r"!\[[^\]]*\]\(([^)\s]+\.png)\)", text))
    mentioned = set(re.findall(r"`([\w.-]+\.png)`", text))
    assert embedded and mentioned <= embedded  # every figure the text names is shown
    referenced = embedded
    for name in sorted(referenced):
        png = out / name
        data = png.read_bytes()
        assert data[:8] == PNG_SIGNATURE, name
        assert data[12:16] == b"IHDR"
        width, height = struct.unpack(">II", data[16:24])
        assert width >= 200 and height >= 200, (name, width, height)
        header, rows = _read_csv(png.with_suffix(".csv"))
        assert header and len(rows) >= 2, name
        numbers = 0
        for r in rows:
            assert len(r) == len(header), name
            for cell in r:
                try:
                    x = float(cell)
                except ValueError:
                    continue  # a label column (mass, norm)
                numbers += 1
                assert math.isfinite(x) or (name == "hertz_impact.png" and math.isnan(x)), (name, cell)
        assert numbers >= len(rows), name
    on_disk = {p.name for p in out.glob("*.png")}
    assert on_disk == referenced, on_disk ^ referenced


def test_hertz_figure_pads_only_at_the_end(reproduced):
    """hertz_impact.csv pads the shorter series with nan at their ends only."""
    pytest.importorskip("gmsh", reason="the Hertz benchmarks mesh with gmsh (pip install '.[mesh]')")
    _, out, _, _ = reproduced
    header, rows = _read_csv(out / "hertz_impact.csv")
    for j, name in enumerate(header):
        col = np.array([float(r[j]) for r in rows])
        nan = np.isnan(col)
        assert not nan.any() or nan[np.argmax(nan) :].all(), name


# ----------------------------------------------------------------------------- references, sizes
def test_report_states_references_mesh_sizes_and_time_steps(reproduced):
    size, out, text, cfg = reproduced
    ratio = cfg["ratio"]
    b1, b2, b3 = get_benchmark("bar1d"), get_benchmark("bar2d"), get_benchmark("bar3d")
    p1 = b1.params()
    T1 = 3 * p1["L"] / math.sqrt(p1["E"] / p1["rho"])
    assert f"1. 1D clamped bar against the exact solution (T = 3L/c = {T1:g}, one period; dt = {ratio:g} h)" in text
    n2 = cfg["n2d"]
    assert f"2. 2D bar, n = {n2} ({n2}x{10 * n2} Q1), dt = {ratio:g} h, T = {cfg['T2d']:g}" in text
    for d, b, key in (("2D", b2, "2d"), ("3D", b3, "3d")):
        ref, finest = cfg[f"ref{key}"], max(cfg[f"levels{key}"])
        h = b.params()["width"] / ref
        factor = ref / finest
        want = (
            f"Reference: crank-nicolson + seed at n = {ref} (h = {h:.4g}, dt = {ratio * h:.4g}), "
            f"{factor:g}x finer in h and {factor:.3g}x in dt than the finest level n = {finest} (T = {cfg['Tconv']:g})"
        )
        assert want in text, (d, want)
        assert factor >= 4
    sec6a = _section(text, "### 6a.", "### 6b.")
    l1 = cfg["levels1d"]
    assert "against the exact solution" in sec6a
    h1 = [get_benchmark("bar1d-impact").h(n) for n in l1]
    assert f"levels n = {', '.join(map(str, l1))} (h = {h1[0]:.4g} .. {h1[-1]:.4g}, dt = {ratio:g} h)" in sec6a
    sec6b = _section(text, "### 6b.")
    assert f"Errors against the reference crank-nicolson + seed at n = {cfg['ref2d']}" in sec6b


# ----------------------------------------------------------------------------- ranking
def _ranking_tables(text):
    tables = []
    for head in ("### 6a.", "### 6b."):
        sec = _section(text, head, "\n### " if head == "### 6a." else "\n## ")
        lines = [ln for ln in sec.splitlines() if ln.startswith("| ")]
        cols = [c.strip() for c in lines[0].strip("|").split("|")]
        rows = [dict(zip(cols, (c.strip() for c in ln.strip("|").split("|")), strict=True)) for ln in lines[1:]]
        tables.append(rows)
    return tables


def test_ranking_tables_have_every_pair_once(reproduced):
    _, _, text, _ = reproduced
    schemes = report.COMPARE_SCHEMES.split(",")
    masses = report.COMPARE_MASSES.split(",")
    expected = set(itertools.product(schemes, masses))
    for rows in _ranking_tables(text):
        pairs = [(r["scheme"], r["mass"]) for r in rows]
        assert len(pairs) == len(set(pairs)) and set(pairs) == expected, pairs
        ranks = [r["rank"] for r in rows]
        numeric = [int(x) for x in ranks if x != "n/a"]
        assert numeric[0] == 1 and numeric == sorted(numeric) and max(numeric) <= len(numeric)
        assert all(x == "n/a" for x in ranks[len(numeric) :])  # the unavailable pairs come last
        for r in rows:
            if r["rank"] == "n/a":  # Paoli-Schatzman refuses massless dofs (docs/schemes.md)
                assert (r["scheme"], r["mass"]) == ("paoli-schatzman", "seed") and r["note"].startswith("n/a: ")
            else:
                assert r["decided by"] and float(r["u error L2(H1)"]) > 0


def test_ranking_error_of_the_exact_1d_case_recomputed(reproduced):
    """6a's u error of CN + seed at the finest level = errors_1d of a run made here."""
    _, _, text, cfg = reproduced
    rows = _ranking_tables(text)[0]
    row = next(r for r in rows if (r["scheme"], r["mass"]) == ("crank-nicolson", "seed"))
    b = get_benchmark("bar1d-impact")
    n, T = cfg["levels1d"][-1], cfg["Tcmp1d"]
    dt = cfg["ratio"] * b.h(n)
    p = b.problem(n)
    H = simulate(p, "crank-nicolson", dt, T, mass="seed", snapshot_every=1)
    e = errors_1d(H, p, b.exact(b.params(), T))
    assert abs(float(row["u error L2(H1)"]) - e["u_H1"]) <= 0.5e-3 * e["u_H1"]  # printed .3e
    assert abs(float(row["v error L2(L2)"]) - e["v_L2"]) <= 0.5e-3 * e["v_L2"]


# ----------------------------------------------------------------------------- data vs histories
def _runs_2d(cfg, scheme):
    b = get_benchmark("bar2d")
    n = cfg["n2d"]
    return {m: simulate(b.problem(n), scheme, cfg["ratio"] * b.h(n), cfg["T2d"], mass=m) for m in ("standard", "seed")}


@pytest.mark.parametrize("scheme, contact_fig, energy_fig", [("crank-nicolson", 1, 2), ("backward-euler", 6, 7)])
def test_contact_and_energy_figures_plot_the_runs(reproduced, scheme, contact_fig, energy_fig):
    _, out, _, cfg = reproduced
    runs = _runs_2d(cfg, scheme)
    contact_csv = out / f"{PAPER_FIGURES[contact_fig][0]}.csv"
    energy_csv = out / f"{PAPER_FIGURES[energy_fig][0]}.csv"
    header, _ = _read_csv(contact_csv)
    for mass, H in runs.items():
        nodes = [int(m.group(1)) for h in header if (m := re.fullmatch(rf"gap_{mass}_node(\d+)", h))]
        # from the corner to the centre of the contact face, at most three nodes
        x = H.coordinates[:, 0]
        assert 1 <= len(nodes) <= 3 and x[nodes[0]] == x.min()
        assert np.all(np.diff(x[nodes]) > 0) and x[nodes[-1]] <= 0.5 * (x.min() + x.max()) + 1e-12
        for i in nodes:
            _same(_column(contact_csv, f"t_{mass}_node{i}"), H.t)
            _same(_column(contact_csv, f"gap_{mass}_node{i}"), H.gap[:, i])
            _same(_column(contact_csv, f"lambda_{mass}_node{i}"), H.lam[:, i])
        assert H.lam.min() < 0  # there was contact to plot
        _same(_column(energy_csv, f"t_{mass}"), H.t)
        _same(_column(energy_csv, f"energy_{mass}"), H.energy)
        _same(_column(energy_csv, f"energy_ratio_{mass}"), H.energy / H.energy[0])


@pytest.mark.parametrize("scheme, fig", [("crank-nicolson", 3), ("backward-euler", 8)])
def test_convergence_figures_plot_errors_against_the_reference(reproduced, scheme, fig):
    """Fig. 3/8: the force errors recomputed here (reference: CN + seed at ref2d, linear
    interpolation in time to its levels, rectangle sums); every plotted error equals the
    report's table to its printed digits."""
    _, out, text, cfg = reproduced
    b = get_benchmark("bar2d")
    T, ratio = cfg["Tconv"], cfg["ratio"]
    header, rows = _read_csv(out / f"{PAPER_FIGURES[fig][0]}.csv")
    assert header == ["mass", "norm", "n", "relative_error", "reference_level"]
    plotted = {(r[0], r[1], int(r[2])): float(r[3]) for r in rows}
    assert {int(r[4]) for r in rows} == {cfg["ref2d"]}
    assert {(m, n) for m, _, n in plotted} == {(m, n) for m in ("standard", "seed") for n in cfg["levels2d"]}
    # the report's convergence table (4 decimals)
    table = _section(text, "## 3. 2D convergence")
    columns = {"u_H1": 2, "v_L2": 3, "v_Linf": 4, "force": 5}
    for (mass, norm, n), value in plotted.items():
        line = next(ln for ln in table.splitlines() if ln.startswith(f"| {scheme}/{mass} | {n} |"))
        printed = float(line.strip("|").split("|")[columns[norm]])
        assert abs(printed - value) <= 0.5e-4 + 1e-12, (mass, norm, n, printed, value)
    # the force error recomputed from the histories
    nref = cfg["ref2d"]
    ref = simulate(b.problem(nref), "crank-nicolson", ratio * b.h(nref), T, mass="seed")
    f_ref = ref.lambda_sum[ref.t <= T * (1 + 1e-12)]
    t_ref = ref.t[: f_ref.size]
    for mass in ("standard", "seed"):
        for n in cfg["levels2d"]:
            H = simulate(b.problem(n), scheme, ratio * b.h(n), T, mass=mass)
            f = np.interp(t_ref, H.t, H.lambda_sum)
            err = math.sqrt(np.sum((f - f_ref) ** 2) / np.sum(f_ref**2))
            assert abs(plotted[(mass, "force", n)] - err) <= 1e-10 * err, (mass, n, plotted[(mass, "force", n)], err)


def test_von_mises_figures_plot_the_3d_runs(reproduced):
    _, out, _, cfg = reproduced
    b = get_benchmark("bar3d")
    n, ratio, T = cfg["n3d"], cfg["ratio"], cfg["T3d"]
    dt = ratio * b.h(n)
    every = max(1, int(round(T / report.SNAPSHOTS_3D / dt)))
    for mass, name in (("standard", "fig4_von_mises_standard"), ("seed", "fig5_von_mises_seed")):
        p = b.problem(n)
        H = simulate(p, "crank-nicolson", dt, T, mass=mass, snapshot_every=every)
        header, rows = _read_csv(out / f"{name}.csv")
        assert header == ["mass", "t", "y", "z", "von_mises"] and {r[0] for r in rows} == {mass}
        pts = p.mesh.points
        face = np.flatnonzero(np.isclose(pts[:, 0], pts[:, 0].min(), rtol=0, atol=1e-12))
        plotted = {}
        for r in rows:
            plotted.setdefault(float(r[1]), []).append((float(r[2]), float(r[3]), float(r[4])))
        _same(sorted(plotted), H.snapshots["t"])
        for t, u in zip(H.snapshots["t"], H.snapshots["u"], strict=True):
            vm = von_mises(p.mesh, p.material, u)[face]
            want = sorted(zip(pts[face, 1], pts[face, 2], vm, strict=True))
            got = sorted(plotted[float(t)])
            _same(np.array(got)[:, :2], np.array(want)[:, :2])
            _same(np.array(got)[:, 2], np.array(want)[:, 2])


def test_hertz_figure_plots_the_disc_run(reproduced):
    pytest.importorskip("gmsh", reason="the Hertz benchmarks mesh with gmsh (pip install '.[mesh]')")
    _, out, _, cfg = reproduced
    b = get_benchmark("hertz2d")
    p = b.params()
    n = cfg["hertz2d"][-1]
    dt, T = b.run_times(n)
    H = simulate(b.problem(n), "cn", dt, T, mass="seed")
    pred = hertz_prediction(2, p["R"], p["E"], p["nu"], p["rho"], p["velocity"])
    label = f"hertz2d n = {n}"
    s = _column(out / "hertz_impact.csv", f"{label} t/t_c")
    F = _column(out / "hertz_impact.csv", f"{label} F/F*")
    model = _column(out / "hertz_impact.csv", f"{label} Hertz F/F*")
    k = H.t.size
    assert np.all(np.isnan(s[k:]))  # padding only
    _same(s[:k], H.t / pred.duration)
    _same(F[:k], -H.lambda_sum / pred.peak_force)
    # the dotted model: zero at both ends of the contact, its peak F* at t_c / 2
    m = model[:k]
    assert m[0] == 0.0 and np.all(m[s[:k] > 1.0] == 0.0) and 0.98 <= m.max() <= 1.0 + 1e-9
    assert abs(s[:k][np.argmax(m)] - 0.5) <= 1.0 / (n * 25)  # within a step dt = t_c / (25 n)


def test_section_1_table_is_errors_1d_of_the_runs(reproduced):
    """Section 1's CN + seed row at the finest level = errors_1d of a run made here, to the printed digits."""
    _, _, text, cfg = reproduced
    b = get_benchmark("bar1d")
    n, ratio = cfg["levels1d"][-1], cfg["ratio"]
    p1 = b.params()
    T = 3 * p1["L"] / math.sqrt(p1["E"] / p1["rho"])
    p = b.problem(n)
    H = simulate(p, "crank-nicolson", ratio * b.h(n), T, mass="seed", snapshot_every=1)
    e = errors_1d(H, p, b.exact(p1, T))
    sec = _section(text, "## 1. 1D clamped bar")
    line = next(ln for ln in sec.splitlines() if ln.startswith(f"| crank-nicolson | seed | {n} |"))
    cells = [float(c) for c in line.strip("|").split("|")[3:]]
    want = [e["u_H1"], e["u_L2"], e["v_L2"], e["stress"], float(H.energy[-1])]
    for got, value in zip(cells, want, strict=True):
        assert abs(got - value) <= 0.5e-4 + 1e-12, (got, value)


def test_an_interrupted_reproduce_keeps_and_names_the_sections_it_finished(tmp_path, monkeypatch):
    """A SIGINT inside a run of the second section: that run raises (no section goes on with a
    truncated history), the report keeps the first section and says where it stopped."""
    import os
    import signal

    from signorini.dynamics.stepping.simulate import simulate
    from signorini.studies import report

    def first(cfg, out, summary, ctx):
        (out / "first.txt").write_text("done")
        return ["## first", ""]

    def second(cfg, out, summary, ctx):
        b = report.get_benchmark("bar1d")

        def interrupt(n, N):
            if n == 10:
                os.kill(os.getpid(), signal.SIGINT)

        simulate(b.problem(20), "cn", b.h(20) / 2, 50.0, progress=interrupt)
        raise AssertionError("the interrupted run returned a truncated history")

    monkeypatch.setattr(report, "SECTIONS", [first, second])
    s = report.reproduce(tmp_path, "tiny")
    assert s["status"] == "interrupted" and s["interrupted_in"] == "second" and s["sections_done"] == ["first"]
    text = (tmp_path / "report.md").read_text()
    assert "## first" in text and "**Interrupted**" in text and "during `second`" in text
    assert json.loads((tmp_path / "summary.json").read_text())["status"] == "interrupted"

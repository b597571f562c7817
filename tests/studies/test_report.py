import json
import re

import numpy as np
import pytest

from signorini.studies import plots, report
from signorini.studies.reference_study import DEFAULT_REFERENCE_FACTOR


@pytest.fixture(scope="module")
def tiny_report(reproduced_tiny):
    out = reproduced_tiny  # one run of reproduce --tiny per session (tests/conftest.py)
    return out, (out / "report.md").read_text(), json.loads((out / "summary.json").read_text())


def test_reproduce_tiny_writes_report(tiny_report):
    out, text, s = tiny_report
    h = s["bar2d_histories"]
    # the paper's claims, measured: CN + standard oscillates and gains energy, BE dissipates
    assert h["crank-nicolson/standard"]["energy_max_ratio"] > 1.5
    assert h["crank-nicolson/seed"]["energy_max_ratio"] < 1.01
    assert h["crank-nicolson/standard"]["oscillation_index"] > 2 * h["crank-nicolson/seed"]["oscillation_index"]
    assert h["backward-euler/seed"]["energy_ratio_final"] < 1.0
    for v in h.values():
        assert v["max_complementarity_residual"] < 5e-14  # relative; measured 5.6e-16


def test_report_has_one_figure_per_paper_figure(tiny_report):
    out, text, _ = tiny_report
    assert sorted(plots.PAPER_FIGURES) == list(range(1, 9))
    mapping = text[text.index("## Paper figures in this report") :].split("\n## ")[0]
    for number, (name, _) in plots.PAPER_FIGURES.items():
        assert name.startswith(f"fig{number}_")
        assert (out / f"{name}.png").stat().st_size > 1000
        assert (out / f"{name}.csv").stat().st_size > 0
        assert f"| Fig. {number} | `{name}.png`" in mapping  # the mapping table
        assert f"![Paper Fig. {number}]({name}.png)" in text  # the figure in its section


def test_report_has_no_nan_and_no_hard_coded_contact_time(tiny_report):
    _, text, s = tiny_report
    assert not re.search(r"\bnan\b", text, re.IGNORECASE)
    assert "inf" not in re.findall(r"\b\w+\b", text)
    ps = next(r for r in s["bar1d_beyond"] if r["label"].startswith("paoli"))
    assert all(np.isfinite(ps["u_H1"])) and all(np.isfinite(ps["stress"]))
    # the first contact comes from the history and the free-flight time from the parameters
    assert "gap/velocity = 0.2/0.5 = 0.4" in text


def test_report_states_references_and_compares_rates(tiny_report):
    _, text, s = tiny_report
    conv = s["bar2d_convergence"]["crank-nicolson/seed"]
    ref = conv["reference"]
    assert ref["factor_h"] >= DEFAULT_REFERENCE_FACTOR and ref["factor_dt"] >= DEFAULT_REFERENCE_FACTOR - 1e-9
    assert f"at n = {ref['level']}" in text and f"{ref['factor_h']:g}x finer in h" in text
    assert "### Do the rates depend on the reference?" in text
    assert [c["reference"]["level"] for c in conv["checks"]] == report.SIZES["tiny"]["checks2d"]
    agreement = s["bar2d_rate_agreement"]["crank-nicolson/seed"]
    assert agreement and all("max_diff" in a for a in agreement)
    assert re.search(r"2x vs 4x: (agree|do NOT agree), max \|difference\| \d\.\d\d", text)


def test_sizes_use_references_at_least_four_times_finer():
    for cfg in report.SIZES.values():
        for d in ("2d", "3d"):
            levels, ref = cfg[f"levels{d}"], cfg[f"ref{d}"]
            assert ref >= DEFAULT_REFERENCE_FACTOR * max(levels)
            assert all(ref % n == 0 for n in levels)


def test_von_mises_figures_share_one_colour_scale(tiny_report):
    out, _, s = tiny_report
    vm = s["bar3d_von_mises"]
    lo, hi = vm["clim"]
    assert lo == 0.0 and hi > 0
    assert vm["masses"]["standard"]["clim"] == vm["masses"]["seed"]["clim"] == [lo, hi]
    # the scale is the largest value of both runs
    import csv

    peak = max(
        float(r["von_mises"])
        for name in ("fig4_von_mises_standard", "fig5_von_mises_seed")
        for r in csv.DictReader(open(out / f"{name}.csv"))
    )
    assert hi == pytest.approx(peak, rel=1e-14, abs=0)  # the CSV holds repr(float): measured 0


def test_oscillation_index_monotone_pulse_is_one():
    t = np.linspace(0, 1, 201)
    pulse = -np.where((t > 0.2) & (t < 0.8), np.sin(np.pi * (t - 0.2) / 0.6), 0.0)  # rise and fall, <= 0
    assert report.oscillation_index(t, pulse) == pytest.approx(1.0, rel=1e-14, abs=0)  # measured 0
    # a triangle too, and the scale does not matter
    tri = -np.maximum(0.0, 0.3 - np.abs(t - 0.5))
    assert report.oscillation_index(t, 5 * tri) == pytest.approx(1.0, rel=1e-14, abs=0)  # measured 0
    assert report.oscillation_index(t, np.zeros_like(t)) == 0.0


def test_oscillation_index_counts_extra_swings():
    t = np.linspace(0, 1, 401)
    on = (t > 0.2) & (t < 0.8)
    # a plateau at -1 with 3 oscillations of amplitude 0.2: index = TV / (2 peak), well above 1
    f = -np.where(on, 1.0 + 0.2 * np.sin(2 * np.pi * 3 * (t - 0.2) / 0.6), 0.0)
    idx = report.oscillation_index(t, f)
    peak = np.max(np.abs(f))
    tv = np.sum(np.abs(np.diff(np.concatenate([[0.0], f[on], [0.0]]))))
    assert idx == pytest.approx(tv / (2 * peak), rel=1e-14, abs=0)  # measured 0
    assert idx > 1.5
    # one dip of depth a x peak during contact gives 1 + a
    g = np.zeros(11)
    g[2:9] = [-0.5, -1.0, -1.0, -0.7, -1.0, -1.0, -0.5]
    assert report.oscillation_index(np.arange(11.0), g) == pytest.approx(1.3, rel=1e-14, abs=0)  # measured 0


def test_fmt_prints_na_for_undefined_values():
    assert report.fmt(float("nan")) == "n/a" and report.fmt(None) == "n/a" and report.fmt(np.inf) == "n/a"
    assert report.fmt(0.12345) == "0.1235"
    assert report.mean_rate([0.5, float("nan")]) != report.mean_rate([0.5, float("nan")])  # nan
    assert report.fmt(report.mean_rate([])) == "n/a"


def test_report_has_the_compare_section(tiny_report):
    _, text, s = tiny_report
    sec = text[text.index("## 6. Scheme x mass comparison") :]
    assert "### 6a. 1D impact `bar1d-impact` against the exact solution" in sec
    assert "### 6b. 2D bar against the reference of section 3" in sec
    assert sec.count("\n| rank |") == 2
    c2 = s["compare"]["bar2d"]
    conv = s["bar2d_convergence"]["crank-nicolson/seed"]
    # the comparison reuses section 3's reference and states it
    assert c2["reference"]["level"] == conv["reference"]["level"] == report.SIZES["tiny"]["ref2d"]
    assert f"at n = {c2['reference']['level']}" in sec and "x finer in h" in sec
    assert s["compare"]["bar1d-impact"]["reference"]["kind"] == "exact"
    for c in s["compare"].values():
        assert len(c["pairs"]) == 8
        for p in c["pairs"]:  # Paoli-Schatzman refuses massless dofs (docs/schemes.md): n/a with the reason
            if p["scheme"] == "paoli-schatzman" and p["mass"] == "seed":
                assert not p["available"]
            else:
                assert p["available"], p["label"]
        assert sorted(p["rank"] for p in c["pairs"] if p["rank"] is not None)[0] == 1
    # same numbers as section 3 for a pair both compute (same runs, same reference)
    row = conv["rows"][-1]
    pair = next(p for p in c2["pairs"] if p["label"] == "crank-nicolson / seed")
    assert pair["runs"][-1]["errors"]["u_H1"] == pytest.approx(row["u_H1"], rel=1e-14, abs=0)  # measured 0


def test_report_has_the_hertz_section(tiny_report):
    import importlib.util

    out, text, s = tiny_report
    assert "## 7. Hertz impact" in text
    if importlib.util.find_spec("gmsh") is None:
        assert s["hertz"] is None and 'pip install ".[mesh]"' in text
        return
    assert (out / "hertz_impact.png").is_file() and (out / "hertz_impact.csv").is_file()
    assert {r["benchmark"] for r in s["hertz"]} == {"hertz2d", "hertz3d"}
    for r in s["hertz"]:
        assert abs(r["deviation"]["duration"]) < 0.1 and abs(r["deviation"]["peak_force"]) < 0.1

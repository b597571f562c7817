"""``signorini compare``: the scheme x mass matrix, its report, its ranking rule."""

import json
import re
from pathlib import Path

import pytest

from signorini.dynamics.schemes import SCHEMES
from signorini.errors import InputError
from signorini.io.cli import main
from signorini.studies import compare as cmp

ROOT = Path(__file__).parents[2]
SCHEMES_1D = "crank-nicolson,generalized-alpha[rho_inf=0.5]"
TINY_1D = ["--levels", "3", "--n0", "10", "--T", "1"]
FILES = ("compare.md", "compare.json") + tuple(
    f"{name}.{ext}" for name in ("energy", "contact_force", "penetration", "errors", "cost") for ext in ("png", "csv")
)


def _compare(out, *args):
    return main(["compare", *args, "--out", str(out), "--quiet"])


def _report(tmp_path_factory, bench: str, schemes: str, tiny: list):
    """(out, compare.md text, compare.json) of a standard x seed comparison on 2 processes."""
    out = tmp_path_factory.mktemp("cmp") / "c"
    rc = _compare(out, bench, "--schemes", schemes, "--masses", "standard,seed", *tiny, "--jobs", "2")
    assert rc == 0
    return out, (out / "compare.md").read_text(), json.loads((out / "compare.json").read_text())


@pytest.fixture(scope="module")
def bar1d_report(tmp_path_factory):
    return _report(tmp_path_factory, "bar1d", SCHEMES_1D, TINY_1D)


def _table(md: str) -> list[list[str]]:
    """The rows (cells) of the ranking table of compare.md."""
    lines = [ln for ln in md.splitlines() if ln.startswith("| ")]
    return [[c.strip() for c in ln.strip("|").split("|")] for ln in lines[1:]]


def test_compare_bar1d_writes_a_complete_report(bar1d_report):
    out, md, res = bar1d_report
    for name in FILES:
        assert (out / name).stat().st_size > (1000 if name.endswith(".png") else 10), name
    rows = _table(md)
    labels = {(r[1], r[2]) for r in rows}
    assert labels == {
        (s, m) for s in ("crank-nicolson", "generalized-alpha[rho_inf=0.5]") for m in ("standard", "seed")
    }
    assert sorted(int(r[0]) for r in rows) == [1, 2, 3, 4]  # no ties here
    for r in rows:  # every cell a value, or a declared n/a
        for cell in r:
            assert cell and not re.search(r"\b(nan|None|inf)\b", cell, re.IGNORECASE), r
    assert md.count("\n| rank |") == 1  # one table
    assert "Rule: First, a run whose contact" in md and "Then lexicographic" in md
    assert "Errors against the exact solution." in md
    assert res["reference"]["kind"] == "exact" and res["levels"] == [10, 20, 40]
    for p in res["pairs"]:
        assert p["available"] and len(p["runs"]) == 3
        assert set(p["rates"]) == {"u_H1", "v_L2", "stress"}
        assert all(isinstance(v, float) for v in p["rates"].values())
    # figures are embedded and every CSV has the plotted numbers of every pair
    for name in ("energy", "contact_force", "penetration", "errors", "cost"):
        assert f"]({name}.png)" in md
        text = (out / f"{name}.csv").read_text()
        assert all(p["label"] in text for p in res["pairs"])


def test_parallel_equals_serial(bar1d_report):
    _, _, res = bar1d_report  # 2 processes
    assert res["jobs"] == 2
    pairs = cmp.make_pairs(cmp.parse_schemes(SCHEMES_1D), cmp.parse_masses("standard,seed"))
    serial, _ = cmp.run_plan(cmp.plan_benchmark("bar1d", pairs, 3, 10, 1.0), jobs=1)
    assert serial["jobs"] == 1
    assert cmp.strip_timings(serial) == cmp.strip_timings(res)


def test_compare_numbers_equal_those_of_run(bar1d_report, tmp_path):
    _, _, res = bar1d_report
    pair = next(
        p for p in res["pairs"] if p["scheme_label"] == "generalized-alpha[rho_inf=0.5]" and p["mass"] == "seed"
    )
    finest = pair["runs"][-1]
    assert finest["n"] == 40
    args = ["run", "bar1d", "--scheme", "generalized-alpha", "--scheme-option", "rho_inf=0.5", "--mass", "seed"]
    args += ["--n", "40", "--dt", repr(finest["dt"]), "--T", "1", "--out", str(tmp_path / "r"), "--quiet"]
    assert main(args) == 0
    s = json.loads((tmp_path / "r" / "summary.json").read_text())
    for key in ("energy_final", "penetration_max", "oscillation_index"):
        assert finest["summary"][key] == pytest.approx(s[key], rel=1e-14, abs=1e-300), key  # measured 0
    assert finest["summary"]["steps"] == s["steps"] == 80


@pytest.mark.parametrize(
    "args, message",
    [
        (
            ["--schemes", "crank-nicolson,leapfrog", "--masses", "seed"],
            "unknown scheme 'leapfrog'; allowed: crank-nicolson",
        ),
        (["--schemes", "generalized-alpha[rho=0.5]", "--masses", "seed"], "allowed: rho_inf"),
        (["--schemes", "generalized-alpha[rho_inf=2]", "--masses", "seed"], "rho_inf"),
        (["--schemes", "generalized-alpha[rho_inf=0.5", "--masses", "seed"], "missing ']'"),
        (["--schemes", "cn,crank-nicolson", "--masses", "seed"], "twice"),
        (["--schemes", "cn", "--masses", "seed,heavy"], "unknown mass 'heavy'; allowed: standard"),
        (["--schemes", "cn", "--masses", "seed", "--reference", "80"], "exact solution"),
        (["--schemes", "cn", "--masses", "seed", "--T", "1.01"], "not an integer multiple"),
        (["--schemes", "cn", "--masses", "seed", "--jobs", "0"], "--jobs"),
    ],
)
def test_bad_input_exits_2_and_writes_nothing(tmp_path, capsys, args, message):
    out = tmp_path / "deep" / "c"
    assert _compare(out, "bar1d", *args, "--levels", "2", "--n0", "10") == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
    assert not (tmp_path / "deep").exists()


def test_bad_reference_and_case_file_flags(tmp_path, capsys):
    out = tmp_path / "c"
    assert _compare(out, "bar2d", "--schemes", "cn", "--masses", "seed", "--levels", "2", "--reference", "5") == 2
    assert "not nested" in capsys.readouterr().err
    case = str(ROOT / "examples" / "bar2d.toml")
    assert _compare(out, case, "--schemes", "cn", "--masses", "seed", "--levels", "2") == 2
    assert "does not apply to a case file" in capsys.readouterr().err
    assert not out.exists()


def test_case_file(tmp_path):
    out = tmp_path / "case"
    case = str(ROOT / "examples" / "bar2d.toml")
    assert _compare(out, case, "--schemes", "cn,be", "--masses", "standard,seed", "--jobs", "1") == 0
    res = json.loads((out / "compare.json").read_text())
    assert res["kind"] == "case" and res["levels"] == [None] and res["reference"] is None
    assert not (out / "errors.png").exists()
    for name in ("energy", "contact_force", "penetration", "cost"):
        assert (out / f"{name}.png").stat().st_size > 1000
    rows = _table((out / "compare.md").read_text())
    assert len(rows) == 4 and all(r[0].isdigit() for r in rows)
    first = dict(zip(("rank", "scheme", "mass"), rows[0][:3], strict=True))
    assert (first["scheme"], first["mass"]) == ("crank-nicolson", "seed")  # smallest drift, as in the paper
    # each pair with the control `signorini run` takes for the file (issue 52): the energy control, except the
    # standard mass (its contact chatters at every step: the steps asked for, as run says)
    control = {(p["scheme"], p["mass"]): p["metrics"]["time_control"] for p in res["pairs"]}
    assert control == {("crank-nicolson", "seed"): "energy", ("backward-euler", "seed"): "energy",
                       ("crank-nicolson", "standard"): "fixed", ("backward-euler", "standard"): "fixed"}  # fmt: skip
    runs = {(p["scheme"], p["mass"]): p["runs"][0]["summary"] for p in res["pairs"]}
    for (scheme, mass), summary in runs.items():  # the numbers of `signorini run` on the same file
        rc = main(["run", case, "--scheme", scheme, "--mass", mass, "--out", str(tmp_path / f"{scheme}-{mass}"),
                   "--quiet"])  # fmt: skip
        alone = json.loads((tmp_path / f"{scheme}-{mass}" / "summary.json").read_text())
        assert rc == 0 and alone["steps"] == summary["steps"] and alone["warnings"] == summary["warnings"]
        assert alone["energy_final"] == summary["energy_final"]
    warned = [w for s in runs.values() for w in s["warnings"]]
    assert ("## Warnings" in (out / "compare.md").read_text()) == bool(warned)


def test_pair_the_problem_refuses_is_reported_not_raised(tmp_path):
    """moment-preserving-tensor needs a generated structured grid; the tetra block is not one."""
    out = tmp_path / "c"
    case = str(ROOT / "examples" / "block3d_tetra.toml")
    assert _compare(out, case, "--schemes", "cn", "--masses", "seed,moment-preserving-tensor") == 0
    res = json.loads((out / "compare.json").read_text())
    bad = next(p for p in res["pairs"] if p["mass"] == "moment-preserving-tensor")
    assert not bad["available"] and bad["rank"] is None and "structured grid" in bad["reason"]
    row = next(r for r in _table((out / "compare.md").read_text()) if r[2] == "moment-preserving-tensor")
    assert row[0] == "n/a" and row[-1].startswith("n/a: mass 'moment-preserving-tensor' needs")
    assert all(c == "n/a" for c in row[3:-1])


def test_2d_reference_is_stated(tmp_path):
    out = tmp_path / "c"
    assert _compare(out, "bar2d", "--schemes", "cn,be", "--masses", "seed", "--levels", "2", "--T", "0.5") == 0
    md = (out / "compare.md").read_text()
    res = json.loads((out / "compare.json").read_text())
    ref = res["reference"]
    assert (ref["level"], ref["scheme"], ref["mass"], ref["factor_h"]) == (8, "crank-nicolson", "seed", 4)
    assert "crank-nicolson + seed at n = 8" in md and "4x finer in h and 4x in dt than the finest level n = 2" in md
    assert {p["label"] for p in res["pairs"]} == {"crank-nicolson / seed", "backward-euler / seed"}
    assert set(res["pairs"][0]["rates"]) == {"u_H1", "v_L2", "force"}


def test_reference_syntax():
    s, m, n = cmp.parse_reference("generalized-alpha[rho_inf=0.5]:seed:32")
    assert (s.label, m, n) == ("generalized-alpha[rho_inf=0.5]", "seed", 32)
    assert cmp.parse_reference("16")[0].name == "crank-nicolson"
    for bad in ("cn:seed", "cn:seed:x", "cn:seed:0", "cn:bogus:8"):
        with pytest.raises(InputError):
            cmp.parse_reference(bad)


def test_scheme_list_syntax_works_for_every_registry_entry():
    specs = cmp.parse_schemes(",".join(SCHEMES.names(aliases=False)))
    assert [s.name for s in specs] == SCHEMES.names(aliases=False)
    for e in SCHEMES:  # every option of every entry, at its default, in bracket form
        if e.parameters:
            text = f"{e.name}[{','.join(f'{p.name}={p.default}' for p in e.parameters)}]"
            assert cmp.parse_scheme(text).name == e.name
    spec = cmp.parse_schemes("cn, newmark[beta=0.3,gamma=0.6] ,be")[1]
    assert spec.label == "newmark[beta=0.3,gamma=0.6]" and spec.option_dict == {"beta": 0.3, "gamma": 0.6}


def _items(**columns):
    keys = list(columns)
    return [dict(zip(keys, vals, strict=True)) for vals in zip(*columns.values(), strict=True)]


def test_ranking_rule_on_synthetic_input():
    items = _items(
        error_u=[0.100, 0.105, 0.200, 0.108, None, 0.050, 0.104],
        energy_drift=[1e-2, 1e-4, 1e-6, 1e-4, 0.0, 0.5, 1e-2],
        oscillation_index=[1.0, 3.0, 1.0, 1.02, 1.0, 1.0, 1.0],
        penetration_max=[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1e-3],
    )
    ranked = cmp.rank_pairs(items)
    order = [r["index"] for r in ranked]
    # 5 (error 0.05) alone in the best band, whatever its drift; then the band 0.100 .. 0.110:
    # drift 1e-4 (1, 3) before 1e-2 (0, 6); 3 before 1 by the oscillation index (1.02 vs 3);
    # 0 before 6 by the penetration; then 2 (error 0.2); the missing error (4) last
    assert order == [5, 3, 1, 0, 6, 2, 4]
    by = {r["index"]: r for r in ranked}
    assert [by[i]["rank"] for i in order] == [1, 2, 3, 4, 5, 6, 7]
    assert by[5]["decided_by"] == "error_u" and by[3]["decided_by"] == "oscillation_index"
    assert by[1]["decided_by"] == "energy_drift" and by[0]["decided_by"] == "penetration_max"
    assert by[4]["decided_by"] is None


def test_ranking_ties_share_a_rank_and_tolerances_are_absolute_too():
    items = _items(
        error_u=[0.1, 0.1 * 1.05, 0.1],
        energy_drift=[1e-12, 5e-10, 2e-3],  # both below 1e-9: tied
        oscillation_index=[1.0, 1.04, 1.0],  # within 0.05: tied
        penetration_max=[1e-18, 3e-17, 0.0],  # below 1e-12 x length: tied
    )
    ranked = cmp.rank_pairs(items)
    assert [(r["index"], r["rank"]) for r in ranked] == [(0, 1), (1, 1), (2, 3)]
    assert ranked[0]["decided_by"] == "tie" and ranked[1]["decided_by"] == "energy_drift"
    # a larger body makes a larger penetration a tie; a smaller one separates it
    items = _items(error_u=[0.1, 0.1], energy_drift=[0.0, 0.0], oscillation_index=[1, 1], penetration_max=[0, 1e-9])
    assert [r["rank"] for r in cmp.rank_pairs(items, length_scale=1e4)] == [1, 1]
    assert [r["rank"] for r in cmp.rank_pairs(items, length_scale=1.0)] == [1, 2]
    # case files: no error key
    keys = tuple(k for k in cmp.RANK_KEYS if k[0] != "error_u")
    items = _items(energy_drift=[0.3, 0.1], oscillation_index=[1, 1], penetration_max=[0, 0])
    assert [r["index"] for r in cmp.rank_pairs(items, keys)] == [1, 0]


def test_help_lists_the_options(capsys):
    with pytest.raises(SystemExit):
        main(["compare", "--help"])
    text = re.sub(r"-\n\s+", "-", capsys.readouterr().out)  # argparse wraps at hyphens
    for flag in ("--schemes", "--masses", "--levels", "--n0", "--reference", "--T", "--ratio", "--set", "--jobs"):
        assert flag in text
    assert all(name in text for name in SCHEMES.names())
    assert "moment-preserving-tensor" in text and "n/a" in text


def test_too_large_a_matrix_is_refused_with_its_estimate(tmp_path, capsys):
    out = tmp_path / "deep" / "c"
    args = ["bar2d", "--schemes", "cn,be", "--masses", "seed,standard", "--levels", "3", "--max-memory", "0.2"]
    assert _compare(out, *args) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "this comparison is large: 13 runs" in err
    assert "fields held for the errors" in err and "kept fields of all runs" in err and "--max-memory 0.2 GiB" in err
    assert not (tmp_path / "deep").exists()
    assert _compare(out, *args[:-2], "--max-steps", "100") == 2  # the finest level has 160 steps, the reference 640
    assert "more than --max-steps 100 steps" in capsys.readouterr().err
    assert not (tmp_path / "deep").exists()


def test_the_compare_estimate_counts_the_kept_fields():
    from signorini.dynamics.stepping.budget import estimate_run

    pairs = cmp.make_pairs(cmp.parse_schemes("cn,be"), cmp.parse_masses("seed,standard"))
    plan = cmp.plan_benchmark("bar2d", pairs, 2, T=0.5)
    est = cmp.estimate_plan(plan, 1)
    b = plan.target.bench
    jobs = cmp.make_jobs(plan)
    fields = [16.0 * b.mesh_counts(j.level)[0] * 2 * (round(j.T / j.dt) + 1) for j in jobs]  # U, V of every level
    assert est.kept_fields_bytes == pytest.approx(sum(fields), rel=1e-14, abs=0)  # measured 0
    assert est.held_bytes == est.kept_fields_bytes  # 2D: every run's fields come back for the errors
    bare = [estimate_run(*b.mesh_counts(j.level), 2, b.contact_count(j.level), round(j.T / j.dt)) for j in jobs]
    assert est.total_bytes == pytest.approx(
        max(r.total_bytes for r in bare) + 2 * max(fields) + sum(fields), rel=1e-14, abs=0
    )  # measured 0
    longer = cmp.estimate_plan(cmp.plan_benchmark("bar2d", pairs, 2, T=1.0), 1)
    # grows with the levels kept (measured 8.2e-3: not exactly linear in T)
    assert longer.kept_fields_bytes == pytest.approx(2 * est.kept_fields_bytes, rel=0.01, abs=0)
    assert longer.total_bytes > est.total_bytes
    assert cmp.estimate_plan(plan, 2).running_bytes > est.running_bytes  # two runs at once
    one_d = cmp.estimate_plan(cmp.plan_benchmark("bar1d", pairs, 2, 10, 1.0), 2)
    assert one_d.held_bytes == 0 and one_d.kept_fields_bytes > 0  # 1D: errors in the worker


SCHEMES_3D = "crank-nicolson,backward-euler,moreau-jean[theta=1]"
TINY_3D = ["--levels", "2", "--n0", "1", "--reference", "4", "--T", "0.5"]


@pytest.fixture(scope="module")
def bar3d_report(tmp_path_factory):
    return _report(tmp_path_factory, "bar3d", SCHEMES_3D, TINY_3D)


def test_compare_bar3d_table_is_the_json_ranking(bar3d_report):
    out, md, res = bar3d_report
    assert res["dim"] == 3 and res["levels"] == [1, 2] and res["contact_norm"] == "force"
    ref = res["reference"]
    assert (ref["level"], ref["scheme"], ref["mass"], ref["factor_h"]) == (4, "crank-nicolson", "seed", 2)
    assert "only 2x finer" in md  # the warning is stated
    rows, ranked = _table(md), cmp.ranked_pairs(res)
    assert len(rows) == len(ranked) == 6 and all(p["available"] for p in ranked)
    assert [(r[1], r[2]) for r in rows] == [(p["scheme_label"], p["mass"]) for p in ranked]
    for r, p in zip(rows, ranked, strict=True):
        m = p["metrics"]
        assert r[0] == str(p["rank"])
        assert r[3] == format(m["error_u"], ".3e") and r[5] == format(m["error_v"], ".3e")
        assert r[4] == format(p["rates"]["u_H1"], ".2f") and r[7] == format(m["energy_drift"], ".2e")
        assert r[8] == format(m["oscillation_index"], ".3f") and r[9] == format(m["penetration_max"], ".2e")
        assert m["energy_drift"] == p["runs"][-1]["summary"]["energy_max_relative_drift"]
    assert [int(r[0]) for r in rows] == sorted(int(r[0]) for r in rows)
    # the velocity-level scheme penetrates, the exact-contact ones do not
    pen = {(p["scheme"], p["mass"]): p["metrics"]["penetration_max"] for p in ranked}
    assert (
        pen[("moreau-jean", "standard")] > 1e-3
        and max(pen[("crank-nicolson", m)] for m in ("standard", "seed")) < 1e-15
    )


@pytest.mark.parametrize(
    "scheme, options, mass", [("crank-nicolson", [], "standard"), ("moreau-jean", ["theta=1"], "seed")]
)
def test_compare_bar3d_numbers_equal_those_of_run(bar3d_report, tmp_path, scheme, options, mass):
    """Diagnostics equal those of ``signorini run``; errors equal relative_errors of the same runs."""
    from signorini.dynamics.stepping.simulate import simulate
    from signorini.studies.benchmarks import get_benchmark
    from signorini.studies.reference_study import Reference, relative_errors

    _, _, res = bar3d_report
    pair = next(p for p in res["pairs"] if p["scheme"] == scheme and p["mass"] == mass)
    finest = pair["runs"][-1]
    args = ["run", "bar3d", "--scheme", scheme, "--mass", mass, "--n", "2", "--dt", repr(finest["dt"]), "--T", "0.5"]
    args += [a for o in options for a in ("--scheme-option", o)] + ["--out", str(tmp_path / "r"), "--quiet"]
    assert main(args) == 0
    s = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert finest["summary"]["steps"] == s["steps"] == 20
    for key in ("energy_final", "energy_max_relative_drift", "penetration_max", "oscillation_index", "impulse"):
        assert finest["summary"][key] == pytest.approx(s[key], rel=1e-14, abs=1e-300), key  # measured 0
    b = get_benchmark("bar3d")
    p_ref, p2 = b.problem(4), b.problem(2)
    H_ref = simulate(p_ref, "crank-nicolson", b.h(4) / 2, 0.5, mass="seed", snapshot_every=1)
    ref = Reference("bar3d", 4, "crank-nicolson", "seed", H_ref, p_ref, b.h(4), {})
    opts = dict(o.split("=") for o in options)
    H = simulate(p2, scheme, finest["dt"], 0.5, mass=mass, snapshot_every=1, scheme_options=opts)
    errors = relative_errors(H, p2.mesh, ref, 0.5)
    for key in ("u_H1", "v_L2", "force"):
        assert finest["errors"][key] == pytest.approx(errors[key], rel=1e-14, abs=0), key  # measured 0

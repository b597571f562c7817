"""The 2D/3D convergence machinery: default reference, reference checks, transfer operators."""

import numpy as np
import pytest

from signorini.dynamics.stepping.simulate import simulate
from signorini.errors import InputError
from signorini.fem.mesh import box, rectangle
from signorini.io.cli import main
from signorini.studies.benchmarks import get_benchmark
from signorini.studies.reference_study import (
    convergence_study,
    pair_rates,
    prolong,
    rate_comparison,
    reference_run,
    study,
    table_markdown,
    time_interpolate,
)


def test_default_reference_is_four_times_finer_than_the_finest_level():
    r = study("bar2d", "be", "seed", n0=1, levels=2, T=0.5)
    ref = r["reference"]
    assert ref["level"] == 4 * 2 and r["ref_level"] == 8
    assert ref["factor_h"] == 4 and ref["factor_dt"] == pytest.approx(4, rel=1e-14, abs=0)  # measured 0
    assert ref["dt"] == pytest.approx(0.5 * get_benchmark("bar2d").h(8), rel=1e-14, abs=0)  # measured 0
    md = table_markdown(r)
    assert "at n = 8" in md and "4x finer in h" in md and "than the finest level n = 2" in md


def test_reference_too_short_in_time():
    ref = reference_run("bar2d", 4, "cn", "seed", T=0.5)
    with pytest.raises(InputError, match="before the study's T"):
        convergence_study("bar2d", "cn", "seed", [1], T=1.0, reference=ref)


@pytest.mark.parametrize(
    "match, levels, ref_level, ref_args",
    [
        ("not nested", [2, 3], 8, None),  # a reference level the study levels do not divide
        ("not nested", [1, 3], None, (4, 0.5)),  # a reference run, same defect
        ("not finer", [1, 2], 2, None),  # the reference is the finest level itself
        ("not finer", [1, 2], None, (2, 0.5)),
        ("time step", [1, 2], None, (4, 2.0)),  # finer mesh but a coarser time step
    ],
)
def test_reference_must_be_nested_and_finer(match, levels, ref_level, ref_args):
    """By --ref-level or by a reference run (level, dt/h): a clear InputError."""
    ref = None if ref_args is None else reference_run("bar2d", ref_args[0], "cn", "seed", T=0.2, ratio=ref_args[1])
    with pytest.raises(InputError, match=match):
        convergence_study("bar2d", "cn", "seed", levels, ref_level=ref_level, T=0.2, reference=ref)


def test_reference_history_without_snapshots_is_refused():
    b = get_benchmark("bar2d")
    H = simulate(b.problem(4), "cn", b.h(4) / 2, 0.2, mass="seed")
    with pytest.raises(InputError, match="snapshots"):
        convergence_study("bar2d", "cn", "seed", [1], ref_level=4, T=0.2, reference=H)


def test_cli_study_reference_errors(tmp_path):
    assert main(["study", "bar2d", "--levels", "2", "--ref-level", "2", "--out", str(tmp_path / "a")]) == 2
    assert main(["study", "bar2d", "--levels", "3", "--ref-level", "6", "--out", str(tmp_path / "b")]) == 2
    assert main(["study", "bar1d", "--ref-level", "160", "--out", str(tmp_path / "c")]) == 2
    assert not any((tmp_path / d).exists() for d in "abc")


def test_check_references_and_rate_comparison():
    r = study("bar2d", "be", "seed", n0=1, levels=2, T=0.5, check_ref_levels=(4, 16))
    assert [c["reference"]["level"] for c in r["checks"]] == [4, 16]
    # every check reference compares the levels coarser than itself
    assert [row["n"] for row in r["checks"][0]["rows"]] == [1, 2]
    rates = pair_rates(r)
    factors = sorted({x["factor"] for x in rates if x["norm"] == "u_H1"})
    assert factors == [2, 4, 8]
    comp = rate_comparison(r, ["u_H1"])
    assert [c["factors"] for c in comp] == [(2, 4), (4, 8)]
    by = {x["factor"]: x["rate"] for x in rates if x["norm"] == "u_H1"}
    assert comp[0]["max_diff"] == pytest.approx(abs(by[4] - by[2]), rel=1e-14, abs=0)  # measured 0
    md = table_markdown(r)
    assert "ref n = 4" in md and "ref n = 16" in md and "4x vs 8x finer" in md


def _bilinear(p, dim):
    x, y = p[:, 0], p[:, 1]
    return np.stack([1 + 2 * x - y + 3 * x * y] + [x * y - y] * (dim - 1), 1).ravel()


def test_prolongation_is_exact_for_bilinear_fields():
    for coarse, fine, dim in ((rectangle(2, 3, 0.1, 1.0), rectangle(4, 12, 0.1, 1.0), 2),
                              (box(1, 2, 2, 0.1, 0.2, 1.0), box(2, 4, 6, 0.1, 0.2, 1.0), 3)):  # fmt: skip
        out = prolong(coarse.grid, fine.grid, _bilinear(coarse.points, dim)[None, :], dim)
        assert np.allclose(out[0], _bilinear(fine.points, dim), rtol=0, atol=1e-14)  # values <= 1.2: measured 2.2e-16


def _biquadratic(p, dim):
    x, y = p[:, 0], p[:, 1]
    z = p[:, 2] if dim == 3 else 0.0
    f = 1 + 2 * x - y + 3 * x * y + 5 * x * x * y * y - 2 * y * y + (x * x * z * z if dim == 3 else 0.0)
    return np.stack([f] + [x * x - y * y + z] * (dim - 1), 1).ravel()


def test_quadratic_prolongation_is_exact_for_q2_fields_and_not_for_q1():
    """Issue 54: levels of quad9 / hexahedron27 cells (elevated, numbered vertices first) prolonged with their own
    shape functions: a field in Q2 on the coarse cells is reproduced at every node of the nested fine level; the
    Q1 interpolation of the same nodes (a linear lattice of them) is not exact."""
    from signorini.studies.reference_study import Lattice, lattice, lattice_prolongation

    cases = ((rectangle(2, 3, 0.1, 1.0, order=2), rectangle(4, 12, 0.1, 1.0, order=2), 2, (2, 3)),
             (box(1, 2, 2, 0.1, 0.2, 1.0, order=2), box(2, 4, 4, 0.1, 0.2, 1.0, order=2), 3, (1, 2, 2)))  # fmt: skip
    for coarse, fine, dim, cells in cases:
        c, f = lattice(coarse), lattice(fine)
        assert c.order == f.order == 2 and [a.size for a in c.axes] == [2 * n + 1 for n in cells]
        P = lattice_prolongation(c, f, dim)
        out = P @ _biquadratic(coarse.points, dim)
        ref = _biquadratic(fine.points, dim)
        assert np.allclose(out, ref, rtol=0, atol=1e-13 * np.abs(ref).max())  # measured 4.4e-16 of the largest
        as_q1 = lattice_prolongation(Lattice(c.axes, 1, c.index), Lattice(f.axes, 1, f.index), dim)
        assert np.abs(as_q1 @ _biquadratic(coarse.points, dim) - ref).max() > 1e-6


def test_a_mesh_without_a_tensor_lattice_is_refused_by_name():
    from signorini.errors import InputError
    from signorini.studies.reference_study import lattice

    with pytest.raises(InputError, match="tensor grid"):
        lattice(rectangle(2, 2, 1.0, 1.0, "triangle", order=2))


def test_time_interpolation_linear():
    t_c = np.linspace(0, 1, 5)
    field = np.stack([3 * t_c - 1, t_c], 1)
    t_f = np.linspace(0, 1, 17)
    assert np.allclose(time_interpolate(t_c, field, t_f), np.stack([3 * t_f - 1, t_f], 1), rtol=0, atol=1e-14)  # 0


def test_cli_study_with_check_reference(tmp_path):
    out = tmp_path / "s"
    args = ["study", "bar2d", "--scheme", "be", "--levels", "2", "--T", "0.5", "--quiet"]
    assert main([*args, "--check-ref-level", "4", "--out", str(out)]) == 0
    md = (out / "study.md").read_text()
    assert "Reference: be + moment-preserving at n = 8" in md and "4x finer in h" in md  # the default mass
    assert "ref n = 4" in md and "references 2x vs 4x finer" in md
    import csv
    import json

    rows = list(csv.DictReader(open(out / "study.csv")))
    assert [r["reference_level"] for r in rows] == ["8", "8"]
    assert json.loads((out / "study.json").read_text())["checks"][0]["reference"]["level"] == 4
    # a check reference finer than only one level gives no rate: refused
    assert main([*args, "--check-ref-level", "2", "--out", str(tmp_path / "t")]) == 2
    assert not (tmp_path / "t").exists()

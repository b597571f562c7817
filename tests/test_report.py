import json

from signorini.io.cli import main


def test_reproduce_tiny_writes_report(tmp_path):
    out = tmp_path / "rep"
    assert main(["reproduce", "--tiny", "--out", str(out), "--quiet"]) == 0
    text = (out / "report.md").read_text()
    for fig in ("fig_contact_2d", "fig_energy_2d", "fig_convergence_2d", "fig_von_mises_3d"):
        assert (out / f"{fig}.png").stat().st_size > 1000
        assert (out / f"{fig}.csv").exists()
        assert fig in text
    s = json.loads((out / "summary.json").read_text())
    h = s["bar2d_histories"]
    # the paper's claims, measured: CN + standard oscillates and gains energy, BE dissipates
    assert h["crank-nicolson/standard"]["energy_max_ratio"] > 1.5
    assert h["crank-nicolson/seed"]["energy_max_ratio"] < 1.01
    assert h["crank-nicolson/standard"]["oscillation_index"] > 2 * h["crank-nicolson/seed"]["oscillation_index"]
    assert h["backward-euler/seed"]["energy_ratio_final"] < 1.0
    for v in h.values():
        assert v["max_complementarity_residual"] < 1e-10

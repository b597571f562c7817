"""A run that violates the contact constraint ranks below every run that respects it."""

from signorini.studies.compare import CONTACT_TOLERANCE, rank_result


def _pair(label, drift, pen, untagged=0.0):
    metrics = {"energy_drift": drift, "oscillation_index": 1.0, "penetration_max": pen}
    metrics["untagged_penetration_max"] = untagged
    return {"label": label, "available": True, "metrics": metrics}


def test_penetration_beyond_the_tolerance_ranks_last_whatever_its_energy():
    result = {
        "kind": "case",
        "length_scale": 2.0,
        "pairs": [
            _pair("penetrates 2%", 1e-12, 0.04),  # the best drift, but 2% of the gap inside the obstacle
            _pair("exact", 1e-3, 1e-17),
            _pair("untagged inside", 1e-6, 0.0, untagged=0.01),
            _pair("round-off", 1e-2, 0.5 * CONTACT_TOLERANCE * 2.0),
        ],
    }
    order = rank_result(result)["ranking"]["order"]
    assert order[:2] == ["round-off", "exact"] or order[:2] == ["exact", "round-off"]
    assert set(order[2:]) == {"penetrates 2%", "untagged inside"}
    ranked = {p["label"]: p for p in result["pairs"]}
    assert ranked["exact"]["rank"] < ranked["penetrates 2%"]["rank"]
    assert "Lexicographic" not in result["ranking"]["rule"].split(".")[0]

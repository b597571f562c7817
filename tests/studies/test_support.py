"""docs/support.md, the generated table of material model x scheme x mass (issue 41): it is the code's
(regenerated and compared), and every combination either runs with its identity closed or is refused by
name (no run fails, no cell is empty)."""

from __future__ import annotations

from pathlib import Path

from signorini.dynamics.model.mass import MASS_VARIANTS
from signorini.dynamics.schemes import SCHEMES
from signorini.studies import support


def test_the_support_table_is_the_codes_and_every_cell_runs_or_is_refused_by_name():
    text = support.render()
    stale = "docs/support.md is out of date: python -m signorini.studies.support --write"
    assert text == (Path(__file__).parents[2] / "docs" / "support.md").read_text(), stale  # the repository's
    rows = [line for line in text.splitlines() if line.startswith("| `")]
    cells = [c.strip() for line in rows for c in line.strip("|").split("|")[1:]]
    assert len(cells) == len(support.MATERIAL_MODELS) * len(list(SCHEMES)) * len(list(MASS_VARIANTS))
    assert all(c.startswith("✓") or (c.startswith("[") and c.endswith("]")) for c in cells), cells
    notes = [line for line in text.splitlines() if line[:1].isdigit()]
    assert notes and not any(n.split(". ", 1)[1].startswith(("failed", "runs")) for n in notes), notes
    # energy-momentum runs every model with the default mass
    em = [line for line in rows if line.startswith("| `energy-momentum`")]
    assert len(em) == 3 and all(line.split("|")[6].strip() == "✓" for line in em), em

"""docs/architecture.md stays true: every module it names exists, and its layer list is the one
tests/test_layout.py enforces."""

import re
from pathlib import Path

from test_layout import LAYERS

ROOT = Path(__file__).parents[1]
DOC = (ROOT / "docs" / "architecture.md").read_text()


def test_every_module_named_exists():
    named = set(re.findall(r"`(signorini/[\w/]+(?:\.py|/))`", DOC))
    assert len(named) >= 30
    missing = [m for m in sorted(named) if not (ROOT / "src" / m).exists()]
    assert missing == []


def test_the_layers_are_the_layout_tests():
    (line,) = re.findall(r"<!-- layers: ([a-z ]+) -->", DOC)
    assert line.split() == LAYERS
    rows = re.findall(r"^\| ([a-z]+) \| ", DOC, flags=re.M)
    assert [r for r in rows if r != "layer"] == LAYERS


def test_it_answers_the_newcomers_three_questions():
    for question in ("**The loop**", "**B**", "**Dof numbers**"):
        assert question in DOC

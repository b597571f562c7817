"""docs/architecture.md stays true: every module it names exists, every module is in its generated module map,
every package folder is named, every name it places in a module is defined there, and its layer list is the one
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


def test_every_package_folder_is_named():
    named = set(re.findall(r"`(signorini/[\w/]+/)`", DOC))
    src = ROOT / "src"
    rooms = {str(p.parent.relative_to(src)) + "/" for p in (src / "signorini").rglob("__init__.py")}
    assert sorted(rooms - named - {"signorini/"}) == []


#: a name said to be in a module: `Name` (`signorini/...py`), `Name` in `signorini/...py`, `Name` (`signorini/...py`:
CLAIM = re.compile(r"`([A-Za-z_]\w*)`(?: \(| in )`(signorini/[\w/]+\.py)`")


def test_every_name_placed_in_a_module_is_defined_there():
    claims = CLAIM.findall(DOC)
    assert len(claims) >= 15  # measured 2026-12-06: 16
    wrong = []
    for name, module in claims:
        text = (ROOT / "src" / module).read_text()
        if not re.search(rf"^\s*(class|def)\s+{name}\b|^{name}\s*[:=]", text, re.M):
            wrong.append((name, module))
    assert wrong == []


def test_the_claim_check_can_fail():
    ((name, module),) = CLAIM.findall("the `NoSuchClass` (`signorini/fem/mesh.py`) ...")
    text = (ROOT / "src" / module).read_text()
    assert not re.search(rf"^\s*(class|def)\s+{name}\b|^{name}\s*[:=]", text, re.M)


def test_every_module_is_in_the_module_map_with_a_line_of_its_own():
    """Issue 53, item 4: the page's table names every module of the package (generated from the docstrings)."""
    import sys

    sys.path.insert(0, str(ROOT / "scripts"))
    import module_map

    assert module_map.render() in DOC, "run python3 scripts/module_map.py --write"
    rows = module_map.rows()
    assert len(rows) == len(list((ROOT / "src" / "signorini").rglob("*.py")))
    assert [m for m, line in rows if not line] == []  # a module without a docstring fails here

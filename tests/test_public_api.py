"""The curated public API of ``signorini`` (issue 39, item 5): every listed name resolves to the
object its module defines, ``import signorini`` stays light, and the README's and tutorial's
examples import from it."""

import importlib
import subprocess
import sys
from pathlib import Path

import pytest

import signorini

ROOT = Path(__file__).parents[1]


@pytest.mark.parametrize("name", sorted(signorini._PUBLIC))
def test_each_public_name_is_its_modules_object(name):
    module = importlib.import_module(f"signorini.{signorini._PUBLIC[name]}")
    assert getattr(signorini, name) is getattr(module, name)
    assert name in signorini.__all__ and name in dir(signorini)


def test_an_unknown_name_is_an_attribute_error():
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        signorini.nope  # noqa: B018


def test_import_signorini_loads_no_solver_module():
    """The command line imports the package first: the API must not load numpy's users at once."""
    code = "import sys, signorini; print(sorted(m for m in sys.modules if m.startswith('signorini')))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "['signorini']"


def test_the_readme_and_tutorial_examples_use_the_public_api():
    for f in ("api_bar2d.py", "tutorial_bar2d.py", "tutorial_stepper.py"):
        text = (ROOT / "examples" / f).read_text()
        assert "from signorini import " in text, f

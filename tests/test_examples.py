"""The Python examples of the README and the tutorial: files in ``examples/`` that the docs
show verbatim (each block follows a ``<!-- example: FILE ... -->`` marker) and that run here,
their output meaningful."""

import re
import runpy
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).parents[1]
DOCS = ("README.md", "docs/tutorial.md")
MARKED = r"<!-- example: (\S+) \(the file, verbatim\) -->\n```python\n(.*?)```"


@pytest.mark.parametrize("doc", DOCS)
def test_every_python_block_of_the_docs_is_an_example_file_verbatim(doc):
    text = (ROOT / doc).read_text()
    marked = re.findall(MARKED, text, re.S)
    assert len(marked) == len(re.findall(r"```python\n", text))  # no unmarked (untested) block
    for path, code in marked:
        assert (ROOT / path).read_text() == code, f"{doc} shows an outdated copy of {path}"


def _run(path: str, capsys) -> str:
    runpy.run_path(str(ROOT / path), run_name="__main__")
    return capsys.readouterr().out


def test_readme_python_example(capsys):
    out = _run("examples/api_bar2d.py", capsys).splitlines()
    ratios = {line.split()[0]: float(line.split()[3]) for line in out}
    assert ratios["standard"] > 1.5 and abs(ratios["seed"] - 1) < 0.01


def test_tutorial_example(capsys):
    lines = _run("examples/tutorial_bar2d.py", capsys).splitlines()
    std, seed = (
        {k.strip(): v for k, v in re.findall(r"(E\(T\)/E\(0\)|first contact t|TV\(force\)) = ([\d.]+)", line)}
        for line in lines
    )
    assert float(std["E(T)/E(0)"]) > 1.5 and abs(float(seed["E(T)/E(0)"]) - 1) < 0.01
    assert float(std["TV(force)"]) > 3 * float(seed["TV(force)"])


def test_tutorial_friction_example(capsys):
    """The sliding acceleration it prints is the closed form g (sin 30 - 0.3 cos 30)."""
    out = _run("examples/tutorial_slope.py", capsys)
    accel = float(re.search(r"x_G'' = ([\d.]+)", out).group(1))
    g_sin, g_cos = np.sin(np.radians(30.0)), np.cos(np.radians(30.0))
    assert abs(accel / (g_sin - 0.3 * g_cos) - 1) <= 1e-6
    assert "stick / slip nodes at the end: 0 9" in out

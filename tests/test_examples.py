"""The README's Python example runs and its output is meaningful."""

import re
from pathlib import Path

import numpy as np


def test_readme_python_example(capsys):
    text = (Path(__file__).parents[1] / "README.md").read_text()
    code = re.search(r"```python\n(.*?)```", text, re.S).group(1)
    exec(compile(code, "README", "exec"), {})
    out = capsys.readouterr().out.splitlines()
    ratios = {line.split()[0]: float(line.split()[3]) for line in out}
    assert ratios["standard"] > 1.5 and abs(ratios["seed"] - 1) < 0.01


def test_tutorial_friction_example(capsys):
    """The tutorial's second block: the sliding acceleration it prints is the closed form."""
    text = (Path(__file__).parents[1] / "docs" / "tutorial.md").read_text()
    code = re.findall(r"```python\n(.*?)```", text, re.S)[1]
    exec(compile(code, "tutorial-friction", "exec"), {})
    out = capsys.readouterr().out
    accel = float(re.search(r"x_G'' = ([\d.]+)", out).group(1))
    g_sin, g_cos = np.sin(np.radians(30.0)), np.cos(np.radians(30.0))
    assert abs(accel / (g_sin - 0.3 * g_cos) - 1) <= 1e-6
    assert "stick / slip nodes at the end: 0 9" in out


def test_tutorial_example(capsys):
    text = (Path(__file__).parents[1] / "docs" / "tutorial.md").read_text()
    code = re.search(r"```python\n(.*?)```", text, re.S).group(1)
    exec(compile(code, "tutorial", "exec"), {})
    lines = capsys.readouterr().out.splitlines()
    std, seed = (
        {k.strip(): v for k, v in re.findall(r"(E\(T\)/E\(0\)|first contact t|TV\(force\)) = ([\d.]+)", line)}
        for line in lines
    )
    assert float(std["E(T)/E(0)"]) > 1.5 and abs(float(seed["E(T)/E(0)"]) - 1) < 0.01
    assert float(std["TV(force)"]) > 3 * float(seed["TV(force)"])

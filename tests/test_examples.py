"""The README's Python example runs and its output is meaningful."""

import re
from pathlib import Path


def test_readme_python_example(capsys):
    text = (Path(__file__).parents[1] / "README.md").read_text()
    code = re.search(r"```python\n(.*?)```", text, re.S).group(1)
    exec(compile(code, "README", "exec"), {})
    out = capsys.readouterr().out.splitlines()
    ratios = {line.split()[0]: float(line.split()[3]) for line in out}
    assert ratios["standard"] > 1.5 and abs(ratios["seed"] - 1) < 0.01


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

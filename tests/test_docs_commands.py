"""Every command line of the README, docs/tutorial.md and docs/cli.md runs as written.

The lines are every non-comment line of every ``bash`` block of those files (not a
block picked by its position): a command added to the docs is tested without editing
this file.  They run in a scratch directory that sees the repository's ``examples/``,
``benchmarks/`` and ``.venv-mpi/`` as the docs assume (the working directory is the
source tree), with this interpreter's ``bin`` first on PATH.  The README's two commands
(``pip install`` then the main job or the tests) are run verbatim by ``.ci/run`` in a
fresh virtual environment; here it is checked that ``.ci/run`` runs exactly those lines.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).parents[1]
DOCS = ("README.md", "docs/tutorial.md", "docs/cli.md")
#: command lines that take more than ~10 s (the main job's study, the performance suite)
SLOW = ("signorini reproduce", "python3 -m benchmarks")


def command_lines(doc: str) -> list[str]:
    """The non-empty, non-comment lines of every ```bash block of ``doc``."""
    text = (ROOT / doc).read_text()
    blocks = re.findall(r"^```bash\n(.*?)^```", text, re.S | re.M)
    return [
        line.strip() for b in blocks for line in b.splitlines() if line.strip() and not line.lstrip().startswith("#")
    ]


def _params() -> list:
    out = []
    for doc in DOCS:
        for line in command_lines(doc):
            if line.startswith("python3 -m pip install"):
                continue  # the README's two commands: .ci/run (test below)
            marks = [pytest.mark.slow] if line.startswith(SLOW) else []
            if line.startswith(".venv-mpi/"):
                marks.append(pytest.mark.skipif(not (ROOT / ".venv-mpi").is_dir(),
                                                reason="no .venv-mpi: run `bash scripts/mpi-env.sh`"))  # fmt: skip
            if re.search(r"\bhertz[23]d\b", line):
                from backends import needs_gmsh

                marks.append(needs_gmsh)
            out.append(pytest.param(line, id=f"{doc}:{line.split(' --out')[0][:60]}", marks=marks))
    return out


@pytest.mark.parametrize("line", _params())
def test_the_command_line_runs_as_written(tmp_path, line):
    for name in ("examples", "benchmarks", ".venv-mpi"):
        if (ROOT / name).exists():
            (tmp_path / name).symlink_to(ROOT / name)
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}",
           "OMP_NUM_THREADS": "1"}  # fmt: skip
    r = subprocess.run(["bash", "-c", line], cwd=tmp_path, env=env, capture_output=True, text=True,
                       stdin=subprocess.DEVNULL, timeout=900)  # fmt: skip
    assert r.returncode == 0, f"{line}\n{r.stdout[-2000:]}\n{r.stderr[-2000:]}"
    outs = [a for a in (shlex.split(line, comments=True)) if a.startswith(("out/", "results"))]
    for out in outs:  # what it said it writes is there, complete (the marker of a finished result)
        assert (tmp_path / out / ".signorini").exists(), out


def test_ci_runs_the_readme_two_commands_verbatim():
    """The README's two commands are the lines .ci/run runs in its fresh virtual environment."""
    readme = [line for line in command_lines("README.md") if line.startswith("python3 -m pip install")]
    assert len(readme) == 2 and "signorini reproduce" in readme[0] and "pytest" in readme[1]
    ci = (ROOT / ".ci" / "run").read_text().splitlines()
    plain = ci[ci.index("# --- a new user: the plain install in a fresh virtual environment ---") :]
    for line in readme:
        assert any(c.strip() == line for c in plain), line

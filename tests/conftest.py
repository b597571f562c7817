import sys
from pathlib import Path

import numpy as np
import pytest

# the tests live in folders that mirror the package (tests/fem, tests/contact, tests/dynamics/solve, ...); a test
# module may use another's helpers by its name (``from test_pairs import bars``), wherever it lives
_here = Path(__file__).parent
for _folder in sorted(p for p in _here.rglob("*") if p.is_dir() and "data" not in p.relative_to(_here).parts
                      and "__pycache__" not in p.parts):  # fmt: skip
    if str(_folder) not in sys.path:
        sys.path.insert(0, str(_folder))


@pytest.fixture
def rng():
    return np.random.default_rng(1234)


def pytest_sessionfinish(session, exitstatus):
    """With SIGNORINI_NO_SKIPS=1 (CI, where every extra is installed) a skipped test fails the run.

    A failed install must not turn into a green build: every optional backend, gmsh, GetFEM
    and the tmpfs mount are expected on CI's machine, so any skip is reported and fails.
    """
    import os

    if os.environ.get("SIGNORINI_NO_SKIPS") != "1":
        return
    reporter = session.config.pluginmanager.get_plugin("terminalreporter")
    skipped = reporter.stats.get("skipped", []) if reporter is not None else []
    if skipped:
        for rep in skipped:
            reason = rep.longrepr[2] if isinstance(rep.longrepr, tuple) else str(rep.longrepr)
            reporter.write_line(f"SIGNORINI_NO_SKIPS: skipped {rep.nodeid}: {reason}", red=True)
        reporter.write_line(f"SIGNORINI_NO_SKIPS=1: {len(skipped)} test(s) skipped; expected none", red=True)
        session.exitstatus = pytest.ExitCode.TESTS_FAILED


@pytest.fixture(scope="session")
def reproduced_tiny(tmp_path_factory):
    """``signorini reproduce --tiny`` run once per session (read-only for the tests that use it)."""
    from signorini.io.cli import main

    out = tmp_path_factory.mktemp("reproduce_tiny") / "out"
    assert main(["reproduce", "--tiny", "--out", str(out), "--quiet"]) == 0
    return out

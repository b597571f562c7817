"""Every tolerance comparison in the tests states both of its tolerances.

``np.allclose(a, b, atol=1e-12)`` silently keeps numpy's ``rtol=1e-5``, and
``np.isclose(a, b, rtol=1e-12)`` keeps ``atol=1e-8``: on a quantity of size 5e-5 the
second one checks 2e-4 relative, not 1e-12.  ``pytest.approx`` has the same two defaults
(``rel=1e-6``, ``abs=1e-12``).  So every call of np.allclose, np.isclose,
numpy.testing.assert_allclose, math.isclose and pytest.approx in tests/*.py must pass
both tolerances explicitly (``rtol=0`` / ``abs=0`` when one of them is meant to be off),
whatever name the function was imported under.
"""

import ast
from pathlib import Path

import pytest

TESTS = Path(__file__).parent

# function -> (its tolerance parameters, their positions among the positional arguments)
RULES = {
    "numpy.allclose": (("rtol", "atol"), (2, 3)),
    "numpy.isclose": (("rtol", "atol"), (2, 3)),
    "numpy.testing.assert_allclose": (("rtol", "atol"), (2, 3)),
    "math.isclose": (("rel_tol", "abs_tol"), (None, None)),  # keyword-only
    "pytest.approx": (("rel", "abs"), (1, 2)),
}

EXEMPT: set[str] = set()  # every test file is under the rule


def _imported_names(tree: ast.Module) -> dict[str, str]:
    """Local name -> dotted name, from the module's imports (``import numpy as np``,
    ``from numpy.testing import assert_allclose as close``, ...)."""
    names = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                if a.asname:
                    names[a.asname] = a.name
                else:  # ``import numpy.testing`` binds ``numpy``
                    top = a.name.split(".")[0]
                    names[top] = top
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            for a in node.names:
                names[a.asname or a.name] = f"{node.module}.{a.name}"
    return names


def _dotted(node: ast.AST, names: dict[str, str]) -> str | None:
    """The dotted name an expression like ``np.testing.assert_allclose`` refers to."""
    parts = []
    while isinstance(node, ast.Attribute):
        parts.append(node.attr)
        node = node.value
    if not isinstance(node, ast.Name) or node.id not in names:
        return None
    return ".".join([names[node.id], *reversed(parts)])


def _canonical(dotted: str | None) -> str | None:
    if dotted is None:
        return None
    if dotted.startswith("numpy.testing._private.utils."):
        dotted = "numpy.testing." + dotted.rsplit(".", 1)[1]
    return dotted if dotted in RULES else None


def violations(source: str, filename: str = "<test>") -> list[str]:
    """``file:line: message`` for every comparison that leaves a tolerance at its default."""
    tree = ast.parse(source, filename)
    names = _imported_names(tree)
    called = set()
    out = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.Call):
            continue
        fn = _canonical(_dotted(node.func, names))
        if fn is None:
            continue
        called.add(id(node.func))
        params, positions = RULES[fn]
        given = {k.arg for k in node.keywords if k.arg is not None}
        if any(k.arg is None for k in node.keywords) or any(isinstance(a, ast.Starred) for a in node.args):
            out.append(f"{filename}:{node.lineno}: {fn} with *args/**kwargs: pass {params[0]} and {params[1]} by name")
            continue
        given |= {p for p, i in zip(params, positions, strict=True) if i is not None and len(node.args) > i}
        missing = [p for p in params if p not in given]
        if missing:
            out.append(f"{filename}:{node.lineno}: {fn} without {' and '.join(missing)} (the default would decide)")
    # a reference that is not called (map(np.isclose, ...), f = pytest.approx) hides the defaults too
    for node in ast.walk(tree):
        if isinstance(node, (ast.Attribute, ast.Name)) and id(node) not in called and isinstance(node.ctx, ast.Load):
            fn = _canonical(_dotted(node, names))
            if fn is not None:
                out.append(f"{filename}:{node.lineno}: {fn} used without a call; call it with both tolerances")
    return sorted(set(out), key=lambda s: (s.split(":")[0], int(s.split(":")[1])))


def _test_files() -> list[Path]:
    return sorted(TESTS.rglob("*.py"))


def test_every_comparison_in_the_tests_states_both_tolerances():
    found = []
    for path in _test_files():
        if path.name not in EXEMPT:
            found += violations(path.read_text(), path.name)
    assert not found, "tolerances left at their defaults:\n" + "\n".join(found)


def test_the_exempt_files_exist():
    """An exemption for a file that is gone is stale: remove it from EXEMPT."""
    present = {p.name for p in _test_files()}
    assert not EXEMPT - present, sorted(EXEMPT - present)


CHECKS = [
    ("import numpy as np\nnp.allclose(a, b)", ["numpy.allclose without rtol and atol"]),
    ("import numpy as np\nnp.allclose(a, b, atol=1e-12)", ["numpy.allclose without rtol"]),
    ("import numpy as np\nnp.isclose(a, b, rtol=1e-12)", ["numpy.isclose without atol"]),
    ("import numpy as np\nnp.isclose(a, b, rtol=0, atol=1e-12)", []),
    ("import numpy as np\nnp.allclose(a, b, 1e-12, 0.0)", []),  # positional rtol, atol
    ("import numpy as np\nnp.allclose(a, b, 1e-12)", ["numpy.allclose without atol"]),
    ("import numpy as np\nnp.allclose(a, b, **tol)", ["numpy.allclose with *args/**kwargs"]),
    ("import numpy\nnumpy.testing.assert_allclose(a, b, rtol=1e-9)", ["numpy.testing.assert_allclose without atol"]),
    ("import numpy.testing as npt\nnpt.assert_allclose(a, b, atol=0)", ["numpy.testing.assert_allclose without rtol"]),
    ("from numpy.testing import assert_allclose as c\nc(a, b, rtol=0, atol=0)", []),
    ("from numpy import isclose\nisclose(a, b)", ["numpy.isclose without rtol and atol"]),
    ("import pytest\nx == pytest.approx(1.0)", ["pytest.approx without rel and abs"]),
    ("import pytest\nx == pytest.approx(1.0, rel=1e-12)", ["pytest.approx without abs"]),
    ("import pytest\nx == pytest.approx(1.0, 1e-12, 0)", []),
    ("from pytest import approx\nx == approx(1.0, abs=1e-3)", ["pytest.approx without rel"]),
    ("import math\nmath.isclose(x, 1.0, rel_tol=1e-12)", ["math.isclose without abs_tol"]),
    ("import numpy as np\nlist(map(np.isclose, a, b))", ["numpy.isclose used without a call"]),
    ("import numpy as np\nnp.array_equal(a, b)\nnp.testing.assert_array_equal(a, b)", []),
    ("def isclose(a, b):\n    return a == b\nisclose(1, 1)", []),  # a local function of that name
]


@pytest.mark.parametrize("source, expected", CHECKS)
def test_the_lint_finds_the_defaults(source, expected):
    found = violations(source)
    assert len(found) == len(expected), found
    for message, fragment in zip(found, expected, strict=True):
        assert fragment in message, (message, fragment)

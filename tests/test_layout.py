"""The package layout shows the pipeline: no module imports from a layer above it."""

import ast
from pathlib import Path

PKG = Path(__file__).parents[1] / "src" / "signorini"
LAYERS = ["core", "fem", "linalg", "contact", "dynamics", "studies", "io"]


def layer_of(path: Path) -> str:
    rel = path.relative_to(PKG).parts
    return rel[0] if len(rel) > 1 else "core"


def imported_layers(path: Path):
    tree = ast.parse(path.read_text())
    pkg_parts = list(path.relative_to(PKG).parent.parts)
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.level:
            base = pkg_parts[: len(pkg_parts) - (node.level - 1)] if node.level > 1 else pkg_parts
            target = base + (node.module.split(".") if node.module else [])
            yield (target[0] if target and target[0] in LAYERS else "core"), node.lineno
        elif isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("signorini."):
            part = node.module.split(".")[1]
            yield (part if part in LAYERS else "core"), node.lineno


def test_no_module_imports_from_a_layer_above():
    bad = []
    for path in sorted(PKG.rglob("*.py")):
        mine = LAYERS.index(layer_of(path))
        for layer, line in imported_layers(path):
            if LAYERS.index(layer) > mine:
                bad.append(f"{path.relative_to(PKG)}:{line} imports from {layer}")
    assert not bad, "\n".join(bad)


def test_optional_backends_are_not_imported_eagerly():
    """Importing the package (CLI included) and running a small case never loads pypardiso."""
    import subprocess
    import sys

    code = (
        "import sys, signorini.io.cli, signorini.linalg;"
        "from signorini.studies.benchmarks import get_benchmark;"
        "from signorini.dynamics.simulate import simulate;"
        "b = get_benchmark('bar2d'); simulate(b.problem(2), 'cn', 0.025, 0.1);"
        "print('pypardiso' in sys.modules, 'pyamg' in sys.modules)"
    )
    out = subprocess.check_output([sys.executable, "-c", code], text=True).split()
    assert out == ["False", "False"]

"""The package layout shows the pipeline: no module imports from a layer above it."""

import ast
from pathlib import Path

PKG = Path(__file__).parents[1] / "src" / "signorini"
LAYERS = ["core", "fem", "linalg", "contact", "dynamics", "studies", "io"]


def layer_of(path: Path) -> str:
    rel = path.relative_to(PKG).parts
    if rel == ("__main__.py",):  # ``python -m signorini``: the entry point, above every layer
        return LAYERS[-1]
    return rel[0] if len(rel) > 1 else "core"


def _layer(parts: list[str]) -> str:
    """The layer of a module path inside the package (``['dynamics', 'mass']`` -> dynamics)."""
    return parts[0] if parts and parts[0] in LAYERS else "core"


def imported_layers(source: str, pkg_parts: list[str]):
    """(layer, line) of every import of the package in ``source``, a module of the
    subpackage ``pkg_parts``: ``from .x import``, ``from ..x import``, ``from .. import x``,
    ``from signorini.x import``, ``from signorini import x``, ``import signorini.x``."""
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = pkg_parts[: len(pkg_parts) - (node.level - 1)] if node.level > 1 else list(pkg_parts)
            elif node.module and (node.module == "signorini" or node.module.startswith("signorini.")):
                base = []
            else:
                continue
            module = node.module.split(".") if node.module else []
            if node.level == 0:
                module = module[1:]  # drop "signorini"
            if module:
                yield _layer(base + module), node.lineno
            else:  # from .. import x / from signorini import x: x is a subpackage or module
                for alias in node.names:
                    yield _layer(base + [alias.name]), node.lineno
        elif isinstance(node, ast.Import):
            for alias in node.names:
                parts = alias.name.split(".")
                if parts[0] == "signorini":
                    yield _layer(parts[1:]), node.lineno


def test_the_checker_sees_every_import_form():
    src = (
        "import numpy\nimport signorini.io.cli\nimport signorini.studies.report as r\n"
        "from signorini import io\nfrom signorini.studies import compare\nfrom .. import studies\n"
        "from ..io.cli import main\nfrom . import mass\nfrom .schemes import base\nimport signorini\n"
    )
    got = list(imported_layers(src, ["dynamics"]))
    assert got == [
        ("io", 2),
        ("studies", 3),
        ("io", 4),
        ("studies", 5),
        ("studies", 6),
        ("io", 7),
        ("dynamics", 8),
        ("dynamics", 9),
        ("core", 10),
    ]


def test_no_module_imports_from_a_layer_above():
    bad = []
    for path in sorted(PKG.rglob("*.py")):
        mine = LAYERS.index(layer_of(path))
        for layer, line in imported_layers(path.read_text(), list(path.relative_to(PKG).parent.parts)):
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
        "from signorini.dynamics.stepping.simulate import simulate;"
        "b = get_benchmark('bar2d'); simulate(b.problem(2), 'cn', 0.025, 0.1);"
        "print('pypardiso' in sys.modules, 'pyamg' in sys.modules)"
    )
    out = subprocess.check_output([sys.executable, "-c", code], text=True).split()
    assert out == ["False", "False"]


#: the rooms of ``dynamics/`` in pipeline order: a module imports from its own room or from the rooms before it
#: (type hints under ``TYPE_CHECKING`` apart: they run no code)
ROOMS = ["model", "rows", "solve", "schemes", "observe", "restart", "stepping"]


def _upward_room_imports(pkg: Path) -> list[str]:
    bad = []
    for path in sorted((pkg / "dynamics").rglob("*.py")):
        rel = path.relative_to(pkg / "dynamics").parts
        if len(rel) < 2:
            continue
        mine, parts = rel[0], ["dynamics", *rel[:-1]]
        tree = ast.parse(path.read_text())
        hints = {id(m) for n in ast.walk(tree) if isinstance(n, ast.If) and "TYPE_CHECKING" in ast.unparse(n.test)
                 for m in ast.walk(n)}  # fmt: skip
        for node in ast.walk(tree):
            if id(node) in hints or not isinstance(node, ast.ImportFrom):
                continue
            if node.level:
                module = parts[: len(parts) - node.level + 1] + (node.module.split(".") if node.module else [])
            elif node.module and node.module.startswith("signorini.dynamics"):
                module = node.module.split(".")[1:]
            else:
                continue
            if module[:1] != ["dynamics"]:
                continue
            room = module[1] if len(module) > 1 else node.names[0].name
            if room in ROOMS and ROOMS.index(room) > ROOMS.index(mine):
                bad.append(f"dynamics/{'/'.join(rel)}:{node.lineno} ({mine}) imports from {room}")
    return bad


def test_the_rooms_of_dynamics_import_only_downward():
    """Issue 53: dynamics/ in rooms that show the pipeline, no import circle across them (lazy imports too)."""
    assert not _upward_room_imports(PKG), "\n".join(_upward_room_imports(PKG))
    rooms = sorted(p.name for p in (PKG / "dynamics").iterdir() if p.is_dir() and p.name != "__pycache__")
    assert rooms == sorted(ROOMS)
    for room in ROOMS:
        folder = PKG / "dynamics" / room
        assert (folder / "__init__.py").read_text().startswith('"""'), room  # each room says what it holds
        assert len(list(folder.glob("*.py"))) <= 15, room


def test_the_room_checker_sees_an_upward_import(tmp_path):
    for room in ("model", "stepping"):
        (tmp_path / "dynamics" / room).mkdir(parents=True)
    (tmp_path / "dynamics" / "model" / "bad.py").write_text("def f():\n    from ..stepping.setup import x\n")
    (tmp_path / "dynamics" / "stepping" / "good.py").write_text("from ..model.bad import f\n")
    assert _upward_room_imports(tmp_path) == ["dynamics/model/bad.py:2 (model) imports from stepping"]

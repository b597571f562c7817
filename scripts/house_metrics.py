"""The measures of issue 39 ("the house for what comes next"), read off the source tree.

    python3 scripts/house_metrics.py [--json]

Printed, with the places that count:

* classes with more than 20 methods (the issue asks none);
* the parameters of ``Stepper.__init__`` (at most 8);
* accesses to another object's ``_private`` attribute across modules (``x._name`` where ``x``
  is not ``self``/``cls`` and ``_name`` is not defined in the same module; none);
* ``mesh.mixed`` branches (none outside ``fem/mesh.py``, refusals apart);
* classes with a ``__getattr__`` (none: no forwarding an editor cannot follow);
* the README's lines (at most 220);
* ``d * node + c`` computed by hand outside ``fem/dofmap.py`` (``<name> * <dim> + ...`` or
  ``<dim> * <name> + ...`` with a dimension-like name: d, dim, block_size, components);
* backend names compared outside the backend choice (``== "petsc"`` and the like, ``in
  ("cg", ...)``, outside ``linalg/base.py``).

A measure, not a test: it reads the tree as text (ast), as the issue's verification does.
"""

from __future__ import annotations

import ast
import json
import sys
from pathlib import Path

PKG = Path(__file__).resolve().parents[1] / "src" / "signorini"
BACKEND_NAMES = {"superlu", "pardiso", "cholmod", "cg", "petsc", "petsc-cg", "mkl", "auto"}
DIM_NAMES = {"d", "dim", "block_size", "components", "nd", "ncomp"}
MAX_METHODS = 20


def _modules():
    for path in sorted(PKG.rglob("*.py")):
        yield path.relative_to(PKG.parent).as_posix(), ast.parse(path.read_text(), str(path))


def big_classes() -> list[tuple[str, str, int]]:
    out = []
    for name, tree in _modules():
        for node in ast.walk(tree):
            if isinstance(node, ast.ClassDef):
                methods = [n for n in node.body if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))]
                if len(methods) > MAX_METHODS:
                    out.append((name, node.name, len(methods)))
    return out


def stepper_parameters() -> int:
    tree = ast.parse((PKG / "dynamics" / "stepping" / "stepper.py").read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.ClassDef) and node.name == "Stepper":
            for f in node.body:
                if isinstance(f, ast.FunctionDef) and f.name == "__init__":
                    a = f.args
                    return len(a.posonlyargs) + len(a.args) + len(a.kwonlyargs) - 1  # without self
    return -1


def private_access() -> list[tuple[str, int, str]]:
    out = []
    for name, tree in _modules():
        own = {n.attr for n in ast.walk(tree) if isinstance(n, ast.Attribute) and isinstance(n.ctx, ast.Store)}
        own |= {n.name for n in ast.walk(tree) if isinstance(n, (ast.FunctionDef, ast.ClassDef))}
        for n in ast.walk(tree):
            if not (isinstance(n, ast.Attribute) and n.attr.startswith("_") and not n.attr.startswith("__")):
                continue
            base = n.value
            if isinstance(base, ast.Name) and base.id in ("self", "cls", "np", "sys", "os", "ckpt", "_signals"):
                continue
            if n.attr in own:
                continue
            out.append((name, n.lineno, ast.unparse(n)))
    return out


def mixed_branches() -> list[tuple[str, int]]:
    """Conditions that read ``.mixed`` (an ``if``, a conditional expression, a ``while`` or a comprehension's
    filter, anywhere in the condition: ``if mesh.mixed and ...`` too), outside ``fem/mesh.py`` (the module of
    the blocks) and except refusals (an ``if`` whose body ends in ``raise``: a capability refused by name)."""
    out = []
    for name, tree in _modules():
        if name == "signorini/fem/mesh.py":
            continue
        for n in ast.walk(tree):
            if isinstance(n, (ast.If, ast.IfExp, ast.While)):
                tests = [n.test]
            elif isinstance(n, ast.comprehension):
                tests = list(n.ifs)
            else:
                continue
            if not any(isinstance(a, ast.Attribute) and a.attr == "mixed" for t in tests for a in ast.walk(t)):
                continue
            if isinstance(n, ast.If) and not n.orelse and isinstance(n.body[-1], ast.Raise):
                continue
            out.append((name, n.lineno))
    return sorted(set(out))


def forwarding_getattr() -> list[tuple[str, str]]:
    """Classes that define ``__getattr__`` (attributes an editor or a type checker cannot follow; a module's own
    ``__getattr__``, the package's lazy public names, is not a class's)."""
    out = []
    for name, tree in _modules():
        for node in ast.walk(tree):
            if isinstance(node, ast.ClassDef):
                if any(isinstance(f, ast.FunctionDef) and f.name == "__getattr__" for f in node.body):
                    out.append((name, node.name))
    return out


def formatter_escapes() -> list[tuple[str, int]]:
    """(module, line) of every ``# fmt: skip`` in the package (issue 53: the formatter's layout is the house's;
    a table kept aligned by hand is one ``# fmt: off`` block, not counted here)."""
    out = []
    for path in sorted(PKG.rglob("*.py")):
        for k, line in enumerate(path.read_text().splitlines(), 1):
            if line.rstrip().endswith("# fmt: skip"):
                out.append((str(path.relative_to(PKG.parent)), k))
    return out


def readme_lines() -> int:
    """The README's length in lines (issue 53: a front page of at most 220)."""
    return len((PKG.parents[1] / "README.md").read_text().splitlines())


def _is_dim(node: ast.AST) -> bool:
    return isinstance(node, ast.Name) and node.id in DIM_NAMES or (
        isinstance(node, ast.Attribute) and node.attr in DIM_NAMES
    )


def _matches(owner: str, test) -> list[tuple[str, int, str]]:
    """(module, line, expression) of every node for which ``test(node)`` holds, outside the
    module ``owner`` (the one place allowed to do it)."""
    out = []
    for name, tree in _modules():
        if not name.endswith(owner):
            out += [(name, n.lineno, ast.unparse(n)[:80]) for n in ast.walk(tree) if test(n)]
    return out


def _dof_by_hand(n: ast.AST) -> bool:
    """A block layout's arithmetic with a dimension-like name: ``<a> * <dim> + ...`` or ``<dim> * <a> + ...``
    (a dof from a node), ``<a> // <dim>`` and ``<a> % <dim>`` (a dof's node and component, a layout's blocks),
    ``x[k::<dim>]`` (a component's entries)."""
    left = getattr(n, "left", None)
    if isinstance(n, ast.BinOp) and isinstance(n.op, (ast.FloorDiv, ast.Mod)) and _is_dim(n.right):
        return True
    if isinstance(n, ast.Slice) and n.step is not None and _is_dim(n.step):
        return True
    return (isinstance(n, ast.BinOp) and isinstance(n.op, ast.Add) and isinstance(left, ast.BinOp)
            and isinstance(left.op, ast.Mult) and (_is_dim(left.left) or _is_dim(left.right)))  # fmt: skip


def _backend_comparison(n: ast.AST) -> bool:
    if not isinstance(n, ast.Compare):
        return False
    consts = [c.value for c in ast.walk(n) if isinstance(c, ast.Constant) and isinstance(c.value, str)]
    return any(c in BACKEND_NAMES for c in consts) and "backend" in ast.unparse(n)


def hand_dofs() -> list[tuple[str, int, str]]:
    return _matches("fem/dofmap.py", _dof_by_hand)


def backend_comparisons() -> list[tuple[str, int, str]]:
    return _matches("linalg/base.py", _backend_comparison)


def main(argv: list[str]) -> int:
    m = {
        "classes_over_20_methods": big_classes(),
        "stepper_init_parameters": stepper_parameters(),
        "private_access_across_objects": private_access(),
        "mesh_mixed_branches": mixed_branches(),
        "dofs_by_hand": hand_dofs(),
        "backend_name_comparisons": backend_comparisons(),
        "classes_with_getattr": forwarding_getattr(),
        "readme_lines": readme_lines(),
        "formatter_escapes": formatter_escapes(),
    }
    if "--json" in argv:
        print(json.dumps(m, indent=1))
        return 0
    for key, value in m.items():
        if isinstance(value, list):
            print(f"{key}: {len(value)}")
            for row in value:
                print("   ", *row)
        else:
            print(f"{key}: {value}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))

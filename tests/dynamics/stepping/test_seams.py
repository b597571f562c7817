"""The step control's and the checkpointer's seams with the stepper (issue 53, item 3): every attribute they
read of it is a member of their protocol in dynamics/stepping/seams.py, they write none into it, and the
Stepper has every member."""

from __future__ import annotations

import ast
import inspect
from pathlib import Path

import pytest

from signorini.dynamics.stepping import seams
from signorini.dynamics.stepping.stepper import Stepper

ROOT = Path(seams.__file__).parent


def _members(protocol: type) -> set[str]:
    names = set(getattr(protocol, "__annotations__", {}))
    public = {k: v for k, v in vars(protocol).items() if not k.startswith("_")}
    names |= {k for k, v in public.items() if callable(v) or isinstance(v, property)}
    return names


def _stepper_uses(source: str, cls_name: str) -> tuple[set[str], set[str]]:
    """(attributes read, attributes written) of ``self.stepper`` and its local aliases (``s = self.stepper``) in
    the methods of class ``cls_name``; a write into an attribute of the stepper (``s.run.x = ...``) counts as a
    write of its first name."""
    cls = next(n for n in ast.parse(source).body if isinstance(n, ast.ClassDef) and n.name == cls_name)
    reads, writes = set(), set()

    def is_stepper(node: ast.AST, aliases: set[str]) -> bool:
        if isinstance(node, ast.Name):
            return node.id in aliases
        return (isinstance(node, ast.Attribute) and node.attr == "stepper" and isinstance(node.value, ast.Name)
                and node.value.id == "self")  # fmt: skip

    for fn in (n for n in ast.walk(cls) if isinstance(n, ast.FunctionDef)):
        aliases = set()
        for node in ast.walk(fn):
            if isinstance(node, ast.Assign):
                for target in node.targets:
                    both = isinstance(target, ast.Tuple) and isinstance(node.value, ast.Tuple)
                    pairs = zip(target.elts, node.value.elts, strict=False) if both else [(target, node.value)]
                    aliases |= {t.id for t, v in pairs if isinstance(t, ast.Name) and is_stepper(v, set())}
        for node in ast.walk(fn):
            if isinstance(node, ast.Attribute) and is_stepper(node.value, aliases):
                reads.add(node.attr)
                if isinstance(node.ctx, ast.Store):
                    writes.add(node.attr)
            if isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store):  # s.run.n_steps = ...
                inner = node.value
                while isinstance(inner, ast.Attribute) and not is_stepper(inner.value, aliases):
                    inner = inner.value
                if isinstance(inner, ast.Attribute) and is_stepper(inner.value, aliases):
                    writes.add(inner.attr)
    return reads, writes


@pytest.mark.parametrize(
    "module, cls_name, protocol",
    [("step_control.py", "AdaptiveSteps", seams.ControlledStepper),
     ("checkpointer.py", "Checkpointer", seams.CheckpointedStepper)],
)  # fmt: skip
def test_they_read_only_their_protocol_and_write_nothing_into_the_stepper(module, cls_name, protocol):
    reads, writes = _stepper_uses((ROOT / module).read_text(), cls_name)
    assert reads, "the scan found no use of the stepper (has the class stopped holding it as self.stepper?)"
    assert reads <= _members(protocol), sorted(reads - _members(protocol))
    assert writes == set(), sorted(writes)
    hints = inspect.signature(getattr(__import__(f"signorini.dynamics.stepping.{module[:-3]}", fromlist=[cls_name]),
                                      cls_name).__init__).parameters["stepper"].annotation  # fmt: skip
    assert hints == protocol.__name__


def test_the_scan_sees_reads_and_writes():
    """The scan itself: a read through an alias, a read through self.stepper, a nested write."""
    source = (
        "class C:\n"
        "    def f(self):\n"
        "        s = self.stepper\n"
        "        x = s.grid\n"
        "        self.stepper.run.n_steps = s.n\n"
    )
    reads, writes = _stepper_uses(source, "C")
    assert reads == {"grid", "run", "n"} and writes == {"run"}


@pytest.mark.parametrize("protocol", [seams.ControlledStepper, seams.CheckpointedStepper])
def test_the_stepper_has_every_member(protocol):
    from signorini.studies.benchmarks import get_benchmark

    b = get_benchmark("bar1d")
    dt, _ = b.run_times(10, {})
    s = Stepper(b.problem(10, {}), "crank-nicolson", (dt, 4 * dt), {"control": "energy"})
    missing = [m for m in _members(protocol) if not hasattr(s, m)]
    s.finish()
    assert missing == []

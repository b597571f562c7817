"""Every module of the package in one table for docs/architecture.md (issue 53, item 4): its path and the first
sentence of its docstring.  ``python3 scripts/module_map.py --write`` regenerates the section between the markers
of the page; tests/test_architecture.py fails when it is out of date or a module has no docstring."""

from __future__ import annotations

import ast
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "src" / "signorini"
DOC = ROOT / "docs" / "architecture.md"
BEGIN, END = "<!-- module map: begin -->", "<!-- module map: end -->"


def first_sentence(text: str) -> str:
    """The docstring's first sentence, on one line (at most 160 characters)."""
    paragraph = re.split(r"\n\s*\n|\n\s*=+\s", text.strip(), maxsplit=1)[0]  # (a table after it: not part of it)
    flat = " ".join(paragraph.split())
    m = re.search(r"^(.+?\.)(\s+[A-Z(`:*]|$)", flat)
    out = m.group(1) if m else flat
    return out if len(out) <= 160 else out[:157].rstrip() + "..."


def rows() -> list[tuple[str, str]]:
    """(module path, its first sentence) of every module of the package, sorted; "" for a module without one."""
    out = []
    for path in sorted(PKG.rglob("*.py")):
        doc = ast.get_docstring(ast.parse(path.read_text())) or ""
        out.append((str(path.relative_to(ROOT / "src")), first_sentence(doc).replace("|", "\\|")))
    return out


def render() -> str:
    lines = [BEGIN, "", "| Module | What it holds |", "| --- | --- |"]
    lines += [f"| `{m}` | {s} |" for m, s in rows()]
    return "\n".join([*lines, "", END])


def write() -> None:
    text = DOC.read_text()
    a, b = text.index(BEGIN), text.index(END) + len(END)
    DOC.write_text(text[:a] + render() + text[b:])


if __name__ == "__main__":
    if "--write" in sys.argv[1:]:
        write()
    else:
        print(render())

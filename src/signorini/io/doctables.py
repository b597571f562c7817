"""Generated documentation: the registry tables (``docs/registries.md``) and the
case-file reference (``docs/case-files.md``).

``python -m signorini.io.doctables --write`` regenerates both files;
``--check`` exits with 1 when one is out of date (the test suite checks it too).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..contact.friction import CONTACT_LAWS
from ..contact.obstacles import OBSTACLES
from ..dynamics.model.mass import MASS_VARIANTS
from ..dynamics.schemes import SCHEMES
from ..linalg import BACKENDS, PRECONDITIONERS, SOLVER_OPTIONS
from ..registry import Registry
from ..studies.benchmarks import BENCHMARKS

DOCS = Path(__file__).resolve().parents[3] / "docs"
DOC = DOCS / "registries.md"


def all_registries() -> dict[str, Registry]:
    """Every registry of the package, by the title used in the documentation."""
    return {
        "Time schemes (`--scheme`, `[time] scheme`; options: `--scheme-option`, keys of `[time]`)": SCHEMES,
        "Mass variants (`--mass`, `[solver] mass`)": MASS_VARIANTS,
        "Contact laws (`--friction LAW:VALUE`, `[contact] friction = { law = ... }`)": CONTACT_LAWS,
        "Obstacles (`[contact] obstacle = { type = ... }`)": OBSTACLES,
        "Linear-algebra backends (`--backend`, `--solver-option backend=`, `[solver] backend`)": BACKENDS,
        "Preconditioners (backend `cg`: `--solver-option preconditioner=`)": PRECONDITIONERS,
        "Benchmarks (`signorini run NAME`, parameters with `--set NAME=VALUE`)": BENCHMARKS,
    }


def render() -> str:
    """The whole ``docs/registries.md``."""
    md = [
        "# Registries",
        "",
        "Generated from the code by `python -m signorini.io.doctables --write`; do not edit by hand.",
        "Every name below is accepted on the command line, in case files and in the Python API.",
        "",
    ]
    for title, reg in all_registries().items():
        md += [f"## {title}", "", reg.markdown_table()]
    md += ["## Friction per scheme (docs/friction.md)", "", "| scheme | friction |", "|---|---|"]
    for e in SCHEMES:
        why = e.obj.friction_refusal
        text = "carries it (frictional work in its energy identity)" if why is None else f"refuses: {why}"
        md.append(f"| `{e.name}` | {text} |")
    md.append("")
    md += ["## Solver options (`--solver-option NAME=VALUE`, keys of `[solver]`)", ""]
    md += ["| option | default | allowed | meaning |", "|---|---|---|---|"]
    for p in SOLVER_OPTIONS:
        md.append(f"| `{p.name}` | {p.default} | {p.bounds_text()} | {p.doc} |")
    md.append("")
    return "\n".join(md)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m signorini.io.doctables", description=__doc__.splitlines()[0])
    ap.add_argument("--write", action="store_true", help="regenerate docs/registries.md and docs/case-files.md")
    ap.add_argument("--check", action="store_true", help="exit 1 if one of them is out of date")
    a = ap.parse_args(argv)
    from .schema import reference_markdown

    files = {DOC: render(), DOCS / "case-files.md": reference_markdown()}
    if a.write:
        for path, text in files.items():
            path.write_text(text)
        return 0
    if a.check:
        return 0 if all(p.exists() and p.read_text() == t for p, t in files.items()) else 1
    print("\n".join(files.values()))
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""The argument parser of ``signorini``; every list of names in the help comes from a registry."""

from __future__ import annotations

import argparse

from .. import __version__
from ..contact.friction import CONTACT_LAWS
from ..dynamics.model.mass import DEFAULT_MASS, MASS_VARIANTS
from ..dynamics.schemes import SCHEMES
from ..dynamics.stepping.step_control import TIME_CONTROLS
from ..linalg import BACKENDS, SOLVER_OPTIONS
from ..studies.benchmarks import BENCHMARKS
from .commands import cmd_compare, cmd_reproduce, cmd_study, cmd_template
from .messages import OneLineParser
from .run_command import cmd_resume, cmd_run

EXAMPLES_RUN = """  signorini run bar1d --scheme cn --mass seed --n 40 --T 6 --out out/bar1d
  signorini run bar2d --scheme be --mass standard --n 4 --T 1 --out out/bar2d-be
  signorini run bar2d --scheme newmark --scheme-option beta=0.3 --scheme-option gamma=0.6 --out out/nm
  signorini run bar1d-impact --set gap=0.3 --set velocity=1 --n 80 --out out/impact
  signorini run bar3d --n 8 --solver-option backend=cg --solver-option preconditioner=amg --out out/b3
  signorini run hertz2d --n 16 --set velocity=0.02 --out out/hertz2d   # vs Hertz (needs pip install ".[mesh]")
  signorini run examples/bar2d.toml --out out/case
  signorini run bar2d --scheme my_schemes:MyScheme --out out/mine   # ./my_schemes.py (import path)
  signorini run bar2d --scheme path/to/my_schemes.py:MyScheme --out out/mine   # a scheme file
"""

TIME_CONTROL_NAMES = TIME_CONTROLS.names(aliases=False)


def add_output_arguments(p, default: str | None, out_help: str, quiet_help: str) -> None:
    """--out, --overwrite and --quiet, shared by every command that writes a directory."""
    p.add_argument("--out", default=default, help=out_help)
    p.add_argument(
        "--overwrite",
        action="store_true",
        help="replace an empty directory or a result that signorini wrote (it holds the marker .signorini and "
        "only the files that marker lists); any other directory, the working directory and its parents are "
        "refused (exit 2, nothing touched)",
    )
    p.add_argument("--quiet", action="store_true", help=quiet_help)


def add_limit_arguments(p, steps_what: str, memory_what: str) -> None:
    """--max-steps, --max-memory and --yes, shared by every command that may start large runs."""
    p.add_argument("--max-steps", type=int, default=None, help=f"refuse {steps_what} unless --yes (default 1,000,000)")
    p.add_argument(
        "--max-memory",
        type=float,
        default=None,
        metavar="GIB",
        help=f"refuse {memory_what} unless --yes (default 80%% of the machine's memory)",
    )
    p.add_argument("--yes", action="store_true", help="run even if over --max-steps or --max-memory")


def add_friction_argument(p, default: str) -> None:
    """``--friction LAW:VALUE`` (run, compare)."""
    laws = "; ".join(
        f"{e.name}" + (f":{e.parameters[0].name.upper()} ({e.parameters[0].doc})" if e.parameters else "")
        for e in CONTACT_LAWS
    )
    p.add_argument(
        "--friction",
        default=None,
        metavar="LAW:VALUE",
        help=f"contact law: {laws}; e.g. coulomb:0.3 or tresca:0.01; 2D/3D only {default}",
    )


def add_command(sub, name: str, help: str, description: str, examples: str) -> argparse.ArgumentParser:
    """A subcommand whose help ends with its examples (kept verbatim)."""
    return sub.add_parser(
        name,
        help=help,
        description=description,
        epilog="examples:\n" + examples,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )


def _benchmarks() -> str:
    return ", ".join(BENCHMARKS.names())


def _solver_option_names() -> str:
    return ", ".join([p.name for p in SOLVER_OPTIONS] + sorted({p.name for e in BACKENDS for p in e.parameters}))


def add_solver_arguments(group, scope: str) -> None:
    """``--backend`` and ``--solver-option`` (run, compare); ``scope`` ends their help."""
    tail = f"; {scope}" if scope else ""
    group.add_argument(
        "--backend",
        default=None,
        help=f"linear solver: {'; '.join(f'{e.name}: {e.description}' for e in BACKENDS)} (default auto{tail})",
    )
    group.add_argument(
        "--solver-option",
        action="append",
        metavar="NAME=VALUE",
        help=f"a solver option (repeatable): {_solver_option_names()}{tail}",
    )


def _add_run(sub) -> None:
    """The sub-command ``signorini run``."""
    benchmarks = _benchmarks()
    r = add_command(
        sub,
        "run",
        f"run a named benchmark ({benchmarks}) or a case file",
        "Run one simulation and write history.csv, contact.npz and summary.json (and fields.xdmf "
        "with --snapshot-every) into --out.  Exit codes: 0 finished, 2 invalid input (nothing written), "
        "3 numerical failure, 4 out of memory or a file-system failure, 130 interrupted (partial results "
        "are written with their status).  Case files: docs/case-files.md, `signorini template`.",
        EXAMPLES_RUN,
    )
    r.add_argument("target", help=f"benchmark name ({benchmarks}) or a CASE.toml file (docs/case-files.md)")
    both = r.add_argument_group("scheme, mass and solver (benchmarks and case files; override the file's)")
    both.add_argument(
        "--scheme",
        default=None,
        help=f"time scheme: {SCHEMES.help_text()}; or a Scheme subclass as module:Class (module "
        "importable from the working directory, as with python -m) or path/to/file.py:Class "
        "(default cn, or the case file's)",
    )
    both.add_argument(
        "--scheme-option",
        action="append",
        metavar="NAME=VALUE",
        help="a parameter of the scheme (repeatable), e.g. beta=0.3",
    )
    both.add_argument(
        "--mass",
        default=None,
        help=f"mass variant: {', '.join(MASS_VARIANTS.names())} (default {DEFAULT_MASS}, which keeps the "
        "mass, centre of mass and inertia; or the case file's)",
    )
    add_friction_argument(both, "(default frictionless, or the case file's)")
    add_solver_arguments(both, "")
    bench = r.add_argument_group("benchmarks only (errors with a case file: set these in the file)")
    bench.add_argument(
        "--n",
        type=int,
        default=None,
        help="elements across the width (2D/3D, 10n along) or along the bar (1D); default 40 in 1D, 4 in 2D/3D; "
        "hertz: elements across the Hertz contact radius, default 8 (2D), 3 (3D)",
    )
    both.add_argument(
        "--dt",
        type=float,
        default=None,
        help="time step (default h/2; hertz: t_c/(25n); a case file's [time] dt otherwise, which this overrides: "
        "the summary says so); T must be a multiple of it",
    )
    both.add_argument(
        "--T",
        type=float,
        default=None,
        help="final time (default 6 in 1D, 1 in 2D/3D; hertz: 1.5 t_c; a case file's [time] T otherwise, which this "
        "overrides: the summary says so)",
    )
    both.add_argument(
        "--dt-control",
        default=None,
        choices=TIME_CONTROL_NAMES,
        help="time-step control: energy (dt is the largest step; steps that create or destroy energy no physical "
        "work explains are rejected and halved, down to dt/1024 (deeper on a fine mesh, whose tolerance is finer: "
        "docs/schemes.md): impacts resolved in time; the default for a case "
        "file, except with a mass that keeps the contact inertia or a scheme that cannot change its step) or fixed "
        "(the steps asked for; the default for a benchmark); case file: [time] control",
    )
    both.add_argument(
        "--stop-at",
        default=None,
        metavar="EVENT",
        help="end the run (status finished) at the first level where an event occurs: first-contact, separation "
        "(every contact node free again after a contact), rest[:FRACTION] (kinetic energy below that fraction of "
        "its initial value, default 0.01); comma-separated for several (case file: [time] stop_at)",
    )
    bench.add_argument("--set", action="append", metavar="NAME=VALUE", help="override a benchmark parameter")
    out = r.add_argument_group("output and limits (benchmarks and case files; override the file's)")
    out.add_argument(
        "--snapshot-every", type=int, default=None, help="stream XDMF fields every k steps and at the end (0: none)"
    )
    out.add_argument(
        "--checkpoint-every",
        type=int,
        default=None,
        metavar="K",
        help="write checkpoint.h5 every K steps (atomically; default 0: only at the end, which every run does, "
        "also when interrupted or failed); `signorini resume` continues from it (case file: [output] "
        "checkpoint_every)",
    )
    add_limit_arguments(
        out,
        "runs with more steps (case file: [limits] max_steps)",
        "runs whose estimated memory exceeds this many GiB (case file: [limits] max_memory)",
    )
    add_output_arguments(
        out, None, "output directory (default out/run, or the case file's)", "no progress bar and no summary"
    )
    r.set_defaults(func=cmd_run)


EXAMPLES_RESUME = """  signorini run bar2d --T 1 --out out/first           # or interrupted: Ctrl-C, SIGTERM, job limit
  signorini resume out/first --T 2 --out out/longer    # levels 0..T=1 copied, then on to T = 2
  signorini run bar2d --T 2 --checkpoint-every 20 --out out/long   # killed (SIGKILL)? its last checkpoint is kept
  signorini resume out/long --out out/long-done      # to the run's own T
  signorini resume out/mine --scheme my_schemes.py:MyScheme --out out/mine-done   # a scheme of your own
"""


def _add_resume(sub) -> None:
    """The sub-command ``signorini resume``."""
    r = add_command(
        sub,
        "resume",
        "continue a run from its checkpoint to a later final time",
        "Continue the run of RESULT_DIR from its checkpoint.h5 (written at the end of every run, interrupted "
        "and failed ones included, and every K steps with --checkpoint-every) up to --T (default: the run's own "
        "final time), into a new result directory that holds every level from t = 0 (the earlier ones copied).  "
        "The run is rebuilt as it was started (benchmark, case file, scheme, mass, solver); a case file that "
        "changed since is refused.  A checkpoint is data: nothing it names is imported or executed, and a "
        "scheme of your own (module:Class, file.py:Class) must be named again with --scheme.  The "
        "resumed run computes what the uninterrupted run computes (bit for bit on the same machine, backend "
        "and thread count: docs/tutorial.md).  Exit codes as `signorini run`.",
        EXAMPLES_RESUME,
    )
    r.add_argument("result", metavar="RESULT_DIR", help="a result directory holding checkpoint.h5")
    r.add_argument(
        "--T",
        type=float,
        default=None,
        help="the final time (after the checkpoint's time; default: the interrupted run's own T)",
    )
    r.add_argument(
        "--scheme",
        default=None,
        metavar="SCHEME",
        help="the run's scheme of your own (module:Class or path/to/file.py:Class), named again: a checkpoint "
        "never imports code; checked against the checkpoint's record (another scheme is refused)",
    )
    r.add_argument(
        "--dt",
        type=float,
        default=None,
        help="continue with this time step from the checkpoint (a new factorization; T - t_checkpoint must be a "
        "multiple of it; schemes that cannot change their step refuse); default: the run's own steps",
    )
    r.add_argument(
        "--snapshot-every", type=int, default=None, help="stream XDMF fields every k steps (default: the run's)"
    )
    r.add_argument(
        "--checkpoint-every", type=int, default=None, metavar="K", help="checkpoint every K steps (default: the run's)"
    )
    add_limit_arguments(
        r,
        "runs with more steps (as `signorini run`)",
        "runs whose estimated memory exceeds this many GiB (as `signorini run`)",
    )
    add_output_arguments(
        r, None, "output directory (required; a new directory, or --overwrite)", "no progress bar and no summary"
    )
    r.set_defaults(func=cmd_resume)


def _add_study(sub) -> None:
    """The sub-command ``signorini study``."""
    benchmarks = _benchmarks()
    st = add_command(
        sub,
        "study",
        "convergence study on nested meshes against the exact (1D) or a reference (2D/3D) solution",
        "Errors and observed rates on levels n0 2^k (k < levels) with dt = ratio h; "
        "1D benchmarks against their exact solution, 2D/3D against a reference run of the same "
        "scheme and mass (default 4x finer in h and dt than the finest level; the tables state it).  "
        "Writes study.md, study.csv and study.json into --out.",
        "  signorini study bar1d --scheme cn --mass seed --n0 20 --levels 4 --T 3 --out out/s1\n"
        "  signorini study bar2d --scheme be --mass standard --n0 1 --levels 3 --T 1 --out out/s2\n"
        "  signorini study bar2d --levels 3 --check-ref-level 8 --out out/s3   # rates vs n = 16 and n = 8",
    )
    st.add_argument("benchmark", help=benchmarks)
    st.add_argument("--scheme", default="cn", help=f"time scheme: {', '.join(SCHEMES.names())} (default cn)")
    st.add_argument("--mass", default=DEFAULT_MASS, help=f"mass variant, as for run (default {DEFAULT_MASS})")
    st.add_argument("--n0", type=int, default=None, help="coarsest level (default 20 in 1D, 1 in 2D/3D)")
    st.add_argument("--levels", type=int, default=3, help="number of levels (default 3)")
    st.add_argument(
        "--ref-level",
        type=int,
        default=None,
        help="reference level for 2D/3D: a multiple of every level, finer than the finest "
        "(default 4 x the finest level, n0 2^(levels+1), same dt/h ratio)",
    )
    st.add_argument(
        "--check-ref-level",
        type=int,
        action="append",
        metavar="N",
        help="also measure the rates against a reference at level N (repeatable) and compare them",
    )
    st.add_argument("--ratio", type=float, default=0.5, help="time step over mesh size, dt = ratio h (default 0.5)")
    st.add_argument(
        "--T",
        type=float,
        default=None,
        help="final time (default 3 in 1D: one period of bar1d, whose contact is on [1, 2); 1 in 2D/3D)",
    )
    st.add_argument("--set", action="append", metavar="NAME=VALUE", help="override a benchmark parameter")
    add_limit_arguments(
        st,
        "a level with more steps",
        "the study when a level's estimated memory (with the fields it keeps for the errors) exceeds this many GiB",
    )
    add_output_arguments(st, "out/study", "output directory (default out/study)", "no table on stdout")
    st.set_defaults(func=cmd_study)


def _add_template(sub) -> None:
    """The sub-command ``signorini template``."""
    tp = add_command(
        sub,
        "template",
        "print a commented starting case file",
        "Print a case file for a bar released onto a rigid plane, every key commented with its meaning "
        "and units; it runs as printed.  Reference of every key: docs/case-files.md.",
        "  signorini template --dim 2 > case.toml && signorini run case.toml --out out/case",
    )
    tp.add_argument("--dim", type=int, default=2, choices=(1, 2, 3), help="space dimension (default 2)")
    tp.set_defaults(func=cmd_template)


def _add_compare(sub) -> None:
    """The sub-command ``signorini compare``."""
    benchmarks = _benchmarks()
    cp = add_command(
        sub,
        "compare",
        "run a matrix of schemes x mass variants on a benchmark or a case file and rank the pairs",
        "Run every scheme x mass pair; benchmarks on nested levels n0 2^k (k < levels) with dt = ratio h "
        "(T must be a multiple of every level's dt), errors at every level against the exact solution (1D) or "
        "a reference run (2D/3D; default CN + seed, on quadratic cells CN + moment-preserving, 4x finer than the "
        "finest level) and least-squares rates; "
        "a case file on its own mesh, dt and T (diagnostics only).  A pair the problem refuses (e.g. a mass "
        "variant that needs a generated grid) is reported as n/a with the reason.  Writes compare.md (one "
        "ranking table: lexicographic on the error, then energy drift, oscillation index, penetration; the "
        "rule is stated in it), compare.json, and energy.png, contact_force.png, penetration.png, errors.png "
        "(benchmarks), cost.png, each with its CSV, into --out.  Schemes with options: name[opt=value,...] "
        "(quote it for the shell).",
        "  signorini compare bar1d --schemes cn,be,'generalized-alpha[rho_inf=0.5]' --masses standard,seed "
        "--out out/c1\n"
        "  signorini compare bar2d --schemes cn,be,hht --masses standard,seed,moment-preserving --levels 3 "
        "--out out/c2\n"
        "  signorini compare bar2d --schemes cn,ps --masses seed --reference crank-nicolson:seed:16 --out out/c3\n"
        "  signorini compare examples/bar2d.toml --schemes cn,be --masses standard,seed --jobs 2 --out out/c4",
    )
    cp.add_argument("target", help=f"benchmark name ({benchmarks}) or a CASE.toml file")
    cp.add_argument(
        "--schemes",
        required=True,
        metavar="S1,S2,...",
        help=f"comma-separated schemes, each name or name[opt=value,...]: {SCHEMES.help_text()}",
    )
    cp.add_argument(
        "--masses",
        required=True,
        metavar="M1,M2,...",
        help=f"comma-separated mass variants: {', '.join(MASS_VARIANTS.names())}",
    )
    add_friction_argument(cp, "for every run of the matrix (default frictionless, or the case file's)")
    add_solver_arguments(cp, "for every run of the matrix and the reference (override the case file's)")
    cb = cp.add_argument_group("benchmarks only (errors with a case file)")
    cb.add_argument("--levels", type=int, default=None, help="number of nested levels n0 2^k (default 3)")
    cb.add_argument("--n0", type=int, default=None, help="coarsest level (default 20 in 1D, 1 in 2D/3D)")
    cb.add_argument(
        "--reference",
        default=None,
        metavar="LEVEL|SCHEME:MASS:LEVEL",
        help="2D/3D reference run: a level (CN + seed; on quadratic cells CN + moment-preserving) or "
        "scheme:mass:level, a multiple of every level (default crank-nicolson:seed at 4x the finest level, same "
        "dt/h ratio); 1D uses the exact solution",
    )
    cb.add_argument(
        "--T",
        type=float,
        default=None,
        help="final time (a benchmark: default 3 in 1D, 1 in 2D/3D; a case file: its own T)",
    )
    cb.add_argument("--ratio", type=float, default=None, help="dt = ratio h on every level (default 0.5)")
    cb.add_argument("--set", action="append", metavar="NAME=VALUE", help="override a benchmark parameter")
    cpo = cp.add_argument_group("execution and output")
    cpo.add_argument(
        "--jobs",
        type=int,
        default=None,
        help="parallel processes (default: min(available cores, number of runs)); results do not depend on it",
    )
    add_limit_arguments(
        cpo,
        "a run with more steps",
        "the matrix when its estimated memory exceeds this many GiB: every run with the fields it keeps for the "
        "errors, --jobs runs at once, the fields held for a 2D/3D reference",
    )
    add_output_arguments(cpo, "out/compare", "output directory (default out/compare)", "no table on stdout")
    cp.set_defaults(func=cmd_compare)


def _add_reproduce(sub) -> None:
    """The sub-command ``signorini reproduce``."""
    q = add_command(
        sub,
        "reproduce",
        "reproduce the seed paper's study into a report (report.md, figures, summary.json)",
        "1D exact benchmark, 2D bar histories and convergence, 3D von Mises, for CN/BE with "
        "standard and seed masses; one figure per figure of the paper (fig1_*.png .. fig8_*.png, "
        "mapped in report.md); 2D/3D rates against a reference 4x finer than the finest level, "
        "checked against other references; section 6 ranks CN, BE, generalized-alpha and Paoli-Schatzman x "
        "standard/seed with `signorini compare` (1D impact, 2D bar).  --quick (default) takes 25-60 s on 2 "
        "cores (idle to loaded).",
        "  signorini reproduce --quick --out results\n  signorini reproduce --full --out full",
    )
    g = q.add_mutually_exclusive_group()
    g.add_argument("--quick", action="store_true", help="small sizes (default)")
    g.add_argument(
        "--full", action="store_true", help="finer levels: 2D up to n=16 (reference 64), 3D n=8; ~6 min, 4 GB"
    )
    g.add_argument("--tiny", action="store_true", help="smallest sizes (used by the tests)")
    add_output_arguments(q, "results", "output directory (default results)", "no summary on stdout")
    q.set_defaults(func=cmd_reproduce)


def build_parser() -> argparse.ArgumentParser:
    """The parser; every list of names in the help comes from a registry."""
    p = OneLineParser(
        prog="signorini",
        description="Dynamic Signorini contact of elastic bodies with the mass redistribution method.",
    )
    p.add_argument("--version", action="version", version=f"signorini {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    for add in (_add_run, _add_resume, _add_study, _add_template, _add_compare, _add_reproduce):
        add(sub)
    return p

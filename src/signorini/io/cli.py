"""The ``signorini`` command line.

Exit codes: 0 success; 2 invalid input (nothing written); 3 numerical failure (a
non-finite value or a solver that did not converge: the levels computed are written,
with ``status = "failed"`` in summary.json); 4 the environment failed (out of memory,
disk full, an I/O error: what could be kept is kept); 130 interrupted by Ctrl-C or
SIGTERM (the levels computed are written, ``status = "interrupted"``); 1 an internal
error (a bug: one line, the traceback with ``SIGNORINI_TRACEBACK=1``).
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import json
import os
import shutil
import signal
import sys
import time
import traceback
import warnings
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from .. import __version__
from ..dynamics.mass import DEFAULT_MASS
from ..errors import ConvergenceError, InputError
from ..registry import parse_assignments
from .messages import OneLineParser, one_line
from .results_dir import ResultConflict, ResultDirectory, run_into
from .streams import deferred_signals, guarded_stdio

EXIT_CODES = {"finished": 0, "failed": 3, "interrupted": 130}
EXIT_ENVIRONMENT = 4

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


class Progress:
    """A one-line progress bar on stderr, only when it is a terminal and not quiet."""

    def __init__(self, quiet: bool, label: str):
        self.enabled = (not quiet) and sys.stderr.isatty()
        self.label = label
        self.t0 = time.perf_counter()
        self.last = 0.0
        self.first: tuple[float, int] | None = None  # (time, step) of the first step seen

    def __call__(self, i: int, n: int) -> None:
        if not self.enabled:
            return
        now = time.perf_counter()
        if self.first is None:  # the estimate starts with the loop: set-up time is not a step's
            self.first = (now, i)
        if now - self.t0 < 2.0 or (now - self.last < 0.2 and i < n):
            return
        self.last = now
        frac = i / n
        bar = "#" * int(30 * frac)
        t1, i1 = self.first
        eta = (now - t1) / max(i - i1, 1) * (n - i)
        sys.stderr.write(f"\r{self.label} [{bar:<30}] {i}/{n} steps, {eta:5.1f}s left")
        if i == n:
            sys.stderr.write("\n")
        sys.stderr.flush()


def mass_effect_line(s: dict) -> str:
    """One line: the mass variant (and whether it is the default) and what it keeps."""
    e = s.get("mass_effect") or {}
    if not e:
        return ""
    how = "" if s.get("mass_named", True) else " (the default)"
    return (
        f"  mass {s['mass']}{how}: keeps {100 * e['mass_ratio']:.6g}% of the mass, centre of mass moved by "
        f"{100 * e['centre_shift']:.2g}% of the body's size, inertia changed by {100 * e['inertia_change']:.2g}%\n"
    )


def energy_line(H, s: dict) -> str:
    """The energy line: the drift for a closed system; with work done on it (time-dependent
    loads, prescribed motion), the external work and the identity's residual instead."""
    work = H.columns()["external_work"]
    w = float(work[-1]) if work.size and np.isfinite(work[-1]) else 0.0
    scale = max(abs(s["energy_initial"]), abs(s["energy_final"]), abs(w), 1e-300)
    if abs(w) > 1e-9 * scale:
        res = s.get("energy_identity_residual")
        res_text = f"{res:.2e}" if res is not None else "n/a"
        return (
            f"  energy {s['energy_initial']:.6g} -> {s['energy_final']:.6g}, external work {w:.6g} "
            f"(loads and prescribed motion; energy identity residual {res_text})\n"
        )
    drift = s["energy_max_relative_drift"]
    drift_text = f"max drift {100 * drift:.3g}% of E0" if drift is not None else "E0 = 0: no relative drift"
    return f"  energy {s['energy_initial']:.6g} -> {s['energy_final']:.6g} ({drift_text})\n"


def one_screen_summary(H) -> str:
    s = H.summary()
    c = s["counters"]
    return (
        f"{s['problem']}: {s['scheme']} / {s['mass']} mass, {s['dofs']} dofs, {s['contact_nodes']} contact nodes\n"
        f"  status {s['status']}{': ' + s['message'] if s['message'] else ''}\n"
        f"  steps {s['steps']} (dt={s['dt']:.4g}, T={s['T']:.4g}), impacts {s['impacts']}, "
        f"fallbacks {s['fallbacks']}\n"
        f"{energy_line(H, s)}"
        f"  max complementarity residual {s['max_complementarity_residual']:.2e}\n"
        f"{mass_effect_line(s)}"
        f"  setup {s['setup_seconds']:.3g}s, {1e3 * s['step_seconds']:.3g} ms/step ({s['backend']}), "
        f"{c.get('factorizations', 0)} factorization(s), {c.get('linear_solves', 0)} solves" + factorization_tip(s)
    )


def factorization_tip(s: dict) -> str:
    """A hint when SuperLU factored a large 3D system and a faster backend is one pip away."""
    from ..linalg import has_cholmod, has_pardiso

    big_3d = s.get("dim") == 3 and s.get("free_dofs", s["dofs"]) >= 30_000
    if s["backend"] != "superlu" or not big_3d or has_cholmod() or has_pardiso():
        return ""
    return (
        '\n  tip: the extras cholmod and metis (pip install ".[cholmod,metis]"; or pardiso on x86-64) factor'
        " 3D systems like this one several times faster with a fraction of the memory (docs/performance.md)"
    )


@contextmanager
def _first_on_sys_path(directory: str):
    """``directory`` first on ``sys.path`` for the duration of one import (then removed)."""
    sys.path.insert(0, directory)
    try:
        yield
    finally:
        try:
            sys.path.remove(directory)
        except ValueError:  # the imported code removed it itself
            pass


def _import_scheme_source(source: str) -> ModuleType:
    """The module of ``--scheme SOURCE:Class``: a file ``path/to/file.py`` or a dotted module.

    A dotted module is imported with the current working directory first on
    ``sys.path`` (as ``python -m`` does), so ``--scheme my_schemes:MyScheme`` finds
    ``./my_schemes.py`` whichever way ``signorini`` was started.  A file is loaded
    under its stem with its own directory first on ``sys.path`` (as ``python file.py``
    does), so it can import its neighbours.
    """
    if source.endswith(".py") or "/" in source or os.sep in source:
        path = Path(source).expanduser().resolve()
        if not path.is_file():
            raise ImportError(f"no file {source}")
        name = f"_signorini_scheme_{path.stem}"
        spec = importlib.util.spec_from_file_location(name, path)
        if spec is None or spec.loader is None:
            raise ImportError(f"{source} is not a Python file")
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        with _first_on_sys_path(str(path.parent)):
            try:
                spec.loader.exec_module(module)
            except BaseException:
                del sys.modules[name]
                raise
        return module
    with _first_on_sys_path(os.getcwd()):
        return importlib.import_module(source)


def load_scheme(name: str):
    """A registered scheme name, or a Scheme subclass by import path.

    ``module:Class`` or ``module.Class`` (``module`` importable from the current
    working directory or ``sys.path``), or ``path/to/file.py:Class``.
    """
    from ..dynamics.schemes import SCHEMES, Scheme

    if name in SCHEMES or (":" not in name and "." not in name):
        return SCHEMES.resolve(name)
    source, _, cls = name.rpartition(":") if ":" in name else name.rpartition(".")
    try:
        obj = getattr(_import_scheme_source(source), cls)
    except (ImportError, AttributeError, SyntaxError) as exc:
        raise InputError(
            f"--scheme {name!r}: cannot import it ({exc}); allowed: {', '.join(SCHEMES.names())}, "
            "module:Class (module importable from the working directory) or path/to/file.py:Class"
        ) from None
    if not (isinstance(obj, type) and issubclass(obj, Scheme)):
        raise InputError(f"--scheme {name!r} is not a subclass of signorini.dynamics.schemes.Scheme")
    return obj


# ----------------------------------------------------------------------------- run
@dataclass
class RunSpec:
    """Everything ``signorini run`` needs, from a benchmark or a case file."""

    problem: Any
    scheme: Any
    dt: float
    T: float
    mass: str
    out: Path
    label: str
    scheme_options: dict = field(default_factory=dict)
    solver_options: dict = field(default_factory=dict)
    snapshot_every: int = 0
    meta: dict = field(default_factory=dict)
    case_file: Path | None = None
    limits: dict = field(default_factory=dict)
    measure: Any = None  # a benchmark's extra figures (observers, summary fields, text)


def _limits(args: argparse.Namespace, case_limits: dict) -> dict:
    """--max-steps, --max-memory (GiB) and --yes over the case file's [limits]."""
    out = dict(case_limits)
    if args.max_steps is not None:
        if args.max_steps < 1:
            raise InputError(f"--max-steps must be a positive integer, got {args.max_steps}")
        out["max_steps"] = args.max_steps
    if args.max_memory is not None:
        from ..errors import check_positive

        out["max_memory"] = check_positive("--max-memory", args.max_memory)
    if args.yes:
        out["yes"] = True
    return out


def check_size(counts: tuple[int, int, int, int, int], dt: float, T: float, limits: dict) -> None:
    """Refuse (exit 2, with the estimate) a run over the step or memory limit unless confirmed.

    ``counts`` = (nodes, cells, nodes per cell, dim, contact nodes), known before meshing
    for a benchmark.
    """
    from ..dynamics.budget import check_run_size, estimate_run
    from ..dynamics.simulate import number_of_steps

    est = estimate_run(*counts, number_of_steps(dt, T))
    mem = limits.get("max_memory")
    check_run_size(est, limits.get("max_steps"), None if mem is None else mem * 2**30, bool(limits.get("yes")))


def mesh_counts(problem) -> tuple[int, int, int, int, int]:
    m = problem.mesh
    return m.n_nodes, m.n_cells, m.cells.shape[1], m.dim, m.nodes_of(problem.contact_tag).size


def _options(args: argparse.Namespace, scheme_options: dict, solver_options: dict) -> tuple[dict, dict]:
    sch = {**scheme_options, **parse_assignments(args.scheme_option, "--scheme-option")}
    given = parse_assignments(args.solver_option, "--solver-option")
    sol = {**solver_options, **given}
    if args.backend is not None:
        if "backend" in given and str(given["backend"]) != args.backend:
            raise InputError(
                f"--backend {args.backend} and --solver-option backend={given['backend']} disagree; give one of them"
            )
        sol["backend"] = args.backend
    return sch, sol


def benchmark_spec(args: argparse.Namespace) -> RunSpec:
    from ..studies.benchmarks import get_benchmark

    bench = get_benchmark(args.target)
    overrides = parse_assignments(args.set, "--set")
    n = args.n if args.n is not None else bench.n_default()
    if n < 1:
        raise InputError(f"--n must be a positive integer, got {n}")
    dt_default, T_default = bench.run_times(n, overrides)
    dt = args.dt if args.dt is not None else dt_default
    T = args.T if args.T is not None else T_default
    limits = _limits(args, {})
    nodes, cells, per_cell = bench.mesh_counts(n, overrides)
    check_size((nodes, cells, per_cell, bench.dim, bench.contact_count(n, overrides)), dt, T, limits)
    problem = bench.problem(n, overrides)
    sch, sol = _options(args, {}, {})
    params = bench.params(overrides)
    meta = {"benchmark": args.target, "n": n, "parameters": params, "mass_named": args.mass is not None}
    if args.snapshot_every is not None and args.snapshot_every < 0:
        raise InputError(f"--snapshot-every must be >= 0, got {args.snapshot_every}")
    scheme = load_scheme(args.scheme or "cn")
    measure = bench.measure(params) if bench.measure is not None else None
    return RunSpec(problem, scheme, dt, T, args.mass or DEFAULT_MASS, Path(args.out or "out/run"), args.target,
                   sch, sol, args.snapshot_every or 0, meta, limits=limits, measure=measure)  # fmt: skip


def case_spec(args: argparse.Namespace) -> RunSpec:
    from .config import load_case

    for flag in ("n", "dt", "T"):
        if getattr(args, flag) is not None:
            raise InputError(f"--{flag} does not apply to a case file; set it in the file")
    if args.set:
        raise InputError("--set does not apply to a case file; edit the file")
    case = load_case(args.target, _limits(args, {}), check_size)
    out = Path(args.out) if args.out else (case.out or Path("out") / Path(args.target).stem)
    scheme = load_scheme(args.scheme) if args.scheme else case.scheme
    sch, sol = _options(args, case.scheme_options if not args.scheme else {}, case.solver_options)
    every = args.snapshot_every if args.snapshot_every is not None else case.snapshot_every
    if every < 0:
        raise InputError(f"--snapshot-every must be >= 0, got {every}")
    limits = _limits(args, case.limits)
    check_size(mesh_counts(case.problem), case.dt, case.T, limits)
    meta = {"case_file": str(args.target), "mass_named": bool(args.mass) or case.mass_named}
    return RunSpec(case.problem, scheme, case.dt, case.T, args.mass or case.mass, out, Path(args.target).name,
                   sch, sol, every, meta, Path(args.target), limits)  # fmt: skip


class LazyFieldWriter:
    """A :class:`~signorini.io.output.FieldWriter` into the result directory, which is
    created only when the time loop starts (so invalid input creates nothing)."""

    def __init__(self, rd: ResultDirectory, every: int):
        self.rd, self.every, self.inner = rd, every, None

    def start(self, run) -> None:
        from .output import FieldWriter

        self.inner = FieldWriter(self.rd.create() / "fields.xdmf", self.every)
        self.inner.start(run)

    def record(self, run, n, state) -> None:
        self.inner.record(run, n, state)

    def close(self, run, status, n_last, state) -> None:
        if self.inner is not None:
            self.inner.close(run, status, n_last, state)


def write_setup_failure(rd: ResultDirectory, spec: RunSpec, exc: Exception) -> None:
    """summary.json of a run that failed before its first step (status failed, no levels,
    every counter of :data:`~signorini.dynamics.history.COUNTER_KEYS` zero)."""
    from ..dynamics.history import COUNTER_KEYS

    tmp = rd.create()
    summary = {"status": "failed", "success": False, "message": f"set-up: {exc}", "problem": spec.label,
               "steps": 0, "counters": dict.fromkeys(COUNTER_KEYS, 0), **spec.meta}  # fmt: skip
    (tmp / "summary.json").write_text(json.dumps(summary, indent=1, default=str))
    rd.commit()


def execute(spec: RunSpec, args: argparse.Namespace) -> int:
    """Run the simulation into a temporary directory and publish it, whatever the status."""
    from ..dynamics.simulate import simulate

    with ResultDirectory(spec.out, args.overwrite) as rd:
        observers = [LazyFieldWriter(rd, spec.snapshot_every)] if spec.snapshot_every else []
        if spec.measure is not None:
            observers += spec.measure.observers()
        try:
            H = simulate(
                spec.problem,
                spec.scheme,
                spec.dt,
                spec.T,
                mass=spec.mass,
                progress=Progress(args.quiet, spec.label),
                scheme_options=spec.scheme_options,
                solver_options=spec.solver_options,
                observers=observers,
            )
        except ConvergenceError as exc:  # before the first step (non-finite operators, ...)
            write_setup_failure(rd, spec, exc)
            print(f"signorini: failed: {one_line(exc)} (summary in {spec.out})", file=sys.stderr)
            return EXIT_CODES["failed"]
        with deferred_signals() as late:  # a signal now would lose every computed step: record it
            H.meta.update(spec.meta)
            if spec.measure is not None:
                H.meta.update(spec.measure.summary(H))
            tmp = rd.create()
            if spec.case_file is not None:
                shutil.copy(spec.case_file, tmp / "case.toml")
            H.save(tmp)
            if late.name and H.status == "finished":
                H.status, H.message = "interrupted", f"{late.name} while the results were written (all steps kept)"
                H.save(tmp)
            rd.commit()
    with deferred_signals() as after:  # the results are in place: a signal only shortens the report
        report_run(H, spec, args)
    return EXIT_CODES["interrupted"] if after.name and H.success else EXIT_CODES[H.status]


def report_run(H, spec: RunSpec, args: argparse.Namespace) -> None:
    """Warnings and failures on stderr, the one-screen summary on stdout (unless quiet)."""
    for w in H.meta.get("warnings", []):
        print(f"signorini: warning: {one_line(w)}", file=sys.stderr)
    if not args.quiet:
        print(one_screen_summary(H))
        if spec.measure is not None:
            print(spec.measure.text(H.meta))
        print(f"  results in {spec.out}")
    if not H.success:
        print(f"signorini: {H.status}: {one_line(H.message)} (partial results in {spec.out})", file=sys.stderr)


def cmd_run(args: argparse.Namespace) -> int:
    spec = case_spec(args) if args.target.endswith(".toml") else benchmark_spec(args)
    return execute(spec, args)


def check_study_size(bench, levels: list[int], args: argparse.Namespace, overrides: dict) -> None:
    """Refuse (exit 2, with the estimate) a study whose largest run is over the limits, as ``run`` does.

    Every level keeps its fields for the errors; a 2D/3D study also runs its reference.
    Levels are estimated from their counts, without building anything.
    """
    from ..dynamics.budget import check_run_size, estimate_run
    from ..dynamics.simulate import number_of_steps
    from ..studies.reference_study import DEFAULT_REFERENCE_FACTOR

    runs = list(levels)
    if bench.dim > 1:
        runs.append(args.ref_level or DEFAULT_REFERENCE_FACTOR * levels[-1])
    limits = _limits(args, {})
    mem = limits.get("max_memory")
    for n in sorted(set(runs), reverse=True):
        nodes, cells, per_cell = bench.mesh_counts(n, overrides)
        steps = number_of_steps(args.ratio * bench.h(n, overrides), args.T)
        est = estimate_run(nodes, cells, per_cell, bench.dim, bench.contact_count(n, overrides), steps, True)
        check_run_size(est, limits.get("max_steps"), None if mem is None else mem * 2**30, bool(limits.get("yes")))


def cmd_study(args: argparse.Namespace) -> int:
    import json

    from ..dynamics.history import _json_default
    from ..errors import check_positive
    from ..studies.benchmarks import get_benchmark
    from ..studies.reference_study import DEFAULT_REFERENCE_FACTOR, check_levels, study, table_csv, table_markdown

    bench = get_benchmark(args.benchmark)
    bench.require_nested("signorini study")
    overrides = parse_assignments(args.set, "--set")
    bench.params(overrides)
    if args.levels < 2:
        raise InputError(f"--levels must be >= 2 to measure a rate, got {args.levels}")
    if args.n0 is None:
        args.n0 = 20 if bench.dim == 1 else 1
    if args.n0 < 1:
        raise InputError(f"--n0 must be a positive integer, got {args.n0}")
    check_positive("--ratio", args.ratio)
    check_positive("--T", args.T)
    levels = [args.n0 * 2**k for k in range(args.levels)]
    check_refs = tuple(args.check_ref_level or ())
    if bench.dim == 1 and (args.ref_level is not None or check_refs):
        raise InputError(
            f"{args.benchmark} is compared with its exact solution; --ref-level/--check-ref-level do not apply"
        )
    if bench.dim > 1:
        check_levels(levels, args.ref_level or DEFAULT_REFERENCE_FACTOR * levels[-1])
    check_study_size(bench, levels, args, overrides)
    out = Path(args.out)
    holder = {}

    def work(tmp: Path) -> None:
        res = study(
            args.benchmark, args.scheme, args.mass, args.n0, args.levels, args.T, args.ratio, args.ref_level, overrides,
            check_refs,
        )  # fmt: skip
        md = table_markdown(res)
        (tmp / "study.md").write_text(md)
        table_csv(res, tmp / "study.csv")
        (tmp / "study.json").write_text(json.dumps(res, indent=1, default=_json_default))
        holder["md"] = md

    run_into(out, args.overwrite, work)
    if not args.quiet:
        print(holder["md"])
        print(f"saved {out / 'study.md'} and {out / 'study.csv'}")
    return 0


def compare_plan(args: argparse.Namespace):
    """The validated plan of ``signorini compare`` (InputError before anything is created)."""
    import functools

    from ..studies import compare as cmp

    pairs = cmp.make_pairs(cmp.parse_schemes(args.schemes), cmp.parse_masses(args.masses))
    if args.jobs is not None and args.jobs < 1:
        raise InputError(f"--jobs must be a positive integer, got {args.jobs}")
    limits = _limits(args, {})
    if args.target.endswith(".toml"):
        from .config import case_problem, load_case

        for flag in ("levels", "n0", "reference", "T", "ratio"):
            if getattr(args, flag) is not None:
                raise InputError(f"--{flag} does not apply to a case file (one level: its mesh, dt and T)")
        if args.set:
            raise InputError("--set does not apply to a case file; edit the file")
        case = load_case(args.target, limits, check_size)
        load = functools.partial(case_problem, str(args.target))
        target = cmp.CaseTarget(
            Path(args.target).name, load, case.dt, case.T, tuple(sorted(case.solver_options.items()))
        )
        plan = cmp.plan_case(target, pairs, case.problem)
        check_compare_size(plan, args.jobs, _limits(args, case.limits))
        return plan
    overrides = parse_assignments(args.set, "--set")
    ref = cmp.parse_reference(args.reference) if args.reference is not None else None
    levels = cmp.DEFAULT_LEVELS if args.levels is None else args.levels
    ratio = cmp.DEFAULT_RATIO if args.ratio is None else args.ratio
    plan = cmp.plan_benchmark(args.target, pairs, levels, args.n0, args.T, ratio, overrides, ref)
    check_compare_size(plan, args.jobs, _limits(args, {}))
    return plan


def check_compare_size(plan, jobs: int | None, limits: dict) -> None:
    """Refuse (exit 2, with the estimate) a matrix over the step or memory limit unless --yes.

    The estimate counts every run with the fields it keeps for the errors, the runs in
    progress at once and the fields held for a 2D/3D reference
    (:func:`signorini.studies.compare.estimate_plan`).
    """
    from ..dynamics.budget import check_run_size
    from ..studies.compare import estimate_plan

    mem = limits.get("max_memory")
    est = estimate_plan(plan, jobs)
    check_run_size(est, limits.get("max_steps"), None if mem is None else mem * 2**30, bool(limits.get("yes")))


def cmd_compare(args: argparse.Namespace) -> int:
    from ..studies import compare as cmp

    plan = compare_plan(args)
    out = Path(args.out)
    holder = {}

    def work(tmp: Path) -> None:
        result, series = cmp.run_plan(plan, args.jobs)
        cmp.write_report(result, series, tmp)
        holder["result"] = result

    try:
        run_into(out, args.overwrite, work)
    except KeyboardInterrupt:
        print("signorini: compare interrupted; nothing written", file=sys.stderr)
        return EXIT_CODES["interrupted"]
    if not args.quiet:
        r = holder["result"]
        print(cmp.setup_text(r))
        print(cmp.reference_text(r))
        print("\n".join(cmp.table_markdown(r)))
        print(f"{r['runs']} runs in {r['jobs']} process(es), {r['seconds']:.1f} s; report in {out / 'compare.md'}")
    return 0


def cmd_reproduce(args: argparse.Namespace) -> int:
    from ..studies.report import reproduce

    size = "full" if args.full else ("tiny" if args.tiny else "quick")
    out = Path(args.out)
    t0 = time.perf_counter()
    holder = {}
    run_into(out, args.overwrite, lambda tmp: holder.update(s=reproduce(tmp, size)))
    if not args.quiet:
        h = holder["s"]["bar2d_histories"]
        print(f"report written to {out / 'report.md'} in {time.perf_counter() - t0:.1f}s")
        for k, v in h.items():
            print(f"  {k:32s} oscillation index {v['oscillation_index']:.2f}, E(T)/E(0) {v['energy_ratio_final']:.3f}")
    return 0


def cmd_template(args: argparse.Namespace) -> int:
    from .schema import template

    print(template(args.dim), end="")
    return 0


def add_output_arguments(p, default: str | None, out_help: str, quiet_help: str) -> None:
    """--out, --overwrite and --quiet, shared by every command that writes a directory."""
    p.add_argument("--out", default=default, help=out_help)
    p.add_argument("--overwrite", action="store_true", help="replace a non-empty output directory")
    p.add_argument("--quiet", action="store_true", help=quiet_help)


def add_command(sub, name: str, help: str, description: str, examples: str) -> argparse.ArgumentParser:
    """A subcommand whose help ends with its examples (kept verbatim)."""
    return sub.add_parser(
        name,
        help=help,
        description=description,
        epilog="examples:\n" + examples,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )


def build_parser() -> argparse.ArgumentParser:
    """The parser; every list of names in the help comes from a registry."""
    from ..dynamics.mass import MASS_VARIANTS
    from ..dynamics.schemes import SCHEMES
    from ..linalg import BACKENDS, SOLVER_OPTIONS
    from ..studies.benchmarks import BENCHMARKS

    benchmarks = ", ".join(BENCHMARKS.names())
    solver_opts = ", ".join([p.name for p in SOLVER_OPTIONS] + sorted({p.name for e in BACKENDS for p in e.parameters}))
    p = OneLineParser(
        prog="signorini",
        description="Dynamic Signorini contact of elastic bodies with the mass redistribution method.",
    )
    p.add_argument("--version", action="version", version=f"signorini {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")

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
    both.add_argument(
        "--backend",
        default=None,
        help=f"linear solver: {'; '.join(f'{e.name}: {e.description}' for e in BACKENDS)} (default auto)",
    )
    both.add_argument(
        "--solver-option",
        action="append",
        metavar="NAME=VALUE",
        help=f"a solver option (repeatable): {solver_opts}",
    )
    bench = r.add_argument_group("benchmarks only (errors with a case file: set these in the file)")
    bench.add_argument(
        "--n",
        type=int,
        default=None,
        help="elements across the width (2D/3D, 10n along) or along the bar (1D); default 40 in 1D, 4 in 2D/3D; "
        "hertz: elements across the Hertz contact radius, default 8 (2D), 3 (3D)",
    )
    bench.add_argument(
        "--dt", type=float, default=None, help="time step (default h/2; hertz: t_c/(25n)); T must be a multiple of it"
    )
    bench.add_argument("--T", type=float, default=None, help="final time (default 6 in 1D, 1 in 2D/3D; hertz: 1.5 t_c)")
    bench.add_argument("--set", action="append", metavar="NAME=VALUE", help="override a benchmark parameter")
    out = r.add_argument_group("output and limits (benchmarks and case files; override the file's)")
    out.add_argument(
        "--snapshot-every", type=int, default=None, help="stream XDMF fields every k steps and at the end (0: none)"
    )
    out.add_argument(
        "--max-steps",
        type=int,
        default=None,
        help="refuse runs with more steps unless --yes (default 1,000,000; case file: [limits] max_steps)",
    )
    out.add_argument(
        "--max-memory",
        type=float,
        default=None,
        metavar="GIB",
        help="refuse runs whose estimated memory exceeds this many GiB unless --yes "
        "(default 80%% of the machine's memory; case file: [limits] max_memory)",
    )
    out.add_argument("--yes", action="store_true", help="run even if over --max-steps or --max-memory")
    add_output_arguments(
        out, None, "output directory (default out/run, or the case file's)", "no progress bar and no summary"
    )
    r.set_defaults(func=cmd_run)

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
    st.add_argument("--T", type=float, default=1.0, help="final time (default 1)")
    st.add_argument("--set", action="append", metavar="NAME=VALUE", help="override a benchmark parameter")
    st.add_argument(
        "--max-steps", type=int, default=None, help="refuse a level with more steps unless --yes (default 1,000,000)"
    )
    st.add_argument(
        "--max-memory",
        type=float,
        default=None,
        metavar="GIB",
        help="refuse the study when a level's estimated memory (with the fields it keeps for the errors) exceeds "
        "this many GiB unless --yes (default 80%% of the machine's memory)",
    )
    st.add_argument("--yes", action="store_true", help="run even if over the step or memory limits")
    add_output_arguments(st, "out/study", "output directory (default out/study)", "no table on stdout")
    st.set_defaults(func=cmd_study)

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

    cp = add_command(
        sub,
        "compare",
        "run a matrix of schemes x mass variants on a benchmark or a case file and rank the pairs",
        "Run every scheme x mass pair; benchmarks on nested levels n0 2^k (k < levels) with dt = ratio h "
        "(T must be a multiple of every level's dt), errors at every level against the exact solution (1D) or "
        "a reference run (2D/3D; default CN + seed 4x finer than the finest level) and least-squares rates; "
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
    cb = cp.add_argument_group("benchmarks only (errors with a case file)")
    cb.add_argument("--levels", type=int, default=None, help="number of nested levels n0 2^k (default 3)")
    cb.add_argument("--n0", type=int, default=None, help="coarsest level (default 20 in 1D, 1 in 2D/3D)")
    cb.add_argument(
        "--reference",
        default=None,
        metavar="LEVEL|SCHEME:MASS:LEVEL",
        help="2D/3D reference run: a level (CN + seed) or scheme:mass:level, a multiple of every level "
        "(default crank-nicolson:seed at 4x the finest level, same dt/h ratio); 1D uses the exact solution",
    )
    cb.add_argument("--T", type=float, default=None, help="final time (default 3 in 1D, 1 in 2D/3D)")
    cb.add_argument("--ratio", type=float, default=None, help="dt = ratio h on every level (default 0.5)")
    cb.add_argument("--set", action="append", metavar="NAME=VALUE", help="override a benchmark parameter")
    cpo = cp.add_argument_group("execution and output")
    cpo.add_argument(
        "--jobs",
        type=int,
        default=None,
        help="parallel processes (default: min(available cores, number of runs)); results do not depend on it",
    )
    cpo.add_argument(
        "--max-steps", type=int, default=None, help="refuse a run with more steps unless --yes (default 1,000,000)"
    )
    cpo.add_argument(
        "--max-memory",
        type=float,
        default=None,
        metavar="GIB",
        help="refuse the matrix when its estimated memory exceeds this many GiB unless --yes: every run with the "
        "fields it keeps for the errors, --jobs runs at once, the fields held for a 2D/3D reference "
        "(default 80%% of the machine's memory)",
    )
    cpo.add_argument("--yes", action="store_true", help="run even if over the step or memory limits")
    add_output_arguments(cpo, "out/compare", "output directory (default out/compare)", "no table on stdout")
    cp.set_defaults(func=cmd_compare)

    q = add_command(
        sub,
        "reproduce",
        "reproduce the seed paper's study into a report (report.md, figures, summary.json)",
        "1D exact benchmark, 2D bar histories and convergence, 3D von Mises, for CN/BE with "
        "standard and seed masses; one figure per figure of the paper (fig1_*.png .. fig8_*.png, "
        "mapped in report.md); 2D/3D rates against a reference 4x finer than the finest level, "
        "checked against other references; section 6 ranks CN, BE, generalized-alpha and Paoli-Schatzman x "
        "standard/seed with `signorini compare` (1D impact, 2D bar).  --quick (default) takes about 25 s on 2 "
        "idle cores.",
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
    return p


def _sigterm(signum, frame):
    raise KeyboardInterrupt


def main(argv: list[str] | None = None) -> int:
    with guarded_stdio():
        parser = build_parser()
        args = parser.parse_args(argv)
        if not getattr(args, "command", None):
            parser.print_help()
            return 2
        return _dispatch(args)


def _dispatch(args: argparse.Namespace) -> int:
    """Run the command; map every exception to its exit code and a one-line message."""
    old = signal.signal(signal.SIGTERM, _sigterm) if sys.platform != "win32" else None
    try:
        # every quantity is checked for finiteness where it matters; numpy's floating-point
        # warnings would only add lines before a one-line error
        with np.errstate(all="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            return args.func(args)
    except InputError as exc:
        print(f"signorini: error: {one_line(exc)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("signorini: interrupted before the time loop; nothing written", file=sys.stderr)
        return 130
    except ResultConflict as exc:
        print(f"signorini: error: {one_line(exc.strerror)}", file=sys.stderr)
        return EXIT_ENVIRONMENT
    except ConvergenceError as exc:
        print(f"signorini: failed: {one_line(exc)}", file=sys.stderr)
        return EXIT_CODES["failed"]
    except MemoryError:
        print(
            "signorini: error: out of memory (try a smaller size, --backend cg, or a larger machine)", file=sys.stderr
        )
        return EXIT_ENVIRONMENT
    except OSError as exc:
        where = f" {exc.filename!r}" if exc.filename else ""
        print(f"signorini: error: file system:{one_line(where)} {exc.strerror or exc}", file=sys.stderr)
        return EXIT_ENVIRONMENT
    except Exception as exc:  # a bug: one line, the traceback on request
        if os.environ.get("SIGNORINI_TRACEBACK"):
            traceback.print_exc()
        print(
            f"signorini: internal error: {type(exc).__name__}: {one_line(exc)} "
            "(please report it; SIGNORINI_TRACEBACK=1 shows the traceback)",
            file=sys.stderr,
        )
        return 1
    finally:
        if old is not None:
            signal.signal(signal.SIGTERM, old)


if __name__ == "__main__":
    sys.exit(main())

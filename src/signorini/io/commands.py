"""``signorini study``, ``compare``, ``reproduce`` and ``template``: validation, size checks, execution."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from ..errors import InputError
from ..registry import parse_assignments
from .exit_codes import EXIT_CODES, EXIT_ENVIRONMENT
from .results_dir import run_into
from .run_command import _limits, _options, check_size


def check_study_size(bench, levels: list[int], args: argparse.Namespace, overrides: dict) -> None:
    """Refuse (exit 2, with the estimate) a study whose largest run is over the limits, as ``run`` does.

    Every level keeps its fields for the errors; a 2D/3D study also runs its reference.
    Levels are estimated from their counts, without building anything.
    """
    from ..dynamics.stepping.budget import check_run_size, estimate_run
    from ..dynamics.stepping.simulate import number_of_steps
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

    from ..dynamics.observe.history import _json_default
    from ..errors import check_positive
    from ..studies.benchmarks import STUDY_T, get_benchmark
    from ..studies.reference_study import DEFAULT_REFERENCE_FACTOR, check_levels, study, table_csv, table_markdown

    bench = get_benchmark(args.benchmark)
    overrides = parse_assignments(args.set, "--set")
    bench.require_nested("signorini study", overrides)
    if args.levels < 2:
        raise InputError(f"--levels must be >= 2 to measure a rate, got {args.levels}")
    if args.n0 is None:
        args.n0 = 20 if bench.dim == 1 else 1
    if args.n0 < 1:
        raise InputError(f"--n0 must be a positive integer, got {args.n0}")
    check_positive("--ratio", args.ratio)
    if args.T is None:
        args.T = STUDY_T[bench.dim]
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
            args.benchmark,
            args.scheme,
            args.mass,
            args.n0,
            args.levels,
            args.T,
            args.ratio,
            args.ref_level,
            overrides,
            check_refs,
        )
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
        case = load_case(args.target, limits, check_size, args.backend)
        load = functools.partial(case_problem, str(args.target))
        _, sol = _options(args, {}, case.solver_options)
        from types import SimpleNamespace

        from .run_command import case_control

        controls = []  # each pair's control as `signorini run FILE --scheme S --mass M` takes it
        for pair in pairs:
            control = case_control(
                SimpleNamespace(dt_control=None), case.control, pair.scheme.name, {}, pair.mass, pair.scheme.option_dict
            )
            controls.append(((pair.scheme.label, pair.mass), control))
        target = cmp.CaseTarget(
            Path(args.target).name,
            load,
            case.dt,
            case.T,
            tuple(sorted(_checked(sol).items())),
            friction=args.friction,
            controls=tuple(controls),
        )
        plan = cmp.plan_case(target, pairs, case.problem)
        check_compare_size(plan, args.jobs, _limits(args, case.limits))
        return plan
    overrides = parse_assignments(args.set, "--set")
    ref = cmp.parse_reference(args.reference) if args.reference is not None else None
    levels = cmp.DEFAULT_LEVELS if args.levels is None else args.levels
    ratio = cmp.DEFAULT_RATIO if args.ratio is None else args.ratio
    _, sol = _options(args, {}, {})
    plan = cmp.plan_benchmark(
        args.target, pairs, levels, args.n0, args.T, ratio, overrides, ref, args.friction, _checked(sol)
    )
    check_compare_size(plan, args.jobs, _limits(args, {}))
    return plan


def _checked(given: dict) -> dict:
    """The solver options as given, validated (an unknown name or value: exit 2 before any run)."""
    from ..linalg.base import solver_options

    solver_options(given, "--solver-option")
    return given


def check_compare_size(plan, jobs: int | None, limits: dict) -> None:
    """Refuse (exit 2, with the estimate) a matrix over the step or memory limit unless --yes.

    The estimate counts every run with the fields it keeps for the errors, the runs in
    progress at once and the fields held for a 2D/3D reference
    (:func:`signorini.studies.compare.estimate_plan`).
    """
    from ..dynamics.stepping.budget import check_run_size
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
    if holder["s"].get("status") == "interrupted":
        done = holder["s"]["sections_done"]
        print(
            f"signorini: interrupted during {holder['s']['interrupted_in']}: {out / 'report.md'} holds the "
            f"{len(done)} section(s) finished ({', '.join(done) or 'none'})",
            file=sys.stderr,
        )
        return EXIT_CODES["interrupted"]
    if not args.quiet:
        h = holder["s"]["bar2d_histories"]
        print(f"report written to {out / 'report.md'} in {time.perf_counter() - t0:.1f}s")
        for k, v in h.items():
            print(f"  {k:32s} oscillation index {v['oscillation_index']:.2f}, E(T)/E(0) {v['energy_ratio_final']:.3f}")
        if "hertz" in holder["s"] and holder["s"]["hertz"] is None:
            print(
                '  section 7 (Hertz impact) skipped: gmsh is not installed; pip install ".[mesh]" and run again '
                "for it (a bare Debian also needs the X/OpenGL libraries the README lists)"
            )
    return 0


def cmd_template(args: argparse.Namespace) -> int:
    from .schema import template

    print(template(args.dim), end="")
    sys.stdout.flush()
    if getattr(sys.stdout, "failed", False):  # the template is the product: a full disk or closed pipe is a failure
        print("signorini: error: the template could not be written to stdout", file=sys.stderr)
        return EXIT_ENVIRONMENT
    return 0

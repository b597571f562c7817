"""The ``signorini`` command line.

Exit codes: 0 success, 1 unexpected failure, 2 invalid input (nothing written).
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from .. import __version__
from ..errors import InputError

EXAMPLES_RUN = """examples:
  signorini run bar1d --scheme cn --mass seed --n 40 --T 6 --out out/bar1d
  signorini run bar2d --scheme be --mass standard --n 4 --T 1 --out out/bar2d-be
  signorini run bar1d-impact --set gap=0.3 --set velocity=1 --n 80 --out out/impact
  signorini run examples/bar2d.toml --out out/case
"""


class Progress:
    """A one-line progress bar on stderr, only when it is a terminal and not quiet."""

    def __init__(self, quiet: bool, label: str):
        self.enabled = (not quiet) and sys.stderr.isatty()
        self.label = label
        self.t0 = time.perf_counter()
        self.last = 0.0

    def __call__(self, i: int, n: int) -> None:
        if not self.enabled:
            return
        now = time.perf_counter()
        if now - self.t0 < 2.0 or (now - self.last < 0.2 and i < n):
            return
        self.last = now
        frac = i / n
        bar = "#" * int(30 * frac)
        eta = (now - self.t0) / max(frac, 1e-9) * (1 - frac)
        sys.stderr.write(f"\r{self.label} [{bar:<30}] {i}/{n} steps, {eta:5.1f}s left")
        if i == n:
            sys.stderr.write("\n")
        sys.stderr.flush()


def parse_sets(items: list[str]) -> dict[str, str]:
    out = {}
    for item in items or []:
        if "=" not in item:
            raise InputError(f"--set expects NAME=VALUE, got {item!r}")
        k, v = item.split("=", 1)
        out[k.strip()] = v.strip()
    return out


def prepare_output(out: Path, overwrite: bool) -> Path:
    """Check ``out`` and return a fresh temporary directory next to it."""
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {str(out)!r} exists and is not a directory")
    if out.exists() and any(out.iterdir()) and not overwrite:
        raise InputError(f"output directory {str(out)!r} is not empty; pass --overwrite to replace it")
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    tmp.chmod(0o755)
    return tmp


def commit_output(tmp: Path, out: Path) -> None:
    """Move the finished results into place (the old directory is replaced only now)."""
    if out.exists():
        shutil.rmtree(out)
    tmp.rename(out)


def run_into(out: Path, overwrite: bool, work: Callable[[Path], None]) -> None:
    """Run ``work(tmpdir)`` and publish the directory only if it succeeds."""
    tmp = prepare_output(out, overwrite)
    try:
        work(tmp)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    commit_output(tmp, out)


def one_screen_summary(H) -> str:
    s = H.summary()
    drift = s["energy_max_relative_drift"]
    return (
        f"{s['problem']}: {s['scheme']} / {s['mass']} mass, {s['dofs']} dofs, {s['contact_nodes']} contact nodes\n"
        f"  steps {s['steps']} (dt={s['dt']:.4g}, T={s['T']:.4g}), impacts {s['impacts']}, "
        f"fallbacks {s['fallbacks']}\n"
        f"  energy {s['energy_initial']:.6g} -> {s['energy_final']:.6g} "
        f"(max drift {100 * drift:.3g}% of E0)\n"
        f"  max complementarity residual {s['max_complementarity_residual']:.2e}\n"
        f"  setup {s['setup_seconds']:.3g}s, {1e3 * s['step_seconds']:.3g} ms/step ({s['backend']})"
    )


# ----------------------------------------------------------------------------- commands
def cmd_run(args: argparse.Namespace) -> int:
    from ..dynamics.simulate import simulate
    from ..studies.benchmarks import get_benchmark

    target = args.target
    if target.endswith(".toml"):
        return run_case_file(args)
    bench = get_benchmark(target)
    overrides = parse_sets(args.set)
    n = args.n if args.n is not None else (40 if bench.dim == 1 else 4)
    problem = bench.problem(n, overrides)
    dt = args.dt if args.dt is not None else bench.h(n, overrides) / 2
    T = args.T if args.T is not None else (6.0 if bench.dim == 1 else 1.0)
    out = Path(args.out or "out/run")
    holder = {}

    def work(tmp: Path) -> None:
        if (args.scheme or "").lower() in ("ps", "paoli-schatzman"):
            from ..competitors import paoli_schatzman

            if args.snapshot_every:
                raise InputError("--snapshot-every is not available with the paoli-schatzman scheme")
            H = paoli_schatzman(problem, dt, T, mass=args.mass or "standard", backend=args.backend)
            H.meta.update({"benchmark": target, "n": n, "parameters": bench.params(overrides)})
            save_run(tmp, H, problem, 0, holder)
            return
        H = simulate(
            problem,
            args.scheme or "cn",
            dt,
            T,
            mass=args.mass or "seed",
            snapshot_every=args.snapshot_every,
            backend=args.backend,
            progress=Progress(args.quiet, target),
        )
        H.meta.update({"benchmark": target, "n": n, "parameters": bench.params(overrides)})
        save_run(tmp, H, problem, args.snapshot_every, holder)

    run_into(out, args.overwrite, work)
    return report_run(args, holder, out)


def save_run(tmp: Path, H, problem, snapshot_every: int, holder: dict) -> None:
    """Write a run's files (and its XDMF fields when snapshots were taken)."""
    H.save(tmp)
    if snapshot_every:
        from ..io.output import write_fields

        write_fields(tmp / "fields.xdmf", problem, H)
    holder["H"] = H


def report_run(args: argparse.Namespace, holder: dict, out: Path) -> int:
    if not args.quiet:
        print(one_screen_summary(holder["H"]))
        print(f"  results in {out}")
    return 0


def run_case_file(args: argparse.Namespace) -> int:
    from ..dynamics.simulate import simulate
    from ..io.config import load_case

    for flag in ("n", "dt", "T"):
        if getattr(args, flag) is not None:
            raise InputError(f"--{flag} does not apply to a case file; set it in the file")
    if args.set:
        raise InputError("--set does not apply to a case file; edit the file")
    case = load_case(args.target)
    out = Path(args.out) if args.out else (case.out or Path("out") / Path(args.target).stem)
    every = args.snapshot_every or case.snapshot_every
    holder = {}

    def work(tmp: Path) -> None:
        H = simulate(
            case.problem,
            args.scheme or case.scheme,
            case.dt,
            case.T,
            mass=args.mass or case.mass,
            snapshot_every=every,
            backend=args.backend,
            progress=Progress(args.quiet, Path(args.target).name),
        )
        H.meta.update({"case_file": str(args.target)})
        shutil.copy(args.target, tmp / "case.toml")
        save_run(tmp, H, case.problem, every, holder)

    run_into(out, args.overwrite, work)
    return report_run(args, holder, out)


def cmd_study(args: argparse.Namespace) -> int:
    import json

    from ..dynamics.history import _json_default
    from ..errors import check_positive
    from ..studies.benchmarks import get_benchmark
    from ..studies.reference_study import study, table_csv, table_markdown

    bench = get_benchmark(args.benchmark)
    overrides = parse_sets(args.set)
    bench.params(overrides)
    if args.levels < 2:
        raise InputError(f"--levels must be >= 2 to measure a rate, got {args.levels}")
    if args.n0 < 1:
        raise InputError(f"--n0 must be a positive integer, got {args.n0}")
    check_positive("--ratio", args.ratio)
    check_positive("--T", args.T)
    finest = args.n0 * 2 ** (args.levels - 1)
    if args.ref_level is not None and (args.ref_level <= finest or args.ref_level % finest):
        raise InputError(
            f"--ref-level must be a multiple of the finest level {finest} and larger, got {args.ref_level}"
        )
    out = Path(args.out)
    holder = {}

    def work(tmp: Path) -> None:
        res = study(
            args.benchmark, args.scheme, args.mass, args.n0, args.levels, args.T, args.ratio, args.ref_level, overrides
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


def add_output_arguments(p: argparse.ArgumentParser, default: str | None, out_help: str, quiet_help: str) -> None:
    """--out, --overwrite and --quiet, shared by every command that writes a directory."""
    p.add_argument("--out", default=default, help=out_help)
    p.add_argument("--overwrite", action="store_true", help="replace a non-empty output directory")
    p.add_argument("--quiet", action="store_true", help=quiet_help)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="signorini",
        description="Dynamic Signorini contact of elastic bodies with the mass redistribution method.",
    )
    p.add_argument("--version", action="version", version=f"signorini {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")

    r = sub.add_parser(
        "run",
        help="run a named benchmark (bar1d, bar1d-impact, bar2d, bar3d) or a case file",
        description="Run one simulation and write history.csv, contact.npz and summary.json into --out.",
        epilog=EXAMPLES_RUN,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    r.add_argument("target", help="benchmark name (bar1d, bar1d-impact, bar2d, bar3d) or a CASE.toml file")
    r.add_argument(
        "--scheme",
        default=None,
        help="cn|crank-nicolson, be|backward-euler, or ps|paoli-schatzman (benchmarks only) "
        "(default cn, or the case file's)",
    )
    r.add_argument(
        "--mass",
        default=None,
        help="standard|lumped|seed|seed-normal|moment-preserving|neighbour|mass-free-surface "
        "(default seed, or the case file's)",
    )
    r.add_argument(
        "--n",
        type=int,
        default=None,
        help="elements across the width (2D/3D, 10n along) or along the bar (1D)",
    )
    r.add_argument("--dt", type=float, default=None, help="time step (default h/2)")
    r.add_argument("--T", type=float, default=None, help="final time (default 6 in 1D, 1 in 2D/3D)")
    r.add_argument("--set", action="append", metavar="NAME=VALUE", help="override a benchmark parameter")
    r.add_argument(
        "--backend",
        default="auto",
        help="linear solver: auto (default: direct factor if it fits in 40%% of RAM, else CG), superlu, pardiso, cg",
    )
    r.add_argument("--snapshot-every", type=int, default=0, help="write XDMF fields every k steps (0: none)")
    add_output_arguments(
        r, None, "output directory (default out/run, or the case file's)", "no progress bar and no summary"
    )
    r.set_defaults(func=cmd_run)

    st = sub.add_parser(
        "study",
        help="convergence study on nested meshes against the exact (1D) or a reference (2D/3D) solution",
        description="Errors and observed rates on levels n0 2^k (k < levels) with dt = ratio h; "
        "writes study.md, study.csv and study.json into --out.",
        epilog="examples:\n  signorini study bar1d --scheme cn --mass seed --n0 20 --levels 4 --T 3 --out out/s1\n"
        "  signorini study bar2d --scheme be --mass standard --n0 1 --levels 3 --T 1 --out out/s2",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    st.add_argument("benchmark", help="bar1d, bar1d-impact, bar2d or bar3d")
    st.add_argument("--scheme", default="cn", help="cn|crank-nicolson or be|backward-euler (default cn)")
    st.add_argument("--mass", default="seed", help="mass variant, as for run (default seed)")
    st.add_argument("--n0", type=int, default=1, help="coarsest level (default 1)")
    st.add_argument("--levels", type=int, default=3, help="number of levels (default 3)")
    st.add_argument("--ref-level", type=int, default=None, help="reference level for 2D/3D (default n0 2^levels)")
    st.add_argument("--ratio", type=float, default=0.5, help="time step over mesh size, dt = ratio h (default 0.5)")
    st.add_argument("--T", type=float, default=1.0, help="final time (default 1)")
    st.add_argument("--set", action="append", metavar="NAME=VALUE", help="override a benchmark parameter")
    add_output_arguments(st, "out/study", "output directory (default out/study)", "no table on stdout")
    st.set_defaults(func=cmd_study)

    q = sub.add_parser(
        "reproduce",
        help="reproduce the seed paper's study into a report (report.md, figures, summary.json)",
        description="1D exact benchmark, 2D bar histories and convergence, 3D von Mises, for CN/BE with "
        "standard and seed masses.  --quick (default) takes well under 3 minutes on 2 cores.",
        epilog="examples:\n  signorini reproduce --quick --out results\n  signorini reproduce --full --out full",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    g = q.add_mutually_exclusive_group()
    g.add_argument("--quick", action="store_true", help="small sizes (default)")
    g.add_argument("--full", action="store_true", help="finer levels: 2D up to n=16 (reference 32), 3D n=8; ~2 min")
    g.add_argument("--tiny", action="store_true", help="smallest sizes (used by the tests)")
    add_output_arguments(q, "results", "output directory (default results)", "no summary on stdout")
    q.set_defaults(func=cmd_reproduce)
    return p


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "command", None):
        parser.print_help()
        return 2
    try:
        return args.func(args)
    except InputError as exc:
        print(f"signorini: error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # output piped into `head` and the like
        sys.stderr.close()
        return 0


if __name__ == "__main__":
    sys.exit(main())

"""``signorini run``: a benchmark or a case file into a validated RunSpec, executed into a result directory."""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import shutil
import signal
import sys
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..dynamics.model.mass import DEFAULT_MASS
from ..dynamics.model.problem import contact_node_count, with_friction
from ..dynamics.observe.events import parse_stop_at
from ..errors import ConvergenceError, InputError
from ..parallel import mark_unshared
from ..registry import parse_assignments
from .exit_codes import EXIT_CODES
from .messages import one_line
from .plugins import load_scheme
from .results_dir import ResultDirectory
from .streams import deferred_signals
from .summary import Progress, one_screen_summary


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
    #: built-in events that end the run (--stop-at, [time] stop_at)
    events: list = field(default_factory=list)
    #: a checkpoint every k steps (0: at the end only)
    checkpoint_every: int = 0
    #: how to build this run again (the command's arguments), kept in its checkpoints
    invocation: dict = field(default_factory=dict)
    #: the checkpoint a resumed run continues from, and the result directory it is in
    resume: Path | None = None
    #: hash of the case file's text (a resumed case must be the same file)
    case_hash: str | None = None
    #: the time-step control (:mod:`~signorini.dynamics.stepping.step_control`): a name or {"control": ..., options}
    control: Any = None


#: the JSON type of each kept argument: an edited checkpoint's invocation is checked against
#: it, by name, before anything of it is used
INVOCATION_TYPES: dict[str, tuple[type, ...]] = {
    "target": (str,),
    "scheme": (str,),
    "scheme_option": (list,),
    "mass": (str,),
    "friction": (str,),
    "backend": (str,),
    "solver_option": (list,),
    "n": (int,),
    "dt": (int, float),
    "T": (int, float),
    "set": (list,),
    "stop_at": (str,),
    "snapshot_every": (int,),
    "checkpoint_every": (int,),
    "max_steps": (int,),
    "max_memory": (int, float),
    "yes": (bool,),
    "dt_control": (str,),
}


#: the arguments of ``signorini run`` a checkpoint keeps to build the run again
INVOCATION_ARGS = tuple(INVOCATION_TYPES)


def is_plugin_scheme(name: str | None) -> bool:
    """True for ``--scheme module:Class``, ``module.Class`` or ``file.py:Class`` (code of the
    user's own, imported), False for a name of the scheme registry (or None)."""
    from ..dynamics.schemes import SCHEMES

    return isinstance(name, str) and name not in SCHEMES and (":" in name or "." in name)


def invocation(args: argparse.Namespace) -> dict:
    """The run's arguments as JSON-able data (a case file by its absolute path)."""
    out = {k: getattr(args, k, None) for k in INVOCATION_ARGS}
    if str(out["target"]).endswith(".toml"):
        out["target"] = str(Path(out["target"]).resolve())
    scheme = out.get("scheme")
    if isinstance(scheme, str) and ".py:" in scheme:  # a scheme file: found again from any directory
        file, _, cls = scheme.rpartition(":")
        out["scheme"] = f"{Path(file).resolve()}:{cls}"
    return out


def case_text_hash(path: Path, files: list[Path] | tuple = ()) -> str:
    """The identity of a case: sha256 of its text, and, when it reads other files (a mesh
    file, a surface obstacle), of its text and each file's name and contents, so that a
    resume refuses a case whose data changed in any of them."""
    import hashlib

    h = hashlib.sha256(Path(path).read_bytes())
    if not files:
        return h.hexdigest()
    for f in files:
        h.update(b"\0" + str(Path(f).name).encode() + b"\0" + hashlib.sha256(Path(f).read_bytes()).digest())
    return h.hexdigest()


def _checkpoint_every(args: argparse.Namespace, default: int) -> int:
    k = getattr(args, "checkpoint_every", None)
    k = default if k is None else k
    if not isinstance(k, int) or k < 0:
        raise InputError(f"--checkpoint-every must be >= 0, got {k}")
    return k


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


def check_size(
    counts: tuple[int, int, int, int, int],
    dt: float,
    T: float,
    limits: dict,
    solver: dict | None = None,
    steps: int | None = None,
) -> None:
    """Refuse (exit 2, with the estimate) a run over the step or memory limit unless confirmed.

    ``counts`` = (nodes, cells, nodes per cell, dim, contact nodes), known before meshing
    for a benchmark; ``solver``, the solver options as given: ``backend`` (None: ``auto``)
    decides the factor and, on the ranks of ``mpiexec``, the copies on this machine;
    ``condense_budget`` bounds petsc's Delassus columns (a value the options' validation
    will refuse counts as the default here).
    """
    from ..dynamics.stepping.budget import COLUMNS_BUDGET, check_run_size, estimate_run
    from ..dynamics.stepping.simulate import number_of_steps
    from ..parallel import local_ranks

    solver = solver or {}
    try:
        budget = float(solver.get("condense_budget", COLUMNS_BUDGET))
    except (TypeError, ValueError, OverflowError):
        budget = COLUMNS_BUDGET
    if not 0.0 <= budget < float("inf"):
        budget = COLUMNS_BUDGET
    backend = str(solver.get("backend") or "auto")
    from ..dynamics.stepping.time_grid import TimeGrid

    if steps is None:
        steps = number_of_steps(dt, T) if isinstance(dt, (int, float)) else TimeGrid.build(dt, T).n_steps
    est = estimate_run(*counts, steps, backend=backend, ranks=local_ranks(), condense_budget=budget)
    mem = limits.get("max_memory")
    check_run_size(est, limits.get("max_steps"), None if mem is None else mem * 2**30, bool(limits.get("yes")))


def mesh_counts(problem) -> tuple[int, int, int, int, int]:
    m = problem.mesh
    return m.n_nodes, m.n_cells, max(b.cells.shape[1] for b in m.blocks), m.dim, contact_node_count(problem)


def _options(args: argparse.Namespace, scheme_options: dict, solver_options: dict) -> tuple[dict, dict]:
    sch = {**scheme_options, **parse_assignments(getattr(args, "scheme_option", None), "--scheme-option")}
    given = parse_assignments(args.solver_option, "--solver-option")
    sol = {**solver_options, **given}
    if args.backend is not None:
        if "backend" in given and str(given["backend"]) != args.backend:
            raise InputError(
                f"--backend {args.backend} and --solver-option backend={given['backend']} disagree; give one of them"
            )
        sol["backend"] = args.backend
    return sch, sol


def _check_out_given(args: argparse.Namespace) -> None:
    if args.out is not None and not args.out.strip():
        raise InputError("--out must not be empty (omit it for the default)")
    if getattr(args, "scheme", None) is not None and not args.scheme.strip():
        from ..dynamics.schemes import SCHEMES

        raise InputError(
            f"--scheme must not be empty; allowed: {', '.join(SCHEMES.names())}, module:Class or "
            "path/to/file.py:Class (omit it for the default)"
        )


def benchmark_spec(args: argparse.Namespace) -> RunSpec:
    from ..studies.benchmarks import get_benchmark

    _check_out_given(args)
    bench = get_benchmark(args.target)
    overrides = parse_assignments(args.set, "--set")
    n = args.n if args.n is not None else bench.n_default()
    if n < 1:
        raise InputError(f"--n must be a positive integer, got {n}")
    dt_default, T_default = bench.run_times(n, overrides)
    dt = args.dt if args.dt is not None else dt_default
    T = args.T if args.T is not None else T_default
    limits = _limits(args, {})
    sch, sol = _options(args, {}, {})
    nodes, cells, per_cell = bench.mesh_counts(n, overrides)
    counts = (nodes, cells, per_cell, bench.dim, bench.contact_count(n, overrides))
    # a resume checks the steps of its own grid later; the mesh and operators now, before they are built
    check_size(counts, dt, T, limits, sol, steps=1 if getattr(args, "resuming", False) else None)
    problem = with_friction(bench.problem(n, overrides), args.friction)
    params = bench.params(overrides)
    meta = {"benchmark": args.target, "n": n, "parameters": params, "mass_named": args.mass is not None}
    if args.snapshot_every is not None and args.snapshot_every < 0:
        raise InputError(f"--snapshot-every must be >= 0, got {args.snapshot_every}")
    scheme = load_scheme(args.scheme or "cn")
    measure = bench.measure(params) if bench.measure is not None else None
    control = getattr(args, "dt_control", None) or "fixed"  # the paper's benchmarks keep their fixed grids
    meta["time_control_chosen_by"] = "command line" if getattr(args, "dt_control", None) else "default (a benchmark)"
    return RunSpec(
        problem,
        scheme,
        dt,
        T,
        args.mass or DEFAULT_MASS,
        Path(args.out or "out/run"),
        args.target,
        sch,
        sol,
        args.snapshot_every or 0,
        meta,
        limits=limits,
        measure=measure,
        events=parse_stop_at(args.stop_at),
        checkpoint_every=_checkpoint_every(args, 0),
        invocation=invocation(args),
        control=control,
    )


def _control_name(control: Any) -> str:
    """The name of a run's control (``fixed`` for None)."""
    from ..dynamics.stepping.step_control import control_spec

    return control_spec(control)[0]


#: masses that keep the inertia of the contact nodes: their contact chatters at every step size,
#: so the default control leaves them at the steps asked for (the energy control, asked for by
#: name, runs and reports it: docs/schemes.md)
CONTACT_INERTIA_MASSES = ("standard", "lumped")


def case_control(
    args: argparse.Namespace,
    case_control: dict | None,
    scheme: Any,
    meta: dict,
    mass: str = "",
    scheme_options: dict | None = None,
) -> Any:
    """The control of a case file's run: ``--dt-control``, else the file's ``[time] control``,
    else ``energy`` (the default of a user's run; docs/schemes.md), which a scheme that cannot
    change its step (paoli-schatzman) or a mass with contact inertia (standard, lumped) turns
    into ``fixed``, said in the summary."""
    given = getattr(args, "dt_control", None)
    if given:
        meta["time_control_chosen_by"] = "command line"
        if case_control is not None and case_control.get("control") != given:
            meta.setdefault("overrides", {})["control"] = {
                "case_file": case_control.get("control"),
                "command_line": given,
            }
        if given == "energy" and case_control is not None and case_control.get("control") == "energy":
            return case_control
        return given
    if case_control is not None:
        meta["time_control_chosen_by"] = "case file"
        return case_control
    from ..dynamics.schemes import make_scheme

    try:
        why = make_scheme(scheme, scheme_options).step_control_refusal()
    except (InputError, TypeError, AttributeError):  # refused later, by name, where the scheme is built
        why = ""
    if why:
        meta["time_control_chosen_by"] = "default"
        meta["time_control_note"] = (
            f"control 'energy' (the default for case files) cannot run this scheme: {why}; "
            'the steps asked for were taken ([time] control = "fixed" says so in the '
            "file)"
        )
        return "fixed"
    meta["time_control_chosen_by"] = "default"
    if mass in CONTACT_INERTIA_MASSES:
        meta["time_control_note"] = (
            f"control 'energy' (the default for case files) is not used with the {mass!r} "
            "mass: its contact nodes keep their inertia and its contact chatters at every "
            "step, which halving cannot resolve (docs/schemes.md); the steps asked for were "
            'taken ([time] control = "energy" runs it anyway and reports it)'
        )
        return "fixed"
    return "energy"


def _time_overrides(args: argparse.Namespace, dt, T: float) -> tuple[Any, float, dict]:
    """``--dt`` and ``--T`` over a case file's ``[time]`` values, checked as the file's are;
    the overrides as ``{key: {"case_file": ..., "command_line": ...}}`` for the summary."""
    from ..dynamics.stepping.time_grid import TimeGrid
    from ..errors import check_positive

    overrides: dict[str, dict] = {}
    if getattr(args, "dt", None) is not None:
        new_dt = check_positive("--dt", args.dt)
        if new_dt != dt:  # the file's own value given again is not an override
            overrides["dt"] = {"case_file": dt, "command_line": new_dt}
        dt = new_dt
    if getattr(args, "T", None) is not None:
        new_T = check_positive("--T", args.T)
        if new_T != T:
            overrides["T"] = {"case_file": T, "command_line": new_T}
        T = new_T
    if overrides and not getattr(args, "resuming", False):  # a resume checks its own grid, from its checkpoint
        if not isinstance(dt, (list, tuple)) and T < dt:
            raise InputError(f"--T must be >= the time step, got T={T} < dt={dt}")
        TimeGrid.build(dt, T)  # a whole number of steps (of each segment of a schedule)
    return dt, T, overrides


def _choice_overrides(args: argparse.Namespace, case, scheme, problem) -> dict:
    """``--scheme``, ``--mass`` and ``--friction`` over a case file's choices (summary.json ``overrides``), each
    ``{"case_file": ..., "command_line": ...}`` when it differs from the file's."""
    from ..dynamics.model.problem import pair_laws

    def laws(p) -> str:  # the contact laws of a problem's rows, as the --friction spelling
        used = ([p.friction] if p.obstacle is not None else []) + pair_laws(p)
        return ", ".join(dict.fromkeys(law.label for law in used)) or "frictionless"

    out: dict[str, dict] = {}
    name = getattr(scheme, "name", scheme)
    if args.scheme and name != case.scheme:
        out["scheme"] = {"case_file": case.scheme, "command_line": str(name)}
    if args.mass and args.mass != case.mass:
        out["mass"] = {"case_file": case.mass, "command_line": args.mass}
    if args.friction is not None and laws(problem) != laws(case.problem):
        out["friction"] = {"case_file": laws(case.problem), "command_line": laws(problem)}
    return out


def case_spec(args: argparse.Namespace) -> RunSpec:
    from .config import load_case

    if getattr(args, "n", None) is not None:
        raise InputError("--n does not apply to a case file; its mesh is set in the file")
    if args.set:
        raise InputError("--set does not apply to a case file; edit the file")
    _check_out_given(args)
    case = load_case(args.target, _limits(args, {}), check_size, args.backend)
    out = Path(args.out) if args.out else (case.out or Path("out") / Path(args.target).stem)
    scheme = load_scheme(args.scheme) if args.scheme else case.scheme
    sch, sol = _options(args, case.scheme_options if not args.scheme else {}, case.solver_options)
    every = args.snapshot_every if args.snapshot_every is not None else case.snapshot_every
    if every < 0:
        raise InputError(f"--snapshot-every must be >= 0, got {every}")
    limits = _limits(args, case.limits)
    dt, T, overrides = _time_overrides(args, case.dt, case.T)
    # a resume checks the steps of its own grid later (the case's mesh is built: its size is the file's)
    check_size(mesh_counts(case.problem), dt, T, limits, sol, steps=1 if getattr(args, "resuming", False) else None)
    meta = {"case_file": str(args.target), "mass_named": bool(args.mass) or case.mass_named}
    problem = with_friction(case.problem, args.friction)
    overrides.update(_choice_overrides(args, case, scheme, problem))
    if overrides:
        meta["overrides"] = overrides
    events = parse_stop_at(args.stop_at) if args.stop_at is not None else case.stop_at
    control = case_control(args, case.control, scheme, meta, args.mass or case.mass, sch)
    return RunSpec(
        problem,
        scheme,
        dt,
        T,
        args.mass or case.mass,
        out,
        Path(args.target).name,
        sch,
        sol,
        every,
        meta,
        Path(args.target),
        limits,
        events=events,
        checkpoint_every=_checkpoint_every(args, case.checkpoint_every),
        invocation=invocation(args),
        case_hash=case_text_hash(Path(args.target), case.files),
        control=control,
    )


class LazyFieldWriter:
    """A :class:`~signorini.io.output.FieldWriter` into the result directory, which is
    created only when the time loop starts (so invalid input creates nothing); a resumed
    run's writer first copies the snapshots of the run it continues (``source``: its
    fields.xdmf) up to the resumed level."""

    def __init__(self, rd: ResultDirectory, every: int, source: Path | None = None):
        self.rd, self.every, self.inner, self.source = rd, every, None, source
        self.warning = ""

    def resume(self, run, n, state, data) -> None:
        if self.source is None or self.inner is None:
            return
        if not self.source.is_file():  # a killed run: its partial fields were not kept
            self.warning = (
                f"the fields before the resumed level {n} are not in this result: the run it continues "
                f"has no {self.source.name} (killed, or run without --snapshot-every)"
            )
            return
        with _rank0_only():
            self.inner.copy_from(self.source, run.level_times, n)

    def start(self, run) -> None:
        from .output import FieldWriter

        with _rank0_only():
            self.inner = FieldWriter(self.rd.create() / "fields.xdmf", self.every)
            self.inner.start(run)

    def record(self, run, n, state) -> None:
        with _rank0_only():
            self.inner.record(run, n, state)

    def close(self, run, status, n_last, state) -> None:
        if self.inner is not None:
            with _rank0_only():
                self.inner.close(run, status, n_last, state)


@contextmanager
def _rank0_only():
    """Code that only rank 0 runs inside the time loop: a failure there is not the other
    ranks' (they would wait for rank 0 at the next step), so it ends every rank."""
    try:
        yield
    except BaseException:
        mark_unshared()
        raise


def write_setup_failure(rd: ResultDirectory, spec: RunSpec, exc: Exception) -> None:
    """summary.json of a run that failed before its first step (status failed, no levels,
    every counter of :data:`~signorini.dynamics.observe.history.COUNTER_KEYS` zero)."""
    from ..dynamics.observe.history import COUNTER_KEYS

    tmp = rd.create()
    summary = {
        "status": "failed",
        "success": False,
        "message": f"set-up: {exc}",
        "problem": spec.label,
        "steps": 0,
        "counters": dict.fromkeys(COUNTER_KEYS, 0),
        **spec.meta,
    }
    (tmp / "summary.json").write_text(json.dumps(summary, indent=1, default=str))
    rd.commit()


def execute(spec: RunSpec, args: argparse.Namespace) -> int:
    """Run the simulation into a temporary directory and publish it, whatever the status.

    Started by ``mpiexec`` (backend ``petsc``), rank 0 does this and the other ranks run
    the same simulation writing nothing (:func:`execute_follower`)."""
    from ..dynamics.stepping.simulate import simulate
    from ..linalg.base import BACKENDS
    from ..parallel import launched, run_comm

    rank, _ = launched()
    backend = str(spec.solver_options.get("backend", "auto"))
    if backend not in BACKENDS.names():  # a misspelling on several ranks: say so, as a serial run does
        raise InputError(f"unknown solver.backend {backend!r}; allowed: {', '.join(BACKENDS.names(aliases=False))}")
    comm = run_comm(backend)  # a serial backend on P > 1: refused
    if rank != 0:
        return execute_follower(spec, comm)
    try:
        rd = ResultDirectory(spec.out, args.overwrite)  # the checks of the output path
    except BaseException:
        comm.bcast(False)  # the other ranks stop too, silently (rank 0 says why)
        raise
    comm.bcast(True)
    # from the end of the time loop to the end of the report, one block records SIGINT/SIGTERM
    # (a gap between two blocks let a signal after the commit say "nothing written", exit 130)
    with contextlib.ExitStack() as after_loop:
        with rd:
            source = spec.resume.parent / "fields.xdmf" if spec.resume is not None else None
            observers = [LazyFieldWriter(rd, spec.snapshot_every, source)] if spec.snapshot_every else []
            if spec.measure is not None:
                observers += spec.measure.observers()
            try:
                H = simulate(
                    spec.problem,
                    spec.scheme,
                    spec.dt,
                    spec.T,
                    mass=spec.mass,
                    progress=Progress(args.quiet, spec.label, estimated=_control_name(spec.control) != "fixed"),
                    scheme_options=spec.scheme_options,
                    solver_options=spec.solver_options,
                    observers=observers,
                    events=spec.events,
                    control=spec.control,
                    **_checkpoint_arguments(spec, lambda: rd.create() / "checkpoint.h5"),
                    on_checkpoint=lambda c: rd.checkpointed(killed_summary(spec, c)),
                )
            except ConvergenceError as exc:  # before the first step (non-finite operators, ...)
                write_setup_failure(rd, spec, exc)
                print(f"signorini: failed: {one_line(exc)} (summary in {spec.out})", file=sys.stderr)
                return EXIT_CODES["failed"]
            late = after_loop.enter_context(deferred_signals())  # a signal now would lose every step: record it
            H.meta.update(spec.meta)
            fold_time_control(H.meta)
            H.meta["warnings"] += [o.warning for o in observers if getattr(o, "warning", "")]
            if spec.measure is not None:
                H.meta.update(spec.measure.summary(H))
            tmp = rd.create()
            if spec.case_file is not None:
                shutil.copy(spec.case_file, tmp / "case.toml")
            try:
                H.save(tmp)
            except OSError as exc:  # a full disk, a file-size limit: keep the checkpoint, name the file
                raise keep_after_write_failure(rd, tmp, H, spec, exc) from None
            if late.name and H.status == "finished":
                H.status, H.message = "interrupted", f"{late.name} while the results were written (all steps kept)"
                H.save(tmp)
            rd.commit()
        report_run(H, spec, args)  # the results are in place: a signal now only shortens the report
    late_signal = late.name if H.status == "finished" else None
    if late_signal:
        print(f"signorini: {late_signal} received after the results were written; nothing lost", file=sys.stderr)
    return EXIT_CODES[H.status]


def fold_time_control(meta: dict) -> None:
    """The run's ``time_control_chosen_by`` and ``time_control_note`` into ``time_control``."""
    tc = meta.get("time_control")
    for k in ("chosen_by", "note"):
        v = meta.pop(f"time_control_{k}", None)
        if v and isinstance(tc, dict):
            tc[k] = v


def keep_after_write_failure(rd: ResultDirectory, tmp: Path, H, spec: RunSpec, exc: OSError) -> OSError:
    """The run's results could not all be written (``exc``, a full disk or a file-size limit):
    the file that failed is removed, a summary saying so is written if it fits, and the
    directory, with its complete checkpoint of the last level (every level's series), is
    published as a resumable result.  Returns the error to raise (exit 4), naming the file."""
    name = Path(exc.filename).name if exc.filename else "the results"
    why = exc.strerror or str(exc)
    if exc.filename and Path(exc.filename).parent == tmp:
        Path(exc.filename).unlink(missing_ok=True)  # a partial file of this run
    resumable = (tmp / "checkpoint.h5").is_file()
    how = (
        (
            f"checkpoint.h5 holds the {H.steps} step(s) computed: `signorini resume {spec.out} --T <later T> --out "
            "<new directory>` continues it"
        )
        if resumable
        else "no checkpoint was written"
    )
    message = f"the run {H.status} ({H.steps} step(s)) but writing {name} failed: {why}; {how}"
    try:
        s = {**H.summary(), "status": "failed", "success": False, "message": message, "resumable": resumable}
        (tmp / "summary.json").write_text(json.dumps(s, indent=1, default=str))
    except (OSError, ValueError, TypeError):
        (tmp / "summary.json").unlink(missing_ok=True)
    try:
        rd.commit()
        kept = f"what was computed is in {str(spec.out)!r}"
    except OSError as again:
        kept = f"the result directory could not be published either ({again.strerror or again})"
    return OSError(
        exc.errno,
        f"writing {name} failed: {why}; the run computed {H.steps} step(s); {kept}"
        + (" (resumable from its checkpoint.h5)" if resumable else ""),
    )


def execute_follower(spec: RunSpec, comm) -> int:
    """A rank other than 0: waits for rank 0's checks of the output path, then runs the
    same simulation and writes nothing (the command line keeps it silent)."""
    from ..dynamics.stepping.simulate import simulate

    if not comm.bcast(None):  # rank 0 refused the output path and says why
        return 2
    observers = spec.measure.observers() if spec.measure is not None else []
    try:
        H = simulate(
            spec.problem,
            spec.scheme,
            spec.dt,
            spec.T,
            mass=spec.mass,
            scheme_options=spec.scheme_options,
            solver_options=spec.solver_options,
            observers=observers,
            events=spec.events,
            control=spec.control,
            **_checkpoint_arguments(spec, None),
        )
    except ConvergenceError:
        return EXIT_CODES["failed"]
    # the loop's stop is agreed: a signal from now on must not end this rank on its own
    # (KeyboardInterrupt would abort every rank while rank 0 writes the results)
    for s in (signal.SIGINT, signal.SIGTERM):
        signal.signal(s, signal.SIG_IGN)
    return EXIT_CODES[H.status]


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
        again = ""
        if (H.meta.get("checkpoints") or {}).get("written"):
            again = f"; continue with `signorini resume {spec.out} --out NEW`"
        print(f"signorini: {H.status}: {one_line(H.message)} (partial results in {spec.out}{again})", file=sys.stderr)


def _checkpoint_arguments(spec: RunSpec, path) -> dict:
    """simulate's checkpoint arguments of a run of the command line (every run checkpoints its
    last level; rank 0 writes, the other ranks compute the same contents and write nothing)."""
    return {
        "checkpoint": path if path is not None else Path("/nonexistent/checkpoint.h5"),
        "checkpoint_every": spec.checkpoint_every,
        "checkpoint_meta": {"invocation": spec.invocation},
        "case_hash": spec.case_hash,
        "resume": spec.resume,
    }


def killed_summary(spec: RunSpec, c: dict) -> dict:
    """summary.json of a run killed outright after the checkpoint ``c`` (the watchdog writes it)."""
    return {
        "status": "killed",
        "success": False,
        "problem": spec.label,
        "steps": c["level"],
        "message": f"killed (SIGKILL, a job limit or the kernel) after the checkpoint of level {c['level']} "
        f"(t = {c['t']:.6g}); continue it with `signorini resume <this directory> --T ... --out ...`",
        "resumable": True,
        "checkpoint": {"level": c["level"], "t": c["t"]},
        "counters": c["counters"],
        "scheme": c["scheme"],
        "mass": c["mass"],
        **spec.meta,
    }


def _kept_invocation(attrs: dict, where: str) -> dict:
    """The arguments of ``signorini run`` a checkpoint keeps, each checked against
    :data:`INVOCATION_TYPES` (an edited file is refused by name, never used as is)."""
    inv = (attrs.get("meta") or {}).get("invocation") if isinstance(attrs.get("meta"), dict) else None
    if not isinstance(inv, dict) or not inv.get("target"):
        raise InputError(
            f"{where} was not written by `signorini run` (no command to rebuild the run from); "
            "resume it from Python: simulate(..., resume=PATH)"
        )
    for key, value in inv.items():
        kinds = INVOCATION_TYPES.get(key)
        if kinds is None:
            raise InputError(f"{where}: malformed checkpoint: its invocation holds an unknown argument {key!r}")
        ok = value is None or (isinstance(value, kinds) and (bool in kinds or not isinstance(value, bool)))
        if ok and isinstance(value, list):
            ok = all(isinstance(x, str) for x in value)
        if not ok:
            allowed = " or ".join(k.__name__ for k in kinds)
            raise InputError(
                f"{where}: malformed checkpoint: invocation argument {key!r} is {value!r}, expected {allowed} or null"
            )
    return inv


def _resume_scheme(recorded: str | None, given: str | None, where: str) -> str | None:
    """The scheme a resumed run is rebuilt with.  A checkpoint never names code to import: a
    scheme of the user's own must be named again with ``--scheme`` (the resumed run then
    compares its label with the checkpoint's record and refuses another one by name)."""
    if given is not None:
        return given
    if is_plugin_scheme(recorded):
        raise InputError(
            f"{where} was computed with a scheme of your own ({recorded!r}); a checkpoint never imports code: "
            "name it again with --scheme (it is checked against the checkpoint's record)"
        )
    return recorded


def resume_spec(args: argparse.Namespace) -> RunSpec:
    """``signorini resume RESULT_DIR [--T T] --out NEW``: the run of RESULT_DIR rebuilt from the
    arguments its checkpoint keeps, continued from it to T (default: the run's own final time;
    :mod:`~signorini.dynamics.restart.checkpoint`).

    The checkpoint's checksum is verified and every kept argument type-checked before any is
    used; nothing it names is imported or executed (a scheme of the user's own is named again
    with ``--scheme``)."""
    from ..dynamics.restart.checkpoint import read

    result = Path(args.result)
    if not result.is_dir():
        raise InputError(f"RESULT_DIR {str(result)!r} is not a directory (a result of `signorini run`)")
    where = result / "checkpoint.h5"
    meta = read(where)["attrs"]  # format, version, checksum and attribute types checked first
    label = f"checkpoint {str(where)!r}"
    inv = _kept_invocation(meta, label)
    if args.out is None or not str(args.out).strip():
        raise InputError("--out is required: the resumed result goes into a new directory (RESULT_DIR is kept)")
    if Path(args.out).resolve() == result.resolve():
        raise InputError("--out must not be RESULT_DIR: the resumed result is a new directory")
    ns = argparse.Namespace(**{k: inv.get(k) for k in INVOCATION_ARGS})
    ns.scheme = _resume_scheme(inv.get("scheme"), getattr(args, "scheme", None), label)
    ns.out, ns.quiet, ns.overwrite = args.out, args.quiet, args.overwrite
    ns.max_steps, ns.max_memory, ns.yes = args.max_steps, args.max_memory, args.yes
    case = str(ns.target).endswith(".toml")
    if case and not Path(ns.target).is_file():
        raise InputError(f"the case file of the run, {ns.target!r}, is gone; put it back to resume")
    if args.snapshot_every is not None:
        ns.snapshot_every = args.snapshot_every
    if args.checkpoint_every is not None:
        ns.checkpoint_every = args.checkpoint_every
    if args.T is not None:
        ns.T = args.T
    ns.resuming = True
    spec = case_spec(ns) if case else benchmark_spec(ns)
    if case and spec.case_hash != meta.get("identity", {}).get("case_file"):
        raise InputError(
            f"the case file {ns.target!r} or a file it reads (mesh, surface obstacle) changed since "
            f"the checkpoint of {str(result)!r}; resume needs the same files"
        )
    t_ckpt = float(meta["t"])
    if args.dt is not None:
        from ..errors import check_positive

        spec.dt = check_positive("--dt", args.dt)
    elif not isinstance(spec.dt, (list, tuple)):  # one step: the checkpoint's (a resume --dt goes on with its own)
        # an adaptive run's: its largest step (the checkpoint's dt is the refined step it was on)
        spec.dt = _plan_dt(meta, where) if "time_control" in meta else float(meta["dt"])
    if _control_name(spec.control) == "energy" and not isinstance(meta.get("time_control"), dict):
        raise InputError(
            f"checkpoint {str(where)!r}: the energy control's state is missing or malformed (a run under "
            "the control keeps it in every checkpoint); resume from an intact checkpoint"
        )
    if not spec.T > t_ckpt:
        if args.T is None:
            raise InputError(
                f"the run of {str(result)!r} already reached its final time T = {t_ckpt:.10g}; "
                "give a later --T to continue it"
            )
        raise InputError(f"--T {args.T:g} must be after the checkpoint's t = {t_ckpt:.10g}")
    from ..dynamics.stepping.time_grid import TimeGrid

    if "time_control" in meta and _control_name(spec.control) == "energy":  # an adaptive run's grid goes on
        from ..dynamics.stepping.stepper import adaptive_grid

        grid = adaptive_grid(spec.dt, spec.T, meta, str(where))
        # its size at its largest steps, piece by piece of its plan (a dt schedule too; the grid's own count continues
        # the refined step it was on: a resume inside an impact was refused as 1.5 million steps)
        spans = [(max(begin, t_ckpt), min(end, spec.T), dt) for begin, end, dt in grid.plan]
        steps = int(meta["level"]) + sum(math.ceil((b - a) / dt - 1e-9) for a, b, dt in spans if b > a)
    else:
        grid = TimeGrid.build(spec.dt, spec.T, int(meta["level"]), t_ckpt, meta.get("segment"))  # T, --dt
        steps = grid.n_steps
    check_size(mesh_counts(spec.problem), spec.dt, spec.T, spec.limits, spec.solver_options, steps=steps)
    fields = result / "fields.xdmf"
    if spec.snapshot_every and fields.is_file():  # copied into the new result: readable, or refused now
        from .output import check_fields

        check_fields(fields)
    spec.resume = where
    spec.invocation["T"] = spec.T  # a resume of this run's result continues to this T
    spec.meta["resumed_from_directory"] = str(result)
    return spec


def _plan_dt(meta: dict[str, Any], where: Any) -> float:
    """The energy control's largest step (``time_control.plan_dt``) of a checkpoint, checked: a positive number whose
    dyadic ladder holds the checkpoint's step (segment step = plan_dt / 2^k, k the control's level)."""
    tc = meta["time_control"]
    plan = tc.get("plan_dt") if isinstance(tc, dict) else None
    if isinstance(plan, bool) or not isinstance(plan, (int, float)) or not (math.isfinite(plan) and plan > 0):
        raise InputError(
            f"checkpoint {str(where)!r}: the energy control's largest step plan_dt {plan!r} is not a positive number"
        )
    k, segment = tc.get("k"), meta.get("segment")
    try:
        step = float(segment[1])
    except (TypeError, ValueError, IndexError):
        raise InputError(f"checkpoint {str(where)!r}: its segment {segment!r} is malformed") from None
    if (
        isinstance(k, bool)
        or not isinstance(k, int)
        or not 0 <= k <= 64
        or not (abs(step - plan / 2**k) <= 1e-12 * plan)
    ):
        raise InputError(
            f"checkpoint {str(where)!r}: its step {step:g} is not the energy control's largest step "
            f"plan_dt = {plan:g} / 2^k at its level k = {k!r}"
        )
    return float(plan)


def cmd_resume(args: argparse.Namespace) -> int:
    """``signorini resume RESULT_DIR [--T T] --out NEW`` (:func:`resume_spec`), on every rank alike."""
    return execute(agreed(lambda: resume_spec(args)), args)


def cmd_run(args: argparse.Namespace) -> int:
    spec = agreed(lambda: case_spec(args) if args.target.endswith(".toml") else benchmark_spec(args))
    return execute(spec, args)


def _spec_identity(spec: RunSpec) -> str:
    """What every rank of a run must have read alike: the case's hash (its text and the files it
    reads) and the arguments (the case file's path left out: ranks may see it at other paths)."""
    inv = {k: v for k, v in spec.invocation.items() if k != "target"}
    return json.dumps([spec.case_hash, spec.label, inv], sort_keys=True, default=str)


def agreed(build) -> RunSpec:
    """``build()``'s spec, agreed between the ranks of ``mpiexec``: a rank that refuses its
    input, or one that read another input than rank 0 (a node-local case file that differs),
    makes every rank stop with exit 2 and one line, never the others wait for it forever.
    One process: ``build()`` as it is."""
    from ..parallel import MPIComm, launched

    size = launched()[1]
    if size < 2:
        return build()
    try:
        spec, error = build(), ""
    except InputError as exc:
        spec, error = None, one_line(exc)
    try:
        comm = MPIComm()
    except InputError:  # no mpi4py: no collective follows, each rank refuses on its own
        if error:
            raise InputError(error) from None
        return spec
    errors = comm.gather(error)
    bad = [k for k, e in enumerate(errors) if e]
    if bad:
        if len(bad) == size and all(e == errors[0] for e in errors):
            raise InputError(errors[0])
        raise InputError(
            f"rank {bad[0]} of {size} refused its input ({errors[bad[0]]}) and "
            f"{size - len(bad)} rank(s) did not: every rank must read the same input (a file that "
            "differs between the machines?)"
        )
    ids = comm.gather(_spec_identity(spec))
    other = [k for k, i in enumerate(ids) if i != ids[0]]
    if other:
        raise InputError(
            f"rank {other[0]} of {size} read another input than rank 0 (the arguments, the case file or "
            "a file it reads differ): every rank must read the same input (a node-local copy that "
            "differs?)"
        )
    return spec

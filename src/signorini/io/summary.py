"""What a run prints: the progress bar on stderr and the one-screen summary on stdout."""

from __future__ import annotations

import sys
import time

import numpy as np

#: a batch log's first progress line comes after this many seconds [s] (shorter runs print none)
LOG_FIRST = 10.0
#: and then at most one line per this many seconds [s] (``SIGNORINI_PROGRESS_EVERY`` sets both)
LOG_EVERY = 30.0


class Progress:
    """Progress on stderr, unless quiet: a one-line bar redrawn in place when stderr is a
    terminal; otherwise (a batch job's log) plain lines at a bounded rate, the first after
    :data:`LOG_FIRST` s with the set-up time, then at most one per :data:`LOG_EVERY` s (step,
    time, elapsed, ETA), and a last one when the loop ends (only if one was printed).  ``estimated``: the
    step total is an estimate that changes as the run goes (the energy control refines and coarsens the
    step): it is shown as ``~n``, "estimated"."""

    def __init__(self, quiet: bool, label: str, stream=None, estimated: bool = False):
        import os

        self.stream = stream if stream is not None else sys.stderr
        tty = self.stream.isatty()
        self.enabled = not quiet
        self.mode = "bar" if tty else "log"
        self.label = label
        self.t0 = time.perf_counter()
        self.last = 0.0
        self.first: tuple[float, int] | None = None  # (time, step) of the first step seen
        every = os.environ.get("SIGNORINI_PROGRESS_EVERY", "")
        try:
            self.log_first = self.log_every = float(every) if every else None
        except ValueError:
            self.log_first = self.log_every = None
        if self.log_every is None or not self.log_every >= 0:
            self.log_first, self.log_every = LOG_FIRST, LOG_EVERY
        self.lines = 0
        self.estimated = estimated

    def _total(self, n: int) -> str:
        return f"~{n} (estimated)" if self.estimated else str(n)

    def __call__(self, i: int, n: int) -> None:
        if not self.enabled:
            return
        now = time.perf_counter()
        if self.first is None:  # the estimate starts with the loop: set-up time is not a step's
            self.first = (now, i)
        if self.mode == "log":
            self._log(now, i, n)
            return
        if now - self.t0 < 2.0 or (now - self.last < 0.2 and i < n):
            return
        self.last = now
        frac = i / n
        bar = "#" * int(30 * frac)
        self.stream.write(f"\r{self.label} [{bar:<30}] {i}/{self._total(n)} steps, {self._eta(now, i, n):5.1f}s left")
        if i == n:
            self.stream.write("\n")
        self.stream.flush()

    def _eta(self, now: float, i: int, n: int) -> float:
        t1, i1 = self.first
        return (now - t1) / max(i - i1, 1) * (n - i)

    def _log(self, now: float, i: int, n: int) -> None:
        """A plain line for a log file (no carriage return), at a bounded rate."""
        if i < n:
            if self.lines == 0 and now - self.t0 < self.log_first:
                return
            if self.lines and now - self.last < self.log_every:
                return
        elif self.lines == 0:  # a short run: no line at all
            return
        first = ""
        if self.lines == 0:
            first = f"set-up {self.first[0] - self.t0:.1f} s; "
        self.last = now
        self.lines += 1
        state = "done" if i == n else f"ETA {self._eta(now, i, n):.0f} s"
        self.stream.write(
            f"{self.label}: {first}step {i}/{self._total(n)} ({100 * i / n:.0f}%), "
            f"{now - self.t0:.0f} s elapsed, {state}\n"
        )
        self.stream.flush()


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


def damping_line(H, s: dict) -> str:
    """With Rayleigh damping: its coefficients and what it dissipated (the energy line's drift
    includes it: a damped run loses energy by design)."""
    d = s.get("damping") or {}
    if d.get("model", "none") == "none":
        return ""
    diss = float(H.columns()["damping_dissipation"][-1]) + 0.0  # no "-0"
    work = f"{diss:.6g}" if np.isfinite(diss) else "n/a"
    res = s.get("energy_identity_residual")
    res_text = f" (energy identity residual {res:.2e} with it)" if res is not None else ""
    e0 = abs(float(s["energy_initial"]))
    share = f", {100 * diss / e0:.3g}% of E0" if e0 > 0 and np.isfinite(diss) else ""
    regions = "".join(f"{r['tag']} alpha {r['alpha']:g}, beta {r['beta']:g}; " for r in d.get("regions", ()))
    coefficients = f"alpha {d['alpha']:g}, beta {d['beta']:g}"
    if regions:
        coefficients = f"{regions}cells in no listed region {coefficients}"
    return f"  damping rayleigh {coefficients}: damping_dissipation {work}{share}{res_text}\n"


def material_line(H, s: dict) -> str:
    """With finite strain: the models and the Newton iterations and tangent factorizations it took."""
    if not s.get("finite_strain"):
        return ""
    c = s["counters"]
    it = H.columns()["nonlinear_iterations"][1:]
    mean = f", {float(np.mean(it)):.3g} per step (max {int(np.max(it))})" if it.size else ""
    projected = "; velocities projected on the momenta (momentum_projection)" if s.get("momentum_projection") else ""
    return (
        f"  finite strain ({', '.join(s.get('material_model') or [])}): Newton {int(np.sum(it))} iterations{mean}, "
        f"{c.get('tangent_factorizations', 0)} tangent factorizations{projected}\n"
    )


def friction_line(H, s: dict) -> str:
    """With friction: the law, what it dissipated, the last level's stick/slip nodes and the solver."""
    f = s.get("friction") or {}
    if f.get("law", "frictionless") == "frictionless":
        return ""
    cols = H.columns()
    diss = float(cols["friction_dissipation"][-1]) + 0.0  # no "-0"
    res = s.get("energy_identity_residual")
    work = "n/a" if not np.isfinite(diss) else f"{diss:.6g}"
    res_text = f" (energy identity residual {res:.2e} with it)" if res is not None else ""
    c = s["counters"]
    return (
        f"  friction {', '.join(f'{k} {v}' for k, v in f.items() if k != 'law')} ({f['law']}): friction_dissipation "
        f"{work}{res_text}, at the end {int(cols['stick_nodes'][-1])} stick / "
        f"{int(cols['slip_nodes'][-1])} slip nodes; {c.get('friction_iterations', 0)} Newton iterations, "
        f"{c.get('friction_fallbacks', 0)} cone solve(s) by the fallback, "
        f"cone residual max {s['cone_residual_max']:.2e}\n"
    )


def bodies_lines(s: dict) -> str:
    """With several bodies: per body its regions, mass and, at the last level, momentum and
    kinetic energy; per contact pair its rows, law and re-pairings."""
    bodies = s.get("bodies") or []
    if len(bodies) < 2:
        return ""
    out = []
    for k, b in enumerate(bodies):
        regions = f" ({', '.join(b['regions'])})" if b.get("regions") else ""
        mass = f"mass {b['mass']:.6g}" if b.get("mass") is not None else "mass n/a"
        end = ""
        if b.get("momentum") is not None:
            end = (
                f", at the end momentum [{', '.join(f'{x:.4g}' for x in b['momentum'])}], "
                f"kinetic energy {b['kinetic_energy']:.4g}"
            )
        out.append(f"  body {k}{regions}: {b['nodes']} nodes, {mass}{end}\n")
    if s.get("master_penetration_max"):  # node-to-facet: the master nodes are free to enter the slave surface
        out.append(
            f"  master nodes through the slave surface: at most {s['master_penetration_max']:.3g} (node "
            f"{s['master_penetration_node']} at t = {s['master_penetration_time']:.6g}); contact constrains "
            "the slave nodes only (docs/bodies.md: the finer side as slave)\n"
        )
    for p in s.get("pairs") or []:
        law = (p.get("friction") or {}).get("law", "frictionless")
        again = f", {p['repaired_rows']} re-paired" if p.get("repaired_rows") else ""
        end = p.get("slave_nodes_facing_nothing_at_end")
        end = "" if end is None else f", {end} at the end"
        out.append(
            f"  pair {p['slave']} / {p['master']}: {p['rows']} rows ({p['inactive_slave_nodes']} slave nodes "
            f"facing nothing at t = 0{end}), {law}{again}\n"
        )
    return "".join(out)


def _quadratic(s: dict) -> str:
    """`` on quadratic cells (tetra10)`` for a run of quadratic cells (the first line says what is computed)."""
    cells = s.get("cells") or {}
    return f" on quadratic cells ({', '.join(cells['types'])})" if cells.get("order") == 2 else ""


def one_screen_summary(H) -> str:
    s = H.summary()
    c = s["counters"]
    return (
        f"{s['problem']}: {s['scheme']} / {s['mass']} mass, {s['dofs']} dofs{_quadratic(s)}, {s['contact_nodes']} "
        "contact nodes\n"
        f"  status {s['status']}{': ' + s['message'] if s['message'] else ''}\n"
        f"  steps {s['steps']} (dt={s['dt']:.4g}, T={s['T']:.4g}), impacts {s['impacts']}, "
        f"{s['fallbacks']} step(s) with the contact solver's fallback\n"
        f"{time_lines(s)}"
        f"{equilibrium_line(s)}"
        f"{energy_line(H, s)}"
        f"{friction_line(H, s)}"
        f"{damping_line(H, s)}"
        f"{material_line(H, s)}"
        f"  max complementarity residual {s['max_complementarity_residual']:.2e}\n"
        f"{mass_effect_line(s)}"
        f"{bodies_lines(s)}"
        f"  setup {s['setup_seconds']:.3g}s, {1e3 * s['step_seconds']:.3g} ms/step ({s['backend']}), "
        f"{c.get('factorizations', 0)} factorization(s), {c.get('linear_solves', 0)} solves" + factorization_tip(s)
    )


def equilibrium_line(s: dict) -> str:
    """What ``[initial] equilibrium = true`` solved at t = 0 (nothing when it was not asked)."""
    e = s.get("initial_equilibrium") or {}
    if e.get("reason") == "not asked" or not e:
        return ""
    if not e.get("solved"):
        return f"  initial equilibrium not solved: {e.get('reason', '')}\n"
    free = f", free bodies {e['free_bodies']} keep their state" if e.get("free_bodies") else ""
    return (
        f"  initial equilibrium: bodies {e['held_bodies']} start in static equilibrium ({e['iterations']} "
        f"iteration(s), force left {e['force_left']:.2g} of {e['scale']:.3g}){free}\n"
    )


def time_lines(s: dict) -> str:
    """Where a resumed run resumed, the steps of a schedule, and the checkpoints written."""
    out = ""
    over = s.get("overrides")
    if over:
        out += (
            "  over the case file: "
            + ", ".join(
                f"{k} {_value(v['command_line'])} (the file's {_value(v['case_file'])})" for k, v in over.items()
            )
            + "\n"
        )
    r = s.get("resumed_from")
    if r:
        out += f"  resumed from level {r['level']} (t = {r['t']:.6g}) of {r['checkpoint']}\n"
    tc = s.get("time_control") or {}
    steps = s.get("dt_schedule")
    if tc.get("control") == "energy":
        out += time_control_line(tc)
    elif steps:
        out += "  time steps " + ", ".join(f"{x['dt']:.4g} to t = {x['until']:.6g}" for x in steps) + "\n"
    if tc.get("note"):
        out += f"  note: {tc['note']}\n"
    c = s.get("checkpoints")
    if c and c.get("written"):
        out += f"  checkpoint of level {c['level']} ({c['written']} written, {c['seconds']:.3g} s)"
        out += f"; {c['failed']} failed" if c.get("failed") else ""
        out += "\n"
    return out


def time_control_line(tc: dict) -> str:
    """The energy control's line: the steps used, accepted and rejected, where it refined."""
    if not tc.get("steps_accepted"):
        return "  time steps: energy control, no step taken\n"
    refined = tc.get("refined") or []
    where = ""
    if refined:
        shown = ", ".join(f"[{a:.4g}, {b:.4g}]" for a, b, _ in refined[:3])
        where = f"; refined over t in {shown}" + (f" and {len(refined) - 3} more" if len(refined) > 3 else "")
    told = ""
    if tc.get("tolerance") is not None:  # the control's tolerance, and whether the mesh made it (a default that
        # changes with the mesh says so)
        how = f"from the mesh, h/L = {tc['mesh_resolution']:.3g}" if tc.get("tolerance_from_mesh") else "given"
        told = f"tolerance {tc['tolerance']:.3g} ({how}), "
    return (
        f"  time steps: energy control, {told}{tc['dt_largest_used']:.4g} s largest used, "
        f"{tc['dt_smallest_used']:.4g} s smallest; {tc['steps_accepted']} accepted, {tc['steps_rejected']} "
        f"rejected, {tc['factorizations']} factorization(s){where}\n"
    )


def _value(x) -> str:
    """A number as %.6g, a name as itself (a control), a step schedule as 'schedule', none as 'none'."""
    if isinstance(x, str):
        return x
    if x is None:
        return "none"
    return f"{x:.6g}" if isinstance(x, (int, float)) else "schedule"


def factorization_tip(s: dict) -> str:
    """A hint when SuperLU factored a large 3D system and a faster backend is one pip away."""
    from ..linalg import BACKENDS, has_cholmod, has_pardiso

    big_3d = s.get("dim") == 3 and s.get("free_dofs", s["dofs"]) >= 30_000
    fallback = s["backend"] in BACKENDS.names() and BACKENDS.get(s["backend"]).traits.fallback
    if not fallback or not big_3d or has_cholmod() or has_pardiso():
        return ""
    from ..linalg.base import IMPORT_FAILURES

    broken = [f"{name} is installed but does not import ({why})" for name, why in sorted(IMPORT_FAILURES.items())]
    if broken:
        return "\n  tip: " + "; ".join(broken) + ": fix that install for a faster 3D factor (docs/performance.md)"
    return (
        '\n  tip: the extras cholmod and metis (pip install ".[cholmod,metis]"; or pardiso on x86-64) factor'
        " 3D systems like this one several times faster with a fraction of the memory (docs/performance.md)"
    )

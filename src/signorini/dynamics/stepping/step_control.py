"""Time-step control: the steps asked for, or steps that resolve each impact (issue 40).

``control = "fixed"`` takes the steps asked for (``dt`` or its schedule) at every level.

``control = "energy"`` takes them as the *largest* steps: inside each piece of the schedule
(one piece for one ``dt``) the step is dt / 2^k, k = 0 .. k_max, and a step is judged by the
part of its energy increment that no physical work explains (the energy identity of the
scheme, :meth:`~signorini.dynamics.schemes.Scheme.energy_increment`):

    delta = W_contact + D_numerical

* ``W_contact``: the work of the contact forces of the step, against a fixed obstacle (it
  never works on a body: zero for an impact resolved in time) and between the bodies of a
  contact pair (the relative work, zero as well); left out when the obstacle moves (its work
  is then physical).
* ``D_numerical``: the scheme's own part.  For an energy-conserving scheme (crank-nicolson,
  newmark with gamma = 1/2, theta = 1/2, hht alpha = 0, generalized-alpha rho_inf = 1,
  energy-conserving, penalty: :attr:`~signorini.dynamics.schemes.Scheme.conserving`) it is
  the error of the step, of either sign; for a dissipative one (backward-euler, theta > 1/2,
  hht, generalized-alpha, moreau-jean, contact-stabilized-newmark) its losses are the
  scheme's intended damping and only a gain counts.

A step whose |delta| (conserving) or delta (dissipative) exceeds

    allowed(h) = tolerance * E_scale * h / dt_piece

is **rejected**: the solvers' warm starts go back to the level before it (the state, the
pairing and the observers are only changed by an accepted step) and it is tried again at
h / 2.  E_scale is the run's energy scale (the largest of |E0|, the kinetic energy so far,
the new level's included, and the loads' work: ``summary.json`` ``spurious_energy.scale``),
so that the energy a contact episode shorter than dt may create is about ``tolerance *
E_scale`` (the allowance per step is proportional to the step).  A step that fails (a
contact solve that does not converge, a non-finite state) is rejected the same way.  After
``grow_after`` accepted steps with delta below a quarter of the allowance, the step grows
by 2 when the level is on the grid of 2h (never above the piece's dt, never across its end:
every level is on the piece's dyadic grid, its time start + j h without accumulated round-off).
At h = dt_min a step above the allowance is accepted, counted (``unresolved_steps``) and
warned of; nothing loops.

The factorizations of the steps used are kept (:meth:`~signorini.dynamics.solve.factorizations.Factorizations.use`)
within a share of the memory budget, so that a second impact at the same step factorizes
nothing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from ...errors import InputError
from ...registry import Parameter, Registry

if TYPE_CHECKING:
    from .seams import ControlledStepper

#: the largest refinement by default: dt_min = dt / 2^DEFAULT_LEVELS
DEFAULT_LEVELS = 10
#: the most doublings of the calm steps a growth needs after growths rejected in a row (grow_after 2^6 = 256)
MAX_BACKOFF = 6
#: the deepest refinement allowed (dt_min >= dt / 2^MAX_LEVELS): below, M / dt^2 swamps S in the
#: operators and the energy identity itself is lost to round-off (measured: bar1d_compressed
#: with dt_min = 1e-20 went down to 1e-17 and "finished" with 900 times its energy)
MAX_LEVELS = 20

TIME_CONTROLS = Registry("time control")
TIME_CONTROLS.register("fixed", None, "the steps asked for (dt or its schedule) at every level")
TIME_CONTROLS.register(
    "energy",
    None,
    "dt (each schedule piece's) as the largest step; a step whose energy indicator (contact work of a fixed "
    "obstacle or between bodies, and the scheme's numerical part beyond its intended damping) exceeds "
    "tolerance x E_scale x h / dt is rejected and tried again at h / 2, down to dt_min; the step grows back by 2",
    parameters=(
        Parameter(
            "tolerance",
            0.0,
            "energy a contact episode may create, relative to the energy scale (0: from the mesh, "
            "min(1e-3, 0.025 (h/L)^2), docs/schemes.md)",
            float,
            0.0,
            1.0,
        ),
        Parameter("dt_min", 0.0, "smallest step [s] (0: dt / 2^10)", float, 0.0),
        Parameter("grow_after", 4, "accepted calm steps before the step grows by 2", int, 1, 10**6),
    ),
)


#: the tolerance of a coarse mesh (h / L >= 0.2), and the rule's coefficient: tolerance = min(1e-3, 0.025 (h / L)^2)
COARSE_TOLERANCE = 1e-3
RESOLUTION_COEFFICIENT = 0.025


def mesh_tolerance(mesh: Any) -> tuple[float, float | None]:
    """(tolerance, h / L) of a run that gives none: min(1e-3, 0.025 (h / L)^2) with h / L the mesh's resolution
    (:func:`~signorini.fem.mesh.resolution`: a body's median cell size over its extent, the finest body's).

    Why the square: the control bounds each contact step's error estimate in energy (its elastic energy
    1/2 e.S e) by a fraction ``tolerance`` of the energy scale, so the error of the motion, |e| in the energy norm
    relative to the motion's, is of the order of sqrt(tolerance); linear elements resolve the motion to O(h / L) in
    that norm.  A time error below the mesh's own needs sqrt(tolerance) ~ h / L: measured on a nu = 0 steel column
    (a bar, whose exact rebound is its velocity reversed), 0.025 (h / L)^2 puts the rebound error at the fixed
    fine step's at 20, 40 and 80 cells (docs/schemes.md), where 1e-3 stalled at 2%.  (1e-3, None) without a
    mesh."""
    if mesh is None:
        return COARSE_TOLERANCE, None
    from ...fem.mesh import resolution

    r = resolution(mesh)
    return min(COARSE_TOLERANCE, RESOLUTION_COEFFICIENT * r * r), r


def default_levels(tolerance: float) -> int:
    """The deepest refinement of a step without a dt_min: DEFAULT_LEVELS (dt / 1024) at a tolerance of 1e-3 or
    more, one level more per factor 4 below it (an onset's energy error falls as h^2: a tolerance 4 times smaller
    needs a step half as long), at most MAX_LEVELS."""
    if tolerance >= COARSE_TOLERANCE:
        return DEFAULT_LEVELS
    return min(MAX_LEVELS, DEFAULT_LEVELS + math.ceil(0.5 * math.log2(COARSE_TOLERANCE / tolerance) - 1e-9))


def control_spec(control: Any, key: str = "control", prefix: str = "control") -> tuple[str, dict[str, Any]]:
    """(name, options) of ``control``: ``"fixed"``, ``"energy"``, or a mapping ``{"control":
    "energy", "tolerance": ..., "dt_min": ..., "grow_after": ...}``; an InputError naming the
    key (``key``; its options as ``prefix.option``) and the allowed names and options otherwise."""
    names = ", ".join(TIME_CONTROLS.names())
    if control is None:
        return "fixed", {}
    if isinstance(control, str):
        name, options = control, {}
    elif isinstance(control, dict):
        options = dict(control)
        name = options.pop("control", "energy")
    else:
        raise InputError(f"'{key}' must be one of {names} (or a table with its options), got {control!r}")
    if not isinstance(name, str):
        raise InputError(f"'{key}' must be one of {names}, got {name!r}")
    try:
        entry = TIME_CONTROLS.get(name)
    except InputError:
        raise InputError(f"unknown {key} {name!r}; allowed: {names}") from None
    if options and not entry.parameters:
        raise InputError(f"'{key}' = {entry.name!r} takes no options, got {', '.join(sorted(options))}")
    return entry.name, entry.options(options, where=prefix)


@dataclass
class EnergyControl:
    """The adaptive control of ``control = "energy"`` (module docstring): where it is on the
    ladder, its decisions, and what the summary says of them."""

    tolerance: float = 1e-3
    dt_min: float = 0.0
    grow_after: int = 4
    #: refinement of the current step: h = dt_piece / 2^k
    k: int = 0
    #: accepted calm steps since the step last changed
    calm: int = 0
    #: growths rejected in a row: the calm steps a growth needs are grow_after 2^backoff (:meth:`calm_needed`)
    backoff: int = 0
    #: whether the step was grown at the last accepted level (its rejection raises ``backoff``)
    just_grown: bool = False
    accepted: int = 0
    rejected: int = 0
    failed_trials: int = 0
    #: [t, excess] of each step accepted at dt_min above its allowance, judged again at the end
    #: against the run's final energy scale (:meth:`settle`: a run starting from E0 = 0 has no
    #: scale at its first steps)
    unresolved_excess: list[list[float]] = field(default_factory=list)
    #: steps rejected because a terminal event fell inside them (located within dt_min)
    event_refinements: int = 0
    smallest: float = math.inf
    largest: float = 0.0
    #: [t_start, t_end, smallest step] of each stretch where the step was below the piece's dt
    refined: list[list[float]] = field(default_factory=list)
    #: [first, last] level of each of those stretches
    refined_levels: list[list[int]] = field(default_factory=list)
    #: relative change of the total contact force over a step below which it is steady
    force_change: float = 0.01
    #: the contact force's sum at the level before the last accepted one, and whether its acting rows were the
    #: same as the last level's (:meth:`resting`)
    prev_sum: float | None = None
    persistent: bool = False
    #: the smallest step allowed: dt_min, or the smallest piece's dt / 2^default_levels (the Stepper sets it)
    dt_min_used: float = 0.0
    #: the deepest refinement without a dt_min: DEFAULT_LEVELS, one more per factor 4 of the tolerance below 1e-3
    #: (:func:`default_levels`)
    default_levels: int = DEFAULT_LEVELS
    #: h / L of the mesh when the tolerance was made from it (:func:`mesh_tolerance`), else None (given)
    mesh_resolution: float | None = None
    #: a test hook: every step is rejected once and tried again at the same step
    force_reject_once: bool = False
    _forced: bool = False

    def k_max(self, dt_piece: float) -> int:
        """The deepest refinement of a piece of step dt_piece: dt_piece / 2^k >= dt_min."""
        if self.dt_min <= 0.0:
            return self.default_levels
        ratio = dt_piece / self.dt_min
        if not math.isfinite(ratio):
            return MAX_LEVELS
        return min(MAX_LEVELS, max(0, int(math.floor(math.log2(ratio) + 1e-9))))

    def allowed(self, scale: float, h: float, dt_piece: float) -> float:
        """The energy a step may create or destroy beyond its scheme's intent [energy]:
        tolerance E_scale / 2 (a contact episode resolved in time errs at its onset and at its
        release, each O(h^2): about tolerance E_scale per episode)."""
        return 0.5 * self.tolerance * scale

    def judge(self, delta: float, conserving: bool, scale: float, h: float, dt_piece: float, eta: float = 0.0) -> str:
        """``accept``, ``reject`` (try h / 2), ``retry`` (the test hook: the same h again) or
        ``unresolved`` (above the allowance at dt_min: accepted and counted)."""
        if self.force_reject_once and not self._forced:
            self._forced = True
            return "retry"
        self._forced = False
        excess = max(abs(delta) if conserving else delta, eta)
        if excess <= self.allowed(scale, h, dt_piece):
            return "accept"
        if self.k >= self.k_max(dt_piece):
            return "unresolved"
        return "reject"

    def calm_needed(self) -> int:
        """The calm steps before the step grows: ``grow_after``, doubled for each growth rejected in a row (at most
        :data:`MAX_BACKOFF` times).  A step that is calm at h but above its allowance at 2h (an indicator of order
        above 2 in h inside a contact) was grown and rejected every ``grow_after`` levels: measured on the
        bouncing Hertz ball, 110 of its 142 rejections."""
        return self.grow_after * 2 ** min(self.backoff, MAX_BACKOFF)

    def calm_step(
        self, delta: float, conserving: bool, scale: float, h: float, dt_piece: float, eta: float = 0.0
    ) -> bool:
        """Whether the step was well inside its allowance (a quarter of it), energy and error alike."""
        excess = max(abs(delta) if conserving else delta, eta)
        return excess <= 0.25 * self.allowed(scale, h, dt_piece)

    def steady_force(self, before, after) -> bool:
        """Whether the contact forces are steady over the step (none, or a resting contact):
        |sum lambda^{n+1} - sum lambda^n| <= force_change max(|sum lambda^n|, |sum lambda^{n+1}|).
        The step grows only then: inside an impact the force follows the waves of the body and
        its history must stay resolved (the step that resolved the onset is kept to the release)."""
        a, b = float(np.sum(before)), float(np.sum(after))
        return abs(b - a) <= self.force_change * max(abs(a), abs(b))

    def resting(self, before: np.ndarray | None, after: np.ndarray) -> bool:
        """Whether the contact rests over the last two steps (levels n-1, n, n+1): the same rows act at the three
        levels and the contact force averaged over consecutive levels is steady,
        |<lambda>_{n+1/2} - <lambda>_{n-1/2}| <= force_change max(...) with <lambda>_{n+1/2} = sum (lambda^n +
        lambda^{n+1})/2.  A body at rest whose force alternates from level to level (Crank-Nicolson's undamped
        (-1)^n mode of the damping velocity on its massless contact dofs: 38% of the weight on a damped steel
        block) rests; an impact's force, which follows the body's waves, does not.  Called once per accepted
        level (it keeps the level before's sum and whether its rows persisted)."""
        if before is None or before.size != after.size or not after.size:
            self.prev_sum, self.persistent = None, False
            return False
        same = bool(np.array_equal(before != 0, after != 0) and np.any(after != 0))
        a, b = float(np.sum(before)), float(np.sum(after))
        ok = (
            same
            and self.persistent
            and self.prev_sum is not None
            and self.steady_force(np.array([0.5 * (self.prev_sum + a)]), np.array([0.5 * (a + b)]))
        )
        self.prev_sum, self.persistent = a, same
        return ok

    def note_accepted(
        self, t0: float, t1: float, h: float, dt_piece: float, verdict: str, n: int = 0, excess: float = 0.0
    ) -> None:
        """Count the level n (t0 -> t1, step h) just accepted, and the stretch of refined levels it extends."""
        self.accepted += 1
        self.smallest, self.largest = min(self.smallest, h), max(self.largest, h)
        if verdict == "unresolved":
            self.unresolved_excess.append([float(t1), float(excess)])
        if h < dt_piece * (1 - 1e-12):
            if self.refined and abs(self.refined[-1][1] - t0) <= 1e-12 * max(abs(t0), h):
                self.refined[-1][1] = t1
                self.refined[-1][2] = min(self.refined[-1][2], h)
                if self.refined_levels:
                    self.refined_levels[-1][1] = n
            else:
                self.refined.append([t0, t1, h])
                self.refined_levels.append([n, n])

    def summary(self, factorizations: int) -> dict[str, Any]:
        """``summary.json`` ``time_control`` of an adaptive run."""
        return {
            "control": "energy",
            "tolerance": self.tolerance,
            "tolerance_from_mesh": self.mesh_resolution is not None,
            "mesh_resolution": self.mesh_resolution,
            "dt_min": self.dt_min_used,
            "dt_smallest_used": None if self.accepted == 0 else self.smallest,
            "dt_largest_used": None if self.accepted == 0 else self.largest,
            "steps_accepted": self.accepted,
            "steps_rejected": self.rejected,
            "failed_trials": self.failed_trials,
            "unresolved_steps": self.unresolved,
            "event_refinements": self.event_refinements,
            "factorizations": factorizations,
            "refined": [[float(a), float(b), float(h)] for a, b, h in self.refined],
            "refined_levels": [[int(a), int(b)] for a, b in self.refined_levels],
        }

    def settle(self, scale: float) -> None:
        """The steps accepted at dt_min that exceed the allowance of the run's final energy scale
        (those judged against the small scale of a run's start may not)."""
        self.unresolved_excess = [r for r in self.unresolved_excess if r[1] > self.allowed(scale, 0.0, 1.0)]

    @property
    def unresolved(self) -> int:
        """The steps accepted at dt_min above their allowance (``unresolved_steps``)."""
        return len(self.unresolved_excess)

    @property
    def first_unresolved_t(self) -> float | None:
        return self.unresolved_excess[0][0] if self.unresolved_excess else None

    def unresolved_message(self) -> str:
        """The warning of a run whose steps at dt_min still exceeded their allowance."""
        at = "" if self.first_unresolved_t is None else f", the first at t = {self.first_unresolved_t:.6g}"
        return (
            f"the energy control accepted {self.unresolved} step(s) at its smallest step {self.smallest:.3g} s "
            f"above its tolerance{at}: the impact is not resolved there; give a smaller dt_min "
            "(or dt)"
        )

    def state(self) -> dict[str, Any]:
        """What a checkpoint keeps of the control (a resume continues on the same ladder)."""
        return {
            "k": self.k,
            "calm": self.calm,
            "accepted": self.accepted,
            "rejected": self.rejected,
            "failed_trials": self.failed_trials,
            "event_refinements": self.event_refinements,
            "smallest": self.smallest if math.isfinite(self.smallest) else -1.0,
            "largest": self.largest,
            "refined": [list(map(float, r)) for r in self.refined],
            "refined_levels": [list(map(int, r)) for r in self.refined_levels],
            "unresolved_excess": [list(map(float, r)) for r in self.unresolved_excess],
            "prev_sum": self.prev_sum,
            "persistent": self.persistent,
            "backoff": self.backoff,
            "just_grown": self.just_grown,
        }

    def restore(self, data: dict[str, Any], level: int | None = None, t: float | None = None) -> None:
        """Take back :meth:`state` (types checked: a checkpoint is data from outside), and, given the checkpoint's
        ``level`` and time ``t``, checked against them (at most ``level`` steps accepted, the refined spans and
        levels within the run so far, the smallest step at most the largest): a forged state is refused."""
        ints = ("k", "calm", "accepted", "rejected", "failed_trials", "event_refinements")
        for key in ints:
            v = data.get(key, 0 if key == "event_refinements" else None)
            if isinstance(v, bool) or not isinstance(v, int) or v < 0:
                raise InputError(f"checkpoint: time control {key!r} must be a non-negative integer, got {v!r}")
            setattr(self, key, v)
        for key in ("smallest", "largest"):
            v = data.get(key)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise InputError(f"checkpoint: time control {key!r} must be a finite number, got {v!r}")
        self.smallest = math.inf if data["smallest"] < 0 else float(data["smallest"])
        self.largest = float(data["largest"])
        self.refined = _rows(data, "refined", 3, float, "[t_start, t_end, dt]")
        self.refined_levels = _rows(data, "refined_levels", 2, int, "[first, last] levels")
        self.unresolved_excess = _rows(data, "unresolved_excess", 2, float, "[t, excess]")
        prev, persistent = data.get("prev_sum"), data.get("persistent", False)  # (a checkpoint of before: none)
        if prev is not None and (
            isinstance(prev, bool) or not isinstance(prev, (int, float)) or not math.isfinite(prev)
        ):
            raise InputError(f"checkpoint: time control 'prev_sum' must be a finite number or null, got {prev!r}")
        if not isinstance(persistent, bool):
            raise InputError(f"checkpoint: time control 'persistent' must be true or false, got {persistent!r}")
        self.prev_sum, self.persistent = (None if prev is None else float(prev)), persistent
        backoff, grown = data.get("backoff", 0), data.get("just_grown", False)  # (a checkpoint of before: none)
        if isinstance(backoff, bool) or not isinstance(backoff, int) or not 0 <= backoff <= MAX_BACKOFF:
            raise InputError(
                f"checkpoint: time control 'backoff' must be an integer in [0, {MAX_BACKOFF}], got {backoff!r}"
            )
        if not isinstance(grown, bool):
            raise InputError(f"checkpoint: time control 'just_grown' must be true or false, got {grown!r}")
        self.backoff, self.just_grown = backoff, grown
        if self.k > MAX_LEVELS:
            raise InputError(f"checkpoint: time control 'k' = {self.k} is beyond the ladder (at most {MAX_LEVELS})")
        if level is None or t is None:
            return
        span = 1e-9 * max(abs(t), 1e-300)
        if self.accepted > level:
            raise InputError(f"checkpoint: time control 'accepted' = {self.accepted} is more than its {level} levels")
        if any(not (0 <= a <= b <= level) for a, b in self.refined_levels):
            raise InputError(f"checkpoint: time control 'refined_levels' reach beyond its {level} levels")
        if any(not (-span <= a <= b <= t + span and 0 < dt) for a, b, dt in self.refined):
            raise InputError(f"checkpoint: time control 'refined' spans reach beyond its t = {t:.10g}")
        if math.isfinite(self.smallest) and not 0 < self.smallest <= self.largest:
            raise InputError("checkpoint: time control 'smallest' and 'largest' steps are not 0 < smallest <= largest")


def _rows(data: dict[str, Any], key: str, width: int, kind: type, what: str) -> list[list]:
    """``data[key]`` (default empty) as a list of rows of ``width`` finite numbers of ``kind``
    (int: integers only); an InputError naming the key otherwise (a checkpoint is data from outside)."""
    rows = data.get(key, [])

    def ok(x: Any) -> bool:
        if isinstance(x, bool) or not isinstance(x, (int, float) if kind is float else int):
            return False
        return math.isfinite(x)

    if not isinstance(rows, list) or any(
        not isinstance(r, list) or len(r) != width or not all(map(ok, r)) for r in rows
    ):
        raise InputError(f"checkpoint: time control {key!r} must be a list of {what}")
    return [[kind(x) for x in r] for r in rows]


class AdaptiveSteps:
    """The energy control driving a :class:`~.stepper.Stepper`: each level tried, judged,
    rejected and tried again at half the step (its rollback: the solvers' warm starts,
    :class:`~.restart.SolverStates`), and the step grown back after calm steps.

    Parameters
    ----------
    stepper : the run (its grid, energies, event watch, solvers and trial step).
    control : the :class:`EnergyControl` (its counters and ladder).
    """

    def __init__(self, stepper: ControlledStepper, control: EnergyControl) -> None:
        self.stepper, self.control = stepper, control
        #: the judgement of the level accepted last: (verdict, delta, scale, h, dt_piece, eta)
        self.verdict: tuple = ()
        #: T reached with a grown step: the segment a resume to a later T goes on with
        self.next_segment: list | None = None
        #: the contact force at the level before the step (a steady force lets the step grow)
        self.force_before: np.ndarray | None = None

    @classmethod
    def build(
        cls, stepper: ControlledStepper, scheme: Any, grid: Any, energy: bool, options: dict[str, Any], mesh: Any = None
    ) -> AdaptiveSteps:
        """The control of ``options`` (:func:`control_spec`) for ``scheme`` on ``grid``; an
        InputError for a scheme that refuses it, a run without energy, or a dt_min outside
        [dt / 2^MAX_LEVELS, dt].  A tolerance of 0 (the default) is made from ``mesh``
        (:func:`mesh_tolerance`; 1e-3 without a mesh)."""
        why = scheme.step_control_refusal() if hasattr(scheme, "step_control_refusal") else ""
        if why:
            raise InputError(f"control 'energy' cannot run scheme {scheme.label}: {why}; use control 'fixed'")
        if not energy:
            raise InputError("control 'energy' judges each step by the energy identity: it needs energy=True")
        options = dict(options)
        resolution = None
        if not options.get("tolerance"):
            options["tolerance"], resolution = mesh_tolerance(mesh)
        ctl = EnergyControl(**options, mesh_resolution=resolution, default_levels=default_levels(options["tolerance"]))
        smallest = min(piece[2] for piece in grid.plan)
        ctl.dt_min_used = ctl.dt_min or smallest / 2 ** ctl.k_max(smallest)
        if ctl.dt_min > smallest:
            raise InputError(
                f"control 'energy': dt_min = {ctl.dt_min:g} is above the step {smallest:g}; give dt_min <= dt"
            )
        if 0 < ctl.dt_min < smallest / 2**MAX_LEVELS:
            raise InputError(
                f"control 'energy': dt_min = {ctl.dt_min:g} is below dt / 2^{MAX_LEVELS} = "
                f"{smallest / 2**MAX_LEVELS:.4g} (the energy identity is lost to round-off at such "
                "steps); give a larger dt_min"
            )
        return cls(stepper, ctl)

    def step(self, n: int) -> tuple[Any, str]:
        """Level n under the control: (state, "") or (None, why it failed).  A step judged above
        its allowance, or failed, is rejected (the warm starts put back) and tried again at half
        the step, down to dt_min."""
        s, ctl = self.stepper, self.control
        grid, run = s.grid, s.run
        comm = run.ctx.comm
        while True:
            begin, _, dt_piece = grid.piece(s.t)
            h = grid.segment(n).dt
            s.use_segment(n)  # the systems of h first: theirs are the warm starts a rejection puts back
            marked = s.step_parts.mark()  # the parts a step changes (:mod:`~.restart.protocol`)
            new, why = s.trial(n)
            if comm.any(new is None):  # every rank takes the same decision
                new, why = None, why or f"step {n} failed on another rank"
            if new is None:
                verdict = "reject" if ctl.k < ctl.k_max(dt_piece) else "failed"
                if verdict == "failed":
                    s.step_parts.rollback(marked)
                    return None, why
                ctl.failed_trials += 1
            else:
                delta, scale, eta = s.energies.indicator(run, n, new)
                verdict = ctl.judge(delta, run.scheme.conserving, scale, h, dt_piece, eta)
                if comm.any(verdict == "reject"):
                    verdict = "reject"
            if (
                verdict == "accept"
                and s.watch is not None
                and ctl.k < ctl.k_max(dt_piece)
                and comm.any(s.watch.would_stop(new))
            ):  # a terminal event inside the step: located within dt_min
                verdict = "reject"
                ctl.event_refinements += 1
            if verdict == "unresolved" and s.energies.check == "fail":  # energy_check=fail: levels kept
                s.step_parts.rollback(marked)
                allowed = ctl.allowed(scale, h, dt_piece)
                return None, (
                    f"step {n} (t = {s.grid.time_of(n):.6g}): at the smallest step {h:.3g} s the step still "
                    f"creates or destroys {abs(delta):.3g} of energy (its error estimate: {eta:.3g}), above "
                    f"the allowance {allowed:.3g} (energy_check=fail); give a smaller dt_min"
                )
            if verdict in ("accept", "unresolved"):
                self.verdict = (verdict, delta, scale, h, dt_piece, eta)
                s.step_parts.release()
                return new, ""
            s.step_parts.rollback(marked)
            if verdict == "retry":  # the test hook: the same step again
                continue
            ctl.rejected += 1
            if ctl.just_grown:  # the grown step did not hold: wait longer before the next growth
                ctl.backoff = min(ctl.backoff + 1, MAX_BACKOFF)
                ctl.just_grown = False
            ctl.k += 1
            ctl.calm = 0
            try:
                grid.continue_with(s.n, s.t, dt_piece / 2**ctl.k)
            except InputError as exc:  # the control's own grid (a bug if it happens): the levels are kept
                return None, f"step {n}: the energy control could not halve its step: {exc}"

    def accepted(self, t0: float) -> None:
        """The control's count of the level just accepted; the step grows by 2 after
        ``grow_after`` calm steps when the level is on the grid of the doubled step."""
        s, ctl = self.stepper, self.control
        verdict, delta, scale, h, dt_piece, eta = self.verdict
        excess = max(abs(delta) if s.run.scheme.conserving else delta, eta)
        ctl.note_accepted(t0, s.t, h, dt_piece, verdict, s.n, excess)
        self._grow(delta, scale, h, dt_piece, eta)

    def _grow(self, delta: float, scale: float, h: float, dt_piece: float, eta: float) -> None:
        """The step of the next levels: the piece's own at a piece's start; twice h after
        ``grow_after`` calm steps with a steady contact force, on the grid of 2h."""
        s, ctl = self.stepper, self.control
        grid = s.grid
        at_T = s.n >= grid.n_steps
        resting = ctl.resting(self.force_before, s.state.lam)  # every accepted level: it keeps the level before's
        if ctl.just_grown:  # the grown step held
            ctl.backoff, ctl.just_grown = max(ctl.backoff - 1, 0), False
        if not np.any(s.state.lam):  # no contact force: a flight grows at the plain pace
            ctl.backoff = 0
        begin, end, dt_piece_next = grid.piece(s.t)
        if not at_T and (dt_piece_next != dt_piece or begin >= s.t - 1e-12 * max(abs(s.t), h)):  # a new piece
            ctl.k, ctl.calm = 0, 0  # its own dt
            return
        calm = ctl.calm_step(delta, s.run.scheme.conserving, scale, h, dt_piece, eta)
        steady = resting or ctl.steady_force(self.force_before, s.state.lam)
        ctl.calm = ctl.calm + 1 if calm and steady else 0
        if ctl.k == 0 or ctl.calm < ctl.calm_needed():
            return
        r = (s.t - begin) / (2.0 * h)
        # not on the grid of 2h yet: r's round-off is eps |r| (t and h exact to a few ulps), far below 1e-6; a
        # tolerance relative to r (1e-6 |r|, before) took half a step for a whole one beyond 5e5 steps of 2h
        # into the piece, and the next segment could not divide the rest of the piece (a steel block at rest,
        # 0.025 s at 2.5e-5 / 512: exit 2 midway, its levels lost)
        if abs(r - round(r)) > 1e-6 + 1e-12 * abs(r):
            return
        ctl.k -= 1
        ctl.calm = 0
        ctl.just_grown = True
        if at_T:  # T reached: the grown step is where a resume to a later T goes on (:meth:`grid_attrs`)
            self.next_segment = [float(s.t), dt_piece / 2**ctl.k, s.n]
            return
        try:
            grid.continue_with(s.n, s.t, dt_piece / 2**ctl.k)
        except InputError:  # the control's own grid cannot take the grown step here (a bug if it happens):
            ctl.k += 1  # keep the step, the run goes on

    def grid_attrs(self) -> dict[str, Any]:
        """The segment of the next level, the step factorized now and the control's state (a
        checkpoint's ``segment``, ``dt`` and ``time_control``)."""
        s = self.stepper
        n, grid = s.n, s.grid
        if n < grid.n_steps:  # a growth or rejection may have changed it
            seg = grid.segment(n + 1)
            segment = [seg.start, seg.dt, seg.first]
        else:  # at T: the segment a resume to a later T goes on with (grown at T, or the last one)
            seg = grid.segment(n)
            segment = self.next_segment or [seg.start, seg.dt, seg.first]
        state = {**self.control.state(), "plan_dt": grid.piece(s.t)[2]}  # the largest step (a resume's dt)
        return {"segment": segment, "dt": s.dt, "time_control": state}

    def summary(self, meta: dict[str, Any], scale: float, factorizations: int, failed: bool) -> None:
        """``summary.json`` ``time_control`` and the warning of unresolved steps."""
        ctl = self.control
        ctl.settle(scale)
        meta["time_control"] = ctl.summary(factorizations)
        if ctl.unresolved and not failed:
            meta["warnings"].append(ctl.unresolved_message())

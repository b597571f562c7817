"""The time levels of a run: one time step, or a schedule of steps that change.

A schedule is a list of segments ``[{until = 0.2, dt = 1e-3}, {until = 1.0, dt = 1e-2}]``
(or ``[(0.2, 1e-3), (1.0, 1e-2)]`` in Python): from the previous ``until`` (0 for the
first) to its own, the step is its ``dt``; each segment's length must be an integer
multiple of its dt (to a relative 1e-9, as T for one step).  T defaults to the last
``until``; a smaller T cuts the schedule (it must then fall on a level).  The level times
are computed from the segment's start and the level's index in it, so that no round-off
accumulates: t = start + j dt.

A resumed run continues on the grid from the checkpoint's level n at t_n
(:meth:`TimeGrid.build` with ``start_level`` and ``start_time``): the segments before
t_n are dropped and t_n must be a level of the segment it falls in (for a different
step, ``signorini resume --dt``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from ...errors import InputError, check_positive

#: relative tolerance of a segment's length against an integer number of steps
GRID_RTOL = 1e-9


@dataclass(frozen=True)
class Segment:
    """Levels ``first`` .. ``last`` at t = start + (n - first) dt (a resumed run's first
    segment may start before its first computed level: its times stay those of the
    uninterrupted run)."""

    start: float
    dt: float
    first: int
    last: int

    @property
    def end(self) -> float:
        return self.start + (self.last - self.first) * self.dt


def parse_schedule(dt: Any, where: str = "dt") -> list[tuple[float, float]]:
    """``[(until, dt), ...]`` of a schedule given as a list of {until, dt} tables or pairs;
    an InputError naming ``where`` for anything else."""
    if isinstance(dt, (list, tuple)):
        if not dt:
            raise InputError(f"'{where}' is an empty schedule; give a number or a list of {{until, dt}}")
        out = []
        for k, item in enumerate(dt):
            if isinstance(item, dict):
                extra = set(item) - {"until", "dt"}
                if extra or set(item) != {"until", "dt"}:
                    raise InputError(f"'{where}[{k}]' must have exactly the keys until and dt, got {sorted(item)}")
                until, step = item["until"], item["dt"]
            elif isinstance(item, (list, tuple)) and len(item) == 2:
                until, step = item
            else:
                raise InputError(f"'{where}[{k}]' must be {{until = T_k, dt = DT_k}}, got {item!r}")
            for name, v in (("until", until), ("dt", step)):
                if isinstance(v, bool) or not isinstance(v, (int, float)):
                    raise InputError(f"'{where}[{k}].{name}' must be a number, got {v!r}")
            out.append((check_positive(f"{where}[{k}].until", until), check_positive(f"{where}[{k}].dt", step)))
            from .setup import DT_RANGE

            if not DT_RANGE[0] <= out[-1][1] <= DT_RANGE[1]:  # as one dt: dt^2 a normal double
                raise InputError(
                    f"'{where}[{k}].dt' must be between {DT_RANGE[0]:g} and {DT_RANGE[1]:g} (dt^2 must be "
                    f"a normal double), got {out[-1][1]:g}"
                )
        for k in range(1, len(out)):
            if out[k][0] <= out[k - 1][0]:
                raise InputError(f"'{where}': the until values must increase, got {out[k - 1][0]:g} then {out[k][0]:g}")
        return out
    raise InputError(f"'{where}' must be a number or a schedule [{{until = ..., dt = ...}}, ...], got {dt!r}")


def _steps(length: float, dt: float, where: str) -> int:
    ratio = length / dt
    n = round(ratio)
    if n < 1 or abs(n * dt - length) > GRID_RTOL * max(length, dt):
        lo, hi = max(math.floor(ratio), 1), max(math.ceil(ratio), 1)
        raise InputError(
            f"{where}: a length of {length:.10g} is not an integer multiple of dt = {dt:g} (ratio "
            f"{ratio:.6g}); nearest valid dt: {length / hi:.10g} or {length / lo:.10g}"
        )
    return int(n)


class TimeGrid:
    """The levels of a run (module docstring): ``n_steps`` = the last level's index."""

    def __init__(self, segments: Sequence[Segment]):
        self.segments = list(segments)
        last = self.segments[-1]
        self.n_steps = last.last
        self.T = last.end
        #: the pieces (begin, end, dt) of the steps asked for: an adaptive control
        #: (:mod:`~.step_control`) takes dt / 2^k inside each, never across its end
        self.plan = [(s.start, s.end, s.dt) for s in self.segments]

    def piece(self, t: float) -> tuple[float, float, float]:
        """The (begin, end, dt) of :attr:`plan` whose steps follow time t (the next one when t
        is at its end)."""
        for begin, end, dt in self.plan:
            if t < end - GRID_RTOL * max(abs(end), dt):
                return begin, end, dt
        return self.plan[-1]

    def continue_with(self, n: int, t: float, dt: float, start: float | None = None, first: int | None = None) -> None:
        """From level n (at time t) on, the step ``dt`` up to the end of the plan's piece that
        follows t, then the plan's own steps (an adaptive control that refines or coarsens;
        ``start`` and ``first``: the new segment's origin when it continues one begun before
        level n, so that its levels' times are start + (m - first) dt, without round-off).

        ``dt`` must divide the piece's remaining length (a step dt_piece / 2^k on its dyadic grid)."""
        begin, end, _ = self.piece(t)
        start = t if start is None else float(start)
        first = n if first is None else int(first)
        kept = []
        for seg in self.segments:
            if seg.last <= n:
                kept.append(seg)
            elif seg.first < n:
                kept.append(Segment(seg.start, seg.dt, seg.first, n))
        m = _steps(end - start, dt, f"the steps of dt = {dt:g} from t = {start:.10g} to {end:.10g}")
        kept.append(Segment(start, float(dt), first, first + m))
        level = first + m
        for b, e, step in self.plan:
            if b >= end - GRID_RTOL * max(abs(end), step):
                k = _steps(e - b, step, f"the segment [{b:.10g}, {e:.10g}] of the time steps")
                kept.append(Segment(b, step, level, level + k))
                level += k
        self.segments = kept
        self.n_steps = kept[-1].last

    @property
    def variable(self) -> bool:
        """More than one step size."""
        return len({s.dt for s in self.segments}) > 1

    @classmethod
    def build(
        cls,
        dt: Any,
        T: float | None,
        start_level: int = 0,
        start_time: float = 0.0,
        segment: Sequence[float] | None = None,
    ) -> TimeGrid:
        """The grid of ``dt`` (a number or a schedule) up to ``T`` (None: the schedule's last
        until), from level ``start_level`` at ``start_time`` (a resumed run; ``segment``: the
        (start, dt, first) of the checkpoint's segment, continued as it is when ``dt`` is its
        step, so that the levels' times are those of the uninterrupted run)."""
        from .setup import number_of_steps

        if start_level and segment is not None and not isinstance(dt, (list, tuple)):
            start, step, first = float(segment[0]), float(segment[1]), int(segment[2])
            if check_positive("dt", dt) == step and start_level >= first:
                T = check_positive("T", T)
                n = _steps(T - start, step, f"the steps of dt = {step:g} from t = {start:.10g} to T = {T:.10g}")
                if first + n <= start_level:
                    raise InputError(f"T = {T:.10g} leaves no step after the checkpoint's t = {start_time:.10g}")
                return cls([Segment(start, step, first, first + n)])

        if not isinstance(dt, (list, tuple)):  # one step (number_of_steps names a wrong type)
            if T is None:
                raise InputError("T is needed with one time step")
            if start_level == 0:
                return cls([Segment(0.0, float(dt), 0, number_of_steps(dt, T))])
            T = check_positive("T", T)
            pieces = [(0.0, T, check_positive("dt", dt))]
        else:
            schedule = parse_schedule(dt)
            T = schedule[-1][0] if T is None else check_positive("T", T)
            if T > schedule[-1][0] * (1 + GRID_RTOL):
                raise InputError(
                    f"T = {T:g} is after the schedule's last until = {schedule[-1][0]:g}; extend the schedule"
                )
            pieces, begin = [], 0.0
            for until, step in schedule:
                end = min(until, T)
                if end > begin:
                    pieces.append((begin, end, step))
                begin = until
                if until >= T:
                    break
        segments, level = [], 0
        for begin, end, step in pieces:
            if start_level and end <= start_time * (1 + GRID_RTOL):
                continue  # before the resumed level
            if start_level and begin < start_time:  # the segment of the resumed level
                ratio = (start_time - begin) / step
                if abs(ratio - round(ratio)) > 1e-6:  # not one of its levels: a new grid from t_n
                    if len(pieces) > 1:
                        raise InputError(
                            f"the resumed time t = {start_time:.10g} is not a level of the segment "
                            f"[{begin:g}, {end:g}] of dt = {step:g}; resume with --dt to change the "
                            "step"
                        )
                    begin = start_time
                    first = start_level
                else:
                    first = start_level - round(ratio)
                n = _steps(end - begin, step, f"the segment [{begin:.10g}, {end:.10g}] of the time steps")
                segments.append(Segment(begin, step, first, first + n))
                level = first + n
                continue
            n = _steps(end - begin, step, f"the segment [{begin:.10g}, {end:.10g}] of the time steps")
            first = level if not start_level or segments else start_level
            segments.append(Segment(begin, step, first, first + n))
            level = first + n
        if not segments:
            raise InputError(f"T = {T:g} leaves no step after t = {start_time:g}")
        return cls(segments)

    def segment(self, n: int) -> Segment:
        """The segment of the step that ends at level n (n >= first level + 1)."""
        for s in self.segments:
            if n <= s.last:
                return s
        return self.segments[-1]

    def time_of(self, n: int) -> float:
        """The time of level n [s]."""
        seg = self.segment(n)
        return seg.start + (n - seg.first) * seg.dt

    def schedule(self) -> list[dict[str, float]]:
        """[{until, dt}] of the grid (summary.json ``dt_schedule``)."""
        return [{"until": s.end, "dt": s.dt} for s in self.segments]

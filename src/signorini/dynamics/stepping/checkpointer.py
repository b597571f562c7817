"""A run's checkpoints: the walk over its restartable parts (:mod:`~.restart`), written by a
policy (every K levels, at the end, the watchdog told) and read back by a resume.

:class:`Checkpointer` is the stepper's observer of checkpoints: the stepper tells it before
each step (``before_step``: what a checkpoint of the current level holds is taken before the
step works, so that a step that fails or is interrupted midway leaves the level before it),
after each accepted level (``accepted``, then ``level_done``: the periodic checkpoint) and at the end
(``at_exit``: the last level computed); ``restore`` puts a checkpoint's parts back in a run
just set up.  The file itself is :mod:`~.checkpoint`'s.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ...errors import InputError
from ..restart import checkpoint as ckpt
from ..restart.protocol import ObserverPart, StatePart
from .run_options import CheckpointPolicy

if TYPE_CHECKING:
    from .seams import CheckpointedStepper


class Checkpointer:
    """The checkpoints of one run (module docstring).

    Parameters
    ----------
    stepper : the run.
    policy : when and where to write (None: only :meth:`save` with a path).
    case_hash : the case file's hash (part of the identity a resume compares).
    """

    def __init__(
        self, stepper: CheckpointedStepper, policy: CheckpointPolicy | None, case_hash: str | None = None
    ) -> None:
        run = stepper.run
        self.stepper, self.policy = stepper, policy
        self.solvers = stepper.solvers
        self.pairing = stepper.pairing
        self.series = ckpt.SeriesLog()  # the levels' series written beside the checkpoint
        self.meta = dict(policy.meta) if policy is not None else {}
        self.log = ckpt.CheckpointLog(policy.every, policy.path) if policy is not None else None
        self.identity = ckpt.identity(run, case_hash)
        #: what a checkpoint of the current level holds of the grid and the counters, taken before the next step
        #: works (the solvers' part takes its own: :meth:`~.restart.protocol.SolverStates.take`)
        self._level: dict[str, Any] | None = None

    # -- the stepper's calls ---------------------------------------------------------
    def before_step(self) -> None:
        """The solvers' warm starts, the grid's attributes and the counters at the current
        level, if not taken yet (a rejected step tries again from the same level)."""
        if self.log is not None and self._level is None:
            self.solvers.take()
            self._level = {"grid": self.grid_attrs(), "counters": self.stepper.counters}

    def accepted(self) -> None:
        """A new level: what a checkpoint holds is taken again before the next step."""
        self._level = None
        self.solvers.drop()

    def level_done(self) -> None:
        """The periodic checkpoint, when the level is due (not the last: :meth:`at_exit` writes it)."""
        s = self.stepper
        if self.log is not None and self.log.every and s.n % self.log.every == 0 and s.n < s.n_steps:
            self._write_or_note()

    def at_exit(self) -> None:
        """The last level computed, whatever the status (a finished run can be continued to a
        later T; level 0 too: a run interrupted before its first step is resumable)."""
        if self.log is not None and self.log.level != self.stepper.n:
            self._write_or_note(InputError)

    def _write_or_note(self, *also: type[BaseException]) -> None:
        """A checkpoint that cannot be written (a full disk, a file-size limit) is said in the
        summary and the run goes on (the previous one is intact)."""
        try:
            self.save()
        except (OSError, RuntimeError, ValueError, *also) as exc:
            self.log.error = f"level {self.stepper.n}: {type(exc).__name__}: {exc}"
            self.log.failed += 1

    def grid_attrs(self) -> dict[str, Any]:
        """Where the grid goes on from the current level: the segment of the next level and the
        step of the operators factorized now (a checkpoint's ``segment`` and ``dt``), and an
        adaptive control's state (``time_control``): taken before a step works, so that a
        checkpoint of a step interrupted midway resumes as from the start of the step."""
        s = self.stepper
        if s.adaptive is not None:
            return s.adaptive.grid_attrs()
        n = s.n
        seg = s.grid.segment(max(n, s.grid.segments[0].first + 1))
        segment = [seg.start, seg.dt, seg.first] if seg.dt == s.dt else [float(s.state.t), s.dt, n]
        return {"segment": segment, "dt": s.dt}

    # -- the walk --------------------------------------------------------------------
    def parts(self, level: int, t: float) -> list[Any]:
        """The run's restartable parts at a level (:mod:`~.restart.protocol`), in the order a resume puts them
        back: the state, the solvers, the contact rows (at the state's time), the observers (given the state)."""
        s = self.stepper
        return [StatePart(s, t), self.solvers, self.pairing, *(ObserverPart(s, o, level) for o in s.observers)]

    def contents(self) -> dict[str, Any]:
        """Every part at the current level, each flattened under its key, and the header: the level, its time,
        the identity, the counters, where the grid goes on (:mod:`~.restart`)."""
        s = self.stepper
        run, n = s.run, s.n
        arrays: dict[str, np.ndarray] = {}
        attrs: dict[str, Any] = {}
        series: dict[str, np.ndarray] = {}
        for part in self.parts(n, float(s.state.t)):
            if part.key is None:
                continue
            data = dict(part.saved())
            series.update({f"{part.series_key}/{k}": v for k, v in data.pop("series", {}).items()})
            ckpt.flatten(part.key, data, arrays, attrs)
        level = self._level or {}
        attrs.update(level.get("grid") or self.grid_attrs())
        attrs.update(
            level=n,
            t=float(s.state.t),
            identity=self.identity,
            counters=level.get("counters") or s.counters,
            meta=self.meta,
            scheme=run.scheme.name,
            created=time.strftime("%Y-%m-%dT%H:%M:%S"),
        )
        return {"arrays": arrays, "attrs": attrs, "series": series}

    def save(self, path: str | Path | None = None) -> Path | None:
        """Write the checkpoint of the current level (to ``path``, else the policy's; only rank 0
        writes on several ranks).  Returns the path written."""
        target = path if path is not None else (self.policy.path if self.policy is not None else None)
        if target is None:
            raise InputError("save_checkpoint needs a path (the stepper was built without a checkpoint policy)")
        contents = self.contents()
        s = self.stepper
        if s.run.ctx.comm.rank != 0:
            return None
        target = Path(target() if callable(target) else target)

        def write() -> int:  # the levels' series appended beside it, then the checkpoint that counts them
            layout, records, digest = self.series.append(ckpt.series_path(target), contents.pop("series"), s.n)
            contents["attrs"]["series"] = {"layout": layout, "records": records, "digest": digest}
            return ckpt.write(target, contents)

        if self.log is not None and path is None:
            self.log.timed(write)
            self.log.level = s.n
            if self.policy.on_checkpoint is not None:
                a = contents["attrs"]
                self.policy.on_checkpoint(
                    {
                        "level": a["level"],
                        "t": a["t"],
                        "counters": a["counters"],
                        "scheme": s.run.scheme.label,
                        "mass": s.run.ctx.disc.mass_name,
                    }
                )
        else:
            write()
        return target

    def restore(self, saved: dict[str, Any], where: str) -> dict[str, Any]:
        """The parts of checkpoint ``saved`` (read from ``where``) put back in the run; returns
        where the run resumes (level, t, the counters before, the observers' series)."""
        try:
            return self._restore(saved, where)
        except InputError:
            raise
        except (TypeError, ValueError, KeyError, IndexError, AttributeError) as exc:  # a forged file, in one line
            raise InputError(f"checkpoint {where!r}: malformed ({type(exc).__name__}: {exc})") from None

    def _restore(self, saved: dict[str, Any], where: str) -> dict[str, Any]:
        s = self.stepper
        saved = ckpt.upgrade(saved)
        attrs, run = saved["attrs"], s.run
        ckpt.compare_identity(attrs["identity"], self.identity, f"checkpoint {where!r}")
        n, t = int(attrs["level"]), float(attrs["t"])
        info = attrs.get("series", {})
        series = ckpt.read_series(
            Path(where),
            info.get("layout", []),
            info.get("records", -1),
            info.get("digest", ""),
            f"checkpoint {where!r}",
        )
        if any(len(v) != n + 1 for v in series.values()):
            raise InputError(f"checkpoint {where!r}: its series hold {info.get('records')} levels, not {n + 1}")
        times = series.get("history/times")
        run.level_times = None if times is None else np.asarray(times)
        if s.adaptive is not None and "time_control" in attrs:
            s.adaptive.control.restore(dict(attrs["time_control"]), n, t)
        self.solvers.where = where
        for part in self.parts(n, t):  # each with its data; an observer without a key with none
            data = ckpt.unflatten(part.key, saved) if part.key else {}
            if getattr(part, "series_key", None):
                key = part.series_key
                data["series"] = {k[len(key) + 1 :]: v for k, v in series.items() if k.startswith(f"{key}/")}
            part.resume(data)
        return {
            "level": n,
            "t": t,
            "counters": {k: int(v) for k, v in attrs["counters"].items() if k != "steps"},
            "created": attrs.get("created", ""),
        }

    def summary(self, meta: dict[str, Any]) -> None:
        """``summary.json`` ``checkpoints`` and the warning of checkpoints not written."""
        if self.log is None:
            return
        meta["checkpoints"] = self.log.summary()
        if self.log.error:
            last = f"the last written is of level {self.log.level}" if self.log.level >= 0 else "none was written"
            meta["warnings"].append(
                f"{self.log.failed} checkpoint(s) could not be written (the last: {self.log.error}); {last}"
            )

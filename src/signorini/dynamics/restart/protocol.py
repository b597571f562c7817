"""Restart and rollback, one protocol: what a step changes, saved and put back.

Every object whose state a step changes is a *restartable part*: it has a ``key`` (its name
in a checkpoint), ``saved() -> dict`` (arrays, numbers, strings: a copy of its state now) and
``resume(data)`` (that state put back).  A checkpoint (:class:`~.checkpointer.Checkpointer`)
is the walk over the parts, each flattened under its key in the file; the in-memory rollback
of a rejected step (:class:`~.step_control.AdaptiveSteps`) is the walk over the parts that a
step changes before it is accepted (:class:`StepParts`).

The parts of a run:

=================  ==================================================================  =========
key                what                                                                rollback
=================  ==================================================================  =========
``state``          the scheme's state at the level (U, V, A, lambda, declared extras)  no [1]
                   (:class:`StatePart`)
``solvers``        each factorized system's warm starts and Delassus columns; a        yes [3]
                   Newton tangent kept across levels with its matrix (factorized
                   again on resume), where it was made, and which one is kept
``pairing``        the contact rows: the pairs' pairing, the current configuration's   yes
                   normals and master points (the same ``saved``/``resume`` calls)
``observers/KEY``  each observer's series (``Observer.saved`` / ``resume``,             no [1]
                   :class:`ObserverPart`)
(header)           the level, its time, the identity, the counters; the time grid's    yes [2]
                   segment and step and an adaptive control's state (read by the
                   set-up, before the parts exist)
=================  ==================================================================  =========

[1] changed only when a level is accepted (a rejected step never reaches them).
[2] the control puts its grid back itself (:meth:`~.time_grid.TimeGrid.continue_with`).
[3] in memory, not through a file: ``SolverStates.mark``/``rollback`` (the warm starts copied; the Delassus
columns copied once if the step moves their rows, as the current configuration's Newton iterates do: their
columns are updated incrementally, and moving the rows back would not give back the same round-off; a
checkpoint's ``resume`` solves the logged columns again, which a rollback need not pay for).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol

import numpy as np
import scipy.sparse as sp

from ...errors import InputError
from ..model.operator import Operator, Tangent, Viscous
from ..solve.context import Context
from . import checkpoint as ckpt


class Restartable(Protocol):
    """A part of a run's state (module docstring)."""

    key: str

    def saved(self) -> dict[str, Any]:
        """A copy of the part's state now."""

    def resume(self, data: dict[str, Any]) -> None:
        """The state of :meth:`saved` put back."""


class SolverStates:
    """The factorized systems' restartable data: each contact solver's warm starts (a few
    vectors) and the log of its Delassus columns (solved again alike on resume, so that every
    product summing over them is bit for bit the uninterrupted run's).

    Parameters
    ----------
    ctx : the run's :class:`~.context.Context` (its factor cache ``ctx.factors``).
    kept_steps : an adaptive control keeps the systems of the steps it left (all saved, least
        recently used first); else only the current step's are.
    ladder_bytes : the factor bytes an adaptive control keeps for those steps.
    """

    key = "solvers"

    def __init__(self, ctx: Context, kept_steps: bool, ladder_bytes: float) -> None:
        self.ctx, self.kept_steps, self.ladder_bytes = ctx, kept_steps, ladder_bytes
        #: where the data comes from (the messages of :meth:`resume`)
        self.where = "checkpoint"
        #: the level's snapshot taken before a step works (:meth:`take`), what :meth:`saved` gives until dropped
        self.taken: list[tuple] | None = None

    # -- a checkpoint --------------------------------------------------------------------
    def snapshot(self) -> list[tuple]:
        """The warm starts (copies) and the lengths of the Delassus logs now, per factorized
        operator (a rank's are its own rows): what a checkpoint of this level holds of them."""
        ctx = self.ctx
        systems = []
        if ctx.comm.size == 1:
            systems = ctx.factors.by_step() if self.kept_steps else [(ctx.dt, s) for s in ctx.factors.current]
            systems += [(ctx.dt, s) for s in ctx.factors.kept]  # a Newton tangent kept across levels: last
        out = []
        for dt, sys in systems:  # each factorized operator's solver, in order of creation
            warm = _warm_copy(sys)
            if sys.op.tangent is not None:  # the kept tangent's use (its policy's record)
                warm["tangent/use"] = np.array(ctx.factors.kept_use)
            delassus = getattr(sys.solver, "delassus", None)
            blocks = len(delassus.log) if hasattr(delassus, "log") else None
            out.append((sys, warm, blocks, dt))
        return out

    @staticmethod
    def arrays(snapshot: list[tuple]) -> dict[str, np.ndarray]:
        """``k/operator``, ``k/dt``, ``k/<warm start>`` and ``k/delassus/...`` of a :meth:`snapshot`."""
        out: dict[str, np.ndarray] = {}
        for k, (sys, arrays, blocks, dt) in enumerate(snapshot):
            out[f"{k}/operator"] = np.array(sys.op.coefficients())
            out[f"{k}/dt"] = np.array(dt)
            if sys.op.tangent is not None:  # a kept tangent: its matrix, factorized again on resume
                G = sp.csr_matrix(sys.op.tangent.matrix)
                out.update({f"{k}/tangent/{name}": getattr(G, name) for name in ("data", "indices", "indptr")})
                out[f"{k}/tangent/shape"] = np.array(G.shape)
                if sys.op.tangent.at is not None:  # where it was made: it turns with its bodies from there
                    out[f"{k}/tangent/at"] = np.asarray(sys.op.tangent.at)
            out.update({f"{k}/{name}": a for name, a in arrays.items()})
            log = sys.solver.delassus.history(blocks) if blocks is not None else None
            if log is not None:  # the Delassus columns solved, to solve them again alike on resume
                out.update({f"{k}/delassus/{name}": a for name, a in log.items()})
        return out

    def take(self) -> None:
        """What a checkpoint of the current level holds of the solvers, taken before a step changes their warm
        starts (a step interrupted or failed midway leaves the level before it); kept until :meth:`drop`."""
        if self.taken is None:
            self.taken = self.snapshot()

    def drop(self) -> None:
        """A new level: the next :meth:`take` takes again."""
        self.taken = None

    def saved(self) -> dict[str, Any]:
        arrays = self.arrays(self.taken if self.taken is not None else self.snapshot())
        return {**arrays, "count": self.count(arrays)}

    @staticmethod
    def count(arrays: dict[str, Any]) -> int:
        """The number of systems in :meth:`arrays`."""
        return sum(1 for name in arrays if name.endswith("/operator") and name.count("/") == 1)

    def resume(self, data: dict[str, Any]) -> None:
        """Each saved operator factorized (with its step under an adaptive control), its warm
        starts set, its Delassus columns solved again; the current step's systems last."""
        ctx, where = self.ctx, self.where
        count = int(data.get("count", 0))  # the systems saved (a checkpoint's ``solvers/count``)
        current, restored = ctx.dt, {}
        for k in range(count if ctx.comm.size == 1 else 0):
            op = data.get(f"{k}/operator")
            if op is None or op.shape not in ((2,), (3,)) or not np.all(np.isfinite(op)):
                raise InputError(f"checkpoint {where!r}: solver {k} has no valid operator")
            step = data.get(f"{k}/dt")
            tangent = self._tangent(data, k) if f"{k}/tangent/indptr" in data else None
            # a step an adaptive control kept: its own systems (a kept tangent serves any step)
            if self.kept_steps and step is not None and tangent is None:
                if step.shape != () or not np.isfinite(step) or not step > 0:
                    raise InputError(f"checkpoint {where!r}: solver {k} has no valid step")
                ctx.use_step(float(step), ctx.t0, [], self.ladder_bytes)
            viscous = None
            if op.shape == (3,):  # damping per region: c C, the third term
                if ctx.damping_matrix is None:
                    raise InputError(f"checkpoint {where!r}: solver {k} holds a damping matrix this run does not have")
                viscous = Viscous(float(op[2]), ctx.damping_matrix)
            # made now if the loop made it
            operator = Operator(float(op[0]), float(op[1]), tangent, viscous)
            sys, _ = ctx.factors.system(operator)
            if tangent is not None:
                use = data.get(f"{k}/tangent/use")
                if use is None or use.shape != (2,) or use.dtype.kind not in "iu" or np.any((use < 0) | (use > 2**53)):
                    raise InputError(f"checkpoint {where!r}: solver {k} has no valid kept tangent (its use)")
                ctx.factors.keep(operator, (int(use[0]), int(use[1])))
            for name in _warm_names(sys):
                a = data.get(f"{k}/{name}")
                old = np.asarray(getattr(sys.solver, name))
                if a is None or a.shape != old.shape:
                    raise InputError(
                        f"checkpoint {where!r}: the warm start {name!r} of solver {k} is missing or "
                        f"has another shape (another backend?)"
                    )
                setattr(sys.solver, name, a.astype(old.dtype, copy=True))
                restored.setdefault(id(sys), {})[name] = getattr(sys.solver, name).copy()
            prefix = f"{k}/delassus/"
            log = {name[len(prefix) :]: a for name, a in data.items() if name.startswith(prefix)}
            delassus = getattr(sys.solver, "delassus", None)
            if all(name in log for name in ("nodes", "slots", "sizes")) and hasattr(delassus, "replay"):
                try:
                    delassus.replay(log)
                except ValueError as exc:
                    raise InputError(f"checkpoint {where!r}: solver {k}: {exc}") from None
        if self.kept_steps:
            ctx.use_step(current, ctx.t0, [], self.ladder_bytes)  # back to the checkpoint's step
            for sys in ctx.factors.current:  # its warm starts, not those use_step passed from the last restored
                for name, a in restored.get(id(sys), {}).items():
                    setattr(sys.solver, name, a.copy())

    def _tangent(self, data: dict[str, Any], k: int) -> Tangent:
        """The kept tangent of solver ``k`` (a CSR matrix n x n, n the run's dofs), checked."""
        parts = [data.get(f"{k}/tangent/{name}") for name in ("data", "indices", "indptr", "shape")]
        n = self.ctx.M.shape[0]
        bad = f"checkpoint {self.where!r}: solver {k} has no valid kept tangent"
        if any(a is None for a in parts) or parts[3].shape != (2,) or tuple(parts[3]) != (n, n):
            raise InputError(f"{bad} (a CSR matrix of {n} x {n})")
        values, indices, indptr = parts[0], parts[1], parts[2]
        if (
            values.dtype not in (np.float32, np.float64)
            or indices.dtype.kind not in "iu"
            or indptr.dtype.kind not in "iu"
        ):
            raise InputError(f"{bad} (float values, integer indices)")
        values = values.astype(np.float64, copy=False)
        if not np.all(np.isfinite(values)):
            raise InputError(f"{bad} (non-finite values)")
        try:
            G = sp.csr_matrix((values, indices, indptr), shape=(n, n))
            G.check_format(full_check=True)
        except ValueError as exc:
            raise InputError(f"{bad}: {exc}") from None
        at = data.get(f"{k}/tangent/at")  # absent in a checkpoint written before it was recorded: not turned
        if at is not None and (at.shape != (n,) or at.dtype != np.float64 or not np.all(np.isfinite(at))):
            raise InputError(f"{bad} (the displacement it was made at: {n} finite floats)")
        return Tangent(G, None if at is None else np.array(at))

    # -- a rollback ----------------------------------------------------------------------
    def mark(self) -> list[tuple[Any, dict[str, np.ndarray]]]:
        """What a rejected step must put back: the warm starts of the current step's solvers and of the kept
        tangent's, which tangent is kept (:meth:`~.factorizations.Factorizations.mark_kept`), and every system's
        Delassus columns as they are now (:class:`~signorini.contact.delassus.ColumnsUndo`: copied only if the
        step moves their rows; the columns a step only adds stay valid for its operator)."""
        factors = self.ctx.factors
        factors.mark_kept()
        for sys in factors.every():
            _delassus_call(sys, "mark")
        return [(sys, _warm_copy(sys)) for sys in factors.current + factors.kept]

    def rollback(self, mark: list[tuple[Any, dict[str, np.ndarray]]]) -> None:
        """The solvers as at :meth:`mark`: the kept tangent, the Delassus columns, then the warm starts."""
        self.ctx.factors.rollback_kept()
        for sys in self.ctx.factors.every():
            _delassus_call(sys, "rollback")
        for sys, arrays in mark:
            for name, a in arrays.items():
                setattr(sys.solver, name, a.copy())

    def release(self) -> None:
        """The step was accepted: the marks of :meth:`mark` dropped (nothing is copied after it), the kept
        tangent it replaced retired."""
        self.ctx.factors.release_kept()
        for sys in self.ctx.factors.every():
            _delassus_call(sys, "release")


def _delassus_call(sys: Any, name: str) -> None:
    """``name`` (mark, rollback, release) on a system's Delassus columns, if its solver has them."""
    undo = getattr(getattr(sys.solver, "delassus", None), "undo", None)
    if undo is not None:
        getattr(undo, name)()


def _warm_names(sys: Any) -> tuple[str, ...]:
    return tuple(getattr(sys.solver, "warm_state", ()))


def _warm_copy(sys: Any) -> dict[str, np.ndarray]:
    """Copies of a system's solver's warm starts, by name."""
    return {name: np.array(getattr(sys.solver, name), copy=True) for name in _warm_names(sys)}


class Pairing:
    """The contact rows at the current level (:meth:`~.context.Context.pairing_state`): the pairs' pairing after
    small sliding, the current configuration's normals and master points.

    Parameters
    ----------
    ctx : the run's :class:`~.context.Context`.
    level_time : the current level's time [s] (the stepper's).
    """

    key = "pairing"

    def __init__(self, ctx: Context, level_time: Callable[[], float]) -> None:
        self.ctx, self.level_time = ctx, level_time

    def saved(self) -> dict[str, Any]:
        return self.ctx.rows.pairing_state(self.level_time())

    def resume(self, data: dict[str, Any]) -> None:
        self.ctx.restore_pairing(data, self.level_time())


class StepParts:
    """The parts a step changes before it is accepted (the solvers and the rows' pairing), for the in-memory
    rollback of a rejected step: :meth:`mark` before a trial, :meth:`rollback` after a rejected one,
    :meth:`release` after an accepted one.  The rows are put back by their checkpoint's own calls
    (``Pairing.saved``/``resume``), after the solvers (whose Delassus columns then hold the level's rows).

    Parameters
    ----------
    solvers, pairing : the run's :class:`SolverStates` and :class:`Pairing`.
    """

    def __init__(self, solvers: SolverStates, pairing: Pairing) -> None:
        self.solvers, self.pairing = solvers, pairing

    def mark(self) -> tuple[Any, dict[str, Any]]:
        """What a rollback to the current level puts back."""
        return self.solvers.mark(), self.pairing.saved()

    def rollback(self, marked: tuple[Any, dict[str, Any]]) -> None:
        """The parts as at :meth:`mark`."""
        self.solvers.rollback(marked[0])
        self.pairing.resume(marked[1])

    def release(self) -> None:
        """The step was accepted."""
        self.solvers.release()


class StatePart:
    """The scheme's state at the level (U, V, A, lambda, lambda_t, the scheme's declared data and flags).

    Parameters
    ----------
    stepper : the run (its ``state``, set by :meth:`resume`).
    t : the level's time [s] (a checkpoint's header).
    """

    key = "state"

    def __init__(self, stepper: Any, t: float) -> None:
        self.stepper, self.t = stepper, t

    def saved(self) -> dict[str, Any]:
        s = self.stepper
        arrays, flags = ckpt.state_arrays(s.run, s.state)
        return {**arrays, "flags": flags}

    def resume(self, data: dict[str, Any]) -> None:
        data = dict(data)
        flags = data.pop("flags", {})
        if not isinstance(flags, dict):
            raise InputError("checkpoint: the state's flags are not a mapping")
        self.stepper.state = ckpt.restore_state(self.stepper.run, data, flags, self.t)


class ObserverPart:
    """An observer's data up to the level (``Observer.saved(n)``/``resume(run, n, state, data)``, the public
    calls users' observers implement); its ``series`` go to the checkpoint's series file under ``series_key``.
    An observer without a ``checkpoint_key`` writes nothing and resumes with no data (e.g. one that copies files).

    Parameters
    ----------
    stepper : the run.
    observer : the observer.
    level : the level saved or resumed.
    """

    def __init__(self, stepper: Any, observer: Any, level: int) -> None:
        self.stepper, self.observer, self.level = stepper, observer, level
        self.series_key: str | None = getattr(observer, "checkpoint_key", None)
        self.key = f"observers/{self.series_key}" if self.series_key else None

    def saved(self) -> dict[str, Any]:
        return dict(self.observer.saved(self.level)) if self.key else {}

    def resume(self, data: dict[str, Any]) -> None:
        if hasattr(self.observer, "resume"):
            s = self.stepper
            self.observer.resume(s.run, self.level, s.state, data)

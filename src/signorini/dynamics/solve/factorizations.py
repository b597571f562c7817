"""The factorized step operators of a run, per step size: the only owner of the factor cache.

A scheme solves with an operator K = c_M M + c_S S (:class:`~signorini.dynamics.solve.context.Operator`)
for the current step dt.  :class:`Factorizations` keeps, for that dt, the systems made so far
(a factorized K on the free dofs with its contact solver, ``_System``) and finds the one that
serves an operator: itself, or a multiple of it (``K' = s K`` is solved as ``K x = rhs / s``).
When the step changes it either releases the old step's systems (a schedule, a resume with
another dt: :meth:`replace`) or keeps them on a ladder (an adaptive control's steps dt / 2^k:
:meth:`use`), the least recently used dropped first beyond a memory budget.  The counters of
released systems are kept (:meth:`counters`).

A Newton tangent may be *kept* across levels (:meth:`keep`): its system leaves the step's list and stays found
by :meth:`system` whatever the step (its operator's coefficients name the step it serves), until another
tangent is kept in its place or it is dropped (:meth:`drop_kept`).  The one it replaces is retired at once, or,
while a step is on trial (:meth:`mark_kept`), when the step is accepted (:meth:`release_kept`) or put back by
its rollback (:meth:`rollback_kept`).

The :class:`~signorini.dynamics.solve.context.Context` of a run holds one, as ``ctx.factors``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from ...errors import InputError

if TYPE_CHECKING:
    from ...contact.solver import ContactSolver
    from ..model.operator import Operator


class Factorizations:
    """The systems (factorized operators with their contact solvers) of the current step, and
    those an adaptive control kept for other steps.

    Parameters
    ----------
    build : makes the system of an operator (its factorization and contact solver).
    dt : the step the first systems are made for [time].
    """

    def __init__(self, build: Callable[[Operator], Any], dt: float):
        self._build = build
        self.dt = float(dt)
        #: the systems of the current step, in order of creation
        self.current: list[Any] = []
        self._lookup: dict[Operator, tuple[Any, float]] = {}
        #: the systems of the steps used before (:meth:`use`), least recently used first
        self._ladder: dict[float, tuple[list[Any], dict]] = {}
        #: the counters of the systems released (:meth:`replace`, :meth:`use`)
        self.retired: dict[str, int] = {}
        #: the contact solver of the first system made for the latest step (its backend and condensation, for
        #: the run's summary when a new step's factorization failed and left no system: the run then fails)
        self.main: ContactSolver | None = None
        #: the systems kept across levels (:meth:`keep`: at most one, a Newton tangent)
        self.kept: list[Any] = []
        #: (steps, Newton iterations) the kept tangent served, the step that made it included (its owner's policy)
        self.kept_use: tuple[int, int] = (0, 0)
        #: the kept systems and their use when a step's trial began (:meth:`mark_kept`), None when none is on trial
        self._marked: tuple[list[Any], tuple[int, int]] | None = None

    def system(self, op: Operator) -> tuple[Any, float]:
        """(system, s) with ``op = s * system.op``: a system of the current step that serves ``op``,
        made (factorized) now when none does."""
        found = self._lookup.get(op)
        if found is None:
            for sys in self.kept:
                if sys.op == op:
                    return sys, 1.0
            found = self._lookup[op] = self._find_or_build(op)
        return found

    def _find_or_build(self, op: Operator) -> tuple[Any, float]:
        if op.mass < 0 or op.stiffness < 0 or (op.mass == 0 and op.stiffness == 0):
            raise InputError(f"a scheme operator needs non-negative coefficients, not both zero; got {op}")
        for sys in self.current:
            s = op.ratio_to(sys.op)
            if s is not None:
                return sys, s
        sys = self._build(op)
        self.current.append(sys)
        if len(self.current) == 1:
            self.main = sys.solver
        return sys, 1.0

    def _retire(self, systems: list[Any]) -> None:
        retired = dict(self.retired)
        for sys in systems:
            for k, v in sys.solver.counters.items():
                retired[k] = retired.get(k, 0) + int(v)
            release = getattr(sys.solver, "release", None)  # a solver's factor resources (ContactSolver.release)
            if release is not None:
                release()
        self.retired = retired

    def release(self, op: Operator) -> None:
        """Drop the system made for ``op`` (a Newton iterate's tangent, no longer of use), its
        counters kept; nothing when there is none."""
        found = self._lookup.pop(op, None)
        if found is None:
            return
        sys = found[0]
        if any(o is sys for o, _ in self._lookup.values()):
            return
        self.current = [s for s in self.current if s is not sys]
        self._retire([sys])

    def keep(self, op: Operator, use: tuple[int, int] = (0, 0)) -> None:
        """Keep the system of ``op`` (made by :meth:`system` for the current step) across levels, in place of the
        one kept before (retired now, or when the step on trial is accepted); ``use``: its :attr:`kept_use`."""
        sys, _ = self._lookup.pop(op)
        self.current = [s for s in self.current if s is not sys]
        self.drop_kept()
        self.kept, self.kept_use = [sys], (int(use[0]), int(use[1]))

    def drop_kept(self) -> None:
        """No system kept (the kept tangent serves no longer): it is retired, now or (on trial) when the step is
        accepted."""
        marked = [] if self._marked is None else self._marked[0]
        self._retire([s for s in self.kept if not any(s is m for m in marked)])
        self.kept, self.kept_use = [], (0, 0)

    def kept_for(self, op: Operator) -> Operator | None:
        """The kept tangent's operator when its coefficients (and damping term) are those of ``op``, else None."""
        for sys in self.kept:
            if sys.op.mass == op.mass and sys.op.stiffness == op.stiffness and sys.op.viscous == op.viscous:
                return sys.op
        return None

    def mark_kept(self) -> None:
        """A step's trial begins: a kept system replaced during it is retired only when the step is accepted."""
        self._marked = (list(self.kept), self.kept_use)

    def release_kept(self) -> None:
        """The step on trial was accepted: the kept systems it replaced are retired."""
        systems = [] if self._marked is None else self._marked[0]
        self._marked = None
        self._retire([s for s in systems if not any(s is k for k in self.kept)])

    def rollback_kept(self) -> None:
        """The step on trial was rejected: the systems kept when it began are kept again (with their use), those it
        kept retired."""
        systems, use = ([], (0, 0)) if self._marked is None else self._marked
        self._marked = None
        self._retire([s for s in self.kept if not any(s is m for m in systems)])
        self.kept, self.kept_use = list(systems), use

    def replace(self, dt: float, operators: list[Operator]) -> None:
        """Continue with the step ``dt``: the current systems are released (their counters kept)
        and ``operators`` factorized.  A kept tangent stays (a checkpoint written at the level where a schedule
        changes its step holds it, and a resume does not change the step there)."""
        self._retire(self.current)
        self.current, self._lookup = [], {}
        self.dt = float(dt)
        for op in operators:
            self.system(op)

    def use(self, dt: float, operators: list[Operator], keep_bytes: float) -> None:
        """Continue with the step ``dt`` keeping the systems of the steps used before: those of
        ``dt`` are taken back when kept, else ``operators`` are factorized; the steps used least
        recently are released while the kept factors exceed ``keep_bytes``.  The contact
        solvers' warm starts (``warm_state``) pass from the systems of the step left to those of
        ``dt``, position by position, so that a step starts from the last accepted level
        whatever operator computed it."""
        dt = float(dt)
        if dt == self.dt:
            return
        before = self.current
        self._ladder[self.dt] = (self.current, self._lookup)
        self.current, self._lookup = self._ladder.pop(dt, ([], {}))
        self.dt = dt
        for op in operators:
            self.system(op)
        for old, new in zip(before, self.current, strict=False):
            for name in getattr(new.solver, "warm_state", ()):
                a, b = getattr(old.solver, name, None), getattr(new.solver, name)
                if a is not None and np.shape(a) == np.shape(b):
                    setattr(new.solver, name, np.array(a, copy=True))
        kept = sum(sys.solver.factor_bytes for systems, _ in self._ladder.values() for sys in systems)
        while self._ladder and kept > keep_bytes:  # least recently used first
            step = next(iter(self._ladder))
            systems, _ = self._ladder.pop(step)
            kept -= sum(sys.solver.factor_bytes for sys in systems)
            self._retire(systems)

    def by_step(self) -> list[tuple[float, Any]]:
        """(dt, system) of the steps kept by :meth:`use`, least recently used first, then the
        current step's."""
        kept = [(dt, sys) for dt, (systems, _) in self._ladder.items() for sys in systems]
        return kept + [(self.dt, s) for s in self.current]

    def every(self) -> list[Any]:
        """The systems of the current step, then those kept for other steps, then the kept tangent's."""
        return self.current + [sys for systems, _ in self._ladder.values() for sys in systems] + self.kept

    @property
    def solvers(self) -> list[ContactSolver]:
        """The contact solvers of the current step's systems."""
        return [s.solver for s in self.current]

    def counters(self) -> dict[str, int]:
        """The solvers' counters (factorizations, linear_solves, ...), summed over every system
        made, those released included."""
        out: dict[str, int] = dict(self.retired)
        for solver in (sys.solver for sys in self.every()):
            for k, v in solver.counters.items():
                out[k] = out.get(k, 0) + int(v)
        return out

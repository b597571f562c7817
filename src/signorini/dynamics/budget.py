"""Size of a run before it starts: steps and a memory estimate, checked against limits.

The estimate is deliberately simple and documented (docs/case-files.md, "Run size"):

* set-up: ``BASE + TRIPLET_BYTES * n_cells * (nodes_per_cell * dim)^2`` -- the element
  matrices of assembly dominate; fitted on this project's bars (2D Q1 n = 32, 64 and
  3D Q1 n = 8, 12, peak RSS with the CG backend: 24 to 40 bytes per triplet).  The
  sparse factor is not included: the ``auto`` backend keeps it within its own memory
  budget (``memory_budget``);
* history: ``8 * (levels) * (2 * n_contact + 9)`` bytes (gaps and multipliers of every
  contact node at every level, plus the scalar series), exact up to the Python overhead.

A run whose number of steps or estimated memory exceeds the limits is refused with the
estimate unless it is confirmed (``--yes`` or ``[limits] yes = true``).
"""

from __future__ import annotations

from dataclasses import dataclass

from ..errors import InputError
from ..linalg.base import total_memory

BASE_BYTES = 80e6
TRIPLET_BYTES = 32.0
DEFAULT_MAX_STEPS = 1_000_000


def default_max_memory() -> float:
    """80% of the machine's physical memory [bytes]."""
    return 0.8 * total_memory()


@dataclass(frozen=True)
class RunEstimate:
    """Steps and estimated peak memory [bytes] of a run."""

    steps: int
    dofs: int
    contact_nodes: int
    setup_bytes: float
    history_bytes: float

    @property
    def total_bytes(self) -> float:
        return self.setup_bytes + self.history_bytes

    def describe(self) -> str:
        return (
            f"{self.steps:,} steps, {self.dofs:,} dofs, {self.contact_nodes:,} contact nodes, "
            f"estimated memory {self.total_bytes / 2**30:.3g} GiB "
            f"(set-up {self.setup_bytes / 2**30:.3g} GiB, history {self.history_bytes / 2**30:.3g} GiB)"
        )


def estimate_run(n_nodes: int, n_cells: int, nodes_per_cell: int, dim: int, n_contact: int, steps: int) -> RunEstimate:
    """The estimate of the module docstring from mesh counts, without building anything."""
    k = nodes_per_cell * dim
    setup = BASE_BYTES + TRIPLET_BYTES * float(n_cells) * k * k
    history = 8.0 * (steps + 1) * (2 * n_contact + 9)
    return RunEstimate(int(steps), int(n_nodes * dim), int(n_contact), setup, history)


def check_run_size(
    est: RunEstimate, max_steps: int | None = None, max_memory: float | None = None, confirmed: bool = False
) -> None:
    """Raise :class:`InputError` with the estimate when a limit is exceeded and not confirmed."""
    if confirmed:
        return
    max_steps = DEFAULT_MAX_STEPS if max_steps is None else max_steps
    max_memory = default_max_memory() if max_memory is None else max_memory
    over = []
    if est.steps > max_steps:
        over.append(f"more than --max-steps {max_steps:,} steps")
    if est.total_bytes > max_memory:
        over.append(f"more than --max-memory {max_memory / 2**30:.3g} GiB")
    if over:
        raise InputError(
            f"this run is large: {est.describe()}; that is {' and '.join(over)}. "
            "Pass --yes (case file: [limits] yes = true) to run it anyway, or raise the limit"
        )

"""The dof map: which process owns which dofs, in blocks of d per node.

In the spirit of dolfinx's ``IndexMap``: the nodes are numbered so that each process owns
a contiguous range ``[start, stop)`` of them (its *owned* nodes), and also reads the
*ghost* nodes owned by others that its cells touch.  A node's d dofs are consecutive
(block size d, node-major): ``dof = d * node + component``.  The serial path is the
one-process map (everything owned, no ghost), so the arithmetic lives here only.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np


def blocked(items: np.ndarray, block_size: int, components: Sequence[int] | None = None) -> np.ndarray:
    """The indices ``block_size * item + component`` of a block layout (node-major), shape
    (len(items), len(components)): a node's dofs, a contact row's normal and tangential
    components, a tag's reaction components (``components`` None: all of them)."""
    comps = np.arange(block_size) if components is None else np.asarray(components, dtype=np.int64)
    return block_size * np.asarray(items, dtype=np.int64)[:, None] + comps[None, :]


def block_of(index: np.ndarray | int, block_size: int) -> np.ndarray | int:
    """The item (a node, a contact node) whose block holds each index of a block layout: index // block_size
    (a dof's node; a dof range's node range)."""
    return index // block_size


def component_of(index: np.ndarray | int, block_size: int) -> np.ndarray | int:
    """The component of each index in its block: index % block_size."""
    return index % block_size


def component(k: int, block_size: int) -> slice:
    """The entries of component k of a node-major vector (or of the rows of a matrix): ``x[component(k, d)]``."""
    return slice(k, None, block_size)


def n_blocks(n: int, block_size: int) -> int:
    """The number of whole blocks (nodes, contact nodes) in n indices."""
    return n // block_size


def whole_blocks(n: int, block_size: int) -> bool:
    """Whether n indices are whole blocks of ``block_size`` (a layout that may be blocked)."""
    return n % block_size == 0


@dataclass(frozen=True)
class DofMap:
    """Owned node range, ghost nodes and block size of one process.

    Attributes
    ----------
    n_nodes : global number of nodes.
    block_size : d, the dofs per node.
    start, stop : the owned nodes [start, stop) in the global numbering.
    ghosts : (g,) global indices of the nodes read but owned by other processes.
    """

    n_nodes: int
    block_size: int
    start: int = 0
    stop: int | None = None
    ghosts: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    @classmethod
    def serial(cls, n_nodes: int, block_size: int) -> DofMap:
        """Every node owned by the one process."""
        return cls(int(n_nodes), int(block_size), 0, int(n_nodes))

    @property
    def owned_nodes(self) -> int:
        return (self.n_nodes if self.stop is None else self.stop) - self.start

    @property
    def n_dofs(self) -> int:
        """Global number of dofs d n_nodes."""
        return self.block_size * self.n_nodes

    @property
    def owned_dofs(self) -> tuple[int, int]:
        """The owned dof range [d start, d stop)."""
        stop = self.n_nodes if self.stop is None else self.stop
        return self.block_size * self.start, self.block_size * stop

    def dofs(self, nodes: np.ndarray, components: Sequence[int] | None = None) -> np.ndarray:
        """Global dofs of ``nodes`` for ``components``, shape (len(nodes), len(components))."""
        return blocked(nodes, self.block_size, components)

    def nodes_of(self, dofs: np.ndarray) -> np.ndarray:
        """The node of each dof."""
        return np.asarray(dofs) // self.block_size

    def owns(self, nodes: np.ndarray) -> np.ndarray:
        """Whether each global node is owned here."""
        nodes = np.asarray(nodes)
        stop = self.n_nodes if self.stop is None else self.stop
        return (nodes >= self.start) & (nodes < stop)

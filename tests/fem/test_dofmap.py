"""The dof map (fem/dofmap.py): node-major blocks of d dofs, owned ranges, ghosts."""

import numpy as np

from signorini.fem.dofmap import DofMap
from signorini.fem.mesh import rectangle
from signorini.fem.space import VectorSpace


def test_serial_map_is_the_space_numbering():
    space = VectorSpace(rectangle(3, 2))
    m = space.dofmap
    assert (m.n_nodes, m.block_size, m.owned_nodes, m.n_dofs) == (12, 2, 12, 24)
    assert m.owned_dofs == (0, 24) and m.ghosts.size == 0
    nodes = np.array([0, 5, 11])
    assert np.array_equal(space.dofs(nodes), [[0, 1], [10, 11], [22, 23]])
    assert np.array_equal(m.dofs(nodes, [1]), [[1], [11], [23]])
    assert np.array_equal(m.nodes_of(np.arange(24)), np.repeat(np.arange(12), 2))


def test_owned_range_and_ghosts():
    m = DofMap(10, 3, 4, 7, np.array([2, 8]))
    assert m.owned_nodes == 3 and m.owned_dofs == (12, 21)
    assert np.array_equal(m.owns(np.array([3, 4, 6, 7])), [False, True, True, False])

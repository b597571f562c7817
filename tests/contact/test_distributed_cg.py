"""The pieces of backend ``petsc-cg`` that run without MPI: the
rigid-body near-null space, and the active-set CG's acceptance of a tie (all backends cg)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from signorini.contact.solver import TIE_TOLERANCE, ActiveSetCGSolver
from signorini.errors import ConvergenceError
from signorini.fem.assembly import stiffness_matrix
from signorini.fem.material import IsotropicElastic
from signorini.fem.mesh import box, rectangle
from signorini.fem.space import VectorSpace


@pytest.mark.parametrize("dim", [2, 3])
def test_rigid_body_modes_span_the_kernel_of_the_stiffness(dim):
    mesh = rectangle(3, 2, 1.0, 0.5) if dim == 2 else box(3, 2, 2, 1.0, 0.5, 0.4)
    space = VectorSpace(mesh)
    S = stiffness_matrix(mesh, IsotropicElastic.from_young(200.0, 0.3))
    dofs = np.arange(space.n_dofs)
    R = space.rigid_body_modes(dofs)
    k = 3 if dim == 2 else 6
    assert R.shape == (space.n_dofs, k)
    assert np.abs(R.T @ R - np.eye(k)).max() <= 5e-14  # orthonormal; measured 5.6e-16
    assert np.abs(S @ R).max() <= 1e-14 * abs(S).max()  # rigid motions store no energy; measured 4.6e-17
    # a Dirichlet condition holding the z-translation removes its column (and not the others)
    free = dofs[dofs % dim != dim - 1]
    held = space.rigid_body_modes(free)
    assert held.shape == (free.size, k - 1)


class _NoisyCG(ActiveSetCGSolver):
    """The exact solution of each projected solve plus round-off of alternating sign, as two
    different CG runs give at a tie (a node at zero gap and zero force)."""

    def __init__(self, K, B, noise):
        super().__init__(K, B, gap_scale=1.0)
        self.noise, self.calls = noise, 0

    def _cg(self, rhs, x0, project):
        P = np.eye(rhs.size)
        for i in range(rhs.size):
            project(P[:, i])
        Kd = self.K.toarray()
        x = P @ np.linalg.lstsq(P @ Kd @ P, P @ rhs, rcond=None)[0]
        self.calls += 1
        return x - self.noise * (-1) ** self.calls * np.array([1.0, 0.0])  # + on the first call: a penetration


def test_an_active_set_cycle_at_a_tie_is_accepted_and_a_real_one_fails():
    K = sp.csr_matrix(np.array([[2.0, -1.0], [-1.0, 2.0]]))
    B = sp.csr_matrix(np.array([[1.0, 0.0]]))
    b = np.array([1.0, 0.5])  # unconstrained x = K^-1 b = (5/6, 2/3): the node exactly at its bound
    bound = np.array([5.0 / 6.0])
    tie = _NoisyCG(K, B, 1e-15)
    x, lam, info = tie.solve(b, bound)
    assert np.abs(x - [5 / 6, 2 / 3]).max() <= 1e-14 and abs(lam[0]) <= 1e-14
    assert info.residual <= TIE_TOLERANCE and tie.calls >= 3  # it did go round the cycle
    with pytest.raises(ConvergenceError, match="cycles"):
        _NoisyCG(K, B, 1e-3).solve(b, bound)

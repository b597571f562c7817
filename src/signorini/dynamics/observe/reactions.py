"""Reaction forces: the total force each Dirichlet tag exerts on the body, per level.

On the Dirichlet dofs D the equation of motion holds with an unknown reaction R_D:

    R_D = (M A + S U - F(t) - B^T lambda - T^T lambda_t)_D        [force],

the force the support applies to the body (the contact part is subtracted where a contact
row touches a fixed dof).  ``history.csv`` has, per tag listed in ``[[dirichlet]]`` (in
their order), the sums ``reaction_<tag>_x`` (``_y``, ``_z``) of R over the tag's fixed dofs
of each component.  A dof fixed by several entries (a corner of two clamped sides) is
counted once, in the first tag that fixes it, so that the sum over the tags is the total
reaction.  With it the total momentum p = 1^T M V balances, for the Newmark family,
p^{n+1} - p^n = dt sum_levels w (F + contact + R) (1^T S U = 0: a translation is
stress-free), which ``tests/dynamics/test_reactions.py`` checks.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ...fem.dofmap import blocked

AXES = "xyz"


class Reactions:
    """The reaction of each Dirichlet tag (module docstring), (m, d) per level."""

    def __init__(self, ctx, dirichlet) -> None:
        space = ctx.disc.space
        mesh, d = space.mesh, space.dim
        D = np.asarray(ctx.fixed, dtype=np.int64)
        self.tags: list[str] = []
        index = np.full(space.n_dofs, -1, dtype=np.int64)  # row of G of each fixed dof
        for bc in dirichlet:
            if bc.tag not in self.tags:
                self.tags.append(bc.tag)
            k = self.tags.index(bc.tag)
            nodes = mesh.nodes_of(bc.tag)
            for c in range(d) if bc.components is None else bc.components:
                dofs = space.dofs(nodes, [c]).ravel()
                dofs = dofs[index[dofs] < 0]
                index[dofs] = blocked([k], d, [c])[0, 0]
        rows = index[D]
        keep = rows >= 0
        self.G = sp.csr_matrix(
            (np.ones(int(keep.sum())), (rows[keep], np.flatnonzero(keep))), shape=(len(self.tags) * d, D.size)
        )
        self.d = d
        self.rows = (ctx.M[D], ctx.S[D])  # taken once: the reactions are summed at every level

    def columns(self) -> list[str]:
        """``reaction_<tag>_<axis>`` for every tag and component, in the order of :meth:`__call__`."""
        return [f"reaction_{tag}_{AXES[c]}" for tag in self.tags for c in range(self.d)]

    def __call__(self, ctx, s) -> np.ndarray:
        """(m, d) the reactions of level ``s`` [force] (:func:`~.schemes.base.fixed_reaction`)."""
        from ..schemes.base import fixed_reaction

        return (self.G @ fixed_reaction(ctx, s, self.rows)).reshape(len(self.tags), self.d)

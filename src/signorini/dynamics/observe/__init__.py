"""What a run records and watches: the :class:`~.history.History` of its levels, the observers (energies and
their identity, reactions, snapshots: :mod:`.observers`), events (:mod:`.events`), the watches of untagged nodes
and of the linear model's rotations, and the diagnostics (oscillation indices, penetrations).  Built on the
solvers and the schemes."""

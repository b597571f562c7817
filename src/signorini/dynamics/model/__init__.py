"""The model: what a run computes.  The :class:`~.problem.Problem` (mesh, materials, contact, loads, initial
state) and its discretization, the mass variants (:mod:`.mass`: the contact inertia removed or redistributed,
the extrapolations they use) and what they do to each body (:mod:`.mass_effect`, :mod:`.bodies`), Rayleigh
damping, the step operators c_M M + c_S S (:mod:`.operator`) and the checks of a problem's input.  Imports
nothing else of ``dynamics``."""

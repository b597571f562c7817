"""The time loop: the :class:`~.stepper.Stepper` (a run one level at a time) and :func:`~.simulate.simulate`
(the loop with its signals), the set-up of a run (:mod:`.setup`), its options (:mod:`.run_options`), the time
grid (:mod:`.time_grid`), the energy-driven step control (:mod:`.step_control`), the checkpointer and the
memory budget.  The top room of ``dynamics``: it imports the others, none imports it."""

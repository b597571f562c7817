"""The time integration of dynamic contact, in seven rooms (docs/architecture.md): the model, the contact rows,
the step's solvers, the schemes, what a run records, restart and the time loop."""

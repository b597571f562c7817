"""The step's solvers: the :class:`~.context.Context` a scheme's step uses (operators, data of a time, the
contact solve on factorized step operators, :mod:`.factorizations`), the elastic response, linear or finite
strain (:mod:`.elasticity`), Newton's method for a nonlinear step (:mod:`.newton`) and the static preload
(:mod:`.initial_equilibrium`).  Built on the model and the rows."""

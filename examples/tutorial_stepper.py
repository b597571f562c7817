"""docs/tutorial.md, a loop of your own: the 2D bar stepped by hand, stopped at the first
contact, checkpointed, then resumed to T with half the step.

The tutorial shows this file verbatim (tests/test_examples.py checks both).
"""

import tempfile
from pathlib import Path

from signorini import Stepper, get_benchmark, simulate

problem = get_benchmark("bar2d").problem(4, {})  # the bar of the first example
dt, T = 0.0125, 1.0
stepper = Stepper(problem, "crank-nicolson", (dt, T))
while stepper.status == "running":
    stepper.step()
    if stepper.state.lam.min() < 0:  # the first level in contact
        break
print(f"contact at t = {stepper.t:.4f} (level {stepper.n} of {stepper.n_steps})")
checkpoint = Path(tempfile.mkdtemp()) / "checkpoint.h5"
stepper.save_checkpoint(checkpoint)
H = stepper.finish()  # status 'interrupted': stopped before T
print(f"{H.status}: {len(H.t)} levels")

# later, maybe on another day: on to T, with half the step from the checkpoint on
R = simulate(problem, "crank-nicolson", dt / 2, T, resume=checkpoint)
print(f"resumed at t = {R.meta['resumed_from']['t']:.4f}: {R.status}, {len(R.t)} levels, steps {R.meta['dt_schedule']}")

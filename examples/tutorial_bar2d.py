"""docs/tutorial.md, first example: the seed paper's 2D bar built from scratch.

The tutorial shows this file verbatim (tests/test_examples.py checks both).
"""

import numpy as np

from signorini import Dirichlet, IsotropicElastic, PlaneObstacle, Problem, rectangle, simulate

n = 4                                            # elements across the width
problem = Problem(
    mesh=rectangle(n, 10 * n, 0.1, 1.0),         # tags xmin, xmax, ymin, ymax
    material=IsotropicElastic(lam=0.25, mu=0.5, rho=1.0),
    contact_tag="ymin",
    obstacle=PlaneObstacle(point=[0.0, 0.0], normal=[0.0, 1.0]),
    dirichlet=[Dirichlet("ymax", (0.0, 0.2))],   # clamp lifted by 0.2
    u0=[0.0, 0.2], v0=[0.0, -0.5],
)
dt = 0.1 / n / 2
for mass in ("standard", "seed"):
    H = simulate(problem, "crank-nicolson", dt, T=4.0, mass=mass)
    tv = np.abs(np.diff(H.lambda_sum)).sum()
    print(f"{mass:8s} E(T)/E(0) = {H.energy[-1] / H.energy[0]:.3f}  "
          f"first contact t = {H.t[np.argmax(H.active > 0)]:.4f}  TV(force) = {tv:.3f}")

"""docs/tutorial.md, second example: a block sliding down a slope with Coulomb friction.

The tutorial shows this file verbatim (tests/test_examples.py checks both).
"""

import numpy as np

from signorini.contact.obstacles import PlaneObstacle
from signorini.dynamics.model.problem import Problem
from signorini.dynamics.observe.observers import CentreOfMassRecorder
from signorini.dynamics.stepping.simulate import simulate
from signorini.fem.material import IsotropicElastic
from signorini.fem.mesh import rectangle

a = np.radians(30.0)
block = Problem(
    mesh=rectangle(8, 4, 1.0, 0.25),
    material=IsotropicElastic.from_young(1000.0, 0.3, 1.0),
    contact_tag="ymin",
    obstacle=PlaneObstacle([0.0, 0.0], [0.0, 1.0]),
    body_force=[np.sin(a), -np.cos(a)],
    friction="coulomb:0.3",                       # or "tresca:0.1", or {"law": ..., ...}
)
com = CentreOfMassRecorder([1.0, 0.0])
H = simulate(block, "backward-euler", dt=0.01, T=2.0, observers=[com])
late = H.t >= 0.5
print("x_G'' =", 2 * np.polyfit(H.t[late], com.position[late], 2)[0])        # 0.2402
print("stick / slip nodes at the end:", H.friction_counts()[0][-1], H.friction_counts()[1][-1])
print("dissipated by friction:", -H.friction_work[-1])

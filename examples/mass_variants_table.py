"""The mass variants on users' own parts (issue 21): the table of docs/verification.md.

Run from the repository root: ``python3 examples/mass_variants_table.py [hertz level]``
(the Hertz rows need gmsh: ``pip install ".[mesh]"``).  Prints one markdown table per
body: for every mass variant the mass kept, centre shift and inertia change (against the
consistent mass), the free-fall error, the contact-force oscillation index, the energy
drift, the penetration of untagged boundary nodes, and for the ball Hertz's duration and
peak force deviations.
"""

import sys
from pathlib import Path

import numpy as np

from signorini.contact.obstacles import PlaneObstacle, SphereObstacle
from signorini.dynamics.model.problem import Problem
from signorini.dynamics.stepping.simulate import simulate
from signorini.fem.material import IsotropicElastic
from signorini.fem.mesh import read_mesh

VARIANTS = ("standard", "lumped", "seed", "moment-preserving", "neighbour", "mass-free-surface")
PARTS = Path(__file__).parent / "meshes"


def _fmt(x, spec=".2e"):
    return "n/a" if x is None else format(x, spec)


def cylinder(obstacle: str, mass: str):
    mesh = read_mesh(PARTS / "cylinder.msh")
    rho, g = 1000.0, 9.81
    mat = IsotropicElastic.from_young(1e6, 0.3, rho)
    if obstacle == "plane":
        ob = PlaneObstacle([0.0, 0.0, -0.005], [0.05, 0.0, 1.0])
    else:  # a ball of radius 5 cm under the cylinder's rim
        ob = SphereObstacle([0.03, 0.0, -0.055], 0.05)
    prob = Problem(mesh, mat, "skin", ob, v0=[0.0, 0.0, -1.0], body_force=[0.0, 0.0, -rho * g])
    return simulate(prob, "cn", 5e-5, 0.02, mass=mass)


def free_fall(mass: str) -> float:
    """Relative error of the free-fall displacement -g T^2 / 2 (every node, before contact)."""
    mesh = read_mesh(PARTS / "cylinder.msh")
    rho, g, T = 1000.0, 9.81, 1e-3
    prob = Problem(mesh, IsotropicElastic.from_young(1e6, 0.3, rho), "skin",
                   PlaneObstacle([0, 0, -1.0], [0, 0, 1.0]), body_force=[0, 0, -rho * g])  # fmt: skip
    H = simulate(prob, "cn", T / 20, T, mass=mass, snapshot_every=20)
    uz = H.snapshots["u"][-1].reshape(-1, 3)[:, 2]
    return float(np.abs(uz + 0.5 * g * T**2).max() / (0.5 * g * T**2))


def row(name: str, H, extra: list[str]) -> str:
    s = H.summary()
    e = s["mass_effect"]
    cells = [name, f"{100 * e['mass_ratio']:.4g}%", _fmt(e["centre_shift"]), _fmt(e["inertia_change"]), *extra,
             _fmt(s["oscillation_index"], ".2f"), _fmt(s["energy_max_relative_drift"]),
             _fmt(s["untagged_penetration_max"]), s["status"]]  # fmt: skip
    return "| " + " | ".join(cells) + " |"


def main(argv: list[str]) -> int:
    level = int(argv[0]) if argv else 3
    head = "| mass | mass kept | centre shift | inertia change | {} | oscillation index | energy drift | untagged pen. "
    head += "| status |"
    for obstacle in ("plane", "ball"):
        print(f"\nCylinder (365 nodes, whole skin tagged) dropped at 1 m/s on a {obstacle}, CN, dt = 5e-5 s, T = 0.02")
        print()
        print(head.format("free-fall error"))
        print("|" + "---|" * 9)
        for m in VARIANTS:
            print(row(m, cylinder(obstacle, m), [_fmt(free_fall(m))]), flush=True)
    from signorini.studies.benchmarks import get_benchmark
    from signorini.studies.hertz import HertzMeasure, cap_angle

    b = get_benchmark("hertz3d")
    for skin in (0.0, 1.0):
        p = b.params({"skin": skin})
        prob = b.problem(level, {"skin": skin})
        dt, T = b.run_times(level, {"skin": skin})
        print(f"\nhertz3d n = {level}, contact tag {'cap + surface (whole skin)' if skin else 'cap'}, CN\n")
        print(head.format("duration / peak force vs Hertz"))
        print("|" + "---|" * 9)
        for m in VARIANTS:
            measure = HertzMeasure(3, p, cap_angle(3, p))
            H = simulate(prob, "cn", dt, T, mass=m, observers=measure.observers())
            dev = measure.summary(H)["hertz"]["relative_deviation"]
            print(row(m, H, [f"{100 * dev['duration']:+.1f}% / {100 * dev['peak_force']:+.1f}%"]), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

"""``[initial] equilibrium = true``: the held bodies start in static equilibrium (issue 52, item 4)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from signorini.contact.obstacles import PlaneObstacle
from signorini.dynamics.model.problem import Problem
from signorini.dynamics.stepping.simulate import simulate
from signorini.errors import InputError
from signorini.fem.material import IsotropicElastic
from signorini.fem.mesh import rectangle
from signorini.fem.space import Dirichlet

RHO, E, NU, G = 7800.0, 2.1e11, 0.3, 9.81


def _beam(equilibrium: bool, material=None) -> Problem:
    """A steel beam 1 m x 5 cm simply supported at its ends (vertical rollers, one horizontal pin) under gravity;
    its top face may touch a plane 0.95 m above it (it never does)."""
    mesh = rectangle(40, 4, 1.0, 0.05)
    mat = material or IsotropicElastic.from_young(E, NU, RHO)
    supports = [Dirichlet("xmin", 0.0, (1,)), Dirichlet("xmin", 0.0, (0,)), Dirichlet("xmax", 0.0, (1,))]
    inner = lambda x: (x[:, 0] > 0.01) & (x[:, 0] < 0.99)  # noqa: E731 (the top face less its supported corners)
    return Problem(mesh, mat, "ymax", PlaneObstacle([0.0, 1.0], [0.0, -1.0]), supports, gravity=[0.0, -G],
                   initial_equilibrium=equilibrium, contact_where=inner)  # fmt: skip


def _reaction(H) -> np.ndarray:
    c = H.columns()
    return c["reaction_xmin_y"] + c["reaction_xmax_y"]


def test_a_simply_supported_beam_starts_with_its_weight_on_its_supports_and_stays_at_rest():
    """Level 0's reactions equal the weight (issue: to 1e-6; measured 4e-11) and the beam does not move (kinetic
    energy below 1e-10 of its elastic energy; measured 3e-21); without the preload it starts unstressed (its
    reactions 1.5% of its weight) and sags dynamically (kinetic energy a quarter of the elastic)."""
    weight = RHO * 1.0 * 0.05 * G
    H = simulate(_beam(True), "crank-nicolson", 1e-4, 2e-2)
    c = H.columns()
    assert np.abs(_reaction(H) - weight).max() <= 1e-8 * weight
    assert c["kinetic_energy"].max() <= 1e-10 * c["elastic_energy"].max()
    report = H.summary()["initial_equilibrium"]
    assert report["solved"] and report["held_bodies"] == [0] and report["free_bodies"] == []
    assert report["force_left"] <= 1e-12 * report["scale"]
    cold = simulate(_beam(False), "crank-nicolson", 1e-4, 2e-2)
    assert abs(_reaction(cold)[0] - weight) >= 0.5 * weight
    assert cold.columns()["kinetic_energy"].max() >= 0.1 * cold.columns()["elastic_energy"].max()
    assert cold.summary()["initial_equilibrium"] == {"solved": False, "reason": "not asked"}


def test_friction_is_refused_by_name():
    with pytest.raises(InputError, match=r"equilibrium = true with friction"):
        simulate(dataclasses.replace(_block(), friction="coulomb:0.3"), "crank-nicolson", 1e-5, 1e-4)


@pytest.mark.parametrize("model", ["neo-hookean", "saint-venant-kirchhoff"])
def test_a_finite_strain_beam_starts_with_its_weight_on_its_supports(model):
    """The steel beam with a finite-strain law (issue 52): its static solve converges (the strain formed from the
    displacement gradient: before, from F^T F - I, the force residual stalled at 3e-8 of the load and the preload
    was refused); level 0's reactions equal the weight (measured 5e-11), it stays at rest (kinetic energy below
    1e-10 of the elastic; measured 4.5e-21), and its level-0 displacement equals the linear beam's to 1e-4
    (measured 2.0e-5: the geometric nonlinearity of a sag of 1.6e-4 of the depth); 4 iterations, the force left
    5.9e-13 of the load."""
    from signorini.fem.material import with_model

    weight = RHO * 1.0 * 0.05 * G
    H = simulate(_beam(True, with_model(IsotropicElastic.from_young(E, NU, RHO), model)), "crank-nicolson", 1e-4,
                 5e-3)  # fmt: skip
    assert H.status == "finished", H.message
    c = H.columns()
    assert np.abs(_reaction(H) - weight).max() <= 1e-8 * weight
    assert c["kinetic_energy"].max() <= 1e-10 * c["elastic_energy"].max()
    report = H.summary()["initial_equilibrium"]
    assert report["solved"] and report["iterations"] <= 10 and report["force_left"] <= 1e-12 * report["scale"]
    linear = simulate(_beam(True), "crank-nicolson", 1e-4, 1e-4, snapshot_every=1)
    finite = simulate(_beam(True, with_model(IsotropicElastic.from_young(E, NU, RHO), model)), "crank-nicolson",
                      1e-4, 1e-4, snapshot_every=1)  # fmt: skip
    u, u_linear = finite.snapshots["u"][0], linear.snapshots["u"][0]
    assert np.abs(u - u_linear).max() <= 1e-4 * np.abs(u_linear).max()


def _block(normal=(0.0, 1.0), lift: float = 0.0) -> Problem:
    """A steel block 0.2 x 0.1 m on a plane through the origin (its bottom face on it, or ``lift`` above)."""
    mesh = rectangle(8, 4, 0.2, 0.1)
    return Problem(mesh, IsotropicElastic.from_young(E, NU, RHO), "ymin", PlaneObstacle([0.0, -lift], list(normal)),
                   gravity=[0.0, -G], initial_equilibrium=True)  # fmt: skip


def test_a_block_resting_on_a_plane_is_held_by_its_contact():
    """No support: the block's static operator is singular; the proximal iterations find its equilibrium, the
    contact carries its weight at level 0 and it stays at rest: its kinetic energy below 1e-6 of its elastic
    energy (measured 1.5e-7 with the default mass, 8.8e-8 with the standard one; without the preload it
    bounces, kinetic energy of the order of the elastic: the contact force jitters by 1.6e-7 of the weight
    from step to step, the resting contact's chatter of issue 52, item 1)."""
    weight = RHO * 0.2 * 0.1 * G
    H = simulate(_block(), "crank-nicolson", 1e-5, 1e-3)
    c = H.columns()
    assert H.summary()["initial_equilibrium"]["held_bodies"] == [0]
    assert abs(-c["lambda_sum"][0] - weight) <= 1e-8 * weight
    assert c["kinetic_energy"].max() <= 1e-6 * c["elastic_energy"].max()


def test_a_block_in_flight_keeps_its_state():
    H = simulate(_block(lift=1e-3), "crank-nicolson", 1e-5, 1e-4)
    report = H.summary()["initial_equilibrium"]
    assert not report["solved"] and report["free_bodies"] == [0] and "no body is held" in report["reason"]
    assert H.columns()["elastic_energy"][0] == 0.0


def test_a_block_on_a_frictionless_slope_has_no_equilibrium_and_is_refused_by_name():
    mesh = rectangle(8, 4, 0.2, 0.1)
    slope = PlaneObstacle([0.0, 0.0], [-0.2, 1.0])  # through the block's lower left corner, rising to the right
    problem = Problem(mesh, IsotropicElastic.from_young(E, NU, RHO), "ymin", slope, gravity=[0.0, -G],
                      initial_equilibrium=True, u0=lambda x: np.column_stack([0 * x[:, 0], 0.2 * x[:, 0]]))  # fmt: skip
    with pytest.raises(InputError, match=r"body 0 has no static equilibrium.*slide or fall"):
        simulate(problem, "crank-nicolson", 1e-5, 1e-4)

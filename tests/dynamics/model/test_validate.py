"""The Python API refuses wrong arguments with a one-line InputError naming the field (issue 20 item 6)."""

import numpy as np
import pytest

from signorini.contact.obstacles import PlaneObstacle
from signorini.dynamics.model.problem import Problem
from signorini.dynamics.stepping.simulate import simulate
from signorini.errors import InputError
from signorini.fem.material import IsotropicElastic
from signorini.fem.mesh import Mesh, rectangle
from signorini.fem.space import Dirichlet

MESH = rectangle(2, 2)
MAT = IsotropicElastic.from_young(1.0, 0.3, 1.0)
FLOOR = PlaneObstacle([0.0, -0.1], [0.0, 1.0])


def _problem(**kw):
    args = dict(mesh=MESH, material=MAT, contact_tag="ymin", obstacle=FLOOR)
    args.update(kw)
    return Problem(**args)


@pytest.mark.parametrize(
    "make, match",
    [
        (lambda: simulate(_problem(), "cn", "0.1", 1.0), "dt must be a number"),
        (lambda: simulate(_problem(), "cn", 0.1, "1"), "T must be a number"),
        (lambda: _problem(v0="fast"), "v0 must be a number"),
        (lambda: _problem(u0=[1.0, 2.0, 3.0]), r"u0 has shape \(3,\)"),
        (lambda: _problem(obstacle=None), "obstacle must be a rigid obstacle"),
        (lambda: _problem(material=None), "material must be an IsotropicElastic"),
        (lambda: _problem(mesh=None), "mesh must be a signorini.fem.mesh.Mesh"),
        (lambda: _problem(contact_tag=3), "contact_tag must be a tag"),
        (lambda: _problem(dirichlet=[Dirichlet("ymax", (0.1,), (0, 1))]), "1 value.* for 2 component"),
        (lambda: _problem(dirichlet=[Dirichlet("ymax", (0.1,))]), "1 value.* for 2 component"),
        (lambda: _problem(dirichlet=["ymax"]), r"dirichlet\[0\] must be a Dirichlet"),
        (lambda: _problem(body_force="down"), "body_force must be a number"),
        (lambda: _problem(tractions={"xmax": [1.0]}), r"tractions\['xmax'\] has shape"),
        (lambda: Mesh(MESH.points, MESH.cells + 0.3, "quad", MESH.facets), "cells must be integer"),
    ],
)
def test_wrong_arguments_name_the_field(make, match):
    with pytest.raises(InputError, match=match) as info:
        make()
    assert "\n" not in str(info.value)


def test_a_bow_tie_quad_is_refused_by_the_api_as_by_the_command_line():
    bow = Mesh(np.array([[0, 0], [1, 1], [1, 0], [0, 1]], float), np.array([[0, 1, 2, 3]]), "quad", {"b": [[0, 2]]})
    with pytest.raises(InputError, match="inverted"):
        simulate(Problem(bow, MAT, "b", FLOOR), "cn", 0.1, 1.0)


def test_valid_forms_are_accepted():
    """Nodal arrays (n, d) or node-major (n d,), integral float cells, one number for all components."""
    mesh = Mesh(MESH.points, MESH.cells.astype(float), "quad", MESH.facets)
    p = _problem(mesh=mesh, u0=np.zeros(18), v0=np.zeros((9, 2)), dirichlet=[Dirichlet("ymax", 0.0)])
    assert simulate(p, "cn", 0.1, 0.2, mass="standard").status == "finished"

"""Arguments of the Python API checked as case files are: one-line InputError naming the field.

:func:`check_problem` runs when a :class:`~signorini.dynamics.model.problem.Problem` is made:
every field has the type and shape it needs, so that a wrong argument is an
:class:`~signorini.errors.InputError` naming it and the allowed values, never a
TypeError from deep inside the assembly, a silent broadcast (a Dirichlet value shorter
than its components) or a silent truncation (float cell indices, checked by
:class:`~signorini.fem.mesh.Mesh`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ...contact.obstacles import RigidObstacle
from ...errors import InputError
from ...fem.material import IsotropicElastic
from ...fem.mesh import Mesh
from ...fem.space import Dirichlet


def _short(v: object) -> str:
    text = repr(v)
    return text if len(text) <= 60 else text[:57] + "..."


def vector_value(name: str, value: object, dim: int, n_nodes: int | None = None, allow_none: bool = False) -> None:
    """A number, a vector of ``dim`` numbers, a callable, or (with ``n_nodes``) nodal values
    of shape (n_nodes, dim) or (n_nodes * dim,)."""
    if value is None and allow_none:
        return
    if callable(value):
        return
    if isinstance(value, (str, bytes, bool)) or value is None:
        raise InputError(f"{name} must be a number, a vector of {dim} numbers or a function of x; got {_short(value)}")
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise InputError(
            f"{name} must be a number, a vector of {dim} numbers or a function of x; got {_short(value)}"
        ) from None
    shapes = [(), (dim,)] + ([(n_nodes, dim), (n_nodes * dim,)] if n_nodes is not None else [])
    if a.shape not in shapes:
        allowed = ", ".join(str(s) for s in shapes)
        raise InputError(f"{name} has shape {a.shape}; allowed shapes: {allowed} (dim = {dim})")
    if not np.all(np.isfinite(a)):
        raise InputError(f"{name} must be finite, got {_short(value)}")


def check_dirichlet(conditions: object, dim: int) -> None:
    """A sequence of :class:`Dirichlet` whose values match their components."""
    if not isinstance(conditions, Sequence) or isinstance(conditions, (str, bytes)):
        raise InputError(f"dirichlet must be a list of Dirichlet conditions, got {_short(conditions)}")
    for i, bc in enumerate(conditions):
        if not isinstance(bc, Dirichlet):
            raise InputError(f"dirichlet[{i}] must be a Dirichlet(tag, value, components), got {_short(bc)}")
        comps = tuple(range(dim)) if bc.components is None else bc.components
        if not isinstance(comps, Sequence) or not all(
            isinstance(c, (int, np.integer)) and not isinstance(c, bool) for c in comps
        ):
            raise InputError(f"dirichlet[{i}].components must be integers in 0..{dim - 1}, got {_short(comps)}")
        if callable(bc.value):
            continue
        try:
            v = np.asarray(bc.value, dtype=float)
        except (TypeError, ValueError):
            raise InputError(f"dirichlet[{i}].value must be numbers or a function, got {_short(bc.value)}") from None
        if v.ndim > 1 or (v.ndim == 1 and v.size != len(comps)):
            raise InputError(
                f"dirichlet[{i}] on tag {bc.tag!r}: {v.size} value(s) for {len(comps)} component(s) {list(comps)}; "
                "give one value per component (or one number for all)"
            )


#: how the acceleration at t = 0 is set (Problem.initial_acceleration, [initial] acceleration)
INITIAL_ACCELERATIONS = ("equilibrium", "zero")


def check_regions(problem) -> None:
    """``materials`` (region tag -> IsotropicElastic) and ``initial_regions`` (RegionInitial s)
    name regions of the mesh with usable data; InputError naming the first that does not."""
    from .problem import RegionInitial

    mesh = problem.mesh
    if not isinstance(problem.materials, dict):
        raise InputError(f"materials must be a dict region tag -> IsotropicElastic, got {_short(problem.materials)}")
    for tag, m in problem.materials.items():
        if not isinstance(tag, str):
            raise InputError(f"materials: the key {_short(tag)} is not a region tag")
        if not isinstance(m, IsotropicElastic):
            raise InputError(f"materials[{tag!r}] must be an IsotropicElastic, got {_short(m)}")
        _known_region(mesh, tag, f"materials[{tag!r}]")
    regions = problem.initial_regions
    if not isinstance(regions, Sequence) or not all(isinstance(r, RegionInitial) for r in regions):
        raise InputError(f"initial_regions must be a list of RegionInitial, got {_short(regions)}")
    for k, r in enumerate(regions):
        _known_region(mesh, r.tag, f"initial_regions[{k}]")
        for name in ("velocity", "displacement"):
            if getattr(r, name) is not None:
                vector_value(f"initial_regions[{k}].{name}", getattr(r, name), mesh.dim)


def _known_region(mesh: Mesh, tag, where: str) -> None:
    if not isinstance(tag, str) or tag not in mesh.regions or mesh.regions[tag].size == 0:
        known = (
            ", ".join(sorted(t for t, c in mesh.regions.items() if c.size))
            or "none (a mesh file's physical groups of cells, or signorini.fem.mesh.join, make regions)"
        )
        raise InputError(f"{where}: {_short(tag)} is not a region of the mesh; its regions: {known}")


def check_problem(problem) -> None:
    """Raise :class:`InputError` naming the first field of ``problem`` that cannot be used."""
    if not isinstance(problem.mesh, Mesh):
        raise InputError(f"mesh must be a signorini.fem.mesh.Mesh, got {_short(problem.mesh)}")
    if not isinstance(problem.material, IsotropicElastic):
        raise InputError(f"material must be an IsotropicElastic, got {_short(problem.material)}")
    from ...contact.pairs import ContactPair

    pairs = problem.pairs
    if not isinstance(pairs, Sequence) or not all(isinstance(p, ContactPair) for p in pairs):
        raise InputError(f"pairs must be a list of signorini.contact.pairs.ContactPair, got {_short(pairs)}")
    for p in pairs:
        for tag in (p.slave, p.master):
            problem.mesh.facets_of(tag)  # an unknown or empty tag: its own error
    rigid = problem.obstacle is not None or problem.contact_tag is not None
    if rigid or not pairs:
        if not isinstance(problem.obstacle, RigidObstacle):
            extra = "" if pairs else "; or contact pairs with obstacle=None and contact_tag=None"
            raise InputError(
                "obstacle must be a rigid obstacle (PlaneObstacle, SphereObstacle, SurfaceObstacle), got "
                f"{_short(problem.obstacle)}" + extra
            )
        ob_dim = getattr(problem.obstacle, "dim", None)
        if ob_dim is not None and ob_dim != problem.mesh.dim:
            raise InputError(
                f"the obstacle is {ob_dim}D and the mesh {problem.mesh.dim}D: give the obstacle's "
                f"vectors (or the surface's points) {problem.mesh.dim} components"
            )
        tag = problem.contact_tag
        tags = [tag] if isinstance(tag, str) else tag
        if not isinstance(tags, Sequence) or not tags or not all(isinstance(t, str) for t in tags):
            raise InputError(f"contact_tag must be a tag or a non-empty list of tags, got {_short(tag)}")
    dim, n = problem.mesh.dim, problem.mesh.n_nodes
    check_regions(problem)
    check_dirichlet(problem.dirichlet, dim)
    vector_value("u0", problem.u0, dim, n)
    vector_value("v0", problem.v0, dim, n)
    vector_value("body_force", problem.body_force, dim, allow_none=True)
    vector_value("gravity", problem.gravity, dim, allow_none=True)
    if not isinstance(problem.tractions, dict):
        raise InputError(f"tractions must be a dict tag -> vector or function, got {_short(problem.tractions)}")
    for k, v in problem.tractions.items():
        if not isinstance(k, str):
            raise InputError(f"tractions: the key {_short(k)} is not a tag name")
        vector_value(f"tractions[{k!r}]", v, dim)
    if not isinstance(problem.follow_mass, (bool, np.bool_)):
        raise InputError(f"follow_mass must be True or False, got {_short(problem.follow_mass)}")
    if not isinstance(problem.initial_equilibrium, bool):
        raise InputError(f"initial_equilibrium must be True or False, got {_short(problem.initial_equilibrium)}")
    if problem.initial_acceleration not in INITIAL_ACCELERATIONS:
        raise InputError(
            f"initial_acceleration must be one of {', '.join(INITIAL_ACCELERATIONS)}, "
            f"got {_short(problem.initial_acceleration)}"
        )
    if problem.contact_where is not None and not callable(problem.contact_where):
        raise InputError(f"contact_where must be a function of the points or None, got {_short(problem.contact_where)}")

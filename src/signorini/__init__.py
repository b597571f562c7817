"""signorini: dynamic Signorini contact with the mass redistribution method.

The public API, importable from the package itself::

    from signorini import Problem, simulate, rectangle, IsotropicElastic, PlaneObstacle

Each name is imported when first used (``import signorini`` stays light: the command line
and ``--help`` load only what they need); :data:`__all__` lists them and
``tests/test_public_api.py`` checks that each resolves to the object of its module.
"""

from __future__ import annotations

import importlib
from typing import Any

__version__ = "0.1.0"

#: name -> the module (below this package) that defines it
_PUBLIC = {
    # problems and runs
    "Problem": "dynamics.model.problem",
    "RegionInitial": "dynamics.model.problem",
    "Rayleigh": "dynamics.model.damping",
    "RegionalRayleigh": "dynamics.model.damping",
    "simulate": "dynamics.stepping.simulate",
    "Stepper": "dynamics.stepping.stepper",
    "RunOptions": "dynamics.stepping.run_options",
    "CheckpointPolicy": "dynamics.stepping.run_options",
    "History": "dynamics.observe.history",
    "Event": "dynamics.observe.events",
    "Observer": "dynamics.observe.observers",
    "Scheme": "dynamics.schemes",
    "State": "dynamics.schemes",
    "SCHEMES": "dynamics.schemes",
    "MASS_VARIANTS": "dynamics.model.mass",
    # meshes, materials, boundary conditions
    "read_mesh": "fem.mesh",
    "write_mesh": "fem.mesh",
    "interval": "fem.mesh",
    "rectangle": "fem.mesh",
    "box": "fem.mesh",
    "join": "fem.mesh",
    "Mesh": "fem.mesh",
    "IsotropicElastic": "fem.material",
    "SaintVenantKirchhoff": "fem.material",
    "NeoHookean": "fem.material",
    "Dirichlet": "fem.space",
    # contact
    "PlaneObstacle": "contact.obstacles",
    "SphereObstacle": "contact.obstacles",
    "SurfaceObstacle": "contact.obstacles",
    "Rotation": "contact.obstacles",
    "ContactPair": "contact.pairs",
    # case files and benchmarks
    "load_case": "io.config",
    "get_benchmark": "studies.benchmarks",
    # errors
    "InputError": "errors",
    "ConvergenceError": "errors",
}

__all__ = ["__version__", *_PUBLIC]


def __getattr__(name: str) -> Any:
    """The public name ``name``, imported from its module on first use (PEP 562)."""
    module = _PUBLIC.get(name)
    if module is None:
        raise AttributeError(f"module 'signorini' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value  # the next access is a plain attribute
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_PUBLIC))

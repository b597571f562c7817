"""A scheme of the user's own: ``--scheme module:Class`` or ``--scheme path/to/file.py:Class``."""

from __future__ import annotations

import importlib
import importlib.util
import os
import sys
from contextlib import contextmanager
from pathlib import Path
from types import ModuleType

from ..errors import InputError


@contextmanager
def _first_on_sys_path(directory: str):
    """``directory`` first on ``sys.path`` for the duration of one import (then removed)."""
    sys.path.insert(0, directory)
    try:
        yield
    finally:
        try:
            sys.path.remove(directory)
        except ValueError:  # the imported code removed it itself
            pass


def _import_scheme_source(source: str) -> ModuleType:
    """The module of ``--scheme SOURCE:Class``: a file ``path/to/file.py`` or a dotted module.

    A dotted module is imported with the current working directory first on
    ``sys.path`` (as ``python -m`` does), so ``--scheme my_schemes:MyScheme`` finds
    ``./my_schemes.py`` whichever way ``signorini`` was started.  A file is loaded
    under its stem with its own directory first on ``sys.path`` (as ``python file.py``
    does), so it can import its neighbours.
    """
    if source.endswith(".py") or "/" in source or os.sep in source:
        path = Path(source).expanduser().resolve()
        if not path.is_file():
            raise ImportError(f"no file {source}")
        name = f"_signorini_scheme_{path.stem}"
        spec = importlib.util.spec_from_file_location(name, path)
        if spec is None or spec.loader is None:
            raise ImportError(f"{source} is not a Python file")
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        with _first_on_sys_path(str(path.parent)):
            try:
                spec.loader.exec_module(module)
            except BaseException:
                del sys.modules[name]
                raise
        return module
    with _first_on_sys_path(os.getcwd()):
        return importlib.import_module(source)


def load_scheme(name: str):
    """A registered scheme name, or a Scheme subclass by import path.

    ``module:Class`` or ``module.Class`` (``module`` importable from the current
    working directory or ``sys.path``), or ``path/to/file.py:Class``.
    """
    from ..dynamics.schemes import SCHEMES, Scheme

    if name in SCHEMES or (":" not in name and "." not in name):
        return SCHEMES.resolve(name)
    source, _, cls = name.rpartition(":") if ":" in name else name.rpartition(".")
    try:
        obj = getattr(_import_scheme_source(source), cls)
    except (ImportError, AttributeError, SyntaxError) as exc:
        raise InputError(
            f"--scheme {name!r}: cannot import it ({exc}); allowed: {', '.join(SCHEMES.names())}, "
            "module:Class (module importable from the working directory) or path/to/file.py:Class"
        ) from None
    except SystemExit as exc:  # the user's module ended the process on import: its error, not a result
        raise InputError(
            f"--scheme {name!r}: importing it called sys.exit({exc.code!r}); a scheme module must "
            "not exit when imported"
        ) from None
    except Exception as exc:  # any other failure of the user's own code on import
        raise InputError(f"--scheme {name!r}: importing it raised {type(exc).__name__}: {exc}") from None
    if not (isinstance(obj, type) and issubclass(obj, Scheme)):
        raise InputError(f"--scheme {name!r} is not a subclass of signorini.dynamics.schemes.Scheme")
    return obj

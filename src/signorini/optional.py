"""Optional dependencies: imported only when a feature needs them, with a clear error."""

from __future__ import annotations

import importlib
from types import ModuleType

from .errors import InputError


def optional_import(module: str, feature: str, extra: str, hint: str = "") -> ModuleType:
    """Import ``module`` for ``feature`` or raise an :class:`InputError` naming the
    pip extra that installs it (a missing shared library counts as missing)."""
    try:
        return importlib.import_module(module)
    except (ImportError, OSError) as exc:
        more = f" {hint}" if hint else ""
        raise InputError(
            f"{feature} needs {module.split('.')[0]}, the extra '{extra}': pip install \".[{extra}]\" in the "
            f"signorini source directory{more} [{exc}]"
        ) from None

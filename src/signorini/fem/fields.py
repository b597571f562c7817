"""Data given as constants, functions of x, or functions of (x, t).

A callable is *time dependent* when it declares an attribute ``time_dependent = True``
(the case-file expressions do) or, otherwise, when it takes two required positional
arguments ``(x, t)``.  :func:`at_time` turns any of them into a function of x only.
"""

from __future__ import annotations

import inspect
from typing import Any


def is_time_dependent(f: Any) -> bool:
    """Whether ``f`` is a callable of (x, t) (see the module docstring)."""
    if not callable(f):
        return False
    flag = getattr(f, "time_dependent", None)
    if flag is not None:
        return bool(flag)
    try:
        params = inspect.signature(f).parameters.values()
    except (TypeError, ValueError):
        return False
    kinds = (inspect.Parameter.POSITIONAL_ONLY, inspect.Parameter.POSITIONAL_OR_KEYWORD)
    required = [p for p in params if p.kind in kinds and p.default is inspect.Parameter.empty]
    return len(required) >= 2


def at_time(f: Any, t: float) -> Any:
    """``f`` itself when it does not depend on time, else ``x -> f(x, t)``."""
    if is_time_dependent(f):
        return lambda x: f(x, t)
    return f

"""Exception types raised at the boundary of the package (API arguments, case files)."""

from __future__ import annotations


class InputError(ValueError):
    """Invalid user input: the message names the field and the allowed values.

    The command line maps this exception to exit code 2.
    """


class MeshError(InputError):
    """A mesh that cannot be used (unsupported cells, bad tags, inverted elements)."""


def check_positive(name: str, value: float, *, allow_zero: bool = False) -> float:
    """Return ``float(value)`` or raise :class:`InputError` naming ``name``."""
    if isinstance(value, (bool, str, bytes)):
        raise InputError(f"{name} must be a number, got {value!r}")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a number, got {value!r}") from None
    except OverflowError:
        raise InputError(f"{name} must be finite, got an integer of {len(str(value))} digits") from None
    if v != v or v in (float("inf"), float("-inf")):
        raise InputError(f"{name} must be finite, got {value!r}")
    if v < 0 or (v == 0 and not allow_zero):
        bound = ">= 0" if allow_zero else "> 0"
        raise InputError(f"{name} must be {bound}, got {value!r}")
    return v


def check_choice(name: str, value: str, allowed) -> str:
    """Return ``value`` if it is one of ``allowed``; otherwise raise naming both."""
    if not isinstance(value, str):
        raise InputError(f"{name} must be a string, one of: {', '.join(sorted(allowed))}; got {value!r}")
    if value not in allowed:
        raise InputError(f"unknown {name} {value!r}; allowed: {', '.join(sorted(allowed))}")
    return value


class ConvergenceError(RuntimeError):
    """A numerical method did not converge (iterative solver, active-set cycle, ...).

    :func:`signorini.dynamics.stepping.simulate.simulate` turns it into a result with
    ``status = "failed"``; the command line exits with code 3.
    """


class NonFiniteError(ConvergenceError):
    """A value that is inf or NaN where a finite one is needed: assembled operators,
    loads, initial data or a step's state.  The message names the quantity.

    A run stops with ``status = "failed"``; the command line exits with code 3.
    """


def not_a_file(p, what: str) -> str:
    """Why path ``p`` is not a regular file, in words (it does not exist, or what it is instead);
    ``what`` names the file expected, e.g. "a mesh file"."""
    import stat
    from pathlib import Path

    p = Path(p)
    if "\x00" in str(p):
        return "is not a valid path (it contains a NUL character)"
    try:
        mode = p.stat().st_mode
    except FileNotFoundError:
        return "does not exist" if not p.is_symlink() else "is a symbolic link to a file that does not exist"
    except OSError as exc:
        return f"cannot be read ({exc.strerror or exc})"
    if stat.S_ISDIR(mode):
        return f"is a directory, not {what}"
    if stat.S_ISFIFO(mode):
        return f"is a named pipe (FIFO), not {what}: give a regular file"
    return f"is not a regular file (a device or a socket): give {what}"


#: what the dynamic loader or the kernel says when an address-space or memory limit stops it
_MEMORY_WORDS = ("failed to map segment", "cannot allocate memory", "out of memory", "cannot map")


def is_memory_failure(exc: BaseException) -> bool:
    """Whether ``exc`` is the machine's memory limit, not a bug: a MemoryError, or an
    ImportError/OSError of a shared library that could not be mapped (``ulimit -v``)."""
    if isinstance(exc, MemoryError):
        return True
    if isinstance(exc, OSError) and exc.errno == 12:  # ENOMEM
        return True
    return isinstance(exc, (ImportError, OSError)) and any(w in str(exc).lower() for w in _MEMORY_WORDS)

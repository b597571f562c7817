"""SIGINT and SIGTERM routed to a handler for the duration of a block (one definition for the package)."""

from __future__ import annotations

import contextvars
import signal
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager

SIGNALS = (signal.SIGINT, signal.SIGTERM)
#: the signals that reached one of several MPI ranks before MPI started (appended by the
#: command line's start-up handler, :mod:`signorini.io.entry`; read by
#: :class:`signorini.parallel.MPIComm`, where every rank stops together)
DEFERRED: list[int] = []
#: the start-up handlers that defer signals (registered by :mod:`signorini.io.entry`): MPI's
#: start replaces them by the KeyboardInterrupt of a serial run
STARTUP_HANDLERS: list[Callable] = []
#: inside :func:`interrupts_raise`, an interrupted simulation raises KeyboardInterrupt instead
#: of returning its partial history (a study built of many runs must not use a truncated one)
_RAISE = contextvars.ContextVar("signorini_interrupts_raise", default=False)


@contextmanager
def interrupts_raise() -> Iterator[None]:
    """Within the block, ``simulate`` interrupted by SIGINT/SIGTERM raises KeyboardInterrupt."""
    token = _RAISE.set(True)
    try:
        yield
    finally:
        _RAISE.reset(token)


def interrupts_must_raise() -> bool:
    """Whether an interrupted run must raise (see :func:`interrupts_raise`)."""
    return _RAISE.get()


@contextmanager
def handled(handler: Callable, enabled: bool = True) -> Iterator[None]:
    """Route SIGINT/SIGTERM to ``handler`` inside the block, restore the previous handlers after.

    Signal handlers can only be set from the main thread: elsewhere (and with
    ``enabled=False``) the block runs with the handlers as they are.
    """
    if not enabled or threading.current_thread() is not threading.main_thread():
        yield
        return
    old = {s: signal.getsignal(s) for s in SIGNALS}
    for s in SIGNALS:
        signal.signal(s, handler)
    try:
        yield
    finally:
        for s, h in old.items():
            signal.signal(s, h)

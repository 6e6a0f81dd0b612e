"""Progress reporting and cancellation through one callback type.

A progress callback is ``progress(fraction, message) -> bool | None``; ``fraction``
runs from 0 to 1. Returning ``False`` asks the work to stop: the library raises
:class:`gistools.errors.Cancelled` at the next chunk or tile. ``None`` means silent.
"""

from __future__ import annotations

import threading
from typing import Callable, Optional

from .errors import Cancelled

__all__ = ["ProgressCallback", "null_progress", "sub_progress", "report", "request_interrupt", "interrupt_requested",
           "check_interrupt", "check_stop", "run_stoppable"]

ProgressCallback = Callable[[float, str], Optional[bool]]


def null_progress(fraction: float, message: str = "") -> bool:
    """A callback that reports nothing and never cancels."""
    return True


def report(progress: ProgressCallback | None, fraction: float, message: str = "") -> None:
    """Call ``progress`` and raise :class:`Cancelled` when it returns False."""
    if progress is None:
        return
    if progress(min(max(fraction, 0.0), 1.0), message) is False:
        raise Cancelled("cancelled by the user", hint="Nothing partial was written")


def sub_progress(progress: ProgressCallback | None, start: float, end: float) -> ProgressCallback | None:
    """A callback mapping 0..1 onto ``start..end`` of ``progress``."""
    if progress is None:
        return None

    def scaled(fraction: float, message: str = "") -> Optional[bool]:
        return progress(start + (end - start) * fraction, message)

    return scaled


# Ctrl-C, as the CLI's SIGINT handler records it. A KeyboardInterrupt raised inside a C extension can come out as
# another exception (numpy, laspy and GDAL were seen turning it into a TypeError): the batch code asks here
# before it reports a tile as failed, so an interrupted run stops instead of going on with a "failed" tile.
_INTERRUPT = threading.Event()


def request_interrupt() -> None:
    """Record a Ctrl-C (called by the CLI's signal handler)."""
    _INTERRUPT.set()


def interrupt_requested() -> bool:
    return _INTERRUPT.is_set()


def check_interrupt() -> None:
    """Raise KeyboardInterrupt when a Ctrl-C was recorded."""
    if _INTERRUPT.is_set():
        raise KeyboardInterrupt


# The stop of the thread pool a tile runs on (engine.batch.ThreadPool), set when its run ends early.
_STOP = threading.local()


def check_stop() -> None:
    """On a pool's thread whose run has ended early (an error, Ctrl-C, Cancel): raise Cancelled. The compiled
    kernel's calls and the point readers ask here, so the tile stops at its next step; elsewhere a no-op."""
    stop = getattr(_STOP, "event", None)
    if stop is not None and stop.is_set():
        raise Cancelled("the run stopped")


def run_stoppable(stop: threading.Event, fn, *args):
    """``fn(*args)`` on a pool's thread, which check_stop stops once ``stop`` is set."""
    _STOP.event = stop
    try:
        return fn(*args)
    finally:
        _STOP.event = None

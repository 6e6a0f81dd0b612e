"""Progress reporting and cancellation through one callback type.

A progress callback is ``progress(fraction, message) -> bool | None``; ``fraction``
runs from 0 to 1. Returning ``False`` asks the work to stop: the library raises
:class:`gistools.errors.Cancelled` at the next chunk or tile. ``None`` means silent.
"""

from __future__ import annotations

from typing import Callable, Optional

from .errors import Cancelled

__all__ = ["ProgressCallback", "null_progress", "sub_progress", "report"]

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

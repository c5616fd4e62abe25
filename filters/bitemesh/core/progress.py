"""Progress reporting and cancellation shared by every long step.

A step takes ``progress``: a callable ``progress(fraction, message)`` with ``fraction`` in [0, 1].  To cancel,
the callable raises :class:`~bitemesh.core.errors.Cancelled`; the step stops at its next report.
"""
from __future__ import annotations

from typing import Callable, Optional

ProgressCallback = Optional[Callable[[float, str], None]]


def report(progress: ProgressCallback, fraction: float, message: str = "") -> None:
    """Call ``progress`` if there is one."""
    if progress is not None:
        progress(min(max(float(fraction), 0.0), 1.0), message)


def sub_progress(progress: ProgressCallback, start: float, stop: float) -> ProgressCallback:
    """The callback for a sub-step that covers [start, stop] of ``progress``'s range."""
    if progress is None:
        return None
    return lambda fraction, message="": progress(start + (stop - start) * fraction, message)

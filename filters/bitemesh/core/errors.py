"""Exceptions raised by bitemesh, and the argument checks that raise them.

Every message names the parameter, the value received, the allowed range and, where it helps, a hint.
"""
from __future__ import annotations

import numpy as np


class BitemeshError(Exception):
    """Base class of every error bitemesh raises on purpose."""


class InvalidInputError(BitemeshError, ValueError):
    """An argument or an input dataset is outside what bitemesh accepts."""


class MeshingError(BitemeshError, RuntimeError):
    """Valid input, but the mesher could not produce a valid mesh from it."""


class BitemeshWarning(UserWarning):
    """A result that bitemesh hands on although it misses a bound the user allowed it to miss."""


class Cancelled(BitemeshError):
    """The user asked to stop (a VTK abort, a Slicer cancel button, Ctrl-C in the CLI)."""


def point_text(point) -> str:
    """A point (k,) as a message gives it: "(x, y, z)", four significant digits."""
    return f"({', '.join(f'{value:.4g}' for value in point)})"


def check_number(value, name: str, *, low=None, high=None, low_open=False, high_open=False, hint="") -> float:
    """Return ``value`` as a float after checking that it is finite and inside [low, high].

    ``low_open``/``high_open`` make the bound strict.  The error names ``name`` and the range.
    """
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise InvalidInputError(f"{name} must be a number, got {value!r}") from None
    too_low = low is not None and (number <= low if low_open else number < low)
    too_high = high is not None and (number >= high if high_open else number > high)
    if not np.isfinite(number):
        raise InvalidInputError(f"{name} must be a finite number, got {value!r}" + (f"; {hint}" if hint else ""))
    if too_low or too_high:
        left = "(" if low_open else "["
        right = ")" if high_open else "]"
        span = f"{left}{'-inf' if low is None else low}, {'inf' if high is None else high}{right}"
        raise InvalidInputError(f"{name} must be in {span}, got {value!r}" + (f"; {hint}" if hint else ""))
    return number


def check_choice(value, name: str, choices) -> str:
    """Return ``value`` if it is one of ``choices``, else raise naming ``name`` and the choices."""
    if value not in choices:
        raise InvalidInputError(f"{name} must be one of {', '.join(map(repr, choices))}, got {value!r}")
    return value


def check_points(points, name: str = "points", *, dims=(2, 3, 4, 5)) -> np.ndarray:
    """Return ``points`` as a C-contiguous (n, k) float64 array with k in ``dims`` and every value finite."""
    try:
        array = np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise InvalidInputError(f"{name} must be an (n, k) array of numbers: {error}") from None
    if array.ndim != 2 or array.shape[1] not in dims:
        raise InvalidInputError(
            f"{name} must be an (n, k) array with k in {tuple(dims)}, got shape {array.shape}")
    bad = ~np.isfinite(array).all(axis=1)
    if bad.any():
        raise InvalidInputError(
            f"{name} contains {int(bad.sum())} rows with NaN or infinite coordinates "
            f"(first: index {int(np.argmax(bad))}, counted from 0); remove them before meshing")
    return np.ascontiguousarray(array)

"""Values read from files or given by a user, checked before any work: one-line errors naming
where the value came from (the file and field, or the setting) and the value.

    check_fps(fps, where)             finite, > 0, at most MAX_FPS
    check_int(v, where, lo, hi)       an integer (not a bool, not 2.5) in [lo, hi]
    check_type(v, where, types, what) the JSON type a field must have
"""

from __future__ import annotations

import math
from numbers import Integral, Real

#: the highest frame rate accepted (frames per second)
MAX_FPS = 10_000.0
#: the most frames a sequence may claim
MAX_FRAMES = 10_000_000
#: the largest image side, pixels
MAX_IMAGE_SIDE = 1 << 15


class BadValueError(ValueError):
    """A value of a file or a setting is of the wrong type or out of range."""


def check_type(value, where: str, types: type | tuple[type, ...], what: str):
    """``value`` when it is one of ``types`` (a bool is not a number); else one line naming
    ``where`` and ``what`` was expected."""
    ok = isinstance(value, types) and not (isinstance(value, bool) and bool not in (
        types if isinstance(types, tuple) else (types,)))
    if not ok:
        shown = repr(value)[:60]
        raise BadValueError(f"{where} must be {what}, got {type(value).__name__} {shown}")
    return value


def check_int(value, where: str, lo: int = 0, hi: int | None = None) -> int:
    """An integer in [lo, hi] (a float with an integer value is accepted; bools are not)."""
    if isinstance(value, bool) or not isinstance(value, Real):
        raise BadValueError(f"{where} must be an integer, got {type(value).__name__} {repr(value)[:60]}")
    if not isinstance(value, Integral):
        if not math.isfinite(value) or value != int(value):
            raise BadValueError(f"{where} must be an integer, got {value!r}")
        value = int(value)
    value = int(value)
    if value < lo or (hi is not None and value > hi):
        raise BadValueError(f"{where} = {value} is out of range (an integer in [{lo}, {hi}])")
    return value


def check_fps(value, where: str) -> float:
    """A frame rate: a finite number > 0 and at most :data:`MAX_FPS`."""
    if isinstance(value, bool) or not isinstance(value, Real):
        raise BadValueError(f"{where} must be a number of frames per second, got "
                            f"{type(value).__name__} {repr(value)[:60]}")
    value = float(value)
    if not math.isfinite(value) or not 0 < value <= MAX_FPS:
        raise BadValueError(f"{where} = {value!r} is not a frame rate (finite, > 0, at most {MAX_FPS:g})")
    return value

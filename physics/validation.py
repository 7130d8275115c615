"""The check of a real-valued setting, shared by the configuration classes of every layer.

A setting is valid when it is a real number (``int``, ``float`` or a NumPy scalar; a ``bool``
is not a number here), finite, and within its bounds. :func:`require_finite` returns it as a
float or raises ``ValueError`` with one line naming the value and what is allowed, in the
form of the command line's errors::

    control_dt=0.0 is not allowed; allowed: a finite number > 0 s

It lives at the bottom layer (``physics``) so that ``batch``, ``flagellum_env`` and ``agents``
can use it without importing upwards; it imports only the standard library.
"""

from __future__ import annotations

import math
import numbers
from typing import Any


def is_real(value: Any) -> bool:
    """True for an ``int``, ``float`` or NumPy real scalar; False for a ``bool`` and anything else."""
    if type(value) is float or type(value) is int:  # the usual ones, without the ABC's check (a bool is neither)
        return True
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def finite_range(lo: float | None = None, hi: float | None = None, *, lo_open: bool = False,
                 hi_open: bool = False) -> str:
    """The bounds in words, e.g. ``"> 0"``, ``">= 0 and <= 0.5"``; ``""`` without bounds."""
    parts = []
    if lo is not None:
        parts.append(f"{'>' if lo_open else '>='} {lo:g}")
    if hi is not None:
        parts.append(f"{'<' if hi_open else '<='} {hi:g}")
    return " and ".join(parts)


def require_finite(name: str, value: Any, lo: float | None = None, hi: float | None = None, *,
                   lo_open: bool = False, hi_open: bool = False, unit: str = "") -> float:
    """``value`` as a float if it is a finite real number within ``[lo, hi]`` (either bound may be
    None = none, or open with ``lo_open`` / ``hi_open``); otherwise ``ValueError``:
    ``"{name}={value!r} is not allowed; allowed: a finite number {bounds} {unit}"``."""
    ok = is_real(value) and math.isfinite(value)
    if ok and lo is not None:
        ok = value > lo if lo_open else value >= lo
    if ok and hi is not None:
        ok = value < hi if hi_open else value <= hi
    if not ok:
        allowed = " ".join(s for s in ("a finite number", finite_range(lo, hi, lo_open=lo_open, hi_open=hi_open),
                                       unit) if s)
        raise ValueError(f"{name}={value!r} is not allowed; allowed: {allowed}")
    return float(value)

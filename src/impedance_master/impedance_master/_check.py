"""Argument checks shared by the core modules: ValueError naming the argument, never a NaN."""
from __future__ import annotations

import math


def finite(name: str, value) -> float:
    """`value` as a finite float, else ValueError naming `name`."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f'{name} must be a finite number, got {value!r}') from None
    if not math.isfinite(v):
        raise ValueError(f'{name} must be finite, got {value!r}')
    return v


def positive(name: str, value) -> float:
    v = finite(name, value)
    if v <= 0.0:
        raise ValueError(f'{name} must be > 0, got {value!r}')
    return v


def nonneg(name: str, value) -> float:
    v = finite(name, value)
    if v < 0.0:
        raise ValueError(f'{name} must be >= 0, got {value!r}')
    return v


def seed(name: str, value):
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        raise ValueError(f'{name} must be an int >= 0 or None, got {value!r}')
    return value

"""Argument checks shared by the core (algorithm) modules of every package: ValueError naming
the argument, never a NaN. Pure Python: no rclpy, so core modules may import it."""
from __future__ import annotations

import math


def finite(name: str, value) -> float:
    """Return `value` as a float; ValueError naming `name` if it is not a finite real number."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f'{name} must be a finite number, got {value!r}') from None
    if not math.isfinite(v):
        raise ValueError(f'{name} must be finite, got {value!r}')
    return v


def nonneg(name: str, value) -> float:
    """A finite number >= 0."""
    v = finite(name, value)
    if v < 0.0:
        raise ValueError(f'{name} must be >= 0, got {v!r}')
    return v


def positive(name: str, value) -> float:
    """A finite number > 0."""
    v = finite(name, value)
    if v <= 0.0:
        raise ValueError(f'{name} must be > 0, got {v!r}')
    return v


def probability(name: str, value) -> float:
    """A finite number in [0, 1]."""
    v = finite(name, value)
    if not 0.0 <= v <= 1.0:
        raise ValueError(f'{name} must be in [0, 1], got {v!r}')
    return v


def seed(name: str, value):
    """None or an int >= 0 (bools refused)."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        raise ValueError(f'{name} must be None or an int >= 0, got {value!r}')
    return value


def first(name: str, values, default=None) -> float:
    """The first element of a message sequence (JointState.position, ...) as a finite float;
    `default` when the sequence is empty (ValueError naming `name` when no default is given)."""
    if len(values) == 0:
        if default is None:
            raise ValueError(f'{name} is empty')
        return default
    return finite(f'{name}[0]', values[0])


def all_finite(name: str, values) -> None:
    """ValueError naming the first entry of `values` that is not a finite number."""
    for i, v in enumerate(values):
        finite(f'{name}[{i}]', v)

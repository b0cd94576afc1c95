"""Argument checks shared by the core (algorithm) modules of every package: ValueError naming
the argument, never a NaN. Pure Python: no rclpy, so core modules may import it."""
from __future__ import annotations

import dataclasses
import math

_isfinite = math.isfinite


def _float(name: str, value, wanted: str) -> float:
    """`value` as a float; ValueError naming `name` (it must be `wanted`) if it is none."""
    try:
        return float(value)
    except (TypeError, ValueError):
        raise ValueError(f'{name} must be {wanted}, got {value!r}') from None


def finite(name: str, value) -> float:
    """Return `value` as a float; ValueError naming `name` if it is not a finite real number."""
    if value.__class__ is float and _isfinite(value):
        return value            # the common case (called ~40 times per 1 kHz period)
    v = _float(name, value, 'a finite number')
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


def number(name: str, value) -> float:
    """A real number that may be infinite but not NaN (a bound: -inf / inf for none)."""
    v = _float(name, value, 'a number')
    if math.isnan(v):
        raise ValueError(f'{name} must not be NaN')
    return v


def positive_or_inf(name: str, value) -> float:
    """A number > 0 that may be inf (a limit: inf for none)."""
    v = _float(name, value, 'a number > 0 (inf: none)')
    if not v > 0.0:                                  # also NaN
        raise ValueError(f'{name} must be > 0 (inf: none), got {value!r}')
    return v


def integer(name: str, value, lo: int, hi: int) -> int:
    """An int in lo..hi (bools refused)."""
    if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
        raise ValueError(f'{name} must be an int in {lo}..{hi}, got {value!r}')
    return value


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


#: the checks `check_fields` may name
_FIELD_CHECKS = {'finite': finite, 'nonneg': nonneg, 'positive': positive,
                 'positive_or_inf': positive_or_inf, 'probability': probability}


def check_fields(obj, **groups) -> None:
    """Table-driven validation of an object's attributes (a dataclass's __post_init__): each
    keyword names a check of this module (finite, nonneg, positive, positive_or_inf,
    probability) and lists the attribute names it applies to. Groups are checked in the
    order given; ValueError names the first attribute that fails. The attributes are not
    converted."""
    for check, names in groups.items():
        fn = _FIELD_CHECKS.get(check)
        if fn is None:
            raise TypeError(f'check_fields: unknown check {check!r}, '
                            f'expected one of {tuple(_FIELD_CHECKS)}')
        if isinstance(names, str):
            raise TypeError(f'check_fields: {check}= takes a sequence of names, not a str')
        for name in names:
            fn(name, getattr(obj, name))


def checked(default, check: str = 'finite'):
    """A dataclass field with its default and the check of this module (`check_fields`'s
    names) its value must pass: the field's constraint stands where it is declared, and
    `check_declared` (in __post_init__) applies it."""
    if check not in _FIELD_CHECKS:
        raise TypeError(f'checked: unknown check {check!r}, expected one of '
                        f'{tuple(_FIELD_CHECKS)}')
    return dataclasses.field(default=default, metadata={'check': check})


def check_declared(obj) -> None:
    """Apply to each field of the dataclass instance `obj` the check it was declared with
    (`checked`), in declaration order; ValueError names the first field that fails. Fields
    declared without one are left to the caller."""
    for f in dataclasses.fields(obj):
        check = f.metadata.get('check')
        if check is not None:
            _FIELD_CHECKS[check](f.name, getattr(obj, f.name))


class CheckedFields:
    """Base of a parameters dataclass whose fields are declared with `checked`: validates
    them on construction (a subclass with more checks calls super().__post_init__() first)
    and gives `as_dict` (field name -> value, for parameters, logs and YAML)."""

    def __post_init__(self) -> None:
        check_declared(self)

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)


class Checked:
    """A validated attribute (a descriptor): in a class body, ``limit = Checked(positive)``
    makes every assignment ``obj.limit = v`` store ``positive('limit', v)`` (ValueError naming
    `limit`) in ``obj._limit``, where hot code may read it directly; ``obj.limit`` reads it."""

    def __init__(self, check) -> None:
        self.check = check

    def __set_name__(self, owner, name: str) -> None:
        self.name, self.slot = name, '_' + name

    def __get__(self, obj, owner=None):
        return self if obj is None else getattr(obj, self.slot)

    def __set__(self, obj, value) -> None:
        setattr(obj, self.slot, self.check(self.name, value))

"""A copy of a generated ROS 2 message equal to its serialisation round trip, without the
round trip: the worker bus hands in-process subscribers such a copy of what was published
instead of deserialising its bytes (`catheter_bringup.bus`). No rclpy here: it relies on the
rosidl-generated message classes (their slots and ``SLOT_TYPES``, described in
`message_copier`); tests/catheter_bringup/test_message_copy.py checks every message type of
the graph against rclpy's own round trip.
"""
from __future__ import annotations

from typing import Callable, Optional

#: rosidl basic types whose values the copy takes as they are, when of exactly this Python
#: type (what the serialisation round trip returns; a scalar of another basic type, float32
#: (rounded by the trip) or octet / char, makes the class not copied)
_SCALAR = {'double': float, 'boolean': bool,
           **{t: int for t in ('int8', 'uint8', 'int16', 'uint16', 'int32', 'uint32', 'int64',
                               'uint64')}}
#: fixed-size arrays of these are numpy arrays in rclpy (copied with .copy(), dtype kept)
_NUMPY = set(_SCALAR) - {'boolean'} | {'float'}
_COPIERS: dict = {}


def _slice(v):
    return v[:]


def _ndcopy(v):
    return v.copy()


def message_copier(msg_type) -> Optional[Callable]:
    """A function ``copy(msg)`` returning a copy of a message of the generated class
    `msg_type` equal, field for field and in each value's Python type, to what
    ``deserialize_message(serialize_message(msg), msg_type)`` returns, cheaper (no C round
    trip, no generated ``__init__`` per nested message; measured: the package README,
    "Benchmark", round 5); it returns None for a message it
    cannot copy exactly (a scalar not of its field's exact Python type: with field checks
    off, an int left in a double field, which the round trip turns into garbage such as
    5e-324; a nested field holding another class), and the caller deserialises then.
    `message_copier` returns None for a class with a field it never copies exactly (a
    float32 scalar, rounded by the trip; an octet or char scalar).

    Relies on: a generated message class keeps field ``f`` in the slot ``_f`` (its property
    setter stores there, the C serializer reads the property), sets ``_check_fields`` and
    the fields only in ``__init__``, stores sequences of basic types as array.array of the
    field's typecode (or bytes, or a list of immutable values) and fixed-size numeric arrays
    as numpy arrays of its dtype (its setters convert), and describes its fields in
    ``SLOT_TYPES`` (rosidl_parser.definition) in the order of
    ``get_fields_and_field_types()``."""
    if msg_type in _COPIERS:
        return _COPIERS[msg_type]
    _COPIERS[msg_type] = None                  # (no message type contains itself)
    steps = _copy_steps(msg_type)
    if steps is None:
        return None
    check = msg_type()._check_fields if '_check_fields' in msg_type.__slots__ else None

    def copy(msg, _cls=msg_type, _new=msg_type.__new__, _steps=steps, _check=check):
        if type(msg) is not _cls:
            return None
        m = _new(_cls)
        if _check is not None:
            m._check_fields = _check
        for slot, exact, conv in _steps:
            v = getattr(msg, slot)
            if exact is not None:
                if type(v) is not exact:
                    return None
            else:
                v = conv(v)
                if v is None:
                    return None
            setattr(m, slot, v)
        return m
    _COPIERS[msg_type] = copy
    return copy


def _copy_steps(msg_type):
    """[(slot, exact type or None, copy function or None)] per field of `msg_type`; None if
    one is never copied exactly."""
    from rosidl_parser import definition as d
    fields = list(msg_type.get_fields_and_field_types())
    slots = getattr(msg_type, 'SLOT_TYPES', None)
    if slots is None or len(slots) != len(fields):
        return None
    steps = []
    for field, slot in zip(fields, slots, strict=True):
        how = _how_copied(slot, d)
        if how is None or '_' + field not in msg_type.__slots__:
            return None
        steps.append(('_' + field,) + how)
    return steps


def _nested(slot):
    from catheter_bringup.cdr import message_class
    return message_copier(message_class('/'.join(slot.namespaced_name())))


def _list_of(sub):
    def copy_list(v, _s=sub):
        out = [_s(x) for x in v]
        return None if None in out else out
    return copy_list


def _how_copied(slot, d):
    """(exact type, None) for a scalar taken as it is, (None, copy function) for the rest;
    None when the field is never copied exactly."""
    if isinstance(slot, d.BasicType):
        t = _SCALAR.get(slot.typename)
        return None if t is None else (t, None)
    if isinstance(slot, d.AbstractString):
        return (str, None)
    if isinstance(slot, d.NamespacedType):
        sub = _nested(slot)
        return None if sub is None else (None, sub)
    vt = slot.value_type if isinstance(slot, (d.Array, d.AbstractSequence)) else None
    if isinstance(vt, d.NamespacedType):
        sub = _nested(vt)
        return None if sub is None else (None, _list_of(sub))
    if isinstance(slot, d.Array):
        if isinstance(vt, d.BasicType) and vt.typename in _NUMPY:
            return (None, _ndcopy)
        return (None, list) if isinstance(vt, d.AbstractString) else None
    if isinstance(slot, d.AbstractSequence) and isinstance(vt, (d.BasicType,
                                                                 d.AbstractString)):
        return (None, _slice)
    return None

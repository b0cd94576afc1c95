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
    copy = _generated(msg_type)
    _COPIERS[msg_type] = copy
    return copy


def _generated(msg_type) -> Callable:
    """`message_copier`'s copy as one generated function, per field of `_copy_steps`: a
    scalar or string taken when of its exact type, a nested message's fields copied inline
    (no call, getattr / setattr or loop per field: a third to a half of the time of the
    field-by-field loop it replaces, the package README, round 9), the rest by its copy
    function (None: the message is refused); a sequence of messages calls its element
    type's copier."""
    env: dict = {}
    lines = ['def copy(msg):']
    counter = [0]

    def name(prefix: str, value=None) -> str:
        counter[0] += 1
        n = f'{prefix}{counter[0]}'
        if value is not None:
            env[n] = value
        return n

    def emit(cls, src: str, indent: str) -> str:
        """Lines copying the message `src` (a local of class `cls`, checked) into a new
        local; returns that local's name."""
        c = name('_C', cls)
        m = name('m')
        lines.append(f'{indent}if {src}.__class__ is not {c}:')
        lines.append(f'{indent}    return None')
        lines.append(f'{indent}{m} = {name("_new", cls.__new__)}({c})')
        if '_check_fields' in cls.__slots__:
            lines.append(f'{indent}{m}._check_fields = {name("_chk", cls()._check_fields)}')
        for slot, exact, conv in _copy_steps(cls):
            v = name('v')
            lines.append(f'{indent}{v} = {src}.{slot}')
            if exact is not None:
                lines.append(f'{indent}if {v}.__class__ is not {name("_T", exact)}:')
                lines.append(f'{indent}    return None')
            elif getattr(conv, 'message_class', None) is not None:
                v = emit(conv.message_class, v, indent)
            else:
                lines.append(f'{indent}{v} = {name("_f", conv)}({v})')
                lines.append(f'{indent}if {v} is None:')
                lines.append(f'{indent}    return None')
            lines.append(f'{indent}{m}.{slot} = {v}')
        return m

    lines.append(f'    return {emit(msg_type, "msg", "    ")}')
    exec(compile('\n'.join(lines), f'<copy {msg_type.__name__}>', 'exec'), env)
    return env['copy']


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
    cls = message_class('/'.join(slot.namespaced_name()))
    sub = message_copier(cls)
    if sub is None:
        return None

    def copy_nested(v, _sub=sub):
        return _sub(v)
    copy_nested.message_class = cls          # the generated copy inlines it
    return copy_nested


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

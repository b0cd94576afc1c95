"""A snapshot of a ROS message in Python, equal to what serialising and deserialising it gives,
at a fraction of the cost (no rclpy).

The local bus (`catheter_bringup.bus.LocalBus`) hands every in-process subscriber of a publish
a message of its own: the publishers reuse their outgoing message objects and change them at
their next tick. It used to be ``deserialize_message(serialize_message(msg))``: the
deserialisation (C code calling every nested message's Python constructor and setters) was
the largest single cost of a lockstep step (cProfile: 20 % of the main process). `copier`
builds, per message class, a function that makes a new object with ``__new__`` and copies the
slots directly, converting each value as the serialisation would (a double field holding an
int or a numpy float becomes a Python float, a sequence of doubles an ``array.array('d')``,
a bool field a bool).

Only classes whose every field (recursively) is a double, an integer, a bool, a string, a
nested message, or an unbounded / bounded sequence of doubles, strings or messages are copied
here; anything else (float32, whose value the serialisation rounds; byte sequences; fixed
arrays) gets None from `copier`, and the bus deserialises as before.
tests/catheter_bringup/test_msg_copy.py compares the copy with the round trip on generated
messages of every type of the graph.
"""
from __future__ import annotations

import array
from typing import Callable, Dict, Optional

_INTS = {'int8', 'uint8', 'int16', 'uint16', 'int32', 'uint32', 'int64', 'uint64'}
_CACHE: Dict[type, Optional[Callable]] = {}


def _field_expr(slot, src: str, env: dict, n: list) -> Optional[str]:
    """A Python expression copying the value `src` of a field of type `slot` (None: not
    supported)."""
    from rosidl_parser import definition as d
    if isinstance(slot, d.BasicType):
        t = slot.typename
        if t == 'double':
            return f'({src} if {src}.__class__ is float else float({src}))'
        if t == 'boolean':
            return f'({src} if {src}.__class__ is bool else bool({src}))'
        if t in _INTS:
            return f'({src} if {src}.__class__ is int else int({src}))'
        return None                      # float (rounded by the serialisation), octet, char
    if isinstance(slot, d.AbstractString) and not isinstance(slot, d.AbstractWString):
        return f'({src} if {src}.__class__ is str else str({src}))'
    if isinstance(slot, d.NamespacedType):
        sub = _message_copier(_message_class(slot))
        if sub is None:
            return None
        name = f'_c{len(n)}'
        n.append(name)
        env[name] = sub
        return f'{name}({src})'
    if isinstance(slot, d.AbstractSequence) and not isinstance(slot, d.Array):
        vt = slot.value_type
        if isinstance(vt, d.BasicType) and vt.typename == 'double':
            env['_array'] = array.array
            return f"_array('d', {src})"
        if isinstance(vt, d.AbstractString) and not isinstance(vt, d.AbstractWString):
            return f'[x if x.__class__ is str else str(x) for x in {src}]'
        if isinstance(vt, d.NamespacedType):
            sub = _message_copier(_message_class(vt))
            if sub is None:
                return None
            name = f'_c{len(n)}'
            n.append(name)
            env[name] = sub
            return f'[{name}(x) for x in {src}]'
    return None                          # fixed arrays (numpy), byte sequences, ...


def _message_class(slot):
    import importlib
    pkg, sub, name = slot.namespaced_name()
    return getattr(importlib.import_module(f'{pkg}.{sub}'), name)


def _message_copier(cls) -> Optional[Callable]:
    if cls in _CACHE:
        return _CACHE[cls]
    _CACHE[cls] = None                   # (a recursive type: not supported)
    fields = list(cls.get_fields_and_field_types())
    slots = list(getattr(cls, '__slots__', ()))
    if [f'_{f}' for f in fields] + ['_check_fields'] != slots \
            and [f'_{f}' for f in fields] != slots:
        return None                      # a layout this module does not know
    env: dict = {'_cls': cls, '_new': cls.__new__}
    lines = ['def copy(m):', '    n = _new(_cls)']
    names: list = []
    for f, slot in zip(fields, cls.SLOT_TYPES, strict=True):
        expr = _field_expr(slot, f'm._{f}', env, names)
        if expr is None:
            return None
        lines.append(f'    n._{f} = {expr}')
    if '_check_fields' in slots:
        lines.append('    n._check_fields = m._check_fields')
    lines.append('    return n')
    exec('\n'.join(lines), env)          # noqa: S102 - code built from the type's own fields
    _CACHE[cls] = env['copy']
    return env['copy']


def copier(cls) -> Optional[Callable]:
    """The snapshot function of the ROS message class `cls` (``copy(msg) -> new msg``), or
    None when a field's type is not supported (see the module docstring)."""
    if not isinstance(cls, type) or not hasattr(cls, 'SLOT_TYPES'):
        raise ValueError(f'cls must be a generated ROS message class, got {cls!r}')
    return _message_copier(cls)

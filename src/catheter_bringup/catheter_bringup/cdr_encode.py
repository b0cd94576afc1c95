"""CDR serialisation of ROS messages in Python, generated per message class (no rclpy).

The local bus serialises every publish (for the recording, and for DDS when another process
takes the topic). ``rclpy.serialization.serialize_message`` converts the message through
every field's Python property and nested message object, the largest cost of a lockstep
step once the subscribers got copies instead of deserialised bytes
(`catheter_bringup.msg_copy.message_copier`; figures: the package README, "Benchmark",
round 5 of the lockstep). `encoder` builds, per message class, a function that reads
the slots directly and packs runs of fixed-size fields with one precompiled ``struct``
each: the bytes of plain little-endian CDR (encapsulation ``00 01 00 00``; every primitive
aligned to its size, at most 8, from the end of that header; strings as uint32 length with
the terminating NUL; sequences as a uint32 count, then the elements, aligned only when
there is one), exactly as long as the message (rclpy's buffer has the rmw's estimated
size; `catheter_bringup.cdr.exact_cdr` leaves these bytes as they are), padding bytes zero.

Covered: integers, bool, double, octet (rclpy's bytes of length 1), strings, nested
messages, unbounded and bounded sequences of doubles, strings and messages. Anything else
(float32, fixed arrays, byte sequences, wide strings) gets None from `encoder`, and the bus
keeps ``serialize_message``. tests/catheter_bringup/test_cdr_encode.py decodes the bytes
with rclpy and compares them with rclpy's own (padding aside) on generated messages of every
type of the graph.
"""
from __future__ import annotations

import array
import struct
import sys
from typing import Callable, Dict, List, Optional, Tuple

_FMT = {'boolean': ('?', 1), 'octet': ('c', 1), 'int8': ('b', 1), 'uint8': ('B', 1),
        'int16': ('h', 2), 'uint16': ('H', 2), 'int32': ('i', 4), 'uint32': ('I', 4),
        'int64': ('q', 8), 'uint64': ('Q', 8), 'double': ('d', 8)}
#: the exact Python type a field's value must have to be encoded here (anything else, e.g.
#: an int left in a double field with field checks off, goes to rclpy's serialiser, whose
#: conversion of it is what DDS and the recording have always carried)
_PY = {'boolean': 'bool', 'octet': 'bytes', 'double': 'float'}
_CACHE: Dict[type, Optional[Callable]] = {}
HEADER = b'\x00\x01\x00\x00'
_ZEROS = bytes(8)


class _Gen:
    """Code of one encoder: the body lines, the constants, and the fixed-size fields not
    packed yet. The offset (from the end of the encapsulation header) is known at
    generation time modulo `mod` (1, 2, 4 or 8) to be `val`: fields whose alignment
    divides `mod` are padded statically, the others at run time."""

    def __init__(self):
        self.lines: List[str] = []
        self.env: dict = {'_Z': _ZEROS}
        self.fmt = ''
        self.args: List[str] = []
        self.mod, self.val = 8, 0
        self.n = 0

    def name(self, prefix: str) -> str:
        self.n += 1
        return f'{prefix}{self.n}'

    def value(self, expr: str, cls: Optional[str], indent: str) -> str:
        """A local holding `expr`; with `cls`, the encoder returns None unless the value's
        class is exactly `cls`."""
        v = self.name('_v')
        self.lines.append(f'{indent}{v} = {expr}')
        if cls is not None:
            self.lines.append(f'{indent}if {v}.__class__ is not {cls}:')
            self.lines.append(f'{indent}    return None')
        return v

    def prim(self, code: str, size: int, expr: str, indent: str) -> None:
        if size > self.mod:
            self.flush(indent)
            self.lines.append(f'{indent}b += _Z[:(4 - len(b)) % {size}]')
            self.mod, self.val = size, 0
        pad = (-self.val) % size
        self.fmt += 'x' * pad + code
        self.args.append(expr)
        self.val = (self.val + pad + size) % self.mod

    def flush(self, indent: str) -> None:
        if not self.fmt:
            return
        name = self.name('_s')
        self.env[name] = struct.Struct('<' + self.fmt).pack
        self.lines.append(f'{indent}b += {name}({", ".join(self.args)})')
        self.fmt, self.args = '', []

    def unknown(self, indent: str) -> None:
        """What follows starts at an offset only known at run time."""
        self.flush(indent)
        self.mod, self.val = 1, 0


def slot_class(slot):
    """The generated message class of a NamespacedType slot (shared with cdr_decode)."""
    import importlib
    pkg, sub, name = slot.namespaced_name()
    return getattr(importlib.import_module(f'{pkg}.{sub}'), name)


def message_fields(cls) -> Optional[List[Tuple[str, object]]]:
    """[(field name, SLOT_TYPES entry)] of a generated message class in wire order, or None
    for a layout the generated encoders / decoders do not know (shared with cdr_decode)."""
    fields = list(cls.get_fields_and_field_types())
    slots = [s for s in getattr(cls, '__slots__', ()) if s != '_check_fields']
    if [f'_{f}' for f in fields] != slots or len(cls.SLOT_TYPES) != len(fields):
        return None                      # a layout this module does not know
    return list(zip(fields, cls.SLOT_TYPES, strict=True))


def _emit(g: _Gen, slot, expr: str, indent: str, depth: int) -> bool:
    """Code that appends the field `expr` of type `slot`; False when not covered."""
    from rosidl_parser import definition as d
    if isinstance(slot, d.BasicType):
        if slot.typename not in _FMT:
            return False
        code, size = _FMT[slot.typename]
        g.prim(code, size, g.value(expr, _PY.get(slot.typename, 'int'), indent), indent)
        return True
    if isinstance(slot, d.AbstractString) and not isinstance(slot, d.AbstractWString):
        v = g.name('_t')
        g.flush(indent)
        g.lines.append(f'{indent}{v} = {g.value(expr, "str", indent)}.encode()')
        g.prim('I', 4, f'len({v}) + 1', indent)
        g.unknown(indent)
        g.lines.append(f"{indent}b += {v}")
        g.lines.append(f"{indent}b += b'\\x00'")
        return True
    if isinstance(slot, d.NamespacedType):
        return _emit_struct(g, slot_class(slot), expr, indent, depth + 1)
    if isinstance(slot, d.AbstractSequence) and not isinstance(slot, d.Array):
        vt = slot.value_type
        g.flush(indent)
        double = isinstance(vt, d.BasicType) and vt.typename == 'double'
        seq = g.value(expr, '_array' if double else 'list', indent)
        g.env['_array'] = array.array
        if double:
            g.lines.append(f"{indent}if {seq}.typecode != 'd':")
            g.lines.append(f'{indent}    return None')
        g.prim('I', 4, f'len({seq})', indent)
        if double:
            g.flush(indent)
            g.lines.append(f'{indent}if {seq}:')
            g.lines.append(f'{indent}    b += _Z[:(4 - len(b)) % 8]')
            if sys.byteorder == 'little':    # array('d') holds little-endian doubles
                g.lines.append(f'{indent}    b += {seq}.tobytes()')
            else:
                g.lines.append(f"{indent}    b += _pack('<%dd' % len({seq}), *{seq})")
            g.env['_pack'] = struct.pack
            g.mod, g.val = 4, 0            # empty: after the count; else after doubles
            return True
        if (isinstance(vt, d.AbstractString) and not isinstance(vt, d.AbstractWString)) \
                or isinstance(vt, d.NamespacedType):
            g.unknown(indent)
            x = g.name('_x')
            g.lines.append(f'{indent}for {x} in {seq}:')
            inner = indent + '    '
            g.lines.append(f'{inner}pass')
            if not _emit(g, vt, x, inner, depth):
                return False
            g.unknown(inner)
            return True
    return False


def _emit_struct(g: _Gen, cls, expr: str, indent: str, depth: int) -> bool:
    if depth > 8:
        return False                     # (a recursive type)
    fields = message_fields(cls)
    if fields is None:
        return False
    cname = g.name('_C')
    g.env[cname] = cls
    v = g.value(expr, cname, indent)
    for f, slot in fields:
        if not _emit(g, slot, f'{v}._{f}', indent, depth):
            return False
    return True


def encoder(cls) -> Optional[Callable]:
    """The CDR encoder of the ROS message class `cls`, or None when a field's type is not
    covered (see the module docstring). ``encode(msg)`` returns the bytes, or None when a
    value is not of its field's exact Python type (an int in a double field, a list where
    the generated setter keeps an array): rclpy's serialiser is the one that decides what
    those become."""
    if not isinstance(cls, type) or not hasattr(cls, 'SLOT_TYPES'):
        raise ValueError(f'cls must be a generated ROS message class, got {cls!r}')
    if cls in _CACHE:
        return _CACHE[cls]
    g = _Gen()
    ok = _emit_struct(g, cls, 'm', '    ', 0)
    fn = None
    if ok:
        g.flush('    ')
        src = '\n'.join(['def encode(m):', f'    b = bytearray({HEADER!r})'] + g.lines
                        + ['    return bytes(b)', ''])
        exec(src, g.env)                 # noqa: S102 - code built from the type's own fields
        fn = g.env['encode']
    _CACHE[cls] = fn
    return fn

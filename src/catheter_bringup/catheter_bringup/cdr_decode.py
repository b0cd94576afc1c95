"""CDR deserialisation of ROS messages in Python, generated per message class (no rclpy): the
counterpart of `catheter_bringup.cdr_encode`.

Where a subscriber of the local bus gets bytes and no copy of the published message (the
lockstep vision process: the slave's joint state comes from the main process through a
pipe, 12 000 per 12 s of Experiment II; a replayed input), ``rclpy.serialization.
deserialize_message`` built the message through its C conversion and every nested
message's ``__init__`` (a JointState ~20 us). `decoder` builds, per message class, a
function that reads the fields with precompiled ``struct`` unpackers and fills the slots
directly, as `catheter_bringup.msg_copy` builds its copies: the message equals what rclpy
returns, field for field and in each value's Python type (int, bool, float, str, a
float64[] as ``array.array('d')``, a string[] or message[] as a list).

Covered: integers, bool, double, strings, nested messages, unbounded and bounded sequences
of doubles, strings and messages, little-endian CDR (encapsulation ``00 01``). Anything else
(float32, octet, char, fixed arrays, byte sequences, wide strings, big-endian data) gets
None from `decoder`; bytes it cannot read (cut short, a bad string length) make the
decoder return None. The caller deserialises with rclpy then, which decides what they are.
tests/catheter_bringup/test_cdr_decode.py compares it with rclpy on generated messages of
every type of the graph.
"""
from __future__ import annotations

import array
import struct
import sys
from typing import Callable, Dict, List, Optional

from catheter_bringup.cdr_encode import message_fields, slot_class

#: struct codes and sizes (= alignment) of the basic types read here
_FMT = {'boolean': ('?', 1), 'int8': ('b', 1), 'uint8': ('B', 1), 'int16': ('h', 2),
        'uint16': ('H', 2), 'int32': ('i', 4), 'uint32': ('I', 4), 'int64': ('q', 8),
        'uint64': ('Q', 8), 'double': ('d', 8)}
_CACHE: Dict[type, Optional[Callable]] = {}
#: what a decoder's reads raise on bytes it cannot read: it returns None then
_BAD = (struct.error, ValueError, UnicodeDecodeError, IndexError)


class _Gen:
    def __init__(self):
        self.lines: List[str] = []
        self.env: dict = {'_array': array.array, '_BAD': _BAD}
        self.n = 0

    def name(self, prefix: str, value=None) -> str:
        self.n += 1
        n = f'{prefix}{self.n}'
        if value is not None:
            self.env[n] = value
        return n

    def unpacker(self, code: str) -> str:
        key = f'_u_{code}' if code != '?' else '_u_bool'
        if key not in self.env:
            self.env[key] = struct.Struct('<' + code).unpack_from
        return key


def _align(g: _Gen, size: int, ind: str) -> None:
    if size > 1:
        g.lines.append(f'{ind}p = (p + {size - 1}) & {-size}')


def _string(g: _Gen, ind: str) -> str:
    """Lines reading a string at p; returns the local holding it."""
    v = g.name('s')
    u32 = g.unpacker('I')
    _align(g, 4, ind)
    n = g.name('n')
    g.lines.append(f'{ind}{n} = {u32}(b, 4 + p)[0]')
    g.lines.append(f'{ind}if {n} < 1 or 8 + p + {n} > len(b) or b[3 + 4 + p + {n}] != 0:')
    g.lines.append(f'{ind}    return None')
    g.lines.append(f'{ind}{v} = b[8 + p:7 + p + {n}].decode()')
    g.lines.append(f'{ind}p += 4 + {n}')
    return v


def _field(g: _Gen, slot, ind: str, depth: int) -> Optional[str]:
    """Lines reading a value of type `slot` at p; returns its local (None: not covered)."""
    from rosidl_parser import definition as d
    if isinstance(slot, d.BasicType):
        if slot.typename not in _FMT:
            return None
        code, size = _FMT[slot.typename]
        _align(g, size, ind)
        v = g.name('x')
        g.lines.append(f'{ind}{v} = {g.unpacker(code)}(b, 4 + p)[0]')
        g.lines.append(f'{ind}p += {size}')
        return v
    if isinstance(slot, d.AbstractWString):
        return None
    if isinstance(slot, d.AbstractString):
        return _string(g, ind)
    if isinstance(slot, d.NamespacedType):
        return _struct(g, slot_class(slot), ind, depth + 1)
    if isinstance(slot, d.AbstractSequence) and not isinstance(slot, d.Array):
        vt = slot.value_type
        _align(g, 4, ind)
        c = g.name('c')
        g.lines.append(f"{ind}{c} = {g.unpacker('I')}(b, 4 + p)[0]")
        g.lines.append(f'{ind}p += 4')
        v = g.name('q')
        if isinstance(vt, d.BasicType) and vt.typename == 'double':
            if sys.byteorder != 'little':
                return None                # array('d') would hold the bytes swapped
            g.lines.append(f"{ind}{v} = _array('d')")
            g.lines.append(f'{ind}if {c}:')
            g.lines.append(f'{ind}    p = (p + 7) & -8')
            g.lines.append(f'{ind}    if 4 + p + 8 * {c} > len(b):')
            g.lines.append(f'{ind}        return None')
            g.lines.append(f'{ind}    {v}.frombytes(b[4 + p:4 + p + 8 * {c}])')
            g.lines.append(f'{ind}    p += 8 * {c}')
            return v
        if (isinstance(vt, d.AbstractString) and not isinstance(vt, d.AbstractWString)) \
                or isinstance(vt, d.NamespacedType):
            g.lines.append(f'{ind}if {c} > len(b):')
            g.lines.append(f'{ind}    return None')
            g.lines.append(f'{ind}{v} = []')
            g.lines.append(f'{ind}for _ in range({c}):')
            inner = ind + '    '
            x = _field(g, vt, inner, depth)
            if x is None:
                return None
            g.lines.append(f'{inner}{v}.append({x})')
            return v
    return None


def _struct(g: _Gen, cls, ind: str, depth: int) -> Optional[str]:
    if depth > 8:
        return None                      # (a recursive type)
    fields = message_fields(cls)
    if fields is None:
        return None
    vals = []
    for f, slot in fields:
        v = _field(g, slot, ind, depth)
        if v is None:
            return None
        vals.append((f, v))
    m = g.name('m')
    g.lines.append(f'{ind}{m} = {g.name("_new", cls.__new__)}({g.name("_C", cls)})')
    if '_check_fields' in cls.__slots__:
        g.lines.append(f'{ind}{m}._check_fields = {g.name("_chk", cls()._check_fields)}')
    for f, v in vals:
        g.lines.append(f'{ind}{m}._{f} = {v}')
    return m


def decoder(cls) -> Optional[Callable]:
    """The CDR decoder of the ROS message class `cls`, or None when a field's type is not
    covered (see the module docstring). ``decode(data)`` returns the message, or None for
    bytes it does not read (big endian, cut short, a bad string length, bytes after the
    message are allowed: rclpy's estimated-size padding)."""
    if not isinstance(cls, type) or not hasattr(cls, 'SLOT_TYPES'):
        raise ValueError(f'cls must be a generated ROS message class, got {cls!r}')
    if cls in _CACHE:
        return _CACHE[cls]
    g = _Gen()
    m = _struct(g, cls, '        ', 0)
    fn = None
    if m is not None:
        src = '\n'.join(['def decode(b):',
                         '    if len(b) < 4 or b[0] != 0 or b[1] != 1:',
                         '        return None',
                         '    p = 0',
                         '    try:'] + g.lines
                        + ['    except _BAD:', '        return None',
                           '    if 4 + p > len(b):', '        return None',
                           f'    return {m}', ''])
        exec(src, g.env)                 # noqa: S102 - code built from the type's own fields
        fn = g.env['decode']
    _CACHE[cls] = fn
    return fn

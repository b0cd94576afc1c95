"""The true length of a CDR-serialised ROS 2 message (no rclpy: message classes only).

``rclpy.serialization.serialize_message`` returns a buffer of the rmw's *estimated* size:
for messages with sequences it ends in 8 or more bytes of garbage (a JointState of 140 B
comes back as 148 B; a DDS raw subscription delivers the 140). Strict readers such as
``rosbags`` reject such payloads ("CDR message size mismatch"). `cdr_end` walks the bytes
with the message type's structure (the generated class's ``SLOT_TYPES``, rosidl_parser
definitions) and returns where the message really ends; `exact_cdr` returns the payload cut
there. The walk reads only the lengths of strings and sequences; it checks that the buffer
holds every byte it steps over (a truncated payload is a ValueError, never a short read).

Encoding (XCDR1, what rmw_fastrtps writes): a 4-byte encapsulation header (``00 01`` little
endian, ``00 00`` big endian, 2 option bytes), then the fields in order, each primitive
aligned to its size (at most 8) relative to the end of the header; strings as uint32 length
(with the NUL) + bytes; sequences as uint32 count + elements (primitive elements aligned to
their size when there is at least one); fixed arrays as their elements; nested messages as
their fields, without alignment of their own. wstring, wchar and long double are not used by
this project and refused.

    >>> data = serialize_message(msg)            # rclpy: estimated size
    >>> exact = exact_cdr(data, type(msg))       # the bytes a DDS subscriber receives
"""
from __future__ import annotations

import importlib
import struct
from typing import Any, Callable, Dict, List

#: size (= alignment) in bytes of the rosidl basic types
PRIMITIVE_SIZE = {
    'boolean': 1, 'octet': 1, 'char': 1, 'int8': 1, 'uint8': 1,
    'int16': 2, 'uint16': 2, 'short': 2, 'unsigned short': 2,
    'int32': 4, 'uint32': 4, 'long': 4, 'unsigned long': 4, 'float': 4,
    'int64': 8, 'uint64': 8, 'long long': 8, 'unsigned long long': 8, 'double': 8,
}
HEADER = 4
_U32 = {True: struct.Struct('<I').unpack_from, False: struct.Struct('>I').unpack_from}

# A compiled walker: (buf, pos, little_endian) -> pos after the value; pos counts from the
# end of the encapsulation header (the CDR alignment origin).
Walker = Callable[[bytes, int, bool], int]


def message_class(type_name: str) -> type:
    """'geometry_msgs/msg/WrenchStamped' -> the generated Python message class."""
    parts = type_name.split('/') if isinstance(type_name, str) else []
    if len(parts) != 3 or not all(parts):
        raise ValueError(f'type_name must look like "pkg/msg/Type", got {type_name!r}')
    try:
        mod = importlib.import_module(f'{parts[0]}.{parts[1]}')
        return getattr(mod, parts[2])
    except (ImportError, AttributeError) as exc:
        raise ValueError(f'type_name: no Python message class for {type_name!r} '
                         f'({type(exc).__name__}: {exc})') from None


def type_name_of(msg_or_class: Any) -> str:
    """The 'pkg/msg/Type' name of a message or message class."""
    cls = msg_or_class if isinstance(msg_or_class, type) else type(msg_or_class)
    parts = cls.__module__.split('.')
    return f'{parts[0]}/{parts[1]}/{cls.__name__}'


def _align(pos: int, n: int) -> int:
    return (pos + n - 1) & -n


def _need(buf, end: int) -> None:
    if end > len(buf) - HEADER:
        raise ValueError(f'data is truncated: the message needs {end + HEADER} bytes, '
                         f'got {len(buf)}')


class _Compiled:
    """Walker of one message class: its fields, with runs of constant-size fields merged."""

    def __init__(self, cls):
        self.cls = cls
        self.ops: List[Walker] = [_walker_of(s) for s in cls.SLOT_TYPES]
        self.fixed = all(getattr(op, 'fixed', False) for op in self.ops)
        if self.fixed:
            self.deltas = tuple(self._simulate(r) for r in range(8))

    def _simulate(self, r: int) -> int:
        pos = r
        for op in self.ops:
            pos += op.deltas[pos & 7]
        return pos - r

    def __call__(self, buf, pos: int, le: bool) -> int:
        for op in self.ops:
            pos = op(buf, pos, le)
        return pos


def _primitive(size: int) -> Walker:
    def walk(buf, pos, le, _s=size):
        return _align(pos, _s) + _s
    walk.fixed = True
    walk.deltas = tuple(_align(r, size) + size - r for r in range(8))
    return walk


def _const(deltas) -> Walker:
    def walk(buf, pos, le, _d=deltas):
        return pos + _d[pos & 7]
    walk.fixed = True
    walk.deltas = tuple(deltas)
    return walk


def _string(buf, pos, le):
    pos = _align(pos, 4)
    _need(buf, pos + 4)
    n = _U32[le](buf, HEADER + pos)[0]
    pos += 4 + n
    _need(buf, pos)
    return pos


def _sequence(elem: Walker, elem_size: int) -> Walker:
    """uint32 count + elements (elem_size > 0: primitive elements of that size)."""
    if elem_size:
        def walk(buf, pos, le):
            pos = _align(pos, 4)
            _need(buf, pos + 4)
            n = _U32[le](buf, HEADER + pos)[0]
            pos += 4
            if n:
                pos = _align(pos, elem_size) + n * elem_size
                _need(buf, pos)
            return pos
        return walk
    deltas = getattr(elem, 'deltas', None) if getattr(elem, 'fixed', False) else None

    def walk_nested(buf, pos, le):
        pos = _align(pos, 4)
        _need(buf, pos + 4)
        n = _U32[le](buf, HEADER + pos)[0]
        pos += 4
        if deltas is not None:
            for _ in range(n):
                pos += deltas[pos & 7]
            _need(buf, pos)
        else:
            for _ in range(n):
                pos = elem(buf, pos, le)
        return pos
    return walk_nested


def _array(elem: Walker, size: int) -> Walker:
    if getattr(elem, 'fixed', False):
        deltas = []
        for r in range(8):
            pos = r
            for _ in range(size):
                pos += elem.deltas[pos & 7]
            deltas.append(pos - r)
        return _const(deltas)

    def walk(buf, pos, le):
        for _ in range(size):
            pos = elem(buf, pos, le)
        return pos
    return walk


_CACHE: Dict[object, Walker] = {}


def _walker_of(slot) -> Walker:
    from rosidl_parser import definition as d
    if isinstance(slot, d.BasicType):
        size = PRIMITIVE_SIZE.get(slot.typename)
        if size is None:
            raise ValueError(f'type: CDR size of {slot.typename!r} is not supported')
        return _primitive(size)
    if isinstance(slot, (d.AbstractWString,)):
        raise ValueError('type: wstring is not supported')
    if isinstance(slot, d.AbstractString):
        return _string
    if isinstance(slot, d.NamespacedType):
        key = tuple(slot.namespaced_name())
        if key not in _CACHE:
            _CACHE[key] = _compile(message_class('/'.join(key)))
        return _CACHE[key]
    if isinstance(slot, d.Array):
        return _array(_walker_of(slot.value_type), int(slot.size))
    if isinstance(slot, d.AbstractSequence):
        vt = slot.value_type
        size = PRIMITIVE_SIZE.get(vt.typename) if isinstance(vt, d.BasicType) else 0
        if isinstance(vt, d.BasicType) and size is None:
            raise ValueError(f'type: CDR size of {vt.typename!r} is not supported')
        return _sequence(_walker_of(vt), size)
    raise ValueError(f'type: unsupported field type {slot!r}')


def _compile(cls) -> Walker:
    c = _Compiled(cls)
    return _const(c.deltas) if c.fixed else c


def walker(cls) -> Walker:
    """The compiled walker of a message class (cached)."""
    if not isinstance(cls, type) or not hasattr(cls, 'SLOT_TYPES'):
        raise ValueError(f'cls must be a generated ROS message class, got {cls!r}')
    key = ('cls', cls)
    w = _CACHE.get(key)
    if w is None:
        w = _CACHE[key] = _compile(cls)
    return w


_ENDS: Dict[type, Any] = {}


def _end_lines(slot, lines: List[str], ind: str, names: List[int], depth: int) -> bool:
    """Lines advancing ``p`` (from the end of the header) over a value of type `slot`; False
    for a type they do not cover."""
    from rosidl_parser import definition as d

    def local(prefix):
        names[0] += 1
        return f'{prefix}{names[0]}'
    if isinstance(slot, d.BasicType):
        size = PRIMITIVE_SIZE.get(slot.typename)
        if size is None:
            return False
        lines.append(f'{ind}p = ((p + {size - 1}) & {-size}) + {size}' if size > 1
                     else f'{ind}p += 1')
        return True
    if isinstance(slot, d.AbstractWString):
        return False
    if isinstance(slot, d.AbstractString):
        lines.append(f'{ind}p = (p + 3) & -4')
        lines.append(f'{ind}p += 4 + u32(b, 4 + p)[0]')
        return True
    if isinstance(slot, d.NamespacedType):
        cls = message_class('/'.join(slot.namespaced_name()))
        if depth > 8 or len(cls.SLOT_TYPES) != len(cls.get_fields_and_field_types()):
            return False
        return all(_end_lines(s, lines, ind, names, depth + 1) for s in cls.SLOT_TYPES)
    if isinstance(slot, (d.Array, d.AbstractSequence)):
        vt = slot.value_type
        size = PRIMITIVE_SIZE.get(vt.typename) if isinstance(vt, d.BasicType) else None
        if isinstance(slot, d.Array):
            count = str(int(slot.size))
        else:
            count = local('c')
            lines.append(f'{ind}p = (p + 3) & -4')
            lines.append(f'{ind}{count} = u32(b, 4 + p)[0]')
            lines.append(f'{ind}p += 4')
        if size is not None:              # primitive elements: contiguous after the first
            lines.append(f'{ind}if {count}:')
            lines.append(f'{ind}    p = ((p + {size - 1}) & {-size}) + {count} * {size}'
                         if size > 1 else f'{ind}    p += {count}')
            return True
        if isinstance(vt, d.BasicType):
            return False
        lines.append(f'{ind}if {count} > n:')
        lines.append(f'{ind}    return None')
        lines.append(f'{ind}for _ in range({count}):')
        lines.append(f'{ind}    pass')
        return _end_lines(vt, lines, ind + '    ', names, depth)
    return False


def _generated_end(cls):
    """A function ``end(data)`` -> where the message of `cls` ends (from the end of the
    header), or None when it cannot say (bytes cut short, a length beyond the data); one
    generated function per class, the same positions as `walker` (tested), without a call
    per field. None when a field's type is not covered."""
    if cls in _ENDS:
        return _ENDS[cls]
    lines: List[str] = []
    fn = None
    if len(cls.SLOT_TYPES) == len(cls.get_fields_and_field_types()) and all(
            _end_lines(s, lines, '        ', [0], 0) for s in cls.SLOT_TYPES):
        src = '\n'.join(['def end(b):', '    n = len(b) - 4',
                         '    u32 = _LE if b[1] == 1 else _BE', '    p = 0', '    try:']
                        + lines + ['    except _struct.error:', '        return None',
                                   '    return p if p <= n else None', ''])
        env = {'_LE': _U32[True], '_BE': _U32[False], '_struct': struct}
        exec(src, env)                   # noqa: S102 - code built from the type's own fields
        fn = env['end']
    _ENDS[cls] = fn
    return fn


def cdr_end(data: bytes | bytearray | memoryview, cls: type) -> int:
    """Length in bytes of the CDR message of type ``cls`` at the start of ``data`` (bytes:
    encapsulation header + payload; trailing bytes beyond the message are ignored)."""
    if not isinstance(data, (bytes, bytearray, memoryview)):
        raise ValueError(f'data must be bytes, got {type(data).__name__}')
    if len(data) < HEADER or data[0] != 0 or data[1] not in (0, 1):
        raise ValueError('data is not a CDR payload (no 00 00 / 00 01 encapsulation header)')
    fast = _ENDS[cls] if cls in _ENDS else _generated_end(cls) \
        if isinstance(cls, type) and hasattr(cls, 'SLOT_TYPES') else None
    if fast is not None:
        end = fast(data)
        if end is not None:
            return HEADER + end
    # the walker: the same positions, and the error that says where the bytes fall short
    w = walker(cls)
    try:
        end = w(data, 0, data[1] == 1)
    except struct.error as exc:     # pragma: no cover - _need guards every read
        raise ValueError(f'data is truncated: {exc}') from None
    _need(data, end)
    return HEADER + end


def exact_cdr(data: bytes | bytearray | memoryview, cls: type) -> bytes:
    """``data`` cut to the true length of its message (see the module docstring)."""
    n = cdr_end(data, cls)
    return bytes(data[:n]) if n != len(data) or not isinstance(data, bytes) else data

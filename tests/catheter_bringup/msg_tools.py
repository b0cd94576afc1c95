"""Test helpers for message bytes: hypothesis strategies that build any generated ROS message
(from its class's SLOT_TYPES), an independent conversion to `rosbags` messages (built from
rosbags' own field definitions), and a field-by-field comparison."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
from hypothesis import strategies as st

from catheter_bringup.cdr import message_class, type_name_of
from catheter_bringup.recorder import message_definition

#: every message type the project's graph publishes or records (standard and its own)
GRAPH_TYPES = (
    'geometry_msgs/msg/WrenchStamped', 'geometry_msgs/msg/PoseArray', 'sensor_msgs/msg/Image',
    'sensor_msgs/msg/JointState', 'nav_msgs/msg/Path', 'visualization_msgs/msg/Marker',
    'diagnostic_msgs/msg/DiagnosticArray', 'rosgraph_msgs/msg/Clock',
    'catheter_interfaces/msg/ImpedanceModel', 'catheter_interfaces/msg/TipForceEstimate',
    'catheter_interfaces/msg/MasterCommand',
)

_INT_RANGE = {'int8': (-128, 127), 'uint8': (0, 255), 'octet': (0, 255), 'char': (0, 255),
              'int16': (-2 ** 15, 2 ** 15 - 1), 'uint16': (0, 2 ** 16 - 1),
              'int32': (-2 ** 31, 2 ** 31 - 1), 'uint32': (0, 2 ** 32 - 1),
              'int64': (-2 ** 63, 2 ** 63 - 1), 'uint64': (0, 2 ** 64 - 1)}
_TEXT = st.text(st.characters(min_codepoint=32, max_codepoint=0x2FF), max_size=12)


def _basic(typename):
    if typename == 'octet':          # rclpy: a bytes object of length 1; rosbags reads a
        # ROS 2 `byte` as int8, so values above 127 would compare as negative there
        return st.integers(0, 127).map(lambda v: bytes([v]))
    if typename == 'boolean':
        return st.booleans()
    if typename == 'double':
        return st.floats(allow_nan=False, allow_infinity=False)
    if typename == 'float':
        return st.floats(allow_nan=False, allow_infinity=False, width=32)
    lo, hi = _INT_RANGE[typename]
    return st.integers(lo, hi)


def slot_strategy(slot, max_len: int):
    from rosidl_parser import definition as d
    if isinstance(slot, d.BasicType):
        return _basic(slot.typename)
    if isinstance(slot, d.BoundedString):
        return st.text(st.characters(min_codepoint=32, max_codepoint=126),
                       max_size=slot.maximum_size)
    if isinstance(slot, d.AbstractString):
        return _TEXT
    if isinstance(slot, d.NamespacedType):
        return message_strategy(message_class('/'.join(slot.namespaced_name())), max_len)
    if isinstance(slot, d.Array):
        return st.lists(slot_strategy(slot.value_type, max_len), min_size=slot.size,
                        max_size=slot.size)
    if isinstance(slot, d.AbstractSequence):
        hi = max_len
        if isinstance(slot, d.BoundedSequence):
            hi = min(hi, slot.maximum_size)
        vt = slot.value_type
        if isinstance(vt, d.BasicType) and vt.typename in ('octet', 'uint8'):
            return st.binary(max_size=4 * hi)
        inner = max(1, max_len // 3) if isinstance(vt, d.NamespacedType) else max_len
        return st.lists(slot_strategy(vt, inner), max_size=hi)
    raise ValueError(f'no strategy for {slot!r}')


def message_strategy(cls, max_len: int = 9):
    """Any instance of the generated message class ``cls`` (sequences up to max_len)."""
    fields = list(cls.get_fields_and_field_types())
    parts = {f: slot_strategy(s, max_len) for f, s in zip(fields, cls.SLOT_TYPES, strict=True)}
    return st.fixed_dictionaries(parts).map(lambda kw: cls(**kw))


def sample_message(cls, rng, max_len: int = 6):
    """A deterministic pseudo-random instance of ``cls`` (``rng``: random.Random): every
    field filled, sequences of 0..max_len elements."""
    from rosidl_parser import definition as d

    def value(slot):
        if isinstance(slot, d.BasicType):
            t = slot.typename
            if t == 'octet':
                return bytes([rng.randrange(128)])
            if t == 'boolean':
                return rng.random() < 0.5
            if t in ('double', 'float'):
                return float(rng.choice([0.0, 1.5, -2.25, 1e-3, 123.0]))
            lo, hi = _INT_RANGE[t]
            return rng.randint(max(lo, -1000), min(hi, 1000))
        if isinstance(slot, d.AbstractString):
            return 'x' * rng.randrange(max_len + 1)
        if isinstance(slot, d.NamespacedType):
            return sample_message(message_class('/'.join(slot.namespaced_name())), rng,
                                  max_len)
        if isinstance(slot, d.Array):
            return [value(slot.value_type) for _ in range(slot.size)]
        n = rng.randrange(max_len + 1)
        if isinstance(slot, d.BoundedSequence):
            n = min(n, slot.maximum_size)
        vt = slot.value_type
        if isinstance(vt, d.BasicType) and vt.typename in ('octet', 'uint8'):
            return bytes(rng.randrange(256) for _ in range(n))
        return [value(vt) for _ in range(n)]
    fields = list(cls.get_fields_and_field_types())
    return cls(**{f: value(s) for f, s in zip(fields, cls.SLOT_TYPES, strict=True)})


# ----------------------------------------------------------------------------- rosbags side
_DTYPE = {'bool': np.bool_, 'byte': np.uint8, 'char': np.uint8, 'int8': np.int8,
          'uint8': np.uint8, 'int16': np.int16, 'uint16': np.uint16, 'int32': np.int32,
          'uint32': np.uint32, 'int64': np.int64, 'uint64': np.uint64,
          'float32': np.float32, 'float64': np.float64}


def typestore_with(*type_names):
    """The ROS2_JAZZY typestore plus the project's types, registered from the recorder's
    message definitions (the schema text written into MCAP files)."""
    from rosbags.typesys import Stores, get_typestore, get_types_from_msg
    ts = get_typestore(Stores.ROS2_JAZZY)
    for name in type_names:
        if name not in ts.types:
            ts.register(get_types_from_msg(message_definition(name), name))
    return ts


def _to_rosbags_value(ts, desc, value):
    from rosbags.typesys.base import Nodetype
    kind, rest = desc
    if kind == Nodetype.BASE:
        base = rest[0]
        if base == 'string':
            return str(value)
        if base in ('float32', 'float64'):
            return float(value)
        if base == 'bool':
            return bool(value)
        if isinstance(value, bytes):        # rclpy octet
            return value[0]
        return int(value)
    if kind == Nodetype.NAME:
        return to_rosbags(ts, value, rest)
    elem, _n = rest
    if elem[0] == Nodetype.BASE and elem[1][0] != 'string':
        arr = np.frombuffer(bytes(value), np.uint8) if isinstance(value, (bytes, bytearray)) \
            else np.asarray(list(value))
        return arr.astype(_DTYPE[elem[1][0]])
    return [_to_rosbags_value(ts, elem, v) for v in value]


def to_rosbags(ts, msg, type_name=None):
    """An rclpy message as the equivalent rosbags message (built from rosbags' fielddefs)."""
    type_name = type_name or type_name_of(msg)
    _consts, fields = ts.fielddefs[type_name]
    kw = {name: _to_rosbags_value(ts, desc, getattr(msg, name)) for name, desc in fields}
    return ts.types[type_name](**kw)


def plain(x):
    """A message (rclpy or rosbags) or value as nested plain Python values."""
    if isinstance(x, (bytes, bytearray)):      # rclpy: an octet is bytes of length 1
        return x[0] if len(x) == 1 else [int(v) for v in x]
    if isinstance(x, np.ndarray):
        return [plain(v) for v in x.tolist()]
    if isinstance(x, (list, tuple)) or type(x).__name__ == 'array':
        return [plain(v) for v in x]
    if isinstance(x, (np.generic,)):
        return x.item()
    if isinstance(x, (int, float, str, bool)) or x is None:
        return x
    if hasattr(x, 'get_fields_and_field_types'):
        return {k: plain(getattr(x, k)) for k in x.get_fields_and_field_types()}
    if dataclasses.is_dataclass(x):
        # rosbags lists constants as fields too; ROS field names are lower case, constants not
        return {f.name: plain(getattr(x, f.name)) for f in dataclasses.fields(x)
                if f.name != '__msgtype__' and not f.name.isupper()}
    raise TypeError(f'cannot flatten {type(x).__name__}')


def assert_same(a, b, path='msg'):
    """Field by field: the same keys, lengths and values (floats exactly; NaN == NaN)."""
    pa, pb = plain(a), plain(b)
    _same(pa, pb, path)


def _same(a, b, path):
    if isinstance(a, dict):
        assert isinstance(b, dict) and set(a) == set(b), f'{path}: fields {a.keys()} vs {b}'
        for k in a:
            _same(a[k], b[k], f'{path}.{k}')
    elif isinstance(a, list):
        assert isinstance(b, list) and len(a) == len(b), f'{path}: {len(a)} vs {b!r}'
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _same(x, y, f'{path}[{i}]')
    elif isinstance(a, float) or isinstance(b, float):
        fa, fb = float(a), float(b)
        assert fa == fb or (math.isnan(fa) and math.isnan(fb)), f'{path}: {a!r} vs {b!r}'
    else:
        assert a == b, f'{path}: {a!r} vs {b!r}'

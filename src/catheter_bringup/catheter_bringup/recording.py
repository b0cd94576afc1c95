"""A recording loaded for analysis (no rclpy): per topic the log times, header stamps and the
few values the metrics use, read from an MCAP file with mcap / mcap_ros2.

Only the types whose values the analysis uses are decoded (`VALUE_TYPES`: forces, joint
states, the typed master command, impedance model and tip force estimate); every other topic
(images: most of a run's bytes) is read for its log times and, when its first field is a
std_msgs/Header, its stamp straight from the CDR bytes.
"""
from __future__ import annotations

import math
import os
import struct
from typing import Dict, Iterable, List, Optional

import numpy as np
import yaml

from catheter_bringup.bagfile import read_messages, reading
from catheter_bringup.recorder import read_run_metadata


def _values(msg):
    """A few numbers per message for the analysis (None when the type has none of interest):
    a force (fx, fy, fz) for WrenchStamped and TipForceEstimate; named (value, velocity,
    acceleration) triples for MasterCommand ('insertion', 'rotation') and ImpedanceModel (the
    names of Impedance.to_fields(): 'm', 'c', ..., 'S0', ...). JointState is not decoded
    here: `joint_state_values` reads it straight from its bytes (the same name -> (position,
    velocity, effort) triples; checked against mcap_ros2's decoder in the tests)."""
    if hasattr(msg, 'wrench'):
        f = msg.wrench.force
        return (f.x, f.y, f.z)
    if hasattr(msg, 'covariance') and hasattr(msg, 'force'):          # TipForceEstimate
        f = msg.force
        return (f.x, f.y, f.z)
    if hasattr(msg, 'acceleration') and hasattr(msg, 'rotation'):     # MasterCommand
        return {'insertion': (msg.position, msg.velocity, msg.acceleration),
                'rotation': (msg.rotation, math.nan, math.nan)}
    if hasattr(msg, 's_table'):                                          # ImpedanceModel
        vals = {k: (float(getattr(msg, k)), math.nan, math.nan)
                for k in ('m', 'c', 'k', 'offset', 'valid', 'kind', 'x0', 'dx', 'sigma',
                          'v_s', 'beta')}
        n = len(msg.s_table)
        vals['n'] = (float(n), math.nan, math.nan)
        for prefix, attr in (('S', 's_table'), ('F', 'f_table'), ('B', 'b_table'),
                             ('C', 'c_table')):
            for i, v in enumerate(getattr(msg, attr)):
                vals[f'{prefix}{i}'] = (float(v), math.nan, math.nan)
        return vals
    return None


#: message types whose values the analysis uses (decoded); every other type is read for its
#: log times and header stamps only (no decoding: images are most of a run's bytes)
VALUE_TYPES = ('geometry_msgs/msg/WrenchStamped', 'sensor_msgs/msg/JointState',
               'catheter_interfaces/msg/MasterCommand', 'catheter_interfaces/msg/ImpedanceModel',
               'catheter_interfaces/msg/TipForceEstimate')


def _leading_header(schema_text: str) -> bool:
    """True when the first field of a ros2msg definition is a std_msgs/Header."""
    for line in schema_text.splitlines():
        tokens = line.split('#', 1)[0].split()
        if len(tokens) < 2 or '=' in line.split('#', 1)[0]:
            continue
        return tokens[0] in ('Header', 'std_msgs/Header', 'std_msgs/msg/Header')
    return False


def raw_stamp(data: bytes) -> Optional[float]:
    """Header stamp (s) of a CDR payload whose first field is a std_msgs/Header."""
    if len(data) < 12:
        return None
    fmt = '<iI' if data[1] == 1 else '>iI'
    sec, nsec = struct.unpack_from(fmt, data, 4)
    return sec + nsec * 1e-9


def joint_state_values(data: bytes) -> Dict[str, tuple]:
    """The values of a CDR sensor_msgs/JointState straight from its bytes (the analysis reads
    tens of thousands; a generic decoder spends ~100 us on one with 80 names, this ~20 us):
    name -> (position, velocity, effort), NaN where an array is shorter than the names."""
    le = data[1] == 1
    u32 = struct.Struct('<I' if le else '>I').unpack_from
    pos = 4 + 8                                     # encapsulation, stamp
    n = u32(data, pos)[0]
    pos += 4 + n                                    # frame_id
    pos = 4 + ((pos - 4 + 3) & ~3)
    count = u32(data, pos)[0]
    pos += 4
    names = []
    for _ in range(count):
        pos = 4 + ((pos - 4 + 3) & ~3)
        n = u32(data, pos)[0]
        names.append(data[pos + 4:pos + 3 + n].decode())
        pos += 4 + n
    arrays = []
    for _ in range(3):
        pos = 4 + ((pos - 4 + 3) & ~3)
        n = u32(data, pos)[0]
        pos += 4
        if n:
            pos = 4 + ((pos - 4 + 7) & ~7)
        arrays.append(np.frombuffer(data, '<f8' if le else '>f8', n, pos).tolist())
        pos += 8 * n
    nan = math.nan
    p, v, e = arrays
    return {name: (p[i] if i < len(p) else nan, v[i] if i < len(v) else nan,
                   e[i] if i < len(e) else nan) for i, name in enumerate(names)}


class _JointStateDecoder:
    """The decoder mark of a JointState topic: `_LazyValues` reads it with
    `joint_state_values` (from the bytes), every other decoded type with ``_values(dec(data))``."""


class _LazyValues:
    """topic -> list of `_values` per message, decoded on first use (decoding is most of the
    cost of reading a run: a topic the analysis does not look at is never decoded)."""

    def __init__(self):
        self._raw: Dict[str, list] = {}
        self._decoders: Dict[str, object] = {}
        self._done: Dict[str, list] = {}

    def add(self, topic: str, decoder, data: Optional[bytes]) -> None:
        self._decoders.setdefault(topic, decoder)
        self._raw.setdefault(topic, []).append(data)

    def get(self, topic, default=None):
        if topic not in self._done:
            if topic not in self._raw:
                return default
            dec = self._decoders[topic]
            if dec is _JointStateDecoder:
                self._done[topic] = [joint_state_values(d) for d in self._raw.pop(topic)]
            else:
                self._done[topic] = [None if dec is None or d is None else _values(dec(d))
                                     for d in self._raw.pop(topic)]
        return self._done[topic]

    def __getitem__(self, topic):
        got = self.get(topic)
        if got is None:
            raise KeyError(topic)
        return got

    def __contains__(self, topic) -> bool:
        return topic in self._raw or topic in self._done


class Recording:
    """A recording loaded into arrays: per topic log times, header stamps (s), and (decoded on
    first use) values."""

    def __init__(self, path, topics: Optional[Iterable[str]] = None, decode: bool = True):
        from mcap_ros2.decoder import DecoderFactory
        self.path = str(path)
        self.meta = read_run_metadata(path)
        sc = self.meta.get('scenario_yaml')
        self.scenario = yaml.safe_load(sc) if sc else {}
        self.log: Dict[str, List[float]] = {}
        self.stamp: Dict[str, List[float]] = {}
        self.values = _LazyValues()
        self.types: Dict[str, str] = {}
        want = set(topics) if topics else None
        factory = DecoderFactory()
        plan = {}       # channel id -> (decoder or None, stamp from raw bytes)
        # the chunks' CRCs checked: a flipped bit in a compressed chunk otherwise often
        # decodes to other values without any error, or to a channel id no channel has
        for schema, channel, message in read_messages(self.path, want):
            topic = channel.topic
            how = plan.get(channel.id)
            if how is None:
                text = schema.data.decode(errors='replace') if schema else ''
                dec = factory.decoder_for(channel.message_encoding, schema) \
                    if decode and schema is not None and schema.name in VALUE_TYPES \
                    else None
                if dec is not None and schema.name == 'sensor_msgs/msg/JointState':
                    dec = _JointStateDecoder
                how = plan[channel.id] = (dec, _leading_header(text))
                self.types.setdefault(topic, schema.name if schema else '')
            dec, stamped = how
            self.log.setdefault(topic, []).append(message.log_time * 1e-9)
            s = raw_stamp(message.data) if stamped else None
            self.stamp.setdefault(topic, []).append(math.nan if s is None else s)
            if decode:
                self.values.add(topic, dec, message.data if dec is not None else None)

    @property
    def topics(self) -> List[str]:
        return sorted(self.log)

    def t(self, topic: str) -> np.ndarray:
        return np.asarray(self.log.get(topic, []), dtype=float)

    def stamps(self, topic: str) -> np.ndarray:
        return np.asarray(self.stamp.get(topic, []), dtype=float)

    def force(self, topic: str, axis: int = 0) -> np.ndarray:
        return np.asarray([v[axis] for v in self.values.get(topic, [])], dtype=float)

    def named(self, topic: str, name: str, field: int = 0) -> np.ndarray:
        return np.asarray([v.get(name, (math.nan,) * 3)[field] if isinstance(v, dict)
                           else math.nan for v in self.values.get(topic, [])], dtype=float)


def load(path: str | os.PathLike) -> Recording:
    """The recording at ``path``, checked first (BagError: one line saying what is wrong)."""
    with reading(path):
        return Recording(path)

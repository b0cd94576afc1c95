"""MCAP writer for a run (no rclpy): every topic of a run in one rosbag2-compatible MCAP file.

Layout of the file (what `ros2 bag`, `rosbags` and `mcap_ros2` expect):

- profile ``ros2``; one schema per message type, named like ``geometry_msgs/msg/WrenchStamped``,
  encoding ``ros2msg``: the installed ``.msg`` text of the type followed, for every type it depends
  on (depth first, each once), by a line of 80 ``=``, ``MSG: pkg/Type`` and that type's text;
- one channel per topic, message encoding ``cdr``: each message's CDR payload with its TRUE
  length (`catheter_bringup.cdr`: rclpy's ``serialize_message`` returns the rmw's estimated
  size, with trailing garbage for messages with sequences, which strict readers reject; the
  recorder cuts every payload at its end, so raw-subscription bytes and serialize_message
  bytes are recorded alike), with the offered QoS as rosbag2 writes it
  (``offered_qos_profiles`` YAML, version 9 field names) in its metadata;
- zstd compressed chunks (level `ZSTD_LEVEL`), a summary with statistics and indexes;
- a metadata record ``catheter_run_start`` written when the run starts (`McapRecorder.start`:
  the scenario, mode, seed ... so a killed run's file still says what it was; see
  `catheter_bringup.bagfile.recover`), and ``catheter_run`` written at close: ``status``
  (complete | interrupted | failed), ``reason``, ``last_log_time_ns``, ``messages`` (count),
  per-topic counts and what the caller adds.

Times are integers in nanoseconds (the node clock, i.e. sim time in lockstep runs).
"""
from __future__ import annotations

import json
import os
import pathlib
import re
import struct
import threading
from typing import Dict, List, Mapping, Optional

import mcap.writer
from mcap.writer import CompressionType, Writer

from catheter_bringup.cdr import cdr_end, message_class

#: zstd level of the chunks. mcap's writer compresses with ``zstandard.compress`` (level 3);
#: level 1 compresses an Experiment II recording (its 800x800 frames) about as well for a
#: fraction of the CPU, in the writer process that shares the two cores with the run's
#: processes (figures: the package README, "Benchmark")
ZSTD_LEVEL = 1


class _Zstd:
    """``mcap.writer``'s view of the zstandard module: its ``compress`` at `ZSTD_LEVEL`,
    the rest the module's own."""

    def __init__(self, module, level: int):
        self._module = module
        self.level = level
        self.compress = module.ZstdCompressor(level=level).compress

    def __getattr__(self, name):
        return getattr(self._module, name)


def _use_zstd_level(level: int = ZSTD_LEVEL) -> None:
    """Make mcap's writer compress chunks at `level` (process-wide: every recording here is
    this module's). Relies on: mcap.writer calling its module global ``zstandard.compress``
    (tests/catheter_bringup/test_recorder.py pins it)."""
    z = getattr(mcap.writer, 'zstandard', None)
    if z is None:
        return                       # mcap without zstandard: it refuses zstd itself
    if isinstance(z, _Zstd):
        z = z._module
    mcap.writer.zstandard = _Zstd(z, level)


_use_zstd_level()

#: a Message record as mcap's ``Message.write`` builds it: opcode 5, record length (22 + the
#: payload), channel id, sequence, log time, publish time; then the payload
_MESSAGE_HEAD = struct.Struct('<BQHIQQ')


def fast_message_writer(w: Writer):
    """A function ``add(channel_id, log_time, publish_time, sequence, data)`` that does what
    ``w.add_message`` does for a chunked writer (the file's statistics, the chunk's time
    range and message index, the Message record in the chunk, the chunk finished when full)
    with one packed header instead of mcap's record builder calls and a Message object per
    message (the mcap writer was about half of the recording writer process's CPU in a
    lockstep Experiment II: the package README, round 9). None when `w` does not chunk (its
    own add_message then).

    Relies on mcap's Writer internals (``_Writer__statistics``, ``_Writer__chunk_builder``,
    ``_Writer__maybe_finalize_chunk``; the ChunkBuilder's ``message_indices``,
    ``num_messages``, times and ``record_writer._buffer``, a BytesIO at the chunk's end);
    tests/catheter_bringup/test_recorder.py checks the files are byte for byte the same as
    with ``add_message``."""
    cb = getattr(w, '_Writer__chunk_builder', None)
    stats = getattr(w, '_Writer__statistics', None)
    finish = getattr(w, '_Writer__maybe_finalize_chunk', None)
    if cb is None or stats is None or finish is None:
        return None
    from mcap.records import MessageIndex
    counts = stats.channel_message_counts
    indices = cb.message_indices
    pack = _MESSAGE_HEAD.pack

    def add(channel_id: int, log_time: int, publish_time: int, sequence: int, data) -> None:
        if stats.message_count == 0:
            stats.message_start_time = log_time
        elif log_time < stats.message_start_time:
            stats.message_start_time = log_time
        if log_time > stats.message_end_time:
            stats.message_end_time = log_time
        counts[channel_id] += 1
        stats.message_count += 1
        if cb.num_messages == 0:
            cb.message_start_time = log_time
        elif log_time < cb.message_start_time:
            cb.message_start_time = log_time
        if log_time > cb.message_end_time:
            cb.message_end_time = log_time
        index = indices.get(channel_id)
        if not index:
            index = indices[channel_id] = MessageIndex(channel_id=channel_id, records=[])
        buf = cb.record_writer._buffer
        index.records.append((log_time, buf.tell()))
        cb.num_messages += 1
        buf.write(pack(5, 22 + len(data), channel_id, sequence, log_time, publish_time))
        buf.write(data)
        finish()
    return add

SEPARATOR = '=' * 80
BUILTIN_TYPES = {
    'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16', 'uint16', 'int32',
    'uint32', 'int64', 'uint64', 'string', 'wstring',
}
RUN_METADATA = 'catheter_run'
RUN_START_METADATA = 'catheter_run_start'

_DEFAULT_QOS = {'history': 'keep_last', 'depth': 10, 'reliability': 'reliable',
                'durability': 'volatile'}


def _split_type(type_name: str):
    """'pkg/msg/Type' or 'pkg/Type' -> ('pkg', 'Type')."""
    if not isinstance(type_name, str):
        raise ValueError(f'type_name must be a string like "pkg/msg/Type", got {type_name!r}')
    parts = type_name.split('/')
    if len(parts) == 3 and parts[1] == 'msg':
        return parts[0], parts[2]
    if len(parts) == 2:
        return parts[0], parts[1]
    raise ValueError(f'type_name must look like "pkg/msg/Type", got {type_name!r}')


def _msg_file(pkg: str, name: str) -> pathlib.Path:
    from ament_index_python.packages import (PackageNotFoundError,
                                             get_package_share_directory)
    try:
        share = pathlib.Path(get_package_share_directory(pkg))
    except PackageNotFoundError as exc:
        raise ValueError(f'type_name: message package {pkg!r} is not installed') from exc
    path = share / 'msg' / f'{name}.msg'
    if not path.exists():
        raise ValueError(f'type_name: no message file {path}')
    return path


def _field_types(text: str, pkg: str) -> List[str]:
    """Complex field types ('pkg/Type') named in a .msg text, in order of appearance."""
    out = []
    for line in text.splitlines():
        line = line.split('#', 1)[0].strip()
        if not line:
            continue
        tokens = line.split()
        if len(tokens) < 2:
            continue
        ftype = tokens[0]
        if '=' in tokens[1] or (len(tokens) > 2 and tokens[2].startswith('=')):
            continue  # constant
        base = re.sub(r'\[.*\]$', '', ftype)          # arrays: T[], T[3], T[<=3]
        base = re.sub(r'<=\d+$', '', base)              # bounded strings
        if base in BUILTIN_TYPES:
            continue
        if base == 'Header':
            base = 'std_msgs/Header'
        if '/' not in base:
            base = f'{pkg}/{base}'
        out.append(base.replace('/msg/', '/'))
    return out


_DEF_CACHE: Dict[str, str] = {}


def message_definition(type_name: str) -> str:
    """The full ros2msg definition of ``type_name`` (the text rosbag2 stores as a schema).

    Reads the installed ``share/<pkg>/msg/<Type>.msg`` files through ament_index.
    """
    if type_name in _DEF_CACHE:
        return _DEF_CACHE[type_name]
    pkg, name = _split_type(type_name)
    text = _msg_file(pkg, name).read_text()
    parts = [text.rstrip('\n') + '\n']
    seen = set()
    stack = list(reversed(_field_types(text, pkg)))
    order = []
    # depth-first: a type's dependencies follow it, each dependency once
    while stack:
        dep = stack.pop()
        if dep in seen:
            continue
        seen.add(dep)
        order.append(dep)
        dpkg, dname = _split_type(dep)
        dtext = _msg_file(dpkg, dname).read_text()
        stack.extend(reversed(_field_types(dtext, dpkg)))
        parts.append(f'{SEPARATOR}\nMSG: {dep}\n{dtext.rstrip(chr(10))}\n')
    full = ''.join(parts)
    _DEF_CACHE[type_name] = full
    return full


def qos_yaml(profiles: List[Mapping]) -> str:
    """``offered_qos_profiles`` YAML (rosbag2 format, version 9) from a list of dicts with keys
    history, depth, reliability, durability (strings like 'keep_last', 'best_effort')."""
    lines = []
    for p in profiles:
        q = dict(_DEFAULT_QOS)
        q.update({k: v for k, v in p.items() if v is not None})
        lines += [f"- history: {q['history']}", f"  depth: {int(q['depth'])}",
                  f"  reliability: {q['reliability']}", f"  durability: {q['durability']}",
                  '  deadline:', '    sec: 2147483647', '    nsec: 4294967295',
                  '  lifespan:', '    sec: 2147483647', '    nsec: 4294967295',
                  '  liveliness: automatic', '  liveliness_lease_duration:',
                  '    sec: 2147483647', '    nsec: 4294967295',
                  '  avoid_ros_namespace_conventions: false']
    return '\n'.join(lines) + '\n' if lines else ''


def known_channel(topic: str, type_name: str, ids: Mapping[str, int],
                  types: Mapping[str, str], closed: bool) -> Optional[int]:
    """The checks of a recorder's ``add_topic`` (McapRecorder, part_pipe.PartPipe): an
    absolute topic name, one type per topic. Returns the topic's id when it is already
    recorded, None for a new topic (refused when the recorder is closed)."""
    if not isinstance(topic, str) or not topic.startswith('/'):
        raise ValueError(f'topic must be an absolute name like "/a/b", got {topic!r}')
    if topic in ids:
        if types[topic] != type_name:
            raise ValueError(f'type_name: {topic} already recorded as {types[topic]}')
        return ids[topic]
    if closed:
        raise ValueError('recorder is closed')
    return None


class McapRecorder:
    """Writes messages of many topics into one MCAP file; thread safe; close() is idempotent.

    >>> rec = McapRecorder('bags/run.mcap')
    >>> rec.add_topic('/slave/force', 'geometry_msgs/msg/WrenchStamped',
    ...               [{'reliability': 'best_effort', 'depth': 1}])
    >>> rec.write('/slave/force', cdr_bytes, log_time_ns)
    >>> rec.close(status='complete')
    """

    def __init__(self, path, library: str = 'catheter_bringup recorder',
                 chunk_size: int = 1 << 20, compression: str = 'zstd'):
        path = pathlib.Path(path)
        if path.suffix != '.mcap':
            raise ValueError(f'path must end with .mcap, got {str(path)!r}')
        path.parent.mkdir(parents=True, exist_ok=True)
        self.path = path
        self._tmp = path  # written in place: a crash leaves a readable (unindexed) stream
        self._file = open(path, 'wb')
        comp = {'zstd': CompressionType.ZSTD, 'none': CompressionType.NONE,
                'lz4': CompressionType.LZ4}.get(compression)
        if comp is None:
            raise ValueError(f'compression must be zstd, lz4 or none, got {compression!r}')
        self._w = Writer(self._file, chunk_size=chunk_size, compression=comp)
        self._w.start(profile='ros2', library=library)
        #: mcap's add_message without its per-record builder calls (None: its own)
        self._add = fast_message_writer(self._w)
        self._schemas: Dict[str, int] = {}
        self._channels: Dict[str, int] = {}
        self._types: Dict[str, str] = {}
        self._classes: Dict[str, type] = {}
        self._seq: Dict[str, int] = {}
        self.counts: Dict[str, int] = {}
        self.bytes = 0
        self.first_time_ns: Optional[int] = None
        self.last_time_ns: Optional[int] = None
        self.closed = False
        self.status: Optional[str] = None
        self._lock = threading.Lock()

    def add_topic(self, topic: str, type_name: str, qos: Optional[List[Mapping]] = None) -> int:
        """Register a channel (once per topic); returns its id. ``qos``: offered profiles
        (dicts)."""
        with self._lock:
            known = known_channel(topic, type_name, self._channels, self._types, self.closed)
            if known is not None:
                return known
            cls = message_class(type_name)
            if type_name not in self._schemas:
                self._schemas[type_name] = self._w.register_schema(
                    name=type_name, encoding='ros2msg',
                    data=message_definition(type_name).encode())
            meta = {'offered_qos_profiles': qos_yaml(list(qos) if qos else [_DEFAULT_QOS])}
            cid = self._w.register_channel(topic=topic, message_encoding='cdr',
                                           schema_id=self._schemas[type_name], metadata=meta)
            self._channels[topic] = cid
            self._types[topic] = type_name
            self._classes[topic] = cls
            self._seq[topic] = 0
            self.counts[topic] = 0
            return cid

    def has_topic(self, topic: str) -> bool:
        return topic in self._channels

    def write(self, topic: str, data: bytes, log_time_ns: int,
              publish_time_ns: Optional[int] = None) -> None:
        """Append one CDR-serialised message of a registered topic at ``log_time_ns`` (int, ns).

        ``data``: the CDR payload (encapsulation header first); bytes beyond the message's
        end (rclpy's estimated-size padding) are cut off; a payload too short for its type,
        or not CDR, is refused (ValueError naming ``data``)."""
        if topic not in self._channels:
            raise ValueError(f'topic {topic!r} was not registered with add_topic')
        log_time_ns = int(log_time_ns)
        if log_time_ns < 0:
            raise ValueError(f'log_time_ns must be >= 0, got {log_time_ns}')
        end = cdr_end(data, self._classes[topic])
        data = bytes(data[:end])
        with self._lock:
            if self.closed:
                return
            seq = self._seq[topic]
            self._seq[topic] = seq + 1
            pub = log_time_ns if publish_time_ns is None else int(publish_time_ns)
            if self._add is not None:
                self._add(self._channels[topic], log_time_ns, pub, seq, data)
            else:
                self._w.add_message(channel_id=self._channels[topic], log_time=log_time_ns,
                                    publish_time=pub, sequence=seq, data=data)
            self.counts[topic] += 1
            self.bytes += len(data)
            if self.first_time_ns is None:
                self.first_time_ns = log_time_ns
            self.last_time_ns = log_time_ns if self.last_time_ns is None \
                else max(self.last_time_ns, log_time_ns)

    def start(self, info: Mapping[str, object]) -> None:
        """Write the ``catheter_run_start`` metadata record now (values as in `close`'s
        ``extra``) and flush it to the file, so a run killed before `close` still carries it."""
        meta = {'status': 'running'}
        for k, v in info.items():
            meta[str(k)] = v if isinstance(v, str) else json.dumps(v, sort_keys=True)
        with self._lock:
            if self.closed:
                raise ValueError('recorder is closed')
            self._w.add_metadata(RUN_START_METADATA, meta)
            self._file.flush()

    @property
    def total(self) -> int:
        return sum(self.counts.values())

    def close(self, status: str = 'complete', reason: str = '',
              extra: Optional[Mapping[str, object]] = None) -> None:
        """Write the ``catheter_run`` metadata record and the summary; close the file.

        ``status``: complete | interrupted | failed; ``reason``: free text (why it stopped);
        ``extra``: more string-able values (e.g. scenario name, sim time reached).
        """
        if status not in ('complete', 'interrupted', 'failed'):
            raise ValueError(f'status must be complete, interrupted or failed, got {status!r}')
        with self._lock:
            if self.closed:
                return
            self.closed = True
            self.status = status
            meta = {
                'status': status,
                'reason': str(reason),
                'messages': str(self.total),
                'first_log_time_ns': str(self.first_time_ns if self.first_time_ns is not None
                                         else -1),
                'last_log_time_ns': str(self.last_time_ns if self.last_time_ns is not None else -1),
                'counts': json.dumps(self.counts, sort_keys=True),
            }
            for k, v in (extra or {}).items():
                meta[str(k)] = v if isinstance(v, str) else json.dumps(v, sort_keys=True)
            self._w.add_metadata(RUN_METADATA, meta)
            self._w.finish()
            self._file.flush()
            os.fsync(self._file.fileno())
            self._file.close()

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        if exc_type is None:
            self.close('complete')
        elif issubclass(exc_type, KeyboardInterrupt):
            self.close('interrupted', 'KeyboardInterrupt')
        else:
            self.close('failed', repr(exc))
        return False


def read_run_metadata(path: str | os.PathLike) -> Dict[str, str]:
    """The ``catheter_run`` metadata record of a recording ({} if it has none)."""
    from mcap.reader import make_reader
    with open(path, 'rb') as f:
        reader = make_reader(f)
        for rec in reader.iter_metadata():
            if rec.name == RUN_METADATA:
                return dict(rec.metadata)
    return {}

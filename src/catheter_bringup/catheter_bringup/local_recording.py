"""Recording in the worker processes of the split layout (no rclpy).

In layout split every node runs in a worker process (master, slave, vision). Recording them
from the runner's process through DDS cost a DDS hop and a Python callback per message in a
process that competed with vision for a core, and lost most of the messages. Instead each
worker records what ITS nodes publish, locally: the bus (`catheter_bringup.bus.LocalBus`)
already serialises every publish once, and hands the bytes to ``LocalBus.record`` — the
worker's `catheter_bringup.part_pipe.PartPipe`, whose writer process writes them with the
wall-clock log time, as `PartRecorder` does, into a per-worker MCAP part file (``<bag
stem>.<process>.part.mcap`` next to the run's bag). At the end of the run the runner merges
the parts into the run's bag (`merge_parts`, after each part's writer has let go of it):
every message, in log-time order, with the parts' schemas and QoS, and deletes them.

A worker killed with SIGKILL: its writer closes the part (status interrupted). A part whose
writer was killed too has no summary (and maybe a cut-off chunk at its end): `read_part`
reads such a file as a stream up to the cut, so the merge keeps every message of its
complete chunks and reports the part as ``complete: False``. If the runner itself is killed
the parts stay next to the bag; each is a recording on its own (``recover_bag`` turns a
cut-off one into a readable file).
"""
from __future__ import annotations

import heapq
import pathlib
import time
from typing import Dict, Iterable, List, Mapping, Optional, Tuple

from catheter_bringup.recorder import McapRecorder

#: bytes, MCAP chunk size of the part files (as the real-time recordings: compressing one
#: chunk inside a publish takes a fraction of a 1 ms period)
PART_CHUNK = 64 * 1024
_QOS_KEYS = ('history', 'depth', 'reliability', 'durability')


def part_path(bag, process: str) -> str:
    """Where the worker ``process`` of the run recorded into ``bag`` writes its part."""
    p = pathlib.Path(bag)
    if not process or '/' in process:
        raise ValueError(f'process must be a plain name, got {process!r}')
    return str(p.with_name(f'{p.stem}.{process}.part.mcap'))


def wanted(topic: str, exclude: Iterable[str], only: Optional[Iterable[str]]) -> bool:
    """Whether a run records ``topic`` (its ``record`` section: exclude, only)."""
    if topic in set(exclude):
        return False
    return only is None or topic in set(only)


class PartRecorder:
    """The part file of one worker: `add_topic` for each publisher it records, then
    `record(topic, cdr_bytes)` from the bus for every publish (topics not added are
    ignored); `close` at the end of the worker's run."""

    def __init__(self, path, process: str, chunk_size: int = PART_CHUNK):
        self.recorder = McapRecorder(path, library=f'catheter_bringup part ({process})',
                                     chunk_size=chunk_size)
        self.topics = set()
        self.errors = 0
        self._clock = time.time_ns     # the system clock: what the nodes' clocks use

    @property
    def counts(self) -> Dict[str, int]:
        return dict(self.recorder.counts)

    def add_topic(self, topic: str, type_name: str, qos: Optional[List[Mapping]]) -> None:
        self.recorder.add_topic(topic, type_name, qos)
        self.topics.add(topic)

    def record(self, topic: str, data: bytes, log_time_ns: Optional[int] = None) -> None:
        """Write one publish (log time: now on the system clock, or ``log_time_ns``)."""
        if topic not in self.topics:
            return
        try:
            self.recorder.write(topic, data, self._clock() if log_time_ns is None
                                else log_time_ns)
        except ValueError:
            self.errors += 1         # a payload the recorder refuses: counted, not fatal

    def close(self, status: str, reason: str = '') -> None:
        self.recorder.close(status, reason, extra={'part_errors': self.errors})


def _qos_dicts(text: str) -> Optional[List[dict]]:
    import yaml
    try:
        profiles = yaml.safe_load(text) if text else None
    except yaml.YAMLError:
        return None
    if not isinstance(profiles, list):
        return None
    return [{k: p.get(k) for k in _QOS_KEYS} for p in profiles if isinstance(p, dict)]


def read_part(path) -> Tuple[Dict[str, tuple], List[tuple], dict]:
    """Read a part file as a stream (a complete file, or one cut off by a kill).

    Returns (channels: topic -> (type name, QoS dicts), messages: [(log time ns, sequence
    in the file, topic, data)] sorted by log time (stable), info: {'messages', 'complete',
    'stopped_at', 'status', 'reason'}: the last two from the part's catheter_run record, ''
    without one). ValueError naming ``path`` if it is not an MCAP file at all."""
    from mcap.records import Channel, DataEnd, Footer, Header, Message, Metadata, Schema
    from mcap.stream_reader import StreamReader
    schemas: Dict[int, str] = {}
    chans: Dict[int, str] = {}
    channels: Dict[str, tuple] = {}
    messages: List[tuple] = []
    complete, stopped, started, status, reason = False, '', False, '', ''

    with open(path, 'rb') as f:
        try:
            for rec in StreamReader(f, skip_magic=False, emit_chunks=False).records:
                if isinstance(rec, Header):
                    started = True
                elif isinstance(rec, Schema):
                    schemas[rec.id] = rec.name
                elif isinstance(rec, Channel):
                    if rec.topic not in channels and rec.schema_id in schemas:
                        channels[rec.topic] = (schemas[rec.schema_id], _qos_dicts(
                            rec.metadata.get('offered_qos_profiles', '')))
                    chans[rec.id] = rec.topic
                elif isinstance(rec, Message):
                    topic = chans.get(rec.channel_id)
                    if topic is not None:
                        messages.append((rec.log_time, len(messages), topic, rec.data))
                elif isinstance(rec, Metadata) and rec.name == 'catheter_run':
                    status = rec.metadata.get('status', '')
                    reason = rec.metadata.get('reason', '')
                elif isinstance(rec, (DataEnd, Footer)):
                    complete = True
        except Exception as exc:  # noqa: BLE001 - the cut of a killed worker's file
            stopped = type(exc).__name__
    if not started:
        raise ValueError(f'path: {path} is not an MCAP file (no header record)')
    messages.sort(key=lambda m: m[0])
    return channels, messages, {'messages': len(messages), 'complete': complete,
                                'stopped_at': stopped, 'status': status, 'reason': reason}


def merge_parts(recorder: McapRecorder, parts: Mapping[str, str],
                delete: bool = True) -> Dict[str, dict]:
    """Write every message of the part files (process name -> path) into ``recorder``, in
    log-time order across the parts (ties: in process-name order, then file order); the
    topics are registered with the parts' types and QoS. A missing part is reported, not
    fatal (a worker that failed before its recorder started). Returns per process what
    `read_part` says, plus 'error' for a part that could not be read. ``delete``: remove
    each part once merged."""
    info: Dict[str, dict] = {}
    streams = []
    from catheter_bringup.part_pipe import wait_written
    for k, (proc, path) in enumerate(sorted(parts.items())):
        wait_written(path)             # a killed worker's writer may still be closing it
        try:
            channels, messages, inf = read_part(path)
        except (OSError, ValueError) as exc:
            info[proc] = {'messages': 0, 'complete': False, 'error': f'{exc}'}
            continue
        for topic, (type_name, qos) in channels.items():
            recorder.add_topic(topic, type_name, qos)
        info[proc] = inf
        streams.append([(t, k, seq, topic, data) for t, seq, topic, data in messages])
    for t, _k, _seq, topic, data in heapq.merge(*streams):
        recorder.write(topic, data, t)
    if delete:
        for path in parts.values():
            pathlib.Path(path).unlink(missing_ok=True)
    return info

"""`catheter_topic`: watch a running graph and look into recordings (ros2cli is not installable
from PyPI; this covers what `ros2 topic` and `ros2 bag info` are used for here).

    catheter_topic list [-t] [--wait S]                 topics on DDS (with their types)
    catheter_topic echo TOPIC [--count N] [--timeout S] [--full]
    catheter_topic hz TOPIC [--duration S] [--window N] [--stamps]
    catheter_topic bw TOPIC [--duration S]
    catheter_topic info BAG                             topics, types, counts, duration

A lockstep run publishes on DDS only with ``run_scenario --dds`` (or ``dds: true``): its
messages then come in bursts of simulated time; ``hz --stamps`` measures the rate on the
messages' header stamps (the run's clock) instead of the arrival times (the wall clock).
Exit code 0, or 1 when nothing arrived / the topic is unknown, 2 for a bad bag file.
"""
from __future__ import annotations

import argparse
import math
import os
import statistics
import sys
import time
from typing import Any, Callable, Dict, List, Optional, Sequence

#: sequences longer than this are shown as their length in `echo` (unless --full)
SHOW_MAX = 16


class _Session:
    """A private rclpy context (`catheter_common.ros_testing.RosHarness`) with one node named
    catheter_topic."""

    def __init__(self):
        from catheter_common.ros_testing import RosHarness
        self.harness = RosHarness()
        self.node = self.harness.node('catheter_topic')

    def spin_for(self, seconds: float, until: Callable[[], bool] = lambda: False) -> None:
        self.harness.spin_until(until, timeout=seconds)

    def topic_type(self, topic: str, wait: float) -> Optional[str]:
        """The type of ``topic`` once it is in the graph (None after ``wait`` s)."""
        found: Dict[str, list] = {}

        def seen():
            found.update(dict(self.node.get_topic_names_and_types()))
            return bool(found.get(topic))
        self.spin_for(wait, seen)
        types = found.get(topic)
        return types[0] if types else None

    def subscribe(self, topic: str, type_name: str, callback: Callable[[Any], None],
                  raw: bool) -> Any:
        """Best effort, volatile, keep last 1000: compatible with every publisher, also one
        discovered after this subscription (choosing from the publishers seen so far picked
        reliable when the topic was known only through a subscriber, and a best-effort
        publisher found a moment later was refused as incompatible)."""
        from catheter_bringup.cdr import message_class
        from catheter_common.qos import QOS_OBSERVE
        return self.node.create_subscription(message_class(type_name), topic, callback,
                                             QOS_OBSERVE, raw=raw)

    def close(self) -> None:
        self.harness.close()


def to_yaml(msg: Any, full: bool = False, indent: str = '') -> List[str]:
    """A message as YAML-like lines (field: value; nested messages indented; long sequences
    as their length unless ``full``)."""
    lines = []
    for name in msg.get_fields_and_field_types():
        value = getattr(msg, name)
        if hasattr(value, 'get_fields_and_field_types'):
            lines.append(f'{indent}{name}:')
            lines += to_yaml(value, full, indent + '  ')
            continue
        if isinstance(value, (bytes, bytearray)) and len(value) == 1:
            value = value[0]
        if not isinstance(value, (str, bytes)) and hasattr(value, '__len__'):
            seq = list(value)
            if not full and len(seq) > SHOW_MAX:
                lines.append(f"{indent}{name}: '<sequence of {len(seq)} values>'")
            elif seq and hasattr(seq[0], 'get_fields_and_field_types'):
                lines.append(f'{indent}{name}:')
                for item in seq:
                    sub = to_yaml(item, full, indent + '  ')
                    lines.append(f'{indent}- {sub[0].strip()}')
                    lines += [f'{indent}  {line[len(indent) + 2:]}' for line in sub[1:]]
            else:
                lines.append(f'{indent}{name}: {[_scalar(v) for v in seq]}')
            continue
        if isinstance(value, bool):                  # YAML's spelling, as ros2 topic echo
            lines.append(f'{indent}{name}: {"true" if value else "false"}')
            continue
        lines.append(f'{indent}{name}: {_scalar(value)!r}' if isinstance(value, str)
                     else f'{indent}{name}: {_scalar(value)}')
    return lines


def _scalar(v):
    if isinstance(v, float):
        return float(f'{v:.9g}') if math.isfinite(v) else v
    return v


def _topic_type(s: '_Session', a) -> Optional[str]:
    """The type of ``a.topic`` once it is in the graph, or None (said on stderr) after
    ``a.timeout`` s."""
    type_name = s.topic_type(a.topic, a.timeout)
    if type_name is None:
        print(f'catheter_topic: {a.topic}: no such topic in the graph after {a.timeout:g} s',
              file=sys.stderr)
    return type_name


def cmd_list(a: argparse.Namespace) -> int:
    s = _Session()
    try:
        s.spin_for(a.wait)
        for topic, types in sorted(s.node.get_topic_names_and_types()):
            print(f'{topic} [{", ".join(types)}]' if a.show_types else topic)
    finally:
        s.close()
    return 0


def cmd_echo(a: argparse.Namespace) -> int:
    s = _Session()
    try:
        type_name = _topic_type(s, a)
        if type_name is None:
            return 1
        got = []

        def cb(msg):
            got.append(msg)
            print('\n'.join(to_yaml(msg, a.full)) + '\n---', flush=True)
        s.subscribe(a.topic, type_name, cb, raw=False)
        s.spin_for(a.timeout, lambda: a.count and len(got) >= a.count)
        if not got:
            print(f'catheter_topic: no message on {a.topic} in {a.timeout:g} s',
                  file=sys.stderr)
            return 1
    finally:
        s.close()
    return 0


def rate_stats(times: List[float]) -> Dict[str, float]:
    """Rate (Hz) and period min / max / std (s) of arrival or stamp times (s)."""
    if len(times) < 2:
        return {'rate_hz': math.nan, 'min': math.nan, 'max': math.nan, 'std': math.nan, 'n': 0}
    d = [b - a for a, b in zip(times[:-1], times[1:], strict=True)]
    mean = sum(d) / len(d)
    return {'rate_hz': 1.0 / mean if mean > 0 else math.inf, 'min': min(d), 'max': max(d),
            'std': statistics.pstdev(d), 'n': len(d)}


def cmd_hz(a: argparse.Namespace) -> int:
    s = _Session()
    try:
        type_name = _topic_type(s, a)
        if type_name is None:
            return 1
        times: List[float] = []
        if a.stamps:
            from catheter_bringup.cdr import message_class
            from catheter_bringup.recording import raw_stamp
            first = message_class(type_name).SLOT_TYPES[0]
            if tuple(getattr(first, 'namespaced_name', tuple)()) != ('std_msgs', 'msg', 'Header'):
                print(f'catheter_topic: {a.topic} ({type_name}) has no header stamp',
                      file=sys.stderr)
                return 1

        def cb(data):
            t = raw_stamp(data) if a.stamps else time.monotonic()
            if t is not None:
                times.append(t)
        s.subscribe(a.topic, type_name, cb, raw=True)
        end = time.monotonic() + a.duration
        reports = 0
        while time.monotonic() < end:
            s.spin_for(min(1.0, end - time.monotonic()))
            window = sorted(times)[-a.window:] if a.stamps else times[-a.window:]
            st = rate_stats(window)
            if st['n']:
                reports += 1
                print(f"average rate: {st['rate_hz']:.3f} Hz"
                      f"{' (header stamps)' if a.stamps else ''}\n"
                      f"\tmin: {st['min'] * 1e3:.3f} ms max: {st['max'] * 1e3:.3f} ms "
                      f"std dev: {st['std'] * 1e3:.5f} ms window: {st['n'] + 1}", flush=True)
        if not reports:
            print(f'catheter_topic: fewer than 2 messages on {a.topic} in {a.duration:g} s',
                  file=sys.stderr)
            return 1
    finally:
        s.close()
    return 0


def cmd_bw(a: argparse.Namespace) -> int:
    s = _Session()
    try:
        type_name = _topic_type(s, a)
        if type_name is None:
            return 1
        sizes: List[tuple] = []
        s.subscribe(a.topic, type_name, lambda d: sizes.append((time.monotonic(), len(d))),
                    raw=True)
        t0 = time.monotonic()
        end = t0 + a.duration
        reports = 0
        while time.monotonic() < end:
            s.spin_for(min(1.0, end - time.monotonic()))
            if sizes:
                span = max(time.monotonic() - t0, 1e-9)
                total = sum(n for _, n in sizes)
                reports += 1
                print(f'{total / span / 1024:.2f} KB/s from {len(sizes)} messages\n'
                      f'\tmean: {total / len(sizes):.0f} B min: {min(n for _, n in sizes)} B '
                      f'max: {max(n for _, n in sizes)} B', flush=True)
        if not reports:
            print(f'catheter_topic: no message on {a.topic} in {a.duration:g} s',
                  file=sys.stderr)
            return 1
    finally:
        s.close()
    return 0


def bag_info(path: str | os.PathLike) -> dict:
    """What a recording holds: per topic type, count and QoS reliability; duration, start and
    end (s of its clock), size; the run's status and scenario when it has them."""
    import json
    from mcap.reader import make_reader
    from catheter_bringup.bagfile import check_bag
    from catheter_bringup.recorder import read_run_metadata
    check_bag(path)
    with open(path, 'rb') as f:
        summary = make_reader(f).get_summary()
    st = summary.statistics
    counts = dict(st.channel_message_counts) if st else {}
    topics = {}
    for cid, ch in summary.channels.items():
        schema = summary.schemas.get(ch.schema_id)
        qos = ch.metadata.get('offered_qos_profiles', '')
        topics[ch.topic] = {'type': schema.name if schema else '?', 'count': counts.get(cid, 0),
                            'qos': 'best_effort' if 'best_effort' in qos else
                            ('reliable' if qos else '-')}
    meta = read_run_metadata(path)
    start = st.message_start_time * 1e-9 if st else math.nan
    end = st.message_end_time * 1e-9 if st else math.nan
    import pathlib
    return {'path': str(path), 'size_bytes': pathlib.Path(path).stat().st_size,
            'messages': st.message_count if st else 0, 'start_s': start, 'end_s': end,
            'duration_s': end - start, 'topics': topics,
            'status': meta.get('status', ''), 'reason': meta.get('reason', ''),
            'scenario': meta.get('scenario', ''),
            'nodes': json.loads(meta['nodes']) if meta.get('nodes') else []}


def format_info(info: dict) -> str:
    lines = [f"Files:             {info['path']}",
             f"Bag size:          {info['size_bytes'] / 1e6:.2f} MB",
             "Storage id:        mcap",
             f"Duration:          {info['duration_s']:.3f} s",
             f"Start:             {info['start_s']:.3f} s",
             f"End:               {info['end_s']:.3f} s",
             f"Messages:          {info['messages']}",
             f"Run:               {info['scenario'] or '-'} ({info['status'] or 'no run metadata'}"
             f"{': ' + info['reason'] if info['reason'] else ''})"]
    if info['nodes']:
        lines.append(f"Nodes:             {', '.join(info['nodes'])}")
    lines.append('Topic information:')
    width = max((len(t) for t in info['topics']), default=5)
    for topic, t in sorted(info['topics'].items()):
        lines.append(f"  {topic:<{width}}  {t['type']:<42} {t['count']:>8} msgs  {t['qos']}")
    return '\n'.join(lines)


def cmd_info(a: argparse.Namespace) -> int:
    from catheter_bringup.bagfile import cli_errors
    return cli_errors('catheter_topic info', lambda: print(format_info(bag_info(a.bag))) or 0)


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog='catheter_topic', description=__doc__.split('\n\n')[0])
    sub = ap.add_subparsers(dest='command', required=True)
    p = sub.add_parser('list', help='topics on DDS')
    p.add_argument('-t', '--show-types', action='store_true')
    p.add_argument('--wait', type=float, default=2.0, help='discovery time, s')
    p.set_defaults(func=cmd_list)
    p = sub.add_parser('echo', help='print the messages of a topic')
    p.add_argument('topic')
    p.add_argument('--count', type=int, default=0, help='stop after N messages (0: timeout)')
    p.add_argument('--timeout', type=float, default=10.0, help='s')
    p.add_argument('--full', action='store_true', help='print long sequences in full')
    p.set_defaults(func=cmd_echo)
    p = sub.add_parser('hz', help='rate of a topic')
    p.add_argument('topic')
    p.add_argument('--duration', type=float, default=5.0, help='s')
    p.add_argument('--window', type=int, default=10000, help='last N messages')
    p.add_argument('--timeout', type=float, default=10.0, help='wait for the topic, s')
    p.add_argument('--stamps', action='store_true',
                   help='rate of the header stamps (the run\'s clock) instead of arrivals')
    p.set_defaults(func=cmd_hz)
    p = sub.add_parser('bw', help='bandwidth of a topic')
    p.add_argument('topic')
    p.add_argument('--duration', type=float, default=5.0, help='s')
    p.add_argument('--timeout', type=float, default=10.0, help='wait for the topic, s')
    p.set_defaults(func=cmd_bw)
    p = sub.add_parser('info', help='what a recording (.mcap) holds')
    p.add_argument('bag')
    p.set_defaults(func=cmd_info)
    return ap


def main(argv: Optional[Sequence[str]] = None) -> int:
    from catheter_bringup.rclpy_adapter import without_ros_args
    a = build_parser().parse_args(without_ros_args(sys.argv[1:] if argv is None else argv))
    try:
        return a.func(a)
    except KeyboardInterrupt:
        return 0


if __name__ == '__main__':
    sys.exit(main())

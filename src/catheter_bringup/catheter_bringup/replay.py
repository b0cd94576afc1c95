"""`replay`: republish a recording on its topics at the recorded rate (or scaled), with /clock.

    python -m catheter_bringup.replay bags/experiment_ii.mcap [--rate 2.0] [--topics /slave/force
    ...]
                                      [--no-clock] [--loop] [--start S] [--ros-args ...]

Each topic gets a publisher with the QoS recorded in the channel metadata; messages go out as the
recorded CDR bytes (no deserialisation), paced by the recorded log times divided by ``rate``
(wall-clock pacing on a steady clock). /clock carries the recorded time, so nodes started with
``use_sim_time:=true`` run on the recording's clock. The node is named ``replay``.
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from typing import Callable, Iterable, Optional, Sequence, TYPE_CHECKING

from catheter_bringup.bagfile import check_bag, cli_errors, read_messages
from catheter_bringup.recorder import read_run_metadata
from catheter_common import topics as T

if TYPE_CHECKING:
    from rclpy.context import Context
    from rclpy.node import Node


def _qos_from_metadata(meta: dict):
    from rclpy.qos import (QoSDurabilityPolicy, QoSHistoryPolicy, QoSProfile,
                           QoSReliabilityPolicy)
    import yaml
    prof = QoSProfile(depth=10)
    text = meta.get('offered_qos_profiles', '')
    try:
        items = yaml.safe_load(text) if text else []
    except yaml.YAMLError:
        items = []
    if items:
        q = items[0]
        if str(q.get('reliability', '')).lower() in ('best_effort', '2'):
            prof.reliability = QoSReliabilityPolicy.BEST_EFFORT
        if str(q.get('durability', '')).lower() in ('transient_local', '1'):
            prof.durability = QoSDurabilityPolicy.TRANSIENT_LOCAL
        depth = int(q.get('depth', 10) or 10)
        prof.history = QoSHistoryPolicy.KEEP_LAST
        prof.depth = max(depth, 1)
    return prof


def replay(path: str | os.PathLike, rate: float = 1.0, topics: Optional[Iterable[str]] = None,
           clock: bool = True, context: Optional[Context] = None, start: float = 0.0,
           loop: bool = False, node: Optional[Node] = None,
           should_stop: Callable[[], bool] = lambda: False) -> dict:
    """Republish ``path``; returns {'published': {topic: n}, 'wall_time': s}.

    ``rate``: speed factor (> 0); ``start``: seconds of the recording skipped;
    ``node``: an existing rclpy node to publish from (else one named 'replay' is created).
    The chunks' CRCs are checked as they are read: a damaged chunk stops the replay with a
    one-line BagError at that chunk (what came before it was published), never publishes
    other values.
    """
    import rclpy
    from rclpy.qos import QoSProfile
    from rosgraph_msgs.msg import Clock

    from catheter_bringup.ros_recording import message_class

    check_bag(path)
    if not rate > 0:
        raise ValueError(f'rate must be > 0, got {rate!r}')
    if not start >= 0:
        raise ValueError(f'start must be >= 0, got {start!r}')
    own = node is None
    if own:
        node = rclpy.create_node('replay', context=context)
    pubs = {}
    published = {}
    clock_pub = node.create_publisher(Clock, T.CLOCK, QoSProfile(depth=10)) if clock else None
    want = set(topics) if topics else None
    t_wall0 = time.perf_counter()
    try:
        while True:
            first = None
            start_wall = time.perf_counter()
            last_clock = None
            for schema, channel, message in read_messages(path, want):
                if should_stop():
                    return {'published': published, 'wall_time': time.perf_counter() - t_wall0}
                topic = channel.topic
                if first is None:
                    first = message.log_time + int(start * 1e9)
                if message.log_time < first:
                    continue
                due = (message.log_time - first) * 1e-9 / rate
                while True:
                    wait = due - (time.perf_counter() - start_wall)
                    if wait <= 0:
                        break
                    time.sleep(min(wait, 0.05))
                    if should_stop():
                        return {'published': published,
                                'wall_time': time.perf_counter() - t_wall0}
                if topic not in pubs:
                    cls = message_class(schema.name)
                    pubs[topic] = node.create_publisher(cls, topic,
                                                        _qos_from_metadata(channel.metadata))
                    published[topic] = 0
                if clock_pub is not None and message.log_time != last_clock:
                    c = Clock()
                    c.clock.sec = message.log_time // 1_000_000_000
                    c.clock.nanosec = message.log_time % 1_000_000_000
                    clock_pub.publish(c)
                    last_clock = message.log_time
                pubs[topic].publish(bytes(message.data))
                published[topic] += 1
            if not loop:
                break
    finally:
        if own:
            node.destroy_node()
    return {'published': published, 'wall_time': time.perf_counter() - t_wall0}


def main(argv: Optional[Sequence[str]] = None) -> int:
    import rclpy
    from catheter_bringup.rclpy_adapter import without_ros_args
    args = list(sys.argv[1:] if argv is None else argv)
    ap = argparse.ArgumentParser(prog='replay', description=__doc__.split('\n\n')[0])
    ap.add_argument('bag')
    ap.add_argument('--rate', type=float, default=1.0, help='speed factor (2 = twice as fast)')
    ap.add_argument('--topics', nargs='*', default=None)
    ap.add_argument('--no-clock', action='store_true')
    ap.add_argument('--loop', action='store_true')
    ap.add_argument('--start', type=float, default=0.0, help='skip the first S seconds')
    a = ap.parse_args(without_ros_args(args))

    def body():
        check_bag(a.bag)
        meta = read_run_metadata(a.bag)
        rclpy.init(args=['replay'] + args)
        try:
            print(f"replaying {a.bag} ({meta.get('scenario', '?')}, {meta.get('messages', '?')} "
                  f"messages) at {a.rate:g}x", flush=True)
            res = replay(a.bag, rate=a.rate, topics=a.topics, clock=not a.no_clock,
                         loop=a.loop, start=a.start)
            n = sum(res['published'].values())
            print(f"published {n} messages on {len(res['published'])} topics in "
                  f"{res['wall_time']:.2f} s", flush=True)
        except KeyboardInterrupt:
            pass
        finally:
            rclpy.try_shutdown()
        return 0
    return cli_errors('replay', body)


if __name__ == '__main__':
    sys.exit(main())

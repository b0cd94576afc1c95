"""ROS side of the recorder: raw subscriptions that feed a `McapRecorder`.

`RecordingSink` attaches to any node (the runner's supervisor node, or `RecorderNode`), subscribes
raw (no deserialisation) to the topics it is given or discovers, and writes each message with the
node clock's time (sim time in lockstep runs).
"""
from __future__ import annotations

from typing import Any, Dict, Iterable, List, Optional

from rclpy.node import Node
from rclpy.qos import (QoSDurabilityPolicy, QoSHistoryPolicy, QoSProfile,
                       QoSReliabilityPolicy)

from catheter_bringup.cdr import exact_cdr, message_class, type_name_of  # noqa: F401
from catheter_bringup.recorder import McapRecorder


def exact_bytes(msg: Any) -> bytes:
    """The CDR payload of ``msg`` with its true length: what a DDS subscriber receives and
    what strict readers (rosbags) accept. ``rclpy.serialization.serialize_message`` alone
    returns the rmw's estimated size, with trailing garbage for messages with sequences."""
    from rclpy.serialization import serialize_message
    return exact_cdr(serialize_message(msg), type(msg))


def qos_to_dict(qos: QoSProfile) -> dict:
    return {
        'history': 'keep_all' if qos.history == QoSHistoryPolicy.KEEP_ALL else 'keep_last',
        'depth': int(qos.depth),
        'reliability': 'best_effort' if qos.reliability == QoSReliabilityPolicy.BEST_EFFORT
        else 'reliable',
        'durability': 'transient_local' if qos.durability == QoSDurabilityPolicy.TRANSIENT_LOCAL
        else 'volatile',
    }


def recording_qos(offered: Iterable[QoSProfile]) -> QoSProfile:
    """A subscription QoS compatible with every offered profile, deep enough not to lose data
    while the executor is busy: best effort if any publisher is best effort."""
    offered = list(offered)
    best_effort = any(q.reliability == QoSReliabilityPolicy.BEST_EFFORT for q in offered)
    return QoSProfile(history=QoSHistoryPolicy.KEEP_LAST, depth=1000,
                      reliability=QoSReliabilityPolicy.BEST_EFFORT if best_effort
                      else QoSReliabilityPolicy.RELIABLE,
                      durability=QoSDurabilityPolicy.VOLATILE)


class RecordingSink:
    """Raw subscriptions of ``node`` writing into ``recorder``.

    ``add(topic, type_name, offered_qos)`` subscribes one topic; ``discover()`` subscribes every
    topic in the graph not yet recorded (except ``exclude``). ``received`` counts per topic.
    """

    def __init__(self, node: Node, recorder: McapRecorder, exclude: Iterable[str] = (),
                 only: Optional[Iterable[str]] = None):
        self.node = node
        self.recorder = recorder
        self.exclude = set(exclude)
        self.only = set(only) if only else None
        self.subs: Dict[str, object] = {}
        self.received: Dict[str, int] = {}
        self.errors = 0
        #: optional callable giving the log time in ns (the runner's lockstep time)
        self.now_ns = None
        #: lockstep: hold a step's messages and write them at flush(), ordered by topic (the
        #: arrival order across topics within a step depends on delivery timing)
        self.buffered = False
        self._buffer = []

    def wants(self, topic: str) -> bool:
        if topic in self.exclude or topic in self.subs:
            return False
        if self.only is not None and topic not in self.only:
            return False
        return True

    def add(self, topic: str, type_name: str, offered: Optional[List[QoSProfile]] = None) -> bool:
        if not self.wants(topic):
            return False
        offered = list(offered or [])
        qos_dicts = [qos_to_dict(q) for q in offered] or None
        self.recorder.add_topic(topic, type_name, qos_dicts)
        cls = message_class(type_name)
        self.received[topic] = 0
        clock = self.node.get_clock()
        rec = self.recorder

        def cb(data, topic=topic):
            self.received[topic] += 1
            try:
                t = self.now_ns() if self.now_ns is not None else clock.now().nanoseconds
                if self.buffered:
                    self._buffer.append((topic, t, data))
                else:
                    rec.write(topic, data, t)
            except Exception as exc:  # noqa: BLE001 - keep recording the rest
                self.errors += 1
                self.node.get_logger().error(f'recorder: {topic}: {exc!r}',
                                             throttle_duration_sec=1.0)

        self.subs[topic] = self.node.create_subscription(
            cls, topic, cb, recording_qos(offered), raw=True)
        return True

    def flush(self) -> None:
        """Write the buffered messages, grouped by topic (stable within a topic)."""
        if not self._buffer:
            return
        buf, self._buffer = self._buffer, []
        buf.sort(key=lambda m: m[0])
        for topic, t, data in buf:
            try:
                self.recorder.write(topic, data, t)
            except Exception as exc:  # noqa: BLE001
                self.errors += 1
                self.node.get_logger().error(f'recorder: {topic}: {exc!r}',
                                             throttle_duration_sec=1.0)

    def discover(self) -> List[str]:
        """Subscribe to topics that appeared in the graph since the last call; returns them."""
        new = []
        for topic, types in self.node.get_topic_names_and_types():
            if not types or not self.wants(topic):
                continue
            infos = self.node.get_publishers_info_by_topic(topic)
            if not infos:
                continue
            if self.node.get_name() in {i.node_name for i in infos} and len(infos) == 1:
                continue  # only our own publisher (e.g. /clock when not recorded)
            try:
                if self.add(topic, types[0], [i.qos_profile for i in infos]):
                    new.append(topic)
            except (ValueError, ImportError, AttributeError) as exc:
                self.exclude.add(topic)
                self.node.get_logger().warning(f'recorder: cannot record {topic}: {exc}')
        return new

    def destroy(self) -> None:
        for sub in self.subs.values():
            try:
                self.node.destroy_subscription(sub)
            except Exception:  # noqa: BLE001
                pass
        self.subs.clear()

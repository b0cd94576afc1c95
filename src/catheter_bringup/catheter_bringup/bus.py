"""How messages move between the nodes of a run, and what was counted on the way.

`LocalBus`: the in-process transport of lockstep (and local real-time) runs. `PublishCounter`
and `DeliveryTracker`: counts of what the nodes published and took when DDS is the
transport. `CallbackCost`: wall time per node spent in callbacks. The rclpy internals they
need are in `catheter_bringup.rclpy_adapter`.
"""
from __future__ import annotations

import collections
import time
from typing import Callable, Dict, List, Optional

from catheter_bringup.rclpy_adapter import intercept_publish, take_callback, wrap_callback


class PublishCounter:
    """Counts what every publisher of the given nodes published (per topic), by intercepting
    each publisher's ``publish`` once."""

    def __init__(self):
        self.counts: Dict[str, int] = {}
        self._wrapped = set()
        self.on_publish: Optional[Callable[[str], None]] = None

    def wrap_node(self, node) -> List[object]:
        new = []
        for pub in list(node.publishers):
            if id(pub) in self._wrapped:
                continue
            self._wrapped.add(id(pub))
            topic = pub.topic_name
            self.counts.setdefault(topic, 0)
            orig = pub.publish

            def publish(msg, _orig=orig, _topic=topic, _counts=self.counts):
                _orig(msg)
                _counts[_topic] += 1

            intercept_publish(pub, publish)
            new.append(pub)
        return new


class CallbackCost:
    """Wall time spent in each node's callbacks (timers and deliveries), s."""

    def __init__(self):
        self.samples: Dict[str, list] = {}

    def add(self, node: str, dt: float) -> None:
        self.samples.setdefault(node, []).append(dt)

    def summary(self, wall: float) -> Dict[str, dict]:
        import numpy as np
        out = {}
        for node, xs in sorted(self.samples.items()):
            a = np.asarray(xs)
            out[node] = {'callbacks': int(a.size), 'mean_ms': float(a.mean() * 1e3),
                         'p99_ms': float(np.percentile(a, 99) * 1e3),
                         'max_ms': float(a.max() * 1e3), 'total_s': float(a.sum()),
                         'share': float(a.sum() / wall) if wall > 0 else float('nan')}
        return out


def _drop(*_args):
    """Callback of a DDS delivery that the lockstep bus already delivered."""


class LocalBus:
    """Lockstep transport between the runner's nodes: every publish is serialised once, counted
    and queued; `deliver_all` hands each queued message, in publish order, to every in-process
    subscription of its topic (raw subscriptions get the bytes, the others a fresh deserialised
    copy). Deterministic and without DDS delivery latency. The nodes' own DDS subscriptions
    stay (subscription counts, "work only while subscribed" keep working) but what DDS delivers
    to them is dropped. With ``dds=True`` every message is also published on DDS, for tools
    outside the process."""

    def __init__(self, dds: bool = False):
        self.queue = collections.deque()
        self.counts: Dict[str, int] = {}
        self.delivered = 0
        self.dds = dds
        self.subs: Dict[str, list] = {}
        self.cost = CallbackCost()
        #: topics also published on DDS (their subscribers run in another process)
        self.dds_topics = set()
        #: ids of subscriptions left to DDS (no publisher of their topic in this process)
        self.external = set()
        self._pubs = set()
        self._subs = set()

    def wrap_node(self, node, publishers: bool = True) -> None:
        if publishers:
            self.wrap_publishers(node)
        self.wrap_subscriptions(node)

    def wrap_publishers(self, node) -> None:
        from rclpy.serialization import serialize_message
        for pub in list(node.publishers):
            if id(pub) in self._pubs:
                continue
            self._pubs.add(id(pub))
            topic = pub.topic_name
            self.counts.setdefault(topic, 0)
            orig = pub.publish

            def publish(msg, _orig=orig, _topic=topic, bus=self):
                data = msg if isinstance(msg, bytes) else serialize_message(msg)
                if bus.dds or _topic in bus.dds_topics:
                    _orig(msg)
                bus.counts[_topic] += 1
                bus.queue.append((_topic, data))

            intercept_publish(pub, publish)

    def wrap_subscriptions(self, node) -> None:
        for sub in list(node.subscriptions):
            if id(sub) in self._subs:
                continue
            if sub.topic_name not in self.counts:
                # nobody in this process publishes it (yet): DDS delivers it, the runner spins
                # the executor for it
                self.external.add(id(sub))
                continue
            self.external.discard(id(sub))
            self._subs.add(id(sub))
            cb, with_info = take_callback(sub, _drop)
            self.subs.setdefault(sub.topic_name, []).append(
                (cb, bool(sub.raw), sub.msg_type, with_info, node.get_name()))

    def deliver_all(self) -> int:
        from rclpy.serialization import deserialize_message
        n = 0
        q = self.queue
        clock = time.perf_counter
        cost = self.cost
        while q:
            topic, data = q.popleft()
            for cb, raw, msg_type, with_info, owner in self.subs.get(topic, ()):
                t = clock()
                msg = data if raw else deserialize_message(data, msg_type)
                if with_info:
                    cb(msg, {})
                else:
                    cb(msg)
                cost.add(owner, clock() - t)
                n += 1
        self.delivered += n
        return n


class DeliveryTracker:
    """Counts what every subscription of the given nodes took, to know when every message
    published in this process has been handled (lockstep drain through DDS)."""

    def __init__(self, published: Dict[str, int]):
        self.published = published
        self.subs: List[list] = []          # [subscription, topic, base, taken]
        self._wrapped = set()

    def wrap_node(self, node) -> None:
        for sub in list(node.subscriptions):
            if id(sub) in self._wrapped:
                continue
            self._wrapped.add(id(sub))
            entry = [sub, sub.topic_name, self.published.get(sub.topic_name, 0), 0]
            self.subs.append(entry)

            def counting(orig, _e=entry):
                def callback(*args):
                    _e[3] += 1
                    return orig(*args)
                return callback

            wrap_callback(sub, counting)

    def pending(self) -> int:
        """Messages published in this process that some subscription has not taken yet."""
        n = 0
        for _sub, topic, base, taken in self.subs:
            p = self.published.get(topic)
            if p is not None and p - base > taken:
                n += p - base - taken
        return n

"""How messages move between the nodes of a run, and what was counted on the way.

`LocalBus`: the in-process transport of lockstep (and local real-time) runs. `PublishCounter`
and `DeliveryTracker`: counts of what the nodes published and took when DDS is the
transport. `CallbackCost`: wall time per node spent in callbacks. The rclpy internals they
need are in `catheter_bringup.rclpy_adapter`.
"""
from __future__ import annotations

import array
import collections
import time
from typing import Callable, Dict, List, Optional, Tuple

from catheter_bringup.cdr_decode import decoder
from catheter_bringup.msg_copy import message_copier
from catheter_bringup.rclpy_adapter import (intercept_publish, serializer, set_raw,
                                            take_callback, watch_message_lost, wrap_callback)


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


def _stamp_ns(msg) -> Optional[int]:
    """The header stamp of a message in ns (None: no header, or raw bytes)."""
    st = getattr(getattr(msg, 'header', None), 'stamp', None)
    return None if st is None else st.sec * 1_000_000_000 + st.nanosec


_UNSEEN = object()


def _drop(*_args):
    """Callback of a DDS delivery that the lockstep bus already delivered."""


class LocalBus:
    """Lockstep transport between the runner's nodes: every publish is serialised once (by the
    type's generated encoder, `catheter_bringup.cdr_encode`, where it covers the type),
    counted and queued; `deliver_all` hands each queued message, in publish order, to every
    in-process subscription of its topic (raw subscriptions get the bytes, the others one
    message, shared: subscribers must not modify what they receive, as in rclcpp's
    intra-process delivery; the message is a copy of the published one made at publish,
    `msg_copy.message_copier`, equal to the deserialised bytes, or the bytes
    deserialised where the copier refuses it). Deterministic and without DDS delivery
    latency. The nodes' own
    DDS subscriptions stay (subscription counts, "work only while subscribed" keep working)
    but what DDS delivers to them is dropped (cheaply: they are switched to raw, so nothing is
    deserialised for them). With ``dds=True`` every message is also published on DDS, for
    tools outside the process.

    ``immediate=True`` (real time driven by an executor): what a callback run through `timed`
    (a timer, or a delivery from DDS) publishes is delivered as soon as it returns, in publish
    order, before the executor runs anything else: its publishes go out back to back, not
    each after its subscribers' work (the slave's force waited for the identifier's update of
    the joint state published before it), and the subscribers see the messages in the order
    lockstep delivers them (after the timer). A publish outside such a callback delivers at
    once, in the publisher's call; a publish made by a subscriber during delivery is queued
    and delivered by the same loop, in order. What DDS delivers to subscriptions outside the
    bus is counted per topic in ``received``."""

    def __init__(self, dds: bool = False, immediate: bool = False):
        self.queue = collections.deque()
        self.immediate = immediate
        self._delivering = False
        #: immediate: inside a callback run by `timed` (its publishes wait until it returns)
        self._holding = False
        #: s spent delivering in total (callers subtract it from a timer's own time)
        self.delivery_s = 0.0
        #: per topic: messages DDS delivered to this process's subscriptions outside the bus
        self.received: Dict[str, int] = {}
        #: per topic taken from DDS (`external`): the samples DDS itself reported lost (a gap
        #: in what the reader received: transport or sender), summed over the subscriptions;
        #: a sample a subscription's own queue dropped is not in it
        self.dds_lost: Dict[str, int] = {}
        self._dds_lost_by_sub: Dict[int, Tuple[str, int]] = {}
        self._counted = set()
        #: one deserialised message shared by all subscribers of a publish (as rclcpp hands
        #: a const shared message to its intra-process subscribers: they must not modify
        #: it); False: a fresh copy each
        self.share = True
        #: subscribers get a copy of the published message made at publish
        #: (`msg_copy.message_copier`) instead of deserialising its bytes (lockstep and
        #: the workers alike; False: deserialised, the reference of the tests)
        self.copy = True
        #: topics with a subscriber in this process that takes messages (not raw bytes)
        self.msg_topics = set()
        #: real time: per topic, the wall times (perf_counter s) of its publishes (None: off)
        self.times: Optional[Dict[str, array.array]] = None
        #: real time: topics whose publish also notes (now - header stamp), s, in `latency`
        self.latency_topics = set()
        self.latency: Dict[str, array.array] = {}
        self.wall_ns: Optional[Callable[[], int]] = None
        #: real time: topics whose header stamps (ns) are noted as published (`sent`) and as
        #: taken from DDS (`taken`), to count what DDS lost between processes
        self.stamp_topics = set()
        self.sent: Dict[str, array.array] = {}
        self.taken: Dict[str, array.array] = {}
        self.counts: Dict[str, int] = {}
        self.delivered = 0
        self.dds = dds
        #: a worker of the split layout: called with (topic, cdr bytes) for every publish,
        #: to record it in the process (`catheter_bringup.local_recording`); None: off
        self.record: Optional[Callable[[str, bytes], None]] = None
        self.subs: Dict[str, list] = {}
        self.cost = CallbackCost()
        #: topics also published on DDS (their subscribers run in another process)
        self.dds_topics = set()
        #: ids of subscriptions left to DDS (no publisher of their topic in this process)
        self.external = set()
        self._pubs = set()
        self._subs = set()
        #: immediate: subscriptions left to DDS are taken raw and decoded by the bus
        #: (`cdr_decode`) where the type has a decoder
        self.decode_dds = True
        #: per message class: its generated CDR decoder (`cdr_decode`; None: rclpy's)
        self._decoders: Dict[type, Optional[Callable]] = {}

    def wrap_node(self, node, publishers: bool = True) -> None:
        if publishers:
            self.wrap_publishers(node)
        self.wrap_subscriptions(node)

    def wrap_publishers(self, node) -> None:
        from catheter_bringup.cdr_encode import encoder
        serialize_message = serializer()[0]
        for pub in list(node.publishers):
            if id(pub) in self._pubs:
                continue
            self._pubs.add(id(pub))
            topic = pub.topic_name
            self.counts.setdefault(topic, 0)
            orig = pub.publish
            # the type's own CDR encoder (`cdr_encode`), rclpy's serialiser for the rest
            enc = encoder(pub.msg_type) or (lambda _m: None)
            copier = message_copier(pub.msg_type)

            def publish(msg, _orig=orig, _topic=topic, bus=self, _enc=enc,
                        _type=pub.msg_type, _copier=copier):
                if isinstance(msg, bytes):
                    data = msg
                else:
                    # None: a value the encoder leaves to rclpy (not its field's exact type)
                    data = _enc(msg) if msg.__class__ is _type else None
                    if data is None:
                        data = serialize_message(msg)
                if bus.dds or _topic in bus.dds_topics:
                    _orig(data)       # the bytes already serialised: not serialised twice
                bus.counts[_topic] += 1
                if bus.record is not None:
                    bus.record(_topic, data)
                copied = None
                if bus.copy and _topic in bus.msg_topics and not isinstance(msg, bytes):
                    # a copy for the subscribers instead of deserialising the bytes (cheaper;
                    # taken now: the publisher may refill its message before delivery)
                    cp = _copier if msg.__class__ is _type else message_copier(type(msg))
                    copied = cp(msg) if cp else None
                bus.queue.append((_topic, data, copied))
                if bus.times is not None:
                    bus.note_times(_topic, msg)
                if bus.immediate and not (bus._delivering or bus._holding):
                    bus.deliver_all()

            intercept_publish(pub, publish)

    def note_times(self, topic: str, msg) -> None:
        """Real time: note when `topic` was published (and, for `latency_topics`, how old
        its header stamp was then)."""
        ts = self.times.get(topic)
        if ts is None:
            ts = self.times[topic] = array.array('d')
        ts.append(time.perf_counter())
        if topic in self.latency_topics and self.wall_ns is not None:
            ns = _stamp_ns(msg)
            if ns is not None:
                lat = self.latency.setdefault(topic, array.array('d'))
                lat.append((self.wall_ns() - ns) * 1e-9)
        if topic in self.stamp_topics:
            ns = _stamp_ns(msg)
            if ns is not None:
                self.sent.setdefault(topic, array.array('q')).append(ns)

    def wrap_subscriptions(self, node) -> None:
        for sub in list(node.subscriptions):
            if id(sub) in self._subs:
                continue
            if sub.topic_name not in self.counts:
                # nobody in this process publishes it (yet): DDS delivers it, the runner spins
                # the executor for it
                self.external.add(id(sub))
                self._count_external(sub, node.get_name(), node)
                continue
            self.external.discard(id(sub))
            self._subs.add(id(sub))
            raw = bool(sub.raw)
            # what DDS still delivers is dropped, taken raw: nothing deserialised for it
            cb, with_info = take_callback(sub, _drop, raw=True)
            self.subs.setdefault(sub.topic_name, []).append(
                (cb, raw, sub.msg_type, with_info, node.get_name()))
            if not raw:
                self.msg_topics.add(sub.topic_name)

    def _count_external(self, sub, owner: str, node=None) -> None:
        """Count (and time) what DDS delivers to a subscription outside the bus, and what DDS
        reports lost of it (`dds_lost`)."""
        if id(sub) in self._counted or not self.immediate:
            return
        self._counted.add(id(sub))
        topic = sub.topic_name
        self.received.setdefault(topic, 0)
        if node is not None:
            self.dds_lost.setdefault(topic, 0)
            key = id(sub)
            watch_message_lost(node, sub, lambda total: self.note_dds_lost(key, topic, total))

        # taken raw and decoded here by the type's generated decoder (`cdr_decode`): rclpy's
        # take builds the message through its C conversion and every nested __init__
        # (WrenchStamped 15 against 1.7 us, ImpedanceModel 15 against 3.9 us, measured)
        dec = decoder(sub.msg_type) if self.decode_dds and not sub.raw else None
        if dec is not None:
            set_raw(sub)

        def counting(orig, bus=self, _topic=topic, _owner=owner, _dec=dec,
                     _type=sub.msg_type):
            def callback(*args):
                if _dec is not None:
                    msg = _dec(args[0])
                    if msg is None:            # bytes it does not read: rclpy decides
                        msg = serializer()[1](args[0], _type)
                    args = (msg,) + args[1:]
                bus.received[_topic] += 1
                if bus.times is not None and _topic in bus.stamp_topics:
                    ns = _stamp_ns(args[0])
                    if ns is not None:
                        bus.taken.setdefault(_topic, array.array('q')).append(ns)
                return bus.timed(_owner, orig, *args)
            return callback

        wrap_callback(sub, counting)

    def note_dds_lost(self, key: int, topic: str, total: int) -> None:
        """Subscription `key` of `topic`: DDS reports `total` samples lost since it was made;
        `dds_lost[topic]` is the sum over the topic's subscriptions."""
        self._dds_lost_by_sub[key] = (topic, total)
        self.dds_lost[topic] = sum(n for t, n in self._dds_lost_by_sub.values() if t == topic)

    def timed(self, owner: str, fn, *args):
        """Call fn(*args), adding its wall time minus the deliveries it caused to `owner`'s
        cost (a timer's own work, not its subscribers'). Immediate: what fn publishes is
        delivered when it returns (see the class docstring)."""
        clock = time.perf_counter
        hold = self.immediate and not (self._holding or self._delivering)
        d0 = self.delivery_s
        t = clock()
        if hold:
            self._holding = True
        try:
            return fn(*args)
        finally:
            self.cost.add(owner, clock() - t - (self.delivery_s - d0))
            if hold:
                self._holding = False
                if self.queue:
                    self.deliver_all()

    def deliver_all(self) -> int:
        deserialize_message = serializer()[1]
        decoders = self._decoders
        n = 0
        q = self.queue
        clock = time.perf_counter
        cost = self.cost
        self._delivering = True
        t_all = clock()
        try:
            share = self.share
            while q:
                # copied: the publisher's message copied at publish (`message_copier`) or None
                topic, data, copied = q.popleft()
                last_type = last = None
                for cb, raw, msg_type, with_info, owner in self.subs.get(topic, ()):
                    t = clock()
                    if raw:
                        msg = data
                    elif share and msg_type is last_type:
                        msg = last            # one deserialised message for every subscriber
                    elif copied is not None and type(copied) is msg_type:
                        msg = last = copied   # (share off: the others deserialise)
                        last_type = msg_type
                        copied = None
                    else:
                        # the type's generated decoder (`cdr_decode`), rclpy where it has none
                        # or it does not read the bytes
                        dec = decoders.get(msg_type, _UNSEEN)
                        if dec is _UNSEEN:
                            dec = decoders[msg_type] = decoder(msg_type)
                        msg = dec(data) if dec is not None else None
                        if msg is None:
                            msg = deserialize_message(data, msg_type)
                        last = msg
                        last_type = msg_type
                    if with_info:
                        cb(msg, {})
                    else:
                        cb(msg)
                    cost.add(owner, clock() - t)
                    n += 1
        finally:
            self._delivering = False
            self.delivery_s += clock() - t_all
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

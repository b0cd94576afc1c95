"""Helpers to run nodes in-process in tests: a private context, an executor spun until a
condition holds or a deadline passes, and per-process ROS isolation."""
from __future__ import annotations

import os
import time
from typing import Callable, Iterable

import rclpy
from rclpy.context import Context


# Fast DDS binds UDP ports 7400 + 250 * domain + 0..11 + 2 * participant. On Linux the
# kernel hands out ephemeral ports from 32768-60999 (ip_local_port_range) to any socket
# that asks for one, so a domain whose ports fall there can find them taken and lose
# discovery at random. Domains 20-101 stay below 32768 (with up to 50 participants) and
# 215-232 above 60999 (232 is the last domain whose ports fit below 65536).
ISOLATED_DOMAINS = tuple(range(20, 102)) + tuple(range(215, 233))
EPHEMERAL_PORTS = (32768, 60999)


def domain_ports(domain: int, participants: int = 50) -> range:
    """The UDP ports Fast DDS may bind in ``domain`` with up to ``participants`` participants
    on one host (the RTPS well-known ports: PB 7400, DG 250, PG 2, offsets 0-11)."""
    lo = 7400 + 250 * int(domain)
    return range(lo, lo + 12 + 2 * int(participants))


def isolated_domain(key: int) -> int:
    """The domain id of ISOLATED_DOMAINS for ``key`` (a process id, a seed): neighbouring
    keys get different domains, each with its ports out of the kernel's ephemeral range."""
    return ISOLATED_DOMAINS[int(key) % len(ISOLATED_DOMAINS)]


def isolate_ros_env(seed: int | None = None) -> int:
    """Set a domain id unique to this process (`isolated_domain` of the process id or
    ``seed``) and keep discovery on localhost. Returns the id."""
    dom = isolated_domain(os.getpid() if seed is None else seed)
    os.environ['ROS_DOMAIN_ID'] = str(dom)
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    return dom


class RosHarness:
    """A private rclpy context with one executor; create nodes with `harness.context`.

    >>> h = RosHarness(); node = rclpy.create_node('n', context=h.context); h.add(node)
    >>> h.spin_until(lambda: got, timeout=5.0); h.close()
    """

    def __init__(self, executor: str = 'single'):
        self.context = Context()
        rclpy.init(context=self.context)
        if executor == 'events':
            from rclpy.experimental import EventsExecutor
            self.executor = EventsExecutor(context=self.context)
        else:
            from rclpy.executors import SingleThreadedExecutor
            self.executor = SingleThreadedExecutor(context=self.context)
        self.nodes = []

    def add(self, *nodes):
        for n in nodes:
            self.executor.add_node(n)
            self.nodes.append(n)
        return nodes[0] if len(nodes) == 1 else nodes

    def node(self, name: str, **kw):
        n = rclpy.create_node(name, context=self.context, **kw)
        return self.add(n)

    def spin_for(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=min(0.05, max(0.0, end - time.monotonic())))

    def spin_until(self, cond: Callable[[], bool], timeout: float = 10.0) -> bool:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if cond():
                return True
            self.executor.spin_once(timeout_sec=0.02)
        return bool(cond())

    def close(self, extra: Iterable = ()) -> None:
        for n in list(self.nodes) + list(extra):
            close = getattr(n, 'close', None)
            if callable(close):
                close()
            try:
                self.executor.remove_node(n)
            except Exception:  # noqa: BLE001
                pass
            n.destroy_node()
        self.executor.shutdown()
        rclpy.try_shutdown(context=self.context)


class ManualClock:
    """A node's time set by hand, for driving its timer callback directly in a test: replaces
    the node's ``_clock_ns`` (the nodes read their clock through it) with this clock's time.

    >>> clock = ManualClock(node, 1.0); clock.tick(1.0, 1.005); clock.set(1.010)
    """

    def __init__(self, node, t: float):
        self.node = node
        self.t = float(t)
        node._clock_ns = lambda: int(round(self.t * 1e9))

    def set(self, t: float) -> None:
        """The node's time is now `t` s."""
        self.t = float(t)

    def tick(self, *times: float) -> None:
        """For each time: set it and run the node's timer callback ``_tick``."""
        for t in times:
            self.set(t)
            self.node._tick()


class CapturedLog(list):
    """The log lines of a node, captured in a test instead of printed: ``(level, text)``
    pairs in order (level 'debug', 'info', 'warning', 'error' or 'fatal'). Installing it
    replaces the node's ``get_logger``; `texts(level)` lists one level's texts. rclpy's
    keyword arguments (throttle_duration_sec, once, ...) are accepted and ignored.

    >>> log = CapturedLog(node); node.get_logger().warning('x'); log.texts('warning') == ['x']
    """

    LEVELS = ('debug', 'info', 'warning', 'error', 'fatal')

    def __init__(self, node):
        super().__init__()
        logger = type('CapturedLogger', (), {
            lvl: (lambda _self, text, _lvl=lvl, **_kw: self.append((_lvl, text)))
            for lvl in self.LEVELS})()
        node.get_logger = lambda: logger

    def texts(self, level: str) -> list:
        return [t for lvl, t in self if lvl == level]

"""Helpers to run nodes in-process in tests: a private context, an executor spun until a
condition holds or a deadline passes, and per-process ROS isolation."""
from __future__ import annotations

import os
import time
from typing import Callable, Iterable

import rclpy
from rclpy.context import Context


def isolate_ros_env(seed: int | None = None) -> int:
    """Set a domain id unique to this process and keep discovery on localhost. Returns the id."""
    dom = (os.getpid() if seed is None else seed) % 200 + 20
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

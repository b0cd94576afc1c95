"""Node plumbing shared by every package: a `main` runner with a clean Ctrl-C shutdown,
a diagnostics publisher, and declared parameters with descriptions and ranges.

Only node modules import this file; the algorithm modules never import rclpy.
"""
from __future__ import annotations

import signal
import sys
import time
from typing import Callable, Dict, Optional

import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import (FloatingPointRange, IntegerRange,
                                ParameterDescriptor)
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node

from catheter_common.topics import DIAGNOSTICS
from catheter_common.qos import QOS_DEFAULT


def declare(node: Node, name: str, default, description: str, lo=None, hi=None,
            step=None, read_only: bool = False, choices=None):
    """Declare a parameter with a description and (for numbers) a range; return its value."""
    desc = ParameterDescriptor(description=description, read_only=read_only)
    if choices is not None:
        desc.additional_constraints = 'one of: ' + ', '.join(str(c) for c in choices)
    if lo is not None and hi is not None:
        if isinstance(default, bool):
            pass
        elif isinstance(default, int):
            desc.integer_range = [IntegerRange(from_value=int(lo), to_value=int(hi),
                                               step=int(step or 1))]
        elif isinstance(default, float):
            desc.floating_point_range = [FloatingPointRange(from_value=float(lo),
                                                            to_value=float(hi),
                                                            step=float(step or 0.0))]
    value = node.declare_parameter(name, default, desc).value
    if choices is not None and value not in choices:
        raise ValueError(f'parameter {name}={value!r} is not one of {list(choices)}')
    return value


class Diagnostics:
    """Counts events and rates of a node and publishes a DiagnosticArray on /diagnostics.

    `count(key)` increments a counter; `set(key, value)` sets a value; `error(msg)`
    records a failure (level WARN while failures happened in the last period).
    """

    def __init__(self, node: Node, period: float = 1.0, hardware_id: str = 'sim'):
        self._node = node
        self._name = node.get_fully_qualified_name()
        self._hw = hardware_id
        self._counts: Dict[str, int] = {}
        self._last_counts: Dict[str, int] = {}
        self._values: Dict[str, str] = {}
        self._errors_in_period = 0
        self._last_error = ''
        self._pub = node.create_publisher(DiagnosticArray, DIAGNOSTICS, QOS_DEFAULT)
        self._t_last = node.get_clock().now()
        self._timer = node.create_timer(period, self.publish)

    def count(self, key: str, n: int = 1) -> None:
        self._counts[key] = self._counts.get(key, 0) + n

    def get(self, key: str) -> int:
        return self._counts.get(key, 0)

    def set(self, key: str, value) -> None:
        self._values[key] = value if isinstance(value, str) else f'{value:.6g}' \
            if isinstance(value, float) else str(value)

    def error(self, message: str, key: str = 'errors') -> None:
        self.count(key)
        self._errors_in_period += 1
        self._last_error = message

    def publish(self) -> None:
        now = self._node.get_clock().now()
        dt = (now - self._t_last).nanoseconds * 1e-9
        self._t_last = now
        st = DiagnosticStatus()
        st.name = self._name
        st.hardware_id = self._hw
        if self._errors_in_period:
            st.level = DiagnosticStatus.WARN
            st.message = f'{self._errors_in_period} error(s): {self._last_error}'
        else:
            st.level = DiagnosticStatus.OK
            st.message = 'ok'
        self._errors_in_period = 0
        kv = []
        for k, v in sorted(self._counts.items()):
            kv.append(KeyValue(key=k, value=str(v)))
            if dt > 0:
                rate = (v - self._last_counts.get(k, 0)) / dt
                kv.append(KeyValue(key=k + '_rate_hz', value=f'{rate:.2f}'))
        self._last_counts = dict(self._counts)
        kv += [KeyValue(key=k, value=v) for k, v in sorted(self._values.items())]
        st.values = kv
        msg = DiagnosticArray()
        msg.header.stamp = now.to_msg()
        msg.status = [st]
        self._pub.publish(msg)


def make_executor(kind: str = 'events', context=None):
    """EventsExecutor by default (1 kHz capable); 'single' for SingleThreadedExecutor.

    MultiThreadedExecutor is deliberately not offered: it runs at 3-10 Hz in this rclpy.
    """
    if kind == 'events':
        from rclpy.experimental import EventsExecutor
        return EventsExecutor(context=context)
    if kind == 'single':
        from rclpy.executors import SingleThreadedExecutor
        return SingleThreadedExecutor(context=context)
    raise ValueError(f'executor kind must be "events" or "single", got {kind!r}')


def run_node(node_factory: Callable[..., Node], args=None, executor: str = 'events') -> int:
    """Entry point body for a node executable: init, spin, clean shutdown on Ctrl-C / SIGTERM.

    `node_factory` is called with no arguments after rclpy.init. Returns a process exit code.
    """
    rclpy.init(args=args)
    node: Optional[Node] = None
    exe = None
    code = 0
    # SIGTERM behaves like Ctrl-C (clean shutdown, nodes flush what they hold).
    signal.signal(signal.SIGTERM, lambda *_: rclpy.try_shutdown())
    try:
        node = node_factory()
        exe = make_executor(executor)
        exe.add_node(node)
        node.get_logger().info('running; Ctrl-C to stop')
        # spin_once in a loop, not spin(): EventsExecutor.spin() stays inside C++ and never
        # sees Ctrl-C (KeyboardInterrupt is only raised when control returns to Python).
        while rclpy.ok():
            exe.spin_once(timeout_sec=0.1)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception as exc:  # a failing node says why and exits non-zero
        if node is not None:
            node.get_logger().fatal(f'node failed: {exc!r}')
        else:
            print(f'node failed to start: {exc!r}', file=sys.stderr)
        code = 1
    finally:
        if node is not None:
            close = getattr(node, 'close', None)
            if callable(close):
                try:
                    close()
                except Exception as exc:  # noqa: BLE001 - report, keep shutting down
                    print(f'error while closing node: {exc!r}', file=sys.stderr)
            try:
                node.get_logger().info('shut down cleanly')
            except Exception:  # noqa: BLE001 - logger may be gone after context shutdown
                pass
        if exe is not None:
            exe.shutdown()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return code


def wall_time() -> float:
    """Monotonic wall time in seconds, for measuring latency only (never for node logic)."""
    return time.perf_counter()

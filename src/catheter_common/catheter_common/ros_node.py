"""The body of every node executable: `run_node` (``--help``, spin, a clean stop on SIGINT and
SIGTERM), the executor choice, and wall time for latency measurements.

Only node modules import this file; the algorithm modules never import rclpy. Parameters
are in `catheter_common.params`, diagnostics in `catheter_common.diagnostics` (both also
importable from here, as before).
"""
from __future__ import annotations

import faulthandler
import os
import sys
import threading
import time
from typing import Callable, Optional

import rclpy
from rclpy.node import Node

from catheter_common import stop_signals
from catheter_common.diagnostics import Diagnostics  # noqa: F401  (re-exported)
from catheter_common.params import declare, format_help, seal  # noqa: F401  (re-exported)
from catheter_common.stop_signals import STOP_SIGNALS  # noqa: F401  (re-exported)


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


def wants_help(args) -> bool:
    """True if the command line (without its --ros-args part) asks for help."""
    from rclpy.utilities import remove_ros_args
    argv = list(sys.argv if args is None else args)
    return any(a in ('-h', '--help') for a in remove_ros_args(argv)[1:])


def node_help(node_class, executable: Optional[str] = None) -> str:
    """The --help text of a node class: its docstring's first paragraph and its table."""
    exe = executable or getattr(node_class, 'NODE_NAME', None) or \
        os.path.basename(sys.argv[0]) or node_class.__name__
    mod = sys.modules.get(node_class.__module__)
    doc = (getattr(mod, '__doc__', None) or node_class.__doc__ or '').strip().split('\n\n')[0]
    return format_help(exe, getattr(node_class, 'PARAMS', ()), doc)


def run_node(node_factory: Callable[..., Node], args=None, executor: str = 'events') -> int:
    """Entry point body for a node executable. Returns the process exit code.

    ``--help`` / ``-h``: prints the node's parameters and exits 0 without starting anything.
    SIGINT and SIGTERM stop the spin loop (`catheter_common.stop_signals`: installed by the
    executable's entry point before the node's modules were imported, or here); then the
    node's ``close()`` runs (it may still publish), the node is destroyed, and only then the
    context is shut down: no callback can run against a dead context (that was the
    ``[FATAL] publisher's context is invalid`` on SIGTERM). A signal that came before the
    context was initialised starts nothing. Exit code 0 on a signal, 1 when the node failed.
    """
    stop = stop_signals.install()
    try:
        if wants_help(args):
            sys.stdout.write(node_help(node_factory))
            return 0
        if stop.signum is not None:
            print(f'{stop.name} before the node started: not started', file=sys.stderr)
            return 0
        return _run(node_factory, args, executor, stop)
    finally:
        stop_signals.restore()


def _run(node_factory, args, executor: str, stop: stop_signals.StopFlag) -> int:
    from rclpy.signals import SignalHandlerOptions
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    node: Optional[Node] = None
    exe = None
    code = 0
    try:
        node = node_factory()
        seal(node)
        exe = make_executor(executor)
        exe.add_node(node)
        node.get_logger().info('running; Ctrl-C to stop')
        # spin_once in a loop, not spin(): the handlers run in Python between two spins
        while stop.signum is None and rclpy.ok():
            exe.spin_once(timeout_sec=0.1)
        if stop.signum is not None:
            node.get_logger().info(f'{stop.name}: stopping')
    except Exception as exc:  # a failing node says why and exits non-zero
        if node is not None:
            node.get_logger().fatal(f'node failed: {exc!r}')
        else:
            print(f'node failed to start: {exc!r}', file=sys.stderr)
        code = 1
    finally:
        if exe is not None and node is not None:
            try:
                exe.remove_node(node)
            except Exception:  # noqa: BLE001 - shutting down anyway
                pass
        if node is not None:
            close = getattr(node, 'close', None)
            if callable(close):
                try:
                    close()
                except Exception as exc:  # noqa: BLE001 - report, keep shutting down
                    print(f'error while closing node: {exc!r}', file=sys.stderr)
                    code = code or 1
            node.get_logger().info('shut down cleanly')
        # the node is closed (its data are safe): the rest is rcl / DDS teardown, which once
        # blocked for good in destroy_node under load (impedance_identifier_node, a fresh
        # clone's full run: its stack, dumped on SIGUSR1, ended in destroy_when_not_in_use)
        watchdog = TeardownWatchdog(code)
        try:
            if exe is not None:
                exe.shutdown()
            if node is not None:
                node.destroy_node()
            rclpy.try_shutdown()
        finally:
            watchdog.cancel()
    return code


#: s: how long the rcl / DDS teardown after a node's close() may take before the process
#: exits without waiting for it (normally well under 1 s)
TEARDOWN_TIMEOUT_S = 10.0
#: s: after that, a watchdog that needs no GIL ends the process with the node's code (a
#: POSIX timer whose thread calls _exit; faulthandler's exit 1 where there is none), in case
#: the blocked call holds the GIL (it did: a fresh clone's run, the Python watchdog's timer
#: thread stuck in its wait while destroy_node blocked; the old backstop then exited 1)
TEARDOWN_BACKSTOP_S = 5.0


def _hard_exit(code: int) -> None:
    os._exit(code)


class GilFreeExit:
    """A timer that calls ``_exit(code)`` after `delay` s from a thread glibc starts
    (``timer_create`` with SIGEV_THREAD, the notify function libc's ``_exit``, its argument
    the code): no Python runs, so it fires while another thread holds the GIL. `armed` is
    False where the platform does not offer it (not Linux / glibc, ctypes refused): the caller
    falls back. `cancel()` deletes the timer (idempotent)."""

    def __init__(self, delay: float, code: int):
        self.armed = False
        self._timer = None
        try:
            import ctypes
            import sys as _sys
            if not _sys.platform.startswith('linux'):
                return
            libc = ctypes.CDLL(None, use_errno=True)

            class Sigevent(ctypes.Structure):          # glibc's struct sigevent, 64 bytes
                _fields_ = [('value', ctypes.c_void_p), ('signo', ctypes.c_int),
                            ('notify', ctypes.c_int), ('function', ctypes.c_void_p),
                            ('attribute', ctypes.c_void_p), ('pad', ctypes.c_int * 8)]

            class Timespec(ctypes.Structure):
                _fields_ = [('sec', ctypes.c_long), ('nsec', ctypes.c_long)]

            class Itimerspec(ctypes.Structure):
                _fields_ = [('interval', Timespec), ('value', Timespec)]

            if ctypes.sizeof(Sigevent) != 64:
                return
            sev = Sigevent()
            sev.value = int(code) & 0xFF
            sev.notify = 2                               # SIGEV_THREAD
            sev.function = ctypes.cast(libc._exit, ctypes.c_void_p).value
            timer = ctypes.c_void_p()
            if libc.timer_create(1, ctypes.byref(sev), ctypes.byref(timer)) != 0:   # MONOTONIC
                return
            its = Itimerspec()
            its.value.sec = int(delay)
            its.value.nsec = int(round((delay - int(delay)) * 1e9))
            if libc.timer_settime(timer, 0, ctypes.byref(its), None) != 0:
                libc.timer_delete(timer)
                return
            self._libc, self._timer, self.armed = libc, timer, True
        except Exception:  # noqa: BLE001 - no such timer here: the caller falls back
            self.armed = False

    def cancel(self) -> None:
        if self._timer is not None:
            self._libc.timer_delete(self._timer)
            self._timer = None


class TeardownWatchdog:
    """Ends the process if the teardown after close() has not finished in
    `TEARDOWN_TIMEOUT_S`: one line on stderr, every thread's stack, then exit with `code` (the
    node itself stopped as asked). Should the first never get to run (the blocked call holds
    the GIL), faulthandler's thread dumps every stack and a `GilFreeExit` exits with `code`
    `TEARDOWN_BACKSTOP_S` later (without one, faulthandler exits 1 then)."""

    def __init__(self, code: int, timeout: Optional[float] = None):
        self.timeout = TEARDOWN_TIMEOUT_S if timeout is None else float(timeout)
        self.code = code
        self.fired = False
        self._timer = threading.Timer(self.timeout, self._expire)
        self._timer.daemon = True
        self._timer.start()
        backstop = self.timeout + TEARDOWN_BACKSTOP_S
        self._exit = GilFreeExit(backstop, code)
        faulthandler.dump_traceback_later(backstop - 0.2 if self._exit.armed else backstop,
                                          exit=not self._exit.armed)

    def _expire(self) -> None:
        self.fired = True
        try:
            sys.stderr.write(f'teardown after close() did not finish in {self.timeout:g} s '
                             f'(rcl / DDS); exiting with code {self.code} without waiting; '
                             'the threads:\n')
            sys.stderr.flush()
            faulthandler.dump_traceback(file=sys.stderr, all_threads=True)
            sys.stdout.flush()
            sys.stderr.flush()
        finally:
            _hard_exit(self.code)

    def cancel(self) -> None:
        self._timer.cancel()
        self._exit.cancel()
        faulthandler.cancel_dump_traceback_later()


def node_main(node_class, executor: str = 'events') -> Callable[..., int]:
    """The ``main(args=None)`` entry point of a node module (its console_script): `run_node`
    of `node_class`, returning the exit code."""
    def main(args=None) -> int:
        return run_node(node_class, args, executor)
    main.__doc__ = f'Run {node_class.__name__} as a node executable (see run_node).'
    return main


def clock_ns(clock) -> Callable[[], int]:
    """A function returning `clock`'s time now as integer ns: ``clock.now().nanoseconds``
    without building an rclpy Time (1.2 against 3.4 us per call measured; the 1 kHz nodes
    read their clock 7-10 times per period). Reads what ``Clock.now`` reads: the C clock
    (``Clock.handle``, the same object for the clock's life; its sim time override too),
    under the handle's context."""
    h = clock.handle

    def now_ns(_h=h) -> int:
        with _h:
            return _h.get_now().nanoseconds
    return now_ns


def wall_time() -> float:
    """Monotonic wall time in seconds, for measuring latency only (never for node logic)."""
    return time.perf_counter()

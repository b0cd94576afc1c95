"""Per-frame stage trace of the vision chain (camera -> shape -> force estimate), for the
latency benchmark: off unless the environment variable `ENV` names a directory.

Each stage notes, per frame (keyed by the image's header stamp, ns), the wall clock
(`time.time_ns`, the clock of the real-time header stamps) at its start and end, and from
the thread's scheduler statistics (``/proc/thread-self/schedstat``: CPU time, time spent
runnable on a run queue but not running, number of times it was put on a CPU) the
differences over the stage: wall minus CPU is the time the stage did not run, the run-queue
part of it the time it was preempted (runnable, another task on its CPU), the rest blocked;
the count of times it was put on a CPU less one is how often it was preempted or blocked.
At the process's exit the rows go to ``<dir>/stages.<pid>.json`` ({stage: [[stamp_ns,
start_ns, end_ns, cpu_ns, runqueue_ns, slices, extra], ...]}), which
`tests/bench/bench_vision_stages.py` reads. Costs one environment lookup per frame when
off. No rclpy.
"""
from __future__ import annotations

import atexit
import json
import os
import time
from typing import Dict, List, Optional

#: the environment variable: a directory to write the trace into (unset: no trace)
ENV = 'CATHETER_STAGE_TRACE'

_rows: Dict[str, List[list]] = {}
_registered = False


def enabled() -> bool:
    """True when the trace is on in this process (`ENV` set to a non-empty value)."""
    return bool(os.environ.get(ENV))


class Stage:
    """One timed stage: ``s = Stage.begin()`` ... ``s.end(name, stamp_ns, extra)``; a no-op
    object (`begin` returns None) when the trace is off."""

    __slots__ = ('t0', 's0')

    def __init__(self):
        self.s0 = schedstat()
        self.t0 = time.time_ns()

    @classmethod
    def begin(cls) -> Optional['Stage']:
        return cls() if enabled() else None

    def end(self, name: str, stamp_ns: int, extra=None) -> None:
        t1 = time.time_ns()
        s1 = schedstat()
        note(name, stamp_ns, self.t0, t1, *(b - a for a, b in zip(self.s0, s1, strict=True)),
             extra=extra)


def schedstat() -> tuple:
    """(CPU ns, run-queue wait ns, times put on a CPU) of the calling thread so far; the CPU
    time from `time.thread_time_ns` and zeros where there is no schedstat file."""
    try:
        with open('/proc/thread-self/schedstat') as f:
            a, b, c = f.read().split()[:3]
        return int(a), int(b), int(c)
    except (OSError, ValueError):
        return time.thread_time_ns(), 0, 0


def note(name: str, stamp_ns: int, start_ns: int, end_ns: int, cpu_ns: int = 0,
         runqueue_ns: int = 0, slices: int = 0, extra=None) -> None:
    """Add one row to stage `name` (see the module docstring)."""
    global _registered
    if not _registered:
        atexit.register(dump)
        _registered = True
    _rows.setdefault(name, []).append([int(stamp_ns), int(start_ns), int(end_ns), int(cpu_ns),
                                       int(runqueue_ns), int(slices), extra])


def stamp_ns(stamp) -> int:
    """A builtin_interfaces/Time as ns."""
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def dump(directory: Optional[str] = None) -> Optional[str]:
    """Write the rows (if any) to ``<directory or $ENV>/stages.<pid>.json``; the path or None."""
    d = directory or os.environ.get(ENV)
    if not d or not _rows:
        return None
    path = os.path.join(d, f'stages.{os.getpid()}.json')
    with open(path, 'w') as f:
        json.dump(_rows, f)
    return path


def clear() -> None:
    _rows.clear()

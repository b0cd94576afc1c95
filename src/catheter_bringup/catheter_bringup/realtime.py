"""Process-level settings of a real-time run (no rclpy): OS scheduling priority for the
processes that run 1 kHz loops, the garbage collector kept out of the loop, and a record of
the collector's pauses.

- `set_fifo_priority`: SCHED_FIFO for every thread of the process (the loop, the DDS receive
  threads, the executor's timer thread), so other work on the machine cannot preempt them.
  Needs root or CAP_SYS_NICE (or an ``rtprio`` limit in /etc/security/limits.conf); when not
  permitted it leaves the scheduling as it is and says so in one log line.
- `quiet_gc`: everything alive at start-up frozen out of the collector's sight (a full
  collection of a big heap inside the loop stalled it 55 ms), the young-generation
  threshold raised (fewer, slightly longer young collections), undone afterwards.
- `GcWatch`: counts and times every collection (gc.callbacks) while a run is in its loop.
"""
from __future__ import annotations

import gc
import os
import time
from typing import Callable, Dict, List, Optional


def set_fifo_priority(priority: int, log: Callable[[str], None] = print) -> Optional[str]:
    """Put every thread of this process under SCHED_FIFO at `priority` (1..99). Returns the
    policy now in force ('SCHED_FIFO <p>') or None when not permitted or not available
    (scheduling unchanged, one log line). Threads created later inherit it."""
    if isinstance(priority, bool) or not isinstance(priority, int) or not 1 <= priority <= 99:
        raise ValueError(f'priority must be an int in 1..99, got {priority!r}')
    if not hasattr(os, 'sched_setscheduler'):
        log('[run] SCHED_FIFO not available on this OS: normal scheduling')
        return None
    try:
        tids = [int(t) for t in os.listdir('/proc/self/task')]
    except OSError:
        tids = [0]
    param = os.sched_param(priority)
    try:
        for tid in tids:
            try:
                os.sched_setscheduler(tid, os.SCHED_FIFO, param)
            except ProcessLookupError:       # a thread that ended meanwhile
                continue
    except PermissionError:
        log(f'[run] SCHED_FIFO priority {priority} not permitted (needs root, CAP_SYS_NICE or '
            'an rtprio limit): normal scheduling')
        return None
    return f'SCHED_FIFO {priority}'


def reset_priority() -> None:
    """Every thread back to SCHED_OTHER (the run's process goes on, e.g. a test)."""
    if not hasattr(os, 'sched_setscheduler'):
        return
    try:
        tids = [int(t) for t in os.listdir('/proc/self/task')]
    except OSError:
        tids = [0]
    for tid in tids:
        try:
            os.sched_setscheduler(tid, os.SCHED_OTHER, os.sched_param(0))
        except OSError:
            continue


#: young-generation collection threshold during a real-time loop (Python's default: 700)
GC_THRESHOLD0 = 20_000


def quiet_gc(threshold0: int = GC_THRESHOLD0) -> Callable[[], None]:
    """Collect once, freeze what is alive, raise the young threshold; returns the undo."""
    old = gc.get_threshold()
    gc.collect()
    gc.freeze()
    gc.set_threshold(threshold0, old[1], old[2])

    def undo():
        gc.set_threshold(*old)
        gc.unfreeze()
    return undo


class GcWatch:
    """Times every garbage collection while installed (`start` / `stop`)."""

    def __init__(self):
        self.pauses: Dict[int, List[float]] = {0: [], 1: [], 2: []}
        self._t0 = None

    def _cb(self, phase, info):
        if phase == 'start':
            self._t0 = time.perf_counter()
        elif self._t0 is not None:
            self.pauses.setdefault(info.get('generation', 0), []).append(
                time.perf_counter() - self._t0)
            self._t0 = None

    def start(self) -> 'GcWatch':
        gc.callbacks.append(self._cb)
        return self

    def stop(self) -> None:
        if self._cb in gc.callbacks:
            gc.callbacks.remove(self._cb)

    def summary(self) -> Dict[str, float]:
        allp = [p for ps in self.pauses.values() for p in ps]
        out = {f'gen{g}_count': len(ps) for g, ps in sorted(self.pauses.items())}
        out['total_ms'] = 1e3 * sum(allp)
        out['max_ms'] = 1e3 * max(allp) if allp else 0.0
        return out

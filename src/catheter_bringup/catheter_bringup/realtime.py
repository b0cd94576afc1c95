"""Process-level settings of a real-time run (no rclpy): OS scheduling priority for the
processes that run 1 kHz loops, the garbage collector kept out of the loop, and a record of
the collector's pauses.

- `set_fifo_priority`: SCHED_FIFO for every thread of the process (the loop, the DDS receive
  threads, the executor's timer thread), so other work on the machine cannot preempt them.
  Needs root or CAP_SYS_NICE (or an ``rtprio`` limit in /etc/security/limits.conf); when not
  permitted it leaves the scheduling as it is and says so in one log line.
- `set_nice`: a negative nice value for the vision process: more CPU share than the
  machine's other work without preempting the loops (a SCHED_FIFO vision process rendering
  800x800 frames pushed the real-time tasks into the kernel's RT throttling: 68 ms stalls
  of the 1 kHz loops, measured).
- `own_autogroup`: the vision process in a scheduling group (autogroup) of its own with a
  negative nice: with autogroups enabled the process nice alone does not count against
  other sessions' work.
- `quiet_gc`: everything alive at start-up frozen out of the collector's sight (a full
  collection of a big heap inside the loop stalled it 55 ms), the young-generation
  threshold raised (fewer, slightly longer young collections), undone afterwards.
- `GcWatch`: counts and times every collection (gc.callbacks) while a run is in its loop.
- `align_timers`: a worker's timers restarted together, so those of one period fall due in
  the same executor wake-up.
- `worker_cpus` / `pin_process`: the split layout's CPU placement: the master process on
  one CPU, the vision process on another (see `worker_cpus`).
- `hold_cpu_latency`: a PM QoS CPU latency request (``/dev/cpu_dma_latency``) held while
  the loops run (scenario ``realtime_cpu_latency_us``, off by default), so an idle CPU
  waits for the next tick polling instead of halting: the usual real-time setting on a
  machine with dedicated cores. On the benchmark machine (a virtual machine) a halted
  virtual CPU is woken by its host late by 1-15 ms about 1.5 times a second (`stall_probe`);
  the request removes those, but after a few minutes of polling the host holds the whole
  machine ~100 ms at a time (alternated runs: package README, "Benchmark"), so it is off.
"""
from __future__ import annotations

import gc
import os
import struct
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


def set_nice(nice: int, log: Callable[[str], None] = print) -> Optional[int]:
    """Give every thread of this process the nice value `nice` (-20..19; negative = more CPU
    share under SCHED_OTHER, it never preempts SCHED_FIFO loops and does not count against
    the kernel's real-time throttling). Returns the previous nice value of the calling
    thread, or None when not permitted (one log line, unchanged)."""
    if isinstance(nice, bool) or not isinstance(nice, int) or not -20 <= nice <= 19:
        raise ValueError(f'nice must be an int in -20..19, got {nice!r}')
    try:
        tids = [int(t) for t in os.listdir('/proc/self/task')]
    except OSError:
        tids = [0]
    old = os.getpriority(os.PRIO_PROCESS, 0)
    try:
        for tid in tids:
            try:
                os.setpriority(os.PRIO_PROCESS, tid, nice)
            except ProcessLookupError:
                continue
    except PermissionError:
        log(f'[run] nice {nice} not permitted (needs root or CAP_SYS_NICE): normal priority')
        return None
    return old


#: the PM QoS CPU latency device of Linux: a request (s32, us) holds while the file is open
CPU_DMA_LATENCY = '/dev/cpu_dma_latency'


class CpuLatencyRequest:
    """An open PM QoS CPU latency request (`hold_cpu_latency`); `close()` withdraws it (the
    kernel also does when the process ends)."""

    def __init__(self, fd: int, us: int, path: str):
        self._fd: Optional[int] = fd
        self.us = us
        self.path = path

    @property
    def held(self) -> bool:
        return self._fd is not None

    def close(self) -> None:
        if self._fd is not None:
            fd, self._fd = self._fd, None
            os.close(fd)

    def __repr__(self) -> str:
        return f'CPU latency {self.us} us' + ('' if self.held else ' (withdrawn)')


def hold_cpu_latency(us: int, log: Callable[[str], None] = print,
                     path: str = CPU_DMA_LATENCY) -> Optional[CpuLatencyRequest]:
    """Ask the kernel to keep every CPU's wake-up latency at most `us` microseconds (0: no
    idle state deeper than polling) until the returned request is closed: the real-time
    practice of cyclictest and of RT robot controllers. The price: idle CPUs poll while it
    is held (power; a host sees them busy). Returns None when the device is missing or not
    writable (needs root; one log line, nothing changed)."""
    if isinstance(us, bool) or not isinstance(us, int) or not 0 <= us <= 2_000_000_000:
        raise ValueError(f'us must be an int in 0..2000000000, got {us!r}')
    try:
        fd = os.open(path, os.O_WRONLY)
    except OSError as exc:
        log(f'[run] CPU latency request not made ({path}: {exc.strerror or exc}): idle CPUs '
            'may halt between ticks')
        return None
    try:
        os.write(fd, struct.pack('=i', us))
    except OSError as exc:
        os.close(fd)
        log(f'[run] CPU latency request refused ({path}: {exc.strerror or exc})')
        return None
    return CpuLatencyRequest(fd, us, path)


#: where Linux keeps the autogroup (session) of the calling process and the group's nice
AUTOGROUP = '/proc/self/autogroup'


def own_autogroup(nice: int, log: Callable[[str], None] = print,
                  path: str = AUTOGROUP) -> Optional[str]:
    """Give this process a scheduling group of its own with the nice value `nice`.

    With ``kernel.sched_autogroup_enabled = 1`` (the default of desktop and many server
    kernels, and on the benchmark machine) the CFS scheduler first shares the CPU equally
    between sessions (autogroups) and only then by nice value inside each: a process's nice
    -10 does nothing against other users' jobs in their own sessions (the vision process
    was starved so on the shared machine: the package README, "Benchmark"). So: a new session
    (``setsid``: its own autogroup) and the group's nice set through `path`. Returns a
    description ('autogroup nice -10') or None when there is no autogroup file (scheduling
    unchanged, no log line: the process nice then is all there is) or it is not permitted
    (one log line). Needs root or CAP_SYS_NICE for a negative value."""
    if isinstance(nice, bool) or not isinstance(nice, int) or not -20 <= nice <= 19:
        raise ValueError(f'nice must be an int in -20..19, got {nice!r}')
    if not os.path.exists(path):
        return None
    try:
        if os.getsid(0) != os.getpid():
            os.setsid()                   # a session of its own = an autogroup of its own
    except OSError:
        pass                              # a process group leader: keeps its session
    try:
        with open(path, 'w') as f:
            f.write(str(nice))
    except OSError as exc:
        log(f'[run] autogroup nice {nice} not permitted ({exc.strerror}): the process nice only')
        return None
    return f'autogroup nice {nice}'


def align_timers(timers) -> int:
    """Restart every timer that is not canceled at (nearly) the same instant (`reset`: its
    periods count from now), so timers of one period fall due together: an events executor
    then wakes once per period for all of them instead of once for each (the timers of a
    process are created one after another while its nodes start, at arbitrary phases; the
    cost per wake-up: the package README, "Benchmark", round 5). Returns how many were
    restarted. A destroyed timer is skipped."""
    n = 0
    for tmr in list(timers):
        try:
            if tmr.is_canceled():
                continue                  # reset would start a canceled timer again
            tmr.reset()
        except Exception:  # noqa: BLE001 - a destroyed timer's handle raises
            continue
        n += 1
    return n


def worker_cpus(process: str, processes, cpus) -> Optional[frozenset]:
    """The CPUs a worker process of the split layout is kept on, or None (anywhere).

    With the master and slave loops under SCHED_FIFO on every CPU, the vision process was
    preempted 20-60 times per frame stage (a real-time task that wakes on the CPU where the
    vision thread runs preempts it there, and it waits in that CPU's run queue until the
    loop sleeps again, even when the other CPU is idle): its stages took about three times
    their CPU time (`tests/bench/bench_vision_stages.py`). Placed, the master's force loop
    keeps one CPU to itself and the vision process keeps the last CPU, shared only with the
    slave (which may run on any CPU, as may every process of the run not named here).
    `processes`: the names of the run's workers (placement only when both 'master' and
    'vision' are among them); `cpus`: the CPUs the run may use (e.g.
    ``os.sched_getaffinity(0)``); fewer than two: no placement."""
    cpus = sorted(int(c) for c in cpus)
    if len(cpus) < 2 or not {'master', 'vision'} <= set(processes):
        return None
    if process == 'master':
        return frozenset(cpus[:1])
    if process == 'vision':
        return frozenset(cpus[-1:])
    return None


def pins_loop_thread_only(process: str) -> bool:
    """Whether a placed worker keeps only its loop thread on its CPUs (pinned once its
    threads exist), not every thread: the 1 kHz processes (`scenario.LOOP_PROCESSES`). With
    every thread of the master on its CPU, its helper threads (Fast DDS's, rclpy's) could
    only run there, behind other work of that CPU, and the SCHED_FIFO loop thread stalled
    8-73 ms in 5 of 15 `bench_system --split-only` runs (waiting for a thread that held
    what the loop needed; not traced further); with the loop thread alone pinned, one stall
    (16 ms) in 6 runs, as often as with no placement (catheter_bringup README, round 6)."""
    from catheter_bringup.scenario import LOOP_PROCESSES
    return process in LOOP_PROCESSES


def pin_process(pid: int, cpus, log: Callable[[str], None] = print,
                main_only: bool = False) -> bool:
    """Keep every thread of process `pid` (threads it creates later inherit it) on `cpus`;
    `main_only`: its main thread only (thread id = pid: a real-time loop's executor thread;
    see `pins_loop_thread_only`). False when no thread was pinned (the process is gone) or,
    with one log line, when not permitted or not available; a thread that ended meanwhile
    is skipped."""
    if not hasattr(os, 'sched_setaffinity'):
        log('[run] CPU affinity not available on this OS')
        return False
    try:
        tids = [pid] if main_only else [int(t) for t in os.listdir(f'/proc/{pid}/task')]
    except OSError:
        tids = [pid]
    pinned = 0
    try:
        for tid in tids:
            try:
                os.sched_setaffinity(tid, cpus)
            except ProcessLookupError:
                continue
            pinned += 1
    except OSError as exc:
        log(f'[run] CPU affinity {sorted(cpus)} for process {pid} refused ({exc}): unchanged')
        return False
    return pinned > 0


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


def thread_cpu() -> Dict[str, float]:
    """CPU time (user + system, s) of every thread of this process, summed by thread name
    (``/proc/self/task/<tid>/stat``; {} where there is no /proc). The difference of two calls
    is what each kind of thread (the Python loop, DDS receive threads, the executor's) used
    in between."""
    out: Dict[str, float] = {}
    try:
        tids = os.listdir('/proc/self/task')
        tck = float(os.sysconf('SC_CLK_TCK'))
    except (OSError, ValueError):
        return out
    for tid in tids:
        try:
            with open(f'/proc/self/task/{tid}/stat') as f:
                text = f.read()
        except OSError:
            continue                      # a thread that ended meanwhile
        name = text[text.index('(') + 1:text.rindex(')')]
        fields = text[text.rindex(')') + 2:].split()
        out[name] = out.get(name, 0.0) + (int(fields[11]) + int(fields[12])) / tck
    return out


def cpu_delta(before: Dict[str, float], after: Dict[str, float]) -> Dict[str, float]:
    """Per thread name: CPU s used between two `thread_cpu` calls (threads that ended
    meanwhile are not counted)."""
    return {k: round(v - before.get(k, 0.0), 3) for k, v in sorted(after.items())
            if v - before.get(k, 0.0) > 0}


#: a period longer than this (s) is a gap of a 1 kHz stream: at least one tick was missed
GAP_S = 2e-3
#: at most this many gaps are listed per stream (the longest kept)
MAX_GAPS = 500


def stream_stats(times_s, skip_fraction: float = 0.1) -> Dict[str, float]:
    """Rate and period statistics of a stream from its publish times (s, increasing): the
    first `skip_fraction` of the samples (start-up) left out. n, rate_hz, p50_ms, p99_ms,
    max_ms, and gaps: [start s, length ms] of each period longer than `GAP_S` (time order;
    the `MAX_GAPS` longest), for telling the process's own stalls from the machine's
    (`stall_probe.coinciding`); a stream with fewer than 3 samples left gives n, NaNs and
    no gaps."""
    import numpy as np
    if not 0.0 <= skip_fraction < 1.0:
        raise ValueError(f'skip_fraction must be in [0, 1), got {skip_fraction!r}')
    t = np.asarray(times_s, dtype=float)
    if t.ndim != 1 or not np.all(np.isfinite(t)):
        raise ValueError('times_s must be a 1-D sequence of finite times')
    t = t[int(len(t) * skip_fraction):]
    nan = float('nan')
    if t.size < 3:
        return {'n': int(t.size), 'rate_hz': nan, 'p50_ms': nan, 'p99_ms': nan, 'max_ms': nan,
                'gaps': []}
    d = np.diff(t)
    if np.any(d < 0):
        raise ValueError('times_s must be non-decreasing')
    span = t[-1] - t[0]
    big = np.flatnonzero(d > GAP_S)
    if big.size > MAX_GAPS:
        big = np.sort(big[np.argsort(d[big], kind='stable')[-MAX_GAPS:]])
    return {'n': int(t.size), 'rate_hz': float((t.size - 1) / span) if span > 0 else nan,
            'p50_ms': float(np.percentile(d, 50) * 1e3),
            'p99_ms': float(np.percentile(d, 99) * 1e3), 'max_ms': float(d.max() * 1e3),
            'gaps': [[float(t[i]), float(d[i] * 1e3)] for i in big]}


#: ms, a latency above this is listed by `latency_stats` (the image -> tip force target)
SLOW_MS = 33.0


def latency_stats(lat_s, skip: int = 2, times_s=None) -> Dict[str, float]:
    """n, p50_ms, p99_ms, max_ms of latencies (s), the first `skip` left out (start-up).
    With `times_s` (when each latency was noted, s, as many): also slow, [[start s, latency
    ms], ...] of each latency above `SLOW_MS`, its start being the time noted less the
    latency (for `stall_probe.coinciding`)."""
    import numpy as np
    a = np.asarray(lat_s, dtype=float)[skip:]
    if a.ndim != 1 or not np.all(np.isfinite(a)):
        raise ValueError('lat_s must be a 1-D sequence of finite latencies')
    t = None
    if times_s is not None:
        t = np.asarray(times_s, dtype=float)[skip:]
        if t.shape != a.shape or not np.all(np.isfinite(t)):
            raise ValueError('times_s must be finite times, one per latency')
    nan = float('nan')
    if a.size == 0:
        out = {'n': 0, 'p50_ms': nan, 'p99_ms': nan, 'max_ms': nan}
    else:
        out = {'n': int(a.size), 'p50_ms': float(np.percentile(a, 50) * 1e3),
               'p99_ms': float(np.percentile(a, 99) * 1e3), 'max_ms': float(a.max() * 1e3)}
    if t is not None:
        out['slow'] = [[float(t[i] - a[i]), float(a[i] * 1e3)]
                       for i in np.flatnonzero(a * 1e3 > SLOW_MS)]
    return out


def counts_since(before: Dict[str, int], now: Dict[str, int], keys) -> Dict[str, int]:
    """Running totals `now` minus what they were `before` (0 when absent then), for the keys
    of `now` that are in `keys`: e.g. what DDS reported lost while a loop ran."""
    return {k: int(n) - int(before.get(k, 0)) for k, n in now.items() if k in keys}


def link_loss(sent_ns, taken_ns) -> Dict[str, int]:
    """What DDS lost of a stream between two processes, from the header stamps (ns) the
    publisher sent and those the subscriber took: counted inside the window both were
    running, [max(first sent, first taken), min(last sent, last taken)], so a process that
    started or stopped earlier is not charged. Returns sent, taken (distinct stamps of the
    window that were sent), lost, and where the losses are: `longest_run` (the most
    consecutive sent stamps lost) and `run_at_s` (its first stamp, s after the window's start;
    0.0 when nothing was lost) - a burst at the window's end is a process's shutdown, spread
    single losses are DDS dropping samples."""
    import numpy as np
    s = np.asarray(sent_ns, dtype=np.int64)
    t = np.asarray(taken_ns, dtype=np.int64)
    if s.ndim != 1 or t.ndim != 1:
        raise ValueError('sent_ns and taken_ns must be 1-D sequences of stamps')
    if s.size == 0 or t.size == 0:
        lost = int(s.size) if t.size == 0 else 0
        return {'sent': int(s.size), 'taken': int(t.size), 'lost': lost,
                'longest_run': lost, 'run_at_s': 0.0}
    lo, hi = max(s.min(), t.min()), min(s.max(), t.max())
    sw = np.unique(s[(s >= lo) & (s <= hi)])
    tw = np.intersect1d(np.unique(t[(t >= lo) & (t <= hi)]), sw)
    missing = ~np.isin(sw, tw)
    longest, at = 0, 0.0
    if missing.any():
        # runs of consecutive missing stamps: starts where missing begins, ends where it stops
        m = np.concatenate([[False], missing, [False]]).astype(np.int8)
        d = np.diff(m)
        starts, ends = np.flatnonzero(d == 1), np.flatnonzero(d == -1)
        k = int(np.argmax(ends - starts))
        longest, at = int(ends[k] - starts[k]), float((sw[starts[k]] - lo) * 1e-9)
    return {'sent': int(sw.size), 'taken': int(tw.size), 'lost': int(sw.size - tw.size),
            'longest_run': longest, 'run_at_s': at}

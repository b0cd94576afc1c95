"""Machine stall probe: tells a loop's stalls that the machine caused from its own.

One probe process per CPU, pinned to it, under SCHED_FIFO at the top priority (99) when
permitted: nothing in this operating system that schedules tasks can keep it from running, so
when it wakes up late by milliseconds the CPU itself was taken away (the hypervisor ran
something else on it, or the kernel ran with preemption off). It sleeps `period` at a time on
the monotonic clock (the clock of `time.perf_counter` on Linux, the one the real-time runs
stamp their publishes with) and records every wake-up later than `threshold`: [start s, length
ms], the start being when it was due.

`coinciding(gaps, stalls)` then says which of a stream's gaps (`realtime.stream_stats`'s
``gaps``) overlap a stall the probe saw: those the loop could not have avoided.

    with StallProbe() as probe:
        ...                         # the run
    probe.stalls                    # {cpu: [[start s, length ms], ...]}
    probe.summary()                 # counts, longest, on every CPU at once

Run alone: ``python -m catheter_bringup.stall_probe --seconds 30`` prints what it saw. The
probe costs each CPU one wake-up per period (about 20-40 us of Python each).
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import signal
import subprocess
import sys
import time
from typing import Dict, List, Optional, Sequence

from catheter_common.checks import positive

#: s, the probe's sleep
PERIOD_S = 1e-3
#: s, a wake-up later than this is a stall
THRESHOLD_S = 1e-3
#: SCHED_FIFO priority of the probes (the top: above the loops' `realtime_priority`)
PROBE_PRIORITY = 99


def _check_positive(name: str, value: float) -> float:
    """`catheter_common.checks.positive` (a finite number > 0), a bool refused too."""
    if isinstance(value, bool):
        raise ValueError(f'{name} must be a finite number > 0, got {value!r}')
    return positive(name, value)


def probe_loop(period_s: float = PERIOD_S, threshold_s: float = THRESHOLD_S,
               seconds: Optional[float] = None, stop=lambda: False) -> List[List[float]]:
    """Sleep `period_s` at a time until `seconds` have passed or `stop()` is true; return
    [due time s (monotonic), lateness ms, major page faults, involuntary context switches]
    of every wake-up later than `threshold_s` (the last two counted over that period: a
    stall with neither was not this operating system's doing - the CPU was taken away)."""
    period_s = _check_positive('period_s', period_s)
    threshold_s = _check_positive('threshold_s', threshold_s)
    if seconds is not None:
        seconds = _check_positive('seconds', seconds)
    mono = time.monotonic
    usage = resource.getrusage
    me = resource.RUSAGE_SELF
    t0 = mono()
    end = t0 + seconds if seconds is not None else float('inf')
    due = t0 + period_s
    out: List[List[float]] = []
    while True:
        before = usage(me)
        wait = due - mono()
        if wait > 0:
            time.sleep(wait)
        woke = mono()
        late = woke - due
        if late > threshold_s:
            after = usage(me)
            out.append([round(due, 6), round(late * 1e3, 3),
                        after.ru_majflt - before.ru_majflt, after.ru_nivcsw - before.ru_nivcsw])
        if woke >= end or stop():
            return out
        due += period_s
        if due < woke:                     # after a stall: the next period from now
            due = woke + period_s


def _pin_and_raise(cpu: Optional[int], priority: int) -> str:
    """Pin to `cpu` and take SCHED_FIFO `priority`; returns what was granted."""
    got = []
    if cpu is not None and hasattr(os, 'sched_setaffinity'):
        os.sched_setaffinity(0, {cpu})
        got.append(f'cpu {cpu}')
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
        got.append(f'SCHED_FIFO {priority}')
    except (PermissionError, AttributeError, OSError):
        got.append('normal scheduling (SCHED_FIFO not permitted)')
    return ', '.join(got)


class StallProbe:
    """Context manager: one probe process per CPU this process may use, for the `with`
    block. After it: `stalls` ({cpu: [[due s, late ms, major faults, involuntary context
    switches], ...]}, as `probe_loop` gives them), `scheduling` ({cpu: what was granted}).
    A probe that could not start or report leaves its CPU out (`errors`)."""

    def __init__(self, period_s: float = PERIOD_S, threshold_s: float = THRESHOLD_S,
                 cpus: Optional[Sequence[int]] = None):
        self.period_s = _check_positive('period_s', period_s)
        self.threshold_s = _check_positive('threshold_s', threshold_s)
        if cpus is None:
            cpus = sorted(os.sched_getaffinity(0)) if hasattr(os, 'sched_getaffinity') \
                else [None]
        self.cpus = list(cpus)
        self.stalls: Dict[int, List[List[float]]] = {}
        self.scheduling: Dict[int, str] = {}
        self.errors: Dict[int, str] = {}
        self._procs: list = []
        self.t_start = self.t_end = float('nan')

    def __enter__(self) -> 'StallProbe':
        for cpu in self.cpus:
            cmd = [sys.executable, '-m', 'catheter_bringup.stall_probe',
                   '--period', repr(self.period_s), '--threshold', repr(self.threshold_s),
                   '--json']
            if cpu is not None:
                cmd += ['--cpu', str(cpu)]
            self._procs.append((cpu, subprocess.Popen(
                cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                env={**os.environ, 'PYTHONPATH': os.pathsep.join(p for p in sys.path if p)})))
        time.sleep(0.2)                    # the probes pinned and raised before the run
        self.t_start = time.monotonic()
        return self

    def __exit__(self, *exc) -> None:
        self.t_end = time.monotonic()
        for _, proc in self._procs:
            if proc.poll() is None:
                proc.send_signal(signal.SIGTERM)
        for cpu, proc in self._procs:
            try:
                out, err = proc.communicate(timeout=5.0)
            except subprocess.TimeoutExpired:
                proc.kill()
                out, err = proc.communicate()
            try:
                rep = json.loads(out)
            except ValueError:
                self.errors[cpu] = (err or out or f'exit {proc.returncode}').strip()[-300:]
                continue
            self.stalls[cpu] = [s for s in rep['stalls']
                                if self.t_start <= s[0] <= self.t_end]
            self.scheduling[cpu] = rep['scheduling']
        self._procs = []

    def summary(self, together_s: float = 2e-3) -> Dict[str, float]:
        """Per CPU the number of stalls and the longest (ms); `together`: stalls seen on every
        probed CPU at once (starts within `together_s`), counted on the first CPU; `span_s`:
        the time probed."""
        out: Dict[str, float] = {'span_s': self.t_end - self.t_start}
        for cpu, st in sorted(self.stalls.items()):
            out[f'cpu{cpu}_n'] = len(st)
            out[f'cpu{cpu}_max_ms'] = max((s[1] for s in st), default=0.0)
        lists = [self.stalls[c] for c in sorted(self.stalls)]
        if len(lists) >= 2:
            out['together'] = sum(
                all(any(abs(s[0] - o[0]) <= together_s for o in other) for other in lists[1:])
                for s in lists[0])
        return out

    def stalls_on(self, cpus: Optional[Sequence[int]] = None) -> List[List[float]]:
        """The stalls of the CPUs `cpus` (None or empty: every probed CPU) in one list, in time
        order: those a process kept on `cpus` could not have run through."""
        keep = set(cpus) if cpus else set(self.stalls)
        return sorted(s for c, st in self.stalls.items() if c in keep for s in st)


def coinciding(gaps: Sequence[Sequence[float]], stalls: Sequence[Sequence[float]],
               slack_s: float = 0.5e-3) -> List[bool]:
    """For each gap [start s, length ms] of a stream: does it overlap a stall [due s, late
    ms] (widened by `slack_s` on both sides, for the probe's own wake-up granularity)?"""
    slack_s = float(slack_s)
    if not slack_s >= 0:
        raise ValueError(f'slack_s must be >= 0, got {slack_s!r}')
    ivs = sorted((s[0] - slack_s, s[0] + s[1] * 1e-3 + slack_s) for s in stalls)
    out = []
    for g in gaps:
        a, b = g[0], g[0] + g[1] * 1e-3
        out.append(any(lo < b and a < hi for lo, hi in ivs))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--cpu', type=int, help='the CPU to pin to (default: not pinned)')
    ap.add_argument('--period', type=float, default=PERIOD_S, help='s between wake-ups')
    ap.add_argument('--threshold', type=float, default=THRESHOLD_S,
                    help='s of lateness that counts as a stall')
    ap.add_argument('--seconds', type=float, help='run this long (default: until SIGTERM)')
    ap.add_argument('--json', action='store_true', help='print the report as JSON')
    a = ap.parse_args(argv)
    stop = []
    signal.signal(signal.SIGTERM, lambda *_: stop.append(1))
    signal.signal(signal.SIGINT, lambda *_: stop.append(1))
    if a.cpu is None and not a.json and a.seconds is not None:
        with StallProbe(a.period, a.threshold) as probe:   # every CPU, for `seconds`
            time.sleep(a.seconds)
        print(json.dumps({'summary': probe.summary(), 'scheduling': probe.scheduling,
                          'stalls': probe.stalls, 'errors': probe.errors}, indent=1))
        return 0
    sched = _pin_and_raise(a.cpu, PROBE_PRIORITY)
    stalls = probe_loop(a.period, a.threshold, a.seconds, stop=lambda: bool(stop))
    print(json.dumps({'scheduling': sched, 'stalls': stalls}))
    return 0


if __name__ == '__main__':
    raise SystemExit(main())

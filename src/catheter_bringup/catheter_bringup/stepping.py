"""How a run moves the node graph forward: the lockstep steps (clock, timers, the bus, the
recorder) and the two real-time loops (the local bus on the system clock, or DDS with an
EventsExecutor). A mixin of `catheter_bringup.runner.ScenarioRunner`, which owns the state
these methods use (nodes, executor, bus, timers, recorder, scenario)."""
from __future__ import annotations

import gc
import time

from rosgraph_msgs.msg import Clock

from catheter_bringup.rclpy_adapter import (fire_timer, set_time, spin_ready, timer_due_in_ns,
                                            timer_ready)

#: ns, real time with the local bus: how often DDS is polled for subscriptions outside the bus
#: (the image worker's 30 Hz topics). One poll builds an rclpy wait set, 0.3-1.4 ms measured:
#: every 2 ms that was the largest avoidable cost per 1 kHz tick; every 10 ms keeps up with
#: 30 Hz streams (adds at most 10 ms to their delivery)
EXTERNAL_SPIN_NS = 10_000_000
#: ns, the least time to the next due timer for a DDS poll to start (a poll takes ~0.7 ms)
SPIN_SLACK_NS = 800_000


class Stepping:
    """The run loops of ScenarioRunner (see the module docstring)."""

    def drain(self, max_callbacks: int = 100000) -> int:
        """Run ready callbacks until none is ready and the recorder has caught up."""
        if self.bus is not None:
            return self._drain_bus(max_callbacks)
        n = 0
        for _ in range(10):
            n += spin_ready(self.executor, max_callbacks - n)
            if self._caught_up():
                break
            # delivery still in flight (not intra-process): wait briefly for it
            n += spin_ready(self.executor, 1, timeout=0.002)
        if self.sink is not None:
            self.sink.flush()
        return n

    def _drain_bus(self, max_callbacks: int) -> int:
        """Lockstep drain: run every ready timer (nodes in start order, timers in creation
        order) and deliver what they publish, until no timer is ready and the bus is empty.
        Timers are called directly (rclpy's Python wait-set construction costs ~0.5 ms per
        wait); the executor is spun now and then for anything else (services, guards)."""
        bus = self.bus
        n = 0
        progress = True
        bus.deliver_all()
        # lockstep: time only moves between steps, so each timer's next due time is cached
        # and only timers due now are asked (refreshed on every rescan)
        cache = self.scenario['mode'] == 'lockstep'
        due = self._due
        now = self._now_ns
        while progress and n < max_callbacks:
            progress = False
            for tmr in self._timers:
                if cache and due.get(id(tmr), 0) > now:
                    continue
                ready = timer_ready(tmr)
                if ready is None:            # destroyed
                    continue
                if ready:
                    t0 = time.perf_counter()
                    fire_timer(tmr)
                    bus.cost.add(self._timer_owner.get(id(tmr), '?'),
                                 time.perf_counter() - t0)
                    n += 1
                    progress = True
                    bus.deliver_all()
                if cache:
                    left = timer_due_in_ns(tmr)
                    due[id(tmr)] = now + left if left is not None else 2 ** 62
        self._steps_since_spin += 1
        # lockstep: every 100 steps; real time: every 1000 (one poll builds an rclpy wait set,
        # ~0.6 ms: every 100th 1 kHz period late by that was the p99 period), and not at all
        # when _spin_external polls the same executor anyway
        every = 100 if cache else (10 ** 9 if bus.external else 1000)
        if self._steps_since_spin >= every:
            self._steps_since_spin = 0
            spin_ready(self.executor, 20)
            bus.deliver_all()
        if self.sink is not None:
            self.sink.flush()
        return n

    def _caught_up(self) -> bool:
        return self.tracker.pending() == 0

    def _run_lockstep(self, bar):
        sc = self.scenario
        dt_ns = int(round(sc['step'] * 1e9))
        n_steps = int(round(sc['duration'] / sc['step']))
        msg = Clock()
        self._sim_reached = 0.0
        self._publish_clock(0, msg)
        self.drain()
        last_bar = 0
        for k in range(1, n_steps + 1):
            self._publish_clock(k * dt_ns, msg)
            if self.inject is not None:
                self._inject(k * dt_ns, 'pre')
                self.drain()
                self._inject(k * dt_ns, 'post')
            self.drain()
            self._sim_reached = k * dt_ns * 1e-9
            if k % 64 == 0:
                self._rescan()
            if self.on_step is not None:
                self.on_step(self._sim_reached)
            if self.stop_requested:
                raise KeyboardInterrupt
            if bar is not None and (k - last_bar >= 100 or k == n_steps):
                bar.update(round((k - last_bar) * sc['step'], 6))
                last_bar = k
        return n_steps, self._sim_reached

    def _inject(self, t_ns: int, phase: str):
        for topic, data in self.inject(t_ns, phase):
            self.bus.counts[topic] = self.bus.counts.get(topic, 0) + 1
            self.bus.queue.append((topic, data))

    def _publish_clock(self, t_ns: int, msg: Clock):
        self._now_ns = t_ns
        msg.clock.sec = t_ns // 1_000_000_000
        msg.clock.nanosec = t_ns % 1_000_000_000
        for ts in self.time_sources:
            set_time(ts, msg)
        self.clock_pub.publish(msg)

    def _rescan(self):
        if self.sink is not None:
            self._record_publishers()
        if self.bus is None:
            for node in self.nodes.values():
                self.counter.wrap_node(node)
        self._track()

    def _run_realtime(self, bar):
        # everything alive now (nodes, models, earlier runs' garbage) out of the collector's
        # sight: a full collection of a big heap inside the 1 kHz loop stalled it 55 ms (in
        # the benchmark, after lockstep runs in the same process); young collections remain
        gc.collect()
        gc.freeze()
        try:
            return self._run_realtime_inner(bar)
        finally:
            gc.unfreeze()

    def _run_realtime_inner(self, bar):
        if self.bus is not None:
            return self._run_realtime_local(bar)
        sc = self.scenario
        clock = self.runner_node.get_clock()
        start = clock.now().nanoseconds
        end = start + int(sc['duration'] * 1e9)
        last = 0.0
        self._sim_reached = 0.0
        next_scan = start
        while True:
            now = clock.now().nanoseconds
            self._now_ns = now
            if now >= end:
                break
            if self.stop_requested:
                raise KeyboardInterrupt
            self.executor.spin_once(timeout_sec=min(0.05, (end - now) * 1e-9))
            el = (clock.now().nanoseconds - start) * 1e-9
            self._sim_reached = min(el, sc['duration'])
            if now >= next_scan:
                self._rescan()
                next_scan = now + 200_000_000
            if bar is not None and el - last >= 0.1:
                bar.update(round(min(el, sc['duration']) - last, 3))
                last = min(el, sc['duration'])
        # let the recorder take what is still in flight
        t_end = time.perf_counter() + 0.5
        while not self._caught_up() and time.perf_counter() < t_end:
            self.executor.spin_once(timeout_sec=0.01)
        return 0, self._sim_reached

    def _run_realtime_local(self, bar):
        """Real time on the system clock with the in-process bus: ready timers are called
        directly and what they publish is delivered at once; between timers the loop sleeps
        until the next one is due (no DDS, no wait-set construction per callback)."""
        sc = self.scenario
        clock = self.runner_node.get_clock()
        start = clock.now().nanoseconds
        end = start + int(sc['duration'] * 1e9)
        last = 0.0
        self._sim_reached = 0.0
        next_scan = start
        next_spin = start
        while True:
            now = clock.now().nanoseconds
            self._now_ns = now
            if now >= end:
                break
            if self.stop_requested:
                raise KeyboardInterrupt
            self._drain_bus(100000)
            if self.bus.external and now >= next_spin:
                # poll DDS in the idle gap before the next timer, not across it (unless overdue)
                slack = min((t.time_until_next_call() or 0 for t in self._timers
                             if not t.is_canceled()), default=1_000_000)
                if slack >= SPIN_SLACK_NS or now >= next_spin + 5 * EXTERNAL_SPIN_NS:
                    self._spin_external()
                    next_spin = now + EXTERNAL_SPIN_NS
            el = (clock.now().nanoseconds - start) * 1e-9
            self._sim_reached = min(el, sc['duration'])
            if now >= next_scan:
                self._rescan()
                if self.sink is not None and self.child_nodes:
                    if self.sink.discover():
                        self._track()
                next_scan = now + 200_000_000
            if bar is not None and el - last >= 0.1:
                bar.update(round(min(el, sc['duration']) - last, 3))
                last = min(el, sc['duration'])
            wait = min((t.time_until_next_call() or 0 for t in self._timers
                        if not t.is_canceled()), default=1_000_000)
            if self.bus.external:
                wait = min(wait, next_spin - now)
            wait = min(wait, end - clock.now().nanoseconds, 50_000_000)
            if wait > 60_000:
                time.sleep((wait - 50_000) * 1e-9)   # wake a little early: sleep overshoots
        return 0, self._sim_reached

    def _spin_external(self, limit: int = 50) -> None:
        """Handle what DDS delivered to subscriptions outside the bus (the worker's topics)."""
        spin_ready(self.executor, limit)
        self.bus.deliver_all()

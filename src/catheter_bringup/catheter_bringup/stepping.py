"""How a run moves the node graph forward: the lockstep steps (clock, timers, the bus, the
recorder) and the two real-time loops (the local bus on the system clock, or DDS with an
EventsExecutor). A mixin of `catheter_bringup.runner.ScenarioRunner`, which owns the state
these methods use (nodes, executor, bus, timers, recorder, scenario)."""
from __future__ import annotations

import time

from rosgraph_msgs.msg import Clock

from catheter_bringup.lockstep_peer import PASS_SPIN
from catheter_bringup.rclpy_adapter import (fire_timer, never_done, set_times, spin_for,
                                            spin_ready, timer_due_in_ns, timer_ready,
                                            wrap_timer_callback)
from catheter_bringup.realtime import (GcWatch, counts_since, cpu_delta, latency_stats,
                                       own_autogroup, quiet_gc, reset_priority,
                                       set_fifo_priority, set_nice, stream_stats, thread_cpu,
                                       hold_cpu_latency)

#: ns, real time with the local bus: how often DDS is polled for subscriptions outside the bus
#: (the image worker's 30 Hz topics). One poll builds an rclpy wait set, 0.3-1.4 ms measured:
#: every 2 ms that was the largest avoidable cost per 1 kHz tick; every 10 ms keeps up with
#: 30 Hz streams (adds at most 10 ms to their delivery)
EXTERNAL_SPIN_NS = 10_000_000
#: s, the longest a worker's event loop stays in the executor before it looks at stop
#: requests and rescans (`Stepping._run_realtime_events`)
EVENTS_SLICE_S = 0.05
#: ns, the least time to the next due timer for a DDS poll to start (a poll takes ~0.7 ms)
SPIN_SLACK_NS = 800_000
#: cascade keys (pass, node index, timer index) of what a drain delivers before its first
#: timer and in its executor spin (`Stepping._drain_bus`)
KEY_BEFORE = (0, 0, 0)
KEY_SPIN = (PASS_SPIN, 0, 0)


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

    def _drain_bus(self, max_callbacks: int, feed=None) -> int:
        """Lockstep drain: run every ready timer (nodes in start order, timers in creation
        order) and deliver what they publish, until no timer is ready and the bus is empty.
        Timers are called directly (rclpy's Python wait-set construction costs ~0.5 ms per
        wait); the executor is spun now and then for anything else (services, guards).

        ``self._key`` is the key of the cascade being delivered: (pass, node index, timer
        index) of the timer that started it (pass 1, 2, ...; 0 before the first timer,
        `PASS_SPIN` in the executor spin), which orders the recordings of a lockstep run
        split across processes (`catheter_bringup.lockstep_peer`). ``feed(pass, key)``
        (the vision process of such a run) delivers the main process's messages of that
        pass whose key is below ``key`` (None: all, returning whether later passes have
        any) at their place between this process's timers."""
        bus = self.bus
        n = 0
        progress = True
        self._key = KEY_BEFORE
        if feed is not None:
            feed(0, None)
        bus.deliver_all()
        # lockstep: time only moves between steps, so each timer's next due time is cached
        # and only timers due now are asked (refreshed on every rescan)
        cache = self.scenario['mode'] == 'lockstep'
        due = self._due
        now = self._now_ns
        tkey = self._timer_key
        p = 1
        while progress and n < max_callbacks:
            progress = False
            for tmr in self._timers:
                if feed is not None:
                    feed(p, tkey[id(tmr)])
                if cache and due.get(id(tmr), 0) > now:
                    continue
                ready = timer_ready(tmr)
                if ready is None:            # destroyed
                    continue
                if ready:
                    self._key = (p,) + tkey[id(tmr)]
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
            if feed is not None and feed(p, None):
                progress = True              # the main process's cascades of a later pass
            p += 1
        self._key = KEY_SPIN
        if feed is not None:
            feed(PASS_SPIN, None)
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
        peer = self.peer                   # the vision process of a split lockstep run
        self._step = 0
        self._publish_clock(0, msg)
        self.drain()
        self._step_done = 0
        if peer is not None:
            peer.step_done(0)
        last_bar = 0
        for k in range(1, n_steps + 1):
            self._step = k
            self._publish_clock(k * dt_ns, msg)
            if self.inject is not None:
                self._inject(k * dt_ns, 'pre')
                self.drain()
                self._inject(k * dt_ns, 'post')
            self.drain()
            self._step_done = k
            if peer is not None:
                peer.step_done(k)
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
            self.bus.queue.append((topic, data, None))

    def _publish_clock(self, t_ns: int, msg: Clock):
        self._now_ns = t_ns
        set_times(self.time_sources, t_ns)
        # /clock for tools outside the run (the nodes' time is set directly): a DDS publish
        # per step costs ~20-50 us, so only while someone listens
        if self.clock_pub.get_subscription_count() > 0:
            msg.clock.sec = t_ns // 1_000_000_000
            msg.clock.nanosec = t_ns % 1_000_000_000
            self.clock_pub.publish(msg)

    def _rescan(self):
        if self.sink is not None:
            self._record_publishers()
        if self.bus is None:
            for node in self.nodes.values():
                self.counter.wrap_node(node)
        self._track()

    def _wait_go(self) -> None:
        """A worker: wait until the run's other processes are ready (the go file exists)."""
        import os
        while self.go_file and not os.path.exists(self.go_file):
            if self.stop_requested:
                raise KeyboardInterrupt
            time.sleep(0.02)

    def _run_realtime(self, bar):
        from catheter_bringup.scenario import LINK_TOPICS, LOOP_PROCESSES, VISION_NICE
        self._wait_go()
        self._loop_t0 = time.perf_counter()
        info = self.realtime_info = {'process': self.process, 'scheduling': 'SCHED_OTHER'}
        prio = int(self.scenario.get('realtime_priority', 0))
        # the processes whose loops run at 1 kHz: the master and slave workers, or the one
        # process that holds every loop (not a recorder-only or vision process)
        loops = self.process in LOOP_PROCESSES or (self.process == 'main' and self.nodes
                                                    and not self.events_bus)
        fifo = set_fifo_priority(prio, self.log) if prio > 0 and loops else None
        if fifo:
            info['scheduling'] = fifo
        lat_us = int(self.scenario.get('realtime_cpu_latency_us', -1))
        latency = hold_cpu_latency(lat_us, self.log) if prio > 0 and loops and lat_us >= 0 \
            else None
        if latency is not None:
            info['scheduling'] += f', {latency!r}'
        old_nice = None
        if prio > 0 and self.process == 'vision':
            old_nice = set_nice(VISION_NICE, self.log)
            if old_nice is not None:
                info['scheduling'] = f'SCHED_OTHER nice {VISION_NICE}'
            group = own_autogroup(VISION_NICE, self.log)
            if group:
                info['scheduling'] += f', {group}'
        # everything alive now (nodes, models, earlier runs' garbage) out of the collector's
        # sight: a full collection of a big heap inside the 1 kHz loop stalled it 55 ms (in
        # the benchmark, after lockstep runs in the same process); young collections remain,
        # fewer of them (threshold raised)
        if self.bus is not None:
            # per stream: when it was published (rate, period) and the image -> tip force
            # latency, measured where they happen (a recorder in another process may miss some)
            from catheter_common import topics as T
            self.bus.times = {}
            self.bus.latency_topics = {T.TIP_WRENCH}
            self.bus.stamp_topics = set(LINK_TOPICS) if self.children is None else set()
            self.bus.wall_ns = time.time_ns
            dds_lost0 = dict(self.bus.dds_lost)
            # what this process puts on DDS besides its bus (a worker of layout split: only
            # what another process consumes, `split_run.worker_dds_topics`)
            info['dds_topics'] = 'all' if self.bus.dds else sorted(
                t for t in self.bus.dds_topics if t in self.bus.counts)
        undo = quiet_gc()
        watch = GcWatch().start()
        cpu0, threads0 = time.process_time(), thread_cpu()
        try:
            return self._run_realtime_inner(bar)
        finally:
            # what the process used while its loop ran: all threads, and per kind of thread
            info['cpu_s'] = time.process_time() - cpu0
            info['thread_cpu_s'] = cpu_delta(threads0, thread_cpu())
            watch.stop()
            undo()
            if fifo:
                reset_priority()
            if latency is not None:
                latency.close()
            if old_nice is not None:
                set_nice(old_nice, self.log)
            info['gc'] = watch.summary()
            info['loop_s'] = time.perf_counter() - self._loop_t0
            if self.bus is not None and self.bus.times is not None:
                info['streams'] = {t: stream_stats(v) for t, v in self.bus.times.items()
                                   if len(v) >= 10}
                # with when each was noted, where every publish of the topic gave one
                info['latency'] = {t: latency_stats(
                    v, times_s=self.bus.times.get(t) if len(self.bus.times.get(t, ())) == len(v)
                    else None) for t, v in self.bus.latency.items()}
                info['link_sent'] = {t: list(v) for t, v in self.bus.sent.items()}
                info['link_taken'] = {t: list(v) for t, v in self.bus.taken.items()}
                # what DDS reported lost of them while the loop ran (transport / sender)
                info['link_dds_lost'] = counts_since(dds_lost0, self.bus.dds_lost,
                                                     self.bus.stamp_topics)
                self.bus.times = None

    def _run_realtime_inner(self, bar):
        if self.bus is not None and self.events_bus:
            return self._run_realtime_events(bar)
        if self.bus is not None:
            return self._run_realtime_local(bar)
        for _clock, now, end in self._wall_loop(bar):
            self.executor.spin_once(timeout_sec=min(0.05, (end - now) * 1e-9))
        # let the recorder take what is still in flight
        t_end = time.perf_counter() + 0.5
        while not self._caught_up() and time.perf_counter() < t_end:
            self.executor.spin_once(timeout_sec=0.01)
        return 0, self._sim_reached

    def _wall_loop(self, bar):
        """The iterations of a real-time loop on the runner's clock, until the scenario's
        duration has passed: yields ``(clock, now_ns, end_ns)``; a stop request raises
        KeyboardInterrupt. Before each iteration, the upkeep (`_upkeep`)."""
        clock = self.runner_node.get_clock()
        start = clock.now().nanoseconds
        end = start + int(self.scenario['duration'] * 1e9)
        last = 0.0
        self._sim_reached = 0.0
        next_scan = start
        while True:
            now = clock.now().nanoseconds
            self._now_ns = now
            if now >= end:
                return
            if self.stop_requested:
                raise KeyboardInterrupt
            next_scan, last = self._upkeep(clock, now, start, next_scan, bar, last)
            yield clock, now, end

    def _upkeep(self, clock, now: int, start: int, next_scan: int, bar, last: float):
        """Per-iteration upkeep of the real-time loops: the time reached, a rescan for new
        nodes' entities (and topics to record from worker processes) every 200 ms, the
        progress bar. Returns the next scan time and the progress shown."""
        dur = self.scenario['duration']
        el = (clock.now().nanoseconds - start) * 1e-9
        self._sim_reached = min(el, dur)
        if now >= next_scan:
            self._rescan()
            if self.sink is not None and self.child_nodes and self.sink.discover():
                self._track()
            next_scan = now + 200_000_000
        if bar is not None and el - last >= 0.1:
            bar.update(round(min(el, dur) - last, 3))
            last = min(el, dur)
        return next_scan, last

    def _run_realtime_local(self, bar):
        """Real time on the system clock with the in-process bus: ready timers are called
        directly and what they publish is delivered at once; between timers the loop sleeps
        until the next one is due (no DDS, no wait-set construction per callback)."""
        next_spin = None
        for clock, now, end in self._wall_loop(bar):
            if next_spin is None:
                next_spin = now            # the first external spin is due at the start
            self._drain_bus(100000)
            if self.bus.external and now >= next_spin:
                # poll DDS in the idle gap before the next timer, not across it (unless overdue)
                slack = min((t.time_until_next_call() or 0 for t in self._timers
                             if not t.is_canceled()), default=1_000_000)
                if slack >= SPIN_SLACK_NS or now >= next_spin + 5 * EXTERNAL_SPIN_NS:
                    self._spin_external()
                    next_spin = now + EXTERNAL_SPIN_NS
            wait = min((t.time_until_next_call() or 0 for t in self._timers
                        if not t.is_canceled()), default=1_000_000)
            if self.bus.external:
                wait = min(wait, next_spin - now)
            wait = min(wait, end - clock.now().nanoseconds, 50_000_000)
            if wait > 60_000:
                time.sleep((wait - 50_000) * 1e-9)   # wake a little early: sleep overshoots
        return 0, self._sim_reached

    def _run_realtime_events(self, bar):
        """Real time in a worker process: the EventsExecutor fires the timers on the system
        clock (an rcl timer is due a whole number of periods after its start, so lateness
        never accumulates) and takes what DDS delivers from the other processes; what a
        callback publishes reaches this process's subscribers through the bus at once.

        The executor's own loop (C++) runs for up to `EVENTS_SLICE_S` at a time
        (``spin_until_future_complete`` on a future nobody completes): one ``spin_once`` per
        event returned to this Python loop thousands of times a second in the master
        process, with a clock read each time. A stop request is seen within one slice."""
        sc = self.scenario
        start = time.time_ns()             # the nodes' clock in real time: the system clock
        end = start + int(sc['duration'] * 1e9)
        self._sim_reached = 0.0
        from catheter_bringup.realtime import align_timers
        align_timers(self._timers)         # one wake-up per period for a process's 1 kHz timers
        self._time_timers()
        next_scan = start + 200_000_000
        never = never_done()
        while True:
            now = time.time_ns()
            if now >= end:
                break
            if self.stop_requested:
                raise KeyboardInterrupt
            left = min(EVENTS_SLICE_S, (end - now) * 1e-9, (next_scan - now) * 1e-9)
            spin_for(self.executor, max(left, 1e-4), never)
            now = time.time_ns()
            if self.part is not None:
                self.part.flush()         # the recording's buffer to its writer process
            if now >= next_scan:
                self._now_ns = now
                self._sim_reached = min((now - start) * 1e-9, sc['duration'])
                self._rescan()
                self._time_timers()
                next_scan = now + 200_000_000
        self._sim_reached = min((time.time_ns() - start) * 1e-9, sc['duration'])
        return 0, self._sim_reached

    def _time_timers(self) -> None:
        """Events loop: each timer's callback timed into the bus's per-node cost (its own
        work, without the deliveries its publishes cause)."""
        done = self.__dict__.setdefault('_timed_timers', set())
        for tmr in self._timers:
            if id(tmr) in done:
                continue
            done.add(id(tmr))
            owner = self._timer_owner.get(id(tmr), '?')
            wrap_timer_callback(tmr, lambda f, _o=owner, _b=self.bus: (lambda: _b.timed(_o, f)))

    def _spin_external(self, limit: int = 50) -> None:
        """Handle what DDS delivered to subscriptions outside the bus (the worker's topics)."""
        spin_ready(self.executor, limit)
        self.bus.deliver_all()

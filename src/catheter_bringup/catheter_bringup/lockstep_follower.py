"""The vision process of a lockstep run: ``python -m catheter_bringup.lockstep_follower PLAN``.

Started by `catheter_bringup.lockstep_peer.VisionPeer` (see there for the why and the
frames). It builds the plan's nodes in lockstep (a `ScenarioRunner` with ``only``), and
then follows the main process step by step, behind it:

- it reads the main process's frames from stdin: the inputs its nodes subscribe to (each
  with its step and cascade key) and watermarks ("steps up to k are complete"); for each
  complete step it sets its nodes' sim time, runs its timers in the run's global order
  and delivers each input between them at the place the one-process run delivered it
  (`Stepping._drain_bus` with a feed);
- what its nodes publish (the recorded topics) goes to stdout with step and key, then a
  watermark of the steps done; at the end a report (status, published per topic, callback
  cost, CPU): ``failed`` when a node raised, or published while taking an input (a
  cascade across the processes, whose order in the recording could not be reproduced).

Its life is its pipes: SIGINT, SIGTERM and SIGHUP are ignored (a Ctrl-C to the process
group stops the main process, which ends this one after the steps it completed); the main
process gone (stdin closed) ends it at once.
"""
from __future__ import annotations

import json
import os
import signal
import sys
import time
from typing import Dict, List

from catheter_bringup.lockstep_peer import (END, ERROR, FRAME, MSG, PASS_SPIN, READY,
                                            REPORT, STEP, frame, parse_frames,
                                            set_pipe_size)

#: bytes of output after which the follower writes it out (before: at each wait for input)
OUT_BYTES = 256 * 1024


class CrossingCascade(RuntimeError):
    """A vision node published while taking an input from the main process."""


class Feed:
    """The main process's inputs of one step, delivered at their places
    (`Stepping._drain_bus`'s ``feed``)."""

    def __init__(self, bus):
        self.bus = bus
        self.by_pass: Dict[int, list] = {}
        self.pos: Dict[int, int] = {}
        #: True while an input is being delivered (a publish then is refused)
        self.active = False

    def load(self, items) -> None:
        """items: (pass, (node, timer), topic, data) in the main process's publish order."""
        self.by_pass = {}
        self.pos = {}
        for p, key, topic, data in items:
            self.by_pass.setdefault(p, []).append((key, topic, data))
        for p in self.by_pass:
            self.pos[p] = 0

    def __call__(self, p: int, key) -> bool:
        lst = self.by_pass.get(p)
        if lst:
            i = self.pos[p]
            j = i
            while j < len(lst) and (key is None or lst[j][0] < key):
                j += 1
            if j > i:
                q = self.bus.queue
                for _k, topic, data in lst[i:j]:
                    q.append((topic, data, None))
                self.pos[p] = j
                self.active = True
                try:
                    self.bus.deliver_all()
                finally:
                    self.active = False
        if key is None:
            return any(q > p and q != PASS_SPIN for q in self.by_pass)
        return False


class Follower:
    """Runs the plan's nodes behind the main process (see the module docstring)."""

    def __init__(self, runner, plan: dict, rfd: int, wfd: int):
        self.runner = runner
        self.rfd, self.wfd = rfd, wfd
        self.out = bytearray()
        self.inbuf = bytearray()
        self.dt_ns = int(round(float(runner.scenario['step']) * 1e9))
        bus = runner.bus
        nodes = list(runner.nodes.values())
        produced = {p.topic_name for n in nodes for p in n.publishers}
        subscribed = {s.topic_name for n in nodes for s in n.subscriptions}
        #: what the nodes take from the main process: delivered through the bus
        self.inputs: List[str] = sorted(subscribed - produced)
        for t in self.inputs:
            bus.counts.setdefault(t, 0)
        runner._track()
        self.topics: List[dict] = []
        self.tids: Dict[str, int] = {}
        if plan.get('record'):
            from catheter_bringup.local_recording import wanted
            from catheter_bringup.rclpy_adapter import count_extra_subscriber
            from catheter_bringup.ros_recording import qos_to_dict, type_name_of
            rec = runner.scenario['record']
            for n in nodes:
                for pub in n.publishers:
                    topic = pub.topic_name
                    if not wanted(topic, rec['exclude'], rec.get('only') or None):
                        continue
                    # the main process's recorder is a subscriber of it, as in one process
                    count_extra_subscriber(pub)
                    if topic not in self.tids:
                        self.tids[topic] = len(self.topics)
                        self.topics.append({'topic': topic, 'type': type_name_of(pub.msg_type),
                                            'qos': [qos_to_dict(pub.qos_profile)]})
        self.feed = Feed(bus)
        bus.record = self._record
        self.pending: Dict[int, list] = {}     # step -> inputs
        self.k = -1                            # the last step run
        self.ended = False                     # the main process said END
        self.eof = False                       # the main process's pipe closed

    def ready_info(self) -> dict:
        r = self.runner
        return {'nodes': list(r.nodes), 'skipped': r.skipped, 'start_errors': r.start_errors,
                'fallbacks': r.fallbacks, 'inputs': self.inputs, 'topics': self.topics,
                'publishes': sorted({p.topic_name for n in r.nodes.values()
                                     for p in n.publishers})}

    def _record(self, topic: str, data: bytes) -> None:
        if self.feed.active:
            r = self.runner
            raise CrossingCascade(
                f'a vision node published {topic} while taking an input from the main '
                f'process (step {r._step}): that cascade crosses the processes and its order '
                'in the recording cannot be reproduced; run with lockstep_processes: 1')
        tid = self.tids.get(topic)
        if tid is not None:
            r = self.runner
            self.out += FRAME.pack(MSG, r._step, *r._key, tid, len(data))
            self.out += data
            if len(self.out) >= OUT_BYTES:
                self.flush()

    def flush(self) -> None:
        if self.out:
            _write_all(self.wfd, self.out)
            self.out.clear()

    def serve(self) -> None:
        """Follow the main process until its END (or its pipe closes)."""
        from rosgraph_msgs.msg import Clock
        clock = Clock()
        r = self.runner
        while not self.ended:
            self.flush()
            b = os.read(self.rfd, 1 << 20)
            if not b:
                self.eof = True            # the main process is gone
                break
            self.inbuf += b
            target = self.k
            for kind, step, key, tid, body in parse_frames(self.inbuf):
                if kind == MSG:
                    self.pending.setdefault(step, []).append(
                        (key[0], key[1:], self.inputs[tid], body))
                elif kind == STEP:
                    target = max(target, step)
                elif kind == END:
                    self.ended = True
            for k in range(self.k + 1, target + 1):
                self.feed.load(self.pending.pop(k, ()))
                r._step = k
                r._publish_clock(k * self.dt_ns, clock)
                r._drain_bus(100000, self.feed)
                self.k = k
                r._step_done = k
                r._sim_reached = k * self.dt_ns * 1e-9
                if k % 64 == 0 and k > 0:
                    r._rescan()
            if target >= 0:
                self.out += FRAME.pack(STEP, self.k, 0, 0, 0, 0, 0)


def _write_all(fd: int, data) -> None:
    view = memoryview(data)
    while view:
        n = os.write(fd, view)
        view = view[n:]


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 1:
        print('usage: python -m catheter_bringup.lockstep_follower PLAN.json', file=sys.stderr)
        return 2
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, signal.SIG_IGN)
    rfd = sys.stdin.buffer.fileno()
    # nothing but frames on the pipe to the main process: whatever writes to stdout (a
    # print, C code) goes to stderr instead
    wfd = os.dup(sys.stdout.buffer.fileno())
    sys.stdout.flush()
    os.dup2(sys.stderr.fileno(), sys.stdout.buffer.fileno())
    set_pipe_size(wfd)
    with open(argv[0]) as f:
        plan = json.load(f)

    def fail(reason: str) -> int:
        try:
            _write_all(wfd, frame(ERROR, body=json.dumps({'reason': reason}).encode()))
        except OSError:
            pass
        return 1

    from catheter_bringup.runner import ScenarioRunner
    from catheter_bringup.scenario import NodeSpec
    reg = plan.get('registry')
    if reg is not None:
        reg = {k: NodeSpec(v['executable'], v['module'], tuple(v['consumes']),
                           tuple(v['produces']), v['kind']) for k, v in reg.items()}
    runner = ScenarioRunner(plan['scenario'], record=False, progress=False, registry=reg,
                            only=plan['nodes'], log=lambda m: print(m, file=sys.stderr))
    runner.process = 'vision'
    runner.node_order = list(plan['order'])
    try:
        runner.setup()
        follower = Follower(runner, plan, rfd, wfd)
        _write_all(wfd, frame(READY, body=json.dumps(follower.ready_info()).encode()))
    except Exception as exc:  # noqa: BLE001 - reported to the main process
        runner.close()
        return fail(f'{type(exc).__name__}: {exc}')
    t0, c0 = time.perf_counter(), time.process_time()
    status, reason = 'complete', ''
    try:
        follower.serve()
        if follower.eof:
            status, reason = 'interrupted', 'the main process ended without saying so'
    except Exception as exc:  # noqa: BLE001 - a node failed: reported, the run fails
        status, reason = 'failed', f'{type(exc).__name__}: {exc}'
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    sim = max(follower.k, 0) * follower.dt_ns * 1e-9
    res = runner._finish(status, reason, sim, wall, follower.k + 1)
    try:
        follower.flush()
        published = {t: n for t, n in res.published.items() if t not in follower.inputs}
        _write_all(wfd, frame(REPORT, body=json.dumps({
            'status': status, 'reason': reason, 'published': published, 'cost': res.cost,
            'steps': follower.k + 1, 'wall_s': wall, 'cpu_s': cpu,
            'cpu_total_s': time.process_time()}).encode()))
    except OSError:
        return 1                       # the main process is gone
    return 1 if status == 'failed' else 0


if __name__ == '__main__':
    sys.exit(main())

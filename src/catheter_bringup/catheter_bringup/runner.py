"""Launchless runner: a scenario's nodes in ONE process, in lockstep on a simulated clock or in
real time, every topic recorded into one MCAP file.

Lockstep: the runner's node (``run_scenario``) publishes rosgraph_msgs/Clock on /clock in steps
of ``scenario.step`` (1 ms); every node runs with ``use_sim_time``. After each step the executor
is drained: callbacks run until none is ready and the recorder holds every message published so
far, so a step's timers and the messages they produce are handled before time moves on. With one
seed two runs record the same message streams.

Real time: an EventsExecutor spins the nodes on the system clock for ``duration`` seconds.

Ctrl-C / SIGTERM (through the stop handlers of run_scenario, or a KeyboardInterrupt) or a
failing node stops the run; the recording is closed either way and its ``catheter_run``
metadata says how far the run got and why it stopped (which signal, or the node's error).

Layout split (real time): every node in a worker process (master, slave, vision; see
`catheter_bringup.scenario.PROCESSES`); each worker records its own nodes' messages into a
part file and this process merges the parts into the bag (`local_recording`).

Lockstep with the vision chain in a second process (the default when nothing else consumes
it; ``lockstep_processes: 1`` keeps one): `lockstep_peer` (this side), `lockstep_follower`
(the vision process); the recording is the one-process run's.

The parts: `node_start` (building the node instances), `bus` (the in-process transport and
the counters; `cdr_encode`), `stepping` (the lockstep and real-time loops),
`split_run` (the runner's side
of the split layout: DDS topics, part recording, starting the workers), `worker` (the worker
processes of multi-process real-time runs), `realtime` (scheduling, GC, real-time figures),
`rclpy_adapter` (every rclpy internal all of these use), `run_teardown` (the end of a run: the
recording closed, the result, everything released).
"""
from __future__ import annotations

import os
import pathlib
import signal
import sys
import threading
import time
from typing import Callable, Dict, List, Mapping, Optional

import rclpy
from rclpy.context import Context
from rclpy.node import Node
from rosgraph_msgs.msg import Clock

from catheter_bringup.bus import DeliveryTracker, LocalBus, PublishCounter
from catheter_bringup.local_recording import part_path
from catheter_bringup.lockstep_peer import VisionPeer, vision_plan
from catheter_bringup.lockstep_split import LockstepSplit
from catheter_bringup.part_pipe import PartPipe, RecorderPipe
from catheter_bringup.node_start import available_instances, start_node
from catheter_bringup.rclpy_adapter import detach_clock
from catheter_bringup.recorder import McapRecorder
from catheter_bringup.result import RunResult  # noqa: F401  (re-exported: part of the API)
from catheter_bringup.run_teardown import RunTeardown
from catheter_bringup.ros_recording import RecordingSink, type_name_of
from catheter_bringup.scenario import load_scenario, resolve_nodes, run_start_info
from catheter_bringup.split_run import SplitRun, worker_dds_topics
from catheter_bringup.stepping import KEY_BEFORE, Stepping
from catheter_bringup.worker import Workers
from catheter_common import qos as Q
from catheter_common import topics as T
from catheter_common.params import declare
from catheter_common.ros_node import STOP_SIGNALS, make_executor

RUNNER_NODE = 'run_scenario'
#: bytes, MCAP chunk size of real-time recordings (lockstep: 1 MB)
REALTIME_CHUNK = 64 * 1024




def _record_stop_signals(runner) -> dict:
    """Wrap the Python handlers of SIGINT and SIGTERM (whoever installed them: run_scenario's
    stop handlers, Python's KeyboardInterrupt) so `runner.stop_signal` records which signal
    came first; the old handler still runs. Returns the handlers to restore. Only in the
    main thread; a signal left at its default action keeps it."""
    old = {}
    if threading.current_thread() is not threading.main_thread():
        return old
    for sig in STOP_SIGNALS:
        prev = signal.getsignal(sig)
        if not callable(prev):
            continue

        def handler(signum, frame, _prev=prev):
            if runner.stop_signal is None:
                runner.stop_signal = signum
            _prev(signum, frame)

        signal.signal(sig, handler)
        old[sig] = prev
    return old


class ScenarioRunner(Stepping, SplitRun, LockstepSplit, RunTeardown):
    """Runs one scenario. ``scenario``: a dict from `load_scenario` (or a name/path).

    >>> res = ScenarioRunner('smoke', bag='bags/smoke.mcap').run()
    """

    def __init__(self, scenario, bag: Optional[str] = None, mode: Optional[str] = None,
                 duration: Optional[float] = None, progress: bool = True,
                 registry=None, record: Optional[bool] = None, log=print,
                 only: Optional[List[str]] = None, part_bag: Optional[str] = None):
        self.scenario = load_scenario(scenario) if not isinstance(scenario, Mapping) \
            else scenario
        if mode is not None:
            if mode not in ('lockstep', 'realtime'):
                raise ValueError(f'mode must be lockstep or realtime, got {mode!r}')
            self.scenario['mode'] = mode
        if duration is not None:
            if not duration >= 0:
                raise ValueError(f'duration must be >= 0, got {duration!r}')
            self.scenario['duration'] = float(duration)
        if self.scenario.get('layout', 'one') == 'split' and self.scenario['mode'] != 'realtime' \
                and not only:
            raise ValueError('layout split runs the graph as separate processes in real time: '
                             'use mode realtime (lockstep runs in one process)')
        self.registry = registry
        #: the name of this process in a multi-process run (a worker's), for logs and reports
        self.process = 'main'
        #: a worker process waits for this file before its loop starts (`Workers.go`)
        self.go_file: Optional[str] = None

        #: start only these node instances (a real-time worker process runs a subset)
        self.only = set(only) if only else None
        #: a worker of the split layout: record what its nodes publish into this part file
        #: (`catheter_bringup.local_recording`; the runner merges the parts into the bag)
        self.part_bag = part_bag
        self.part: Optional[PartPipe] = None
        #: layout split, recording: per worker process, its part file (merged at the end)
        self.parts: Dict[str, str] = {}
        #: after the merge: per worker process, what its part held (`merge_parts`)
        self.part_info: Dict[str, dict] = {}
        self.children: Optional[Workers] = None   # worker processes of a real-time run
        #: process name -> node instances that run in a worker process
        self.child_groups: Dict[str, List[str]] = {}
        self.child_nodes: List[str] = []
        self.progress = progress
        self.log = log
        do_record = self.scenario['record']['enabled'] if record is None else record
        if do_record and bag is None:
            root = pathlib.Path(os.environ.get('CATHETER_WS_ROOT', pathlib.Path.cwd()))
            bag = str(root / 'bags' / f"{self.scenario['name']}.mcap")
        self.bag = bag if do_record else None
        self.nodes: Dict[str, Node] = {}
        self.context: Optional[Context] = None
        self.runner_node: Optional[Node] = None
        self.executor = None
        self.recorder: Optional[McapRecorder] = None
        self.sink: Optional[RecordingSink] = None
        self.counter = PublishCounter()
        self.tracker = DeliveryTracker(self.counter.counts)
        self.bus: Optional[LocalBus] = None
        self.time_sources = []
        self._timers = []
        self._timer_owner = {}
        self._due = {}
        self._steps_since_spin = 0
        self._now_ns = 0
        self.on_step: Optional[Callable[[float], None]] = None
        #: set (e.g. by a signal handler) to stop the run after the current step
        self.stop_requested = False
        #: the signal that stopped the run (recorded by the wrapped handlers), or None
        self.stop_signal: Optional[int] = None
        self._old_handlers: dict = {}
        #: lockstep only: called with the step time (ns) and a phase, 'pre' (before the step's
        #: timers run) or 'post' (after them); returns (topic, cdr bytes) pairs delivered to the
        #: nodes as if published in that phase (reprocess)
        self.inject: Optional[Callable[[int, str], list]] = None
        #: the topics `inject` delivers (treated as published in this process)
        self.inject_topics = set()
        #: lockstep: the vision chain's process (`catheter_bringup.lockstep_peer`), its nodes
        self.peer: Optional[VisionPeer] = None
        self.peer_nodes: List[str] = []
        #: the run's node instances in start order (None: this process's); a lockstep
        #: vision process is given the main process's, so both number the nodes alike
        self.node_order: Optional[List[str]] = None
        self._node_index: Dict[str, int] = {}
        self._timer_key: Dict[int, tuple] = {}
        #: the cascade being delivered, the step running and the last step completed
        #: (`Stepping._drain_bus`, `_run_lockstep`)
        self._key = KEY_BEFORE
        self._step = 0
        self._step_done = -1

    # ------------------------------------------------------------------ setup
    def setup(self, context: Optional[Context] = None):
        sc = self.scenario
        self._old_handlers = _record_stop_signals(self)
        lockstep = sc['mode'] == 'lockstep'
        self.context = context or Context()
        self._own_context = context is None
        if self._own_context:
            # no rclpy signal handlers: Ctrl-C stays a plain KeyboardInterrupt that the run loop
            # turns into a clean stop (run_scenario installs a once-only handler)
            from rclpy.signals import SignalHandlerOptions
            rclpy.init(context=self.context, args=[],
                       signal_handler_options=SignalHandlerOptions.NO)
        self.runner_node = rclpy.create_node(RUNNER_NODE, context=self.context)
        declare(self.runner_node, 'scenario', sc['name'], 'scenario being run (read only)',
                read_only=True)
        self.clock_pub = self.runner_node.create_publisher(Clock, T.CLOCK, Q.QOS_DEFAULT)
        from catheter_bringup.scenario import instances
        cands = list(instances(sc, self.registry).values())
        classes = available_instances(cands)
        chosen, missing = resolve_nodes(sc, set(classes), self.registry)
        wanted_all, _ = resolve_nodes(sc, None, self.registry)
        if self.node_order is not None and self.only is not None:
            # a lockstep vision process: the main process resolved the graph (with nodes
            # this process may not import); it starts those of its own
            by_name = {i.name: i for i in cands}
            wanted_all = [by_name[n] for n in self.node_order if n in by_name]
            chosen = [i for i in wanted_all if i.name in classes]
        self._node_index = {n: k for k, n in enumerate(self.node_order
                                                        or [i.name for i in chosen])}
        vision = vision_plan(sc, chosen, self.inject) if self.only is None else []
        #: topics a node of another process of the run consumes (a worker publishes only
        #: these on DDS in layout split)
        self._consumed_elsewhere = set()
        if self.only is not None:
            self._consumed_elsewhere = {t for i in chosen if i.name not in self.only
                                        for t in i.spec.consumes}
            chosen = [i for i in chosen if i.name in self.only]
            wanted_all = [i for i in wanted_all if i.name in self.only]
        elif not lockstep and sc.get('layout', 'one') == 'split':
            # every node in a worker process (master, slave, vision); this process records
            from catheter_bringup.scenario import split_processes
            groups = split_processes(chosen, sc)
            self.child_groups = {g: [i.name for i in insts] for g, insts in groups.items()}
            self.child_nodes = [n for names in self.child_groups.values() for n in names]
            self._child_produces = {t for i in chosen for t in i.spec.produces}
            if self.bag and sc.get('realtime_transport', 'local') == 'local':
                # each worker records its own nodes' messages (no DDS hop, nothing lost);
                # this process merges the parts at the end
                self.parts = {g: part_path(self.bag, g) for g in self.child_groups}
            chosen, wanted_all = [], []
        elif (not lockstep and sc.get('realtime_processes', 2) >= 2
              and sc.get('realtime_transport', 'local') == 'local'
              and any(i.spec.kind == 'vision' for i in chosen)):
            # real time: the image pipeline (tens of ms per frame) runs in a worker process so
            # it never holds up the 1 kHz loops; messages between the two go through DDS
            worker = [i for i in chosen if i.spec.kind == 'vision']
            chosen = [i for i in chosen if i.spec.kind != 'vision']
            self.child_nodes = [i.name for i in worker]
            self.child_groups = {'vision': list(self.child_nodes)}
            self._child_produces = {t for i in worker for t in i.spec.produces}
            wanted_all = [i for i in wanted_all if i.name not in self.child_nodes]
            self._child_inputs = {t for i in worker for t in i.spec.consumes}
        elif vision:
            # lockstep: the vision chain (a pure observer here) in a process of its own,
            # pipelined behind this one; the recording merges both in one-process order
            self.peer = self._start_peer(vision, chosen)
            names = {i.name for i in vision}
            chosen = [i for i in chosen if i.name not in names]
            wanted_all = [i for i in wanted_all if i.name not in names]
        try:
            return self._setup_rest(sc, lockstep, chosen, wanted_all, classes, missing)
        except BaseException:
            if self.peer is not None:
                self.peer.kill()
                self.peer = None
            raise

    def _setup_rest(self, sc, lockstep, chosen, wanted_all, classes, missing):
        self.skipped = sorted({i.name for i in wanted_all} - {i.name for i in chosen})
        self.missing = missing
        self.start_errors = {}
        self.fallbacks = {}
        transport = sc.get('lockstep_transport' if lockstep else 'realtime_transport', 'local')
        if not lockstep and not chosen and self.child_nodes:
            transport = 'dds'            # layout split: this process only records, via DDS
        #: real time in a worker process: an EventsExecutor fires the timers and takes what
        #: DDS delivers; in-process topics go through the bus at once (`LocalBus.immediate`)
        self.events_bus = (not lockstep and transport == 'local' and self.only is not None)
        # the local bus (lockstep, one-process real time) calls timers itself and spins a
        # SingleThreadedExecutor now and then; real time through DDS spins an EventsExecutor
        single = lockstep or (transport == 'local' and not self.events_bus)
        self.executor = make_executor('single' if single else 'events', context=self.context)
        self.executor.add_node(self.runner_node)
        if transport == 'local':
            self.bus = LocalBus(dds=bool(sc.get('dds', False)), immediate=self.events_bus)
            self.counter = self.bus       # the bus counts what was published
            for t in self.inject_topics:
                self.bus.counts.setdefault(t, 0)
            if self.child_nodes:
                self.bus.dds_topics |= self._child_inputs
            if self.only is not None and not lockstep:
                self.bus.dds_topics |= worker_dds_topics(self._consumed_elsewhere)
                # a worker of layout one: its outputs go to the main process's recorder
                self.bus.dds = self.bus.dds or sc.get('layout', 'one') != 'split'
        # lockstep_transport: dds -> messages go through DDS, each step waits for delivery
        # (slower; kept as the reference the benchmark compares with)
        for inst in chosen:
            if self.stop_requested:
                break
            fb = (sc['nodes'].get(inst.name) or {}).get('fallback_params')
            try:
                node, used = start_node(classes[inst.name], inst, self.context, lockstep,
                                        fallback_params=fb, log=self.log)
            except Exception as exc:  # noqa: BLE001 - a node that cannot start is left out
                if sc.get('strict', False):
                    raise
                self.log(f'[run] {inst.name} failed to start, left out: '
                         f'{type(exc).__name__}: {exc}')
                self.skipped.append(inst.name)
                self.start_errors[inst.name] = f'{type(exc).__name__}: {exc}'
                continue
            if used:
                self.fallbacks[inst.name] = dict(fb)
            self.nodes[inst.name] = node
            self.executor.add_node(node)
            if not lockstep:
                # publishers counted from the start; subscriptions are taken over by _track
                # once every node's publishers are known
                if self.bus is not None:
                    self.bus.wrap_publishers(node)
                else:
                    self.counter.wrap_node(node)
            if lockstep:
                self._drive_clock_of(node)
        if self.part_bag and self.bus is not None:
            self._record_part()
        if self.peer is not None:
            self._peer_ready()
        if self.bag:
            # real time: small chunks (a killed run loses less); lockstep: 1 MB
            chunk = REALTIME_CHUNK if not lockstep else 1 << 20
            if self.parts:
                # layout split: the workers record; this process merges their parts at the end
                self.recorder = McapRecorder(self.bag, chunk_size=chunk)
            else:
                # written by a writer process (`part_pipe`): the run's loop hands over bytes,
                # the exact-length walk, mcap and zstd run on the other core
                self.recorder = RecorderPipe(self.bag, chunk_size=chunk)
                # split lockstep: the vision peer keeps what this process records until
                # the vision process has done the same steps, and writes both merged
                self.sink = RecordingSink(self.runner_node, self.peer or self.recorder,
                                          exclude=sc['record']['exclude'],
                                          only=sc['record'].get('only') or None)
                self.sink.now_ns = (lambda: self._now_ns) if lockstep else None
                # lockstep on the bus: delivery order is publish order, nothing to sort
                self.sink.buffered = lockstep and self.peer is None
                if self.peer is not None:
                    self.peer.attach(self, self.recorder, self.sink.received)
                self._record_publishers()
            # what the run is, in the file before the first step: a run killed with SIGKILL
            # still says it (recover_bag carries it over; analyze reads it)
            self.recorder.start(run_start_info(sc, list(self.nodes) + self.peer_nodes))
        elif self.peer is not None:
            self.peer.attach(self, None, None)
        self._track()
        if self.child_groups:
            self._start_children()
        return self

    def _drive_clock_of(self, node: Node):
        """Lockstep: the runner sets the node's sim time directly each step (what its /clock
        subscription would do, but immediately and in order, so a step's timers are ready in
        the same step). The node's own /clock subscription is removed so a late /clock sample
        can never move its time back. /clock is still published for everyone else."""
        ts = detach_clock(node)
        if ts is not None:
            self.time_sources.append(ts)

    def _track(self):
        self._timers = [t for node in self.nodes.values() for t in node.timers]
        idx = self._node_index
        self._timer_key = {id(t): (idx.get(name, k), j)
                           for k, (name, node) in enumerate(self.nodes.items())
                           for j, t in enumerate(node.timers)}
        self._timer_owner = {id(t): name for name, node in self.nodes.items()
                             for t in node.timers}
        self._due = {}
        if self.bus is not None:
            for node in self.nodes.values():
                self.bus.wrap_publishers(node)
            for node in list(self.nodes.values()) + [self.runner_node]:
                self.bus.wrap_subscriptions(node)
        else:
            for node in list(self.nodes.values()) + [self.runner_node]:
                self.tracker.wrap_node(node)

    def _record_publishers(self):
        """Subscribe the recorder to every publisher of the scenario's nodes (known up front:
        no discovery delay, nothing lost at start)."""
        for node in self.nodes.values():
            if self.bus is None:
                self.counter.wrap_node(node)
            for pub in list(node.publishers):
                if self.sink.wants(pub.topic_name):
                    self.sink.add(pub.topic_name, type_name_of(pub.msg_type), [pub.qos_profile])

    # ------------------------------------------------------------------ run
    def run(self) -> RunResult:
        if self.runner_node is None:
            self.setup()
        sc = self.scenario
        status, reason = 'complete', ''
        t0 = time.perf_counter()
        steps = 0
        sim = 0.0
        bar = None
        try:
            if self.progress:
                from tqdm import tqdm
                fmt = ('{desc}: {percentage:3.0f}%|{bar}| {n:.2f}/{total:.2f} s '
                       '[{elapsed}<{remaining}{postfix}]')
                bar = tqdm(total=round(sc['duration'], 3), unit='s', desc=sc['name'],
                           mininterval=0.5, bar_format=fmt, file=sys.stderr)
            if sc['mode'] == 'lockstep':
                steps, sim = self._run_lockstep(bar)
            else:
                steps, sim = self._run_realtime(bar)
        except KeyboardInterrupt:
            status, reason = 'interrupted', self._stop_reason()
        except Exception as exc:  # a node failed: stop, close the recording, report
            status, reason = 'failed', f'{type(exc).__name__}: {exc}'
        finally:
            if bar is not None:
                bar.close()
            wall = time.perf_counter() - t0
            sim = self._sim_reached if hasattr(self, '_sim_reached') else sim
            if sc['mode'] == 'lockstep':
                # the steps completed, also when a stop or a failure cut the run short (the
                # loop's return value never came: it said 0 steps for an interrupted run)
                steps = max(self._step_done, 0)
            result = self._finish(status, reason, sim, wall, steps)
        return result

    def _stop_reason(self) -> str:
        if self.stop_signal is not None:
            return STOP_SIGNALS.get(self.stop_signal, f'signal {self.stop_signal}')
        if self.stop_requested:
            return 'stop requested'
        return 'KeyboardInterrupt'


def run_scenario(scenario, **kwargs) -> RunResult:
    """Load, set up, run and close: the one-call API."""
    return ScenarioRunner(scenario, **kwargs).run()

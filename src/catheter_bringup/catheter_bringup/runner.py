"""Launchless runner: a scenario's nodes in ONE process, in lockstep on a simulated clock or in
real time, every topic recorded into one MCAP file.

Lockstep: the runner's node (``run_scenario``) publishes rosgraph_msgs/Clock on /clock in steps
of ``scenario.step`` (1 ms); every node runs with ``use_sim_time``. After each step the executor
is drained: callbacks run until none is ready and the recorder holds every message published so
far, so a step's timers and the messages they produce are handled before time moves on. With one
seed two runs record the same message streams.

Real time: an EventsExecutor spins the nodes on the system clock for ``duration`` seconds.

Ctrl-C (KeyboardInterrupt) or a failing node stops the run; the recording is closed either way
and its ``catheter_run`` metadata says how far the run got and why it stopped.
"""
from __future__ import annotations

import dataclasses
import datetime
import gc
import importlib
import os
import pathlib
import sys
import time
import types
from typing import Callable, Dict, List, Mapping, Optional

import rclpy
from rclpy.context import Context
from rclpy.executors import TimeoutException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock

from catheter_bringup.recorder import McapRecorder
from catheter_bringup.ros_recording import RecordingSink, type_name_of
from catheter_bringup.scenario import NodeInstance, load_scenario, resolve_nodes
from catheter_common import topics as T
from catheter_common import qos as Q
from catheter_common.ros_node import declare, make_executor

RUNNER_NODE = 'run_scenario'
#: bytes, MCAP chunk size of real-time recordings (lockstep: 1 MB)
REALTIME_CHUNK = 64 * 1024
#: ns, real time with the local bus: how often DDS is polled for subscriptions outside the bus
#: (the image worker's 30 Hz topics). One poll builds an rclpy wait set, 0.3-1.4 ms measured:
#: every 2 ms that was the largest avoidable cost per 1 kHz tick; every 10 ms keeps up with
#: 30 Hz streams (adds at most 10 ms to their delivery)
EXTERNAL_SPIN_NS = 10_000_000
#: ns, the least time to the next due timer for a DDS poll to start (a poll takes ~0.7 ms)
SPIN_SLACK_NS = 800_000


@dataclasses.dataclass
class RunResult:
    """What a run did. Times in seconds; counts per topic."""
    scenario: str
    status: str                  # complete | interrupted | failed
    reason: str
    bag: Optional[str]
    sim_time: float              # simulated (lockstep) or elapsed (real time) seconds reached
    wall_time: float
    steps: int
    nodes: List[str]
    skipped: List[str]           # node instances that could not be imported
    missing_outputs: List[str]   # wanted topics nobody produces
    published: Dict[str, int]
    recorded: Dict[str, int]
    cost: Dict[str, dict] = dataclasses.field(default_factory=dict)   # per node callback time

    @property
    def lost(self) -> Dict[str, int]:
        """Per recorded topic: published in this process but not in the recording."""
        return {t: self.published[t] - self.recorded.get(t, 0)
                for t in self.recorded
                if t in self.published and self.published[t] != self.recorded.get(t, 0)}

    @property
    def realtime_factor(self) -> float:
        return self.sim_time / self.wall_time if self.wall_time > 0 else float('inf')


def _to_param_value(v):
    if isinstance(v, tuple):
        v = list(v)
    if isinstance(v, list) and v and all(isinstance(x, (int, float)) and not isinstance(x, bool)
                                         for x in v) and any(isinstance(x, float) for x in v):
        v = [float(x) for x in v]
    return v


def load_node_class(module: str):
    mod = importlib.import_module(module)
    cls = getattr(mod, 'NODE_CLASS', None)
    if cls is None:
        raise ImportError(f'{module} defines no NODE_CLASS')
    return cls


def available_instances(candidates: List[NodeInstance]) -> Dict[str, object]:
    """name -> node class for every instance whose module imports."""
    out = {}
    for inst in candidates:
        try:
            out[inst.name] = load_node_class(inst.spec.module)
        except ImportError:
            continue
    return out


class PublishCounter:
    """Counts what every publisher of the given nodes published (per topic), by wrapping
    each publisher's ``publish`` once."""

    def __init__(self):
        self.counts: Dict[str, int] = {}
        self._wrapped = set()
        self.on_publish: Optional[Callable[[str], None]] = None

    def wrap_node(self, node: Node) -> List[object]:
        new = []
        for pub in list(node.publishers):
            if id(pub) in self._wrapped:
                continue
            self._wrapped.add(id(pub))
            topic = pub.topic_name
            self.counts.setdefault(topic, 0)
            orig = pub.publish
            counts = self.counts

            def publish(self_pub, msg, _orig=orig, _topic=topic):
                _orig(msg)
                counts[_topic] += 1

            pub.publish = types.MethodType(publish, pub)
            new.append(pub)
        return new


class CallbackCost:
    """Wall time spent in each node's callbacks (timers and deliveries), s."""

    def __init__(self):
        self.samples: Dict[str, list] = {}

    def add(self, node: str, dt: float) -> None:
        self.samples.setdefault(node, []).append(dt)

    def summary(self, wall: float) -> Dict[str, dict]:
        import numpy as np
        out = {}
        for node, xs in sorted(self.samples.items()):
            a = np.asarray(xs)
            out[node] = {'callbacks': int(a.size), 'mean_ms': float(a.mean() * 1e3),
                         'p99_ms': float(np.percentile(a, 99) * 1e3),
                         'max_ms': float(a.max() * 1e3), 'total_s': float(a.sum()),
                         'share': float(a.sum() / wall) if wall > 0 else float('nan')}
        return out


class LocalBus:
    """Lockstep transport between the runner's nodes: every publish is serialised once, counted
    and queued; `deliver_all` hands each queued message, in publish order, to every in-process
    subscription of its topic (raw subscriptions get the bytes, the others a fresh deserialised
    copy). Deterministic and without DDS delivery latency. The nodes' own DDS subscriptions
    stay (subscription counts, "work only while subscribed" keep working) but what DDS delivers
    to them is dropped. With ``dds=True`` every message is also published on DDS, for tools
    outside the process."""

    def __init__(self, dds: bool = False):
        import collections
        self.queue = collections.deque()
        self.counts: Dict[str, int] = {}
        self.delivered = 0
        self.dds = dds
        self.subs: Dict[str, list] = {}
        self.cost = CallbackCost()
        #: topics also published on DDS (their subscribers run in another process)
        self.dds_topics = set()
        #: ids of subscriptions left to DDS (no publisher of their topic in this process)
        self.external = set()
        self._pubs = set()
        self._subs = set()

    def wrap_node(self, node: Node, publishers: bool = True) -> None:
        self.wrap_publishers(node) if publishers else None
        self.wrap_subscriptions(node)

    def wrap_publishers(self, node: Node) -> None:
        from rclpy.serialization import serialize_message
        for pub in list(node.publishers):
            if id(pub) in self._pubs:
                continue
            self._pubs.add(id(pub))
            topic = pub.topic_name
            self.counts.setdefault(topic, 0)
            orig = pub.publish
            bus = self

            def publish(self_pub, msg, _orig=orig, _topic=topic, _type=pub.msg_type):
                data = msg if isinstance(msg, bytes) else serialize_message(msg)
                if bus.dds or _topic in bus.dds_topics:
                    _orig(msg)
                bus.counts[_topic] += 1
                bus.queue.append((_topic, data))

            pub.publish = types.MethodType(publish, pub)

    def wrap_subscriptions(self, node: Node) -> None:
        for sub in list(node.subscriptions):
            if id(sub) in self._subs:
                continue
            if sub.topic_name not in self.counts:
                # nobody in this process publishes it (yet): DDS delivers it, the runner spins
                # the executor for it
                self.external.add(id(sub))
                continue
            self.external.discard(id(sub))
            self._subs.add(id(sub))
            with_info = getattr(sub, '_callback_type', None) is not None and \
                sub._callback_type.name != 'MessageOnly'
            self.subs.setdefault(sub.topic_name, []).append(
                (sub.callback, bool(sub.raw), sub.msg_type, with_info, node.get_name()))
            sub.callback = _drop

    def deliver_all(self) -> int:
        from rclpy.serialization import deserialize_message
        n = 0
        q = self.queue
        clock = time.perf_counter
        cost = self.cost
        while q:
            topic, data = q.popleft()
            for cb, raw, msg_type, with_info, owner in self.subs.get(topic, ()):
                t = clock()
                msg = data if raw else deserialize_message(data, msg_type)
                if with_info:
                    cb(msg, {})
                else:
                    cb(msg)
                cost.add(owner, clock() - t)
                n += 1
        self.delivered += n
        return n


def _drop(*_args):
    """Callback of a DDS delivery that the lockstep bus already delivered."""


class DeliveryTracker:
    """Counts what every subscription of the given nodes took, to know when every message
    published in this process has been handled (lockstep drain)."""

    def __init__(self, published: Dict[str, int]):
        self.published = published
        self.subs: List[list] = []          # [subscription, topic, base, taken]
        self._wrapped = set()

    def wrap_node(self, node: Node) -> None:
        for sub in list(node.subscriptions):
            if id(sub) in self._wrapped:
                continue
            self._wrapped.add(id(sub))
            entry = [sub, sub.topic_name, self.published.get(sub.topic_name, 0), 0]
            self.subs.append(entry)
            orig = sub.callback

            def callback(*args, _orig=orig, _e=entry):
                _e[3] += 1
                return _orig(*args)

            sub.callback = callback

    def pending(self) -> int:
        """Messages published in this process that some subscription has not taken yet."""
        n = 0
        for sub, topic, base, taken in self.subs:
            p = self.published.get(topic)
            if p is not None and p - base > taken:
                n += p - base - taken
        return n


class ScenarioRunner:
    """Runs one scenario. ``scenario``: a dict from `load_scenario` (or a name/path).

    >>> res = ScenarioRunner('smoke', bag='bags/smoke.mcap').run()
    """

    def __init__(self, scenario, bag: Optional[str] = None, mode: Optional[str] = None,
                 duration: Optional[float] = None, progress: bool = True,
                 registry=None, record: Optional[bool] = None, log=print,
                 only: Optional[List[str]] = None):
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
        self.registry = registry
        #: start only these node instances (a real-time worker process runs a subset)
        self.only = set(only) if only else None
        self.child = None             # the worker process of a split real-time run
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
        #: lockstep only: called with the step time (ns) and a phase, 'pre' (before the step's
        #: timers run) or 'post' (after them); returns (topic, cdr bytes) pairs delivered to the
        #: nodes as if published in that phase (reprocess)
        self.inject: Optional[Callable[[int, str], list]] = None
        #: the topics `inject` delivers (treated as published in this process)
        self.inject_topics = set()

    # ------------------------------------------------------------------ setup
    def _params_for(self, inst: NodeInstance, lockstep: bool) -> List[Parameter]:
        sc = self.scenario
        params = {'use_sim_time': lockstep}
        params.update({k: _to_param_value(v) for k, v in inst.params.items()})
        return [Parameter(k, value=v) for k, v in params.items()]

    def setup(self, context: Optional[Context] = None):
        sc = self.scenario
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
        if self.only is not None:
            chosen = [i for i in chosen if i.name in self.only]
            wanted_all = [i for i in wanted_all if i.name in self.only]
        elif (not lockstep and sc.get('realtime_processes', 2) >= 2
              and sc.get('realtime_transport', 'local') == 'local'
              and any(i.spec.kind == 'vision' for i in chosen)):
            # real time: the image pipeline (tens of ms per frame) runs in a worker process so
            # it never holds up the 1 kHz loops; messages between the two go through DDS
            worker = [i for i in chosen if i.spec.kind == 'vision']
            chosen = [i for i in chosen if i.spec.kind != 'vision']
            self.child_nodes = [i.name for i in worker]
            wanted_all = [i for i in wanted_all if i.name not in self.child_nodes]
            self._child_inputs = {t for i in worker for t in i.spec.consumes}
        self.skipped = sorted({i.name for i in wanted_all} - {i.name for i in chosen})
        self.missing = missing
        self.start_errors = {}
        self.fallbacks = {}
        transport = sc.get('lockstep_transport' if lockstep else 'realtime_transport', 'local')
        # the local bus calls timers itself and spins a SingleThreadedExecutor now and then;
        # real time through DDS spins an EventsExecutor
        self.executor = make_executor('single' if lockstep or transport == 'local' else 'events',
                                      context=self.context)
        self.executor.add_node(self.runner_node)
        if transport == 'local':
            self.bus = LocalBus(dds=bool(sc.get('dds', False)))
            self.counter = self.bus       # the bus counts what was published
            for t in self.inject_topics:
                self.bus.counts.setdefault(t, 0)
            if self.child_nodes:
                self.bus.dds_topics |= self._child_inputs
            if self.only is not None and not lockstep:
                self.bus.dds = True       # a worker: its outputs go to the main process
        # lockstep_transport: dds -> messages go through DDS, each step waits for delivery
        # (slower; kept as the reference the benchmark compares with)
        for inst in chosen:
            if self.stop_requested:
                break
            cli = []
            if inst.name != inst.spec.executable:
                cli += ['-r', f'__node:={inst.name}']
            for a, b in inst.remap.items():
                cli += ['-r', f'{a}:={b}']
            kwargs = dict(context=self.context,
                          parameter_overrides=self._params_for(inst, lockstep))
            if cli:
                kwargs['cli_args'] = ['--ros-args'] + cli
            try:
                try:
                    node = classes[inst.name](**kwargs)
                except Exception as first:  # noqa: BLE001
                    fb = (sc['nodes'].get(inst.name) or {}).get('fallback_params')
                    if not fb:
                        raise
                    self.log(f'[run] {inst.name} failed to start ({type(first).__name__}: '
                             f'{first}); retrying with {fb}')
                    params = dict(inst.params)
                    params.update(fb)
                    kwargs['parameter_overrides'] = self._params_for(
                        dataclasses.replace(inst, params=params), lockstep)
                    node = classes[inst.name](**kwargs)
                    self.fallbacks[inst.name] = dict(fb)
            except Exception as exc:  # noqa: BLE001 - a node that cannot start is left out
                if sc.get('strict', False):
                    raise
                self.log(f'[run] {inst.name} failed to start, left out: '
                         f'{type(exc).__name__}: {exc}')
                self.skipped.append(inst.name)
                self.start_errors[inst.name] = f'{type(exc).__name__}: {exc}'
                continue
            self.nodes[inst.name] = node
            self.executor.add_node(node)
            if not lockstep:
                self.counter.wrap_node(node)
            if lockstep:
                self._drive_clock_of(node)
        if self.bag:
            # real time: small chunks, so compressing one (inside a write, in the loop's thread)
            # takes a fraction of a 1 ms period; 1 MB chunks took up to 6 ms (measured)
            self.recorder = McapRecorder(self.bag, chunk_size=REALTIME_CHUNK if not lockstep
                                         else 1 << 20)
            self.sink = RecordingSink(self.runner_node, self.recorder,
                                      exclude=sc['record']['exclude'],
                                      only=sc['record'].get('only') or None)
            self.sink.now_ns = (lambda: self._now_ns) if lockstep else None
            self.sink.buffered = lockstep
            self._record_publishers()
        self._track()
        if self.child_nodes:
            self._start_child()
        return self

    def _start_child(self):
        """Start the worker process running the image pipeline nodes (real time) and wait
        until its nodes are in the graph."""
        import subprocess
        import tempfile
        import yaml
        sc = dict(self.scenario)
        sc.pop('source', None)
        fd, path = tempfile.mkstemp(suffix='.yaml', prefix='worker_')
        with os.fdopen(fd, 'w') as f:
            yaml.safe_dump(sc, f)
        self._child_yaml = path
        cmd = [sys.executable, '-m', 'catheter_bringup.run_scenario', path, '--mode', 'realtime',
               '--no-record', '--quiet', '--only', ','.join(self.child_nodes),
               '--duration', str(self.scenario['duration'] + 30.0)]
        self._child_log = tempfile.TemporaryFile(mode='w+')
        self.child = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=self._child_log,
                                      text=True)
        self.log(f'[run] image pipeline in a worker process (pid {self.child.pid}): '
                 f'{", ".join(self.child_nodes)}')
        t_end = time.monotonic() + 60.0
        while time.monotonic() < t_end:
            if set(self.child_nodes) <= set(self.runner_node.get_node_names()):
                break
            if self.child.poll() is not None:
                self._child_log.seek(0)
                err = self._child_log.read()[-2000:]
                self.log(f'[run] worker process exited ({self.child.returncode}): {err}')
                self.child = None
                return
            time.sleep(0.1)
        if self.sink is not None:
            time.sleep(0.5)
            self.sink.discover()       # the worker's topics, recorded through DDS
            self._track()

    def _stop_child(self):
        if self.child is None:
            return
        import signal as _signal
        if self.child.poll() is None:
            self.child.send_signal(_signal.SIGINT)
            try:
                self.child.wait(timeout=10)
            except Exception:  # noqa: BLE001
                self.child.kill()
                self.child.wait()
        self.child = None
        try:
            os.unlink(self._child_yaml)
        except OSError:
            pass

    def _drive_clock_of(self, node: Node):
        """Lockstep: the runner sets the node's sim time directly each step (what its /clock
        subscription would do, but immediately and in order, so a step's timers are ready in
        the same step). The node's own /clock subscription is removed so a late /clock sample
        can never move its time back. /clock is still published for everyone else."""
        ts = getattr(node, '_time_source', None)
        if ts is None:
            return
        if ts._clock_sub is not None:
            node.destroy_subscription(ts._clock_sub)
            ts._clock_sub = None
        self.time_sources.append(ts)

    def _track(self):
        self._timers = [t for node in self.nodes.values() for t in node.timers]
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
    def drain(self, max_callbacks: int = 100000) -> int:
        """Run ready callbacks until none is ready and the recorder has caught up."""
        n = 0
        ex = self.executor
        if self.bus is not None:
            return self._drain_bus(max_callbacks)
        for _ in range(10):
            while n < max_callbacks:
                try:
                    handler, _, _ = ex.wait_for_ready_callbacks(timeout_sec=0.0)
                except TimeoutException:
                    break
                handler()
                exc = handler.exception()
                if exc is not None:
                    raise exc
                n += 1
            if self._caught_up():
                if self.sink is not None:
                    self.sink.flush()
                return n
            # delivery still in flight (not intra-process): wait briefly for it
            try:
                handler, _, _ = ex.wait_for_ready_callbacks(timeout_sec=0.002)
                handler()
                if handler.exception() is not None:
                    raise handler.exception()
                n += 1
            except TimeoutException:
                pass
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
                try:
                    ready = tmr.is_ready()
                except Exception:  # noqa: BLE001 - destroyed timer
                    continue
                if ready:
                    t0 = time.perf_counter()
                    with tmr.handle:
                        tmr.handle.call_timer()
                    tmr.callback()
                    bus.cost.add(self._timer_owner.get(id(tmr), '?'),
                                 time.perf_counter() - t0)
                    n += 1
                    progress = True
                    bus.deliver_all()
                if cache:
                    try:
                        left = tmr.time_until_next_call()
                    except Exception:  # noqa: BLE001 - destroyed timer
                        left = None
                    due[id(tmr)] = now + left if left is not None else 2 ** 62
        self._steps_since_spin += 1
        # lockstep: every 100 steps; real time: every 1000 (one poll builds an rclpy wait set,
        # ~0.6 ms: every 100th 1 kHz period late by that was the p99 period), and not at all
        # when _spin_external polls the same executor anyway
        every = 100 if cache else (10 ** 9 if bus.external else 1000)
        if self._steps_since_spin >= every:
            self._steps_since_spin = 0
            for _ in range(20):
                try:
                    handler, _, _ = self.executor.wait_for_ready_callbacks(timeout_sec=0.0)
                except TimeoutException:
                    break
                handler()
                exc = handler.exception()
                if exc is not None:
                    raise exc
            bus.deliver_all()
        if self.sink is not None:
            self.sink.flush()
        return n

    def _caught_up(self) -> bool:
        return self.tracker.pending() == 0

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
                bar = tqdm(total=round(sc['duration'], 3), unit='s', desc=sc['name'], mininterval=0.5,
                           bar_format='{desc}: {percentage:3.0f}%|{bar}| {n:.2f}/{total:.2f} s '
                                      '[{elapsed}<{remaining}{postfix}]', file=sys.stderr)
            if sc['mode'] == 'lockstep':
                steps, sim = self._run_lockstep(bar)
            else:
                steps, sim = self._run_realtime(bar)
        except KeyboardInterrupt:
            status, reason = 'interrupted', 'KeyboardInterrupt (Ctrl-C)'
        except Exception as exc:  # a node failed: stop, close the recording, report
            status, reason = 'failed', f'{type(exc).__name__}: {exc}'
        finally:
            if bar is not None:
                bar.close()
            wall = time.perf_counter() - t0
            sim = self._sim_reached if hasattr(self, '_sim_reached') else sim
            result = self._finish(status, reason, sim, wall, steps)
        return result

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
            ts.clock_callback(msg)
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
        for _ in range(limit):
            try:
                handler, _, _ = self.executor.wait_for_ready_callbacks(timeout_sec=0.0)
            except TimeoutException:
                break
            handler()
            exc = handler.exception()
            if exc is not None:
                raise exc
        self.bus.deliver_all()

    # ------------------------------------------------------------------ teardown
    def _finish(self, status, reason, sim, wall, steps) -> RunResult:
        if self.child is not None:
            # what the worker still has in flight, then stop it
            t_end = time.perf_counter() + 0.3
            while time.perf_counter() < t_end:
                self._spin_external()
            self._stop_child()
        if self.sink is not None:
            self.sink.flush()
        recorded = dict(self.sink.received) if self.sink else {}
        published = dict(self.counter.counts)
        for name, node in self.nodes.items():
            close = getattr(node, 'close', None)
            if callable(close):
                try:
                    close()
                except Exception as exc:  # noqa: BLE001 - keep shutting down
                    self.log(f'[run] error closing {name}: {exc!r}')
        if self.recorder is not None:
            self.recorder.close(status, reason, extra={
                'scenario': self.scenario['name'],
                'mode': self.scenario['mode'],
                'seed': self.scenario['seed'],
                'duration_s': self.scenario['duration'],
                'sim_time_reached_s': round(sim, 6),
                'steps': steps,
                'nodes': sorted(self.nodes),
                'skipped_nodes': self.skipped,
                'start_errors': self.start_errors,
                'fallbacks': self.fallbacks,
                'published': published,
                'scenario_yaml': _scenario_text(self.scenario),
            })
        cost = self.bus.cost.summary(wall) if self.bus is not None else {}
        if self.child_nodes:
            res_nodes = sorted(set(self.nodes) | set(self.child_nodes))
        else:
            res_nodes = sorted(self.nodes)
        res = RunResult(self.scenario['name'], status, reason, self.bag, sim, wall, steps,
                        res_nodes, self.skipped, self.missing, published, recorded, cost)
        self.close()
        return res

    def close(self):
        self._stop_child()
        if self.recorder is not None and not self.recorder.closed:
            self.recorder.close('interrupted', 'closed before the run finished')
        if self.executor is not None:
            for n in list(self.nodes.values()) + [self.runner_node]:
                try:
                    self.executor.remove_node(n)
                except Exception:  # noqa: BLE001
                    pass
        for n in list(self.nodes.values()) + ([self.runner_node] if self.runner_node else []):
            try:
                n.destroy_node()
            except Exception:  # noqa: BLE001
                pass
        self.nodes = {}
        self.runner_node = None
        if self.executor is not None:
            self.executor.shutdown()
            self.executor = None
        if self.context is not None and self._own_context:
            rclpy.try_shutdown(context=self.context)
        self.context = None


def _scenario_text(sc) -> str:
    import yaml
    return yaml.safe_dump({k: v for k, v in sc.items() if k != 'source'}, sort_keys=True)


def run_scenario(scenario, **kwargs) -> RunResult:
    """Load, set up, run and close: the one-call API."""
    return ScenarioRunner(scenario, **kwargs).run()

"""In-process fuzzing of one node: its subscription callbacks are fed directly (no DDS round
trip), its timers fired on a simulated clock, its publishers intercepted (nothing leaves the
process) and every output checked when it is published.

`FUZZ_NODES` says, per node, which inputs it takes (topic -> strategy and the diagnostics
counters of which exactly one must move per message: every message is accounted for) and
what its outputs must satisfy. `Rig` runs a sequence of events (a message on a topic, a clock
tick, a parameter change) and keeps the tallies the tests assert on and the benchmark prints.
"""
from __future__ import annotations

import math
import sys
import pathlib
from dataclasses import dataclass, field
from typing import Callable, Dict, Optional, Tuple

from hypothesis import strategies as st

from builtin_interfaces.msg import Time
from rosgraph_msgs.msg import Clock

from catheter_bringup.rclpy_adapter import (detach_clock, fire_timer, intercept_publish,
                                            set_time, timer_ready)
from catheter_common import topics as T

HERE = pathlib.Path(__file__).resolve().parent
for p in (HERE, HERE.parent / 'nodes'):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))

import strategies as S  # noqa: E402
from node_cases import make_node  # noqa: E402


@dataclass
class Input:
    #: builds one message from a strategies.Pick (hypothesis-drawn pool and seed)
    build: Callable
    #: diagnostics counters: exactly one of them moves per message on this topic
    accounted: Tuple[str, ...]


def _js(scale):
    return lambda p: S.build_joint_state(p, scale)


def _cmd(scale):
    return lambda p: S.build_master_command(p, scale)


def _wrench(scale):
    return lambda p: S.build_wrench(p, scale)


@dataclass
class FuzzNode:
    name: str
    inputs: Dict[str, Input]
    params: dict = field(default_factory=dict)
    #: the period of a clock tick event, ns
    tick_ns: int = 1_000_000
    #: value strategies replacing the generic ones for parameters that make a node slow
    #: (the fuzz is about robustness, not about FAM with 5000 arcs)
    param_values: dict = field(default_factory=dict)
    #: share of clock ticks among the events (a camera frame costs milliseconds)
    tick_share: float = 0.15
    #: relative cost: the tests run EXAMPLES / cost examples of this node
    cost: float = 1.0
    #: messages every input topic must have had in the tests (with the default EXAMPLES)
    min_sent: int = 1000
    #: draw half the parameter changes among the dynamic parameters (a node with few)
    dynamic_first: bool = False


FUZZ_NODES = {
    'ima_master_node': FuzzNode('ima_master_node', {
        T.MASTER_COMMAND: Input(_cmd(0.1), ('commands', 'bad_command')),
        T.MASTER_LINK_IMPEDANCE: Input(S.build_impedance, (
            'models_received', 'models_unchanged', 'bad_impedance', 'models_ignored_mode')),
        T.MASTER_LINK_FORCE: Input(_wrench(1.0), ('forces_received', 'bad_force',
                                                     'forces_ignored_mode')),
    }, params={'mode': 'ima'}),
    'dfr_master_node': FuzzNode('ima_master_node', {
        T.MASTER_COMMAND: Input(_cmd(0.1), ('commands', 'bad_command')),
        T.MASTER_LINK_IMPEDANCE: Input(S.build_impedance, (
            'models_received', 'models_unchanged', 'bad_impedance', 'models_ignored_mode')),
        T.MASTER_LINK_FORCE: Input(_wrench(1.0), ('forces_received', 'bad_force',
                                                     'forces_ignored_mode')),
    }, params={'mode': 'dfr'}),
    'impedance_identifier_node': FuzzNode('impedance_identifier_node', {
        T.SLAVE_JOINT_STATE: Input(_js(0.05), ('samples', 'bad_joint_state',
                                                          'update_errors')),
    }, params={'window': 0.1}),
    'sim_haptic_node': FuzzNode('sim_haptic_node', {
        T.MASTER_RENDERED_FORCE: Input(_wrench(1.0), ('rendered_forces',
                                                         'bad_rendered_force')),
        T.SLAVE_IMPEDANCE: Input(S.build_impedance, (
            'impedance_sent', 'impedance_before_start', 'impedance_out_of_time',
            'bad_impedance')),
        T.SLAVE_FORCE: Input(_wrench(1.0), ('force_sent', 'force_before_start',
                                               'force_out_of_time', 'bad_slave_force')),
    }, params={'link.delay': 0.002, 'link.outages': [0.0, 0.0]}),
    'sim_slave_node': FuzzNode('sim_slave_node', {
        T.MASTER_COMMAND: Input(_cmd(0.1), ('commands_received', 'bad_command',
                                                      'commands_before_start')),
    }, params={'link.delay': 0.002, 'link.outages': [0.0, 0.0]}),
    'camera_node': FuzzNode('camera_node', {
        T.SLAVE_JOINT_STATE_DECIMATED: Input(_js(0.06), ('joint_states', 'bad_joint_state')),
    }, tick_ns=34_000_000, param_values={'rate': st.floats(1.0, 60.0),
                                          'n_arcs': st.integers(1, 24)}, tick_share=0.02,
       cost=1.5, dynamic_first=True),
    # the learned models alone (no FAM fallback: it costs ~20 ms an estimate; the fallback
    # has its own entry below)
    'force_estimator_node': FuzzNode('force_estimator_node', {
        T.CONTROL_POINTS: Input(S.build_pose_array, ('messages',)),
    }, params={'fallback': False},
        param_values={'method': st.sampled_from(['svr', 'mlp', 'bogus']),
                      'fallback': st.just(False)}),
    # FAM inversion costs ~20 ms an estimate: fewer messages, its own entries
    'fam_estimator_node': FuzzNode('force_estimator_node', {
        T.CONTROL_POINTS: Input(S.build_pose_array, ('messages',)),
    }, params={'method': 'fam', 'n_arcs': 4},
        param_values={'method': st.just('fam'), 'n_arcs': st.integers(4, 6)}, cost=10.0,
        min_sent=500),
    'hybrid_estimator_node': FuzzNode('force_estimator_node', {
        T.CONTROL_POINTS: Input(S.build_pose_array, ('messages',)),
    }, params={'method': 'svr', 'fallback': True, 'n_arcs': 4},
        param_values={'method': st.sampled_from(['svr', 'mlp']), 'n_arcs': st.integers(4, 6)},
        cost=10.0, min_sent=500),
    'shape_node': FuzzNode('shape_node', {
        T.CAMERA_IMAGE: Input(S.build_image, ('frames',)),
    }, tick_ns=5_000_000),
    'fam_solver_node': FuzzNode('fam_solver_node', {
        T.TIP_LOAD: Input(_wrench(0.5), ('loads_received',)),
    }, tick_ns=100_000_000, param_values={'n_arcs': st.integers(1, 48),
                                          'path_points': st.integers(2, 200),
                                          'max_force': st.floats(1e-3, 1.0),
                                          'max_moment': st.floats(1e-6, 0.01)}, cost=3.0),
    'force_source_node': FuzzNode('force_source_node', {
        T.TIP_WRENCH: Input(_wrench(0.5), ('estimates', 'bad_wrench')),
        T.SLAVE_JOINT_STATE: Input(_js(0.05), ('replaced', 'load_cell_fallback',
                                                          'bad_joint_state')),
    }),
}


def float_values(msg, path=''):
    """Every float in a message (recursively), as (field path, value)."""
    out = []
    for name, kind in msg.get_fields_and_field_types().items():
        v = getattr(msg, name)
        p = f'{path}.{name}' if path else name
        if kind in ('double', 'float'):
            out.append((p, v))
        elif kind.startswith('sequence<double') or kind.startswith('double[') or \
                kind.startswith('sequence<float') or kind.startswith('float['):
            out.extend((p, x) for x in v)
        elif hasattr(v, 'get_fields_and_field_types'):
            out.extend(float_values(v, p))
        elif isinstance(v, (list, tuple)) and v and hasattr(v[0], 'get_fields_and_field_types'):
            for i, x in enumerate(v):
                out.extend(float_values(x, f'{p}[{i}]'))
    return out


@dataclass
class Tally:
    sent: Dict[str, int] = field(default_factory=dict)
    refused: Dict[str, int] = field(default_factory=dict)
    #: messages refused later, when a timer processed them (the shape node decodes there)
    refused_in_timer: int = 0
    outputs: int = 0
    nonfinite: int = 0
    over_limit: int = 0
    crashes: int = 0
    unaccounted: int = 0
    params_set: int = 0
    params_refused: int = 0
    examples: list = field(default_factory=list)     # first few violations, for messages

    def note(self, what: str) -> None:
        if len(self.examples) < 5:
            self.examples.append(what)


class Rig:
    """One node under fuzz (see the module docstring)."""

    def __init__(self, ros, key: str, namespace: Optional[str] = None):
        spec = FUZZ_NODES[key]
        self.spec = spec
        self.ros = ros
        self.node = make_node(ros, spec.name, namespace=namespace, use_sim_time=True,
                              **spec.params)
        self.ts = detach_clock(self.node)
        self.t_ns = 1_000_000_000
        self._set_clock()
        self.tally = Tally()
        self.last_input: Dict[str, object] = {}
        self.outputs: Dict[str, list] = {}        # the latest few, per output topic
        self.counts: Dict[str, int] = {}          # everything published, per output topic
        ns = self.node.get_namespace()
        self.checks: Dict[str, Callable] = {
            T.resolve(T.MASTER_RENDERED_FORCE, ns): self._check_force_limit,
            T.resolve(T.TIP_WRENCH, ns): self._check_estimate,
            T.resolve(T.TIP_FORCE, ns): self._check_typed_estimate}
        probe = ros.node(f'fuzz_probe_{key}', namespace=namespace)
        for pub in list(self.node.publishers):
            if pub.topic_name in ('/parameter_events', '/rosout'):
                continue
            probe.create_subscription(pub.msg_type, pub.topic_name, lambda m: None,
                                      pub.qos_profile)
            intercept_publish(pub, self._recorder(pub.topic_name))
        pubs = [p for p in self.node.publishers
                if p.topic_name not in ('/parameter_events', '/rosout')]
        assert ros.spin_until(lambda: all(p.get_subscription_count() > 0 for p in pubs), 10.0)
        self.subs = {s.topic_name: s for s in self.node.subscriptions}
        self.topics = {T.resolve(t, self.node.get_namespace()): t for t in spec.inputs}
        missing = set(self.topics) - set(self.subs)
        assert not missing, f'{key} does not subscribe {missing}'

    # ------------------------------------------------------------------ driving
    def _set_clock(self) -> None:
        ns = self.t_ns
        set_time(self.ts, Clock(clock=Time(sec=ns // 10 ** 9, nanosec=ns % 10 ** 9)))

    def feed(self, topic: str, msg) -> None:
        """Deliver `msg` on input `topic` (a catheter_common.topics constant)."""
        full = T.resolve(topic, self.node.get_namespace())
        keys = self.spec.inputs[topic].accounted
        d = self.node.diag
        before = sum(d.get(k) for k in keys)
        bad_before = d.get('bad_messages')
        self.last_input[topic] = msg
        self.tally.sent[topic] = self.tally.sent.get(topic, 0) + 1
        if topic == T.CONTROL_POINTS:
            self._watch_estimator()
        try:
            self.subs[full].callback(msg)
        except Exception as exc:  # noqa: BLE001 - a crash is what the fuzz looks for
            self.tally.crashes += 1
            self.tally.note(f'crash on {topic}: {exc!r}')
            return
        if sum(d.get(k) for k in keys) != before + 1:
            self.tally.unaccounted += 1
            self.tally.note(f'{topic}: counters {keys} did not move by exactly 1')
        if d.get('bad_messages') > bad_before:
            self.tally.refused[topic] = self.tally.refused.get(topic, 0) + 1

    def tick(self, n: int = 1) -> None:
        """Advance the clock by n tick periods, firing every due timer of the node."""
        bad_before = self.node.diag.get('bad_messages')
        self._tick(n)
        self.tally.refused_in_timer += self.node.diag.get('bad_messages') - bad_before

    def _tick(self, n: int) -> None:
        for _ in range(n):
            self.t_ns += self.spec.tick_ns
            self._set_clock()
            for _ in range(10):
                fired = False
                for tmr in list(self.node.timers):
                    if timer_ready(tmr):
                        try:
                            fire_timer(tmr)
                        except Exception as exc:  # noqa: BLE001
                            self.tally.crashes += 1
                            self.tally.note(f'crash in a timer: {exc!r}')
                        fired = True
                if not fired:
                    break

    def set_param(self, name: str, value) -> None:
        from rclpy.parameter import Parameter
        try:
            res = self.node.set_parameters([Parameter(name, value=value)])[0]
        except Exception as exc:  # noqa: BLE001 - rclpy refuses a value of another type
            res = None
            if not type(exc).__name__.startswith(('InvalidParameter', 'ParameterNot',
                                                  'ParameterImmutable')):
                self.tally.crashes += 1
                self.tally.note(f'crash setting {name}={value!r}: {exc!r}')
        if res is not None and res.successful:
            self.tally.params_set += 1
        else:
            self.tally.params_refused += 1

    def run(self, events) -> None:
        for ev in events:
            kind = ev[0]
            if kind == 'msg':
                self.feed(ev[1], ev[2])
            elif kind == 'tick':
                self.tick(ev[1])
            else:
                self.set_param(ev[1], ev[2])

    # ------------------------------------------------------------------ output checks
    def _recorder(self, topic):
        def record(msg):
            self.tally.outputs += 1
            for path, v in float_values(msg):
                if not math.isfinite(v):
                    self.tally.nonfinite += 1
                    self.tally.note(f'{topic}.{path} = {v}')
                    break
            check = self.checks.get(topic)
            if check is not None:
                check(msg)
            self.counts[topic] = self.counts.get(topic, 0) + 1
            self.outputs.setdefault(topic, []).append(msg)
            if len(self.outputs[topic]) > 50:
                del self.outputs[topic][:25]
        return record

    def _check_force_limit(self, msg) -> None:
        f = msg.wrench.force.x
        if not abs(f) <= self.node.limit:
            self.tally.over_limit += 1
            self.tally.note(f'rendered {f} N over the limit {self.node.limit} N')

    def _watch_estimator(self) -> None:
        """Keep the ForceEstimate of each message the node estimates from (the estimator may
        have been replaced by a parameter change; FAM inversion warm-starts from its last
        result, so asking it again would neither give the node's answer nor leave it as it
        was)."""
        self._last_est = None
        est = self.node.estimator
        if getattr(est, '_fuzz_watched', False):
            return
        orig = est.estimate

        def estimate(cp):
            out = orig(cp)
            self._last_est = out
            return out
        est.estimate = estimate
        est._fuzz_watched = True

    def _check_estimate(self, msg) -> None:
        """A force published on tip_wrench is a normal estimate of the core, within the
        envelope of the method that produced it, unchanged."""
        e = getattr(self, '_last_est', None)
        f = (msg.wrench.force.x, msg.wrench.force.y)
        if e is None or not e.normal:
            self.tally.over_limit += 1
            self.tally.note(f'tip_wrench {f} published for an estimate that is not normal '
                            f'({None if e is None else e.status})')
        elif f != (float(e.force[0]), float(e.force[1])):
            self.tally.over_limit += 1
            self.tally.note(f'tip_wrench {f} is not the estimate {e.force}')

    def _check_typed_estimate(self, msg) -> None:
        """Every TipForceEstimate: a known status; OK / UNOBSERVABLE_AXIAL only for normal
        estimates; a force within the largest envelope (f_max); a covariance that is known
        (non-negative diagonal, symmetric)."""
        from catheter_common.messages import TIP_FORCE_STATUS
        e = getattr(self, '_last_est', None)
        normal_codes = {TIP_FORCE_STATUS['ok'], TIP_FORCE_STATUS['unobservable_axial']}
        f = math.hypot(msg.force.x, msg.force.y)
        c = list(msg.covariance)
        bad = []
        if msg.status not in TIP_FORCE_STATUS.values():
            bad.append(f'status {msg.status}')
        if (msg.status in normal_codes) != (e is not None and e.normal):
            bad.append(f'status {msg.status} for {None if e is None else e.status}')
        model = getattr(self.node.estimator, 'model', None)     # a learned model's envelope
        bound = max(self.node.params['f_max'], getattr(model, 'f_bound', 0.0))
        if not f <= bound * (1.0 + 1e-9):
            bad.append(f'|force| {f} N beyond the envelope {bound} N')
        if not (c[0] >= 0 and c[3] >= 0 and abs(c[1] - c[2]) <= 1e-9):
            bad.append(f'covariance {c}')
        if bad:
            self.tally.over_limit += 1
            self.tally.note('tip_force: ' + ', '.join(bad))


def expand(key: str, pool_seed, n: int, params) -> list:
    """The event list of one example: `n` messages on the node's inputs (topics mixed) and
    clock ticks, built from the drawn pool and seed, with the drawn parameter changes
    inserted at random places."""
    spec = FUZZ_NODES[key]
    p = S.Pick(*pool_seed)
    topics = sorted(spec.inputs)
    evs = []
    for _ in range(n):
        if p.r.random() < spec.tick_share:
            evs.append(('tick', p.r.randint(1, 3)))
        else:
            t = p.choice(topics)
            evs.append(('msg', t, spec.inputs[t].build(p)))
    for ev in params:
        evs.insert(p.r.randrange(len(evs) + 1), ev)
    return evs


def events(key: str, n=(40, 120), params: bool = True):
    """A strategy for event sequences of node `key`: messages on each input, clock ticks and
    (with `params`) changes of its declared parameters (valid and invalid values)."""
    spec = FUZZ_NODES[key]
    from node_cases import node_class
    table = node_class(spec.name).PARAMS
    names = st.sampled_from(table)
    if spec.dynamic_first:
        # half the changes go to the parameters that apply at run time (camera_node: one
        # among 16 read-only ones; it drew none in 72 changes of a suite run)
        names = st.one_of(st.sampled_from([prm for prm in table if prm.dynamic]), names)
    change = names.flatmap(
        lambda prm: st.tuples(st.just('param'), st.just(prm.name),
                              spec.param_values[prm.name] if prm.name in spec.param_values
                              else S.param_values(prm)))
    return st.builds(expand, st.just(key), S.POOLS, st.integers(*n),
                     st.lists(change, max_size=3) if params else st.just([]))

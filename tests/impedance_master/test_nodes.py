"""In-process tests of the three impedance_master nodes (private ROS context per test)."""
import copy
import math

import pytest
from geometry_msgs.msg import WrenchStamped
from hypothesis import given, settings
from hypothesis import strategies as st
from rclpy.parameter import Parameter
from catheter_interfaces.msg import ImpedanceModel, MasterCommand
from sensor_msgs.msg import JointState

from catheter_common import messages as M
from catheter_common.messages import impedance_fields, impedance_msg, master_command_msg
from catheter_common.topics import (MASTER_COMMAND, MASTER_LINK_FORCE,
                                    MASTER_LINK_IMPEDANCE, MASTER_RENDERED_FORCE, SLAVE_FORCE,
                                    SLAVE_IMPEDANCE, SLAVE_JOINT_STATE)
from catheter_common import topics as T
from catheter_common.qos import QOS_FAST
from impedance_master.ima_master_node import ImaMasterNode
from impedance_master.impedance import Impedance
from impedance_master.impedance_identifier_node import ImpedanceIdentifierNode, fill_table_msg
from impedance_master.sim_haptic_node import MASTER_HAND_FORCE, SimHapticNode

pytestmark = pytest.mark.ros


def params(**kw):
    return [Parameter(k, value=v) for k, v in kw.items()]


def collect(node, msg_type, topic):
    got = []
    node.create_subscription(msg_type, topic, got.append, QOS_FAST)
    return got


def test_identifier_node_publishes_typed_models_and_survives_bad_messages(ros):
    node = ros.add(ImpedanceIdentifierNode(
        context=ros.context, parameter_overrides=params(identifier='thesis', window=0.1,
                                                        publish_rate=100.0)))
    probe = ros.node('probe_ident')
    got = collect(probe, ImpedanceModel, SLAVE_IMPEDANCE)
    pub = probe.create_publisher(JointState, SLAVE_JOINT_STATE, QOS_FAST)
    assert ros.spin_until(lambda: pub.get_subscription_count() > 0, 10.0)
    bad = JointState()
    bad.position = [float('nan')]
    bad.effort = [0.1]
    for n, m in enumerate((bad, JointState())):   # one at a time: depth-1 best effort
        assert ros.spin_until(lambda m=m, n=n: (pub.publish(m),
                                                node.diag.get('bad_messages') > n)[1], 5.0)
    k = [0]

    def feed():
        for _ in range(20):           # f = 2 x' + 30 x, a sinusoidal insertion
            t = k[0] * 1e-3
            k[0] += 1
            x = 0.03 + 0.01 * math.sin(3.0 * t)
            xd = 0.03 * math.cos(3.0 * t)
            m = JointState()
            m.position = [x, 0.0]
            m.velocity = [xd, 0.0]
            m.effort = [2.0 * xd + 30.0 * x, 0.0]
            pub.publish(m)
            ros.executor.spin_once(timeout_sec=0.001)
        return bool(got) and node.diag.get('samples') > 300

    assert ros.spin_until(feed, 30.0)
    msg = got[-1]
    assert msg.kind == ImpedanceModel.KIND_LINEAR and len(msg.s_table) == 0
    assert msg.header.frame_id == 'catheter_base'
    assert msg.status == node.model.status != ''
    imp = Impedance.from_fields(impedance_fields(msg))
    assert imp.kind == 0 and imp.valid
    assert node.diag.get('bad_messages') >= 2


def _identifier_and_its_messages(ros, probe_name):
    """An identifier node with a subscriber, and the list every message it publishes is
    copied into (intercepted at publish: the node may refill its message afterwards)."""
    from catheter_bringup.rclpy_adapter import intercept_publish
    node = ros.add(ImpedanceIdentifierNode(context=ros.context))
    collect(ros.node(probe_name), ImpedanceModel, SLAVE_IMPEDANCE)
    assert ros.spin_until(lambda: node.pub.get_subscription_count() > 0, 10.0)
    out = []
    intercept_publish(node.pub, lambda m: out.append(copy.deepcopy(m)))
    return node, out


def test_identifier_node_converts_a_model_once_and_resends_it_restamped(ros):
    """The 1 kHz re-send of a held model reuses its message (new stamp, the model's current
    status); a new model object is converted anew, anchor included."""
    node, out = _identifier_and_its_messages(ros, 'probe_ident_cache')
    node.model = Impedance(0.1, 2.0, 3.0, 0.5, status='ok', anchor=(0.03, 0.01, 0, 1, 1.2,
                                                                    0.2, 0.01))
    node._publish()
    node.model.status = 'at_rest'            # what the history identifier does when it holds
    node._publish()
    node.model = node.model.copy(c=2.5, anchor=None)
    node._publish()
    assert [m.status for m in out] == ['ok', 'at_rest', 'at_rest']
    assert [m.c for m in out] == [2.0, 2.0, 2.5]
    assert [m.has_anchor for m in out] == [True, True, False] and out[0].anchor_f == 0.2
    assert M.stamp_ns(out[0]) <= M.stamp_ns(out[1]) <= M.stamp_ns(out[2])


def test_ima_master_node_renders_the_model_on_the_local_command(ros):
    node = ros.add(ImaMasterNode(context=ros.context, parameter_overrides=params(
        mode='ima', rate=200.0, blend_time=0.0, max_rate=1e6)))
    probe = ros.node('probe_ima')
    got = collect(probe, WrenchStamped, MASTER_RENDERED_FORCE)
    pub_cmd = probe.create_publisher(MasterCommand, MASTER_COMMAND, QOS_FAST)
    pub_imp = probe.create_publisher(ImpedanceModel, MASTER_LINK_IMPEDANCE, QOS_FAST)
    assert ros.spin_until(lambda: pub_imp.get_subscription_count() > 0 and got, 10.0)
    assert got[-1].wrench.force.x == 0.0                     # no model yet
    imp = Impedance(0.5, 2.0, 5.0, 0.01)
    expect = imp.force(0.03, 0.01, 0.4)      # the acceleration travels in the command

    def send():
        pub_cmd.publish(master_command_msg(0.03, 0.01, 0.4))
        pub_imp.publish(impedance_msg(imp))
        return got and abs(got[-1].wrench.force.x - expect) < 1e-9

    assert ros.spin_until(send, 10.0)
    bad = impedance_msg(imp)
    bad.kind = ImpedanceModel.KIND_TABLE           # a table model without tables
    pub_imp.publish(bad)
    ros.spin_until(lambda: node.diag.get('bad_messages') > 0, 5.0)
    assert node.diag.get('bad_messages') == 1
    n = len(got)
    assert ros.spin_until(lambda: len(got) > n + 5, 5.0)     # keeps rendering
    assert abs(got[-1].wrench.force.x - expect) < 1e-9


def test_ima_master_node_dfr_mode_reflects_the_link_force_clamped(ros):
    ros.add(ImaMasterNode(context=ros.context,
                          parameter_overrides=params(mode='dfr', rate=200.0, limit=0.5)))
    probe = ros.node('probe_dfr')
    got = collect(probe, WrenchStamped, MASTER_RENDERED_FORCE)
    pub = probe.create_publisher(WrenchStamped, MASTER_LINK_FORCE, QOS_FAST)

    def send(f, expect):
        def cond():
            w = WrenchStamped()
            w.wrench.force.x = f
            pub.publish(w)
            return got and got[-1].wrench.force.x == expect
        return ros.spin_until(cond, 10.0)

    assert send(0.25, 0.25)
    assert send(3.0, 0.5)


def test_ima_master_node_refuses_an_unknown_mode(ros):
    with pytest.raises(ValueError, match='mode'):
        ImaMasterNode(context=ros.context, parameter_overrides=params(mode='pid'))


def test_sim_haptic_node_commands_and_delays_the_slave_streams(ros):
    node = ros.add(SimHapticNode(context=ros.context, parameter_overrides=params(
        rate=200.0, **{'link.delay': 0.3, 'link.outages': [0.0, 0.0]})))
    probe = ros.node('probe_haptic')
    cmds = collect(probe, MasterCommand, MASTER_COMMAND)
    hand = collect(probe, WrenchStamped, MASTER_HAND_FORCE)
    delivered = collect(probe, WrenchStamped, MASTER_LINK_FORCE)
    imps = collect(probe, ImpedanceModel, MASTER_LINK_IMPEDANCE)
    pub_f = probe.create_publisher(WrenchStamped, SLAVE_FORCE, QOS_FAST)
    pub_i = probe.create_publisher(ImpedanceModel, SLAVE_IMPEDANCE, QOS_FAST)
    pub_r = probe.create_publisher(WrenchStamped, MASTER_RENDERED_FORCE, QOS_FAST)
    assert ros.spin_until(lambda: len(cmds) > 5 and pub_f.get_subscription_count() > 0, 10.0)
    c = cmds[-1]
    assert 0.0 <= c.position <= 0.06 and c.rotation == 0.0
    assert c.header.frame_id == 'catheter_base'
    # the handle's state travels whole, acceleration included (the script moves after 0.4 s)
    from catheter_bringup.rclpy_adapter import intercept_publish
    sent = []
    # the node reuses its command message (catheter_common.outgoing): what is kept is copied
    orig = intercept_publish(node.pub_cmd,
                             lambda m: (sent.append((copy.deepcopy(m), node.last)), orig(m)))
    node.run.t0 -= 1.0
    assert ros.spin_until(lambda: len(sent) > 5, 10.0)
    assert all((m.position, m.velocity, m.acceleration) == (s.x, s.xd, s.xdd) for m, s in sent)
    assert all(m.acceleration != 0.0 for m, _ in sent)
    w = WrenchStamped()
    w.wrench.force.x = 0.123
    t_send = node.get_clock().now()
    pub_f.publish(w)
    pub_i.publish(impedance_msg(Impedance(0.0, 1.0, 2.0, 0.0)))
    assert ros.spin_until(lambda: delivered and imps, 10.0)
    waited = (node.get_clock().now() - t_send).nanoseconds * 1e-9
    assert waited >= 0.3 - 0.02                      # not before the link's delay
    assert delivered[-1].wrench.force.x == 0.123
    assert Impedance.from_fields(impedance_fields(imps[-1])).c == 1.0
    # the device tracks the rendered force at the hand
    r = WrenchStamped()
    r.wrench.force.x = 0.2

    def tracked():
        pub_r.publish(r)
        return hand and abs(hand[-1].wrench.force.x - 0.2) < 0.02
    assert ros.spin_until(tracked, 10.0)
    bad = WrenchStamped()
    bad.wrench.force.x = float('nan')
    pub_r.publish(bad)
    assert ros.spin_until(lambda: node.diag.get('bad_messages') == 1, 5.0)


def test_identifier_node_writes_and_reloads_its_learned_state(ros, tmp_path):
    from impedance_master.identification import make_identifier
    path = tmp_path / 'ident.json'
    ident = make_identifier(window=0.2)
    for k in range(2000):                       # some motion so the state holds a model
        t = k * 1e-3
        x = 0.03 + 0.01 * math.sin(3.0 * t)
        xd = 0.03 * math.cos(3.0 * t)
        ident.update(x, xd, 0.0, 0.1 * math.copysign(1, xd) + 2.0 * x)
    ident.save_state(str(path))
    node = ImpedanceIdentifierNode(context=ros.context, parameter_overrides=params(
        state_file=str(path)))
    assert node.model is not None and node.model.valid and node.model.kind == 1
    node.ident.update(0.03, 0.01, 0.0, 0.2)
    path.unlink()
    node.close()
    assert path.exists()
    node.destroy_node()


def test_sim_haptic_node_runs_in_lockstep_with_a_clock(ros):
    """use_sim_time: the 1 kHz timer fires once per published 1 ms /clock step and the
    command stamps are the simulated time."""
    from builtin_interfaces.msg import Time
    from rosgraph_msgs.msg import Clock
    from catheter_common.topics import CLOCK
    from catheter_common.qos import QOS_DEFAULT
    node = ros.add(SimHapticNode(context=ros.context, parameter_overrides=params(
        use_sim_time=True, **{'link.outages': [0.0, 0.0]})))
    probe = ros.node('probe_clock')
    cmds = collect(probe, MasterCommand, MASTER_COMMAND)
    clock = probe.create_publisher(Clock, CLOCK, QOS_DEFAULT)
    assert ros.spin_until(lambda: clock.get_subscription_count() > 0
                          and node.pub_cmd.get_subscription_count() > 0, 10.0)
    t_ns = 1_000_000_000

    def step():
        nonlocal t_ns
        t_ns += 1_000_000
        clock.publish(Clock(clock=Time(sec=t_ns // 10 ** 9, nanosec=t_ns % 10 ** 9)))
        for _ in range(4):
            ros.executor.spin_once(timeout_sec=0.002)

    for _ in range(20):      # let the clock subscription settle
        step()
    ticks0 = node.diag.get('ticks')
    for _ in range(300):
        step()
    ticks = node.diag.get('ticks') - ticks0
    assert 270 <= ticks <= 300
    last = cmds[-1].header.stamp
    stamp_ns = last.sec * 10 ** 9 + last.nanosec
    assert t_ns - 5_000_000 <= stamp_ns <= t_ns            # simulated, not wall time
    assert 0.30 - 0.03 <= node.run.t_last <= 0.32 + 0.001


def test_identifier_node_never_overwrites_a_state_file_it_could_not_load(ros, tmp_path):
    """Issue 10 item 5: a rejected state file was logged as ignored, then overwritten at
    shutdown with the new, empty state. It is kept; the new state goes beside it."""
    path = tmp_path / 'ident.json'
    path.write_text('[1, 2, 3]')                       # a JSON list, not a state
    node = ImpedanceIdentifierNode(context=ros.context, parameter_overrides=params(
        state_file=str(path)))
    assert node.model is None
    node.ident.update(0.03, 0.01, 0.0, 0.2)
    node.close()
    assert path.read_text() == '[1, 2, 3]'
    beside = sorted(p.name for p in tmp_path.iterdir() if p.name != 'ident.json')
    assert beside == ['ident.1.json'], beside
    assert node.diag.level()[0] == 1 and 'rejected' in node.diag.level()[1]
    node.destroy_node()


def test_sim_haptic_node_checks_each_model_once_and_still_refuses_a_bad_one(ros):
    """The link side checks a model only when it differs from the last one that passed (the
    identifier re-sends a held model every period): a re-sent model is relayed, a model with
    a NaN anywhere is refused every time, also right after the same model without it."""
    node = ros.add(SimHapticNode(context=ros.context))
    node._tick()                                   # the run starts: sends are timed from here
    good = impedance_msg(Impedance(0.1, 2.0, 3.0, 0.5, x0=0.0, dx=0.01, S=[1, 2], F=[0, 0],
                                   B=[0, 0], C=[0, 0]), 5)
    sent = lambda: node.diag.get('impedance_sent') or 0          # noqa: E731
    node._on_impedance(good)
    node._on_impedance(copy.deepcopy(good))
    assert sent() == 2 and (node.diag.get('bad_messages') or 0) == 0
    checks = []
    import impedance_master.sim_haptic_node as shn
    orig = shn.impedance_fields
    shn.impedance_fields = lambda m: (checks.append(1), orig(m))[1]
    try:
        node._on_impedance(copy.deepcopy(good))    # the same model: relayed, not re-checked
        assert checks == [] and sent() == 3
        for attr, val in (('s_table', [1.0, math.nan]), ('m', math.inf), ('sigma', math.nan)):
            bad = copy.deepcopy(good)
            setattr(bad, attr, val)
            for _ in range(2):
                node._on_impedance(bad)
        assert sent() == 3 and node.diag.get('bad_messages') == 6 and len(checks) == 6
        node._on_impedance(copy.deepcopy(good))    # the model that passed: relayed unchecked
        assert sent() == 4 and len(checks) == 6
        other = impedance_msg(Impedance(0.1, 2.5, 3.0, 0.5), 6)
        node._on_impedance(other)                  # a new model: checked
        assert sent() == 5 and len(checks) == 7
    finally:
        shn.impedance_fields = orig


_F = st.floats(-10.0, 10.0)


def _table_model(draw, n):
    tabs = [draw(st.lists(_F, min_size=n, max_size=n)) for _ in range(4)]
    return Impedance(*(draw(_F) for _ in range(4)), valid=draw(st.booleans()),
                     x0=draw(st.floats(-0.1, 0.1)), dx=draw(st.floats(1e-4, 0.1)),
                     sigma=draw(st.floats(0.0, 0.01)), v_s=draw(st.floats(1e-4, 0.1)),
                     beta=draw(st.floats(0.0, 5.0)), S=tabs[0], F=tabs[1], B=tabs[2],
                     C=tabs[3], status=draw(st.sampled_from(['ok', 'at_rest', ''])),
                     anchor=[draw(_F) for _ in range(7)])


def _same_msg(a, b):
    names = [n for n in ImpedanceModel.get_fields_and_field_types() if n != 'header']
    for n in names:
        assert getattr(a, n) == getattr(b, n), n
    assert a.header.frame_id == b.header.frame_id


@settings(max_examples=60, deadline=None)
@given(st.integers(2, 20), st.data())
def test_fill_table_msg_writes_what_impedance_msg_makes(n, data):
    """Issue 15: the identifier node writes a new table model into its message in place;
    the message is then what impedance_msg makes of the model (header aside)."""
    first, second = _table_model(data.draw, n), _table_model(data.draw, n)
    msg = impedance_msg(first, 5, 'catheter_base')
    assert fill_table_msg(msg, second)
    _same_msg(msg, impedance_msg(second, 5, 'catheter_base'))


def test_fill_table_msg_leaves_everything_else_to_impedance_msg():
    table = dict(S=[0.1, 0.2, 0.3], F=[0.0] * 3, B=[0.0] * 3, C=[1.0] * 3, status='ok',
                 anchor=(0.03, 0.01, 0, 1, 1.2, 0.2, 0.01))
    m = Impedance(0.01, 2.0, 3.0, 0.5, **table)
    msg = impedance_msg(m, 5, 'catheter_base')
    before = copy.deepcopy(msg)
    bad = copy.deepcopy(m)
    bad.S[1] = math.nan                        # mutated after construction: not finite
    huge = m.copy(c=1.7e308, k=1.7e308)        # finite, its sum overflows: impedance_msg's
    for other, target in ((m.copy(anchor=None), msg), (Impedance(0.1, 2.0, 3.0, 0.5), msg),
                          (m.copy(S=[0.1] * 4, F=[0.0] * 4, B=[0.0] * 4, C=[1.0] * 4), msg),
                          (bad, msg), (huge, msg), (m, None),
                          (m, impedance_msg(m.copy(anchor=None), 5, 'catheter_base')),
                          (m, impedance_msg(Impedance(0.1, 2.0, 3.0, 0.5), 5, 'x'))):
        assert not fill_table_msg(target, other)
        _same_msg(msg, before)
    with pytest.raises(ValueError, match='model S1'):
        impedance_msg(bad, 5, 'catheter_base')


def test_identifier_node_writes_a_new_table_model_into_its_message(ros):
    node, out = _identifier_and_its_messages(ros, 'probe_ident_fill')
    a = Impedance(0.01, 2.0, 3.0, 0.5, S=[0.1, 0.2, 0.3], F=[0.0] * 3, B=[0.1] * 3,
                  C=[1.0] * 3, status='ok', anchor=(0.03, 0.01, 0, 1, 1.2, 0.2, 0.01))
    b = a.copy(c=2.5, S=[0.3, 0.2, 0.1], anchor=(0.04, 0.0, 0, -1, -1.2, -0.2, 0.0))
    node.model = a
    node._publish()
    first = node._msg
    node.model = b
    node._publish()
    assert node._msg is first                 # written in place, not a new message
    _same_msg(out[1], impedance_msg(b, 5, T.FRAME_CATHETER_BASE))
    assert out[0].c == 2.0 and list(out[0].s_table) == [0.1, 0.2, 0.3]


def test_identifier_node_reports_the_sensor_bursts_it_dropped(ros):
    """Twentieth round of issue 12: the default identifier's dropped bursts reach the
    diagnostics as `bursts` / `burst_samples` beside `clipped`."""
    node = ros.add(ImpedanceIdentifierNode(context=ros.context))
    for i in range(3000):                       # the core, fed directly: a sweep, then a burst
        t = i * 1e-3
        x, xd = 0.03 + 0.01 * math.sin(3.0 * t), 0.03 * math.cos(3.0 * t)
        f = 5.0 if 2500 <= i < 2505 else 2.0 * xd + 0.1 + 3.0 * x
        node.ident.update(x, xd, None, f)
    node._to_diag()
    assert node.diag.value('bursts') == '1' and int(node.diag.value('burst_samples')) >= 3
    assert node.diag.value('clipped') == '0'


def _joint_state(x, xd, f):
    m = JointState()
    m.name, m.position, m.velocity, m.effort = ['insertion'], [x], [xd], [f]
    return m


def test_identifier_node_counts_a_failed_update_and_keeps_identifying(ros):
    """The identifier raising on a finite sample (a defect) is an ERROR event and a count,
    not a dead callback: the next sample is identified."""
    node = ros.add(ImpedanceIdentifierNode(context=ros.context))
    real = node.ident.update

    def fails_once(*a):
        node.ident.update = real
        raise ValueError('singular normal matrix')

    node.ident.update = fails_once
    node._on_state(_joint_state(0.03, 0.01, 0.2))
    assert node.diag.get('update_errors') == 1 and node.diag.get('samples') == 0
    lvl, msg = node.diag.active()['update_error']
    assert lvl == 2 and 'singular normal matrix' in msg          # ERROR
    node._on_state(_joint_state(0.03, 0.01, 0.2))
    assert node.diag.get('samples') == 1


def test_identifier_node_says_when_it_cannot_write_its_state_and_still_closes(ros, tmp_path):
    d = tmp_path / 'gone'
    d.mkdir()
    node = ImpedanceIdentifierNode(context=ros.context, parameter_overrides=params(
        state_file=str(d / 'ident.json')))
    node.ident.update(0.03, 0.01, 0.0, 0.2)
    d.rmdir()                                          # the folder vanished during the run
    from catheter_common.ros_testing import CapturedLog
    log = CapturedLog(node)
    node.close()                                       # no exception
    errors = log.texts('error')
    assert len(errors) == 1 and 'could not write the learned state' in errors[0]
    node.destroy_node()


def test_identifier_node_held_on_ill_conditioned_data_turns_to_error_after_stuck_after(ros):
    import time
    from types import SimpleNamespace
    node = ros.add(ImpedanceIdentifierNode(context=ros.context, parameter_overrides=params(
        stuck_after=0.1)))
    node.ident = SimpleNamespace(status='ill_conditioned', n_held=3)
    node._to_diag()
    assert node.diag.active()['held'][0] == 1                        # WARN
    time.sleep(0.15)
    node._to_diag()
    lvl, msg = node.diag.active()['held']
    assert lvl == 2 and 'ill-conditioned data for' in msg            # ERROR: stuck
    node.ident = SimpleNamespace(status='ok', n_held=3)
    node._to_diag()
    assert 'held' not in node.diag.active() and node._ill_since is None
    node.ident = SimpleNamespace(status='ill_conditioned', n_held=3)
    node._to_diag()
    assert node.diag.active()['held'][0] == 1                        # the clock starts again


def test_sim_haptic_node_restarts_on_a_clock_jump_and_counts_mistimed_sends(ros):
    """Sim time that jumps back (a bag or a simulation restarted) restarts the script, the
    device and the links, counted; a slave message before the first tick, or stamped before
    the previous send on its link, is counted and dropped, never raised."""
    from catheter_common.ros_testing import ManualClock
    node = SimHapticNode(context=ros.context, parameter_overrides=params(rate=200.0))
    clock = ManualClock(node, 1.0)
    w = WrenchStamped()
    w.wrench.force.x = 0.1
    node._on_slave_force(w)                                  # before the first tick
    assert node.diag.get('force_before_start') == 1 and node.diag.get('force_sent') == 0
    clock.tick(1.0, 1.005)
    clock.set(1.010)
    node._on_slave_force(w)
    clock.set(1.007)                                         # after the tick, before that send
    node._on_slave_force(w)
    assert node.diag.get('force_sent') == 1 and node.diag.get('force_out_of_time') == 1
    links = (node.link_imp, node.link_force)
    resets = []
    real_reset = node.device.reset
    node.device.reset = lambda: (resets.append(1), real_reset())
    clock.tick(0.5)                                          # the clock jumped back
    assert node.diag.get('clock_resets') == 1 and node.run.t_last == 0.0 and resets == [1]
    assert node.link_imp is not links[0] and node.link_force is not links[1]
    clock.set(0.501)
    node._on_slave_force(w)                                  # the new link takes it
    assert node.diag.get('force_sent') == 2
    node.destroy_node()

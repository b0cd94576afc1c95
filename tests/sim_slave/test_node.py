"""sim_slave_node in-process, driven in lockstep by a /clock publisher (use_sim_time)."""
import math

import pytest
from geometry_msgs.msg import WrenchStamped
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from catheter_interfaces.msg import MasterCommand
from sensor_msgs.msg import JointState

from catheter_common.topics import (CLOCK, FRAME_CATHETER_BASE, MASTER_COMMAND, SLAVE_FORCE,
                                    SLAVE_JOINT_STATE, SLAVE_JOINT_STATE_DECIMATED)
from catheter_common.qos import QOS_DEFAULT, QOS_FAST
from sim_slave.sim_slave_node import SimSlaveNode

pytestmark = pytest.mark.ros


class Rig:
    """The node under test, a /clock source, a command publisher and output recorders."""

    def __init__(self, ros, **params):
        overrides = [Parameter('use_sim_time', value=True)]
        overrides += [Parameter(k, value=v) for k, v in params.items()]
        self.ros = ros
        self.node = ros.add(SimSlaveNode(context=ros.context, parameter_overrides=overrides))
        self.peer = ros.node('sim_slave_test_peer')
        self.clock = self.peer.create_publisher(Clock, CLOCK, QOS_DEFAULT)
        self.cmd = self.peer.create_publisher(MasterCommand, MASTER_COMMAND, QOS_FAST)
        self.js, self.force = [], []
        self.peer.create_subscription(JointState, SLAVE_JOINT_STATE, self.js.append, QOS_FAST)
        self.peer.create_subscription(WrenchStamped, SLAVE_FORCE, self.force.append, QOS_FAST)
        self.ms = 0
        assert ros.spin_until(lambda: (self.node.pub_js.get_subscription_count() > 0
                                       and self.node.pub_force.get_subscription_count() > 0
                                       and self.cmd.get_subscription_count() > 0
                                       and self.clock.get_subscription_count() > 0), 10.0)

    def step(self, command=None):
        """Advance the clock by 1 ms, then (optionally) publish a command (insertion m,
        rotation rad) stamped at that time."""
        self.ms += 1
        c = Clock()
        c.clock.sec, c.clock.nanosec = divmod(self.ms * 1_000_000, 1_000_000_000)
        self.clock.publish(c)
        n_js = len(self.js)
        self.ros.spin_until(lambda: len(self.js) > n_js, 2.0)   # the tick of this ms
        if command is not None:
            m = MasterCommand()
            m.header.stamp = c.clock
            m.position, m.rotation = command
            n = self.node.diag.get('commands_received') + self.node.diag.get('bad_commands')
            self.cmd.publish(m)
            self.ros.spin_until(lambda: self.node.diag.get('commands_received')
                                + self.node.diag.get('bad_commands') > n, 2.0)


def stamp(msg):
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


def test_outputs_follow_commands_with_the_configured_delay(ros):
    rig = Rig(ros, **{'link.delay': 0.1, 'link.outages': [0.0, 0.0], 'sensor.noise_std': 0.0})
    t_step = 0.2                                 # the command steps to 10 mm at t = 0.2 s
    for k in range(700):
        t = (k + 1) / 1000
        rig.step((0.01 if t >= t_step else 0.0, 0.5 if t >= t_step else 0.0))
    js = rig.js
    assert len(js) >= 600                        # nearly every tick seen (best effort)
    assert all(m.header.frame_id == FRAME_CATHETER_BASE and m.name == ['insertion', 'rotation']
               for m in js)
    t0 = rig.node.run.t0
    moved = [stamp(m) - t0 for m in js if m.position[0] > 1e-9]
    # the step was sent at ~0.2 s after the first tick; it is followed 0.1 s later
    first = moved[0]
    assert t_step + 0.1 - 0.004 <= first + t0 <= t_step + 0.1 + 0.004
    last = js[-1]
    assert last.position[0] == pytest.approx(0.01, abs=2e-4)      # tracked (300 ms later)
    assert last.position[1] == pytest.approx(0.5, abs=0.05)
    assert last.effort[0] > 0.0                                   # friction after insertion
    # /slave/force carries the same measured force as the joint state's effort
    by_stamp = {stamp(m): m.effort[0] for m in js}
    matched = [(by_stamp[stamp(w)], w.wrench.force.x) for w in rig.force if stamp(w) in by_stamp]
    assert len(matched) > 550
    assert all(a == b for a, b in matched)
    assert all(w.header.frame_id == FRAME_CATHETER_BASE for w in rig.force)
    # before the delayed command arrives, the catheter is out and the force is zero
    assert all(m.effort[0] == 0.0 for m in js if stamp(m) - t0 < 0.29 - t0)
    d = rig.node.diag
    assert d.get('commands_received') >= 650 and d.get('commands_delivered') >= 550
    assert d.get('bad_commands') == 0


def test_decimated_joint_state_is_the_first_state_of_each_period(ros):
    rig = Rig(ros, **{'link.delay': 0.0, 'link.outages': [0.0, 0.0], 'decimated_rate': 100.0})
    dec = []
    rig.peer.create_subscription(JointState, SLAVE_JOINT_STATE_DECIMATED, dec.append, QOS_FAST)
    assert ros.spin_until(lambda: rig.node.pub_js_dec.get_subscription_count() > 0, 10.0)
    for k in range(95):
        rig.step((0.002 * k / 95, 0.0))
    ros.spin_until(lambda: False, 0.2)                  # the last ones delivered
    full = {stamp(m): (tuple(m.position), tuple(m.velocity), tuple(m.effort)) for m in rig.js}
    ts = [stamp(m) for m in dec]
    assert 8 <= len(dec) <= 10                          # 95 ms at 100 Hz
    # one per 10 ms period of the node clock, its first state: the tick at a multiple of 10
    # ms (the first period's first tick is the node's first, at 1 ms)
    assert [round(t * 1000) % 10 for t in ts[1:]] == [0] * (len(ts) - 1)
    assert round(ts[0] * 1000) < 10
    assert [round((b - a) * 1000) for a, b in zip(ts[1:], ts[2:], strict=False)] == \
        [10] * (len(ts) - 2)
    # the same message as the full stream's at that stamp
    assert all(full[stamp(m)] == (tuple(m.position), tuple(m.velocity), tuple(m.effort))
               for m in dec if stamp(m) in full)
    assert all(m.header.frame_id == FRAME_CATHETER_BASE for m in dec)


def test_outage_holds_the_last_command_and_bad_messages_are_counted(ros):
    rig = Rig(ros, **{'link.delay': 0.0, 'link.outages': [0.1, 0.2]})
    for k in range(400):
        rig.step((0.02 * (k + 1) / 400, 0.0))          # a ramp to 20 mm in 0.4 s
        if k == 50:
            rig.step((math.nan, 0.0))
            rig.step((0.01, math.inf))
    for _ in range(250):
        rig.step((0.02, 0.0))
    st = rig.node.link.stats
    assert st.lost_outage >= 190                       # 0.2 s of 1 kHz commands
    t0 = rig.node.run.t0
    # the stage stops within its acceleration limit (0.6 mm from 50 mm/s at 2 m/s^2), then holds
    held = [m.position[0] for m in rig.js if 0.2 < stamp(m) - t0 < 0.3]
    assert held and max(held) - min(held) < 1e-5
    after = [m.position[0] for m in rig.js if stamp(m) - t0 > 0.35]
    assert after[-1] == pytest.approx(0.02, abs=1e-4)   # resumes after the outage
    assert rig.node.diag.get('bad_commands') == 2
    assert rig.node.diag.get('steps') >= 400


def test_initial_position_is_held_until_a_command_arrives(ros):
    rig = Rig(ros, **{'robot.x0': 0.03, 'link.delay': 0.05, 'link.outages': [0.0, 0.0],
                      'sensor.noise_std': 0.0, 'vessel.cardiac_amplitude': 0.0})
    for _ in range(40):
        rig.step((0.03, 0.0))
    assert all(m.position[0] == 0.03 for m in rig.js)
    assert all(m.effort[0] == 0.0 for m in rig.js)     # at rest from the start: no friction load


def test_bad_parameters_are_refused(ros):
    with pytest.raises(Exception, match='outages'):
        SimSlaveNode(context=ros.context,
                     parameter_overrides=[Parameter('link.outages', value=[1.0, 2.0, 3.0])])


def test_a_clock_jump_restarts_the_simulation_and_mistimed_commands_are_counted(ros):
    """Sim time that jumps back restarts the simulation and the link (counted); a command
    before the first tick, stamped after a jump back, or behind the link's last send is
    counted or dropped, never raised."""
    from catheter_common.ros_testing import ManualClock
    node = SimSlaveNode(context=ros.context)
    clock = ManualClock(node, 2.0)
    cmd = MasterCommand()
    cmd.position = 0.01
    node._on_command(cmd)
    assert node.diag.get('commands_before_start') == 1
    clock.tick(2.0, 2.001)
    clock.set(2.004)
    node._on_command(cmd)
    clock.set(2.002)                                 # after the tick, before that send
    node._on_command(cmd)
    assert node.diag.get('commands_received') == 2
    assert node.diag.get('commands_out_of_time') == 1
    clock.set(1.0)                                   # jumped back, before the next tick
    node._on_command(cmd)
    assert node.diag.get('commands_received') == 2   # dropped: the next tick restarts
    resets = []
    real = node.sim.reset
    node.sim.reset = lambda: (resets.append(1), real())
    node.x_cmd = node.sim.robot.x + 0.02             # the old run's last delivered command
    node._tick()
    assert node.diag.get('clock_resets') == 1 and resets == [1] and node.run.t_last == 0.0
    assert node.x_cmd == node.sim.robot.x            # the new run holds the initial position
    clock.set(1.001)
    node._on_command(cmd)
    assert node.diag.get('commands_received') == 3 and node.diag.get('commands_out_of_time') == 1
    node.destroy_node()

"""ROS 2 node `sim_haptic_node` (master side): the simulated haptic device, the operator's
scripted hand and the master's side of the UDP-like link, stepped at `rate` Hz.

Publishes   /master/command         sensor_msgs/JointState, name [insertion, rotation],
                                    position [x m, 0], velocity [x' m/s, 0], effort
                                    [x'' m/s^2, 0] (effort carries the ACCELERATION of the
                                    handle, used by the IMA renderer). QOS_FAST.
            /master/link/impedance  /slave/impedance messages as delivered by the link.
            /master/link/force      /slave/force messages as delivered by the link.
            /master/hand_force      geometry_msgs/WrenchStamped, force.x = force at the
                                    operator's hand N (for metrics and plots). QOS_FAST.
            /diagnostics            ticks, overruns, bad messages, link counters, last force.
Subscribes  /master/rendered_force  geometry_msgs/WrenchStamped (force.x N): the desired force
                                    the device's Eq. 36 PID loop tracks (0 until received).
            /slave/impedance, /slave/force  sent into the master's side of the link (delay,
                                    jitter, loss, outages, latest wins; sim_slave.link.Link).
Parameters: rate Hz; experiment (I | II) and seed of the scripted hand (held at its last
position when the script ends); compliant_hand, hand_stiffness N/m, hand_damping N s/m;
link.delay s, link.jitter s, link.loss, link.outages (flat start,length,... s after the
first tick). Timer on the node clock (use_sim_time supported); a clock jump back restarts
the script, the device and the links.
Thin: physics in impedance_master.haptic / operator, the link in sim_slave.link.
"""
from __future__ import annotations

import math

from geometry_msgs.msg import WrenchStamped
from rclpy.node import Node
from sensor_msgs.msg import JointState

from catheter_common.ros_node import Diagnostics, declare, run_node
from catheter_common.topics import (FRAME_CATHETER_BASE, MASTER_COMMAND, MASTER_LINK_FORCE,
                                    MASTER_LINK_IMPEDANCE, MASTER_RENDERED_FORCE, SLAVE_FORCE,
                                    SLAVE_IMPEDANCE)
from catheter_common.qos import QOS_FAST
from impedance_master.haptic import HapticDevice
from impedance_master.operator import experiment_trajectory
from sim_slave.link import Link
from sim_slave.ros_link import declare_link

#: force at the operator's hand (not in DESIGN section 4; local to this package)
from catheter_common.topics import MASTER_HAND_FORCE  # noqa: E402  (re-exported)
JOINT_NAMES = ['insertion', 'rotation']


class SimHapticNode(Node):
    """Haptic device + scripted operator + master side of the link (see module doc)."""

    def __init__(self, **kwargs):
        super().__init__('sim_haptic_node', **kwargs)
        self.rate = declare(self, 'rate', 1000.0, 'device and publishing rate, Hz',
                            10.0, 10000.0)
        self.experiment = declare(self, 'experiment', 'II',
                                  "scripted hand: thesis Experiment 'I' (20 s) or 'II' (12 s)",
                                  choices=('I', 'II'))
        self.seed = declare(self, 'seed', 0, 'seed of the hand script, links and sensor noise',
                            0, 2 ** 31 - 1)
        compliant = declare(self, 'compliant_hand', False,
                            'spring-damper hand around the script (else rigid)')
        k_hand = declare(self, 'hand_stiffness', 300.0, 'compliant hand stiffness, N/m',
                         1.0, 1e5)
        b_hand = declare(self, 'hand_damping', 15.0, 'compliant hand damping, N s/m', 0.0, 1e3)
        self.link_cfg = declare_link(self, 'impedance and force from the slave')
        self.traj = experiment_trajectory(self.experiment, seed=self.seed)
        self.device = HapticDevice(dt=1.0 / self.rate,
                                   hand_stiffness=k_hand if compliant else None,
                                   hand_damping=b_hand, seed=self.seed)
        self._new_links()
        self.f_rendered = 0.0
        self.t0 = None
        self.t_last = None
        self.last = None
        self.diag = Diagnostics(self)
        self.pub_cmd = self.create_publisher(JointState, MASTER_COMMAND, QOS_FAST)
        self.pub_imp = self.create_publisher(JointState, MASTER_LINK_IMPEDANCE, QOS_FAST)
        self.pub_force = self.create_publisher(WrenchStamped, MASTER_LINK_FORCE, QOS_FAST)
        self.pub_hand = self.create_publisher(WrenchStamped, MASTER_HAND_FORCE, QOS_FAST)
        self.create_subscription(WrenchStamped, MASTER_RENDERED_FORCE, self._on_rendered,
                                 QOS_FAST)
        self.create_subscription(JointState, SLAVE_IMPEDANCE, self._on_impedance, QOS_FAST)
        self.create_subscription(WrenchStamped, SLAVE_FORCE, self._on_slave_force, QOS_FAST)
        self.timer = self.create_timer(1.0 / self.rate, self._tick)
        self._diag_timer = self.create_timer(1.0, self._to_diag)
        self.get_logger().info(
            f'haptic device at {self.rate:g} Hz, Experiment {self.experiment} hand (seed '
            f'{self.seed}, {"compliant" if compliant else "rigid"}); link slave -> master: '
            f'{self.link_cfg.describe()}')

    def _new_links(self) -> None:
        self.link_imp = Link(self.link_cfg, seed=2 * self.seed + 11)
        self.link_force = Link(self.link_cfg, seed=2 * self.seed + 12)

    def _now(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def _bad(self, what: str, why: str) -> None:
        self.diag.count('bad_messages')
        self.diag.error(f'{what}: {why}')
        self.get_logger().warning(f'bad {what}: {why}', throttle_duration_sec=2.0)

    def _t(self):
        """Time since the first tick (s), or None before it / after a clock jump back."""
        if self.t0 is None:
            return None
        t = self._now() - self.t0
        if self.t_last is not None and t < self.t_last:
            return None
        return t

    def _on_rendered(self, msg: WrenchStamped) -> None:
        f = msg.wrench.force.x
        if not math.isfinite(f):
            self._bad('rendered force', f'non-finite force.x {f!r}')
            return
        self.f_rendered = f
        self.diag.count('rendered_forces')

    def _send(self, link: Link, msg, key: str) -> None:
        t = self._t()
        if t is None:
            self.diag.count(key + '_before_start')
            return
        try:
            link.send(t, msg)
        except ValueError:   # a send time before the previous one (clock reset)
            self.diag.count(key + '_out_of_time')
            return
        self.diag.count(key + '_sent')

    def _on_impedance(self, msg: JointState) -> None:
        if len(msg.name) != len(msg.position):
            self._bad('impedance', 'name and position lengths differ')
            return
        self._send(self.link_imp, msg, 'impedance')

    def _on_slave_force(self, msg: WrenchStamped) -> None:
        if not math.isfinite(msg.wrench.force.x):
            self._bad('slave force', 'non-finite force.x')
            return
        self._send(self.link_force, msg, 'force')

    def _tick(self) -> None:
        stamp = self.get_clock().now()
        now = stamp.nanoseconds * 1e-9
        if self.t0 is None:
            self.t0 = now
        t = now - self.t0
        if self.t_last is not None and t < self.t_last:
            self.get_logger().warning('the clock jumped back: restarting script, device, links')
            self.diag.count('clock_resets')
            self.t0, t = now, 0.0
            self.device.reset()
            self._new_links()
        self.t_last = t
        xh, vh, ah = self.traj.sample(t)
        s = self.device.step(self.f_rendered, xh, vh, ah)
        self.last = s
        self.diag.count('ticks')
        st = stamp.to_msg()
        if self.pub_cmd.get_subscription_count() > 0:
            js = JointState()
            js.header.stamp = st
            js.header.frame_id = FRAME_CATHETER_BASE
            js.name = JOINT_NAMES
            js.position = [s.x, 0.0]
            js.velocity = [s.xd, 0.0]
            js.effort = [s.xdd, 0.0]
            self.pub_cmd.publish(js)
        if self.pub_hand.get_subscription_count() > 0:
            w = WrenchStamped()
            w.header.stamp = st
            w.header.frame_id = FRAME_CATHETER_BASE
            w.wrench.force.x = s.f_hand
            self.pub_hand.publish(w)
        got = self.link_imp.receive(t)
        if got is not None:
            self.pub_imp.publish(got)
            self.diag.count('impedance_delivered')
        got = self.link_force.receive(t)
        if got is not None:
            self.pub_force.publish(got)
            self.diag.count('force_delivered')

    def _to_diag(self) -> None:
        d = self.diag
        for name, link in (('impedance', self.link_imp), ('force', self.link_force)):
            st = link.stats
            d.set(f'link_{name}_lost_random', st.lost_random)
            d.set(f'link_{name}_lost_outage', st.lost_outage)
            d.set(f'link_{name}_dropped_stale', st.dropped_stale)
        if self.t_last is not None:
            d.set('link_in_outage', str(self.link_imp.in_outage(self.t_last)))
        if self.last is not None:
            d.set('hand_force_n', float(self.last.f_hand))
            d.set('insertion_m', float(self.last.x))
            d.set('desired_force_n', float(self.f_rendered))


NODE_CLASS = SimHapticNode


def main(args=None):
    return run_node(NODE_CLASS, args)


if __name__ == '__main__':
    raise SystemExit(main())

"""ROS 2 node `sim_haptic_node` (master side): the simulated haptic device, the operator's
scripted hand and the master's side of the UDP-like link, stepped at `rate` Hz.

Publishes   master/command          sensor_msgs/JointState, name [insertion, rotation],
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
first tick; the link.* parameters apply at run time to packets sent from then on, the
others are fixed at start). Timer on the node clock (use_sim_time supported); a clock jump
back restarts the script, the device and the links. Topic names are relative (the node's
namespace applies); /diagnostics is WARN during a link outage and after bad messages.
Thin: physics in impedance_master.haptic / operator, the link in sim_slave.link.
"""
from __future__ import annotations

import math

from geometry_msgs.msg import WrenchStamped
from rclpy.node import Node
from sensor_msgs.msg import JointState

from catheter_common import topics as T
from catheter_common.checks import all_finite
from catheter_common.diagnostics import WARN, Diagnostics
from catheter_common.params import NodeParams, Param, table
from catheter_common.qos import QOS_FAST
from catheter_common.ros_node import run_node
from impedance_master.haptic import HapticDevice
from impedance_master.operator import experiment_trajectory
from sim_slave.link import Link
from sim_slave.sim_slave_node import link_config, link_params

#: force at the operator's hand (re-exported for the tests and tools that import it here)
MASTER_HAND_FORCE = T.MASTER_HAND_FORCE
JOINT_NAMES = ['insertion', 'rotation']
#: N, the largest desired force the simulated device accepts (its motor saturates far below;
#: a bigger value is a renderer fault and is refused, the last force is kept)
MAX_DESIRED_FORCE = 100.0

PARAMS = table(
    Param('rate', 1000.0, 'device and publishing rate, Hz', 10.0, 10000.0),
    Param('experiment', 'II', "scripted hand: thesis Experiment 'I' (20 s) or 'II' (12 s)",
          choices=('I', 'II')),
    Param('seed', 0, 'seed of the hand script, links and sensor noise', 0, 2 ** 31 - 1),
    Param('compliant_hand', False, 'spring-damper hand around the script (else rigid)'),
    Param('hand_stiffness', 300.0, 'compliant hand stiffness, N/m', 1.0, 1e5),
    Param('hand_damping', 15.0, 'compliant hand damping, N s/m', 0.0, 1e3),
    *link_params('impedance and force from the slave'),
)


class SimHapticNode(Node):
    """Haptic device + scripted operator + master side of the link (see module doc)."""

    PARAMS = PARAMS

    def __init__(self, **kwargs):
        super().__init__('sim_haptic_node', **kwargs)
        self.params = p = NodeParams(self, PARAMS, apply=self._apply_params)
        self.rate = p['rate']
        self.experiment = p['experiment']
        self.seed = p['seed']
        compliant = p['compliant_hand']
        self.link_cfg = link_config(p.values)
        self.traj = experiment_trajectory(self.experiment, seed=self.seed)
        self.device = HapticDevice(dt=1.0 / self.rate,
                                   hand_stiffness=p['hand_stiffness'] if compliant else None,
                                   hand_damping=p['hand_damping'], seed=self.seed)
        self._new_links()
        self.f_rendered = 0.0
        self.t0 = None
        self.t_last = None
        self.last = None
        self.diag = Diagnostics(self)
        self.diag.count('bad_messages', 0)
        rel = T.relative
        self.pub_cmd = self.create_publisher(JointState, rel(T.MASTER_COMMAND), QOS_FAST)
        self.pub_imp = self.create_publisher(JointState, rel(T.MASTER_LINK_IMPEDANCE), QOS_FAST)
        self.pub_force = self.create_publisher(WrenchStamped, rel(T.MASTER_LINK_FORCE), QOS_FAST)
        self.pub_hand = self.create_publisher(WrenchStamped, rel(T.MASTER_HAND_FORCE), QOS_FAST)
        self.create_subscription(WrenchStamped, rel(T.MASTER_RENDERED_FORCE), self._on_rendered,
                                 QOS_FAST)
        self.create_subscription(JointState, rel(T.SLAVE_IMPEDANCE), self._on_impedance,
                                 QOS_FAST)
        self.create_subscription(WrenchStamped, rel(T.SLAVE_FORCE), self._on_slave_force,
                                 QOS_FAST)
        self.timer = self.create_timer(1.0 / self.rate, self._tick)
        self.diag.add_updater(self._to_diag)
        self.get_logger().info(
            f'haptic device at {self.rate:g} Hz, Experiment {self.experiment} hand (seed '
            f'{self.seed}, {"compliant" if compliant else "rigid"}); link slave -> master: '
            f'{self.link_cfg.describe()}')

    def _apply_params(self, changes, values) -> None:
        if any(k.startswith('link.') for k in changes):
            cfg = link_config(values)                    # ValueError refuses the change
            self.link_cfg = cfg
            self.link_imp.config = cfg
            self.link_force.config = cfg

    def _new_links(self) -> None:
        self.link_imp = Link(self.link_cfg, seed=2 * self.seed + 11)
        self.link_force = Link(self.link_cfg, seed=2 * self.seed + 12)

    def _now(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

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
        if not math.isfinite(f) or abs(f) > MAX_DESIRED_FORCE:
            self.diag.bad_input('rendered_force', f'force.x {f!r} is not a finite force within '
                                f'+-{MAX_DESIRED_FORCE:g} N: the last one is kept')
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
            self.diag.bad_input('impedance', 'name and position lengths differ')
            return
        try:
            all_finite('position', msg.position)
        except ValueError as exc:
            self.diag.bad_input('impedance', str(exc))
            return
        self._send(self.link_imp, msg, 'impedance')

    def _on_slave_force(self, msg: WrenchStamped) -> None:
        f, t = msg.wrench.force, msg.wrench.torque
        try:
            all_finite('wrench (force xyz, torque xyz)', (f.x, f.y, f.z, t.x, t.y, t.z))
        except ValueError as exc:
            self.diag.bad_input('slave_force', str(exc))
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
            js.header.frame_id = T.FRAME_CATHETER_BASE
            js.name = JOINT_NAMES
            js.position = [s.x, 0.0]
            js.velocity = [s.xd, 0.0]
            js.effort = [s.xdd, 0.0]
            self.pub_cmd.publish(js)
        if self.pub_hand.get_subscription_count() > 0:
            w = WrenchStamped()
            w.header.stamp = st
            w.header.frame_id = T.FRAME_CATHETER_BASE
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
        outage = self.t_last is not None and self.link_imp.in_outage(self.t_last)
        d.set('link_in_outage', str(outage))
        d.condition('link_outage', WARN if outage else 0,
                    'link outage: the slave\'s impedance and force do not arrive')
        if self.last is not None:
            d.set('hand_force_n', float(self.last.f_hand))
            d.set('insertion_m', float(self.last.x))
            d.set('desired_force_n', float(self.f_rendered))


NODE_CLASS = SimHapticNode


def main(args=None):
    return run_node(NODE_CLASS, args)


if __name__ == '__main__':
    raise SystemExit(main())

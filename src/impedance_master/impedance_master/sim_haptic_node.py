"""ROS 2 node `sim_haptic_node` (master side): the simulated haptic device, the operator's
scripted hand and the master's side of the UDP-like link, stepped at `rate` Hz.

Publishes   master/command          catheter_interfaces/MasterCommand: position x m,
                                    velocity x' m/s, acceleration x'' m/s^2 of the handle
                                    (used by the IMA renderer), rotation 0 rad. QOS_FAST.
            /master/link/impedance  /slave/impedance messages (catheter_interfaces/
                                    ImpedanceModel) as delivered by the link.
            /master/link/force      /slave/force messages as delivered by the link.
            /master/hand_force      geometry_msgs/WrenchStamped, force.x = force at the
                                    operator's hand N (for metrics and plots). QOS_FAST.
            /diagnostics            ticks, overruns, bad messages, link counters, last force.
Subscribes  /master/rendered_force  geometry_msgs/WrenchStamped (force.x N): the desired force
                                    the device's Eq. 36 PID loop tracks (0 until received).
            /slave/impedance (ImpedanceModel; a malformed one is refused), /slave/force
                                    sent into the master's side of the link (delay,
                                    jitter, loss, outages, latest wins; sim_slave.link.Link).
                                    QOS_LINK (keep last 100: nothing lost after a stall).
Parameters: rate Hz; experiment (I | II), operator.family (minjerk | sines | human: the
motion family, impedance_master.operator) and seed of the scripted hand (held at its last position
when the script ends); compliant_hand, hand_stiffness N/m, hand_damping N s/m;
link.delay s, link.jitter s, link.loss, link.outages (flat start,length,... s after the
first tick; the link.* parameters apply at run time to packets sent from then on, the
others are fixed at start). Timer on the node clock (use_sim_time supported); a clock jump
back restarts the script, the device and the links. Topic names are relative (the node's
namespace applies); /diagnostics is WARN during a link outage and after bad messages.
Thin: physics in impedance_master.haptic / operator, the link in sim_slave.link.
"""
from __future__ import annotations

import math

from catheter_interfaces.msg import ImpedanceModel, MasterCommand
from geometry_msgs.msg import WrenchStamped
from rclpy.node import Node

from catheter_common import topics as T
from catheter_common.checks import all_finite
from catheter_common.diagnostics import WARN, Diagnostics
from catheter_common.messages import impedance_fields, impedance_key
from catheter_common.outgoing import CommandOut, WrenchOut
from catheter_common.params import NodeParams, Param, table
from catheter_common.qos import QOS_FAST, QOS_LINK
from catheter_common.ros_node import clock_ns, node_main
from impedance_master.haptic import HapticDevice
from impedance_master.operator import OPERATORS, experiment_trajectory
from sim_slave.link import Link
from sim_slave.link_side import (RunClock, apply_link_changes, link_config, link_params,
                                 link_to_diag)

#: force at the operator's hand (re-exported for the tests and tools that import it here)
MASTER_HAND_FORCE = T.MASTER_HAND_FORCE
#: N, the largest desired force the simulated device accepts (its motor saturates far below;
#: a bigger value is a renderer fault and is refused, the last force is kept)
MAX_DESIRED_FORCE = 100.0

PARAMS = table(
    Param('rate', 1000.0, 'device and publishing rate, Hz', 10.0, 10000.0),
    Param('experiment', 'II', "scripted hand: thesis Experiment 'I' (20 s) or 'II' (12 s)",
          choices=('I', 'II')),
    Param('seed', 0, 'seed of the hand script, links and sensor noise', 0, 2 ** 31 - 1),
    Param('operator.family', 'minjerk', 'the hand\'s motion family (impedance_master.'
          'operator): minjerk (the thesis), sines, human', choices=tuple(OPERATORS)),
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
        self.operator = p['operator.family']
        self.traj = experiment_trajectory(self.experiment, seed=self.seed,
                                          operator=self.operator)
        self.device = HapticDevice(dt=1.0 / self.rate,
                                   hand_stiffness=p['hand_stiffness'] if compliant else None,
                                   hand_damping=p['hand_damping'], seed=self.seed)
        self._new_links()
        self.f_rendered = 0.0
        self.run = RunClock()
        self.last = None
        self.diag = Diagnostics(self)
        self.diag.count('bad_messages', 0)
        rel = T.relative
        self.pub_cmd = self.create_publisher(MasterCommand, rel(T.MASTER_COMMAND), QOS_FAST)
        self.pub_imp = self.create_publisher(ImpedanceModel, rel(T.MASTER_LINK_IMPEDANCE),
                                             QOS_FAST)
        self.pub_force = self.create_publisher(WrenchStamped, rel(T.MASTER_LINK_FORCE), QOS_FAST)
        self.pub_hand = self.create_publisher(WrenchStamped, rel(T.MASTER_HAND_FORCE), QOS_FAST)
        self.create_subscription(WrenchStamped, rel(T.MASTER_RENDERED_FORCE), self._on_rendered,
                                 QOS_FAST)
        # the link from the slave: every sample sent is taken, also after a stall (QOS_LINK)
        self.sub_impedance = self.create_subscription(
            ImpedanceModel, rel(T.SLAVE_IMPEDANCE), self._on_impedance, QOS_LINK)
        self.sub_slave_force = self.create_subscription(
            WrenchStamped, rel(T.SLAVE_FORCE), self._on_slave_force, QOS_LINK)
        # the 1 kHz tick's own objects: one message per stream, reused (serialised at publish,
        # catheter_common.outgoing), and the node clock (the same object for the node's life)
        self._cmd_out = CommandOut(T.FRAME_CATHETER_BASE)
        self._hand_out = WrenchOut(T.FRAME_CATHETER_BASE)
        self._clock = self.get_clock()
        self._clock_ns = clock_ns(self._clock)
        self._imp_checked = None      # impedance_key of the last model that passed the check
        self.timer = self.create_timer(1.0 / self.rate, self._tick)
        self.diag.add_updater(self._to_diag)
        self.get_logger().info(
            f'haptic device at {self.rate:g} Hz, Experiment {self.experiment} {self.operator} '
            f'hand (seed '
            f'{self.seed}, {"compliant" if compliant else "rigid"}); link slave -> master: '
            f'{self.link_cfg.describe()}')

    def _apply_params(self, changes, values) -> None:
        cfg = apply_link_changes(changes, values, self.link_imp, self.link_force)
        if cfg is not None:
            self.link_cfg = cfg

    def _new_links(self) -> None:
        self.link_imp = Link(self.link_cfg, seed=2 * self.seed + 11)
        self.link_force = Link(self.link_cfg, seed=2 * self.seed + 12)

    def _now(self) -> float:
        return self._clock_ns() * 1e-9

    def _on_rendered(self, msg: WrenchStamped) -> None:
        f = msg.wrench.force.x
        if not math.isfinite(f) or abs(f) > MAX_DESIRED_FORCE:
            self.diag.bad_input('rendered_force', f'force.x {f!r} is not a finite force within '
                                f'+-{MAX_DESIRED_FORCE:g} N: the last one is kept')
            return
        self.f_rendered = f
        self.diag.count('rendered_forces')

    def _send(self, link: Link, msg, key: str) -> None:
        t = self.run.at(self._now())
        if t is None:
            self.diag.count(key + '_before_start')
            return
        try:
            link.send(t, msg)
        except ValueError:   # a send time before the previous one (clock reset)
            self.diag.count(key + '_out_of_time')
            return
        self.diag.count(key + '_sent')

    def _on_impedance(self, msg: ImpedanceModel) -> None:
        key = impedance_key(msg)
        if key != self._imp_checked:
            # a model the master could not read is not sent; checked once per model (the
            # identifier re-sends a held model re-stamped every period; a key holding a NaN
            # never equals an earlier one)
            try:
                impedance_fields(msg)
            except ValueError as exc:
                self.diag.bad_input('impedance', str(exc))
                return
            self._imp_checked = key
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
        ns = self._clock_ns()
        t, restarted = self.run.tick(ns * 1e-9)
        if restarted:
            self.get_logger().warning('the clock jumped back: restarting script, device, links')
            self.diag.count('clock_resets')
            self.device.reset()
            self._new_links()
        xh, vh, ah = self.traj.sample(t)
        s = self.device.step(self.f_rendered, xh, vh, ah)
        self.last = s
        diag = self.diag
        diag.count('ticks')
        if self.pub_cmd.get_subscription_count() > 0:
            try:
                cmd = self._cmd_out.fill(ns, s.x, s.xd, s.xdd, 0.0)
            except ValueError as exc:     # a device state that is not finite is not sent
                diag.count('nonfinite_commands')
                diag.event('nonfinite_command', WARN, f'command not sent: {exc}')
            else:
                self.pub_cmd.publish(cmd)
        if self.pub_hand.get_subscription_count() > 0:
            self.pub_hand.publish(self._hand_out.fill(ns, s.f_hand))
        # what the links deliver is the slave's own message object: re-published as it is
        # (never one of the reused ones above)
        got = self.link_imp.receive(t)
        if got is not None:
            self.pub_imp.publish(got)
            diag.count('impedance_delivered')
        got = self.link_force.receive(t)
        if got is not None:
            self.pub_force.publish(got)
            diag.count('force_delivered')

    def _to_diag(self) -> None:
        d = self.diag
        link_to_diag(d, [('link_impedance', self.link_imp), ('link_force', self.link_force)],
                     self.run.t_last, 'the slave\'s impedance and force do not arrive',
                     counters=('lost_random', 'lost_outage', 'dropped_stale'))
        if self.last is not None:
            d.set('hand_force_n', float(self.last.f_hand))
            d.set('insertion_m', float(self.last.x))
            d.set('desired_force_n', float(self.f_rendered))


NODE_CLASS = SimHapticNode
main = node_main(NODE_CLASS)


if __name__ == '__main__':
    raise SystemExit(main())

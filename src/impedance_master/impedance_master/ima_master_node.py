"""ROS 2 node `ima_master_node` (master side): renders the desired force for the haptic device.

Subscribes  /master/command         sensor_msgs/JointState, the LOCAL master trajectory:
                                    position[0] x m, velocity[0] m/s, effort[0] x'' m/s^2
                                    (sim_haptic_node's documented use of effort). QOS_FAST.
            /master/link/impedance  the slave's model as delivered by the link (named values,
                                    see impedance_identifier_node). QOS_FAST.
            /master/link/force      geometry_msgs/WrenchStamped, the slave's force as delivered
                                    (force.x N). QOS_FAST.
Publishes   /master/rendered_force  geometry_msgs/WrenchStamped, force.x = desired force N
                                    (positive resists insertion), frame catheter_base; at
                                    `rate` Hz on the node clock while subscribed. QOS_FAST.
            /diagnostics            rendered, models received / switched / ignored (invalid),
                                    clamps, bad messages, age of the last command.
Parameters: mode (ima | ima_thesis | dfr), rate Hz, limit N, blend_time s, max_rate N/s,
passivity (bool, TDPA).
  ima         ImaRenderer with bumpless model switches, slew limiting and the time-domain
              passivity controller (project default);
  ima_thesis  ImaRenderer rendering only the linear part m x'' + c x' + k x + offset of the
              received model, switched at once (thesis Eq. 35), same clamp;
  dfr         DfrRenderer: the last force received (thesis baseline).
Thin: rendering is impedance_master.rendering.
"""
from __future__ import annotations

import math

from geometry_msgs.msg import WrenchStamped
from rclpy.node import Node
from sensor_msgs.msg import JointState

from catheter_common.ros_node import Diagnostics, declare, run_node
from catheter_common.topics import (FRAME_CATHETER_BASE, MASTER_COMMAND, MASTER_LINK_FORCE,
                                    MASTER_LINK_IMPEDANCE, MASTER_RENDERED_FORCE)
from catheter_common.qos import QOS_FAST
from impedance_master.impedance import Impedance
from impedance_master.rendering import DfrRenderer, ImaRenderer

MODES = ('ima', 'ima_thesis', 'dfr')


def fields_from_msg(msg: JointState) -> dict:
    """Named values of an impedance message (ValueError on a malformed message)."""
    if len(msg.name) != len(msg.position):
        raise ValueError(f'name ({len(msg.name)}) and position ({len(msg.position)}) '
                         'must have the same length')
    return dict(zip(msg.name, msg.position))


class ImaMasterNode(Node):
    """Master-side renderer node (see module doc)."""

    def __init__(self, **kwargs):
        super().__init__('ima_master_node', **kwargs)
        self.mode = declare(self, 'mode', 'ima', 'ima (default model, bumpless), ima_thesis '
                            '(linear Eq. 35) or dfr (direct force reflection)', choices=MODES)
        self.rate = declare(self, 'rate', 1000.0, 'rendering rate, Hz', 10.0, 5000.0)
        limit = declare(self, 'limit', 2.0, 'safe force limit |f_d|, N', 0.01, 20.0)
        blend = declare(self, 'blend_time', 0.05, 'bumpless model switch time constant, s',
                        0.0, 5.0)
        max_rate = declare(self, 'max_rate', 20.0, 'slew-rate limit of the desired force, N/s',
                           0.01, 1e6)
        passivity = declare(self, 'passivity', True, 'time-domain passivity controller on the '
                            'rendered model (mode ima only)')
        dt = 1.0 / self.rate
        if self.mode == 'dfr':
            self.renderer = DfrRenderer(limit=limit)
        elif self.mode == 'ima_thesis':
            self.renderer = ImaRenderer(limit=limit, blend_time=0.0, max_rate=1e6, dt=dt)
        else:
            self.renderer = ImaRenderer(limit=limit, blend_time=blend, max_rate=max_rate, dt=dt,
                                        passivity=passivity)
        self.state = None            # (x, xd, xdd) of the local trajectory
        self._t_state = None
        self._last_values = None
        self._last_names = None
        self.diag = Diagnostics(self)
        self.pub = self.create_publisher(WrenchStamped, MASTER_RENDERED_FORCE, QOS_FAST)
        self.create_subscription(JointState, MASTER_COMMAND, self._on_command, QOS_FAST)
        self.create_subscription(JointState, MASTER_LINK_IMPEDANCE, self._on_impedance, QOS_FAST)
        self.create_subscription(WrenchStamped, MASTER_LINK_FORCE, self._on_force, QOS_FAST)
        self.timer = self.create_timer(dt, self._render)
        self._diag_timer = self.create_timer(1.0, self._to_diag)
        self.get_logger().info(
            f'rendering {MASTER_RENDERED_FORCE} at {self.rate:g} Hz in mode {self.mode} '
            f'(limit {limit:g} N) from {MASTER_COMMAND}, {MASTER_LINK_IMPEDANCE}, '
            f'{MASTER_LINK_FORCE}')

    def _bad(self, what: str, why: str) -> None:
        self.diag.count('bad_messages')
        self.diag.error(f'{what}: {why}')
        self.get_logger().warning(f'bad {what}: {why}', throttle_duration_sec=2.0)

    def _on_command(self, msg: JointState) -> None:
        if len(msg.position) < 1:
            self._bad('command', 'position is empty')
            return
        x = msg.position[0]
        xd = msg.velocity[0] if len(msg.velocity) else 0.0
        xdd = msg.effort[0] if len(msg.effort) else 0.0
        if not (math.isfinite(x) and math.isfinite(xd) and math.isfinite(xdd)):
            self._bad('command', f'non-finite x={x!r} xd={xd!r} xdd={xdd!r}')
            return
        self.state = (x, xd, xdd)
        self._t_state = self.get_clock().now()
        self.diag.count('commands')

    def _on_impedance(self, msg: JointState) -> None:
        if self.mode == 'dfr':
            return
        values = list(msg.position)
        if values == self._last_values and list(msg.name) == self._last_names:
            self.diag.count('models_unchanged')   # the identifier re-sends a held model
            return
        try:
            imp = Impedance.from_fields(fields_from_msg(msg))
        except ValueError as exc:
            self._bad('impedance', str(exc))
            return
        if self.mode == 'ima_thesis' and imp.kind != 0:
            imp = Impedance(imp.m, imp.c, imp.k, imp.offset, imp.valid)
        self._last_values, self._last_names = values, list(msg.name)
        self.diag.count('models_received')
        if not self.renderer.set_impedance(imp):
            self.diag.count('models_ignored_invalid')

    def _on_force(self, msg: WrenchStamped) -> None:
        if self.mode != 'dfr':
            return
        f = msg.wrench.force.x
        if not math.isfinite(f):
            self._bad('force', f'non-finite force.x {f!r}')
            return
        self.renderer.set_force(f)
        self.diag.count('forces_received')

    def _render(self) -> None:
        if self.pub.get_subscription_count() == 0:
            return
        if self.mode == 'dfr':
            f = self.renderer.desired_force()
        elif self.state is None:
            f = 0.0
        else:
            f = self.renderer.desired_force(*self.state)
        msg = WrenchStamped()
        msg.header.stamp = self.get_clock().now().to_msg()
        msg.header.frame_id = FRAME_CATHETER_BASE
        msg.wrench.force.x = float(f)
        self.pub.publish(msg)
        self.diag.count('rendered')

    def _to_diag(self) -> None:
        r = self.renderer
        self.diag.set('mode', self.mode)
        self.diag.set('clamped', r.n_clamped)
        if isinstance(r, ImaRenderer):
            self.diag.set('model_switches', r.n_switches)
            self.diag.set('models_ignored', r.n_ignored)
            self.diag.set('has_model', str(r.model is not None))
            self.diag.set('passivity_steps', r.n_passivity)
            self.diag.set('passivity_energy_j', float(r.energy))
        if self._t_state is not None:
            age = (self.get_clock().now() - self._t_state).nanoseconds * 1e-9
            self.diag.set('command_age_s', float(age))


NODE_CLASS = ImaMasterNode


def main(args=None):
    return run_node(NODE_CLASS, args)


if __name__ == '__main__':
    raise SystemExit(main())

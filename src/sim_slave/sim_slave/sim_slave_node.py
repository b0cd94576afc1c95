"""ROS 2 node `sim_slave_node`: the simulated patient side at 1 kHz.

Subscribes  master/command     sensor_msgs/JointState (position[0] insertion m, position[1]
                               rotation rad, optional), QOS_FAST. Every command goes through
                               the slave's side of the UDP-like link (delay, jitter, loss,
                               outages, latest wins); the robot follows the newest delivered
                               command and holds it while nothing new arrives.
Publishes   slave/joint_state  sensor_msgs/JointState, name [insertion, rotation], position,
                               velocity, effort [measured insertion force N, 0], QOS_FAST
            slave/force        geometry_msgs/WrenchStamped, frame catheter_base, force.x =
                               measured insertion force N, QOS_FAST
            /diagnostics       steps, commands received/delivered/lost/stale, bad commands,
                               overruns, tracking error; WARN during a link outage, after bad
                               commands and overruns
Both outputs are stamped with the node clock and go out undelayed (the master's sim node
applies its side of the link). Timer on the node clock: use_sim_time with a /clock publisher
drives it in lockstep. Outage times are relative to the node's first timer tick. Topic names
are relative (the node's namespace applies). The link parameters (link.*) apply at run time
to the packets sent from then on; the simulation's own are fixed at start.

Thin: message conversion, parameters and timers; the physics is in sim_slave.slave/vessel/
robot/sensor/link.
"""
from __future__ import annotations

import math
from dataclasses import fields

from geometry_msgs.msg import WrenchStamped
from rclpy.node import Node
from sensor_msgs.msg import JointState

from catheter_common import topics as T
from catheter_common.checks import finite, first
from catheter_common.diagnostics import WARN, Diagnostics
from catheter_common.params import NodeParams, Param, table
from catheter_common.qos import QOS_FAST
from catheter_common.ros_node import run_node
from sim_slave.link import Link, LinkConfig
from sim_slave.robot import SlaveRobot
from sim_slave.sensor import ForceSensor
from sim_slave.slave import SlaveSimulation, default_rotation_axis
from sim_slave.vessel import VesselModel, VesselParams

JOINT_NAMES = ['insertion', 'rotation']

#: vessel parameters exposed as `vessel.<field>`: (upper bound of the range, unit)
VESSEL_PARAM_RANGES = {
    'friction_per_length': (100.0, 'N/m, Coulomb friction per inserted metre'),
    'capstan_length': (100.0, 'm, depth over which friction per metre doubles'),
    'stribeck_ratio': (5.0, 'breakaway / Coulomb friction, >= 1'),
    'stribeck_velocity': (1.0, 'm/s, Stribeck velocity'),
    'presliding_displacement': (0.01, 'm, pre-sliding (stick) displacement'),
    'bristle_damping': (100.0, 's/m, normalised LuGre micro-damping'),
    'viscous_per_length': (1000.0, 'N s/m^2, viscous drag per inserted metre'),
    'wall_depth': (1.0, 'm, inserted length where the tip meets the wall'),
    'wall_stiffness': (1e5, 'N/m^n, Hunt-Crossley wall stiffness'),
    'wall_exponent': (3.0, 'Hunt-Crossley exponent'),
    'wall_damping': (100.0, 's/m, Hunt-Crossley damping'),
    'cardiac_amplitude': (1.0, 'N, cardiac disturbance amplitude'),
    'cardiac_frequency': (5.0, 'Hz, heart rate'),
    'cardiac_depth': (1.0, 'm, depth of full cardiac amplitude'),
    'shaft_stiffness': (1e5, 'N/m, axial shaft compliance (0 = rigid; > 0 gives stick-slip)'),
    'shaft_damping': (100.0, 'N s/m, shaft damping (compliant shaft only)'),
    'catheter_mass': (1.0, 'kg, moving catheter mass (compliant shaft only)'),
}
_VESSEL_LOWER = {'stribeck_ratio': 1.0, 'capstan_length': 1e-6, 'stribeck_velocity': 1e-6,
                 'presliding_displacement': 1e-7, 'wall_exponent': 0.1, 'cardiac_depth': 1e-6,
                 'catheter_mass': 1e-5}


def _check_outages(flat):
    LinkConfig.from_flat(0.0, 0.0, 0.0, flat)      # ValueError: odd length, negative length


def link_params(what: str):
    """The simulated link's parameters, declared the same way by every node that holds a side
    of the link (`what` names the traffic this side receives). They apply at run time."""
    return (
        Param('link.delay', 0.2, f'one-way delay of {what}, s', 0.0, 10.0, dynamic=True),
        Param('link.jitter', 0.0, f'extra delay U(0, jitter) per packet of {what}, s', 0.0, 5.0,
              dynamic=True),
        Param('link.loss', 0.0, f'probability that a packet of {what} is lost', 0.0, 1.0,
              dynamic=True),
        Param('link.outages', [4.0, 1.0, 8.0, 1.0], 'link outages as a flat list start,length,'
              '... in s after the first timer tick; [0.0, 0.0] for none', numbers=True,
              dynamic=True, check=_check_outages),
    )


def link_config(values) -> LinkConfig:
    """The LinkConfig of the link.* parameter values."""
    return LinkConfig.from_flat(values['link.delay'], values['link.jitter'],
                                values['link.loss'], values['link.outages'])


PARAMS = table(
    Param('rate', 1000.0, 'simulation and publishing rate, Hz', 10.0, 10000.0),
    Param('seed', 0, 'random seed (vessel phase, sensor noise, link)', 0, 2 ** 31 - 1),
    *link_params('master commands'),
    Param('sensor.noise_std', 0.01, 'force sensor noise (std), N', 0.0, 1.0),
    Param('sensor.bias', 0.0, 'force sensor bias, N', -10.0, 10.0),
    Param('robot.kp', 60.0, 'insertion axis position gain, 1/s', 0.1, 1000.0),
    Param('robot.max_speed', 0.1, 'insertion axis speed limit, m/s', 1e-4, 10.0),
    Param('robot.max_accel', 2.0, 'insertion axis acceleration limit, m/s^2', 1e-3, 1000.0),
    Param('robot.x0', 0.0, 'initial inserted length (the robot holds it until the first '
          'command arrives), m', -0.02, 0.2),
    Param('max_catchup_steps', 100, 'most simulation periods computed in one late timer tick',
          1, 10000, dynamic=True),
    *(Param('vessel.' + f.name, float(getattr(VesselParams(), f.name)),
            VESSEL_PARAM_RANGES[f.name][1], _VESSEL_LOWER.get(f.name, 0.0),
            VESSEL_PARAM_RANGES[f.name][0]) for f in fields(VesselParams)),
)


class SimSlaveNode(Node):
    """Robot, vessel, force sensor and the slave's side of the link, stepped on a timer."""

    PARAMS = PARAMS

    def __init__(self, **kwargs):
        super().__init__('sim_slave_node', **kwargs)
        self.params = p = NodeParams(self, PARAMS, apply=self._apply_params)
        self.rate = p['rate']
        seed = p['seed']
        self.max_catchup = p['max_catchup_steps']
        vessel_kw = {f.name: p['vessel.' + f.name] for f in fields(VesselParams)}
        self.link = Link(link_config(p.values), seed=seed + 2)
        robot = SlaveRobot(rate=self.rate, kp=p['robot.kp'], max_speed=p['robot.max_speed'],
                           max_accel=p['robot.max_accel'], x0=p['robot.x0'])
        self.sim = SlaveSimulation(vessel=VesselModel(VesselParams(**vessel_kw), seed=seed),
                                   sensor=ForceSensor(noise_std=p['sensor.noise_std'],
                                                      bias=p['sensor.bias'], seed=seed + 1),
                                   robot=robot, rotation=default_rotation_axis(self.rate))
        self.x_cmd = robot.x
        self.rot_cmd = self.sim.rotation.x
        self.t0 = None              # node-clock time of the first tick, s
        self.t_last = None          # relative time of the last tick, s
        self._err_max = 0.0
        self._err_sq = 0.0
        self._err_n = 0

        self._js = JointState()
        self._js.header.frame_id = T.FRAME_CATHETER_BASE
        self._js.name = JOINT_NAMES
        self._wrench = WrenchStamped()
        self._wrench.header.frame_id = T.FRAME_CATHETER_BASE
        self.diag = Diagnostics(self)
        self.diag.count('bad_messages', 0)
        self.pub_js = self.create_publisher(JointState, T.relative(T.SLAVE_JOINT_STATE), QOS_FAST)
        self.pub_force = self.create_publisher(WrenchStamped, T.relative(T.SLAVE_FORCE), QOS_FAST)
        self.sub = self.create_subscription(JointState, T.relative(T.MASTER_COMMAND),
                                            self._on_command, QOS_FAST)
        self.timer = self.create_timer(1.0 / self.rate, self._tick)
        self.diag.add_updater(self._stats_to_diag)
        self.get_logger().info(
            f'simulating the slave at {self.rate:g} Hz: {self.sub.topic_name} -> link '
            f'({self.link.config.describe()}) -> robot -> vessel -> sensor -> '
            f'{self.pub_js.topic_name}, {self.pub_force.topic_name}')

    def _apply_params(self, changes, values) -> None:
        if any(k.startswith('link.') for k in changes):
            self.link.config = link_config(values)       # ValueError refuses the change
        if 'max_catchup_steps' in changes:
            self.max_catchup = values['max_catchup_steps']

    def _now(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def _on_command(self, msg: JointState) -> None:
        if self.t0 is None:
            self.diag.count('commands_before_start')
            return
        pos = msg.position
        try:
            x = first('position ([insertion m, rotation rad])', pos)
            rot = finite('position[1]', pos[1]) if len(pos) > 1 else None
        except ValueError as exc:
            self.diag.count('bad_commands')
            self.diag.bad_input('command', str(exc))
            return
        t = self._now() - self.t0
        if self.t_last is not None and t < self.t_last:
            return          # the clock jumped back; the next tick resets
        self.diag.count('commands_received')
        try:
            self.link.send(t, (x, rot))
        except ValueError:   # a send time before the previous one: only after a clock reset
            self.diag.count('commands_out_of_time')

    def _restart(self, now: float) -> None:
        self.get_logger().warning('the clock jumped back: restarting the simulation')
        self.diag.count('clock_resets')
        self.sim.reset()
        self.link.reset()
        self.x_cmd = self.sim.robot.x
        self.rot_cmd = self.sim.rotation.x
        self.t0, self.t_last = now, None

    def _tick(self) -> None:
        if not self.context.ok():      # shutting down (SIGTERM): a last queued tick does nothing
            return
        try:
            self._step()
        except Exception:  # noqa: BLE001 - only tolerated while the context goes away
            if self.context.ok():
                raise

    def _step(self) -> None:
        stamp = self.get_clock().now()
        now = stamp.nanoseconds * 1e-9
        if self.t0 is None:
            self.t0 = now
        t = now - self.t0
        if self.t_last is not None and t < self.t_last:
            self._restart(now)
            t = 0.0
        self.t_last = t
        got = self.link.receive(t)
        if got is not None:
            self.diag.count('commands_delivered')
            self.x_cmd, rot = got
            if rot is not None:
                self.rot_cmd = rot
        sample, n = self.sim.advance(t, self.x_cmd, self.rot_cmd, max_steps=self.max_catchup)
        if n == 0:
            return
        self.diag.count('steps', n)
        if n > 1:
            self.diag.count('overruns')
            self.diag.count('missed_periods', n - 1)
            self.diag.event('overrun', WARN, f'{n - 1} simulation period(s) late, caught up')
        err = abs(self.sim.robot.command - sample.x)
        self._err_max = max(self._err_max, err)
        self._err_sq += err * err
        self._err_n += 1
        msg_stamp = stamp.to_msg()
        if self.pub_js.get_subscription_count() > 0:
            js = self._js            # reused: rclpy serialises at publish
            js.header.stamp = msg_stamp
            rotation = self.sim.rotation
            js.position = [sample.x, rotation.x]
            js.velocity = [sample.xd, rotation.xd]
            js.effort = [sample.f_meas, 0.0]
            self.pub_js.publish(js)
        if self.pub_force.get_subscription_count() > 0:
            w = self._wrench
            w.header.stamp = msg_stamp
            w.wrench.force.x = sample.f_meas
            self.pub_force.publish(w)

    def _stats_to_diag(self) -> None:
        s = self.link.stats
        d = self.diag
        d.set('link_sent', s.sent)
        d.set('link_delivered', s.delivered)
        d.set('link_lost_random', s.lost_random)
        d.set('link_lost_outage', s.lost_outage)
        d.set('link_dropped_stale', s.dropped_stale)
        outage = self.t_last is not None and self.link.in_outage(self.t_last)
        d.set('link_in_outage', str(outage))
        d.condition('link_outage', WARN if outage else 0,
                    'link outage: master commands are lost, the robot holds the last one')
        last = self.sim.last
        if last is not None:
            d.set('insertion_m', float(last.x))
            d.set('force_measured_n', float(last.f_meas))
        if self._err_n:
            d.set('tracking_error_max_m', float(self._err_max))
            d.set('tracking_error_rms_m', math.sqrt(self._err_sq / self._err_n))
        self._err_max, self._err_sq, self._err_n = 0.0, 0.0, 0


NODE_CLASS = SimSlaveNode


def main(args=None):
    return run_node(NODE_CLASS, args)


if __name__ == '__main__':
    raise SystemExit(main())

"""ROS 2 node `sim_slave_node`: the simulated patient side at 1 kHz.

Subscribes  master/command     catheter_interfaces/MasterCommand (position: insertion m,
                               rotation rad; velocity and acceleration are not used: the
                               robot's own loop tracks the position), QOS_LINK. A command
                               with a non-finite position or rotation is refused (counted,
                               WARN). Every command goes through
                               the slave's side of the UDP-like link (delay, jitter, loss,
                               outages, latest wins); the robot follows the newest delivered
                               command and holds it while nothing new arrives.
Publishes   slave/joint_state  sensor_msgs/JointState, name [insertion, rotation], position,
                               velocity, effort [measured insertion force N, 0], QOS_FAST
            slave/joint_state_decimated  the same at `decimated_rate` (the first state of each
                               of its periods of the node clock), QOS_FAST: for the 30 Hz
                               camera in another process, which would otherwise take every
                               1 kHz state through DDS
            slave/force        geometry_msgs/WrenchStamped, frame catheter_base, force.x =
                               measured insertion force N, QOS_FAST
            /diagnostics       steps, commands received/delivered/lost/stale, bad commands,
                               overruns, tracking error; WARN during a link outage, after bad
                               commands and overruns
The vessel is `vessel` (sim_slave.vessels, read only; choices in --help), its vessel.*
fields and sensor noise overridable (sim_slave.node_params.vessel_from_params). Both outputs
are stamped with the node clock and go out undelayed (the master's sim node
applies its side of the link). Timer on the node clock: use_sim_time with a /clock publisher
drives it in lockstep. Outage times are relative to the node's first timer tick. Topic names
are relative (the node's namespace applies). The link parameters (link.*) apply at run time
to the packets sent from then on; the simulation's own are fixed at start.

Thin: message conversion, parameters and timers; the physics is in sim_slave.slave/vessel/
robot/sensor/link.
"""
from __future__ import annotations

import array
import math
from dataclasses import fields

from catheter_interfaces.msg import MasterCommand
from geometry_msgs.msg import WrenchStamped
from rclpy.node import Node
from sensor_msgs.msg import JointState

from catheter_common import topics as T
from catheter_common.checks import finite
from catheter_common.diagnostics import WARN, Diagnostics
from catheter_common.params import NodeParams, Param, table
from catheter_common.qos import QOS_FAST, QOS_LINK
from catheter_common.outgoing import set_stamp
from catheter_common.ros_node import clock_ns, node_main
from sim_slave.link import Link
from sim_slave.link_side import (RunClock, apply_link_changes, link_config, link_params,
                                 link_to_diag)
from sim_slave.node_params import DEFAULT_VESSEL, VESSEL_CHOICES, vessel_from_params
from sim_slave.robot import SlaveRobot
from sim_slave.sensor import ForceSensor
from sim_slave.slave import SlaveSimulation, default_rotation_axis
from sim_slave.vessel import VesselParams

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


PARAMS = table(
    Param('rate', 1000.0, 'simulation and publishing rate, Hz', 10.0, 10000.0),
    Param('seed', 0, 'random seed (vessel phase, sensor noise, link)', 0, 2 ** 31 - 1),
    Param('vessel', DEFAULT_VESSEL, 'the simulated vessel (sim_slave.vessels): phantom, '
          'smooth_coulomb, stribeck_kv, stenosis, soft, stiff_wall; vessel.* and '
          'sensor.noise_std values that differ from their (phantom) defaults override it',
          choices=VESSEL_CHOICES),
    *link_params('master commands'),
    Param('sensor.noise_std', 0.01, 'force sensor noise (std), N (default: the vessel\'s own)',
          0.0, 1.0),
    Param('sensor.bias', 0.0, 'force sensor bias, N', -10.0, 10.0),
    Param('robot.kp', 60.0, 'insertion axis position gain, 1/s', 0.1, 1000.0),
    Param('robot.max_speed', 0.1, 'insertion axis speed limit, m/s', 1e-4, 10.0),
    Param('robot.max_accel', 2.0, 'insertion axis acceleration limit, m/s^2', 1e-3, 1000.0),
    Param('robot.x0', 0.0, 'initial inserted length (the robot holds it until the first '
          'command arrives), m', -0.02, 0.2),
    Param('decimated_rate', 100.0, 'rate of slave/joint_state_decimated, Hz (the first state '
          'of each period)', 1.0, 10000.0),
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
        spec = vessel_from_params(p.values)
        self.vessel_name = spec.name
        self.link = Link(link_config(p.values), seed=seed + 2)
        robot = SlaveRobot(rate=self.rate, kp=p['robot.kp'], max_speed=p['robot.max_speed'],
                           max_accel=p['robot.max_accel'], x0=p['robot.x0'])
        self.sim = SlaveSimulation(vessel=spec.build(seed),
                                   sensor=ForceSensor(noise_std=spec.noise_std,
                                                      bias=p['sensor.bias'], seed=seed + 1),
                                   robot=robot, rotation=default_rotation_axis(self.rate))
        self.x_cmd = robot.x
        self.rot_cmd = self.sim.rotation.x
        self.run = RunClock()
        self._err_max = 0.0
        self._err_sq = 0.0
        self._err_n = 0

        self._js = JointState()
        self._js.header.frame_id = T.FRAME_CATHETER_BASE
        self._js.name = JOINT_NAMES
        # the reused message's float64[] fields, written in place each tick (an assigned list
        # is range-checked element by element and copied by the generated setter)
        self._js.position = array.array('d', (0.0, 0.0))
        self._js.velocity = array.array('d', (0.0, 0.0))
        self._js.effort = array.array('d', (0.0, 0.0))
        self._js_arrays = (self._js.position, self._js.velocity, self._js.effort)
        self._wrench = WrenchStamped()
        self._wrench.header.frame_id = T.FRAME_CATHETER_BASE
        self._clock = self.get_clock()       # the same object for the node's life
        self._clock_ns = clock_ns(self._clock)
        self.diag = Diagnostics(self)
        self.diag.count('bad_messages', 0)
        self.pub_js = self.create_publisher(JointState, T.relative(T.SLAVE_JOINT_STATE), QOS_FAST)
        self.pub_force = self.create_publisher(WrenchStamped, T.relative(T.SLAVE_FORCE), QOS_FAST)
        self.pub_js_dec = self.create_publisher(
            JointState, T.relative(T.SLAVE_JOINT_STATE_DECIMATED), QOS_FAST)
        self._dec_period_ns = int(round(1e9 / p['decimated_rate']))
        self._dec_last = None            # the decimated stream's last period index
        # the link from the master: every command sent is taken, also after a stall (QOS_LINK)
        self.sub = self.create_subscription(MasterCommand, T.relative(T.MASTER_COMMAND),
                                            self._on_command, QOS_LINK)
        self.timer = self.create_timer(1.0 / self.rate, self._tick)
        self.diag.add_updater(self._stats_to_diag)
        self.get_logger().info(
            f'simulating the slave ({self.vessel_name} vessel) at {self.rate:g} Hz: '
            f'{self.sub.topic_name} -> link '
            f'({self.link.config.describe()}) -> robot -> vessel -> sensor -> '
            f'{self.pub_js.topic_name}, {self.pub_force.topic_name}')

    def _apply_params(self, changes, values) -> None:
        apply_link_changes(changes, values, self.link)
        if 'max_catchup_steps' in changes:
            self.max_catchup = values['max_catchup_steps']

    def _now(self) -> float:
        return self._clock_ns() * 1e-9

    def _on_command(self, msg: MasterCommand) -> None:
        if self.run.t0 is None:
            self.diag.count('commands_before_start')
            return
        try:
            x = finite('position', msg.position)
            rot = finite('rotation', msg.rotation)
        except ValueError as exc:
            self.diag.count('bad_commands')
            self.diag.bad_input('command', str(exc))
            return
        t = self.run.at(self._now())
        if t is None:
            return          # the clock jumped back; the next tick resets
        self.diag.count('commands_received')
        try:
            self.link.send(t, (x, rot))
        except ValueError:   # a send time before the previous one: only after a clock reset
            self.diag.count('commands_out_of_time')

    def _restart(self) -> None:
        self.get_logger().warning('the clock jumped back: restarting the simulation')
        self.diag.count('clock_resets')
        self.sim.reset()
        self.link.reset()
        self.x_cmd = self.sim.robot.x
        self.rot_cmd = self.sim.rotation.x

    def _tick(self) -> None:
        if not self.context.ok():      # shutting down (SIGTERM): a last queued tick does nothing
            return
        try:
            self._step()
        except Exception:  # noqa: BLE001 - only tolerated while the context goes away
            if self.context.ok():
                raise

    def _step(self) -> None:
        ns = self._clock_ns()
        t, restarted = self.run.tick(ns * 1e-9)
        if restarted:
            self._restart()
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
        dec = ns // self._dec_period_ns
        want_dec = dec != self._dec_last and self.pub_js_dec.get_subscription_count() > 0
        want_js = self.pub_js.get_subscription_count() > 0
        if want_dec or want_js:
            js = self._js            # reused: serialised at publish (catheter_common.outgoing)
            set_stamp(js.header.stamp, ns)
            rotation = self.sim.rotation
            pos, vel, eff = self._js_arrays
            pos[0] = sample.x
            pos[1] = rotation.x
            vel[0] = sample.xd
            vel[1] = rotation.xd
            eff[0] = sample.f_meas
            if want_js:
                self.pub_js.publish(js)
            if want_dec:
                self._dec_last = dec
                self.pub_js_dec.publish(js)
        if self.pub_force.get_subscription_count() > 0:
            w = self._wrench
            set_stamp(w.header.stamp, ns)
            w.wrench.force.x = sample.f_meas
            self.pub_force.publish(w)

    def _stats_to_diag(self) -> None:
        d = self.diag
        link_to_diag(d, [('link', self.link)], self.run.t_last,
                     'master commands are lost, the robot holds the last one')
        last = self.sim.last
        if last is not None:
            d.set('insertion_m', float(last.x))
            d.set('force_measured_n', float(last.f_meas))
        if self._err_n:
            d.set('tracking_error_max_m', float(self._err_max))
            d.set('tracking_error_rms_m', math.sqrt(self._err_sq / self._err_n))
        self._err_max, self._err_sq, self._err_n = 0.0, 0.0, 0


NODE_CLASS = SimSlaveNode
main = node_main(NODE_CLASS)


if __name__ == '__main__':
    raise SystemExit(main())

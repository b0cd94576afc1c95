"""The simulated slave: robot axes, vessel interaction and force sensor stepped together."""
from __future__ import annotations

import math
from typing import NamedTuple, Optional, Tuple

from catheter_common.checks import finite
from sim_slave.robot import SlaveRobot
from sim_slave.sensor import ForceSensor
from sim_slave.vessel import VesselModel


class SlaveSample(NamedTuple):
    """One step of the slave.

    t: s; x: inserted length, m; xd: m/s; xdd: m/s^2; f_true: noise-free vessel force, N;
    f_meas: the sensor's reading, N (positive resists insertion).
    """
    t: float
    x: float
    xd: float
    xdd: float
    f_true: float
    f_meas: float


def default_rotation_axis(rate: float = 1000.0) -> SlaveRobot:
    """The catheter's rotation axis (rad): no stroke limit, 2 pi rad/s, 50 rad/s^2."""
    return SlaveRobot(rate=rate, x_min=-math.inf, x_max=math.inf, max_speed=2.0 * math.pi,
                      max_accel=50.0)


class SlaveSimulation:
    """Robot -> vessel -> sensor, one call per control period.

    Args:
        vessel: a :class:`VesselModel` (default: default parameters, seed 0).
        sensor: a :class:`ForceSensor` (default: 0.01 N noise, seed 0).
        robot: the insertion axis, a :class:`SlaveRobot` (default: 1 kHz).
        rotation: the rotation axis in rad, a :class:`SlaveRobot` (default: see
            :func:`default_rotation_axis`, at the insertion axis's rate). Rotation does not
            change the insertion force in this model.
    """

    def __init__(self, vessel: Optional[VesselModel] = None,
                 sensor: Optional[ForceSensor] = None,
                 robot: Optional[SlaveRobot] = None,
                 rotation: Optional[SlaveRobot] = None):
        for name, obj, cls in (('vessel', vessel, VesselModel), ('sensor', sensor, ForceSensor),
                               ('robot', robot, SlaveRobot), ('rotation', rotation, SlaveRobot)):
            if obj is not None and not isinstance(obj, cls):
                raise ValueError(f'{name} must be a {cls.__name__}, got {type(obj).__name__}')
        self.vessel = vessel if vessel is not None else VesselModel()
        self.sensor = sensor if sensor is not None else ForceSensor()
        self.robot = robot if robot is not None else SlaveRobot()
        self.rotation = rotation if rotation is not None else default_rotation_axis(self.robot.rate)
        if abs(self.rotation.rate - self.robot.rate) > 1e-9 * self.robot.rate:
            raise ValueError(f'rotation rate {self.rotation.rate} must equal the robot rate '
                             f'{self.robot.rate}')
        self.reset()

    @property
    def dt(self) -> float:
        """Control period in s (the robot's)."""
        return self.robot.dt

    def reset(self) -> None:
        """Everything back to rest (robots at their x0, friction unloaded, noise restarted)."""
        self.vessel.reset()
        self.sensor.reset()
        self.robot.reset()
        self.rotation.reset()
        self.rot_cmd = self.rotation.x
        self.t: Optional[float] = None
        self.last: Optional[SlaveSample] = None

    def step(self, t: float, x_cmd: float, rot_cmd: Optional[float] = None) -> SlaveSample:
        """One control period ending at time t [s] towards the insertion command x_cmd [m]
        (and the rotation command rot_cmd [rad]; None holds the last one)."""
        t = finite('t', t)
        x, xd, xdd = self.robot.step(x_cmd)
        if rot_cmd is not None:
            self.rot_cmd = finite('rot_cmd', rot_cmd)
        self.rotation.step(self.rot_cmd)
        f_true = self.vessel.force(t, x, xd)
        f_meas = self.sensor.measure(f_true)
        self.t = t
        self.last = SlaveSample(t, x, xd, xdd, f_true, f_meas)
        return self.last

    def advance(self, t: float, x_cmd: float, rot_cmd: Optional[float] = None,
                max_steps: int = 100) -> Tuple[Optional[SlaveSample], int]:
        """Step as many whole periods as fit between the last step and time t [s] (at least one
        on the first call), all towards the same command, so that a late timer does not slow
        the simulated physics. At most `max_steps` are computed; beyond that the simulation
        jumps (its time is set to t). Returns (the last sample, the number of steps taken);
        (last sample, 0) if less than half a period elapsed (the same clock tick twice).
        """
        t = finite('t', t)
        if not isinstance(max_steps, int) or max_steps < 1:
            raise ValueError(f'max_steps must be an int >= 1, got {max_steps!r}')
        if self.t is None:
            return self.step(t, x_cmd, rot_cmd), 1
        if t < self.t:
            raise ValueError(f't must not decrease: got {t!r} after {self.t!r}')
        n = int(round((t - self.t) * self.robot.rate))
        if n <= 0:
            return self.last, 0
        t0, dt = self.t, self.dt
        steps = min(n, max_steps)
        for k in range(1, steps):
            self.step(t0 + k * dt, x_cmd, rot_cmd)
        return self.step(t, x_cmd, rot_cmd), steps

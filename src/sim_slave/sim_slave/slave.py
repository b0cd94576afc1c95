"""The simulated slave: robot axis, vessel interaction and force sensor stepped together."""
from __future__ import annotations

from typing import NamedTuple, Optional

from sim_slave._check import finite
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


class SlaveSimulation:
    """Robot -> vessel -> sensor, one call per control period.

    Args:
        vessel: a :class:`VesselModel` (default: default parameters, seed 0).
        sensor: a :class:`ForceSensor` (default: 0.01 N noise, seed 0).
        robot: a :class:`SlaveRobot` (default: 1 kHz).
    """

    def __init__(self, vessel: Optional[VesselModel] = None,
                 sensor: Optional[ForceSensor] = None,
                 robot: Optional[SlaveRobot] = None):
        for name, obj, cls in (('vessel', vessel, VesselModel), ('sensor', sensor, ForceSensor),
                               ('robot', robot, SlaveRobot)):
            if obj is not None and not isinstance(obj, cls):
                raise ValueError(f'{name} must be a {cls.__name__}, got {type(obj).__name__}')
        self.vessel = vessel if vessel is not None else VesselModel()
        self.sensor = sensor if sensor is not None else ForceSensor()
        self.robot = robot if robot is not None else SlaveRobot()
        self.last: Optional[SlaveSample] = None

    @property
    def dt(self) -> float:
        """Control period in s (the robot's)."""
        return self.robot.dt

    def reset(self) -> None:
        """Everything back to rest (robot at its x0, friction unloaded, noise restarted)."""
        self.vessel.reset()
        self.sensor.reset()
        self.robot.reset()
        self.last = None

    def step(self, t: float, x_cmd: float) -> SlaveSample:
        """One control period ending at time t [s] towards the insertion command x_cmd [m]."""
        t = finite('t', t)
        x, xd, xdd = self.robot.step(x_cmd)
        f_true = self.vessel.force(t, x, xd)
        f_meas = self.sensor.measure(f_true)
        self.last = SlaveSample(t, x, xd, xdd, f_true, f_meas)
        return self.last

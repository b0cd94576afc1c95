"""The identifier node has no acceleration (a JointState carries position, velocity, effort):
HistoryIdentifier.update(x, xd, None, f) differences x' at its rate, which for the simulated
robot is exactly the x'' the pure experiment passes, so the graph learns the same model."""
import numpy as np

from impedance_master import make_identifier
from impedance_master.operator import experiment_trajectory
from sim_slave.robot import SlaveRobot
from sim_slave.sensor import ForceSensor
from sim_slave.slave import SlaveSimulation
from sim_slave.vessel import VesselModel


def _samples(seconds=4.0, seed=2):
    traj = experiment_trajectory('II', seed=seed)
    sim = SlaveSimulation(vessel=VesselModel(seed=seed), sensor=ForceSensor(seed=seed),
                          robot=SlaveRobot(x0=traj.sample(0.0)[0]))
    return [sim.step(k * 1e-3, traj.sample(k * 1e-3)[0]) for k in range(int(seconds * 1000))]


def test_missing_acceleration_is_the_velocity_difference():
    given, missing = make_identifier(), make_identifier()
    for s in _samples():
        a = given.update(s.x, s.xd, s.xdd, s.f_meas)
        b = missing.update(s.x, s.xd, None, s.f_meas)
    assert a is not None and b is not None
    np.testing.assert_allclose(b.to_fields()['m'], a.to_fields()['m'], rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(missing.theta, given.theta, rtol=1e-6, atol=1e-9)
    for x, xd, xdd in ((0.03, 0.02, 0.5), (0.05, -0.01, -1.0)):
        assert abs(a.force(x, xd, xdd) - b.force(x, xd, xdd)) < 1e-9


def test_acceleration_zero_is_not_what_the_identifier_assumes():
    # the old behaviour (x'' = 0 for a missing acceleration) learns another model
    given, zero = make_identifier(), make_identifier()
    for s in _samples():
        given.update(s.x, s.xd, s.xdd, s.f_meas)
        zero.update(s.x, s.xd, 0.0, s.f_meas)
    assert np.max(np.abs(zero.theta - given.theta)) > 1e-6

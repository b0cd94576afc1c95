"""Force sensor statistics and the stepped slave simulation."""
import math

import numpy as np
import pytest

from sim_slave import (ForceSensor, SlaveRobot, SlaveSample, SlaveSimulation, VesselModel,
                       VesselParams)


def test_noise_statistics_and_determinism():
    s = ForceSensor(noise_std=0.01, seed=4)
    y = np.array([s.measure(0.2) for _ in range(20000)])
    n = len(y)
    assert abs(y.mean() - 0.2) < 5 * 0.01 / math.sqrt(n)
    assert y.std() == pytest.approx(0.01, rel=5 * math.sqrt(1 / (2 * n)))
    s2 = ForceSensor(noise_std=0.01, seed=4)
    assert [s2.measure(0.2) for _ in range(100)] == list(y[:100])
    s.reset()
    assert s.measure(0.2) == y[0]


def test_bias_quantisation_saturation_and_noiseless():
    assert ForceSensor(noise_std=0.0).measure(0.123) == 0.123
    assert ForceSensor(noise_std=0.0, bias=0.05).measure(0.1) == pytest.approx(0.15)
    q = ForceSensor(noise_std=0.01, resolution=0.005, seed=1)
    for _ in range(100):
        r = q.measure(0.2) / 0.005
        assert r == pytest.approx(round(r), abs=1e-9)
    assert ForceSensor(noise_std=0.0, saturation=1.0).measure(5.0) == 1.0
    assert ForceSensor(noise_std=0.0, saturation=1.0).measure(-5.0) == -1.0


@pytest.mark.parametrize('kw,name', [(dict(noise_std=-0.1), 'noise_std'),
                                     (dict(noise_std=math.nan), 'noise_std'),
                                     (dict(bias=math.inf), 'bias'),
                                     (dict(resolution=-1), 'resolution'),
                                     (dict(saturation=0.0), 'saturation'), (dict(seed=-2), 'seed'),
                                     (dict(seed='a'), 'seed')])
def test_bad_sensor_arguments(kw, name):
    with pytest.raises(ValueError, match=name):
        ForceSensor(**kw)


def test_bad_measurement():
    with pytest.raises(ValueError, match='f'):
        ForceSensor().measure(math.nan)


def test_slave_simulation_steps_robot_vessel_sensor(exp1):
    t, cmd = exp1
    sim = SlaveSimulation(vessel=VesselModel(seed=1), sensor=ForceSensor(0.01, seed=2),
                          robot=SlaveRobot(rate=1000.0))
    out = [sim.step(a, b) for a, b in zip(t, cmd, strict=True)]
    assert isinstance(out[0], SlaveSample) and sim.dt == 0.001
    arr = np.array(out)
    assert np.abs(arr[:, 1] - cmd).max() < 0.05 * 0.056
    noise = arr[:, 5] - arr[:, 4]
    assert noise.std() == pytest.approx(0.01, rel=0.1)
    assert 0.33 < arr[:, 4].max() < 0.45
    # the same seeds replay the same run; reset restarts it
    sim.reset()
    again = [sim.step(a, b) for a, b in zip(t[:500], cmd[:500], strict=True)]
    assert again == out[:500]


def test_slave_defaults_and_bad_arguments():
    sim = SlaveSimulation()
    s = sim.step(0.001, 0.0)
    assert s.x == 0.0 and s.f_true == 0.0
    with pytest.raises(ValueError, match='vessel'):
        SlaveSimulation(vessel=VesselParams())
    with pytest.raises(ValueError, match='robot'):
        SlaveSimulation(robot=1)
    with pytest.raises(ValueError, match='t'):
        sim.step(math.nan, 0.0)
    with pytest.raises(ValueError, match='x_cmd'):
        sim.step(0.002, math.inf)


def test_advance_catches_up_whole_periods():
    a, b = SlaveSimulation(), SlaveSimulation()
    cmd = 0.02
    s, n = a.advance(0.001, cmd)
    assert n == 1
    s, n = a.advance(0.001, cmd)                 # the same tick again: nothing to do
    assert n == 0 and s.t == 0.001
    s, n = a.advance(0.005, cmd)                 # a late timer: four periods
    assert n == 4 and s.t == 0.005
    ref = [b.step((k + 1) / 1000, cmd) for k in range(5)]
    assert s.x == pytest.approx(ref[-1].x, abs=1e-15)
    s, n = a.advance(1.0, cmd, max_steps=10)     # a huge jump is capped
    assert n == 10 and s.t == 1.0
    with pytest.raises(ValueError, match='t must not decrease'):
        a.advance(0.5, cmd)
    with pytest.raises(ValueError, match='max_steps'):
        a.advance(2.0, cmd, max_steps=0)


def test_rotation_axis_follows_and_holds():
    sim = SlaveSimulation()
    for k in range(2000):
        sim.step((k + 1) / 1000, 0.0, 1.0 if k < 10 else None)
    assert sim.rotation.x == pytest.approx(1.0, abs=1e-4)
    with pytest.raises(ValueError, match='rot_cmd'):
        sim.step(3.0, 0.0, math.nan)
    with pytest.raises(ValueError, match='rotation'):
        SlaveSimulation(rotation=SlaveRobot(rate=500.0))


def test_quantisation_rounds_to_the_nearest_step_unbiased():
    # mutation sweep W40: truncating would bias every reading by half a step
    q = ForceSensor(noise_std=0.0, resolution=0.01)
    assert q.measure(0.0049) == 0.0 and q.measure(0.0051) == pytest.approx(0.01)
    assert q.measure(-0.0051) == pytest.approx(-0.01) and q.measure(-0.0049) == 0.0
    noisy = ForceSensor(noise_std=0.01, resolution=0.01, seed=2)
    y = np.array([noisy.measure(0.2033) for _ in range(20000)])
    assert abs(y.mean() - 0.2033) < 5 * 0.0105 / math.sqrt(y.size)


def test_the_vessel_force_is_taken_where_the_robot_is():
    """Mutation sweep W42: the force at the robot's position and velocity (a twin vessel
    driven by the same samples gives the same true force), not at the command, which the
    stage reaches only later."""
    sim = SlaveSimulation(vessel=VesselModel(seed=3), sensor=ForceSensor(noise_std=0.0))
    twin = VesselModel(seed=3)
    lag = 0.0
    for k in range(400):
        t = k * 1e-3
        s = sim.step(t, 0.03 * min(t / 0.2, 1.0))
        lag = max(lag, abs(sim.robot.command - s.x))
        assert s.f_true == twin.force(t, s.x, s.xd)
        assert s.f_meas == s.f_true
    assert lag > 1e-3                        # the command did lead the robot

"""The simulated haptic device's physics, each term alone (mutation sweep W14-W19: the
tracking tests of test_core let the device's inertia, friction, back-EMF, feed-forward units,
anti-windup and sensor noise all go missing). Expected values are the DeviceParams'
documented numbers worked by hand: force constant kt / r = 2 N/A, electrical damping
(kt / r)^2 / R = 2.667 N s/m, moving mass 0.15 kg, friction 0.01 N tanh(v / 1 mm/s) +
0.05 N s/m v."""
import math

import numpy as np
import pytest

from impedance_master import DeviceParams, HapticDevice

#: no force loop: the current loop holds the motor current at 0
PASSIVE = dict(kp=0.0, ki=0.0, kd=0.0, feedforward=False, sensor_noise=0.0)


DEFAULT = DeviceParams()


def friction(v, p=DEFAULT):
    return p.coulomb_friction * math.tanh(v / 1e-3) + p.viscous_friction * v


def test_rigid_hand_meets_the_handles_inertia_and_friction():
    dev = HapticDevice(DeviceParams(**PASSIVE))
    a, v0 = 2.0, 0.01
    for k in range(200):
        t = k * 1e-3
        s = dev.step(0.0, 0.01 + v0 * t + 0.5 * a * t * t, v0 + a * t, a)
    assert abs(s.current) < 1e-3
    v = v0 + a * 0.199
    assert s.f_hand == pytest.approx(0.15 * a + friction(v) + 2.0 * s.current, abs=1e-9)
    assert s.f_hand == pytest.approx(0.15 * a + friction(v), abs=2e-3)


def test_compliant_hand_drags_the_handle_against_its_friction():
    dev = HapticDevice(DeviceParams(**PASSIVE), hand_stiffness=300.0)
    v = 0.02
    for k in range(1000):
        s = dev.step(0.0, v * k * 1e-3, v, 0.0)
    # steady sliding: the hand's spring-damper carries the friction (and no motor force)
    assert s.xd == pytest.approx(v, rel=1e-3)
    assert s.f_hand == pytest.approx(friction(v), rel=0.05)


def test_back_emf_damps_the_handle_with_the_current_loop_off():
    p = DeviceParams(**PASSIVE, kp_i=0.0, ki_i=0.0)       # 0 V across the motor
    dev = HapticDevice(p)
    v = 0.02
    for k in range(100):
        s = dev.step(0.0, v * k * 1e-3, v, 0.0)
    kf = p.kt / p.radius
    assert s.f_hand - friction(v) == pytest.approx(kf * kf / p.resistance * v, rel=1e-3)


def test_feedforward_alone_sets_the_current_for_the_desired_force():
    p = DeviceParams(kp=0.0, ki=0.0, kd=0.0, feedforward=True, sensor_noise=0.0)
    dev = HapticDevice(p)
    for _ in range(50):
        s = dev.step(0.5, 0.02, 0.0, 0.0)
    assert s.current == pytest.approx(0.25, rel=1e-3)       # 0.5 N / (2 N/A)
    assert s.f_hand == pytest.approx(0.5, rel=1e-3)


def test_force_loop_does_not_wind_up_while_saturated():
    dev = HapticDevice(DeviceParams(sensor_noise=0.0))
    for _ in range(500):                                    # 10 N asked, 4 N possible
        s = dev.step(10.0, 0.02, 0.0, 0.0)
    assert s.f_hand == pytest.approx(4.0, rel=1e-3)
    back = [float(dev.step(0.5, 0.02, 0.0, 0.0)) for _ in range(100)]
    assert abs(back[-1] - 0.5) < 0.01 and max(abs(f - 0.5) for f in back[30:]) < 0.05


def test_handle_sensor_reads_the_hand_force_with_its_noise():
    dev = HapticDevice(DeviceParams(sensor_noise=0.002), seed=7)
    e = np.array([(lambda s: s.f_measured - s.f_hand)(dev.step(0.3, 0.02, 0.0, 0.0))
                  for _ in range(4000)])
    assert abs(e.mean()) < 5 * 0.002 / math.sqrt(e.size)
    assert e.std() == pytest.approx(0.002, rel=0.1)
    quiet = HapticDevice(DeviceParams(sensor_noise=0.0))
    s = quiet.step(0.3, 0.02, 0.0, 0.0)
    assert s.f_measured == s.f_hand

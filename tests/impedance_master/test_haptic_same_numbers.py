"""HapticDevice.step runs its substeps on local names (a speed change): it must give the very
same numbers as the previous implementation, kept here verbatim as the reference (attribute
lookups, `_friction`), bit for bit, for the rigid hand, saturating and not. (The compliant
hand's step changed on purpose since: its target is interpolated over the substeps, see
test_haptic_device.py; the reference keeps the old held target, so it is compared on the
rigid hand only.)"""
import math

from hypothesis import given, settings
from hypothesis import strategies as st

from impedance_master.haptic import DeviceParams, DeviceSample, HapticDevice


def reference_step(self, f_desired, xh, vh, ah):
    """The step as it was before the local-name version (the loop only; same checks)."""
    p = self.p
    fd = float(f_desired)
    if not self._started:
        self.x, self.xd = xh, vh
        self._started = True
    kf = p.kt / p.radius
    e = fd - self._f_meas
    de = (e - self._e_last) / self.dt
    self._e_last = e
    i_ref = p.kp * e + p.kd * de + self._int_f
    if p.feedforward:
        i_ref += fd / kf
    if i_ref > p.i_max or i_ref < -p.i_max:
        i_ref = max(-p.i_max, min(p.i_max, i_ref))
    else:
        self._int_f += p.ki * e * self.dt
    n = p.substeps
    h = self.dt / n
    decay = math.exp(-p.resistance * h / p.inductance)
    gain = (1.0 - decay) / p.resistance
    rigid = self.hand_stiffness is None
    x, v = self.x, self.xd
    f_hand = 0.0
    a = 0.0
    for s in range(n):
        ei = i_ref - self.i
        volt = p.kp_i * ei + self._int_i
        if volt > p.v_max or volt < -p.v_max:
            volt = max(-p.v_max, min(p.v_max, volt))
        else:
            self._int_i += p.ki_i * ei * h
        if rigid:
            frac = (s + 1) / n
            v = self.xd + (vh - self.xd) * frac
        emf = p.kt * v / p.radius
        self.i = self.i * decay + (volt + emf) * gain
        if self.i > p.i_max:
            self.i = p.i_max
        elif self.i < -p.i_max:
            self.i = -p.i_max
        f_mot = kf * self.i
        if rigid:
            a = ah
            f_hand = p.moving_mass * a + f_mot + self._friction(v)
        else:
            f_hand = self.hand_stiffness * (xh - x) + self.hand_damping * (vh - v)
            a = (f_hand - f_mot - self._friction(v)) / p.moving_mass
            v += a * h
            x += v * h
    if rigid:
        x, v = xh, vh
    self.x, self.xd, self.xdd = x, v, a
    noise = self._rng.gauss(0.0, p.sensor_noise) if p.sensor_noise > 0 else 0.0
    self._f_meas = f_hand + noise
    return DeviceSample(f_hand, x, v, a, self.i, self._f_meas)


def _fields(s):
    return (float(s), s.x, s.xd, s.xdd, s.current, s.f_measured)


STEP = st.tuples(st.floats(-8, 8), st.floats(-0.1, 0.1), st.floats(-2, 2), st.floats(-50, 50))


@settings(max_examples=60, deadline=None)
@given(st.lists(STEP, min_size=1, max_size=40), st.booleans(), st.integers(0, 10))
def test_step_gives_the_reference_numbers_bit_for_bit(steps, weak, seed):
    # weak: a small current / voltage limit, so the saturation branches run too
    params = DeviceParams(i_max=0.3, v_max=1.0) if weak else DeviceParams()
    kw = dict(hand_stiffness=None, hand_damping=15.0, seed=seed)
    a, b = HapticDevice(params, **kw), HapticDevice(params, **kw)
    for fd, x, v, acc in steps:
        got = a.step(fd, x, v, acc)
        ref = reference_step(b, fd, x, v, acc)
        assert _fields(got) == _fields(ref)
        assert (a.i, a._int_i, a._int_f, a._e_last) == (b.i, b._int_i, b._int_f, b._e_last)


def test_saturation_branches_are_reached():
    """The weak device of the test above does saturate (else its branches go untested)."""
    dev = HapticDevice(DeviceParams(i_max=0.3, v_max=1.0), seed=0)
    for _ in range(20):
        dev.step(8.0, 0.0, 0.0, 0.0)
    assert abs(dev.i) == 0.3

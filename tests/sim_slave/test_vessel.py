"""The vessel interaction force: range, friction growth, stick-slip, sign flip, wall, cardiac."""
import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from sim_slave import SlaveRobot, VesselModel, VesselParams
from sim_slave.vessel_extras import VesselExtras

DT = 1e-3
QUIET = VesselParams(cardiac_amplitude=0.0)


def drive(v, xs, t0=0.0):
    """Drive the vessel model along positions xs (1 kHz, velocity by difference); components."""
    xs = np.asarray(xs, float)
    vel = np.gradient(xs, DT) if len(xs) > 1 else np.zeros(1)
    out = []
    for i, (x, xd) in enumerate(zip(xs, vel, strict=True)):
        v.force(t0 + (i + 1) * DT, x, xd)
        out.append(v.last)
    return np.array(out)            # columns friction, viscous, wall, cardiac, total


def test_force_range_on_experiment_one(exp1):
    """Thesis Exp. I: max force 0.387 N at up to 56 mm and 41.3 mm/s. The robot moves the
    catheter."""
    t, cmd = exp1
    r, v = SlaveRobot(), VesselModel(seed=3)
    f = []
    for ti, c in zip(t, cmd, strict=True):
        x, xd, _ = r.step(c)
        f.append(v.force(ti, x, xd))
    f = np.array(f)
    assert np.all(np.isfinite(f))
    assert 0.33 <= f.max() <= 0.45
    assert -0.35 <= f.min() < -0.1          # retraction: friction the other way
    assert abs(f[-1]) < 0.02                # back out of the body: only what is left at x ~ 0


def test_steady_sliding_matches_the_closed_form():
    """At constant velocity the LuGre state settles at z = zc g(v): exact reference."""
    p = QUIET
    zc = p.presliding_displacement * p.stribeck_ratio
    for vel in (0.001, 0.01, 0.0413, -0.02):
        v = VesselModel(p)
        x0 = 0.06 if vel < 0 else 0.0
        settled = int(25 * zc / abs(vel) / DT)       # exp(-25) of the transient is left
        n = max(1500, settled + 500)
        xs = x0 + vel * DT * np.arange(1, n)
        comp = drive(v, xs)
        for i in (settled, (settled + n - 2) // 2, n - 2):
            assert comp[i, 4] == pytest.approx(v.steady_force(xs[i], vel), rel=1e-6, abs=1e-12)


def test_friction_grows_monotonically_with_depth():
    v = VesselModel(QUIET)
    xs = 0.02 * DT * np.arange(1, 3000)     # 20 mm/s up to 60 mm
    fr = drive(v, xs)[:, 0]
    slide = xs > 0.002                       # past the pre-sliding transient
    assert np.all(np.diff(fr[slide]) > 0)
    # super-linear growth (capstan): Fc(56 mm) more than 2x Fc(28 mm)
    assert v.coulomb_force(0.056) > 2.0 * v.coulomb_force(0.028)
    assert v.coulomb_force(0.056) == pytest.approx(0.262, abs=0.002)


@settings(max_examples=60, deadline=None)
@given(st.floats(0.0, 0.2), st.floats(0.0, 0.2), st.floats(1e-5, 0.1))
def test_friction_levels_monotone_and_breakaway_above_coulomb(x1, x2, speed):
    v = VesselModel()
    lo, hi = min(x1, x2), max(x1, x2)
    assert v.coulomb_force(lo) <= v.coulomb_force(hi)
    assert v.breakaway_force(hi) >= v.coulomb_force(hi)
    # steady sliding force: insertion positive, retraction negative, magnitude grows with depth
    assert v.steady_force(hi, speed) >= v.steady_force(lo, speed) >= 0.0
    assert v.steady_force(hi, -speed) <= 0.0 or hi > v.params.wall_depth


def test_retraction_flips_the_friction_sign():
    v = VesselModel(QUIET)
    ins = 0.02 * DT * np.arange(1, 2001)            # to 40 mm (before the wall)
    ret = ins[-1] - 0.02 * DT * np.arange(1, 1001)  # back 20 mm
    a = drive(v, ins)
    b = drive(v, ret, t0=2.0)
    assert a[-1, 0] == pytest.approx(v.coulomb_force(ins[-1]) * (1 + 0.4 * math.exp(-100)),
                                     rel=1e-3)
    assert a[-1, 4] > 0
    assert b[-1, 0] < 0 and b[-1, 4] < 0
    assert b[-1, 0] == pytest.approx(-v.coulomb_force(ret[-1]), rel=1e-3)
    # the flip takes a few pre-sliding lengths of travel, not a jump
    travel_to_flip = (np.argmax(b[:, 0] < 0) + 1) * 0.02 * DT
    d = v.params.presliding_displacement
    assert 0.2 * d < travel_to_flip < 5 * d


def test_stick_at_rest_holds_the_force_below_breakaway():
    v = VesselModel(QUIET)
    ins = 0.02 * DT * np.arange(1, 1501)            # to 30 mm
    a = drive(v, ins)
    rest = drive(v, np.full(2000, ins[-1]), t0=1.5)
    assert np.all(rest[:, 0] == a[-1, 0])            # stuck: friction held, no drift
    assert 0 < rest[0, 0] <= v.breakaway_force(ins[-1])
    # a small reversal (1/6 of the pre-sliding displacement) stays stuck: elastic, no sign
    # flip; LuGre's reversal slope is 2 Fc/zc from the sliding state (Masing-like hysteresis)
    zc = v.params.presliding_displacement
    d = zc / 6
    drive(v, ins[-1] - d * np.linspace(0, 1, 200)[1:], t0=3.5)     # the small reversal
    held = drive(v, np.full(500, ins[-1] - d), t0=3.7)[:, 0]
    fc = v.coulomb_force(ins[-1])
    assert fc * (1 - 2.2 * d / zc) < held[0] < fc * (1 - 1.0 * d / zc)
    assert np.all(held == held[0])


def test_breakaway_peak_when_motion_starts():
    """Stick-slip (Stribeck): creeping from rest the friction rises to the breakaway level Fs;
    once the catheter slips faster it drops to the Coulomb level Fc."""
    p = QUIET
    v = VesselModel(p)
    x0 = 0.03
    drive(v, np.full(10, x0))
    creep = x0 + 0.0005 * DT * np.arange(1, 6001)          # 0.5 mm/s for 6 s (10 zc)
    a = drive(v, creep, t0=0.01)[:, 0] / np.array([v.coulomb_force(x) for x in creep])
    slip = creep[-1] + 0.02 * DT * np.arange(1, 1001)     # then 20 mm/s
    b = drive(v, slip, t0=6.01)[:, 0] / np.array([v.coulomb_force(x) for x in slip])
    g_creep = 1 + (p.stribeck_ratio - 1) * math.exp(-(0.0005 / p.stribeck_velocity) ** 2)
    assert a[-1] == pytest.approx(g_creep, rel=2e-3)       # near breakaway while creeping
    assert a.max() <= p.stribeck_ratio + 1e-9             # never above breakaway
    assert b[-1] == pytest.approx(1.0, rel=1e-3)           # Coulomb level while sliding
    assert a[-1] - b[-1] > 0.3                             # the slip drop


@settings(max_examples=100, deadline=None)
@given(st.floats(-0.05, 0.2), st.floats(-0.1, 0.1))
def test_wall_force_only_past_the_wall_and_never_pulls(x, xd):
    v = VesselModel()
    v.force(0.0, x, xd)
    w = v.last.wall
    assert w >= 0.0
    if x <= v.params.wall_depth:
        assert w == 0.0
    elif xd >= 0:
        assert w > 0.0


def test_wall_force_is_hunt_crossley():
    p = VesselParams()
    v = VesselModel(p)
    d = 0.011
    v.force(0.0, p.wall_depth + d, 0.0)
    assert v.last.wall == pytest.approx(p.wall_stiffness * d ** 1.5)
    v.force(0.001, p.wall_depth + d, 0.0413)
    assert v.last.wall == pytest.approx(p.wall_stiffness * d ** 1.5 * (1 + p.wall_damping * 0.0413))
    # stiffening: twice as deep gives 2^1.5 the force
    v.force(0.002, p.wall_depth + 2 * d, 0.0)
    assert v.last.wall == pytest.approx(2 ** 1.5 * p.wall_stiffness * d ** 1.5)


def test_cardiac_component_is_at_one_point_two_hertz():
    v = VesselModel(seed=7)
    drive(v, 0.02 * DT * np.arange(1, 2001))        # to 40 mm, then rest 10 s
    f = drive(v, np.full(10000, 0.04), t0=2.0)[:, 4]
    spec = np.abs(np.fft.rfft(f - f.mean())) * 2 / len(f)
    freqs = np.fft.rfftfreq(len(f), DT)
    k = np.argmax(spec)
    assert freqs[k] == pytest.approx(1.2)
    assert spec[k] == pytest.approx(0.01, rel=0.02)
    assert np.sort(spec)[-2] < 0.01 * spec[k]        # nothing else moves at rest


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.floats(-0.1, 0.0), st.floats(-0.1, 0.1)), min_size=1, max_size=30),
       st.integers(0, 50))
def test_no_force_outside_the_body(states, seed):
    v = VesselModel(seed=seed)
    drive(v, 0.02 * DT * np.arange(1, 500))          # some friction history inside first
    for i, (x, xd) in enumerate(states):
        assert v.force(1.0 + i * DT, x, xd) == 0.0


def test_deterministic_for_a_seed_and_reset(exp1):
    t, x = exp1
    t, x = t[:3000], x[:3000]
    xd = np.gradient(x, DT)

    def run(v):
        return [v.force(a, b, c) for a, b, c in zip(t, x, xd, strict=True)]
    a, b, c = run(VesselModel(seed=1)), run(VesselModel(seed=1)), run(VesselModel(seed=2))
    assert a == b
    assert a != c
    v = VesselModel(seed=1)
    run(v)
    v.reset()
    assert run(v) == a


@pytest.mark.parametrize('field', ['friction_per_length', 'viscous_per_length', 'wall_depth',
                                   'wall_stiffness', 'cardiac_amplitude', 'capstan_length',
                                   'presliding_displacement', 'stribeck_velocity'])
@pytest.mark.parametrize('bad', [-1.0, math.nan, math.inf])
def test_bad_params(field, bad):
    with pytest.raises(ValueError, match=field):
        VesselParams(**{field: bad})


#: the parameters that divide (lengths, velocities, rates, a mass) or are an exponent: > 0;
#: every other one may be 0 (a term switched off) but not negative (stribeck_ratio: >= 1)
POSITIVE = {'capstan_length', 'stribeck_velocity', 'presliding_displacement', 'wall_exponent',
            'cardiac_depth', 'catheter_mass', 'friction_step_spacing', 'friction_step_width',
            'stenosis_length', 'breathing_frequency'}


@pytest.mark.parametrize('cls', [VesselParams, VesselExtras])
def test_every_parameter_refuses_nan_and_keeps_its_sign_constraint(cls):
    for f in dataclasses.fields(cls):
        with pytest.raises(ValueError, match=f.name):
            cls(**{f.name: math.nan})
        if f.name == 'stribeck_ratio':
            continue
        if f.name in POSITIVE:
            with pytest.raises(ValueError, match=f.name):
                cls(**{f.name: 0.0})
        else:
            cls(**{f.name: 0.0})
            with pytest.raises(ValueError, match=f.name):
                cls(**{f.name: -1e-300})


def test_bad_model_arguments():
    with pytest.raises(ValueError, match='stribeck_ratio'):
        VesselParams(stribeck_ratio=0.5)
    with pytest.raises(ValueError, match='params'):
        VesselModel(params={'wall_depth': 0.1})
    with pytest.raises(ValueError, match='seed'):
        VesselModel(seed=-1)
    v = VesselModel()
    for name, args in (('t', (math.nan, 0.0, 0.0)), ('x', (0.0, math.inf, 0.0)),
                       ('xd', (0.0, 0.0, None))):
        with pytest.raises(ValueError, match=name):
            v.force(*args)
    v.force(1.0, 0.01, 0.0)
    with pytest.raises(ValueError, match='t must not decrease'):
        v.force(0.5, 0.01, 0.0)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.floats(-0.08, 0.08), st.integers(1, 300)), min_size=1, max_size=12),
       st.sampled_from([1e-4, 1e-3, 1e-2]))
def test_bristle_state_bounded_and_friction_below_breakaway_at_rest(segments, dt):
    """For any velocity history (any step size: the exact update is unconditionally stable) the
    LuGre deflection stays within zc * Fs/Fc, so the held friction at rest never exceeds Fs(x)."""
    p = VesselParams(cardiac_amplitude=0.0)
    v = VesselModel(p)
    t, x = 0.0, 0.03
    bound = p.presliding_displacement * p.stribeck_ratio * (1 + 1e-12)
    for vel, n in segments:
        for _ in range(n):
            t += dt
            x = min(max(x + vel * dt, 0.001), 0.2)
            v.force(t, x, vel)
            assert abs(v.z) <= bound
    t += dt
    v.force(t, x, 0.0)
    assert abs(v.last.friction) <= v.breakaway_force(x) * (1 + 1e-9)


STICKY = VesselParams(shaft_stiffness=50.0, presliding_displacement=1e-5, cardiac_amplitude=0.0)


def run_compliant(params, vel, seconds, x0=0.03):
    v = VesselModel(params)
    out = []
    for k in range(int(seconds * 1000)):
        t = k * DT
        f = v.force(t, x0 + vel * t, vel)
        out.append((t, x0 + vel * t, v.y, v.yd, f, v.last.friction / v.coulomb_force(v.y)))
    return v, np.array(out)


def test_default_shaft_is_rigid():
    assert VesselParams().shaft_stiffness == 0.0
    v = VesselModel()
    v.force(0.0, 0.02, 0.01)
    v.force(0.001, 0.03, 0.01)
    assert (v.y, v.yd) == (0.03, 0.01)


def test_compliant_shaft_gives_stick_slip_at_slow_insertion():
    """Drive at 1 mm/s through a 50 N/m shaft: the catheter sticks, the spring loads to the
    breakaway level, it slips (tens of mm/s), friction drops to the Coulomb level, it sticks."""
    vel = 0.001
    v, a = run_compliant(STICKY, vel, 12.0)
    a = a[4000:]                                   # after the spring first loads up
    yd, ratio = a[:, 3], a[:, 5]
    stuck = np.abs(yd) < 0.1 * vel
    assert stuck.mean() > 0.5                      # mostly stuck
    assert yd.max() > 10 * vel                     # slips fast
    slips = np.count_nonzero(np.diff(stuck.astype(int)) == -1)
    assert slips >= 3                              # repeated cycles, not one breakaway
    assert ratio.max() == pytest.approx(STICKY.stribeck_ratio, rel=0.03)   # breaks away at Fs
    assert ratio.min() < 1.05                      # slides down to the Coulomb level
    # the mean velocity of the catheter is the drive's (it does not drift away)
    assert np.mean(yd) == pytest.approx(vel, rel=0.2)


def test_compliant_shaft_slides_smoothly_and_lags_by_force_over_stiffness():
    p = VesselParams(shaft_stiffness=50.0, cardiac_amplitude=0.0)
    vel = 0.01
    v, a = run_compliant(p, vel, 2.5, x0=0.005)
    t, x, y, yd, f, _ = a[-1]
    # steady sliding, no stick-slip: the spring keeps loading as friction grows with depth,
    # so the catheter moves at v / (1 + F'(y) / k) (F' the slope of the sliding force)
    slope = (v.steady_force(y + 1e-6, yd) - v.steady_force(y - 1e-6, yd)) / 2e-6
    assert yd == pytest.approx(vel / (1 + slope / p.shaft_stiffness), rel=2e-3)
    assert np.all(a[-500:, 3] > 0.5 * vel)
    # spring balance: k (x - y) + d (x' - y') = the vessel's force on the catheter
    assert (p.shaft_stiffness * (x - y) + p.shaft_damping * (vel - yd)
            == pytest.approx(f, rel=2e-3))
    assert f == pytest.approx(v.steady_force(y, yd), rel=2e-3)


def test_compliant_shaft_that_cannot_be_integrated_says_so():
    p = VesselParams(shaft_stiffness=1e5, catheter_mass=1e-6, shaft_damping=0.0)
    v = VesselModel(p)
    with pytest.raises(ValueError, match='diverged'):
        for k in range(2000):
            v.force(k * DT, 0.03 + 0.02 * k * DT, 0.02)

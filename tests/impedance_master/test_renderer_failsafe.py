"""The renderers' invariants (issue 10), stated and fuzzed:

* the desired force is always a finite float within [-limit, limit], whatever the models
  and master states (NaN, inf, 1e308, overflowing models), and the limit in force is the
  one set last (runtime changes apply at the next call);
* a fault (bad input, non-finite evaluation) starts the fallback: hold the last safe
  force and ramp it linearly to 0 N over fallback_time;
* the renderer recovers by itself: good data again -> the model's force, bumplessly;
* status() says what is going on (WARN / ERROR while held, refused, dropped, bad input).
"""
import math

import pytest
from hypothesis import example, given, settings, strategies as st

from impedance_master.envelope import ModelEnvelope
from impedance_master.impedance import Impedance
from impedance_master.rendering import DfrRenderer, ImaRenderer
from impedance_master.safety import ERROR, OK, WARN, SafeOutput

GOOD = Impedance(0.0, 2.0, 2.0, 0.02)
STATE = (0.03, 0.01, 0.0)

anything = st.one_of(st.floats(allow_nan=True, allow_infinity=True),
                     st.sampled_from([1e308, -1e308, 1.7e308, -1.7e308, 5e-324, 0.0]))


def table(scale=1.0, n=9):
    return Impedance(0.001, 0.5, 1.0, 0.01, x0=0.0, dx=0.01, S=[0.01 * scale] * n,
                     F=[0.02 * scale * i for i in range(n)], B=[0.005] * n, C=[0.1] * n)


def model_from(vals, kind):
    """An Impedance from fuzzed values; None if the constructor refuses them (it refuses
    non-finite values: only finite absurd models get through to the renderer)."""
    m, c, k, o = vals
    try:
        if kind == 0:
            return Impedance(m, c, k, o)
        return table().copy(m=m, c=c, k=k, offset=o, S=[o] * 9)
    except ValueError:
        return None


ops = st.lists(st.one_of(
    st.tuples(st.just('model'), st.tuples(anything, anything, anything, anything),
              st.integers(0, 1)),
    st.tuples(st.just('render'), st.tuples(anything, anything, anything), st.integers(1, 40)),
    st.tuples(st.just('good'), st.integers(1, 200)),
    st.tuples(st.just('limit'), st.floats(0.05, 5.0)),
), min_size=1, max_size=25)


@settings(max_examples=300, deadline=None)
@given(ops, st.booleans())
@example([('model', (1e308, -1e308, 0.0, 0.0), 0), ('render', (0.03, 2.0, 2.0), 5)], True)
@example([('render', (-1.7e308, 1.7e308, 0.0), 3)], True)
@example([('model', (0.0, 0.0, 1e300, 0.0), 0), ('good', 50)], True)
def test_ima_output_is_always_finite_and_within_the_limit_and_recovers(ops, passivity):
    ren = ImaRenderer(limit=2.0, max_rate=20.0, passivity=passivity)
    limit = 2.0
    for op in ops:
        if op[0] == 'model':
            imp = model_from(op[1], op[2])
            if imp is not None:
                ren.set_impedance(imp)
            continue
        if op[0] == 'limit':
            ren.limit = limit = op[1]
            continue
        if op[0] == 'good':
            ren.set_impedance(GOOD)
            state, n = STATE, op[1]
        else:
            state, n = op[1], op[2]
        for _ in range(n):
            f = ren.desired_force(*state)
            assert isinstance(f, float) and math.isfinite(f) and abs(f) <= limit
        assert math.isfinite(ren.energy)
    # recovers by itself: a good model and good states for long enough give its force
    ren.set_impedance(GOOD.copy(offset=0.0123))
    ren.limit = 2.0
    for _ in range(2000):
        f = ren.desired_force(*STATE)
    assert f == pytest.approx(GOOD.copy(offset=0.0123).force(*STATE), abs=1e-6)
    assert ren.status().state == 'held'            # 2 s without a new model
    ren.set_impedance(GOOD.copy(offset=0.0123))    # the link delivers it again
    assert ren.status().level == OK


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.one_of(anything, st.floats(-5, 5)), st.integers(1, 20)),
                min_size=1, max_size=20), st.floats(0.05, 5.0))
def test_dfr_output_is_always_finite_and_within_the_limit(forces, limit):
    dfr = DfrRenderer(limit=limit)
    for f, n in forces:
        took = dfr.set_force(f)
        assert took == (math.isfinite(f) and abs(f) <= dfr.max_force)
        for _ in range(n):
            out = dfr.desired_force()
            assert isinstance(out, float) and math.isfinite(out) and abs(out) <= limit


def test_the_clamp_refuses_nan_before_comparing():
    """min(max(nan, -lim), lim) is nan: the old clamp let it through. The safe output never
    compares a non-finite value; it falls back instead."""
    out = SafeOutput(limit=2.0)
    assert out.output(0.5) == 0.5
    for bad in (math.nan, math.inf, -math.inf, 1e308, '0.5', None):
        f = out.output(bad)
        assert math.isfinite(f) and abs(f) <= 2.0
    assert out.n_faults == 6 and out.in_fallback


def test_fallback_holds_then_ramps_to_zero_over_fallback_time():
    ren = ImaRenderer(limit=2.0, blend_time=0.0, fallback_time=0.2, dt=1e-3)
    ren.set_impedance(GOOD)
    f0 = ren.desired_force(*STATE)
    out = [ren.desired_force(math.nan, 0.0, 0.0) for _ in range(300)]
    # hand-checked: the held force, then linear to 0 at 0.2 s, then 0
    assert out[0] == pytest.approx(f0)
    assert out[100] == pytest.approx(f0 * (1 - 100 / 200))
    assert out[199] == pytest.approx(f0 / 200) and out[200:] == [0.0] * 100
    st = ren.status()
    assert st.level == ERROR and st.state == 'bad_input' and st.counters['bad_input'] == 300
    # good input again: bumpless take-over from 0 N back to the model's force
    back = [ren.desired_force(*STATE) for _ in range(400)]
    assert back[0] == pytest.approx(0.0, abs=1e-9)
    assert back[-1] == pytest.approx(f0, rel=1e-3)       # 8 time constants of 50 ms
    # no step: the difference decays with 50 ms, the largest step is f0 (1 - exp(-1/50))
    step = max(abs(b - a) for a, b in zip(back[:-1], back[1:], strict=True))
    assert step == pytest.approx(abs(f0) * (1 - math.exp(-1e-3 / 0.05)), rel=1e-6)
    assert ren.status().state == 'held'        # rendering again, on a model 0.7 s old


def test_a_model_that_overflows_is_dropped_and_the_next_one_blends_in():
    # a permissive envelope and state box (not the defaults) let a model through whose
    # evaluation overflows at a state inside the box: the renderer must still cope
    env = ModelEnvelope(max_mass=1e300, max_force=1e308)
    ren = ImaRenderer(limit=2.0, envelope=env, state_box=(-1.0, 1.0, 10.0, 1e10))
    ren.set_impedance(GOOD)
    ren.desired_force(*STATE)
    assert ren.set_impedance(Impedance(1e300, 0.0, 0.0, 0.0))
    f = ren.desired_force(0.005, 0.0, 1e10)
    assert math.isfinite(f) and ren.n_dropped == 1 and ren.model is None
    assert 'evaluation' in ren.last_reason and 'inf' in ren.last_reason   # says why
    assert ren.status().level == ERROR
    ren.set_impedance(GOOD)
    out = [ren.desired_force(*STATE) for _ in range(500)]
    assert out[-1] == pytest.approx(GOOD.force(*STATE), rel=1e-3)
    assert ren.status().state == 'held'


def test_models_outside_the_envelope_are_refused_and_the_current_one_stays():
    ren = ImaRenderer(blend_time=0.0)
    assert ren.set_impedance(GOOD)
    f = ren.desired_force(*STATE)
    for bad in (Impedance(1e308, -1e308, 0, 0), Impedance(0, 0, 1e300, 0),
                table(scale=1e4), Impedance(valid=False)):
        assert ren.set_impedance(bad) is False
        assert ren.desired_force(*STATE) == f
    assert ren.n_refused == 3 and ren.n_ignored == 1
    st = ren.status()
    assert st.level == WARN and st.state == 'refused' and 'model refused' in st.message


def test_runtime_limit_applies_at_the_next_call():
    """Issue 10 item 3 at the core: a limit change takes effect within one cycle."""
    ren = ImaRenderer(limit=2.0, blend_time=0.0)
    ren.set_impedance(Impedance(0.0, 0.0, 0.0, 1.5))
    assert ren.desired_force(*STATE) == 1.5
    ren.limit = 0.5
    assert ren.desired_force(*STATE) == 0.5 and ren.status().limit == 0.5
    for bad in (0.0, -1.0, math.nan, math.inf, 'x'):
        with pytest.raises(ValueError, match='limit'):
            ren.limit = bad
    assert ren.limit == 0.5
    dfr = DfrRenderer(limit=2.0)
    dfr.set_force(1.5)
    dfr.limit = 0.25
    assert dfr.desired_force() == 0.25
    ren.max_rate = 1.0
    ren.limit = 2.0
    assert ren.desired_force(*STATE) == pytest.approx(0.5 + 1.0 * 1e-3)
    with pytest.raises(ValueError, match='max_rate'):
        ren.max_rate = 0.0
    with pytest.raises(ValueError, match='blend_time'):
        ren.blend_time = -1.0


def test_status_levels_follow_the_renderer_state():
    ren = ImaRenderer(stale_time=0.05)
    assert ren.status().state == 'no_model' and ren.status().level == WARN
    ren.set_impedance(GOOD)
    ren.desired_force(*STATE)
    assert ren.status().level == OK
    for _ in range(60):                                  # no model received for 60 ms
        ren.desired_force(*STATE)
    assert ren.status().state == 'held' and ren.status().level == WARN
    ren.set_impedance(GOOD)                              # the same model again: alive
    assert ren.status().level == OK
    dfr = DfrRenderer(stale_time=0.05)
    assert dfr.status().level == WARN
    dfr.set_force(0.1)
    dfr.desired_force()
    assert dfr.status().level == OK
    for _ in range(60):
        dfr.desired_force()
    assert dfr.status().state == 'held'


def test_passivity_damping_never_exceeds_its_cap():
    """The TDPA damping alpha = -E / (dt x'^2) is capped at max_damping: at a slow
    velocity with energy owed, an uncapped alpha would be enormous (a jolt at the hand)."""
    ren = ImaRenderer(limit=50.0, blend_time=0.0, passivity=True, max_damping=5.0)
    # an active damper stronger than the cap: the energy debt grows while it moves fast
    ren.set_impedance(Impedance(0.0, -20.0, 0.0, 0.0))
    x = 0.03
    worst = 0.0
    for k in range(2000):
        xd = 0.02 if k < 1000 else 1e-4                     # fast, then very slow
        x += xd * 1e-3
        f = ren.desired_force(x, xd, 0.0)
        model = -20.0 * xd
        worst = max(worst, abs(f - model) / abs(xd))
    assert ren.n_passivity > 0 and ren.energy < 0.0         # the debt is real
    assert worst == pytest.approx(5.0)                      # the cap binds, never more


def test_bad_arguments_are_refused_naming_them():
    ren = ImaRenderer()
    with pytest.raises(ValueError, match='xd'):
        ren.desired_force(0.0, 'fast', 0.0)
    with pytest.raises(ValueError, match='imp'):
        ren.set_impedance({'m': 1.0})
    with pytest.raises(ValueError, match='anchoring'):
        ImaRenderer(anchoring='both')
    with pytest.raises(ValueError, match='state_box'):
        ImaRenderer(state_box=(1.0, 0.0, 1.0, 1.0))
    with pytest.raises(ValueError, match='f'):
        DfrRenderer().set_force(None)

"""Issue 12, fifth round: the online score that blends the anchored baseline into the
default IMA (`scoring.OnlineScore`) and the continuous extension across gaps in the data
(`support.Support.bracket`); hand-checked values and hypothesis invariants."""
import math
import random

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from impedance_master import ImaRenderer, Impedance
from impedance_master.impedance import steady_states
from impedance_master.scoring import (SCORE_LAG, SCORE_MEMORY, SCORE_MIN, SCORE_RIDGE,
                                      OnlineScore)
from impedance_master.support import DepthSlope, Support


def _score(**kw):
    return OnlineScore(Support(), DepthSlope(), 0.005, 50.0, **kw)


def test_weight_is_the_least_squares_blend_of_the_two_predictions():
    # the truth is p_i + 0.3 (p_a - p_i) plus noise uncorrelated with the difference:
    # w* = sum(d e) / (sum(d d) + n ridge), against numpy's least squares
    rng = random.Random(1)
    sc = _score(memory=1e9, min_scored=0)
    d_all, e_all = [], []
    for _ in range(400):
        pi = rng.uniform(-0.5, 0.5)
        d = rng.uniform(-0.2, 0.2)
        f = pi + 0.3 * d + rng.gauss(0.0, 0.01)
        sc.add(pi, pi + d, f)
        d_all.append(d)
        e_all.append(f - pi)
    d_all, e_all = np.array(d_all), np.array(e_all)
    want = d_all @ e_all / (d_all @ d_all + len(d_all) * SCORE_RIDGE)
    assert sc.target() == pytest.approx(want, rel=1e-6)
    assert abs(sc.target() - 0.3) < 0.03 + 0.3 * len(d_all) * SCORE_RIDGE / (d_all @ d_all)
    assert sc.err_ima == pytest.approx(np.mean(np.abs(e_all)), rel=1e-6)


def test_weight_is_clipped_to_the_unit_interval_and_zero_before_min_scored():
    sc = _score(memory=1e9)
    for _ in range(SCORE_MIN):
        assert sc.target() == 0.0
        sc.add(0.0, 0.1, 0.3)          # the truth beyond the anchored: w* > 1
    assert sc.n_scored == SCORE_MIN and sc.target() == 1.0
    sc2 = _score(min_scored=0)
    for _ in range(100):
        sc2.add(0.0, 0.1, -0.1)        # the anchored moves the wrong way: w* < 0
    assert sc2.target() == 0.0
    sc3 = _score(min_scored=0)
    sc3.add(0.2, 0.2, 0.5)             # the predictors agree: no evidence, no weight
    assert sc3.target() == 0.0


def test_weight_slews_at_most_rate_dt_per_period_and_forgets():
    sc = _score(min_scored=0, rate=1.0, dt=1e-3, memory=0.5)
    for _ in range(200):
        sc.add(0.0, 0.1, 0.1)           # the anchored is right
    w = [sc.tick() for _ in range(2000)]
    assert np.max(np.diff([0.0] + w)) <= 1e-3 + 1e-15
    assert w[499] == pytest.approx(0.5, abs=1e-9)     # 0.5 s at 1 / s
    assert w[-1] == pytest.approx(sc.target())
    assert sc.target() > 0.9
    for _ in range(400):                # the world changes: the IMA is right (8 s)
        sc.tick()
        sc._now += 0.019
        sc.add(0.0, 0.1, 0.0)
    assert sc.target() < 0.05


@given(st.lists(st.tuples(st.floats(-2, 2), st.floats(-2, 2), st.floats(-2, 2)),
                min_size=1, max_size=60))
def test_weight_is_always_finite_in_the_unit_interval(samples):
    sc = _score(min_scored=0)
    for pi, pa, f in samples:
        sc.add(pi, pa, f)
        w = sc.tick()
        assert 0.0 <= sc.target() <= 1.0 and 0.0 <= w <= 1.0


def test_bad_settings_name_themselves():
    for name, kw in (('score_lag', dict(lag=-1.0)), ('score_memory', dict(memory=0.0)),
                     ('score_rate', dict(rate=math.nan))):
        with pytest.raises(ValueError, match=name):
            _score(**kw)
    with pytest.raises(ValueError, match='score_memory'):
        ImaRenderer(score_memory=-1.0)


# ------------------------------------------------------------------ in the renderer

def _path(t):
    """A slave going back and forth over 20-40 mm (0.2 Hz): x m, x' m/s."""
    w = 2 * math.pi * 0.2
    return 0.03 + 0.01 * math.sin(w * t), 0.01 * w * math.cos(w * t)


def _feed(ima, miss, n=500):
    """Models k x + 0.05 + 2 x' of the slave on `_path`, one per 20 ms, each anchored at a
    sample whose measured force misses the model by miss(i) N; the master renders the
    state the slave reaches `SCORE_LAG` later."""
    base = Impedance(0.0, 2.0, 5.0, 0.05)
    for i in range(n):
        x, xd = _path(0.02 * i)
        z1, z2 = steady_states(xd, base.v_s, base.beta)
        f = base.force(x, xd, 0.0) + miss(i)
        assert ima.set_impedance(Impedance(0.0, 2.0, 5.0, 0.05,
                                           anchor=(x, xd, 0.0, z1, z2, f, 0.0)))
        for k in range(20):
            ima.desired_force(*_path(0.02 * i + 0.001 * k + SCORE_LAG), 0.0)
    return base


def test_a_lasting_miss_earns_the_anchored_baseline_a_passing_one_does_not():
    # a model bias that drifts slowly (breathing-like: the latest measured force is right)
    ima = ImaRenderer(blend_time=0.0, max_rate=1e9, score_memory=SCORE_MEMORY)
    assert ima.score is not None and ima.score.memory == SCORE_MEMORY
    _feed(ima, lambda i: 0.08 + 0.02 * math.sin(2 * math.pi * 0.25 * 0.02 * i))
    assert ima.score.weight > 0.8
    # noise-like: every anchor's miss is its own (carrying it forward is wrong)
    rng = random.Random(3)
    ima2 = ImaRenderer(blend_time=0.0, max_rate=1e9, score_memory=SCORE_MEMORY)
    _feed(ima2, lambda i: rng.gauss(0.0, 0.05))
    assert ima2.score.weight < 0.05
    # the rendered force is the blend, weighed by the support at the master's depth
    x, xd = 0.031, 0.01
    off = ImaRenderer(blend_time=0.0, max_rate=1e9, score_memory=None)
    assert off.score is None
    _feed(off, lambda i: 0.08 + 0.02 * math.sin(2 * math.pi * 0.25 * 0.02 * i))
    f_ima = off.desired_force(x, xd, 0.0)
    m = off.model
    a = m.anchor
    f_anch = m.force(x, xd, 0.0) + (a.f - m.force(a.x, a.xd, 0.0))
    w = ima.score.weight * ima.support.anywhere(x)
    assert w > 0.8
    ima.score._step = 0.0               # hold the weight for the comparison
    assert ima.desired_force(x, xd, 0.0) == pytest.approx(f_ima + w * (f_anch - f_ima),
                                                           abs=1e-9)


def test_the_weight_returns_to_the_default_when_models_stop_arriving():
    ima = ImaRenderer(blend_time=0.0, max_rate=1e9, score_memory=SCORE_MEMORY)
    _feed(ima, lambda i: 0.08)
    w0 = ima.score.weight
    assert w0 > 0.8
    x, xd = _path(10.0 + SCORE_LAG)
    w = []
    for _ in range(1500):               # an outage: no model for 1.5 s
        ima.desired_force(x, xd, 0.0)
        w.append(ima.score.weight)
    k = int(round(SCORE_LAG / ima.dt))
    assert w[k - 25] == pytest.approx(w0, abs=1e-9)   # held while the model is fresh (20 ms old)
    assert w[k] < w0
    assert np.min(np.diff(w)) >= -ima.score.rate * ima.dt - 1e-12   # slewed down
    assert w[-1] == 0.0


def test_the_shadow_scores_with_the_model_received_lag_earlier_where_it_had_data():
    from impedance_master.anchoring import anchor_term
    base = Impedance(0.0, 2.0, 5.0, 0.05)
    z1, z2 = steady_states(0.01, base.v_s, base.beta)

    def model(x, miss):
        return Impedance(0.0, 2.0, 5.0, 0.05, anchor=(x, 0.01, 0.0, z1, z2,
                                                      base.force(x, 0.01, 0.0) + miss, 0.0))

    def observe(sc, m):
        sc.observe(m, anchor_term(m, 'local'), m.anchor)

    sup = Support()
    for _ in range(10):
        sup.add(0.03, 0.01)                  # the shadow's data: c(30 mm) = 10 / 13
    sc = OnlineScore(sup, None, 0.005, 50.0, min_scored=0)
    observe(sc, model(0.03, 0.0))            # t = 0
    for _ in range(200):
        sc.tick()
    observe(sc, model(0.03, 0.5))            # t = 0.2 s: no model lag (0.4 s) old yet
    assert sc.n_scored == 0
    for _ in range(200):
        sc.tick()
    observe(sc, model(0.06, 0.5))            # t = 0.4 s, but where the shadow had no data
    assert sc.n_scored == 0
    observe(sc, model(0.03, 0.3))            # scored with the first model (its miss 0):
    assert sc.n_scored == 1                  # both predict the model's force there
    assert sc.err_ima == pytest.approx(0.3) and sc.err_anchored == pytest.approx(0.3)
    assert sc.target() == 0.0                # the predictions agree: no evidence

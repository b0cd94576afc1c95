"""Issue 12, seventh round: the elastic share's parabola through the entry
(`support.ElasticShare` trend 'quad', the renderer's default), against numpy least squares
and hand values: a friction growing with the square of the length is friction, not a wall."""
import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from impedance_master import ImaRenderer
from impedance_master.support import BIN, ELASTIC_TREND, ElasticShare


def _fed(force, trend, lo=0.008, hi=0.056, step=0.001, **kw):
    e = ElasticShare(0.0, 0.1, trend=trend, **kw)
    for i in range(int(round((hi - lo) / step)) + 1):
        x = lo + i * step
        assert e.add(x, 0.01, force(x))
    return e


def test_square_law_friction_has_no_elastic_share_with_the_parabola():
    def f(x):
        return 2.0 * x + 150.0 * x * x      # stribeck_kv's friction: the square of the length

    quad = _fed(f, 'quad')
    line = _fed(f, 'line')
    for x in (0.035, 0.045, 0.056):
        assert quad.rate(x) == pytest.approx(2.0 + 150.0 * x, rel=1e-9)
        assert quad.share(x, f(x)) == pytest.approx(0.0, abs=1e-9)
        assert line.share(x, f(x)) > 0.1                    # the line reads it as a wall


def test_a_wall_beyond_the_fitted_bins_is_still_elastic():
    def f(x):
        return 4.0 * x + (20.0 * (x - 0.04) if x > 0.04 else 0.0)

    e = _fed(f, 'quad')
    x = 0.055                       # the trend is fitted to the bins up to 40 mm
    assert e.rate(x) == pytest.approx(4.0, rel=1e-9)
    assert e.share(x, f(x)) == pytest.approx(20.0 * 0.015 / f(x), rel=1e-9)


def _numpy_nonneg_fit(xb, fs):
    """min sum (f - mu x - nu x^2)^2 over mu, nu >= 0: the unconstrained fit, else the best
    of the two one-term fits (numpy lstsq)."""
    a = np.column_stack([xb, xb * xb])
    sol = np.linalg.lstsq(a, fs, rcond=None)[0]
    if np.all(sol >= 0):
        return sol
    best = None
    for j in (0, 1):
        c = max(0.0, np.linalg.lstsq(a[:, j:j + 1], fs, rcond=None)[0][0])
        s = np.zeros(2)
        s[j] = c
        r = np.sum((fs - a @ s) ** 2)
        if best is None or r < best[0]:
            best = (r, s)
    return best[1]


@pytest.mark.parametrize('curv', [60.0, -40.0, 400.0])
def test_rate_is_numpy_nonnegative_least_squares_over_the_shallow_bins(curv):
    # curv > 0: both terms free; < 0: the square term would be negative (the line);
    # large with an offset: the linear term would be negative (the square term alone)
    e = ElasticShare(0.0, 0.1, margin=0.01, min_depth=0.005, trend='quad')
    rng = np.random.default_rng(5)
    xs = rng.uniform(0.0, 0.06, 300)
    off = -0.05 if curv > 100 else 0.0
    fs = 3.0 * xs + curv * xs * xs + off + rng.normal(0, 0.005, 300)
    for x, f in zip(xs, fs, strict=True):
        e.add(float(x), 0.02, float(f))
    b = np.round(xs / BIN).astype(int)
    sel = (b * BIN >= 0.005) & (b <= 37)
    mu, nu = _numpy_nonneg_fit(b[sel] * BIN, fs[sel])
    if curv < 0:
        assert nu == 0.0
    if curv > 100:
        assert mu == 0.0
    x = 0.047                       # 37 mm and shallower, whole bins
    assert e.rate(x) == pytest.approx(mu + nu * x, rel=1e-8)
    # between bins the running sums are linear: continuous in x
    r = [e.rate(x + 1e-5 * i) for i in range(101)]
    assert max(abs(b2 - a) for a, b2 in zip(r, r[1:], strict=False)) < 0.05 * abs(r[0])


def test_trend_is_checked_and_the_renderer_default_is_the_parabola():
    with pytest.raises(ValueError, match='trend'):
        ElasticShare(trend='cubic')
    with pytest.raises(ValueError, match='trend'):
        ImaRenderer(elastic_trend='cubic')
    assert ELASTIC_TREND == 'quad'
    assert ImaRenderer().elastic.trend == 'quad'
    assert ImaRenderer(elastic_trend='line').elastic.trend == 'line'


@given(st.lists(st.tuples(st.floats(0.0, 0.09), st.floats(-1.0, 3.0)), min_size=0,
                max_size=60), st.floats(0.0, 0.1), st.floats(-1.0, 3.0))
def test_parabola_share_is_always_in_the_unit_interval(anchors, x, f):
    e = ElasticShare(0.0, 0.1, trend='quad')
    for xa, fa in anchors:
        e.add(xa, 0.01, fa)
    s = e.share(x, f)
    assert 0.0 <= s <= 1.0
    r = e.rate(x)
    assert r is None or math.isfinite(r)

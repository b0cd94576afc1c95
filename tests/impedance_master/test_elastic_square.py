"""Issue 12, thirteenth round: the square-law bound of the friction trend
(`ElasticShare.square_rate`, `square_excess`) and the first outward reversal that keeps at
least the force above it (`anchoring.elastic_keep(square=True)`, `ImaRenderer`
elastic_square), on a wall stream and a square-law stream built here, against numpy least
squares."""
import math
import pathlib
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from impedance_master import ImaRenderer, Impedance
from impedance_master.anchoring import elastic_keep
from impedance_master.support import BIN, ELASTIC_SQUARE, ElasticShare, Support

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from streams import insert, pull_back  # noqa: E402

sys.path.pop(0)

MU = 4.0             # N/m, friction growing linearly with the inserted length
WALL = (0.04, 20.0)  # a wall from 40 mm at 20 N/m
CQ = 80.0            # N/m^2, friction growing with the square of the length (stribeck_kv)


def _wall(x):
    return MU * x + (WALL[1] * (x - WALL[0]) if x > WALL[0] else 0.0)


def _square(x):
    return CQ * x * x


def _fed(force, lo=0.010, hi=0.056, step=0.001, **kw):
    e = ElasticShare(0.0, 0.1, **kw)
    for i in range(int(round((hi - lo) / step)) + 1):
        x = lo + i * step
        assert e.add(x, 0.01, force(x))
    return e


def _c_ref(force, x_max, lo=0.010):
    """numpy least squares of f = c x^2 (no intercept, no linear term) over the bins from
    `lo` to `x_max` (1 mm)."""
    xb = np.arange(round(lo / BIN), round(x_max / BIN) + 1) * BIN
    fb = np.array([force(float(x)) for x in xb])
    c, *_ = np.linalg.lstsq((xb * xb)[:, None], fb, rcond=None)
    return float(c[0])


def test_square_rate_is_numpy_least_squares_over_the_shallow_bins():
    e = ElasticShare(0.0, 0.1, margin=0.01, min_depth=0.005)
    rng = np.random.default_rng(5)
    xs = rng.uniform(0.0, 0.06, 200)
    fs = 50.0 * xs * xs + rng.normal(0, 0.01, 200) + np.where(xs > 0.03, 8 * (xs - 0.03), 0)
    for x, f in zip(xs, fs, strict=True):
        e.add(float(x), 0.02, float(f))
    b = np.round(xs / BIN).astype(int)
    sel = (b * BIN >= 0.005) & (b <= 37)        # 10 mm shallower than 47 mm: bins to 37
    xb = b[sel] * BIN
    c, *_ = np.linalg.lstsq((xb * xb)[:, None], fs[sel], rcond=None)
    assert e.square_rate(0.047) == pytest.approx(float(c[0]), rel=1e-9)
    # continuous in x between bins (linear in the running sums)
    r = [e.square_rate(0.047 + 1e-5 * i) for i in range(101)]
    assert max(abs(b2 - a) for a, b2 in zip(r, r[1:], strict=False)) < 0.05 * abs(r[0])


def test_a_square_law_has_no_square_excess_where_the_line_reads_it_as_elastic():
    e = _fed(_square)
    for x in (0.04, 0.048, 0.056):
        f = _square(x)
        assert e.square_rate(x) == pytest.approx(CQ, rel=1e-9)
        assert e.square_excess(x, f) == pytest.approx(0.0, abs=1e-12)
        # the line through the entry (`share`) reads much of it as a wall
        assert e.share(x, f) > 0.3


def test_a_wall_above_linear_friction_keeps_a_lower_bound_of_its_force():
    e = _fed(_wall)
    x = 0.055                   # the trend's bins end at 40 mm: friction alone there
    f = _wall(x)
    wall = WALL[1] * (x - WALL[0])
    c = _c_ref(_wall, x - 0.015)
    assert e.square_rate(x) == pytest.approx(c, rel=1e-9)
    assert e.square_excess(x, f) == pytest.approx(f - c * x * x, rel=1e-9)
    # the square law is the steepest friction growth: what is above it is below the wall's
    # force and a good part of it
    assert 0.4 * wall < e.square_excess(x, f) < wall
    # friction alone, linear: nothing above the square law fitted to it
    lin = _fed(lambda x: MU * x)
    assert lin.square_excess(0.05, MU * 0.05) == 0.0
    # a pulling force: nothing
    assert e.square_excess(x, -f) == 0.0


def test_square_excess_fades_in_with_the_trend():
    e = ElasticShare(0.0, 0.1)              # margin 15 mm, min_bins 3
    for x in (0.010, 0.011, 0.012):
        e.add(x, 0.01, MU * x)
    # 26 mm: only bins 10 and 11 are 15 mm shallower: no trend yet
    assert e.square_excess(0.026, 0.5) == 0.0
    assert e.square_rate(0.0265) is None    # the trend half faded in: no rate yet
    full = e.square_excess(0.0275, 0.5)
    assert full > 0.2
    xs = [0.026 + 1e-5 * i for i in range(151)]
    v = [e.square_excess(x, 0.5) for x in xs]
    assert max(abs(b - a) for a, b in zip(v, v[1:], strict=False)) < 0.02 * full
    assert 0.4 * full < e.square_excess(0.0265, 0.5) < 0.6 * full


def _model(force, nodes=17):
    """Insertion-only identification: all of the static force friction (S = 0)."""
    xs = [0.005 * i for i in range(nodes)]
    return Impedance(0.0, 0.0, 0.0, 0.0, x0=0.0, dx=0.005, sigma=3e-4, beta=0.0,
                     S=[0.0] * nodes, F=[force(x) for x in xs], B=[0.0] * nodes,
                     C=[0.0] * nodes)


def test_elastic_keep_with_the_square_floor():
    x = 0.055
    za = (1.0, 1.0)
    # a wall: with a small gain the floor decides (1 - excess / f_ins)
    m, e = _model(_wall), _fed(_wall)
    f_ins = m.force_z(x, 0.0, 0.0, za)
    ex = e.square_excess(x, f_ins)
    assert ex > 0.1
    assert elastic_keep(m, x, za, Support(0.0, 0.1), e, 0.05) == pytest.approx(
        1.0 - 0.05 * e.share(x, f_ins))
    assert elastic_keep(m, x, za, Support(0.0, 0.1), e, 0.05, True) == pytest.approx(
        1.0 - ex / f_ins)
    # a square law: the floor adds nothing
    m, e = _model(_square), _fed(_square)
    for g in (0.05, 0.5):
        assert elastic_keep(m, x, za, Support(0.0, 0.1), e, g, True) == elastic_keep(
            m, x, za, Support(0.0, 0.1), e, g)


def _inserted(force, **kw):
    """A renderer fed the insertion from 10 to 56 mm at 10 mm/s (a model per 0.5 mm)."""
    kw.setdefault('elastic_hinge', None)     # the fitted wall's keep: test_wall_fit.py
    return insert(ImaRenderer(blend_time=0.0, max_rate=1e9, **kw), _model(force), force)




def test_the_renderer_keeps_the_force_above_the_square_law_at_a_first_reversal():
    assert ELASTIC_SQUARE is True       # the default since the fourteenth round
    x = 0.054
    off = pull_back(_inserted(_wall, elastic_gain=0.05, elastic_square=False))
    # the thirteenth round's floor (no band: test_square_band.py)
    ima = _inserted(_wall, elastic_gain=0.05, elastic_square=True, square_sigmas=0.0)
    on = pull_back(ima)
    f_ins = _wall(x)
    ex = ima.elastic.square_excess(x, f_ins)
    assert ex > 0.1
    assert on == pytest.approx(-f_ins + 2.0 * ex, abs=2e-3)
    assert on > off + 0.15
    # the square law: the same force with and without
    assert pull_back(_inserted(_square, elastic_square=True)) == pytest.approx(
        pull_back(_inserted(_square, elastic_square=False)), abs=1e-12)


def test_elastic_square_must_be_a_bool():
    with pytest.raises(ValueError, match='elastic_square'):
        ImaRenderer(elastic_square='yes')
    with pytest.raises(ValueError, match='elastic_square'):
        ImaRenderer(elastic_square=math.nan)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.floats(0.0, 0.08), st.floats(-0.02, 0.05), st.booleans()),
                min_size=1, max_size=80))
def test_the_running_sums_extended_on_demand_equal_one_pass(steps):
    """ElasticShare keeps its running sums valid below the first bin an anchor changed and
    extends them only as far as a query reads: after any mix of anchors and queries, every
    answer is exactly that of a fresh ElasticShare given the same anchors and asked once."""
    live = ElasticShare(square_sigmas=2.0)
    seen = []
    for x, f, query in steps:
        if query:
            fresh = ElasticShare(square_sigmas=2.0)
            for a in seen:
                fresh.add(*a)
            for q in (x, x + 0.02, 0.06):
                assert live.rate(q) == fresh.rate(q)
                assert live.square_scatter(q) == fresh.square_scatter(q)
                assert live.square_excess(q, 0.3) == fresh.square_excess(q, 0.3)
        else:
            a = (x, 0.01, f)
            if live.add(*a):
                seen.append(a)

"""Issue 12, third round: the renderer's data-support map (`support.Support`), hand-checked."""
import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from impedance_master.support import BIN, DepthSlope, Support


def test_one_anchor_spreads_a_triangle_over_its_width_in_its_direction_only():
    s = Support(0.0, 0.1, width=0.003, n_half=2.0)
    assert s.add(0.05, 0.01)
    assert s.count(0.05, 1.0) == pytest.approx(1.0)
    assert s.count(0.05 + BIN, 1.0) == pytest.approx(0.75)
    assert s.count(0.05 - 3 * BIN, 1.0) == pytest.approx(0.25)
    assert s.count(0.05 + 4 * BIN, 1.0) == 0.0                 # beyond the width
    assert s.count(0.05, -1.0) == 0.0                           # the other direction: none
    assert s.count(0.05 + 0.5 * BIN, 1.0) == pytest.approx(0.875)   # linear between bins
    assert s.anywhere(0.05) == pytest.approx(1.0 / 3.0)             # n / (n + n_half)
    assert s.nearest(0.05, 1.0) is None                             # 1 < n_half: not seen
    s.add(0.05, -0.02)
    assert s.anywhere(0.05) == pytest.approx(0.5)
    assert s.count(0.05, -1.0) == pytest.approx(1.0)


def test_nearest_seen_depth_per_direction_and_in_either():
    s = Support(0.0, 0.1, width=0.001, n_half=1.5)   # kernel: 1/2, 1, 1/2
    for _ in range(2):
        s.add(0.020, 0.01)                           # bin 20: 2, bins 19, 21: 1
        s.add(0.060, -0.01)
    assert s.nearest(0.0, 1.0) == pytest.approx(0.020)
    assert s.nearest(0.05, 1.0) == pytest.approx(0.020)
    assert s.nearest(0.05, -1.0) == pytest.approx(0.060)
    assert s.nearest_any(0.035) == pytest.approx(0.020)
    assert s.nearest_any(0.045) == pytest.approx(0.060)
    s2 = Support(0.0, 0.1, width=0.001, n_half=1.5, min_depth=0.03)
    s2.add(0.020, 0.01)
    s2.add(0.020, 0.01)
    assert s2.nearest_any(0.02) is None              # shallower than min_depth: never seen


def test_anchors_at_rest_or_not_finite_are_not_counted_and_ends_clamp():
    s = Support(0.0, 0.1, min_speed=0.001)
    assert not s.add(0.05, 0.0005)
    assert not s.add(math.nan, 0.01)
    assert s.n == 0 and s.count(0.05, 1.0) == 0.0
    assert s.add(-1.0, 0.01)                                    # below the range: first bin
    assert s.count(0.0, 1.0) == pytest.approx(1.0)
    assert s.count(-5.0, 1.0) == pytest.approx(1.0)
    assert s.add(7.0, -0.01)                                    # above: last bin
    assert s.count(7.0, -1.0) == pytest.approx(1.0)


def test_bad_arguments_name_themselves():
    with pytest.raises(ValueError, match='width'):
        Support(width=0.0)
    with pytest.raises(ValueError, match='n_half'):
        Support(n_half=-1.0)
    with pytest.raises(ValueError, match='x_lo'):
        Support(0.1, 0.0)


@given(st.lists(st.tuples(st.floats(-0.1, 0.3), st.floats(-0.1, 0.1)), max_size=30),
       st.floats(-0.1, 0.3))
def test_support_is_in_unit_interval_grows_with_data_and_nearest_is_seen(anchors, x):
    s = Support(-0.07, 0.25, n_half=3.0)
    before = s.anywhere(x)
    for a in anchors:
        s.add(*a)
        now = s.anywhere(x)
        assert 0.0 <= now < 1.0 and now >= before - 1e-15
        before = now
    xs = s.nearest_any(x)
    if xs is not None:
        assert xs >= s.min_depth
        assert max(s.count(xs, 1.0), s.count(xs, -1.0)) >= s.n_half - 1e-9


def test_bracket_is_the_seen_depths_around_x_in_either_direction():
    s = Support(0.0, 0.1, width=0.001, n_half=1.5)   # kernel: 1/2, 1, 1/2
    for _ in range(2):
        s.add(0.020, 0.01)                           # bin 20: 2 (seen), 19, 21: 1
        s.add(0.060, -0.01)                          # the same at 60 mm, retracting
    assert s.bracket(0.04) == pytest.approx((0.020, 0.060))
    assert s.bracket(0.020) == pytest.approx((0.020, 0.020))   # on a seen bin
    lo, hi = s.bracket(0.01)
    assert lo is None and hi == pytest.approx(0.020)
    lo, hi = s.bracket(0.09)
    assert lo == pytest.approx(0.060) and hi is None
    assert Support().bracket(0.05) == (None, None)


@given(st.lists(st.tuples(st.floats(0.0, 0.08), st.floats(-0.05, 0.05)), max_size=30),
       st.floats(-0.01, 0.1))
def test_bracket_holds_x_between_neighbouring_seen_depths(anchors, x):
    s = Support(-0.07, 0.25, n_half=1.0)
    for a in anchors:
        s.add(*a)
    lo, hi = s.bracket(x)
    seen = sorted(set(s._seen[0]) | set(s._seen[1]))
    assert lo == max([b for b in seen if b <= x], default=None)
    assert hi == min([b for b in seen if b >= x], default=None)


# ---------------------------------------------------------------- fourth round: DepthSlope

def test_depth_slope_of_anchors_on_a_line_is_the_line_and_per_direction():
    s = DepthSlope(length=0.005, min_spread=0.001)
    for i in range(11):                                   # inserting 40 -> 50 mm
        x = 0.040 + 0.001 * i
        assert s.add(x, 0.02, 0.1 + 8.0 * x)
    assert s.slope(1.0) == pytest.approx(8.0)
    assert s.slope(-1.0) is None                          # nothing seen retracting
    for i in range(6):                                    # retracting 50 -> 45 mm
        x = 0.050 - 0.001 * i
        assert s.add(x, -0.02, -0.3 - 2.0 * x, z1=-1.0)
    assert s.slope(-1.0) == pytest.approx(-2.0)
    assert s.slope(1.0) == pytest.approx(8.0)             # the inserting line unchanged


def test_depth_slope_weights_hand_checked():
    """Three anchors 1 mm apart with length 1 mm: weights e^-2, e^-1, 1 (path since)."""
    s = DepthSlope(length=0.001, min_spread=1e-4)
    pts = [(0.010, 0.0), (0.011, 0.010), (0.012, 0.040)]
    for x, f in pts:
        s.add(x, 0.01, f)
    w = [math.exp(-2.0), math.exp(-1.0), 1.0]
    W = sum(w)
    mx = sum(wi * x for wi, (x, _) in zip(w, pts, strict=True)) / W
    mf = sum(wi * f for wi, (_, f) in zip(w, pts, strict=True)) / W
    sxy = sum(wi * (x - mx) * (f - mf) for wi, (x, f) in zip(w, pts, strict=True))
    sxx = sum(wi * (x - mx) ** 2 for wi, (x, _) in zip(w, pts, strict=True))
    assert s.slope(1.0) == pytest.approx(sxy / sxx, rel=1e-6)
    assert 10.0 < s.slope(1.0) < 30.0                     # between the two chords' 10 and 30


def test_depth_slope_skips_rest_reversal_transitions_nonfinite_and_one_depth():
    s = DepthSlope(min_speed=0.005, min_state=0.95, min_spread=0.001)
    assert not s.add(0.04, 0.001, 0.2)                    # slower than min_speed
    assert not s.add(0.04, 0.02, 0.2, z1=0.5)             # friction state still turning
    assert not s.add(0.04, -0.02, 0.2, z1=0.99)           # retracting with z1 still +
    assert not s.add(math.nan, 0.02, 0.2)
    assert not s.add(0.04, 0.02, math.inf)
    assert s.slope(1.0) is None and s.slope(-1.0) is None
    for _ in range(5):
        s.add(0.04, 0.02, 0.2)                            # one depth only: no slope
    assert s.slope(1.0) is None
    with pytest.raises(ValueError, match='length'):
        DepthSlope(length=0.0)
    with pytest.raises(ValueError, match='min_spread'):
        DepthSlope(min_spread=-1.0)


@given(st.lists(st.floats(0.0, 0.2), min_size=2, max_size=30), st.floats(-50.0, 50.0),
       st.floats(-1.0, 1.0))
def test_depth_slope_recovers_any_line_whatever_the_path(xs, b, a):
    s = DepthSlope(length=0.005, min_spread=1e-4)
    for x in xs:
        s.add(x, 0.01, a + b * x)
    got = s.slope(1.0)
    if got is not None:
        assert got == pytest.approx(b, abs=1e-6 + 1e-6 * abs(b))

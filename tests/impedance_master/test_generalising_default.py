"""Issue 12's second to fourth rounds: the renderer's 'local' anchor correction, its
weighing by the data support and the measured slope beyond the data (the model's own
slope capped there: eighth round), the default (hand-checked values)."""
import math

import pytest

from impedance_master import ImaRenderer, Impedance
from impedance_master.impedance import steady_states
from impedance_master.anchoring import SIGN_BAND, measured_slope
from impedance_master.rendering import (LOCAL_ANCHOR_LENGTH, MAX_MODEL_SLOPE, MAX_SLOPE,
                                        SUPPORT_HALF)


def _anchored_model(miss=0.1, x=0.03, xd=0.01):
    """A linear model with an anchor at (x, xd) where the measurement was `miss` N above
    the model."""
    imp = Impedance(0.0, 2.0, 5.0, 0.01)
    z1, z2 = steady_states(xd, imp.v_s, imp.beta)
    f = imp.force(x, xd, 0.0) + miss
    return Impedance(0.0, 2.0, 5.0, 0.01, anchor=(x, xd, 0.0, z1, z2, f, 0.0))


def _render_unsupported(imp, state, **kw):
    return _render(imp, state, support_half=None, **kw)


def _render(imp, state, **kw):
    ima = ImaRenderer(blend_time=0.0, max_rate=1e9, **kw)
    assert ima.set_impedance(imp)
    return ima.desired_force(*state)


def test_local_anchor_corrects_near_the_anchor_and_fades_with_depth_and_reversal():
    """The second round's 'local' correction alone (support off: support_half=None)."""
    imp = _anchored_model(miss=0.1)
    assert ImaRenderer().anchoring == 'local'               # the default
    assert ImaRenderer().anchor_length == LOCAL_ANCHOR_LENGTH == 0.005
    _render = _render_unsupported
    at = (0.03, 0.01, 0.0)
    assert _render(imp, at) == pytest.approx(imp.force(*at) + 0.1)     # the measured force
    near = (0.035, 0.01, 0.0)                                           # one length deeper
    assert _render(imp, near) == pytest.approx(imp.force(*near) + 0.1 * math.exp(-1.0))
    far = (0.07, 0.01, 0.0)                                             # 8 lengths: the model
    assert _render(imp, far) == pytest.approx(imp.force(*far), abs=1e-4)
    back = (0.03, -0.01, 0.0)        # reversed at the anchor's depth: half of the miss at most
    z1 = math.tanh(0.01 / imp.v_s)
    want = imp.force(*back) + 0.1 * max(0.0, 1.0 - 0.5 * abs(-z1 - z1))
    assert _render(imp, back) == pytest.approx(want)
    assert abs(_render(imp, back) - imp.force(*back)) < 0.001


def test_other_anchorings_render_the_model_or_the_anchored_baseline():
    imp = _anchored_model(miss=0.1)
    far = (0.07, -0.01, 0.0)
    assert _render(imp, far, anchoring='none') == pytest.approx(imp.force(*far))
    assert _render(imp, far, anchoring='full') == pytest.approx(imp.force(*far) + 0.1)
    no_anchor = Impedance(0.0, 2.0, 5.0, 0.01)
    at = (0.03, 0.01, 0.0)
    assert _render(no_anchor, at) == pytest.approx(no_anchor.force(*at))
    with pytest.raises(ValueError, match='anchor_length'):
        ImaRenderer(anchor_length=-1.0)


def test_without_data_support_the_default_renders_the_anchored_force():
    """One model (one anchor): no depth has support, so the anchor's miss is kept whole at
    any distance (the anchored baseline), not faded to the model's guess."""
    imp = _anchored_model(miss=0.1)
    assert ImaRenderer().support is not None and ImaRenderer().support.n_half == SUPPORT_HALF
    far = (0.07, 0.01, 0.0)
    assert _render(imp, far) == pytest.approx(imp.force(*far) + 0.1)
    assert _render(imp, far, anchoring='none') == pytest.approx(imp.force(*far))


def _learned(k, offset=0.05, miss=0.02, lo=0.02, hi=0.04, xd=0.01):
    """A renderer that has received models (a linear model k x + offset + 2 x', the
    measurement `miss` above it, and so the identifier's low-passed residual too: a held
    model renders the same miss) anchored every 0.5 mm from lo to hi m, inserting."""
    ima = ImaRenderer(blend_time=0.0, max_rate=1e9)
    imp = None
    for x in [lo + 0.0005 * i for i in range(int(round((hi - lo) / 0.0005)) + 1)]:
        base = Impedance(0.0, 2.0, k, offset)
        z1, z2 = steady_states(xd, base.v_s, base.beta)
        imp = Impedance(0.0, 2.0, k, offset,
                        anchor=(x, xd, 0.0, z1, z2, base.force(x, xd, 0.0) + miss, miss))
        assert ima.set_impedance(imp)
        ima.desired_force(x, xd, 0.0)
    return ima, imp


def test_supported_depths_render_the_model_with_the_local_correction():
    ima, imp = _learned(k=5.0, miss=0.02)
    assert ima.support.anywhere(0.03) > 0.7       # 8 anchors near: 8 / (8 + 3)
    x = 0.03                                    # 10 mm from the last anchor (40 mm)
    c = ima.support.anywhere(x)
    g = 1.0 - (1.0 - (1.0 - c) ** 2) * (1.0 - math.exp(-0.01 / LOCAL_ANCHOR_LENGTH))
    assert ima.desired_force(x, 0.01, 0.0) == pytest.approx(imp.force(x, 0.01, 0.0)
                                                            + 0.02 * g)


def test_beyond_the_data_the_model_is_extended_not_its_prior_guess():
    # deeper: a model falling with depth (k < 0) is held at the edge of the data (never
    # toward a smaller |force|), the anchor's miss kept whole
    ima, imp = _learned(k=-5.0, offset=0.5)
    xs = ima.support.nearest_any(0.06)
    assert 0.039 <= xs <= 0.041
    assert ima.support.anywhere(0.06) == 0.0
    assert ima.desired_force(0.06, 0.01, 0.0) == pytest.approx(imp.force(xs, 0.01, 0.0)
                                                               + 0.02)
    # a model rising with depth is extended with its own slope: the model itself
    ima, imp = _learned(k=5.0)
    assert ima.desired_force(0.06, 0.01, 0.0) == pytest.approx(imp.force(0.06, 0.01, 0.0)
                                                               + 0.02)
    # shallower than the data: in proportion to the depth
    ima, imp = _learned(k=5.0)
    xs = ima.support.nearest_any(0.005)
    assert 0.019 <= xs <= 0.021
    assert ima.support.anywhere(0.005) == 0.0
    want = imp.force(xs, 0.01, 0.0) * 0.005 / xs + 0.02
    assert ima.desired_force(0.005, 0.01, 0.0) == pytest.approx(want)


# ------------------------------------------- fourth round: the measured slope beyond the data

def _learned_rising(rise, k=0.0, lo=0.02, hi=0.04, xd=0.01, **kw):
    """A renderer fed models (k x + 0.05 + 2 x') whose anchors' measured force rises
    `rise` N/m faster with depth than the model's (a wall the tables flatten)."""
    ima = ImaRenderer(blend_time=0.0, max_rate=1e9, **kw)
    imp = None
    for x in [lo + 0.0005 * i for i in range(int(round((hi - lo) / 0.0005)) + 1)]:
        base = Impedance(0.0, 2.0, k, 0.05)
        z1, z2 = steady_states(xd, base.v_s, base.beta)
        f = base.force(x, xd, 0.0) + rise * (x - lo)
        imp = Impedance(0.0, 2.0, k, 0.05, anchor=(x, xd, 0.0, z1, z2, f, 0.0))
        assert ima.set_impedance(imp)
        ima.desired_force(x, xd, 0.0)
    return ima, imp


def test_beyond_the_data_a_flat_model_is_extended_with_the_measured_slope():
    ima, imp = _learned_rising(rise=20.0)
    assert ima.depth_slope.slope(1.0) == pytest.approx(20.0)
    xs = ima.support.nearest_any(0.06)
    miss = 20.0 * (0.04 - 0.02)                   # the last anchor's miss, kept whole there
    want = imp.force(xs, 0.01, 0.0) + 20.0 * (0.06 - xs) + miss
    assert ima.desired_force(0.06, 0.01, 0.0) == pytest.approx(want)
    # the third round (slope_length=None): the model's own (flat) slope
    old, imp = _learned_rising(rise=20.0, slope_length=None)
    assert old.depth_slope is None
    assert old.desired_force(0.06, 0.01, 0.0) == pytest.approx(imp.force(xs, 0.01, 0.0) + miss)


def test_the_measured_slope_is_capped_and_never_flattens_a_steeper_model():
    ima, imp = _learned_rising(rise=200.0, lo=0.036)      # a local bump, not a wall
    assert ima.max_slope == MAX_SLOPE == 50.0
    xs = ima.support.nearest_any(0.055)
    miss = 200.0 * (0.04 - 0.036)
    want = imp.force(xs, 0.01, 0.0) + MAX_SLOPE * (0.055 - xs) + miss
    assert want < ima.limit
    assert ima.desired_force(0.055, 0.01, 0.0) == pytest.approx(want)
    # the model rises 10 N/m, the measurement 10 - 8 = 2 N/m: the model's slope stays
    ima, imp = _learned_rising(rise=-8.0, k=10.0)
    xs = ima.support.nearest_any(0.06)
    miss = -8.0 * (0.04 - 0.02)
    assert ima.desired_force(0.06, 0.01, 0.0) == pytest.approx(
        imp.force(0.06, 0.01, 0.0) + miss)
    with pytest.raises(ValueError, match='max_slope'):
        ImaRenderer(max_slope=0.0)
    with pytest.raises(ValueError, match='slope_length'):
        ImaRenderer(slope_length=-1.0)


# ------------------------------------------- eighth round: the model's own slope is capped

def test_beyond_the_data_a_steep_model_slope_is_capped_and_a_steep_measured_one_is_not():
    assert ImaRenderer().max_model_slope == MAX_MODEL_SLOPE == 10.0
    # the model rises 30 N/m at the edge of its data (its fit of a bump), the measured
    # force only 30 - 25 = 5 N/m: the extension rises at the cap, 10 N/m
    ima, imp = _learned_rising(rise=-25.0, k=30.0)
    assert ima.depth_slope.slope(1.0) == pytest.approx(5.0)
    xs = ima.support.nearest_any(0.06)
    assert ima.support.anywhere(0.06) == 0.0
    miss = -25.0 * (0.04 - 0.02)
    want = imp.force(xs, 0.01, 0.0) + MAX_MODEL_SLOPE * (0.06 - xs) + miss
    assert want < ima.limit
    assert ima.desired_force(0.06, 0.01, 0.0) == pytest.approx(want)
    # uncapped (the seventh round): the model's own 30 N/m
    old, imp = _learned_rising(rise=-25.0, k=30.0, max_model_slope=None)
    assert old.max_model_slope == math.inf
    assert old.desired_force(0.06, 0.01, 0.0) == pytest.approx(
        imp.force(xs, 0.01, 0.0) + 30.0 * (0.06 - xs) + miss)
    # a MEASURED slope steeper than the cap (a wall) still extends the force: 40 N/m
    ima, imp = _learned_rising(rise=30.0, k=10.0)
    assert ima.depth_slope.slope(1.0) == pytest.approx(40.0)
    miss = 30.0 * (0.04 - 0.02)
    want = imp.force(xs, 0.01, 0.0) + 40.0 * (0.055 - xs) + miss
    assert want < ima.limit
    assert ima.desired_force(0.055, 0.01, 0.0) == pytest.approx(want)
    # retracting past the data with a force below 0: the model's fall is capped alike
    assert measured_slope(None, MAX_SLOPE, -30.0, False, MAX_MODEL_SLOPE) == -10.0
    assert measured_slope(None, MAX_SLOPE, 7.0, True, MAX_MODEL_SLOPE) == 7.0
    with pytest.raises(ValueError, match='max_model_slope'):
        ImaRenderer(max_model_slope=0.0)


# ------------------------------------------- fifth round: continuous across a gap in the data

def _learned_gap(miss=0.02, xd=0.01):
    """A renderer with data at 10-13 mm and 25-28 mm (inserting), none between, the last
    anchor at 28 mm; the model k x + offset + 2 x' with a large offset (the old extension
    from the NEAREST seen depth jumped at the gap's middle: in proportion to the depth from
    25 mm, with the slope from 13 mm). The low-passed residual is the miss too."""
    ima = ImaRenderer(blend_time=0.0, max_rate=1e9)
    base = Impedance(0.0, 2.0, 5.0, 0.2)
    z1, z2 = steady_states(xd, base.v_s, base.beta)
    imp = None
    for x in [0.010 + 0.0005 * i for i in range(7)] + [0.025 + 0.0005 * i for i in range(7)]:
        imp = Impedance(0.0, 2.0, 5.0, 0.2,
                        anchor=(x, xd, 0.0, z1, z2, base.force(x, xd, 0.0) + miss, miss))
        assert ima.set_impedance(imp)
        ima.desired_force(x, xd, 0.0)
    return ima, imp


def test_across_a_gap_in_the_data_the_rendered_force_is_continuous():
    ima, imp = _learned_gap()
    lo, hi = ima.support.bracket(0.019)
    assert lo < 0.015 and hi > 0.023                  # a gap of about 10 mm
    xs = [0.0135 + 1e-5 * i for i in range(1101)]     # 13.5 to 24.5 mm, 0.01 mm steps
    f = [ima.desired_force(x, 0.01, 0.0) for x in xs]
    # the model rises 5 N/m (0.05 mN per step); the anchor's correction grows toward 28 mm
    assert max(abs(b - a) for a, b in zip(f, f[1:], strict=False)) < 2e-4
    # a linear model interpolated between the edges of the gap is itself: the model plus
    # the anchor's miss, kept with the support's weight
    x = 0.019
    c = ima.support.anywhere(x)
    g = 1.0 - (1.0 - (1.0 - c) ** 2) * (1.0 - math.exp(-abs(x - 0.028) / LOCAL_ANCHOR_LENGTH))
    assert ima.desired_force(x, 0.01, 0.0) == pytest.approx(imp.force(x, 0.01, 0.0)
                                                            + 0.02 * g)


def test_beyond_the_data_the_extension_is_continuous_where_the_edge_force_crosses_zero():
    # the model's force at the edge lo of the data is 2 x' (drag; 5 N/m (x - lo)): its sign,
    # which decides whether the model is extended with the rising slope (a wall, friction
    # growing) or held, changes with the master's velocity; the old hard switch stepped
    # 5 N/m x 20 mm = 0.1 N at 60 mm as x' crossed 0
    lo = _learned(k=5.0)[0].support.bracket(0.06)[0]
    assert 0.039 <= lo <= 0.042
    ima, imp = _learned(k=5.0, offset=-5.0 * lo)
    assert ima.support.bracket(0.06)[0] == lo and ima.support.anywhere(0.06) == 0.0
    assert SIGN_BAND == 0.01
    # outside the band: pushing (2 x' >= 10 mN) the model's rise, pulling held at the edge
    assert ima.desired_force(0.06, 0.006, 0.0) == pytest.approx(
        imp.force(0.06, 0.006, 0.0) + 0.02)
    assert ima.desired_force(0.06, -0.006, 0.0) == pytest.approx(
        imp.force(lo, -0.006, 0.0) + 0.02)
    # inside: blended, continuous
    f = [ima.desired_force(0.06, -0.006 + 1e-5 * i, 0.0) for i in range(1201)]
    assert max(abs(b - a) for a, b in zip(f, f[1:], strict=False)) < 5e-4
    assert f[600] == pytest.approx(0.5 * 5.0 * (0.06 - lo) + 0.02)      # x' = 0: u = 1/2

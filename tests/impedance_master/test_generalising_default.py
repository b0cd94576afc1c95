"""Issue 12's second round: the renderer's 'local' anchor correction, the default
(hand-checked values)."""
import math

import pytest

from impedance_master import ImaRenderer, Impedance
from impedance_master.impedance import steady_states
from impedance_master.rendering import LOCAL_ANCHOR_LENGTH


def _anchored_model(miss=0.1, x=0.03, xd=0.01):
    """A linear model with an anchor at (x, xd) where the measurement was `miss` N above
    the model."""
    imp = Impedance(0.0, 2.0, 5.0, 0.01)
    z1, z2 = steady_states(xd, imp.v_s, imp.beta)
    f = imp.force(x, xd, 0.0) + miss
    return Impedance(0.0, 2.0, 5.0, 0.01, anchor=(x, xd, 0.0, z1, z2, f, 0.0))


def _render(imp, state, **kw):
    ima = ImaRenderer(blend_time=0.0, max_rate=1e9, **kw)
    assert ima.set_impedance(imp)
    return ima.desired_force(*state)


def test_local_anchor_corrects_near_the_anchor_and_fades_with_depth_and_reversal():
    imp = _anchored_model(miss=0.1)
    assert ImaRenderer().anchoring == 'local'               # the default
    assert ImaRenderer().anchor_length == LOCAL_ANCHOR_LENGTH == 0.005
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

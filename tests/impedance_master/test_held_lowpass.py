"""Issue 12, sixth round: while the model is held (a link outage) the anchor's miss moves
from the latest sample's to the identifier's low-passed one, and back after (ImaRenderer
held_lowpass), hand-checked."""
import pytest

from impedance_master import ImaRenderer, Impedance
from impedance_master.impedance import steady_states
from impedance_master.rendering import HELD_LOWPASS

X, XD = 0.03, 0.01


def _model(sample_miss=0.03, lowpass_miss=0.01):
    base = Impedance(0.0, 2.0, 5.0, 0.01)
    z1, z2 = steady_states(XD, base.v_s, base.beta)
    f = base.force(X, XD, 0.0) + sample_miss
    return base, Impedance(0.0, 2.0, 5.0, 0.01, anchor=(X, XD, 0.0, z1, z2, f, lowpass_miss))


def test_a_held_model_moves_to_the_lowpassed_miss_and_back_continuously():
    base, imp = _model()
    ima = ImaRenderer(blend_time=0.0, max_rate=1e9)
    assert ima.held_lowpass == HELD_LOWPASS == 0.3
    assert ima.set_impedance(imp)
    f0 = base.force(X, XD, 0.0)
    out = [ima.desired_force(X, XD, 0.0) - f0 for _ in range(700)]    # 0.7 s, not re-sent
    assert out[50] == pytest.approx(0.03)               # fresh (age <= stale_time 0.1 s)
    assert out[95] == pytest.approx(0.03)
    assert out[249] == pytest.approx(0.02, abs=1e-4)     # 0.15 s into the 0.3 s blend: half
    assert out[-1] == pytest.approx(0.01)                # held: the low-passed miss
    assert max(abs(b - a) for a, b in zip(out, out[1:], strict=False)) < 0.02 / 300 + 1e-9
    # the link is back: the same model again; back to the latest sample's miss over 0.3 s
    back = []
    for _ in range(400):
        assert ima.set_impedance(imp)
        back.append(ima.desired_force(X, XD, 0.0) - f0)
    assert back[149] == pytest.approx(0.02, abs=1e-4)
    assert back[-1] == pytest.approx(0.03)
    assert max(abs(b - a) for a, b in zip(back, back[1:], strict=False)) < 0.02 / 300 + 1e-9


def test_a_new_model_after_an_outage_is_taken_over_bumplessly_with_the_same_blend():
    base, imp = _model()
    ima = ImaRenderer(blend_time=0.0, max_rate=1e9)
    ima.set_impedance(imp)
    f = [ima.desired_force(X, XD, 0.0) for _ in range(500)]
    _, new = _model(sample_miss=0.05, lowpass_miss=0.02)
    ima.set_impedance(new)                      # arrives held-blended: the same q at the switch
    g = ima.desired_force(X, XD, 0.0)
    assert g == pytest.approx(base.force(X, XD, 0.0) + 0.02, abs=1e-3)
    assert abs(g - f[-1]) < 0.011


def test_off_keeps_the_sample_miss_and_bad_values_name_themselves():
    base, imp = _model()
    ima = ImaRenderer(blend_time=0.0, max_rate=1e9, held_lowpass=None)
    ima.set_impedance(imp)
    out = [ima.desired_force(X, XD, 0.0) for _ in range(700)]
    assert out[-1] == pytest.approx(base.force(X, XD, 0.0) + 0.03)
    with pytest.raises(ValueError, match='held_lowpass'):
        ImaRenderer(held_lowpass=0.0)

"""impedance_master.filters against exact answers: the Butterworth low-pass's steady start and
gain, the backward difference's slope (mutation sweep W20-W22: no test named the module)."""
import math

import pytest

from impedance_master.filters import Biquad, Differentiator


def test_low_pass_starts_in_steady_state():
    f = Biquad(cutoff=20.0, rate=1000.0)
    assert [f(0.7) for _ in range(50)] == pytest.approx([0.7] * 50, abs=1e-12)


@pytest.mark.parametrize('ratio, gain', [(1.0, 1.0 / math.sqrt(2.0)), (0.1, 1.0), (4.0, None)])
def test_low_pass_gain_is_butterworth(ratio, gain):
    """Steady amplitude of a sine at ratio x the cut-off: 1/sqrt(2) at the cut-off (-3 dB),
    about 1 well below; well above, the bilinear Butterworth's |H| (prewarped: the analogue
    1 / sqrt(1 + (tan(pi f / fs) / tan(pi fc / fs))^4))."""
    rate, fc = 1000.0, 20.0
    fs = ratio * fc
    f = Biquad(cutoff=fc, rate=rate)
    n = int(rate / fs * 20)
    y = [f(math.sin(2 * math.pi * fs * k / rate)) for k in range(2 * n)]
    amp = max(abs(v) for v in y[n:])
    if gain is None:
        w = math.tan(math.pi * fs / rate) / math.tan(math.pi * fc / rate)
        gain = 1.0 / math.sqrt(1.0 + w ** 4)
    assert amp == pytest.approx(gain, rel=0.01, abs=2e-3)


def test_differentiator_is_the_backward_difference_at_the_rate():
    d = Differentiator(rate=500.0)
    out = [d(0.3 + 2.5 * k / 500.0) for k in range(5)]
    assert out[0] == 0.0
    assert out[1:] == pytest.approx([2.5] * 4, rel=1e-9)

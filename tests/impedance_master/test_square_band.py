"""Issue 12, fourteenth round: the square-law floor of the elastic share counted only above
the band of the forces' disturbances (`ElasticShare` square_band, square_sigmas;
`square_scatter`: the anchors' rms scatter about the square law), against numpy least
squares on noisy streams built here."""
import math
import pathlib
import sys

import numpy as np
import pytest

from impedance_master.support import BIN, ElasticShare

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from streams import insert, pull_back  # noqa: E402

sys.path.pop(0)

CQ = 80.0            # N/m^2, friction growing with the square of the length (stribeck_kv)


def _noisy(force, sd, seed, lo=0.008, hi=0.056, n=400, **kw):
    """An ElasticShare fed n inserting anchors at random depths in [lo, hi] whose force is
    force(x) + N(0, sd^2); returns it with the depths and forces."""
    e = ElasticShare(0.0, 0.1, **kw)
    rng = np.random.default_rng(seed)
    xs = rng.uniform(lo, hi, n)
    fs = np.array([force(float(x)) for x in xs]) + rng.normal(0.0, sd, n)
    for x, f in zip(xs, fs, strict=True):
        assert e.add(float(x), 0.01, float(f))
    return e, xs, fs


def _ref(xs, fs, x, margin=0.015, min_depth=0.005):
    """numpy: (c, rms scatter with n - 1 degrees of freedom) of f = c x^2 through the
    entry over the anchors whose bin is at least `margin` shallower than x."""
    b = np.round(xs / BIN).astype(int)
    sel = (b * BIN >= min_depth - 1e-12) & (b <= math.floor(round((x - margin) / BIN, 9)))
    xb = b[sel] * BIN
    c, *_ = np.linalg.lstsq((xb * xb)[:, None], fs[sel], rcond=None)
    res = fs[sel] - c[0] * xb * xb
    return float(c[0]), float(np.sqrt(np.sum(res * res) / (sel.sum() - 1)))


@pytest.mark.parametrize('sd', [0.005, 0.02])
def test_square_scatter_is_the_rms_residual_about_the_numpy_fit(sd):
    e, xs, fs = _noisy(lambda x: CQ * x * x, sd, 3)
    for x in (0.030, 0.045, 0.056):
        c, s = _ref(xs, fs, x)
        assert e.square_rate(x) == pytest.approx(c, rel=1e-9)
        assert e.square_scatter(x) == pytest.approx(s, rel=1e-6)
        # the scatter of a square law is its noise
        assert 0.8 * sd < e.square_scatter(x) < 1.25 * sd


def test_square_scatter_counts_the_laws_misfit_and_is_none_without_a_law():
    # a linear friction fitted with a square law: the misfit adds to the noise
    e, xs, fs = _noisy(lambda x: 4.0 * x, 0.0, 4)
    c, s = _ref(xs, fs, 0.05)
    assert s > 0.005
    assert e.square_scatter(0.05) == pytest.approx(s, rel=1e-6)
    assert ElasticShare(0.0, 0.1).square_scatter(0.05) is None
    e = ElasticShare(0.0, 0.1)
    for x in (0.010, 0.011):
        e.add(x, 0.01, 0.1)
    assert e.square_scatter(0.04) is None        # two bins: no law yet


def test_square_excess_is_counted_above_the_band():
    sd = 0.015
    e0, xs, fs = _noisy(lambda x: CQ * x * x, sd, 7)
    x = 0.045
    c, s = _ref(xs, fs, x)
    for f in (c * x * x + 0.02, c * x * x + 0.05, c * x * x + 0.2):
        for band, k in ((0.0, 0.0), (0.03, 0.0), (0.0, 2.0), (0.01, 1.0)):
            e, _, _ = _noisy(lambda x: CQ * x * x, sd, 7, square_band=band, square_sigmas=k)
            want = max(0.0, f - c * x * x - band - k * s)
            assert e.square_excess(x, f) == pytest.approx(want, abs=1e-7)
    # the noise of a square law read as a wall without the band, not with it
    f = c * x * x + 1.5 * sd
    assert e0.square_excess(x, f) > sd
    e2, _, _ = _noisy(lambda x: CQ * x * x, sd, 7, square_sigmas=2.0)
    assert e2.square_excess(x, f) == 0.0


def test_the_scatter_band_is_continuous_in_depth():
    e, _, _ = _noisy(lambda x: CQ * x * x, 0.01, 9, square_sigmas=2.0)
    xs = [0.040 + 1e-5 * i for i in range(301)]
    v = [e.square_excess(x, 0.3) for x in xs]
    assert v[0] > 0.05
    assert max(abs(b - a) for a, b in zip(v, v[1:], strict=False)) < 1e-3


def test_bad_bands_are_named():
    for kw in ({'square_band': -0.01}, {'square_band': math.nan},
               {'square_sigmas': -1.0}, {'square_sigmas': math.inf}):
        with pytest.raises(ValueError, match=next(iter(kw))):
            ElasticShare(0.0, 0.1, **kw)


def _wall(x):
    return 4.0 * x + (20.0 * (x - 0.04) if x > 0.04 else 0.0)


def _inserted(**kw):
    """A renderer fed the insertion from 10 to 56 mm at 10 mm/s along a wall on linear
    friction (a model per 0.5 mm, insertion-only: all of its force friction)."""
    from impedance_master import ImaRenderer, Impedance
    xs = [0.005 * i for i in range(17)]
    m = Impedance(0.0, 0.0, 0.0, 0.0, x0=0.0, dx=0.005, sigma=3e-4, beta=0.0,
                  S=[0.0] * 17, F=[_wall(x) for x in xs], B=[0.0] * 17, C=[0.0] * 17)
    kw.setdefault('elastic_hinge', None)     # the fitted wall's keep: test_wall_fit.py
    return insert(ImaRenderer(blend_time=0.0, max_rate=1e9, elastic_gain=0.05,
                              elastic_square=True, **kw), m, _wall)


def test_the_renderer_counts_the_excess_above_its_band():
    from impedance_master.support import SQUARE_BAND, SQUARE_SIGMAS
    assert (SQUARE_BAND, SQUARE_SIGMAS) == (0.0, 2.0)
    x = 0.054
    f_ins = _wall(x)
    plain = _inserted(square_sigmas=0.0)
    ex0 = plain.elastic.square_excess(x, f_ins)
    assert ex0 > 0.1
    # the default: above twice the shallow forces' scatter about the law (here its misfit
    # to the linear friction)
    d = _inserted()
    sig = d.elastic.square_scatter(x)
    assert 0.001 < sig < 0.05
    assert d.elastic.square_excess(x, f_ins) == pytest.approx(ex0 - 2.0 * sig, abs=1e-9)
    assert pull_back(d) == pytest.approx(-f_ins + 2.0 * (ex0 - 2.0 * sig), abs=2e-3)
    on = _inserted(square_band=0.05, square_sigmas=0.0)
    assert (on.elastic.square_band, on.elastic.square_sigmas) == (0.05, 0.0)
    ex = on.elastic.square_excess(x, f_ins)
    assert ex == pytest.approx(ex0 - 0.05, abs=1e-9)
    # the force kept after the full reversal: the excess above the band
    assert pull_back(on) == pytest.approx(-f_ins + 2.0 * ex, abs=2e-3)
    assert pull_back(plain) == pytest.approx(-f_ins + 2.0 * ex0, abs=2e-3)
    assert _inserted(square_sigmas=2.0).elastic.square_sigmas == 2.0


def test_the_renderer_names_a_bad_band():
    from impedance_master import ImaRenderer
    with pytest.raises(ValueError, match='square_band'):
        ImaRenderer(square_band=-0.1)
    with pytest.raises(ValueError, match='square_sigmas'):
        ImaRenderer(square_sigmas=math.nan, elastic_gain=None)

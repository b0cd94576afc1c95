"""Issue 12, seventeenth round: the wall fitted to the inward forces (`wall_fit.fit_hinge`,
`ElasticShare.hinge`) and the renderer's opt-in keep of it at a first outward reversal
(`anchoring.elastic_keep(hinge_gain=...)`, `ImaRenderer(elastic_hinge=...)`, on by
default since that round), on streams
built here with known walls and friction laws."""
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from impedance_master import ImaRenderer, Impedance
from impedance_master.anchoring import elastic_keep
from impedance_master.support import HINGE_F, HINGE_GAIN, ElasticShare, Support
from impedance_master.wall_fit import Hinge, fit_hinge

X = np.arange(10, 57) * 1e-3          # the bins a 10-56 mm insertion fills (1 mm)
N = np.full(len(X), 20.0)             # anchors per bin


def _bins(f_mean, v_mean=0.01, noise=0.0, seed=0):
    """Bin sums of N anchors per bin with mean force f_mean(x) (+ the bins' noise)."""
    rng = np.random.default_rng(seed)
    f = np.array([f_mean(x) for x in X]) + rng.normal(0.0, noise, len(X))
    v = np.broadcast_to(np.asarray(v_mean, float), X.shape)
    return X, N, f * N, v * N


def _wall(x, mu=1.0, x_w=0.025, k=12.0):
    return mu * x + (k * (x - x_w) if x > x_w else 0.0)


def test_a_linear_wall_over_linear_friction_is_found_where_it_starts_and_as_stiff():
    h = fit_hinge(*_bins(_wall, noise=0.002))
    assert isinstance(h, Hinge)
    assert h.x_w == pytest.approx(0.025, abs=1.5e-3)
    assert h.k == pytest.approx(12.0, rel=0.1)
    assert h.f_ratio >= HINGE_F


@pytest.mark.parametrize('law', [lambda x: 4.0 * x, lambda x: 80.0 * x * x,
                                 lambda x: 2.0 * x + 40.0 * x * x])
def test_friction_growing_linearly_or_with_the_square_of_the_length_is_no_wall(law):
    assert fit_hinge(*_bins(law, noise=0.005, seed=3)) is None


def test_a_wall_damper_is_not_read_as_stiffness():
    """A Kelvin-Voigt wall (spring 6 N/m, damper 3 N s/m) entered at a speed rising with
    depth (the first half of a minimum-jerk stroke): the speed column takes the damper."""
    v = 0.005 + 0.04 * (X - X[0]) / (X[-1] - X[0])
    x_w, k, c = 0.022, 6.0, 3.0
    force = 80.0 * X * X + np.where(X > x_w, k * (X - x_w) + c * v, 0.0)
    rng = np.random.default_rng(1)
    f = force + rng.normal(0.0, 0.002, len(X))
    h = fit_hinge(X, N, f * N, v * N)
    assert h is not None
    assert h.k == pytest.approx(k, rel=0.25)
    assert h.x_w == pytest.approx(x_w, abs=2e-3)


@settings(max_examples=25)
@given(st.floats(0.2, 20.0))
def test_scaling_the_forces_scales_the_stiffness_and_keeps_the_onset(a):
    x, n, fs, vs = _bins(_wall, noise=0.002, seed=7)
    h1 = fit_hinge(x, n, fs, vs)
    h2 = fit_hinge(x, n, a * fs, vs)
    assert h2.x_w == h1.x_w
    assert h2.k == pytest.approx(a * h1.k, rel=1e-6)
    assert h2.f_ratio == pytest.approx(h1.f_ratio, rel=1e-6)


def test_too_few_bins_non_finite_and_mismatched_input():
    x, n, fs, vs = _bins(_wall, noise=0.002)
    assert fit_hinge(x[:9], n[:9], fs[:9], vs[:9]) is None
    bad = fs.copy()
    bad[4] = math.nan
    assert fit_hinge(x, n, bad, vs) is None
    with pytest.raises(ValueError, match='one length'):
        fit_hinge(x, n[:-1], fs, vs)
    assert fit_hinge(x, n, fs, vs, min_f=1e12) is None      # not significant enough


def _share(force, speed=0.01):
    e = ElasticShare(0.0, 0.1)
    for x in X:
        for _ in range(3):
            assert e.add(float(x), speed, force(float(x)))
    return e


def test_elastic_share_hinge_fits_its_bins_and_refits_only_after_new_anchors():
    e = _share(_wall)
    h = e.hinge(HINGE_F)
    assert h is not None and h.x_w == pytest.approx(0.025, abs=1e-3)
    assert h.k == pytest.approx(12.0, rel=1e-3)
    assert e.hinge(HINGE_F) is h                     # no new anchor: the same fit
    e.add(0.057, 0.01, _wall(0.057))
    assert e.hinge(HINGE_F) is not h                 # refitted
    assert _share(lambda x: 80.0 * x * x).hinge(HINGE_F) is None


def _friction_only(f, nodes=30):
    """A table model whose force at every depth is friction f (N), no static force."""
    return Impedance(0.0, 0.0, 0.0, 0.0, x0=0.0, dx=0.005, sigma=3e-4, beta=0.0,
                     S=[0.0] * nodes, F=[f] * nodes, B=[0.0] * nodes, C=[0.0] * nodes)


def test_elastic_keep_keeps_the_fitted_wall_only_when_asked():
    """At 56 mm of the wall stream the model splits its inserting force 0.43 N into no
    static force and friction only; the fitted wall's force 0.7 x 12 N/m x 31 mm = 0.26 N
    is kept (by its share of the flip), not kept without hinge_gain."""
    e = _share(_wall)
    x = 0.056
    f_ins = _wall(x)
    m = _friction_only(f_ins)
    sup = Support(0.0, 0.1, width=0.003, n_half=3.0)
    za = (1.0, 1.0)
    off = elastic_keep(m, x, za, sup, e, 0.0)
    on = elastic_keep(m, x, za, sup, e, 0.0, hinge_gain=0.7)
    assert off == 1.0
    kept = 0.7 * 12.0 * (x - 0.025)
    assert on == pytest.approx(1.0 - kept / f_ins, rel=0.05)
    assert 0.0 <= on < 1.0


@pytest.mark.parametrize('kw', [dict(elastic_hinge=0.0), dict(elastic_hinge=-1.0),
                                dict(elastic_hinge=math.nan), dict(hinge_f=0.0)])
def test_renderer_refuses_bad_hinge_settings(kw):
    with pytest.raises(ValueError):
        ImaRenderer(**kw)


def test_renderer_default_keeps_the_hinge_and_none_turns_it_off():
    r = ImaRenderer()
    assert r.elastic_hinge == HINGE_GAIN == 0.7 and r.hinge_f == HINGE_F
    assert ImaRenderer(elastic_hinge=None).elastic_hinge == 0.0

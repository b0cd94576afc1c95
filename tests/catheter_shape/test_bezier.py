"""Bezier fitting (thesis Eqs. 2-5) with parameter correction: exact recovery, symmetry,
the residual as a true perpendicular distance, constraints and bad input."""
import numpy as np
import pytest
from scipy.optimize import minimize_scalar
from hypothesis import given, settings, assume
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from catheter_shape import (bernstein, bezier_distance, bezier_eval, chord_length_params,
                            fit_bezier, fit_bezier_detailed, project_points)

finite = st.floats(-1.0, 1.0, allow_nan=False, allow_infinity=False)


@given(st.integers(1, 9), arrays(float, 20, elements=st.floats(0, 1)))
def test_bernstein_is_a_partition_of_unity(n, s):
    B = bernstein(s, n)
    assert B.shape == (20, n + 1)
    assert np.all(B >= -1e-15)
    np.testing.assert_allclose(B.sum(axis=1), 1.0, atol=1e-12)


def test_bernstein_cubic_matches_eq5():
    s = np.array([0.0, 0.25, 0.5, 1.0])
    lam = np.stack([(1 - s) ** 3, 3 * s * (1 - s) ** 2, 3 * s ** 2 * (1 - s), s ** 3])
    np.testing.assert_allclose(bernstein(s, 3), lam.T, atol=1e-15)


@settings(max_examples=60, deadline=None)
@given(arrays(float, (4, 3), elements=finite), st.integers(8, 60), st.integers(0, 2 ** 31 - 1))
def test_fit_at_true_parameters_returns_the_control_points(ctrl, n, seed):
    """Eq. 4 is exact: points on a cubic at known parameters give back its control points."""
    rng = np.random.default_rng(seed)
    s = np.sort(rng.random(n))
    s[0], s[-1] = 0.0, 1.0
    assume(np.min(np.diff(s)) > 1e-3)
    pts = bezier_eval(ctrl, s)
    got = fit_bezier(pts, 3, params=s, refine=0)
    np.testing.assert_allclose(got, ctrl, atol=1e-8)


def _catheter_like_ctrl(draw_vals):
    """A smooth, non-self-intersecting cubic: control polygon advancing along x."""
    dx = 0.5 * np.abs(draw_vals[:3]) + 0.5
    x = np.concatenate([[0.0], np.cumsum(dx)])
    y = np.concatenate([[0.0], draw_vals[3:6]])
    return np.stack([x, y], axis=1)


@settings(max_examples=60, deadline=None)
@given(arrays(float, 6, elements=finite), st.integers(30, 120), st.integers(0, 2 ** 31 - 1))
def test_fit_from_chord_length_recovers_a_cubic_after_correction(vals, n, seed):
    """Points exactly on a cubic at unknown (random) parameters: chord-length fitting alone
    is biased, parameter correction converges to the same curve."""
    # a (nearly) straight cubic has no unique control points (its inner ones can slide
    # along the line): bend the inner control points visibly off the chord
    ctrl = _catheter_like_ctrl(vals)
    ctrl[3, 1] = 0.5 * vals[5]
    chord = np.linalg.norm(ctrl[3] - ctrl[0])
    for i, v in ((1, vals[3]), (2, vals[4])):
        line_y = ctrl[3, 1] * ctrl[i, 0] / ctrl[3, 0]
        ctrl[i, 1] = line_y + np.copysign((0.2 + 0.3 * abs(v)) * chord, v)
    rng = np.random.default_rng(seed)
    s = np.sort(rng.random(n))
    s[0], s[-1] = 0.0, 1.0
    assume(np.min(np.diff(s)) > 1e-4)
    pts = bezier_eval(ctrl, s)
    fit = fit_bezier_detailed(pts, 3, refine=40, tol=0.0, correction='orthogonal')
    scale = np.ptp(ctrl, axis=0).max()
    assert fit.residual <= 3e-2 * fit.chord_residual + 1e-12
    # the same curve: every point of either curve lies on the other (Hausdorff distance).
    # The control points themselves are not compared: along near-reparameterisations of
    # the curve the problem is ill-conditioned (a 1e-6 change of shape moves them by 1e-1)
    ss = np.linspace(0, 1, 400)
    assert bezier_distance(fit.control_points, bezier_eval(ctrl, ss)).max() <= 1e-3 * scale
    assert bezier_distance(ctrl, bezier_eval(fit.control_points, ss)).max() <= 1e-3 * scale


@settings(max_examples=40, deadline=None)
@given(arrays(float, 6, elements=finite), st.integers(0, 2 ** 31 - 1), st.integers(1, 5))
def test_reversing_the_points_reverses_the_control_points(vals, seed, degree):
    ctrl = _catheter_like_ctrl(vals)
    rng = np.random.default_rng(seed)
    pts = bezier_eval(ctrl, np.linspace(0, 1, 80)) + rng.normal(0, 0.01, (80, 2))
    a = fit_bezier(pts, degree)
    b = fit_bezier(pts[::-1], degree)
    np.testing.assert_allclose(b[::-1], a, atol=1e-6)


@settings(max_examples=30, deadline=None)
@given(arrays(float, 6, elements=finite), st.integers(0, 2 ** 31 - 1))
def test_residual_is_the_mean_perpendicular_distance(vals, seed):
    """Checked against brute force: the distance to 200 000 curve samples."""
    ctrl = _catheter_like_ctrl(vals)
    rng = np.random.default_rng(seed)
    pts = bezier_eval(ctrl, np.sort(rng.random(60))) + rng.normal(0, 0.01, (60, 2))
    fit = fit_bezier_detailed(pts)
    # independent reference: the nearest of 20 001 samples, then a bounded scalar search
    ss = np.linspace(0, 1, 20_001)
    dense = bezier_eval(fit.control_points, ss)
    idx = np.argmin(np.sum((pts[:, None, :] - dense[None]) ** 2, -1), axis=1)
    brute = []
    for p, i in zip(pts, idx, strict=True):
        def d2(t, p=p):
            return np.sum((bezier_eval(fit.control_points, [t])[0] - p) ** 2)
        res = minimize_scalar(d2,
                              bounds=(max(ss[i] - 1e-4, 0.0), min(ss[i] + 1e-4, 1.0)),
                              method='bounded', options={'xatol': 1e-12})
        brute.append(np.sqrt(min(res.fun, np.sum((dense[i] - p) ** 2))))
    brute = np.array(brute)
    assert fit.residual == pytest.approx(brute.mean(), rel=1e-7, abs=1e-12)
    assert fit.max_distance == pytest.approx(brute.max(), rel=1e-7, abs=1e-12)
    np.testing.assert_allclose(bezier_distance(fit.control_points, pts), brute, rtol=1e-7,
                               atol=1e-12)
    # perpendicular distance can only be below the distance at the chord-length parameters
    assert fit.residual <= fit.chord_residual + 1e-12


@pytest.mark.parametrize('theta', [0.5, 1.5, 3.0])
def test_parameter_correction_reduces_the_arc_residual(theta, shape_helpers):
    """REFERENCES: chord-length residuals overstate the perpendicular distance; correction
    brings a cubic fit of a circular arc much closer."""
    pts = shape_helpers.arc(theta)
    plain = fit_bezier_detailed(pts, refine=0)
    corr = fit_bezier_detailed(pts, refine=10, correction='orthogonal')
    reg = fit_bezier_detailed(pts)
    assert corr.residual < 0.5 * plain.chord_residual
    assert corr.residual <= reg.residual <= plain.residual + 1e-12
    # the residual is measured, not assumed: it matches exact distances to the arc samples
    d = bezier_distance(corr.control_points, pts)
    assert corr.residual == pytest.approx(d.mean(), rel=1e-6)
    # the curve starts and ends near the data's ends (they keep s = 0 and s = 1)
    assert np.linalg.norm(corr.control_points[0] - pts[0]) <= 2 * corr.max_distance
    assert np.linalg.norm(corr.control_points[-1] - pts[-1]) <= 2 * corr.max_distance


def test_arc_beyond_pi_needs_a_higher_degree(shape_helpers):
    """Thesis: a cubic is not enough past |phi| > pi; degree 5 fits much better."""
    pts = shape_helpers.arc(1.3 * np.pi)
    r3 = fit_bezier_detailed(pts, 3, correction='orthogonal').residual
    r5 = fit_bezier_detailed(pts, 5, correction='orthogonal').residual
    assert r5 < 0.1 * r3


@pytest.mark.parametrize('correction', ['regularized', 'orthogonal', 'none'])
def test_start_and_tangent_constraints(shape_helpers, correction):
    pts = shape_helpers.arc(1.0) + np.array([1e-4, -5e-5])
    c = fit_bezier(pts, start=[0.0, 0.0], correction=correction)
    np.testing.assert_allclose(c[0], [0.0, 0.0], atol=1e-15)
    c = fit_bezier(pts, start=[0.0, 0.0], start_tangent=[1.0, 0.0], correction=correction)
    np.testing.assert_allclose(c[0], [0.0, 0.0], atol=1e-15)
    assert abs(c[1, 1]) < 1e-15 and c[1, 0] > 0


@settings(max_examples=20, deadline=None)
@given(st.floats(-2.5, 2.5), st.integers(0, 2 ** 31 - 1))
def test_regularized_control_points_are_stable_under_noise(theta, seed):
    """The default correction keeps the control points as insensitive to point noise as the
    thesis's chord-length fit (a few times the noise at most), unlike an orthogonal fit of
    a flat objective; and it fits the arc at least as well as the chord-length fit."""
    L = 0.065
    t = np.linspace(0, 1, 400) * theta
    pts = (np.stack([L * np.sin(t) / theta, L * (1 - np.cos(t)) / theta], 1)
           if abs(theta) > 1e-9 else np.stack([np.linspace(0, L, 400), np.zeros(400)], 1))
    rng = np.random.default_rng(seed)
    sigma = 2e-5                                      # 0.02 mm point noise
    cps = np.array([fit_bezier(pts + rng.normal(0, sigma, pts.shape)) for _ in range(8)])
    chord = np.array([fit_bezier(pts + rng.normal(0, sigma, pts.shape), refine=0)
                      for _ in range(8)])
    assert cps.std(axis=0).max() < 3 * chord.std(axis=0).max() + 2e-6
    assert cps.std(axis=0).max() < 10 * sigma
    assert fit_bezier_detailed(pts).residual <= fit_bezier_detailed(pts, refine=0).residual + 1e-9


def test_projection_finds_the_foot_point():
    ctrl = np.array([[0, 0], [1, 0], [2, 0], [3, 0.0]])          # the segment y = 0, x in [0, 3]
    s, d = project_points(ctrl, np.array([[1.5, 2.0], [-1.0, 0.0], [4.0, -1.0]]))
    np.testing.assert_allclose(s, [0.5, 0.0, 1.0], atol=1e-9)
    np.testing.assert_allclose(d, [2.0, 1.0, np.sqrt(2.0)], atol=1e-9)


def test_chord_length_params_eq2():
    p = np.array([[0, 0], [3, 4], [3, 10.0]])
    np.testing.assert_allclose(chord_length_params(p), [0.0, 5 / 11, 1.0])


@pytest.mark.parametrize('pts,kw', [
    (np.array([[0, 0], [1, np.nan], [2, 0], [3, 1], [4, 0.0]]), {}),
    (np.arange(10.0), {}),
    (np.zeros((3, 2)), {}),                         # fewer points than control points
    (np.zeros((10, 2)), {}),                        # zero length
    (np.random.default_rng(0).random((10, 2)), {'degree': 0}),
    (np.random.default_rng(0).random((10, 2)), {'degree': 2.5}),
    (np.random.default_rng(0).random((10, 2)), {'refine': -1}),
    (np.random.default_rng(0).random((10, 2)), {'start': [0.0]}),
    (np.random.default_rng(0).random((10, 2)), {'start_tangent': [1.0, 0.0]}),
    (np.random.default_rng(0).random((10, 2)), {'start': [0, 0], 'start_tangent': [0, 0]}),
    (np.random.default_rng(0).random((10, 2)), {'correction': 'best'}),
    (np.random.default_rng(0).random((10, 2)), {'param_weight': -1.0}),
    ('abc', {}),
])
def test_bad_input_is_refused_with_value_error(pts, kw):
    with pytest.raises(ValueError):
        fit_bezier(pts, **kw)


@settings(max_examples=30, deadline=None)
@given(st.integers(5, 80), st.integers(0, 2 ** 31 - 1), st.sampled_from([2, 3]))
def test_thesis_fit_is_the_moore_penrose_solution_eq4(n, seed, dim):
    """refine=0 is Eq. 4 with Eq. 2 parameters: (p0..p3) = Gamma Lambda^T (Lambda Lambda^T)^-1."""
    rng = np.random.default_rng(seed)
    pts = np.cumsum(rng.normal(0, 1, (n, dim)), axis=0)
    s = chord_length_params(pts)
    lam = np.stack([(1 - s) ** 3, 3 * s * (1 - s) ** 2, 3 * s ** 2 * (1 - s), s ** 3])  # 4 x N
    gamma = pts.T                                                                      # D x N
    expected = (gamma @ lam.T @ np.linalg.inv(lam @ lam.T)).T
    np.testing.assert_allclose(fit_bezier(pts, refine=0), expected, atol=1e-7 * np.abs(pts).max())
    np.testing.assert_allclose(fit_bezier(pts, correction='none'), expected,
                               atol=1e-7 * np.abs(pts).max())

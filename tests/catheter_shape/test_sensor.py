"""ShapeSensor on synthetic frames with exact shapes (straight, circular arcs), robustness
options, and bad frames."""
import numpy as np
import pytest
from hypothesis import given, settings, HealthCheck
from hypothesis import strategies as st

from catheter_shape import (STATUSES, ShapeSensor, SyntheticCamera, bezier_distance,
                            bezier_eval, fit_bezier)


@pytest.fixture(scope='module')
def cam():
    return SyntheticCamera(noise=6.0, seed=1)


def _errors(obs, frame, dist):
    truth = frame.centerline_m
    d = dist(obs.points[:, :2], truth)
    tip = np.linalg.norm(obs.points[-1, :2] - truth[-1])
    base = np.linalg.norm(obs.points[0, :2] - truth[0])
    curve = bezier_eval(obs.control_points[:, :2], np.linspace(0, 1, 300))
    bez = dist(curve, truth)
    return d.mean(), d.max(), tip, base, bez.max()


@pytest.mark.parametrize('theta', [0.0, 0.35, -0.7, 1.0])
@pytest.mark.parametrize('use_bg', [True, False])
def test_centreline_and_control_points_match_the_exact_shape(cam, shape_helpers, theta, use_bg):
    f = cam.render(shape_helpers.arc(theta), rng=np.random.default_rng(7))
    s = ShapeSensor(f.psi, background=f.background if use_bg else None, base_px=cam.base_px)
    obs = s.process(f.image)
    assert obs.ok, obs.message
    assert obs.status == 'ok'
    assert obs.points.shape[1] == 3 and obs.points.shape[0] > 300
    assert obs.control_points.shape == (4, 3)
    np.testing.assert_allclose(obs.points[:, 2], 0.0, atol=1e-15)
    mean, mx, tip, base, bez = _errors(obs, f, shape_helpers.dist)
    assert mean < 0.1e-3                 # issue target at 0.15 mm/pixel
    assert mx < 0.3e-3
    assert tip < 0.5e-3                  # issue target
    assert base < 0.2e-3                 # the calibrated clamp point starts the centreline
    assert bez < 0.25e-3
    # the control points are close to the best cubic of the true shape
    best = fit_bezier(f.centerline_m)
    assert np.max(np.linalg.norm(obs.control_points[[0, 3], :2] - best[[0, 3]], axis=1)) < 0.5e-3
    # residual: the mean perpendicular distance of the points to the curve
    d = bezier_distance(obs.control_points, obs.points)
    assert obs.residual == pytest.approx(d.mean(), rel=1e-3)
    assert 0 < obs.residual < 0.1e-3
    assert set(obs.timings) >= {'threshold', 'component', 'skeleton', 'fit', 'total'}


@pytest.mark.parametrize('method', ['otsu', 'adaptive'])
def test_robust_thresholds_without_background(cam, shape_helpers, method):
    f = cam.render(shape_helpers.arc(0.5), rng=np.random.default_rng(3))
    obs = ShapeSensor(f.psi, base_px=cam.base_px, method=method).process(f.image)
    assert obs.ok, obs.message
    mean, _, tip, _, _ = _errors(obs, f, shape_helpers.dist)
    assert mean < 0.1e-3 and tip < 0.5e-3


def test_base_found_at_the_image_border_without_base_px(shape_helpers):
    """The catheter enters from the left border (clamp outside the view): without base_px
    the base is the end nearest the border."""
    cam = SyntheticCamera(noise=4, base_px=(-30, 240))
    f = cam.render(shape_helpers.arc(0.6))
    for base in (None, cam.base_px):
        obs = ShapeSensor(f.psi, background=f.background, base_px=base).process(f.image)
        assert obs.ok, obs.message
        assert obs.base_px[0] < 2                         # starts on the border
        tip_err = np.linalg.norm(obs.points[-1, :2] - f.centerline_m[-1])
        assert tip_err < 0.5e-3


def test_mirrored_shape_gives_mirrored_control_points(cam, shape_helpers):
    """Ordering comes from the base, not from the skeleton traversal: a shape and its mirror
    image give mirrored control points, p0 at the base either way."""
    rng = np.random.default_rng(0)
    c = shape_helpers.arc(0.8)
    obs_a = ShapeSensor(cam.psi, background=cam.background, base_px=cam.base_px).process(
        cam.render(c, rng=rng).image)
    obs_b = ShapeSensor(cam.psi, background=cam.background, base_px=cam.base_px).process(
        cam.render(c * [1, -1], rng=rng).image)
    assert obs_a.ok and obs_b.ok
    mirrored = obs_b.control_points * [1, -1, 1]
    # the same curve (Hausdorff distance) with the same ends; the inner control points are
    # ill-conditioned (they slide along near-reparameterisations), so a looser bound there
    ss = np.linspace(0, 1, 200)
    assert bezier_distance(mirrored, bezier_eval(obs_a.control_points, ss)).max() < 0.3e-3
    np.testing.assert_allclose(mirrored[[0, 3]], obs_a.control_points[[0, 3]], atol=0.3e-3)
    np.testing.assert_allclose(mirrored, obs_a.control_points, atol=1.5e-3)
    assert np.linalg.norm(obs_a.control_points[0, :2]) < 0.5e-3


@pytest.mark.parametrize('angle', [-np.pi / 2, 0.3, np.pi])
def test_any_camera_orientation(shape_helpers, angle):
    base = {np.pi: (590, 200), -np.pi / 2: (320, 20), 0.3: (40, 440)}[angle]
    cam = SyntheticCamera(noise=4, base_px=base, angle=angle)
    f = cam.render(shape_helpers.arc(0.5))
    assert f.in_view
    obs = ShapeSensor(f.psi, background=f.background, base_px=cam.base_px).process(f.image)
    assert obs.ok, obs.message
    mean, _, tip, _, _ = _errors(obs, f, shape_helpers.dist)
    assert mean < 0.1e-3 and tip < 0.5e-3


def test_a_gap_in_the_mask_is_bridged(cam, shape_helpers):
    f = cam.render(shape_helpers.arc(0.4), rng=np.random.default_rng(5))
    img = f.image.copy()
    u = int(f.centerline_px[200, 0])
    img[:, u - 4:u + 4] = f.background[:, u - 4:u + 4]        # an 8 px (1.2 mm) gap
    obs = ShapeSensor(f.psi, background=f.background, base_px=cam.base_px).process(img)
    assert obs.ok, obs.message
    assert obs.bridged == 1
    mean, _, tip, _, _ = _errors(obs, f, shape_helpers.dist)
    assert mean < 0.1e-3 and tip < 0.5e-3


def test_tissue_over_the_tip_gives_the_visible_end(cam, shape_helpers):
    f = cam.render(shape_helpers.arc(-0.6), tissue_depth=0.006)
    obs = ShapeSensor(f.psi, background=f.background, base_px=cam.base_px).process(f.image)
    assert obs.ok, obs.message
    vis = f.visible_centerline_m
    assert np.linalg.norm(obs.points[-1, :2] - vis[-1]) < 0.5e-3
    assert shape_helpers.dist(obs.points[:, :2], vis).mean() < 0.1e-3


def test_clamp_in_the_mask_is_cut_at_base_px(cam, shape_helpers):
    """The thesis's fixed threshold without background removal segments the dark clamp with
    the catheter; the path is cut at the clamp point (and starts exactly there)."""
    f = cam.render(shape_helpers.arc(0.3))
    obs = ShapeSensor(f.psi, base_px=cam.base_px, method='fixed').process(f.image)
    assert obs.ok and obs.base_cut
    assert np.linalg.norm(obs.points[0, :2]) < 1e-12
    # the default (flat-field with a background estimated by a closing) keeps the clamp in
    # the background: the catheter starts at the clamp too
    obs = ShapeSensor(f.psi, base_px=cam.base_px).process(f.image)
    assert obs.ok and np.linalg.norm(obs.points[0, :2]) < 0.2e-3


def test_base_constraints(cam, shape_helpers):
    f = cam.render(shape_helpers.arc(0.6))
    obs = ShapeSensor(f.psi, background=f.background, base_px=cam.base_px,
                      base_constraint='tangent').process(f.image)
    assert obs.ok
    np.testing.assert_allclose(obs.control_points[0], 0.0, atol=1e-12)
    assert abs(obs.control_points[1, 1]) < 1e-12 and obs.control_points[1, 0] > 0


def test_higher_degree(cam, shape_helpers):
    f = cam.render(shape_helpers.arc(0.6))
    obs = ShapeSensor(f.psi, background=f.background, base_px=cam.base_px,
                      degree=5).process(f.image)
    assert obs.ok and obs.control_points.shape == (6, 3)


def test_bgr_frames(cam, shape_helpers):
    f = cam.render(shape_helpers.arc(0.3))
    bgr = np.repeat(f.image[:, :, None], 3, axis=2)
    obs = ShapeSensor(f.psi, background=f.background, base_px=cam.base_px).process(bgr)
    assert obs.ok


# --- bad frames --------------------------------------------------------------------------

def _two_catheters(cam, shape_helpers):
    a = cam.render(shape_helpers.arc(0.2)).image
    b = SyntheticCamera(noise=0, base_px=(51.2, 100), clamp=False).render(
        shape_helpers.arc(-0.1)).image
    return np.minimum(a, b)


@pytest.mark.parametrize('make,status', [
    (lambda cam, h: np.zeros((0, 0), np.uint8), 'bad_input'),
    (lambda cam, h: np.zeros((480, 640, 2), np.uint8), 'bad_input'),
    (lambda cam, h: np.zeros((480, 640), np.float32), 'bad_input'),
    (lambda cam, h: np.zeros((480, 640), np.int16), 'bad_input'),
    (lambda cam, h: np.zeros((4, 4), np.uint8), 'bad_input'),
    (lambda cam, h: np.full((480, 640), 200, np.uint8), 'low_contrast'),
    (lambda cam, h: np.zeros((480, 640), np.uint8), 'low_contrast'),
    (lambda cam, h: cam.background.copy(), 'no_catheter'),
    (lambda cam, h: np.where(np.arange(640)[None, :] < 400, 10, 200).astype(np.uint8)
     .repeat(480, 0), 'bad_segmentation'),
    (_two_catheters, 'multiple_objects'),
])
@pytest.mark.parametrize('method', ['flatfield', 'fixed'])
def test_bad_frames_give_a_status(cam, shape_helpers, make, status, method):
    frame = make(cam, shape_helpers)
    # what each method says where it differs from the reason the frame was made for
    other = {('fixed', None, 'no_catheter'): 'too_short',       # the dark clamp alone
             ('flatfield', 'bg', 'bad_segmentation'): 'no_catheter',   # brighter than bg
             ('flatfield', None, 'bad_segmentation'): 'bad_skeleton'}   # the edge: a thin
                                                                      # line (no catheter)
    for bg in (None, cam.background):
        s = ShapeSensor(cam.psi, background=bg, base_px=cam.base_px, method=method)
        obs = s.process(frame)
        assert not obs.ok
        assert obs.status in STATUSES
        if bg is None or frame.shape == bg.shape or status == 'bad_input':
            if method == 'fixed' and bg is not None and status == 'bad_segmentation':
                continue
            expect = other.get((method, None if bg is None else 'bg', status), status)
            assert obs.status == expect, (obs.status, obs.message)
        assert np.all(np.isnan(obs.control_points))
        assert obs.points.shape == (0, 3)


def test_background_of_another_size_is_bad_input(cam):
    s = ShapeSensor(cam.psi, background=np.zeros((10, 10), np.uint8))
    obs = s.process(cam.background)
    assert not obs.ok and obs.status == 'bad_input'


@pytest.mark.parametrize('frame', [None, [[1, 2], [3, 4]], 'image', 3.0])
def test_wrongly_typed_frames_raise_value_error(cam, frame):
    with pytest.raises(ValueError, match='frame'):
        ShapeSensor(cam.psi).process(frame)


@pytest.mark.parametrize('kw', [dict(psi=np.zeros((3, 3))), dict(psi=np.full((3, 4), np.nan)),
                                dict(threshold=0), dict(threshold=300), dict(method='magic'),
                                dict(degree=0), dict(base_px=(1, 2, 3)),
                                dict(base_constraint='point'), dict(diameter=-1.0)])
def test_bad_sensor_arguments(cam, kw):
    args = dict(psi=cam.psi)
    args.update(kw)
    with pytest.raises(ValueError):
        ShapeSensor(**args)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(8, 120), st.integers(8, 160), st.integers(0, 2 ** 31 - 1),
       st.sampled_from(['uniform', 'blobs', 'lines']))
def test_random_frames_never_raise(h, w, seed, kind):
    rng = np.random.default_rng(seed)
    if kind == 'uniform':
        frame = rng.integers(0, 256, (h, w), dtype=np.uint8)
    else:
        frame = np.full((h, w), 200, np.uint8)
        import cv2
        for _ in range(rng.integers(1, 5)):
            p = tuple(int(x) for x in rng.integers(0, max(h, w), 2))
            q = tuple(int(x) for x in rng.integers(0, max(h, w), 2))
            if kind == 'blobs':
                cv2.circle(frame, p, int(rng.integers(1, 20)), 20, -1)
            else:
                cv2.line(frame, p, q, 20, int(rng.integers(1, 12)))
    psi = SyntheticCamera(640, 480, 0.15, noise=0).psi
    obs = ShapeSensor(psi).process(frame)
    assert obs.status in STATUSES
    if obs.ok:
        assert np.all(np.isfinite(obs.control_points)) and np.isfinite(obs.residual)
    else:
        assert obs.message


@pytest.mark.parametrize('theta', [2.2, -2.5, 2.8])
def test_the_parameter_correction_beats_the_thesis_fit_on_strong_bends(shape_helpers, theta):
    """The sensor's default (one regularized correction round) follows a strongly bent
    catheter more closely than the thesis's chord-length fit of the same points (measured:
    0.04-0.06 mm vs 0.10-0.17 mm mean deviation from the true centreline)."""
    cam = SyntheticCamera(width=1024, height=1024, mm_per_px=0.15, base_px=(300, 700), noise=4,
                          seed=3)
    f = cam.render(shape_helpers.arc(theta), rng=np.random.default_rng(1))
    dev = {}
    for ref in (None, 0):
        kw = {} if ref is None else dict(refine=ref)
        obs = ShapeSensor(f.psi, background=f.background, base_px=cam.base_px,
                          **kw).process(f.image)
        assert obs.ok
        curve = bezier_eval(obs.control_points[:, :2], np.linspace(0, 1, 300))
        dev[ref] = shape_helpers.dist(curve, f.centerline_m).mean()
    assert dev[None] < 0.07e-3 and dev[None] < 0.6 * dev[0], dev

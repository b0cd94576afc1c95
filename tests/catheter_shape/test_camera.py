"""Synthetic camera: calibration (Eq. 1), geometry of the drawn tube, determinism, bad input."""
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from catheter_shape import (BLAZER_DIAMETER, SyntheticCamera, make_psi, pixels_to_metres,
                            psi_to_pixels)


@given(st.floats(0.01, 1.0), st.floats(-100, 800), st.floats(-100, 800), st.floats(-4, 4))
def test_psi_maps_the_base_to_the_origin_with_the_scale(mm, u0, v0, ang):
    psi = make_psi(mm, (u0, v0), ang)
    np.testing.assert_allclose(pixels_to_metres(psi, [[u0, v0]]), [[0, 0, 0]], atol=1e-12)
    # one pixel along the x direction of the image is mm_per_px along +x of catheter_base
    step = np.array([[u0 + np.cos(ang), v0 - np.sin(ang)]])
    np.testing.assert_allclose(pixels_to_metres(psi, step), [[mm * 1e-3, 0, 0]], atol=1e-12)
    # the y direction is +x turned counter-clockwise on the screen (v grows downwards)
    step = np.array([[u0 - np.sin(ang), v0 - np.cos(ang)]])
    np.testing.assert_allclose(pixels_to_metres(psi, step), [[0, mm * 1e-3, 0]], atol=1e-12)


@settings(max_examples=30)
@given(st.lists(st.tuples(st.floats(-1e3, 1e3), st.floats(-1e3, 1e3)), min_size=1, max_size=20),
       st.floats(-3, 3))
def test_pixels_metres_round_trip(uv, ang):
    psi = make_psi(0.2, (100, 50), ang)
    uv = np.array(uv)
    xyz = pixels_to_metres(psi, uv)
    np.testing.assert_allclose(psi_to_pixels(psi, xyz), uv, atol=1e-6)
    np.testing.assert_allclose(psi_to_pixels(psi, xyz[:, :2]), uv, atol=1e-6)
    cam = SyntheticCamera(64, 48, 0.2, base_px=(100, 50), angle=ang, noise=0)
    np.testing.assert_allclose(cam.to_metres(cam.to_pixels(xyz[:, :2])), xyz[:, :2], atol=1e-12)
    np.testing.assert_allclose(cam.to_pixels(xyz[:, :2]), uv, atol=1e-6)


def test_render_draws_a_dark_tube_of_the_catheter_diameter(shape_helpers):
    cam = SyntheticCamera(noise=0.0)
    f = cam.render(shape_helpers.arc(0.7))
    assert f.image.dtype == np.uint8 and f.image.shape == (480, 640)
    assert f.background.shape == (480, 640) and f.background.dtype == np.uint8
    assert f.in_view
    np.testing.assert_allclose(f.psi, cam.psi)
    np.testing.assert_allclose(f.centerline_px, cam.to_pixels(f.centerline_m))
    # on the centreline (away from the tip cut): dark; the diameter in pixels, then bright
    px = f.centerline_px[20:-40]
    vals = f.image[np.rint(px[:, 1]).astype(int), np.rint(px[:, 0]).astype(int)]
    assert vals.max() < 60
    t = np.gradient(px, axis=0)
    n = np.stack([-t[:, 1], t[:, 0]], 1) / np.linalg.norm(t, axis=1)[:, None]
    r_px = BLAZER_DIAMETER / 2 / 0.15e-3
    for k, expect_dark in ((0.6 * r_px, True), (1.6 * r_px, False)):
        q = np.rint(px + k * n).astype(int)
        v = f.image[q[:, 1], q[:, 0]].astype(int)
        bg = f.background[q[:, 1], q[:, 0]].astype(int)
        if expect_dark:
            assert np.all(bg - v > 123)
        else:
            assert np.all(np.abs(bg - v) <= 3)
    # away from the catheter the frame is the background
    far = np.ones_like(f.image, bool)
    far[:, :int(f.centerline_px[:, 0].max()) + 30] = False
    assert np.abs(f.image[far].astype(int) - f.background[far]).max() <= 1


def test_render_is_deterministic_and_noise_follows_rng(shape_helpers):
    c = shape_helpers.arc(0.4)
    a = SyntheticCamera(noise=8, seed=3).render(c, rng=np.random.default_rng(1)).image
    b = SyntheticCamera(noise=8, seed=3).render(c, rng=np.random.default_rng(1)).image
    d = SyntheticCamera(noise=8, seed=3).render(c, rng=np.random.default_rng(2)).image
    np.testing.assert_array_equal(a, b)
    assert np.any(a != d)
    diff = a.astype(float) - d.astype(float)
    assert 6 < diff[:100, 300:].std() / np.sqrt(2) < 10      # noise std ~ 8 grey levels


def test_a_camera_renders_each_frame_as_a_fresh_camera_would(shape_helpers):
    """The camera keeps its float frame buffer between frames: a frame must not depend on
    the frames drawn before it (nor change when later ones are drawn), with or without
    tissue, noise or blur."""
    shapes = [shape_helpers.arc(k) for k in (0.4, -1.1, 2.5, 0.0)]
    for kw in (dict(noise=8, seed=3), dict(noise=0, blur=0.0, seed=1)):
        cam = SyntheticCamera(**kw)
        seq = [cam.render(c, rng=np.random.default_rng(i), tissue_depth=0.006 * (i == 1))
               for i, c in enumerate(shapes)]
        kept = [f.image.copy() for f in seq]
        for i, c in enumerate(shapes):
            fresh = SyntheticCamera(**kw).render(c, rng=np.random.default_rng(i),
                                                 tissue_depth=0.006 * (i == 1))
            np.testing.assert_array_equal(seq[i].image, fresh.image)
            np.testing.assert_array_equal(seq[i].image, kept[i])


def test_tissue_hides_the_tip_and_is_in_the_background(shape_helpers):
    cam = SyntheticCamera(noise=0)
    f = cam.render(shape_helpers.arc(-0.8), tissue_depth=0.006)
    vis = f.visible_centerline_m
    L_vis = np.sum(np.linalg.norm(np.diff(vis, axis=0), axis=1))
    assert 0.065 - 0.006 - 0.001 < L_vis < 0.065 - 0.006 + 0.001
    tip = np.rint(f.centerline_px[-1]).astype(int)
    assert abs(int(f.image[tip[1], tip[0]]) - int(f.background[tip[1], tip[0]])) <= 1


def test_frames_report_when_the_catheter_leaves_the_view(shape_helpers):
    cam = SyntheticCamera()
    assert not cam.render(shape_helpers.arc(2.5)).in_view
    assert cam.render(shape_helpers.arc(0.2)).in_view


@pytest.mark.parametrize('kw', [dict(width=0), dict(mm_per_px=0.0), dict(mm_per_px=np.nan),
                                dict(noise=-1.0), dict(base_px=(1, 2, 3)), dict(vignetting=0.9)])
def test_bad_camera_arguments(kw):
    with pytest.raises(ValueError):
        SyntheticCamera(**kw)


@pytest.mark.parametrize('c', [np.zeros((5, 4)), np.array([[0, 0], [np.nan, 1]]), np.zeros(5),
                               np.zeros((1, 2)), np.zeros((5, 2))])
def test_bad_centerlines(c):
    with pytest.raises(ValueError):
        SyntheticCamera().render(c)


def test_framing_sees_every_loaded_shape(shape_helpers):
    cam = SyntheticCamera.framing(noise=0)
    assert cam.mm_per_px < 0.25
    for theta in (-3.0, -1.5, 0.0, 1.5, 3.0):        # arcs up to a U-turn
        assert cam.render(shape_helpers.arc(theta)).in_view
    assert cam.render(np.array([[0, 0], [-0.03, 0.058]])).in_view


def test_the_frame_outside_the_tube_is_the_truncated_noisy_background(shape_helpers):
    """The uint8 frame outside the tube's box comes from one OpenCV pass (rounding bg - 1/2 +
    noise to nearest): against floor(clip(bg + noise)) in float64 it differs only where the
    sum is within float32 rounding of an integer."""
    cam = SyntheticCamera(width=400, height=300, noise=8, seed=2)
    c = shape_helpers.arc(0.6, length=0.02)
    f = cam.render(c, rng=np.random.default_rng(5))
    rng = np.random.default_rng(5)                           # the draw render made
    k = int(rng.integers(2))
    dy, dx = (int(x) for x in rng.integers(0, cam._pad, 2))
    ref = np.floor(np.clip(cam._bg.astype(np.float64)
                           + cam._bank[k, dy:dy + 300, dx:dx + 400], 0, 255)).astype(int)
    far = np.ones((300, 400), bool)
    far[:, :int(f.centerline_px[:, 0].max()) + 20] = False
    d = np.abs(f.image.astype(int) - ref)[far]
    assert d.max() <= 1 and np.count_nonzero(d) <= 1e-4 * d.size
    # inside the tube's box (composed in float32) but off the tube and its blur: the same
    from scipy.spatial import cKDTree
    v, u = np.mgrid[0:300, 0:400]
    dist, _ = cKDTree(f.centerline_px).query(np.stack([u.ravel(), v.ravel()], 1))
    px = f.centerline_px
    near_box = ((u >= px[:, 0].min() - 5) & (u <= px[:, 0].max() + 5)
                & (v >= px[:, 1].min() - 5) & (v <= px[:, 1].max() + 5)).ravel()
    off = near_box & (dist > cam.radius_px + 3 * cam.blur + 3)
    assert off.sum() > 500
    d = np.abs(f.image.astype(int).ravel() - ref.ravel())[off]
    assert d.max() <= 1 and np.count_nonzero(d) <= 1e-3 * d.size
    # without noise: the truncated background itself
    cam0 = SyntheticCamera(width=400, height=300, noise=0, seed=2)
    f0 = cam0.render(c)
    np.testing.assert_array_equal(f0.image[far], np.floor(np.clip(cam0._bg, 0, 255))
                                  .astype(np.uint8)[far])

"""Ordering of the skeleton: the base is the end nearest base_px whatever the traversal
order; spurs are ignored; without base_px the base is the end nearest the border."""
import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from catheter_shape.centerline import skeleton_path, smooth_path


def _tube(p, q, h=120, w=200, t=9, spur=False):
    m = np.zeros((h, w), np.uint8)
    cv2.line(m, p, q, 1, t)
    if spur:
        mid = ((p[0] + q[0]) // 2, (p[1] + q[1]) // 2)
        cv2.line(m, mid, (mid[0] + 3, mid[1] + 25), 1, 5)
    return m


@settings(max_examples=25, deadline=None)
@given(st.integers(20, 60), st.integers(20, 100), st.integers(140, 180), st.integers(20, 100),
       st.booleans(), st.booleans())
def test_base_is_the_end_nearest_base_px(x0, y0, x1, y1, reverse, spur):
    p, q = (x0, y0), (x1, y1)
    m = _tube(p, q, spur=spur)
    base = np.array(q if reverse else p, float)
    tip = np.array(p if reverse else q, float)
    cl = skeleton_path(m, (0, 0), base_px=base, image_shape=m.shape)
    assert cl.status == 'ok'
    px = cl.pixels
    assert np.linalg.norm(px[0] - base) < np.linalg.norm(px[-1] - base)
    assert np.linalg.norm(px[-1] - tip) < 10           # the spur is not taken
    # the path follows the axis: every pixel within a few pixels of the line p-q
    u = (tip - base) / np.linalg.norm(tip - base)
    rel = px - base
    d = np.abs(rel[:, 0] * u[1] - rel[:, 1] * u[0])
    assert d.max() < 4


def test_without_base_px_the_border_end_is_the_base():
    m = _tube((0, 60), (150, 40))                       # enters from the left border
    cl = skeleton_path(m, (0, 0), base_px=None, image_shape=m.shape)
    assert cl.status == 'ok' and cl.pixels[0][0] < 3
    m = _tube((150, 40), (199, 60))                     # leaves through the right border
    cl = skeleton_path(m, (0, 0), base_px=None, image_shape=m.shape)
    assert cl.pixels[0][0] > 195


def test_roi_offset_is_applied():
    m = _tube((10, 10), (60, 12), h=30, w=80)
    a = skeleton_path(m, (0, 0), base_px=(10, 10), image_shape=(500, 500)).pixels
    b = skeleton_path(m, (100, 200), base_px=(110, 210), image_shape=(500, 500)).pixels
    np.testing.assert_allclose(b - a, np.array([[100, 200]]).repeat(len(a), 0))


def test_degenerate_masks():
    assert skeleton_path(np.zeros((10, 10), np.uint8), (0, 0)).status == 'bad_skeleton'
    m = np.zeros((10, 10), np.uint8)
    m[4:6, 4:7] = 1
    assert skeleton_path(m, (0, 0), min_length_px=10).status in ('too_short', 'bad_skeleton')


@pytest.mark.parametrize('window', [3, 5, 7])
def test_smoothing_keeps_ends_and_straight_lines(window):
    t = np.linspace(0, 1, 50)[:, None]
    line = np.hstack([t * 40, t * 10])
    np.testing.assert_allclose(smooth_path(line, window), line, atol=1e-12)
    stair = np.round(line)
    sm = smooth_path(stair, window)
    np.testing.assert_array_equal(sm[[0, -1]], stair[[0, -1]])
    assert np.abs(sm - line).mean() < np.abs(stair - line).mean()

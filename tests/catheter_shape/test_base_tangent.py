"""The clamped catheter leaves the clamp along +x of catheter_base: where the skeleton stops
short of the calibrated clamp point, the sensor joins them by a curve tangent to that
direction, in any camera orientation (thesis: the clamp fixes the base tangent)."""
import numpy as np
import pytest

from catheter_shape import ShapeSensor, SyntheticCamera


@pytest.mark.parametrize('angle', [0.0, 0.3, 0.7, 1.2, 2.0])
def test_the_centreline_leaves_the_clamp_along_its_axis(shape_helpers, angle):
    cam = SyntheticCamera(width=1024, height=1024, noise=4, base_px=(512, 512), angle=angle,
                          seed=2)
    f = cam.render(shape_helpers.arc(-0.7), rng=np.random.default_rng(7))
    sensor = ShapeSensor(f.psi, background=f.background, base_px=cam.base_px)
    obs = sensor.process(f.image)
    assert obs.ok, obs.message
    assert not obs.base_cut                            # the joint path, not a cut clamp
    px = obs.pixels
    np.testing.assert_allclose(px[0], cam.base_px, atol=1e-9)
    # the clamp's axis in the image, independently of the sensor: +x of catheter_base
    # through the camera's calibration (metres -> pixels)
    ax = np.linalg.lstsq(f.psi[:, :2], np.array([1.0, 0.0, 0.0]), rcond=None)[0]
    ax /= np.linalg.norm(ax)
    d = (px[1] - px[0]) / np.linalg.norm(px[1] - px[0])
    angle_deg = np.degrees(abs(np.arctan2(ax[0] * d[1] - ax[1] * d[0], ax @ d)))
    assert angle_deg < 2.5          # measured 0.3-1.2 deg; a chord to the skeleton: 1.4-5.3

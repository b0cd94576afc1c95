"""The sensor refuses, with the status that says why, frames it cannot measure right:
a catheter running along the image border (its tube cut by the border: the visible part
is not centred on the centreline) and a dark object of the wrong width for the calibrated
catheter (a sensor set up for another catheter)."""
import numpy as np
import pytest

from catheter_shape import ShapeSensor, SyntheticCamera
from catheter_shape.camera import BLAZER_DIAMETER


@pytest.mark.parametrize('base_y, theta', [(3, -1.0), (5, -1.5), (476, 1.0), (476, 1.5)])
def test_a_catheter_along_the_image_border_is_outside_frame(shape_helpers, base_y, theta):
    """The clamp 3-5 px from the top or bottom border of a 480-px frame (a 15.6-px tube):
    the catheter runs along the border for centimetres before it bends into view."""
    cam = SyntheticCamera(noise=4, base_px=(51.2, base_y), seed=1)
    f = cam.render(shape_helpers.arc(theta), rng=np.random.default_rng(3))
    obs = ShapeSensor(f.psi, background=f.background, base_px=cam.base_px).process(f.image)
    assert obs.status == 'outside_frame' and not obs.ok
    assert 'border' in obs.message


@pytest.mark.parametrize('ratio', [1 / 3, 1 / 4])
def test_a_sensor_for_a_thinner_catheter_refuses_the_frame(shape_helpers, ratio):
    cam = SyntheticCamera(noise=4, seed=1)
    f = cam.render(shape_helpers.arc(0.5), rng=np.random.default_rng(3))
    right = ShapeSensor(f.psi, background=f.background, base_px=cam.base_px).process(f.image)
    assert right.ok                                  # the frame itself is measurable
    obs = ShapeSensor(f.psi, background=f.background, base_px=cam.base_px,
                      diameter=ratio * BLAZER_DIAMETER).process(f.image)
    assert obs.status == 'bad_segmentation' and not obs.ok
    assert 'wide' in obs.message

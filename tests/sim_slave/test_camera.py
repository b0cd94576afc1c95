"""The slave's camera: tip force from the wall contact, FAM shape, frames the shape sensor reads."""
import math

import numpy as np
import pytest

pytest.importorskip('fam_solver')
pytest.importorskip('catheter_shape')

from catheter_shape import ShapeSensor  # noqa: E402
from sim_slave import VesselParams  # noqa: E402
from sim_slave.camera import TipCamera  # noqa: E402


@pytest.fixture(scope='module')
def cam():
    return TipCamera(seed=1)


def test_tip_force_is_the_wall_force_along_the_angle(cam):
    p = VesselParams()
    assert np.all(cam.tip_force(p.wall_depth - 1e-3, 0.02) == 0.0)
    d = 0.011
    f = cam.tip_force(p.wall_depth + d, 0.0)
    mag = p.wall_stiffness * d ** 1.5
    assert np.hypot(*f) == pytest.approx(mag)
    assert math.atan2(f[1], f[0]) == pytest.approx(2 * math.pi / 3)


@pytest.mark.parametrize('x', [0.02, 0.05, 0.056, 0.06])
def test_frames_show_the_fam_shape(cam, x):
    fr = cam.frame(x, 0.0)
    assert fr.image.dtype == np.uint8 and fr.image.shape == (800, 800)
    assert fr.converged
    if x < VesselParams().wall_depth:
        assert fr.tip == pytest.approx([0.065, 0.0], abs=1e-9)     # straight, unloaded
    else:
        assert fr.tip[1] > 0.02                                     # bent towards +y
    # an independent reading: the image pipeline finds the tip where FAM put it
    sensor = ShapeSensor(cam.psi, background=cam.camera.background, base_px=cam.camera.base_px)
    obs = sensor.process(fr.image)
    assert obs.ok, obs.status
    assert np.linalg.norm(obs.control_points[3, :2] - fr.tip) < 1e-3


def test_bad_arguments():
    with pytest.raises(ValueError, match='force_angle'):
        TipCamera(force_angle=math.nan)
    with pytest.raises(ValueError, match='length'):
        TipCamera(length=-0.065)
    with pytest.raises(ValueError, match='n_arcs'):
        TipCamera(n_arcs=0)
    with pytest.raises(ValueError, match='seed'):
        TipCamera(seed=-1)
    with pytest.raises(ValueError, match='x'):
        TipCamera().tip_force(math.nan, 0.0)

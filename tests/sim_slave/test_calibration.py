"""One camera calibration for the whole image path: camera_node draws with
catheter_shape.camera.SYSTEM_CAMERA and shape_node's default psi/base_px are the same camera,
so a scenario that passes neither measures the drawn catheter in the right place."""
import numpy as np
import pytest

from catheter_shape import ShapeSensor
from catheter_shape.camera import SYSTEM_CAMERA, system_psi
from sim_slave.camera import DEFAULT_CAMERA, TipCamera

shape_node = pytest.importorskip('catheter_shape.shape_node')


def test_camera_and_shape_node_defaults_are_one_calibration():
    assert DEFAULT_CAMERA == SYSTEM_CAMERA
    cam = TipCamera(camera=dict(noise=0.0), seed=1)
    np.testing.assert_allclose(np.reshape(shape_node.DEFAULT_PSI, (3, 4)), cam.psi, atol=0)
    np.testing.assert_allclose(shape_node.DEFAULT_BASE_PX, SYSTEM_CAMERA['base_px'])
    np.testing.assert_allclose(system_psi(), cam.psi)


def test_unloaded_catheter_is_measured_straight_with_the_default_calibration():
    # no wall contact (x before the wall): the 65 mm catheter lies along +x of catheter_base
    cam = TipCamera(camera=dict(noise=0.0), seed=1)
    frame = cam.frame(0.01, 0.0)
    assert np.allclose(frame.tip_force, 0.0)
    sensor = ShapeSensor(np.reshape(shape_node.DEFAULT_PSI, (3, 4)),
                         base_px=shape_node.DEFAULT_BASE_PX)
    obs = sensor.process(frame.image)
    assert obs.ok, obs.status
    cp = obs.control_points
    np.testing.assert_allclose(cp[0, :2], [0.0, 0.0], atol=1.0e-3)          # at the clamp
    np.testing.assert_allclose(cp[-1, :2], frame.tip, atol=1.0e-3)          # the drawn tip
    assert abs(cp[-1, 0] - 0.065) < 2e-3 and abs(cp[-1, 1]) < 1e-3

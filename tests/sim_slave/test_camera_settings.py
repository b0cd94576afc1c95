"""The slave camera's settings reach what it draws: the SyntheticCamera keyword arguments
(camera_node's camera.* parameters), the seed, and the vessel whose wall loads the tip."""
import numpy as np
import pytest

pytest.importorskip('fam_solver')
pytest.importorskip('catheter_shape')

from catheter_shape.camera import psi_to_pixels  # noqa: E402
from sim_slave import VesselParams  # noqa: E402
from sim_slave.camera import TipCamera  # noqa: E402

SMALL = dict(width=160, height=120, mm_per_px=0.6, base_px=(20.0, 60.0))


def test_camera_keywords_set_the_frame_and_calibration():
    cam = TipCamera(camera=SMALL, seed=1)
    fr = cam.frame(0.02, 0.0)
    assert fr.image.shape == (120, 160)                        # (height, width)
    assert tuple(cam.camera.base_px) == (20.0, 60.0)
    # the clamp (catheter_base origin) at the given pixel; 6 mm along +x is 10 pixels right
    uv = psi_to_pixels(cam.psi, np.array([[0.0, 0.0], [0.006, 0.0]]))
    assert uv == pytest.approx(np.array([[20.0, 60.0], [30.0, 60.0]]), abs=1e-9)


def test_the_seed_changes_the_background():
    a = TipCamera(camera=SMALL, seed=1).camera.background
    b = TipCamera(camera=SMALL, seed=2).camera.background
    assert a.shape == b.shape and not np.array_equal(a, b)


def test_the_given_vessels_wall_loads_the_tip():
    """A vessel with its wall at 20 mm (the phantom's is at 45 mm) loads the tip at 30 mm
    with the Hunt-Crossley force k d^1.5 of its own wall."""
    vp = VesselParams(wall_depth=0.02)
    cam = TipCamera(vessel_params=vp, camera=SMALL)
    f = cam.tip_force(0.03, 0.0)
    assert np.hypot(*f) == pytest.approx(vp.wall_stiffness * 0.01 ** vp.wall_exponent)

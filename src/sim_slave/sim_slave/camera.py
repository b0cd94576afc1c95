"""The slave's camera: the distal catheter bent by the tip's wall-contact force, drawn as a
fluoroscopy-like frame (thesis Chapter 2's image-based force estimation needs images).

The catheter (thesis defaults: Blazer II-XP, 65 mm, EI = 6.0e-5 N m^2) is clamped at the
catheter_base origin (the camera frame moves with the insertion, as in the thesis's
ex-vivo set-up). Its tip carries the vessel's Hunt-Crossley wall force (0 before the wall)
pointing along ``force_angle`` in catheter_base (within the thesis's training range
[0, pi]). FAM (fam_solver.solve_fam, warm-started from the previous frame) gives the shape;
catheter_shape.SyntheticCamera draws it.

No rclpy. fam_solver and the synthetic camera are imported when a TipCamera is made (the
calibration constant SYSTEM_CAMERA comes from catheter_shape.camera at import).
"""
from __future__ import annotations

import math
from typing import NamedTuple, Optional

import numpy as np

from catheter_shape.camera import SYSTEM_CAMERA
from catheter_common.checks import finite, positive, seed as check_seed
from sim_slave.vessel import VesselModel, VesselParams

#: the force estimator's training camera (force_estimator.dataset.TRAIN_CAMERA): 800 x 800 at
#: 0.15 mm/pixel, the clamp at pixel (260, 400), +x to the right; every Blazer shape with a tip
#: force up to 0.3 N stays in view. The shape node needs the same calibration (see `psi`).
#: Defined once, in catheter_shape.camera.SYSTEM_CAMERA (shape_node's default calibration).
DEFAULT_CAMERA = dict(SYSTEM_CAMERA)
BLAZER_LENGTH = 0.065       # m
BLAZER_EI = 6.0e-5          # N m^2


class CameraFrame(NamedTuple):
    """image: uint8 (H, W) mono; tip_force: (2,) N in catheter_base; tip: (2,) m;
    converged: whether the FAM solve converged (if not, the best iterate is drawn)."""
    image: np.ndarray
    tip_force: np.ndarray
    tip: np.ndarray
    converged: bool


class TipCamera:
    """Tip force from the slave's state, FAM shape, synthetic frame.

    Args:
        vessel_params: the vessel whose wall contact loads the tip (defaults if None).
        force_angle: rad, direction of the tip force in catheter_base (default 2 pi / 3).
        length: m, catheter length in view (clamp to tip). ei: N m^2, bending stiffness.
        n_arcs: FAM arcs.
        camera: SyntheticCamera keyword arguments (width, height, mm_per_px, base_px, angle,
            noise, blur, ...); DEFAULT_CAMERA if None.
        seed: int >= 0 (background texture and image noise).
    """

    def __init__(self, vessel_params: Optional[VesselParams] = None,
                 force_angle: float = 2.0 * math.pi / 3.0, length: float = BLAZER_LENGTH,
                 ei: float = BLAZER_EI, n_arcs: int = 12, camera: Optional[dict] = None,
                 seed: Optional[int] = 0):
        from catheter_shape import SyntheticCamera
        from fam_solver import Catheter

        self.vessel = VesselModel(vessel_params, seed=0)
        self.force_angle = finite('force_angle', force_angle)
        self.catheter = Catheter(length=positive('length', length), ei=positive('ei', ei))
        if isinstance(n_arcs, bool) or not isinstance(n_arcs, int) or n_arcs < 1:
            raise ValueError(f'n_arcs must be an int >= 1, got {n_arcs!r}')
        self.n_arcs = n_arcs
        kw = dict(DEFAULT_CAMERA)
        kw.update(camera or {})
        kw['seed'] = check_seed('seed', seed) or 0
        self.camera = SyntheticCamera(**kw)
        self._shape = None

    @property
    def psi(self) -> np.ndarray:
        """The camera's 3x4 calibration matrix (thesis Eq. 1), for the shape node."""
        return self.camera.psi.copy()

    def tip_force(self, x: float, xd: float) -> np.ndarray:
        """Tip force (fx, fy) in N, catheter_base, at inserted length x [m], velocity xd [m/s]."""
        f = self.vessel.wall_force(x, xd)
        return np.array([f * math.cos(self.force_angle), f * math.sin(self.force_angle)])

    def frame(self, x: float, xd: float) -> CameraFrame:
        """One frame of the catheter at inserted length x [m] moving at xd [m/s]."""
        from fam_solver import Loads, solve_fam

        force = self.tip_force(x, xd)
        # circular arcs on the graded mesh, as when the reference bags were recorded
        shape = solve_fam(self.catheter, Loads(tip_force=(float(force[0]), float(force[1]))),
                          n_arcs=self.n_arcs, initial=self._shape, arc_model='exact',
                          spacing='graded')
        if shape.converged:
            self._shape = shape
        frame = self.camera.render(shape.centerline(200))
        return CameraFrame(frame.image, force, np.asarray(shape.tip, float).copy(),
                           bool(shape.converged))

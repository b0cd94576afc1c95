"""Image-based shape sensing: camera frame to ordered centreline to Bezier control points;
synthetic camera (thesis Chapter 2, section 2.2.2, Eqs. 1-5).

Public API (DESIGN section 5):
    ShapeSensor(psi, threshold=132, background=None, base_px=None, ...)
        .process(frame) -> Observation
    fit_bezier(points, degree=3, ...) -> (degree + 1, D)
    SyntheticCamera(width=640, height=480, mm_per_px=0.15, ...)
        .render(centerline_m) -> SyntheticFrame
"""
from catheter_shape.bezier import (BezierFit, bernstein, bezier_distance, bezier_eval,
                                   bezier_derivative, chord_length_params, fit_bezier,
                                   fit_bezier_detailed, project_points)
from catheter_shape.camera import (BLAZER_DIAMETER, SyntheticCamera, SyntheticFrame, make_psi,
                                   pixels_to_metres, psi_to_pixels)
from catheter_shape.sensor import STATUSES, Observation, ShapeSensor

__all__ = ['BezierFit', 'bernstein', 'bezier_distance', 'bezier_eval', 'bezier_derivative',
           'chord_length_params', 'fit_bezier', 'fit_bezier_detailed', 'project_points',
           'BLAZER_DIAMETER', 'SyntheticCamera', 'SyntheticFrame', 'make_psi',
           'pixels_to_metres', 'psi_to_pixels', 'STATUSES', 'Observation', 'ShapeSensor']

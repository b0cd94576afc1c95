"""Validation of the estimators' input, the 4 Bezier control points, in one place.

Pure numpy; no rclpy.
"""
from __future__ import annotations

from typing import Optional, Tuple

import numpy as np

__all__ = ['N_FEATURES', 'MAX_COORD', 'control_points_to_features', 'check_control_points']

N_FEATURES = 12
#: largest plausible control-point coordinate, m: a catheter in view of a camera that
#: resolves it is centimetres long; beyond this the input is refused as 'bad_input'
MAX_COORD = 1.0


def _as_array(control_points) -> np.ndarray:
    try:
        x = np.asarray(control_points, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f'control_points must be numbers of shape (4, 3): {exc}') from None
    if x.ndim < 2 or x.ndim > 3 or x.shape[-2] != 4 or x.shape[-1] not in (2, 3):
        raise ValueError(f'control_points must have shape (4, 3) or (B, 4, 3), got {x.shape}')
    if x.shape[-1] == 2:
        x = np.concatenate([x, np.zeros(x.shape[:-1] + (1,))], axis=-1)
    return x


def control_points_to_features(control_points) -> np.ndarray:
    """Validate control points and flatten them to features.

    control_points: (4, 3) or (B, 4, 3) m (a planar (4, 2) / (B, 4, 2) input gets z = 0).
    Returns (12,) or (B, 12) float64. Raises ValueError (naming `control_points`) on a
    wrong shape or non-finite values.
    """
    x = _as_array(control_points)
    if not np.isfinite(x).all():
        raise ValueError('control_points contain non-finite values')
    return x.reshape(x.shape[:-2] + (N_FEATURES,))


def check_control_points(control_points) -> Optional[Tuple[str, str]]:
    """None for one usable set of control points (4, 3) / (4, 2); else (status, message):
    ('non_finite_input', ...) or ('bad_input', ...) for coordinates beyond MAX_COORD.
    Raises ValueError (naming `control_points`) for a wrong shape or a batch."""
    x = _as_array(control_points)
    if x.ndim != 2:
        raise ValueError(f'control_points must have shape (4, 3) for one estimate, got {x.shape}')
    if not np.isfinite(x).all():
        return 'non_finite_input', 'control_points contain non-finite values'
    big = float(np.max(np.abs(x)))
    if big > MAX_COORD:
        return 'bad_input', (f'control_points reach {big:.3g} m (> {MAX_COORD:g} m): not a '
                             f'catheter in view')
    return None

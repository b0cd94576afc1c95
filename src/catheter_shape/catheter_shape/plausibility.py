"""Plausibility checks of a measured centreline before the sensor reports it as ok: a shape
that a clamped catheter cannot take, or that the frame cannot show, is refused with a
status saying which check failed ("never ok when wrong").

Bounds for a clamped Blazer catheter (65 mm, EI 6e-5 N m^2) under tip forces up to 0.3 N at
any angle, measured on 4000 FAM shapes (24 arcs): total turning of the tangent at most 175
deg (the range of the tangent's direction), bending radius at least 7.1 mm, turning over one
catheter width at most 18 deg. The defaults leave a wide margin for pixel noise and other
loads: 220 deg in total, 45 deg over one width; a centreline never crosses itself.

Pure numpy; no rclpy. Paths are (N, 2) pixels (u, v), ordered base -> tip.
"""
from __future__ import annotations

from typing import Optional, Tuple

import numpy as np

__all__ = ['MAX_TURNING', 'MAX_KINK', 'path_length', 'resample', 'turning',
           'self_intersects', 'inside_frame', 'on_border', 'check_fold']

#: largest total turning of the tangent along the catheter, rad (220 deg)
MAX_TURNING = np.radians(220.0)
#: largest turning of the tangent over one catheter width, rad (45 deg)
MAX_KINK = np.radians(45.0)


def path_length(px: np.ndarray) -> float:
    """Arc length of a polyline (N, 2)."""
    return float(np.sum(np.hypot(*np.diff(px, axis=0).T))) if len(px) > 1 else 0.0


def resample(px: np.ndarray, step: float) -> np.ndarray:
    """The polyline at equal arc-length steps (about `step`), both ends kept."""
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(px, axis=0).T))])
    n = max(2, int(np.ceil(s[-1] / max(step, 1e-9))) + 1)
    t = np.linspace(0.0, s[-1], n)
    return np.stack([np.interp(t, s, px[:, 0]), np.interp(t, s, px[:, 1])], axis=1)


def turning(px: np.ndarray, width_px: float) -> Tuple[float, float]:
    """(range of the tangent's direction along the path, largest turning over one width),
    rad, of the path resampled at half-width steps. (The range, not the summed |turning|:
    pixel noise adds up in a sum; the tangent of a tip-loaded clamped rod turns one way.)"""
    step = max(0.5 * width_px, 1.0)
    q = resample(px, step)
    if len(q) < 3:
        return 0.0, 0.0
    d = np.diff(q, axis=0)
    th = np.unwrap(np.arctan2(d[:, 1], d[:, 0]))
    total = float(np.ptp(th))
    k = max(1, int(round(width_px / step)))
    kink = float(np.max(np.abs(th[k:] - th[:-k]))) if len(th) > k else float(np.ptp(th))
    return total, kink


def self_intersects(px: np.ndarray, step: float) -> bool:
    """True when the polyline, resampled at `step`, crosses itself (non-adjacent segments
    intersect)."""
    return _crosses(resample(px, step))


def _crosses(q: np.ndarray) -> bool:
    n = len(q) - 1
    if n < 3:
        return False
    a, b = q[:-1], q[1:]
    d = b - a
    # segment i vs j: solve a_i + t d_i = a_j + u d_j
    cross = d[:, None, 0] * d[None, :, 1] - d[:, None, 1] * d[None, :, 0]
    w = a[None, :, :] - a[:, None, :]
    with np.errstate(divide='ignore', invalid='ignore'):
        t = (w[..., 0] * d[None, :, 1] - w[..., 1] * d[None, :, 0]) / cross
        u = (w[..., 0] * d[:, None, 1] - w[..., 1] * d[:, None, 0]) / cross
    hit = (t > 0) & (t < 1) & (u > 0) & (u < 1) & (np.abs(cross) > 1e-12)
    i, j = np.nonzero(hit)
    return bool(np.any(np.abs(i - j) > 1))


def inside_frame(px: np.ndarray, shape: Tuple[int, int], tol: float = 0.5) -> bool:
    """Every point within the image (H, W) (pixel centres 0..W-1, 0..H-1, +- tol)."""
    H, W = shape
    return bool(np.all((px[:, 0] >= -tol) & (px[:, 0] <= W - 1 + tol)
                       & (px[:, 1] >= -tol) & (px[:, 1] <= H - 1 + tol)))


def on_border(p, shape: Tuple[int, int], tol: float = 1.5) -> bool:
    """The point (u, v) lies within tol pixels of the image border."""
    H, W = shape
    return bool(min(p[0], p[1], W - 1 - p[0], H - 1 - p[1]) <= tol)


def check_fold(px: np.ndarray, width_px: float, max_turning: float = MAX_TURNING,
               max_kink: float = MAX_KINK) -> Optional[str]:
    """None when the path (smoothed) is a shape a clamped catheter can take; else the
    reason (the tangent turns more than max_turning in total, or more than max_kink within
    one width, or the path crosses itself)."""
    step = max(0.5 * width_px, 1.0)
    q = resample(px, step)
    if len(q) < 3:
        return None
    d = np.diff(q, axis=0)
    th = np.unwrap(np.arctan2(d[:, 1], d[:, 0]))
    total = float(np.ptp(th))
    k = max(1, int(round(width_px / step)))
    kink = float(np.max(np.abs(th[k:] - th[:-k]))) if len(th) > k else float(np.ptp(th))
    if total > max_turning:
        return (f'the centreline turns {np.degrees(total):.0f} deg in total '
                f'(> {np.degrees(max_turning):.0f})')
    if kink > max_kink:
        return (f'the centreline turns {np.degrees(kink):.0f} deg within one catheter width '
                f'(> {np.degrees(max_kink):.0f}): a kink')
    # a polyline whose segment directions span less than 180 deg advances monotonically
    # along their bisector: it cannot cross itself (the O(n^2) test only beyond)
    if total >= np.pi and _crosses(q):
        return 'the centreline crosses itself'
    return None

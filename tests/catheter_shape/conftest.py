"""Shared helpers of the catheter_shape tests: exact shapes (straight, circular arcs)."""
import numpy as np
import pytest

L_BLAZER = 0.065


def arc(theta: float, length: float = L_BLAZER, k: int = 400) -> np.ndarray:
    """Centreline (k, 2) m of a clamped catheter bent by a pure tip moment: a circular arc
    of total angle theta (rad); theta = 0 is straight along +x."""
    s = np.linspace(0.0, 1.0, k)
    if abs(theta) < 1e-12:
        return np.stack([s * length, np.zeros(k)], axis=1)
    t = s * theta
    return np.stack([length * np.sin(t) / theta, length * (1 - np.cos(t)) / theta], axis=1)


def dist_to_polyline(points: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Exact distance (N,) of points (N, 2) to the polyline (k, 2)."""
    a = poly[:-1][None]
    d = np.diff(poly, axis=0)[None]
    p = points[:, None, :2]
    t = np.clip(np.sum((p - a) * d, -1) / np.maximum(np.sum(d * d, -1), 1e-30), 0, 1)
    return np.sqrt(np.min(np.sum((a + t[..., None] * d - p) ** 2, -1), axis=1))


@pytest.fixture(scope='session')
def shape_helpers():
    class H:
        pass
    h = H()
    h.arc = arc
    h.dist = dist_to_polyline
    return h

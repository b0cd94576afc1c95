"""Where a wall starts and how stiff it is, from the force met while inserting (the
seventeenth round of issue 12; `ImaRenderer` `elastic_hinge`, on by default).

The inward anchors' forces, binned by depth (`support.ElasticShare`: 1 mm bins, the
measured force less the model's velocity terms, with the bins' mean speed), are fitted by
weighted least squares (weights: the anchors per bin) with

    f(x) = a x + b x^2 + k (x - x_w)+ + c_w [x > x_w] v(x)

friction growing linearly or with the square of the inserted length (the drawn vessels'
friction laws), a linear wall from x_w on, and the wall's damper (a Kelvin-Voigt tissue
wall's force grows with the speed of entry: without this column a fast minimum-jerk
insertion read its damper as stiffness, 17 N/m where the spring was 5.7 N/m). x_w is
searched over the bins' depths (at least `min_bins` bins shallower, three deeper). The
wall is accepted only where it explains the forces better than the friction law alone by
an F ratio (rss_0 - rss) / (rss / dof) of at least `min_f`, and k > 0.

A wall's force does not reverse when the catheter is pulled back; friction does. The
renderer's elastic keep at a first outward reversal (`anchoring.elastic_keep`) can keep
`elastic_hinge` x k (x - x_w)+ of the inserting force.

numpy, vectorised over the candidate onsets from suffix sums (O(bins)); no rclpy.
"""
from __future__ import annotations

from typing import NamedTuple, Optional, Sequence

import numpy as np

from impedance_master.support import HINGE_F


class Hinge(NamedTuple):
    """A fitted wall: onset x_w (m), stiffness k (N/m), its F ratio."""
    x_w: float
    k: float
    f_ratio: float


def fit_hinge(x: Sequence[float], n: Sequence[float], f_sum: Sequence[float],
              v_sum: Sequence[float], min_f: float = HINGE_F, min_bins: int = 5
              ) -> Optional[Hinge]:
    """The wall of binned inward forces, or None (too few bins, no significant wall).

    Args:
        x: m, bin depths (ascending), only bins with anchors.
        n: anchors per bin (> 0).
        f_sum, v_sum: per bin, the sums of the anchors' forces (N) and speeds (m/s).
        min_f: the F ratio the hinge must reach.
        min_bins: bins shallower than the shallowest candidate onset.
    """
    x = np.asarray(x, float)
    w = np.asarray(n, float)
    if x.ndim != 1 or not (len(w) == len(x) == len(f_sum) == len(v_sum)):
        raise ValueError('x, n, f_sum and v_sum must be 1-d and of one length')
    if len(x) < min_bins + 5 or not np.all(w > 0.0):
        return None
    f = np.asarray(f_sum, float) / w
    v = np.asarray(v_sum, float) / w
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(f)) and np.all(np.isfinite(v))):
        return None
    # the friction law alone
    X0 = np.stack([x, x * x], 1)
    A0 = X0.T @ (w[:, None] * X0)
    try:
        c0 = np.linalg.solve(A0, X0.T @ (w * f))
    except np.linalg.LinAlgError:
        return None
    rss0 = float(np.sum(w * (f - X0 @ c0) ** 2))
    # every candidate onset x_w at once, from suffix sums over the bins beyond it (the
    # normal equations of the columns x, x^2, (x - x_w)+, [x > x_w] v; O(bins))
    first = min_bins
    cand = x[first:-3]
    def suffix(a):          # sum over the bins deeper than each candidate
        c = np.cumsum(a[::-1])[::-1]
        return c[first + 1:len(x) - 2]
    wx, wx2, wx3, wx4 = w * x, w * x ** 2, w * x ** 3, w * x ** 4
    S = {name: suffix(a) for name, a in (
        ('w', w), ('wx', wx), ('wx2', wx2), ('wx3', wx3), ('wv', w * v), ('wxv', wx * v),
        ('wx2v', wx2 * v), ('wv2', w * v * v), ('wf', w * f), ('wxf', wx * f),
        ('wvf', w * v * f))}
    t = cand
    C = len(cand)
    A = np.empty((C, 4, 4))
    A[:, 0, 0] = wx2.sum()
    A[:, 0, 1] = A[:, 1, 0] = wx3.sum()
    A[:, 1, 1] = wx4.sum()
    A[:, 0, 2] = A[:, 2, 0] = S['wx2'] - t * S['wx']
    A[:, 1, 2] = A[:, 2, 1] = S['wx3'] - t * S['wx2']
    A[:, 2, 2] = S['wx2'] - 2.0 * t * S['wx'] + t * t * S['w']
    A[:, 0, 3] = A[:, 3, 0] = S['wxv']
    A[:, 1, 3] = A[:, 3, 1] = S['wx2v']
    A[:, 2, 3] = A[:, 3, 2] = S['wxv'] - t * S['wv']
    A[:, 3, 3] = S['wv2']
    rhs = np.empty((C, 4))
    rhs[:, 0] = np.sum(wx * f)
    rhs[:, 1] = np.sum(wx2 * f)
    rhs[:, 2] = S['wxf'] - t * S['wf']
    rhs[:, 3] = S['wvf']
    scale = np.trace(A, axis1=1, axis2=2)[:, None, None]
    A = A + 1e-12 * scale * np.eye(4)[None]
    try:
        coef = np.linalg.solve(A, rhs[:, :, None])[:, :, 0]
    except np.linalg.LinAlgError:
        return None
    # the residual sum of squares of the least-squares solution: sum w f^2 - coef . rhs
    rss = np.maximum(0.0, float(np.sum(w * f * f)) - np.sum(coef * rhs, 1))
    i = int(np.argmin(rss))
    dof = max(1, len(x) - 4)
    r = float(rss[i])
    ratio = (rss0 - r) / (r / dof) if r > 0.0 else np.inf
    k = float(coef[i, 2])
    if not (k > 0.0 and ratio >= min_f and np.isfinite(k)):
        return None
    return Hinge(float(cand[i]), k, float(ratio))

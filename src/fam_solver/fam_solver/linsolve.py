"""Linear algebra of the FAM Newton step: the Jacobian J = I - W D from its semiseparable
factors (see ``equations.evaluate``), dense for N <= DENSE_MAX_N and O(N) beyond, and the
branch / stability check on its eigenvalues. No rclpy here.
"""
from __future__ import annotations

from typing import Optional, Tuple

import numpy as np

from .equations import Factors

DENSE_MAX_N = 64


_TRIL_CACHE = {}


def _masks(n: int):
    m = _TRIL_CACHE.get(n)
    if m is None:
        idx = np.arange(n)
        m = (idx[:, None] > idx[None, :], np.eye(n, dtype=bool), np.eye(n))
        _TRIL_CACHE[n] = m
    return m


def dense_jacobian(w, fac: Factors) -> np.ndarray:
    """J (B, N, N) = I - W D from the factors (A, Bd, C, e) of ``equations.evaluate``."""
    A, Bd, C, e = fac
    B, N = A.shape
    lower, diag, eye = _masks(N)
    D = np.where(lower, A[:, :, None], C[:, None, :] + e[:, :, None])
    D[:, diag] = Bd
    w = np.asarray(w, dtype=float)
    J = eye - (w[..., :, None] if w.ndim else w) * D    # row i scaled by w_i = l_i / EI
    return J


def structured_solve(w, fac: Factors, rhs: np.ndarray) -> np.ndarray:
    """Solve J x = rhs for J = I - w D (D semiseparable, see evaluate) in O(N), batched."""
    A, Bd, C, e = fac
    B, N = A.shape
    # three affine runs: (u, sigma) = (0,0), (1,0), (0,1)
    P = np.zeros((B, 3))
    U = np.zeros((B, 3))
    S = np.zeros((B, 3))
    U[:, 1] = 1.0
    S[:, 2] = 1.0
    X = np.zeros((B, N, 3))
    R = np.zeros((B, 3))
    w = np.broadcast_to(np.asarray(w, dtype=float), (B, N))
    for i in range(N):
        wi = w[:, i]
        gam = 1.0 - wi * Bd[:, i] + wi * C[:, i] + wi * e[:, i]
        R[:, 0] = rhs[:, i]
        wc = wi[:, None]
        xi = (R + wc * A[:, i, None] * P + wc * U + wc * e[:, i, None] * S) / gam[:, None]
        X[:, i] = xi
        P += xi
        U -= C[:, i, None] * xi
        S -= xi
    # final U, S must vanish; run 0 is the particular part, runs 1 and 2 are homogeneous
    a11, a12, a21, a22 = U[:, 1], U[:, 2], S[:, 1], S[:, 2]
    b1, b2 = -U[:, 0], -S[:, 0]
    det = a11 * a22 - a12 * a21
    det = np.where(det == 0, 1e-300, det)
    u = (b1 * a22 - a12 * b2) / det
    s = (a11 * b2 - a21 * b1) / det
    x = X[:, :, 0] + u[:, None] * X[:, :, 1] + s[:, None] * X[:, :, 2]
    return x


def newton_step(w, fac: Factors, r: np.ndarray) -> Tuple[np.ndarray, Optional[np.ndarray]]:
    """Newton step dx (B, N) solving J dx = -r, and J (B, N, N) when it was assembled."""
    B, N = r.shape
    if N <= DENSE_MAX_N:
        J = dense_jacobian(w, fac)
        try:
            dx = np.linalg.solve(J, -r[:, :, None])[:, :, 0]
        except np.linalg.LinAlgError:
            dx = np.linalg.lstsq(J[0], -r[0], rcond=None)[0][None] if B == 1 else \
                np.stack([np.linalg.lstsq(J[b], -r[b], rcond=None)[0] for b in range(B)])
        return dx, J
    return structured_solve(w, fac, -r), None


def principal_ok(w, fac: Factors) -> np.ndarray:
    """Branch check for a directly solved case: every eigenvalue of the Newton Jacobian has a
    positive real part (J = I at zero load; reaching another branch means an eigenvalue
    crossed zero). (B,) bool; N <= DENSE_MAX_N only."""
    J = dense_jacobian(w, fac)
    ev = np.linalg.eigvals(J)
    return np.min(ev.real, axis=1) > 1e-9

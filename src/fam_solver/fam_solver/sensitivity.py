"""Analytic sensitivity of a converged FAM shape to its tip force (exact arc model).

At a converged solution the arc angles phi (N,) satisfy r(phi, F) = 0 with (see ``fam``)

    r_i = phi_i - w_i Mbar_i,    Mbar_i = m - Im(Z_i conj(F)),    w_i = l_i / EI,

Z_i = (P_N - P_i) + l_i e^{i theta_{i-1}} q(phi_i) the lever of the tip force about arc i
(complex notation of ``arcs``). The moment is LINEAR in the dead tip force F = fx + i fy:

    dr_i/dfx = w_i Im Z_i,      dr_i/dfy = -w_i Re Z_i,

so the implicit function theorem gives dphi/dF = -(dr/dphi)^-1 dr/dF with the same analytic
Jacobian dr/dphi that Newton uses. A point at arc-length fraction tau inside arc i,
z = P_{i-1} + l_i e^{i theta_{i-1}} tau g(phi_i tau), moves with the arc angles as

    dz/dphi_j = l_j e^{i theta_{j-1}} g'(phi_j) + i (z - P_j)    (j < i: arc j's end moves,
                                                                 everything beyond rotates)
    dz/dphi_i = l_i e^{i theta_{i-1}} tau^2 g'(phi_i tau),        dz/dphi_j = 0 (j > i).

The arcs are held FIXED (the shape's own ``arc_lengths``, graded or equal): this is the
derivative of the FAM on that mesh. A graded ``solve_fam`` re-places its arcs for every
force, which moves the points by a further amount of the order of the change of the
discretisation error (tiny next to the shape change itself; the tests measure it).
No rclpy here.
"""
from __future__ import annotations

from typing import Tuple

import numpy as np
from numpy.typing import ArrayLike

from scipy.linalg.lapack import dgesv as _dgesv

from .arcs import _CCOEF, SERIES_LIMIT, _powers, arc_funcs
from .model import Shape, _bounds, _locate

_MASKS = {}
_MAXR = np.maximum.reduce


def _masks(n):
    """Strictly-lower mask (N, N), flat diagonal stride and the column index row."""
    m = _MASKS.get(n)
    if m is None:
        if len(_MASKS) > 32:
            _MASKS.clear()
        m = _MASKS[n] = (np.tri(n, n, -1, dtype=bool), np.arange(n))
    return m


def shape_sensitivity(shape: Shape, tip_force: ArrayLike, s: ArrayLike, ei: float,
                      tip_moment: float = 0.0) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points, their derivative with respect to the tip force, and unit tangents.

    shape: a converged ``Shape`` of the exact arc model under a dead (base-frame) tip force
    and tip moment only (what ``solve_fam(cat, Loads(tip_force=..., tip_moment=...))``
    returns). tip_force: (2,) N, the force it was solved for. s: arc-length fractions (k,) in
    [0, 1]. ei: bending stiffness EI, N m^2. tip_moment: N m.

    Returns points (k, 2) m, dpoints (k, 2, 2) m/N (dpoints[p, c, f] = d points[p, c] /
    d tip_force[f], arcs held fixed) and tangents (k, 2) (unit).
    """
    if getattr(shape, 'arc_model', 'exact') != 'exact':
        raise ValueError(f'shape must be of the exact arc model, got {shape.arc_model!r}')
    if not getattr(shape, 'converged', False):
        raise ValueError('shape must be a converged solution')
    f = np.asarray(tip_force, dtype=float)
    if f.shape != (2,) or not np.all(np.isfinite(f)):
        raise ValueError(f'tip_force must be finite with shape (2,), got {tip_force!r}')
    if not (np.isfinite(ei) and ei > 0):
        raise ValueError(f'ei must be positive and finite, got {ei}')
    if not np.isfinite(tip_moment):
        raise ValueError(f'tip_moment must be finite, got {tip_moment}')
    s = np.atleast_1d(np.asarray(s, dtype=float))
    if s.ndim != 1 or not np.all(np.isfinite(s)) or np.any(s < 0) or np.any(s > 1):
        raise ValueError('s must be a 1-D array of fractions in [0, 1]')
    phi = shape.arc_angles
    l = np.asarray(shape.arc_lengths, dtype=float)
    n = phi.size
    w = l / float(ei)
    th_end = np.cumsum(phi)
    th_start = th_end - phi
    E = np.exp(1j * th_start)
    lE = l * E
    i, tau = _locate(_bounds(l / l.sum()), s)
    k = s.size
    # one call for the arcs and the partial arcs up to the points
    x = np.concatenate([phi, phi[i] * tau])
    if _MAXR(np.abs(x)) < SERIES_LIMIT:      # arc_funcs' series, without its dispatch
        G, Q, GP, QP = (_powers(x) @ _CCOEF).T
    else:
        G, Q, GP, QP = arc_funcs(x)
    g, q, gp, qp = G[:n], Q[:n], GP[:n], QP[:n]
    gt, gpt = G[n:], GP[n:]
    P = np.cumsum(lE * g)                                  # arc end points
    rel = P[-1] - P
    cF = complex(f[0], -f[1])
    Z = rel + lE * q
    ZF = Z * cF
    # dr/dphi, as in fam._fast_tip_newton (dead load)
    C = ((1j * rel + lE * gp) * cF).imag
    Bd = ((1j * rel + lE * qp) * cF).imag
    lower, cols = _masks(n)
    J = np.where(lower, ZF.real[:, None], C) * w[:, None]
    J.flat[::n + 1] = w * Bd + 1.0
    dr_dF = np.empty((n, 2))
    dr_dF[:, 0] = -w * Z.imag                              # minus: dphi = J^-1 (-dr/dF)
    dr_dF[:, 1] = w * Z.real
    _, _, dphi, info = _dgesv(J, dr_dF)                   # (N, 2)
    if info != 0:
        raise ValueError('shape is singular (a critical load): no sensitivity')
    # points and their derivative with respect to phi
    lEi = lE[i]
    z = P[i] - lEi * g[i] + lEi * tau * gt
    Dz = (lE * gp) + 1j * (z[:, None] - P)
    Dz = np.where(cols < i[:, None], Dz, 0.0)
    Dz[np.arange(k), i] = lEi * tau * tau * gpt
    dz = Dz @ dphi                                         # (k, 2) complex
    points = np.stack([z.real, z.imag], axis=1)
    dpoints = np.stack([dz.real, dz.imag], axis=1)
    ang = th_start[i] + phi[i] * tau
    tangents = np.stack([np.cos(ang), np.sin(ang)], axis=1)
    return points, dpoints, tangents

"""How well a tip force is determined by the shape it produces: the covariance of the force
from the FAM model's Jacobian, per estimate (FAM inversion) or tabulated over the force
range (learned models).

The observed curve is compared with the FAM shape at n points along the arc length; the
points carry an effective noise `SHAPE_NOISE` (m) each. With J the Jacobian of the points
with respect to (fx, fy, delta, eps) (the force, where the observed curve starts along the
catheter and how its arc length stretches; see fam_inverse), the information is

    A = J^T J / sigma^2 + diag(1 / s_f^2, 1 / s_f^2, 1 / s_delta^2, 1 / s_eps^2)

(the prior widths: s_f the force range, s_delta and s_eps the nuisance priors of the
inversion) and the force's covariance is the 2x2 force block of A^-1 (the nuisance
parameters marginalised). An axial pull barely bends an inextensible catheter: there the
column of J for the axial component is nearly zero and only the prior bounds its variance,
so the covariance shows the cone of directions the shape cannot resolve.

`SHAPE_NOISE` is calibrated (force_estimator.train, on the tuning camera styles) so that
the errors of the FAM inversion through the image pipeline match the covariance on
observable estimates: it is larger than the centreline's point error (about 0.04 mm)
because the cubic Bezier curve's deviation from the true centreline is correlated along
the curve.

Pure numpy; no rclpy. fam_solver is imported when a table is built.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ['SHAPE_NOISE', 'FORCE_PRIOR', 'ALIGN_SIGMA', 'STRETCH_SIGMA',
           'force_covariance', 'ObservabilityTable', 'build_table']

#: effective noise of each compared point of the observed curve, m (calibrated: see train)
SHAPE_NOISE = 1.0e-4
#: prior width of each force component, N (the force range, 0.3 N full scale)
FORCE_PRIOR = 0.3
#: prior width of the arc-length offset of the observed curve's start, m
ALIGN_SIGMA = 1e-3
#: prior width of the relative stretch of the observed curve's arc length
STRETCH_SIGMA = 0.02


def force_covariance(J: np.ndarray, sigma: float = SHAPE_NOISE,
                     force_prior: float = FORCE_PRIOR) -> np.ndarray:
    """The marginal 2x2 covariance (N^2) of the force from the point Jacobian J (2n, 4)
    (columns fx, fy, delta, eps; m/N, m/N, m/m, m) at point noise sigma (m)."""
    A = J.T @ J / sigma ** 2
    A[0, 0] += 1.0 / force_prior ** 2
    A[1, 1] += 1.0 / force_prior ** 2
    A[2, 2] += 1.0 / ALIGN_SIGMA ** 2
    A[3, 3] += 1.0 / STRETCH_SIGMA ** 2
    C = np.linalg.inv(A)[:2, :2]
    C = 0.5 * (C + C.T)
    return C


@dataclass
class ObservabilityTable:
    """Force covariances (A, M, 2, 2) N^2 on a polar grid of forces: angles (A,) rad
    (equally spaced over the circle, from angles[0]) x magnitudes (M,) N (from 0)."""
    angles: np.ndarray
    magnitudes: np.ndarray
    cov: np.ndarray

    def lookup(self, force) -> np.ndarray:
        """The covariance at force (2,) N (or (k, 2) -> (k, 2, 2)), bilinear in (angle,
        magnitude); magnitudes beyond the table use its last row."""
        f = np.asarray(force, dtype=float)
        one = f.ndim == 1
        f = f.reshape(-1, 2)
        mag = np.hypot(f[:, 0], f[:, 1])
        A = len(self.angles)
        step = 2.0 * np.pi / A
        t = ((np.arctan2(f[:, 1], f[:, 0]) - self.angles[0]) / step) % A
        i0 = np.floor(t).astype(int) % A
        i1 = (i0 + 1) % A
        wa = (t - np.floor(t))[:, None, None]
        m = self.magnitudes
        j = np.clip(np.searchsorted(m, mag) - 1, 0, len(m) - 2)
        wm = np.clip((mag - m[j]) / (m[j + 1] - m[j]), 0.0, 1.0)[:, None, None]
        c = self.cov
        out = ((1 - wa) * ((1 - wm) * c[i0, j] + wm * c[i0, j + 1])
               + wa * ((1 - wm) * c[i1, j] + wm * c[i1, j + 1]))
        return out[0] if one else out

    def arrays(self) -> dict:
        return dict(obs_angles=self.angles, obs_magnitudes=self.magnitudes, obs_cov=self.cov)

    @classmethod
    def from_arrays(cls, a: dict) -> 'ObservabilityTable':
        t = cls(np.asarray(a['obs_angles'], float), np.asarray(a['obs_magnitudes'], float),
                np.asarray(a['obs_cov'], float))
        A, M = len(t.angles), len(t.magnitudes)
        if t.cov.shape != (A, M, 2, 2) or A < 4 or M < 2 or not np.isfinite(t.cov).all() \
                or not np.isfinite(t.angles).all() or np.any(np.diff(t.magnitudes) <= 0):
            raise ValueError('observability table arrays are inconsistent or not finite')
        return t


def point_jacobian(shape, force, frac, ei: float, length: float) -> np.ndarray:
    """The (2n, 4) Jacobian of the FAM points at arc-length fractions frac for a converged
    exact-arc Shape under tip force `force` (columns fx, fy, delta, eps)."""
    from fam_solver.sensitivity import shape_sensitivity
    _, dP, T = shape_sensitivity(shape, force, frac, ei)
    n = len(frac)
    a = np.asarray(frac, float) * length
    J = np.zeros((2 * n, 4))
    J[:, :2] = dP.reshape(2 * n, 2)
    J[:, 2] = T.reshape(-1)
    J[:, 3] = (T * a[:, None]).reshape(-1)
    return J


def build_table(cat, f_max: float = 0.315, n_angles: int = 96, n_magnitudes: int = 15,
                n_points: int = 24, n_arcs: int = 24, sigma: float = SHAPE_NOISE,
                force_prior: float = FORCE_PRIOR) -> ObservabilityTable:
    """Tabulate `force_covariance` over a polar grid of tip forces on catheter `cat`
    (angles half a step off the axes: an exact axial push is a bifurcation point)."""
    from fam_solver import Loads, solve_fam
    step = 2.0 * np.pi / n_angles
    angles = -np.pi + 0.5 * step + step * np.arange(n_angles)
    mags = np.linspace(0.0, f_max, n_magnitudes)
    frac = np.linspace(0.0, 1.0, n_points)
    cov = np.empty((n_angles, n_magnitudes, 2, 2))
    for i, a in enumerate(angles):
        prev = None
        for j, m in enumerate(mags):
            f = (float(m * np.cos(a)), float(m * np.sin(a)))
            s = solve_fam(cat, Loads(tip_force=f), n_arcs=n_arcs, arc_model='exact',
                          spacing='graded', initial=prev)
            if not s.converged:
                s = solve_fam(cat, Loads(tip_force=f), n_arcs=n_arcs, arc_model='exact',
                              spacing='graded')
            try:
                J = point_jacobian(s, f, frac, cat.ei, cat.length)
                cov[i, j] = force_covariance(J, sigma, force_prior)
            except (ValueError, np.linalg.LinAlgError):
                cov[i, j] = np.eye(2) * force_prior ** 2
            prev = s if s.converged else prev
    return ObservabilityTable(angles, mags, cov)

"""Tip force from shape by inverting the Finite Arc Method (no learning).

Given observed Bezier control points P_obs (4, 3) m in catheter_base, find the tip force
f = (fx, fy) N whose FAM shape, fitted with the same cubic Bezier code as the camera path,
has the nearest control points:

    min_f  r(f)^T r(f),   r(f) = vec(P_fam(f)[:, :2] - P_obs[:, :2])   (8 residuals, m)

solved by Levenberg-Marquardt with a finite-difference Jacobian at the start of each
estimate (the base point and the two perturbed forces are one batched FAM solve) and
Broyden rank-one updates afterwards (one FAM solve per further iteration). The start is
the previous estimate (warm start: consecutive camera frames change little) or, for the
first frame or when the warm start ends in a poor fit, the nearest entry of a table of
FAM control points precomputed over the force range.

The confidence is the residual: the RMS control-point distance (m) of the final fit.
A result is `in_envelope` when LM converged, the residual is below `max_residual` and the
force magnitude lies within `f_max`.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from force_estimator.models import control_points_to_features


@dataclass
class FamInverseResult:
    """One estimate: force (2,) N, residual (RMS control-point distance, m), iterations,
    FAM solves used, converged (LM step below tolerance), in_envelope (converged, residual
    below max_residual and |force| <= f_max)."""
    force: np.ndarray
    residual: float
    iterations: int
    solves: int
    converged: bool
    in_envelope: bool


class FamInverseEstimator:
    """Force from control points by Levenberg-Marquardt on the FAM forward model.

    cat: fam_solver.Catheter (length m, ei N m^2). n_arcs: FAM arcs. n_points: centreline
    samples fed to the Bezier fit. f_max: largest plausible force magnitude, N (bounds the
    search, sets the start table). tol: step tolerance, N. max_residual: residual above
    which the estimate is flagged, m. fd_step: finite-difference step, N.
    """

    def __init__(self, cat, n_arcs: int = 12, n_points: int = 60, f_max: float = 0.45,
                 tol: float = 2e-5, max_iter: int = 12, max_residual: float = 5e-4,
                 fd_step: float = 2e-4, table_angles: int = 24, table_magnitudes: int = 12):
        for name, v in (('f_max', f_max), ('tol', tol), ('max_residual', max_residual),
                        ('fd_step', fd_step)):
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f'{name} must be positive and finite, got {v}')
        if int(n_arcs) < 1:
            raise ValueError(f'n_arcs must be >= 1, got {n_arcs}')
        if int(n_points) < 8:
            raise ValueError(f'n_points must be >= 8, got {n_points}')
        if int(max_iter) < 1:
            raise ValueError(f'max_iter must be >= 1, got {max_iter}')
        from catheter_shape import fit_bezier
        from fam_solver import solve_fam_batch
        self.cat = cat
        self.n_arcs = int(n_arcs)
        self.n_points = int(n_points)
        self.f_max = float(f_max)
        self.tol = float(tol)
        self.max_iter = int(max_iter)
        self.max_residual = float(max_residual)
        self.fd_step = float(fd_step)
        self._solve_batch = solve_fam_batch
        self._fit = fit_bezier
        self._last: Optional[np.ndarray] = None
        self.last_result: Optional[FamInverseResult] = None
        # start table over the half plane fy >= 0 and its mirror (fy < 0)
        ang = np.linspace(-np.pi, np.pi, 2 * table_angles, endpoint=False)
        mag = self.f_max * np.arange(1, table_magnitudes + 1) / table_magnitudes
        A, M = np.meshgrid(ang, mag, indexing='ij')
        F = np.concatenate([[[0.0, 0.0]],
                            np.stack([M.ravel() * np.cos(A.ravel()),
                                      M.ravel() * np.sin(A.ravel())], axis=1)])
        self._table_f = F
        self._table_c = self._shape_cp(F)

    def reset(self) -> None:
        """Forget the warm start (e.g. after a jump in the image stream)."""
        self._last = None

    # forward model: forces (m, 2) N -> control points x, y (m, 8) m
    def _shape_cp(self, forces: np.ndarray) -> np.ndarray:
        b = self._solve_batch(self.cat, forces, np.zeros(len(forces)), n_arcs=self.n_arcs)
        cl = b.centerlines(self.n_points)
        pts = np.zeros((self.n_points, 3))
        out = np.empty((len(forces), 8))
        for i in range(len(forces)):
            pts[:, :2] = cl[i]
            out[i] = self._fit(pts, degree=3)[:, :2].reshape(8)
        return out

    def _table_start(self, c_obs: np.ndarray) -> np.ndarray:
        d = ((self._table_c - c_obs) ** 2).sum(axis=1)
        return self._table_f[int(np.argmin(d))].copy()

    def _solve(self, c_obs: np.ndarray, f0: np.ndarray):
        h = self.fd_step
        F = np.array([f0, f0 + (h, 0.0), f0 + (0.0, h)])
        C = self._shape_cp(F)
        solves = 3
        f = f0.copy()
        r = C[0] - c_obs
        J = np.stack([(C[1] - C[0]) / h, (C[2] - C[0]) / h], axis=1)    # (8, 2)
        cost = r @ r
        mu = 1e-3 * np.trace(J.T @ J) / 2.0 + 1e-30
        converged = False
        it = 0
        for it in range(1, self.max_iter + 1):
            A = J.T @ J
            g = J.T @ r
            step = -np.linalg.solve(A + mu * np.diag(np.diag(A) + 1e-30), g)
            # keep |f| <= 1.5 f_max: the search never wanders far off the force range
            fn = f + step
            nf = np.hypot(fn[0], fn[1])
            if nf > 1.5 * self.f_max:
                fn *= 1.5 * self.f_max / nf
                step = fn - f
            cn = self._shape_cp(fn[None])[0]
            solves += 1
            rn = cn - c_obs
            costn = rn @ rn
            # Broyden rank-one update of J along the step taken (accepted or not)
            ss = step @ step
            if ss > 0:
                J += np.outer((rn - r) - J @ step, step) / ss
            if costn < cost:
                f, r, cost = fn, rn, costn
                mu = max(mu / 5.0, 1e-12)
                if np.sqrt(ss) < self.tol:
                    converged = True
                    break
            else:
                mu *= 8.0
                if np.sqrt(ss) < self.tol:
                    converged = True    # no descent left at the tolerance scale
                    break
        return f, cost, it, solves, converged

    def estimate(self, control_points) -> FamInverseResult:
        """Full result for one observation: control_points (4, 3) m (z ignored)."""
        x = control_points_to_features(control_points)
        if x.ndim != 1:
            raise ValueError('control_points must have shape (4, 3) for estimate()')
        c_obs = x.reshape(4, 3)[:, :2].reshape(8)
        starts = []
        if self._last is not None:
            starts.append(self._last)
        starts.append(self._table_start(c_obs))
        best = None
        total = 0
        for f0 in starts:
            f, cost, it, solves, conv = self._solve(c_obs, f0)
            total += solves
            res = float(np.sqrt(cost / 4.0))      # RMS distance over the 4 control points
            if best is None or res < best[1]:
                best = (f, res, it, conv)
            if conv and res <= self.max_residual:
                break
        f, res, it, conv = best
        inside = bool(conv and res <= self.max_residual and np.hypot(*f) <= self.f_max)
        self._last = f.copy()
        out = FamInverseResult(force=f, residual=res, iterations=it, solves=total,
                               converged=bool(conv), in_envelope=inside)
        self.last_result = out
        return out

    @property
    def last_residual(self) -> float:
        """Residual of the last estimate, m (nan before the first)."""
        return float('nan') if self.last_result is None else self.last_result.residual

    def predict(self, control_points, return_flags: bool = False):
        """Tip force (fx, fy) N from control points (4, 3) m -> (2,); (B, 4, 3) -> (B, 2)
        (a batch is processed in order, each warm-starting the next).
        return_flags: also return in_envelope (bool or (B,) bool)."""
        x = np.asarray(control_points, dtype=float)
        if x.ndim == 3:
            res = [self.estimate(xi) for xi in x]
            F = np.array([r.force for r in res]).reshape(-1, 2)
            flags = np.array([r.in_envelope for r in res], dtype=bool)
            return (F, flags) if return_flags else F
        r = self.estimate(x)
        return (r.force, r.in_envelope) if return_flags else r.force

"""Tip force from shape by inverting the Finite Arc Method (no learning).

Given observed Bezier control points P_obs (4, 3) m in catheter_base (from the camera path),
find the tip force f = (fx, fy) N whose FAM shape best matches the observed curve:

    min_f  r(f)^T r(f),   r_j(f) = x_FAM(f; a_j) - c_obs(a_j),   j = 1..n_points

where c_obs is the observed cubic Bezier curve re-sampled at equal *absolute* arc lengths
a_j in [0, min(L_obs, L)] (L_obs its own length, L the catheter length) and x_FAM(f; a) the
FAM centreline at arc length a. So the fit compares shapes, point for point along the
catheter.

Why shapes, not control points. The brief suggested comparing the FAM shape's control
points (its centreline fitted with the camera path's `fit_bezier`) with the observed ones.
Measured during development: the cubic control points of one and the same curve moved by
up to 5.8 mm between the camera path and a fit of the exact centreline, and by more between
fitting variants, because a cubic only approximates the catheter and its inner control
points can slide along the curve at almost no cost in fit error; a fit with adaptive
stopping also makes them a non-smooth function of the force (poison for a finite-difference
Jacobian), and each fit costs milliseconds. The curve itself is what both sides agree on
(the camera fit lies within about 0.1 mm of the true centreline), and comparing curves needs
no fit inside the loop: each iteration is one batched FAM solve. Two nuisance parameters
absorb where the observed curve starts and how its arc length stretches (a fitted cubic ends
a fraction of a millimetre short of the true ends); without them the force error through
the camera was 3x larger.

Accuracy is set by the FAM model error: on eight clean rod-solver (elastica) shapes fitted
with the camera path's `fit_bezier`, the force error was 1-11 mN with 12 arcs (FAM tip error
about 0.07 mm = 0.1 % L) and 0.3-2.4 mN with 24 arcs (the largest errors for post-buckled,
curled shapes whose form barely changes with the load). More arcs cost time in proportion;
the node uses 24.

Solver: Gauss-Newton with Levenberg-Marquardt damping over (fx, fy, delta, eps) with an
ANALYTIC Jacobian (decision; `solver="analytic"`, the default). At a converged FAM solution
R(phi, f) = 0 the arc angles move as dphi/df = -(dR/dphi)^-1 dR/df: dR/dphi is the analytic
Newton Jacobian of the solver, and dR/df is cheap because the internal moment is linear in a
dead tip force; the points along the arc length are closed-form functions of phi
(`fam_solver.sensitivity.shape_sensitivity`, ~0.1 ms for 24 arcs). So each iteration is
ONE warm-started `solve_fam` (the residual, exact) plus the sensitivity, instead of the base
force and two forward-difference perturbations (three solves). The sensitivity holds the
arcs of the solved shape fixed, while `solve_fam`'s graded arcs are re-placed for every
force; the neglected part is small (measured: at most 0.015 % of the force columns with
24 arcs at 0.1-0.22 N, up to 0.65 % with 12 arcs at 0.22 N) and only slows the
Gauss-Newton contraction: the residual, and so the minimiser, are those of the graded FAM
as before (same MAE on the benchmark frames). The previous forward-difference variants stay
available (`solver="single"`:
three warm-started `solve_fam` calls per iteration; `"batch"`: one `solve_fam_batch` call
of three forces) as the reference in tests and benchmark.

A Gauss-Newton step below the tolerance is taken without another solve. The start is the
previous estimate (warm start: consecutive camera frames change little; more precisely the
last force evaluated there, whose FAM shape is kept, so a streamed frame often needs a
single new solve) and, when that fails to fit, the nearest entry of a table of FAM shapes
precomputed over the force range (both bending directions), looked up only then. After an
'axial_unobservable' estimate the warm start drops the previous force's component along
the weak direction (the prior's mean there is 0): the shape had not determined it, and a
guessed push beyond the buckling load made the next, loaded frame's inversion crawl for 8
iterations and fall back to the table (12 solves instead of 2-5 in the system scene). And
while the force along the weak direction stays unobservable at the current point (its std
above `UNOBSERVABLE_STD`), that warm start steps only across it (`hold_unobservable`); where
the shape does determine it (a push near the buckling load), the point's std there is below
the threshold and the iteration moves freely. The contact-onset frame after
straight ones (0.2 mN lateral) had its fit at the shape noise after one solve, then crawled
along the axial direction through cost changes below one noise unit, 8 solves without
converging, and then through two table starts: 17 solves, 'not_converged' (force_estimator
README, round 10). The warm start after any other estimate is held the same way where it
reaches such a point (judged with the shape noise alone: a start still far from the new
frame's fit is not unobservable because of its residual), after setting the force along
the weak direction to the prior's mean there (again if the direction turns, at most 3
times): a straight frame after a bent one took 9 solves crawling along the axial
direction, now 5-6, with the same answer (issue 15, 2026-12-03).

A weak prior on the force (`FORCE_PRIOR`, the force range, per component) keeps the
iteration where the shape says nothing: an axial pull leaves an inextensible catheter
straight, and without the prior the iteration drifted along that flat direction to the
edge of its search (straight control points gave 0.675 N); with it the axial component
stays near 0 and its uncertainty says that it is unknown.

Confidence: `residual`, the RMS point distance (m) between the observed curve and the
best FAM shape, and the force's covariance from the Jacobian at the solution
(force_estimator.uncertainty: `SHAPE_NOISE` per point, or the residual when larger). The
result's status: 'not_converged'; 'no_fit' (residual above `max_residual`);
'out_of_envelope' (|f| > f_max: the force is scaled back to f_max); else 'ok' or
'axial_unobservable' (the weakest direction's std above 0.03 N); `in_envelope` is True
for the last two.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Optional

import numpy as np

from force_estimator.estimate import (DOMAIN_UNKNOWN, ForceEstimate, bounded, domain_distance,
                                      failed_estimate, status_of, unobservable_direction)
from force_estimator.inputs import control_points_to_features
from force_estimator.inputs import check_control_points
from force_estimator.uncertainty import (ALIGN_SIGMA, FORCE_PRIOR, SHAPE_NOISE,
                                         STRETCH_SIGMA, force_covariance)

#: Jacobian variants: analytic force columns (default) or forward differences
SOLVERS = ('analytic', 'single', 'batch')


#: FAM solves after which an estimate begins no further start (`FamInverseEstimator`'s
#: max_solves): a warm start plus one table start, the most an estimate needed in the
#: replays of recorded runs (5) and round 6's contact-onset frame (12); in a real-time split
#: run one estimate tried every start, 35 solves, 34 ms CPU (catheter_bringup README,
#: round 9)
MAX_SOLVES = 12


@dataclass
class FamInverseResult(ForceEstimate):
    """One estimate (a ForceEstimate, method 'fam') and the inversion's details: residual
    (RMS point distance to the FAM shape, m), iterations, FAM solves used, converged (LM step
    below tolerance). in_envelope: the estimate is normal (converged, residual below
    max_residual, |force| <= f_max)."""
    residual: float = float('nan')
    iterations: int = 0
    solves: int = 0
    converged: bool = False

    @property
    def in_envelope(self) -> bool:
        return self.normal


class FamInverseEstimator:
    """Force from control points by Gauss-Newton / Levenberg-Marquardt on the FAM shape.

    cat: fam_solver.Catheter (length m, ei N m^2). n_arcs: FAM arcs. n_points: points
    compared along the catheter. f_max: largest plausible force magnitude, N (bounds the
    search, sets the start table). tol: step tolerance, N. max_iter: iterations per start.
    max_residual: RMS distance above which the estimate is flagged, m. fd_step:
    finite-difference step, N. table_angles x table_magnitudes: start table over the full
    circle of force directions. solver: "analytic" (default; one warm-started `solve_fam`
    per iteration, force columns of the Jacobian from `fam_solver.sensitivity`), "single"
    (forward differences: three warm-started `solve_fam` calls per iteration; fd_step is
    used only by this and "batch") or "batch" (one `solve_fam_batch` call of three forces
    per iteration). max_solves: no further start begins once an estimate has spent this
    many FAM solves (the best so far is its answer): bounds an estimate's cost at about
    max_solves + one start's. hold_unobservable: the warm start keeps the force along the
    weak direction at the prior's mean while the shape does not determine it (after an
    'axial_unobservable' estimate from the start, after another where it gets there; False:
    it moves freely, as before round 10; for comparisons).
    """

    def __init__(self, cat, n_arcs: int = 12, n_points: int = 24, f_max: float = 0.45,
                 tol: float = 1e-4, max_iter: int = 8, max_residual: float = 5e-4,
                 fd_step: float = 1e-4, table_angles: int = 64, table_magnitudes: int = 30,
                 solver: str = 'analytic', max_solves: int = MAX_SOLVES,
                 hold_unobservable: bool = True):
        for name, v in (('f_max', f_max), ('tol', tol), ('max_residual', max_residual),
                        ('fd_step', fd_step)):
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f'{name} must be positive and finite, got {v}')
        for name, v, lo in (('n_arcs', n_arcs, 1), ('n_points', n_points, 4),
                            ('max_iter', max_iter, 1), ('table_angles', table_angles, 4),
                            ('max_solves', max_solves, 1),
                            ('table_magnitudes', table_magnitudes, 1)):
            if int(v) != v or v < lo:
                raise ValueError(f'{name} must be an integer >= {lo}, got {v!r}')
        if solver not in SOLVERS:
            raise ValueError(f'solver must be one of {SOLVERS}, got {solver!r}')
        from fam_solver import Loads, solve_fam, solve_fam_batch
        from fam_solver.sensitivity import shape_sensitivity
        self._sens = shape_sensitivity
        self.solver = solver
        # circular arcs on the graded mesh: the model the analytic sensitivity is written for
        # (fam_solver's default is now the clothoid arc; at 24 arcs the two differ by ~3e-4 L)
        self._solve_one = functools.partial(solve_fam, arc_model='exact', spacing='graded')
        self._Loads = Loads
        self._prev_shape = None
        self.cat = cat
        self.length = float(cat.length)
        self.n_arcs = int(n_arcs)
        self.n_points = int(n_points)
        self.f_max = float(f_max)
        self.tol = float(tol)
        self.max_iter = int(max_iter)
        self.max_solves = int(max_solves)
        self.hold_unobservable = bool(hold_unobservable)
        self.max_residual = float(max_residual)
        self.fd_step = float(fd_step)
        self._w = 1e-4          # prior rows in metres of shape residual per sigma
        self._solve_batch = functools.partial(solve_fam_batch, arc_model='exact', spacing='graded')
        self._last: Optional[np.ndarray] = None
        self._last_eval: Optional[np.ndarray] = None
        self._shapes = {}          # analytic: FAM shapes by force evaluated in this estimate
        self._n_solves = 0         # FAM solve calls made (solve_fam, or batched calls x 3)
        self.last_result: Optional[FamInverseResult] = None
        # dense Bernstein basis to measure and re-sample the observed curve
        u = np.linspace(0.0, 1.0, 257)
        self._Bu = np.stack([(1 - u) ** 3, 3 * u * (1 - u) ** 2, 3 * u ** 2 * (1 - u), u ** 3],
                            axis=1)
        # start table: FAM shapes on a polar grid of forces (+ the unloaded catheter)
        # half a step off the axis: a start exactly on the pull/push axis would sit on the
        # buckling branch point (FAM then bends to one side arbitrarily)
        ang = np.linspace(-np.pi, np.pi, int(table_angles), endpoint=False) \
            + np.pi / int(table_angles)
        mag = self.f_max * np.arange(1, int(table_magnitudes) + 1) / int(table_magnitudes)
        A, M = np.meshgrid(ang, mag, indexing='ij')
        F = np.concatenate([[[0.0, 0.0]],
                            np.stack([M.ravel() * np.cos(A.ravel()),
                                      M.ravel() * np.sin(A.ravel())], axis=1)])
        b = self._solve_batch(cat, F, np.zeros(len(F)), n_arcs=self.n_arcs)
        ok = b.converged
        self._table_f = F[ok]
        self._table_frac = np.linspace(0.0, 1.0, 65)
        self._table_pts = b.points_at(self._table_frac)[ok]          # (T, 65, 2)
        # the same, laid out for the start search: rows by fraction, contiguous over T
        self._tab_x = np.ascontiguousarray(self._table_pts[:, :, 0].T)   # (65, T)
        self._tab_y = np.ascontiguousarray(self._table_pts[:, :, 1].T)
        self._tab_n2 = self._tab_x ** 2 + self._tab_y ** 2
        quad = (self._table_f[:, 0] >= 0).astype(int) * 2 + (self._table_f[:, 1] >= 0)
        self._tab_quads = [np.flatnonzero(quad == q) for q in range(4)]

    def reset(self) -> None:
        """Forget the warm start (e.g. after a jump in the image stream)."""
        self._last = None
        self._last_eval = None
        self._prev_shape = None
        self._shapes = {}

    def observed_points(self, control_points) -> np.ndarray:
        """The observed curve re-sampled at n_points equal arc lengths from its base up to
        min(its length, L): (n_points, 2) m. Also sets the arc-length fractions compared."""
        x = control_points_to_features(control_points)
        if x.ndim != 1:
            raise ValueError('control_points must have shape (4, 3)')
        P = x.reshape(4, 3)[:, :2]
        pts = self._Bu @ P
        cum = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))])
        length = min(cum[-1], self.length)
        if not length > 0:
            raise ValueError('control_points describe a curve of zero length')
        a = np.linspace(0.0, length, self.n_points)
        obs = np.stack([np.interp(a, cum, pts[:, 0]), np.interp(a, cum, pts[:, 1])], axis=1)
        self._frac = a / self.length
        self._a = a
        return obs

    def _table_starts(self, obs: np.ndarray, k: int = 3) -> list:
        """Up to k start forces: the nearest table shape in each force quadrant (sign of fx,
        fy), nearest first. Slightly bent shapes look alike under a push and a pull, so
        the search may start on the wrong side; the next quadrant is the fallback."""
        idx = np.rint(self._frac * 64).astype(int)
        # squared distances |table - obs|^2 summed over the points, minus the constant |obs|^2
        # (rows gathered contiguously; the cross term as two matrix-vector products)
        d = self._tab_n2[idx].sum(axis=0) - 2.0 * (obs[:, 0] @ self._tab_x[idx]
                                                   + obs[:, 1] @ self._tab_y[idx])
        best = []
        for sel in self._tab_quads:
            if sel.size:
                i = sel[np.argmin(d[sel])]
                best.append((d[i], i))
        best.sort()
        return [self._table_f[i].copy() for _, i in best[:k]]

    def _eval(self, x: np.ndarray, obs: np.ndarray):
        """Residual, Jacobian and cost at x = (fx, fy, delta, eps).

        The FAM shape is compared at arc lengths a'_j = delta + (1 + eps) a_j: delta (m) and
        eps absorb where the observed curve starts and how its parameterisation stretches
        (a fitted cubic ends a fraction of a millimetre short of the true ends), so only the
        shape decides the force. FAM solves of f and its two forward-difference perturbations
        (three warm-started single solves, or one batched call); the delta/eps columns come
        from the FAM tangent. Two prior rows keep
        delta ~ 0 +- `ALIGN_SIGMA` m and eps ~ 0 +- `STRETCH_SIGMA`."""
        f = x[:2]
        ap = np.clip(x[2] + (1.0 + x[3]) * self._a, 0.0, self.length)
        frac = ap / self.length
        n = self.n_points
        J = np.zeros((2 * n + 4, 4))
        if self.solver == 'analytic':
            base = self._solve_base(f)
            if base is None:
                return None, None, np.inf
            try:
                P0, dP, T = self._sens(base, f, frac, self.cat.ei)
            except ValueError:                   # singular FAM Jacobian (critical load)
                return None, None, np.inf
            J[:2 * n, :2] = dP.reshape(2 * n, 2)
            return self._finish(x, obs, P0, T, J)
        h = self.fd_step
        dh = 1e-4
        fr2 = np.where(frac + dh / self.length <= 1.0, frac + dh / self.length,
                       frac - dh / self.length)
        if self.solver == 'batch':
            b = self._solve_batch(self.cat, np.array([f, f + (h, 0.0), f + (0.0, h)]),
                                  np.zeros(3), n_arcs=self.n_arcs)
            self._n_solves += 3
            if not b.converged.all():
                return None, None, np.inf
            P = b.points_at(frac)
            P2 = b.points_at(fr2)[0]
        else:
            # three single solves, each warm-started (the base from the previous base shape,
            # the perturbations from the base): cheaper than one batched call
            base = self._solve_base(f)
            if base is None:
                return None, None, np.inf
            self._n_solves += 2
            sx = self._solve_one(self.cat, self._Loads(tip_force=(float(f[0]) + h, float(f[1]))),
                                 n_arcs=self.n_arcs, initial=base)
            sy = self._solve_one(self.cat, self._Loads(tip_force=(float(f[0]), float(f[1]) + h)),
                                 n_arcs=self.n_arcs, initial=base)
            if not (sx.converged and sy.converged):
                return None, None, np.inf
            P = np.stack([base.points_at(frac), sx.points_at(frac), sy.points_at(frac)])
            P2 = base.points_at(fr2)
        T = (P2 - P[0]) / (fr2 - frac)[:, None] / self.length   # unit tangent
        J[:2 * n, 0] = (P[1] - P[0]).reshape(-1) / h
        J[:2 * n, 1] = (P[2] - P[0]).reshape(-1) / h
        return self._finish(x, obs, P[0], T, J)

    def _solve_base(self, f):
        """Warm-started FAM solve at force f (from the previous base shape; cold if that
        fails). The converged Shape (also kept as the next warm start), or None."""
        key = (float(f[0]), float(f[1]))
        base = self._shapes.get(key)
        if base is not None:
            self._prev_shape = base
            return base
        loads = self._Loads(tip_force=key)
        base = self._solve_one(self.cat, loads, n_arcs=self.n_arcs, initial=self._prev_shape)
        self._n_solves += 1
        if not base.converged and self._prev_shape is not None:
            base = self._solve_one(self.cat, loads, n_arcs=self.n_arcs)
            self._n_solves += 1
        if not base.converged:
            return None
        self._prev_shape = base
        if self.solver == 'analytic':
            self._shapes[key] = base
        return base

    def _finish(self, x, obs, P0, T, J):
        """Residual, Jacobian (force columns already in J) and cost from the FAM points P0
        (n_points, 2) m and unit tangents T (n_points, 2) at the compared arc lengths."""
        n = self.n_points
        w = self._w
        r = np.concatenate([(P0 - obs).reshape(-1),
                            [x[2] / ALIGN_SIGMA * w, x[3] / STRETCH_SIGMA * w,
                             x[0] / FORCE_PRIOR * w, x[1] / FORCE_PRIOR * w]])
        J[:2 * n, 2] = T.reshape(-1)
        J[:2 * n, 3] = (T * self._a[:, None]).reshape(-1)
        J[2 * n, 2] = w / ALIGN_SIGMA
        J[2 * n + 1, 3] = w / STRETCH_SIGMA
        J[2 * n + 2, 0] = w / FORCE_PRIOR
        J[2 * n + 3, 1] = w / FORCE_PRIOR
        cost = float(r @ r)
        if not (np.isfinite(cost) and np.isfinite(J).all()):
            return r, J, np.inf
        return r, J, cost

    def _solve(self, obs: np.ndarray, x0: np.ndarray, hold: bool = False):
        """LM from x0 = (fx, fy[, delta, eps]). Returns (x = (fx, fy, delta, eps), shape cost,
        iterations, FAM solves, converged); the shape cost excludes the prior rows.

        hold: where the force along the weakest direction is unobservable at the current point
        (`_unobservable`), set it to the prior's mean (0) and step only across it (the warm
        starts; not the table's: held there, the benchmark frames' errors grew)."""
        # returns (x, x_eval, ...): x_eval is the last evaluated point (its FAM shape is
        # cached), x may be one Gauss-Newton step below the tolerance beyond it
        x = np.zeros(4)
        x0 = np.asarray(x0, dtype=float)
        x[:len(x0)] = x0
        n0 = self._n_solves
        r, J, cost = self._eval(x, obs)
        if not np.isfinite(cost):
            return x, x, np.inf, 0, self._n_solves - n0, False, None
        xe = x                                   # the last x with a FAM solve behind it
        mu = 1e-4
        converged = False
        dropped = 0
        it = 0
        n2 = 2 * self.n_points
        for it in range(1, self.max_iter + 1):  # noqa: B007 (the count is returned)
            v = self._unobservable(J) if hold else None
            if v is not None and dropped < 3 and abs(float(x[:2] @ v)) > self.tol:
                # found unobservable here: the force along v to the prior's mean (0), then
                # held there (again if the direction turns as the shape changes, at most 3
                # times)
                dropped += 1
                xd = x.copy()
                xd[:2] -= float(x[:2] @ v) * v
                rd, Jd, cd = self._eval(xd, obs)
                if np.isfinite(cd):
                    x, r, J, cost = xd, rd, Jd, cd
                    xe = x
                    v = self._unobservable(J)
            if v is None:
                A = J.T @ J
                step = -np.linalg.solve(A + mu * np.diag(np.diag(A)) + 1e-30 * np.eye(4),
                                        J.T @ r)
            else:
                # the force along v is not determined by the shape here: step only across it
                # (fx, fy = a (-v_y, v_x)) and in delta, eps; the force along v stays where the
                # start put it (after an unobservable estimate: the prior's mean, 0)
                Pm = np.zeros((4, 3))
                Pm[0, 0], Pm[1, 0], Pm[2, 1], Pm[3, 2] = -v[1], v[0], 1.0, 1.0
                Jr = J @ Pm
                A = Jr.T @ Jr
                step = Pm @ -np.linalg.solve(A + mu * np.diag(np.diag(A)) + 1e-30 * np.eye(3),
                                             Jr.T @ r)
            xn = x + step
            nf = np.hypot(xn[0], xn[1])
            if nf > 1.5 * self.f_max:            # stay within reach of the force range
                xn[:2] *= 1.5 * self.f_max / nf
                step = xn - x
            small = bool(np.hypot(step[0], step[1]) < self.tol)
            if small and mu < 1e-2:
                # a Gauss-Newton step below the tolerance: take it without another solve
                x = xn
                converged = True
                break
            rn, Jn, cn = self._eval(xn, obs)
            if cn <= cost:
                x, r, J, cost = xn, rn, Jn, cn
                xe = x
                mu = max(0.2 * mu, 1e-9)
                if small:
                    converged = True
                    break
            else:
                mu = max(10.0 * mu, 1e-2)
                if small:                        # no descent left at the tolerance scale
                    converged = True
                    break
        shape_cost = float(r[:n2] @ r[:n2])
        return x, xe, shape_cost, it, self._n_solves - n0, converged, J[:n2].copy()

    def _unobservable(self, J: np.ndarray) -> Optional[np.ndarray]:
        """The weakest direction (2,) of the force covariance at the current point (J: its
        Jacobian) with the shape noise alone, when its std is above UNOBSERVABLE_STD (as an
        estimate's there, 'axial_unobservable'), else None. Not with the point's residual
        (as `_result`'s covariance): a start still far from a new frame's fit would be taken
        for unobservable by its residual (a streamed ok frame: 5 solves instead of 2)."""
        n2 = 2 * self.n_points
        cov = self._covariance(J[:n2], 0.0)
        return unobservable_direction(cov)

    @staticmethod
    def _covariance(J: np.ndarray, res: float) -> np.ndarray:
        """Force covariance (2, 2) N^2 from the shape rows of the Jacobian (2 n_points, 4)
        and the fit residual res m (shape noise SHAPE_NOISE per point, or res when larger);
        the prior's alone when J is not usable."""
        if np.isfinite(res) and np.all(np.isfinite(J)):
            try:
                return force_covariance(J, max(SHAPE_NOISE, res), FORCE_PRIOR)
            except np.linalg.LinAlgError:
                pass
        return np.eye(2) * FORCE_PRIOR ** 2

    def estimate(self, control_points) -> FamInverseResult:
        """Full result for one observation: control_points (4, 3) m (z ignored), or (4, 2).

        Raises ValueError (naming control_points) for a wrong shape; non-finite or absurd
        (> 1 m) coordinates, or a curve of zero length, give a result with the status
        'non_finite_input' / 'bad_input' and force 0."""
        bad = check_control_points(control_points)
        if bad is not None:
            status, msg = bad
            r = failed_estimate(status, 'fam', msg, self.f_max)
            out = FamInverseResult(**{k: getattr(r, k) for k in
                                      ('force', 'covariance', 'status', 'method', 'primary',
                                       'domain_distance', 'message')})
            self.last_result = out
            return out
        try:
            obs = self.observed_points(control_points)
        except ValueError as exc:
            r = failed_estimate('bad_input', 'fam', str(exc), self.f_max)
            out = FamInverseResult(force=r.force, covariance=r.covariance, status='bad_input',
                                   method='fam', primary='fam', domain_distance=DOMAIN_UNKNOWN,
                                   message=str(exc))
            self.last_result = out
            return out
        starts = []
        if self._last is not None:
            # analytic: from the last evaluated point, whose FAM shape is cached (saves the
            # first solve; the step beyond it was below the tolerance)
            x0 = self._last_eval if self.solver == 'analytic' else self._last
            prev = self.last_result
            if prev is not None and prev.status == 'axial_unobservable':
                # the shape did not determine the force along the weak direction: start at
                # the prior's mean there (0), not at the guess (a push beyond the buckling
                # load warm-started the next, loaded frame 8 iterations from its answer)
                # (a component below the tolerance is left: the cached shape stays usable)
                w = prev.weak_direction
                along = float(x0[:2] @ w)
                if abs(along) > self.tol:
                    x0 = x0.copy()
                    x0[:2] -= along * w
                starts.append(('hold', x0))
            else:
                starts.append(('warm', x0))
            key = (float(self._last_eval[0]), float(self._last_eval[1]))
            self._shapes = {key: self._shapes[key]} if key in self._shapes else {}
        else:
            self._shapes = {}
        starts.append(('table', None))         # the table starts, looked up only if needed
        best = None
        total = 0
        while starts:
            kind, f0 = starts.pop(0)
            if f0 is None:
                starts = [('table', f) for f in self._table_starts(obs)]
                continue
            if kind == 'table':
                self._prev_shape = None        # a far warm start could pick another branch
            x, xe, cost, it, solves, conv, J = self._solve(
                obs, f0, hold=kind in ('hold', 'warm') and self.hold_unobservable)
            total += solves
            res = float(np.sqrt(cost / self.n_points))
            if best is None or res < best[1]:
                best = (x, res, it, conv, xe, J)
            if conv and res <= 0.5 * self.max_residual:
                break
            if total >= self.max_solves:
                break                           # the budget is spent: the best so far
        x, res, it, conv, xe, J = best
        if np.isfinite(res):
            self._last = x.copy()
            self._last_eval = xe.copy()
        out = self._result(x[:2], res, it, total, conv, J)
        self.last_result = out
        return out

    def _result(self, f, res, it, solves, conv, J) -> FamInverseResult:
        """The estimate from the best solution: force bounded by f_max, covariance from the
        Jacobian (shape noise SHAPE_NOISE per point, or the fit residual when larger)."""
        force, clipped = bounded(f, self.f_max)
        cov = self._covariance(J, res) if J is not None else np.eye(2) * FORCE_PRIOR ** 2
        status, msg = status_of(
            cov, (not conv, 'not_converged', 'the FAM inversion did not converge'),
            (not res <= self.max_residual, 'no_fit', lambda: f'no tip force explains the shape: '
             f'residual {1e3 * res:.3f} mm > {1e3 * self.max_residual:.3f} mm'),
            (clipped, 'out_of_envelope',
             lambda: f'|f| = {np.hypot(*f):.3g} N > f_max {self.f_max:g} N (scaled back)'))
        dist = domain_distance(res / self.max_residual if np.isfinite(res) else np.inf)
        return FamInverseResult(force=force, covariance=cov, status=status, method='fam',
                                primary='fam', domain_distance=dist, message=msg,
                                residual=res, iterations=it, solves=solves,
                                converged=bool(conv))

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
            for xi in x:
                self.observed_points(xi)               # ValueError before any estimate
            res = [self.estimate(xi) for xi in x]
            F = np.array([r.force for r in res]).reshape(-1, 2)
            flags = np.array([r.in_envelope for r in res], dtype=bool)
            return (F, flags) if return_flags else F
        self.observed_points(x)             # ValueError for bad input (predict's contract)
        r = self.estimate(x)
        return (r.force, r.in_envelope) if return_flags else r.force

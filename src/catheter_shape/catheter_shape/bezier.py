"""Bezier curves: evaluation, least-squares fitting (thesis Eqs. 2-5) with parameter
correction, and perpendicular (orthogonal) distances of points to a curve.

Pure numpy; no rclpy. Control points are an array (n + 1, D) for degree n in D
dimensions (D = 2 or 3 here, any D works); points are (N, D); parameters s are in [0, 1].
Units are whatever the points carry (metres in this project).
"""
from __future__ import annotations

from dataclasses import dataclass
from math import comb
from typing import Optional

import numpy as np

__all__ = ['CORRECTIONS', 'BezierFit', 'bernstein', 'bezier_eval', 'bezier_derivative',
           'chord_length_params',
           'fit_bezier', 'fit_bezier_detailed', 'project_points', 'bezier_distance']


def _as_points(points, name: str = 'points', min_rows: int = 1) -> np.ndarray:
    try:
        p = np.asarray(points, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f'{name} must be a numeric array (N, D): {exc}') from None
    if p.ndim != 2 or p.shape[1] < 1:
        raise ValueError(f'{name} must have shape (N, D), got {p.shape}')
    if p.shape[0] < min_rows:
        raise ValueError(f'{name} needs at least {min_rows} rows, got {p.shape[0]}')
    if not np.all(np.isfinite(p)):
        raise ValueError(f'{name} contains non-finite values')
    return p


def _as_ctrl(ctrl) -> np.ndarray:
    c = _as_points(ctrl, 'control_points', min_rows=2)
    return c


def bernstein(s, degree: int) -> np.ndarray:
    """Bernstein basis matrix (len(s), degree + 1): B[i, j] = C(n, j) s_i^j (1 - s_i)^(n - j).

    For degree 3 its transpose is the thesis's Lambda (Eq. 5)."""
    if int(degree) != degree or degree < 0:
        raise ValueError(f'degree must be an integer >= 0, got {degree!r}')
    degree = int(degree)
    s = np.asarray(s, dtype=float).reshape(-1)
    j = np.arange(degree + 1)
    return _binom(degree) * (s[:, None] ** j) * ((1.0 - s)[:, None] ** (degree - j))


_BINOM: dict = {}
_B2P: dict = {}


def _binom(n: int) -> np.ndarray:
    b = _BINOM.get(n)
    if b is None:
        b = _BINOM[n] = np.array([comb(n, k) for k in range(n + 1)], dtype=float)
    return b


def _bez2pow(n: int) -> np.ndarray:
    """(n+1, n+1) matrix taking Bezier control points to power-basis coefficients:
    c(s) = sum_k a_k s^k with a = _bez2pow(n) @ ctrl."""
    m = _B2P.get(n)
    if m is None:
        m = np.zeros((n + 1, n + 1))
        for k in range(n + 1):
            for i in range(k + 1):
                m[k, i] = comb(n, k) * comb(k, i) * (-1) ** (k - i)
        _B2P[n] = m
    return m


def bezier_eval(control_points, s) -> np.ndarray:
    """Curve points c(s), shape (len(s), D), of the Bezier curve with control points (n+1, D) (Eq.
    3)."""
    c = _as_ctrl(control_points)
    return bernstein(s, c.shape[0] - 1) @ c


def bezier_derivative(control_points, order: int = 1) -> np.ndarray:
    """Control points (n + 1 - order, D) of the order-th derivative curve d^k c / ds^k."""
    c = _as_ctrl(control_points)
    for _ in range(order):
        n = c.shape[0] - 1
        if n < 1:
            return np.zeros((1, c.shape[1]))
        c = n * np.diff(c, axis=0)
    return c


def chord_length_params(points) -> np.ndarray:
    """Normalised cumulative chord length (Eq. 2): s_0 = 0, s_{N-1} = 1, shape (N,).

    Raises ValueError when the points have zero total length."""
    p = _as_points(points, min_rows=2)
    d = np.sqrt(np.sum(np.diff(p, axis=0) ** 2, axis=1))
    total = d.sum()
    if not total > 0:
        raise ValueError('points have zero total length: cannot parameterise by arc length')
    s = np.empty(p.shape[0])
    s[0] = 0.0
    np.cumsum(d, out=s[1:])
    s /= total
    s[-1] = 1.0
    return s


@dataclass
class BezierFit:
    """A fitted curve: control_points (n+1, D), the final parameter of every point (N,),
    the mean and max perpendicular distance of the points to the curve (same unit as the
    points), and the mean distance at the chord-length parameters before correction."""
    control_points: np.ndarray
    params: np.ndarray
    residual: float
    max_distance: float
    chord_residual: float


def _constraint_map(n1: int, D: int, start, start_tangent):
    """Affine parameterisation of the control points, vec(C) = c0 + M x (point-major)."""
    size = n1 * D
    c0 = np.zeros(size)
    if start is None:
        return c0, np.eye(size)
    c0[:D] = start
    if start_tangent is None:
        M = np.zeros((size, size - D))
        M[D:, :] = np.eye(size - D)
        return c0, M
    c0[D:2 * D] = start
    M = np.zeros((size, 1 + size - 2 * D))
    M[D:2 * D, 0] = start_tangent
    M[2 * D:, 1:] = np.eye(size - 2 * D)
    return c0, M


def _solve_ls(B: np.ndarray, p: np.ndarray, c0: np.ndarray, M: np.ndarray) -> np.ndarray:
    """Least-squares control points (n+1, D) for basis B (N, n+1), points p (N, D) and the
    affine constraint vec(C) = c0 + M x. Unconstrained this is the Moore-Penrose
    solution of Eq. 4 (computed with lstsq, better conditioned than the normal equations)."""
    n1 = B.shape[1]
    D = p.shape[1]
    if M.shape[1] == n1 * D:
        return np.linalg.lstsq(B, p, rcond=None)[0]
    A = np.einsum('ij,de->idje', B, np.eye(D)).reshape(B.shape[0] * D, n1 * D)
    x = np.linalg.lstsq(A @ M, p.reshape(-1) - A @ c0, rcond=None)[0]
    return (c0 + M @ x).reshape(n1, D)


#: weight of the tangential residual in the Gauss-Newton step (0 = pure TDM)
_TANGENT_WEIGHT = 0.03


def _tdm_step(ctrl: np.ndarray, p: np.ndarray, s: np.ndarray, c0: np.ndarray,
              M: np.ndarray, tw: float = _TANGENT_WEIGHT, t_offset=None,
              reg=None) -> np.ndarray:
    """One tangent-distance-minimisation (Gauss-Newton on the perpendicular distances)
    update of the control points for points p at their foot-point parameters s."""
    n = ctrl.shape[0] - 1
    N, D = p.shape
    B = bernstein(s, n)
    r = B @ ctrl - p
    t = bernstein(s, n - 1) @ bezier_derivative(ctrl, 1)
    tn = np.linalg.norm(t, axis=1, keepdims=True)
    t = t / np.where(tn > 0, tn, 1.0)
    if reg is not None:
        # the regularized problem with the parameters eliminated: per-point tangential
        # weight sqrt(mu / (|c'|^2 + mu)) and tangential residual t.r - |c'| (s - s0)
        mu, s0 = reg
        g = tn[:, 0] ** 2
        tw = np.sqrt(mu / (g + mu)) if mu > 0 else np.zeros_like(g)
        t_offset = tn[:, 0] * (s - s0)
    if D == 2:
        # one normal per point: scalar signed distances e_i = n_i . r_i
        # plus the tangential part with a small weight: it keeps the step well-posed when
        # the normals are nearly parallel (an almost straight catheter), where pure TDM
        # cannot place the inner control points along the line
        nrm = np.stack([-t[:, 1], t[:, 0]], axis=1)
        tw = (tw[:, None] if np.ndim(tw) else tw) * t
        A = np.vstack([(B[:, :, None] * nrm[:, None, :]).reshape(N, (n + 1) * D),
                       (B[:, :, None] * tw[:, None, :]).reshape(N, (n + 1) * D)])
        tr = np.sum(tw * r, axis=1)
        if t_offset is not None:
            tr = tr - (np.sqrt(np.sum(tw * tw, axis=1)) * t_offset)
        rhs = -np.concatenate([np.sum(nrm * r, axis=1), tr])
    else:
        # normal space (D - 1 dimensions) through its projector, plus the tangential row
        P = np.eye(D)[None] - t[:, :, None] * t[:, None, :]
        twv = (tw[:, None] if np.ndim(tw) else tw) * t
        tr = np.sum(twv * r, axis=1)
        if t_offset is not None:
            tr = tr - np.sqrt(np.sum(twv * twv, axis=1)) * t_offset
        A = np.vstack([np.einsum('ij,ide->idje', B, P).reshape(N * D, (n + 1) * D),
                       (B[:, :, None] * twv[:, None, :]).reshape(N, (n + 1) * D)])
        rhs = -np.concatenate([np.einsum('ide,ie->id', P, r).reshape(-1), tr])
    # the first and last points keep s = 0 and s = 1: their full distance counts, so the
    # curve starts and ends at the data instead of running past it
    ends = np.einsum('ij,de->idje', B[[0, -1]], np.eye(D)).reshape(2 * D, (n + 1) * D)
    A = np.vstack([A, ends])
    rhs = np.concatenate([rhs, -r[[0, -1]].reshape(-1)])
    # M has orthonormal columns (selection / unit tangent), so dC = M dx
    dx = np.linalg.lstsq(A @ M, rhs, rcond=None)[0]
    return ctrl + (M @ dx).reshape(n + 1, D)


def _anchored(s: np.ndarray) -> np.ndarray:
    s[0], s[-1] = 0.0, 1.0
    return s


def _newton_params(ctrl: np.ndarray, p: np.ndarray, s: np.ndarray, steps: int,
                   s0: Optional[np.ndarray] = None, mu: float = 0.0) -> np.ndarray:
    """Newton steps on (c(s) - p) . c'(s) + mu (s - s0) = 0 for every point, clamped to
    [0, 1] (mu = 0: the orthogonal foot point; mu > 0: held towards s0).
    Evaluated in the power basis (a few numpy calls per step: this is the hot loop)."""
    n = ctrl.shape[0] - 1
    k = np.arange(n + 1)
    A = _bez2pow(n) @ ctrl
    A1 = A[1:] * k[1:, None]                           # c'(s)  = sum_j A1[j] s^j
    A2 = A1[1:] * k[1:n, None]                         # c''(s) = sum_j A2[j] s^j
    for _ in range(steps):
        S = _powers(s, n)
        r = S @ A - p
        c1 = S[:, :n] @ A1
        g = np.einsum('ij,ij->i', c1, c1)
        f = np.einsum('ij,ij->i', r, c1)
        fp = g + np.einsum('ij,ij->i', r, S[:, :n - 1] @ A2) if n >= 2 else g
        if mu > 0:
            f = f + mu * (s - s0)
            fp = fp + mu
        # a Newton step where the objective is locally convex, none otherwise
        ok = fp > 1e-12 * g + 1e-300
        step = np.divide(f, fp, out=np.zeros_like(f), where=ok)
        s = np.clip(s - step, 0.0, 1.0)
    return s


def _project_global(c: np.ndarray, p: np.ndarray, samples: int, steps: int) -> np.ndarray:
    n = c.shape[0] - 1
    ss = np.linspace(0.0, 1.0, samples)
    cs = bernstein(ss, n) @ c
    d2 = (np.sum(p * p, axis=1)[:, None] - 2.0 * p @ cs.T + np.sum(cs * cs, axis=1)[None, :])
    return _newton_params(c, p, ss[np.argmin(d2, axis=1)], steps)


def _powers(s: np.ndarray, n: int) -> np.ndarray:
    """(N, n + 1) powers s^0 .. s^n (np.vander, increasing, in one ufunc call)."""
    return s[:, None] ** _EXPONENTS[:n + 1]


_EXPONENTS = np.arange(11, dtype=float)


def _dist(c: np.ndarray, p: np.ndarray, s: np.ndarray) -> np.ndarray:
    r = _powers(s, c.shape[0] - 1) @ (_bez2pow(c.shape[0] - 1) @ c) - p
    return np.sqrt(np.einsum('ij,ij->i', r, r))


def project_points(control_points, points, params=None, steps: int = 8,
                   samples: int = 0) -> tuple:
    """Orthogonal projection of points (N, D) onto the curve: returns (s (N,), distances (N,)).

    Starts from `params` when given, otherwise from the nearest of `samples` (default
    max(64, 16 (n+1))) equally spaced curve samples, then Newton steps."""
    c = _as_ctrl(control_points)
    p = _as_points(points)
    if p.shape[1] != c.shape[1]:
        raise ValueError(f'points have D={p.shape[1]} but control_points D={c.shape[1]}')
    n = c.shape[0] - 1
    if params is None:
        s = _project_global(c, p, samples or max(64, 16 * (n + 1)), steps)
    else:
        s = np.clip(np.asarray(params, dtype=float).reshape(-1), 0.0, 1.0)
        if s.size != p.shape[0]:
            raise ValueError(f'params has {s.size} entries for {p.shape[0]} points')
        s = _newton_params(c, p, s, steps)
    return s, _dist(c, p, s)


def bezier_distance(control_points, points) -> np.ndarray:
    """Perpendicular (closest-point) distance (N,) of each point to the curve."""
    return project_points(control_points, points)[1]


def _fit_regularized(ctrl, p, s, degree, c0, M, lam, rounds, tol):
    """Minimise J = sum |c(s_i) - p_i|^2 + mu sum (s_i - s0_i)^2 over the control points
    and the parameters, mu = lam * mean |c'(s0)|^2 (s0: chord length). Eliminating each
    s_i gives a Gauss-Newton step of the same form as TDM with a per-point tangential
    weight sqrt(mu / (|c'_i|^2 + mu)): the penalty makes the problem well-conditioned
    along reparameterisations of the curve, where the orthogonal fit is flat."""
    n = degree
    s0 = s.copy()
    d1 = bezier_derivative(ctrl, 1)
    g0 = np.sum((bernstein(s0, n - 1) @ d1) ** 2, axis=1)
    mu = lam * float(g0.mean())

    def solve_s(c, s_start):
        return _anchored(_newton_params(c, p, s_start, 2, s0, mu))

    def objective(c, ss):
        return float(np.sum(_dist(c, p, ss) ** 2) + mu * np.sum((ss - s0) ** 2))
    s = solve_s(ctrl, s)
    J = objective(ctrl, s)
    for _ in range(rounds):
        trial = _tdm_step(ctrl, p, s, c0, M, reg=(mu, s0))
        if not np.all(np.isfinite(trial)):
            break
        s_t = solve_s(trial, s)
        J_t = objective(trial, s_t)
        if J_t >= J:
            break                   # at the noise floor: Gauss-Newton no longer helps
        done = (J - J_t) <= tol * 0.1 * J
        ctrl, s, J = trial, s_t, J_t
        if done:
            break
    return ctrl, s


#: parameter-correction methods of fit_bezier: 'regularized' (default), 'orthogonal', 'none'
CORRECTIONS = ('regularized', 'orthogonal', 'none')


def fit_bezier_detailed(points, degree: int = 3, *, params=None, refine: int = 3,
                        start=None, start_tangent=None, tol: float = 1e-3,
                        correction: str = 'regularized', param_weight: float = 0.05,
                        global_residual: bool = True, project: bool = True) -> BezierFit:
    """Least-squares Bezier fit of ordered points (N, D) (thesis Eqs. 2-5) with parameter
    correction.

    points: (N, D), ordered from the start (s = 0) to the end (s = 1); N >= degree + 1.
    params: optional initial parameters (N,) in [0, 1]; default normalised chord length (Eq. 2).
    correction: how the chord-length parameters are corrected after the first solve:
        'regularized' (default): each round moves every point's parameter towards its foot
            point on the curve, held back by a penalty param_weight * mean|c'|^2 * (s - s0)^2
            from its chord-length value s0, then re-solves Eq. 4. Most of the accuracy of
            an orthogonal fit, and control points as stable as the thesis's (they are the
            features of the force estimator: see the benchmark's jitter table).
        'orthogonal': minimises the perpendicular distances (foot points by Newton, then a
            Gauss-Newton step on the normal distances, Levenberg-Marquardt-like damping).
            Smallest residual, but along near-reparameterisations of the curve the problem
            is flat: the inner control points then move by millimetres with pixel noise.
        'none': the thesis's chord-length fit (same as refine=0).
    refine: at most this many correction rounds (0 = the thesis's chord-length fit).
    param_weight: the penalty of 'regularized' (dimensionless, >= 0; 0 = no penalty).
    global_residual: also search the whole curve for each point's closest point when
        computing the residual (robust; False uses the local foot points only).
    project: compute the points' foot points, residual and max_distance (default). False
        (with 'regularized'): return the fit's own (regularized) parameters and NaN for the
        distances, for a caller that projects its points itself (the sensor projects every
        centreline point, not only those fitted).
    tol: 'orthogonal' stops once a round lowers the mean squared distance by less than this
        fraction; 'regularized' once no control point moves by more than tol * 1e-2 of the
        points' extent (0 runs all `refine` rounds).
    start: optional (D,) point that p0 is fixed to (e.g. the clamp).
    start_tangent: optional (D,) direction; p1 is then constrained to p0 + a * t (needs start).
    Returns a BezierFit whose residual is the mean perpendicular distance.
    """
    if int(degree) != degree or degree < 1:
        raise ValueError(f'degree must be an integer >= 1, got {degree!r}')
    degree = int(degree)
    p = _as_points(points, min_rows=degree + 1)
    if int(refine) != refine or refine < 0:
        raise ValueError(f'refine must be a non-negative integer, got {refine!r}')
    D = p.shape[1]
    if start is not None:
        start = np.asarray(start, dtype=float).reshape(-1)
        if start.shape != (D,) or not np.all(np.isfinite(start)):
            raise ValueError(f'start must be a finite point of dimension {D}')
    if start_tangent is not None:
        if start is None:
            raise ValueError('start_tangent needs start')
        t = np.asarray(start_tangent, dtype=float).reshape(-1)
        nt = np.linalg.norm(t) if t.shape == (D,) else 0.0
        if t.shape != (D,) or not np.isfinite(nt) or nt == 0:
            raise ValueError(f'start_tangent must be a finite non-zero vector of dimension {D}')
        start_tangent = t / nt
        if degree < 2:
            raise ValueError('start_tangent needs degree >= 2')
    if params is None:
        s = chord_length_params(p)
    else:
        s = np.asarray(params, dtype=float).reshape(-1)
        if s.size != p.shape[0] or not np.all(np.isfinite(s)):
            raise ValueError(f'params must be {p.shape[0]} finite values')
        s = np.clip(s, 0.0, 1.0)
    if correction not in CORRECTIONS:
        raise ValueError(f'correction must be one of {CORRECTIONS}, got {correction!r}')
    if not (np.isfinite(param_weight) and param_weight >= 0):
        raise ValueError(f'param_weight must be >= 0, got {param_weight!r}')
    if correction == 'none':
        refine = 0
    c0, M = _constraint_map(degree + 1, D, start, start_tangent)
    ctrl = _solve_ls(bernstein(s, degree), p, c0, M)
    chord_res = float(np.mean(_dist(ctrl, p, s)))
    if correction == 'regularized' and refine > 0:
        ctrl, s = _fit_regularized(ctrl, p, s, degree, c0, M, param_weight, int(refine), tol)
        if not project:
            return BezierFit(control_points=ctrl, params=s, residual=float('nan'),
                             max_distance=float('nan'), chord_residual=chord_res)
        refine = 0                                   # skip the orthogonal loop below
    # Parameter correction: foot points by Newton (orthogonal projection), then a
    # Gauss-Newton step on the perpendicular distances (tangent distance minimisation).
    # A step is kept only if it lowers the mean squared perpendicular distance.
    s = _anchored(_newton_params(ctrl, p, s, 2))
    dist = _dist(ctrl, p, s)
    err = float(np.mean(dist ** 2))
    # Levenberg-Marquardt-like control of the tangential weight: smaller after a good
    # step (towards pure TDM, fast convergence), larger after a bad one (towards a plain
    # point-distance step, safe). Every trial counts as a round.
    tw = _TANGENT_WEIGHT
    for _ in range(int(refine)):
        if err <= 1e-30:
            break
        trial = _tdm_step(ctrl, p, s, c0, M, tw)
        if not np.all(np.isfinite(trial)):
            tw *= 10.0
            continue
        s_t = _anchored(_newton_params(trial, p, s, 3))
        e_t = float(np.mean(_dist(trial, p, s_t) ** 2))
        if e_t >= err:
            if tw >= 1.0:
                break
            tw = min(1.0, tw * 10.0)
            continue
        improved = err - e_t
        ctrl, s, err = trial, s_t, e_t
        tw = max(tw / 3.0, 1e-6)
        if improved <= tol * err:
            break
    # final residual: the closest point, from the fit's parameters and from a coarse
    # global search (guards against a local foot point), whichever is nearer
    s = _newton_params(ctrl, p, s, 4)
    dist = _dist(ctrl, p, s)
    if global_residual:
        s_g = _project_global(ctrl, p, 8 * (degree + 1), 4)
        d_g = _dist(ctrl, p, s_g)
        better = d_g < dist
        s = np.where(better, s_g, s)
        dist = np.where(better, d_g, dist)
    return BezierFit(control_points=ctrl, params=s, residual=float(dist.mean()),
                     max_distance=float(dist.max()), chord_residual=chord_res)


def fit_bezier(points, degree: int = 3, *, params=None, refine: int = 3, start=None,
               start_tangent=None, tol: float = 1e-3, correction: str = 'regularized',
               param_weight: float = 0.05) -> np.ndarray:
    """Control points (degree + 1, D) of the least-squares Bezier curve through ordered
    points (N, D); see fit_bezier_detailed for the options. refine=0 gives the thesis's
    chord-length Moore-Penrose fit (Eq. 4)."""
    return fit_bezier_detailed(points, degree, params=params, refine=refine, start=start,
                               start_tangent=start_tangent, tol=tol, correction=correction,
                               param_weight=param_weight).control_points

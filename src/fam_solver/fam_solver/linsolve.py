"""Linear algebra of the FAM Newton step: the Jacobian J = I - W D from its semiseparable
factors (see ``equations.evaluate``), dense for N <= DENSE_MAX_N and O(N) beyond (a forward
sweep vectorised over cases, or one banded LAPACK solve for a single case), and the branch /
stability check on its eigenvalues. No rclpy here.
"""
from __future__ import annotations

import math
from typing import Optional, Tuple

import numpy as np
from scipy.linalg.lapack import dgbsv as _dgbsv, dgeev as _dgeev, dpotrf as _dpotrf

from .equations import Factors

DENSE_MAX_N = 64
#: one case (B = 1): the banded solve from this N on (measured: dense 17 / banded 16 us at
#: N = 24, 47 / 20 us at N = 64)
BANDED_MIN_N = 24


_TRIL_CACHE = {}
#: chord (simplified Newton) steps, which reuse the last Jacobian's factors: only with a
#: Jacobian built where max|r| was below CHORD_MAX_RES (rad), near the solution, where the
#: rates are predictable, and with a predicted contraction of max|r| below CHORD_MAX_RATIO
CHORD_MAX_RES = 1e-2
CHORD_MAX_RATIO = 0.1
#: a chord step right after a Newton step contracts max|r| by ~2x the Newton step's ratio
#: (theory: e' = K e_J e against e' = (K/2) e^2); measured over the cliff bench's cases
#: (N = 1-64, both sets, circular and clothoid arcs, 476 chord steps): median 2.1x, 90 % below
#: 7.7x (those at Newton ratios below 1e-4, which land far below tol anyway); this factor
#: predicts it
CHORD_GROWTH = 4.0


def chord_pays(res: float, res_prev: float, res_jac: float, tol: float,
               after_chord: bool) -> bool:
    """Whether the next step of the fast kernels should be a chord step (the last Jacobian's
    LU factors again: a back-substitution) rather than a Newton step (a new Jacobian and its
    factorisation).

    res: max|r| now, res_prev: before the last step, res_jac: where the Jacobian in hand was
    built; after_chord: the last step was a chord step. Near a root the error falls as
    e' = K e_J e per chord step (e_J: where the Jacobian was built) and e' = (K/2) e^2 per
    Newton step. The last step's ratio q = res / res_prev gives the chord steps' ratio (q
    itself after a chord step, CHORD_GROWTH q after a Newton step) and a Newton step's ratio
    now, q res / res_jac (then chord steps at that ratio). The chord step is taken when chord
    steps alone are predicted to reach tol in no more steps than a Newton step followed by
    chord steps (a chord step saves less than a residual evaluation costs: measured at
    N = 1-64, the Jacobian's build and LU cost 0.5-1.6 chord steps). Typically the last step
    of a solve becomes a chord step when it lands below tol: then one more step costs a
    residual evaluation and a back-substitution, not a Jacobian (the staircase of the solve
    time over N, issue 15)."""
    if not (res_jac <= CHORD_MAX_RES and 0.0 < res < res_prev):
        return False
    q = res / res_prev
    qc = q if after_chord else CHORD_GROWTH * q
    if not qc < CHORD_MAX_RATIO:
        return False
    n_chord = math.ceil(math.log(tol / res) / math.log(qc))
    qn = q * res / res_jac
    e1 = qn * res
    n_newton = 1 if e1 <= tol else 1 + math.ceil(math.log(tol / e1) / math.log(qn))
    return n_chord <= n_newton


def limited_step(phi: np.ndarray, dx: np.ndarray, step_limit: float) -> Optional[np.ndarray]:
    """The Newton update ``phi - dx`` of the fast paths, with dx scaled down (in place) to a
    largest component of `step_limit` rad; None when dx is not finite (the caller stops)."""
    mx = np.maximum.reduce(np.abs(dx))
    if not mx < np.inf:
        return None
    if mx > step_limit:
        dx *= step_limit / mx
    return phi - dx


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
    if N <= DENSE_MAX_N and not (B == 1 and N > BANDED_MIN_N):
        J = dense_jacobian(w, fac)
        try:
            dx = np.linalg.solve(J, -r[:, :, None])[:, :, 0]
        except np.linalg.LinAlgError:
            dx = np.linalg.lstsq(J[0], -r[0], rcond=None)[0][None] if B == 1 else \
                np.stack([np.linalg.lstsq(J[b], -r[b], rcond=None)[0] for b in range(B)])
        return dx, J
    if B == 1:
        # one case (solve_fam's general path: Bezier, point forces): one LAPACK banded solve,
        # cheaper than the dense solve from BANDED_MIN_N arcs on and than the vectorised
        # sweep's Python loop over the arcs beyond DENSE_MAX_N (~10x at N = 100)
        w1 = np.asarray(w, dtype=float)
        dx = banded_solve(w1[0] if w1.ndim == 2 else w1, tuple(None if f is None else f[0]
                                                              for f in fac), -r[0])
        if np.all(np.isfinite(dx)):
            return dx[None], None
    return structured_solve(w, fac, -r), None


def principal_ok(w, fac: Factors) -> np.ndarray:
    """Branch check for a directly solved case: every eigenvalue of the Newton Jacobian has a
    positive real part (J = I at zero load; reaching another branch means an eigenvalue
    crossed zero). (B,) bool; N <= DENSE_MAX_N only. One case: ``energy_stable`` (the same
    criterion, a Cholesky factorisation first: 10x cheaper than the eigenvalues at N = 64)."""
    J = dense_jacobian(w, fac)
    if J.shape[0] == 1:
        w1 = np.broadcast_to(np.asarray(w, dtype=float), J.shape[:2])[0]
        return np.array([energy_stable(J[0], w1)])
    ev = np.linalg.eigvals(J)
    return np.min(ev.real, axis=1) > 1e-9


def banded_solve(w: np.ndarray, fac: Factors, rhs: np.ndarray) -> np.ndarray:
    """Solve J x = rhs for ONE case, J = I - W D (factors (A, Bd, C, e), each (N,), as in
    ``equations.evaluate``), in O(N) with one LAPACK banded solve (dgbsv).

    Unknowns: the partial sums y_i = x_0 + ... + x_i and z_i = sum_{j > i} C_j x_j, ordered
    (y_0, z_0, y_1, z_1, ...). Row i of J x = rhs and z_i - z_{i+1} = C_{i+1} (y_{i+1} - y_i)
    are then banded (2 sub- and 2 super-diagonals) except for Y = y_{N-1}, which enters row i
    through e_i (follower forces): it is solved for from a second right-hand side."""
    A, Bd, C, e = fac
    n = A.shape[0]
    w = np.broadcast_to(np.asarray(w, dtype=float), (n,))
    wB = 1.0 - w * Bd
    # LAPACK band storage, kl = ku = 2: A[r, c] at ab[4 + r - c, c]
    ab = np.zeros((7, 2 * n))
    ab[4, 0::2] = wB if e is None else wB + w * e      # row i: y_i
    ab[6, 0:-2:2] = -wB[1:] - w[1:] * A[1:]             # row i: y_{i-1}
    ab[3, 1::2] = -w                                     # row i: z_i
    ab[4, 1::2] = 1.0                                    # z-row i: z_i
    ab[2, 3::2] = -1.0                                   # z-row i: -z_{i+1}
    ab[3, 2::2] = -C[1:]                                 # z-row i: -C_{i+1} y_{i+1}
    ab[5, 0:-2:2] = C[1:]                                # z-row i: +C_{i+1} y_i
    follower = e is not None and bool(np.any(e))
    b = np.zeros((2 * n, 2 if follower else 1))
    b[0::2, 0] = rhs
    if follower:
        b[0::2, 1] = w * e
    u = _dgbsv(2, 2, ab, b)[2]
    y = u[0::2, 0]
    if follower:
        Y = y[-1] / (1.0 - u[-2, 1])
        y = y + Y * u[0::2, 1]
    x = np.empty(n)
    x[0] = y[0]
    np.subtract(y[1:], y[:-1], out=x[1:])
    return x


def energy_stable(J: np.ndarray, w: np.ndarray) -> bool:
    """True when every eigenvalue of J (N, N) = I - W D has a real part > 1e-9: the branch and
    stability criterion of ``principal_ok`` for one case.

    Cheap sufficient test first: Re(lambda(J)) >= the smallest eigenvalue of W^1/2 S W^1/2,
    S the symmetric part of W^-1 J, so a Cholesky factorisation of S - 1e-9 W^-1 that succeeds
    proves it (for dead loads on circular arcs W^-1 J is the energy Hessian, symmetric, and
    the test is exact). Otherwise (follower forces, clothoid arcs near a critical point) the
    eigenvalues decide (dgeev)."""
    M = J / w[:, None]
    S = M + M.T
    S.flat[::J.shape[0] + 1] -= 2e-9 / w
    if _dpotrf(S, lower=0, clean=0, overwrite_a=1)[1] == 0:
        return True
    wr = _dgeev(J, compute_vl=0, compute_vr=0)[0]
    return bool(np.min(wr) > 1e-9)

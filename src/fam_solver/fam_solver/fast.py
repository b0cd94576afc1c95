"""Fast path: one load case with tip loads only (force, moment; dead or follower), circular,
clothoid or Bezier arcs, any N -- which equilibrium, with the Newton kernel of ``fast_newton``
(Bezier arcs: ``fast_bezier``).

* N <= FAST_DENSE_MAX_N (64): Newton from the rescaled small-deflection start (with a tip
  moment and axial tension: the stiffened one, ``_stiffened_linear``); accepted when it
  turned the way the small-deflection beam (or its stiffened version) turns and the branch
  check holds (``linsolve.energy_stable``). Otherwise: N > 12 restarts from the 12-arc
  solution; N <= 12: Bezier arcs restart from the circular-arc solution of the same N
  (``_bezier_from_circular``), then (and for the other models) the load is applied by
  continuation on this path (``_continuation``).
* N > FAST_DENSE_MAX_N: Newton (O(N) banded solve) from the COARSE_N solution resampled onto
  the arcs; stability judged on the COARSE_N model, as ``globalise.stability`` does.
* spacing='graded': a second Newton pass on the graded arcs (``mesh.fast_grade``).

Returns None when nothing is accepted (a fold, a critical point, a straight catheter under
compression); the caller then uses the general path (``globalise``). No rclpy here.
"""
from __future__ import annotations

import math
from typing import Optional, Tuple

import numpy as np
from scipy.linalg.lapack import dgesv as _dgesv

from .fast_newton import FAST_DENSE_MAX_N, fast_tip_newton, jacobian_at
from .linsolve import energy_stable
from .mesh import fast_grade
from .problem import COARSE_N

_MAXR = np.maximum.reduce
_MINR = np.minimum.reduce
_EQUAL_CACHE = {}
#: continuation on the fast path: at most this many Newton iterations in all, and steps not
#: below this load fraction (smaller steps mean a fold or a critical point: general path)
_CONT_MAX_ITERS = 200
_CONT_MIN_STEP = 1e-3
#: ... and the intermediate steps solved to this relative tolerance (the last to 1e-12)
_CONT_RTOL = 1e-4
#: models of more arcs whose direct attempt fails start from the solution on this many arcs
#: (which has the branch checks and, if need be, the load continuation on few arcs)
_FALLBACK_N = 12
#: the direct attempt from the small-deflection start is given up after this many Newton
#: iterations still far from a solution (max|r| > fast_newton.QUASI_ABOVE)
_PATIENCE = 4
#: a coarse solution that only starts a finer model is solved to this relative tolerance:
#: resampled onto the fine arcs it is ~1e-3 off anyway (Newton's last step saved)
_START_RTOL = 1e-7

#: the graded second pass starts from the equal-arc solution's tangent angle interpolated by
#: local cubics (``mesh.cubic_start``) on up to this many arcs; beyond, from the tangent angle
#: linear in each equal arc (``remap``): there the cubic start saved a chord step where N - 8
#: saved none (clothoid arcs: N = 24 -> 32, a new 1-3 % drop) and, for circular and Bezier
#: arcs, no step on the median load (package README, round 7)
_CUBIC_MAX_N = 16
#: ... and on at least this many arcs for circular and Bezier arcs (3 for clothoid arcs); on
#: fewer from the curvature (``mesh.curvature_start``; on 2 arcs it is the same parabola,
#: computed in fewer operations): on 3-4 circular or Bezier arcs the cubic start saved no
#: step on the median load and cost 2-6 % more (its ~20 array operations)
_CUBIC_MIN_N = 5


def _graded_start(n: int, clothoid: bool) -> str:
    """The graded second pass's start on n arcs (``mesh.fast_grade``'s `start`): 'remap'
    beyond _CUBIC_MAX_N arcs, 'cubic' from _CUBIC_MIN_N (clothoid arcs from 3), else
    'curvature'."""
    if n > _CUBIC_MAX_N:
        return 'remap'
    return 'cubic' if n >= (3 if clothoid else _CUBIC_MIN_N) else 'curvature'


def _equal_arcs(n: int, L: float, EI: float):
    key = (n, L, EI)
    c = _EQUAL_CACHE.get(key)
    if c is None:
        if len(_EQUAL_CACHE) > 64:
            _EQUAL_CACHE.clear()
        l = np.full(n, L / n)
        c = _EQUAL_CACHE[key] = (l, l / EI, L - (np.cumsum(l) - 0.5 * l))
    return c


def _resample(phi: np.ndarray, n: int) -> np.ndarray:
    """Arc angles of the same curvature (piecewise linear between equal-arc midpoints) on n
    equal arcs: phi_new = kappa(s_mid) L / n."""
    m = phi.size
    sm = (np.arange(m) + 0.5) / m
    sn = (np.arange(n) + 0.5) / n
    return np.interp(sn, sm, phi) * (m / n)


def _continuation(n: int, l: np.ndarray, w: np.ndarray, F: complex, m: float, follower: bool,
                  clothoid: bool, lin: np.ndarray, max_iter: int,
                  bezier: bool = False):
    """Load the case from zero on the fast path (N <= FAST_DENSE_MAX_N): secant predictor (the
    small-deflection shape for the first step), at most 0.5 rad tip-angle change per step,
    the branch check after every step, as ``globalise.continuation`` does; None when the
    path needs steps below _CONT_MIN_STEP (a fold or a critical point) or too many
    iterations: the general path then handles it (snap-through, instability)."""
    th_lin = float(np.max(np.abs(np.add.accumulate(lin))))
    s, ds = 0.0, min(0.5, 0.5 / max(th_lin, 1e-12))
    phi = np.zeros(n)
    prev, prev_s = None, 0.0
    total = 0
    out = None
    while s < 1.0:
        if ds < _CONT_MIN_STEP or total > _CONT_MAX_ITERS:
            return None
        s_new = min(1.0, s + ds)
        guess = lin * s_new if prev is None else phi + (phi - prev) * ((s_new - s) / (s - prev_s))
        last = s_new >= 1.0
        p, c, it, res, tip, J, rho = fast_tip_newton(n, l, w, F * s_new, m * s_new, follower,
                                                     guess, max_iter,
                                                     rtol=1e-12 if last else _CONT_RTOL,
                                                     clothoid=clothoid, bezier=bezier)
        total += it
        if last:
            c = res <= 1e-13 + 1e-12 * _MAXR(np.abs(p))
        else:
            c = res <= 1e-13 + _CONT_RTOL * _MAXR(np.abs(p))
        ok = c and abs(float(p.sum() - phi.sum())) <= 0.5
        if ok:
            Jc = J if J is not None else jacobian_at(p, l, w, F * s_new, m * s_new, follower,
                                                      clothoid, bezier)
            ok = Jc is None or energy_stable(Jc, w)
        if not ok:
            ds *= 0.5
            continue
        prev, prev_s, phi, s = phi, s, p, s_new
        ds = min(ds * 2.0, 0.5)
        out = (p, total, res, tip, rho)
    return out


def _linear_start(lin: np.ndarray, th_lin: float, F: complex, m: float, follower: bool,
                  L: float, EI: float) -> np.ndarray:
    """Newton's start: the small-deflection shape rescaled to a plausible tip angle (towards
    the force for a dead tip force alone, else at most 1.5 rad)."""
    ath = abs(th_lin)
    target = min(ath, 1.5)
    beta = math.atan2(F.imag, F.real)
    if not follower and m == 0.0 and beta != 0.0 and (beta > 0) == (th_lin > 0):
        a_ax = max(0.0, -math.cos(beta)) * abs(F) * L * L / EI / 2
        target = abs(beta) * -math.expm1(-(ath + a_ax) / abs(beta))
    # not target / ath: overflows for denormal loads
    return (lin / ath) * target if ath > 0 else lin


def _coarse_start(n: int, L: float, EI: float, F: complex, m: float, follower: bool,
                  clothoid: bool, nc: int = COARSE_N,
                  bezier: bool = False) -> Optional[Tuple[np.ndarray, int, float]]:
    """The solution on nc arcs (this path) resampled onto n equal arcs, its iterations and
    tip angle; None when the coarse model is not solved on this path."""
    coarse = fast_solve(nc, L, EI, F, m, follower, clothoid=clothoid, rtol=_START_RTOL,
                        bezier=bezier)
    if coarse is None:
        return None
    return _resample(coarse[0], n), coarse[2], float(coarse[0].sum())


def _accepted(phi: np.ndarray, conv: bool, res: float, tip: complex, rtol: float,
              th_c: Optional[float], warm: bool, dense: bool, th_lin: float, l: np.ndarray,
              w: np.ndarray, F: complex, m: float, follower: bool, clothoid: bool,
              lin: np.ndarray, L: float, EI: float, J: Optional[np.ndarray],
              bezier: bool = False) -> bool:
    """Acceptance of a direct solution: converged (to rtol), finite; on the branch of the
    coarse solution it started from (tip angle within 0.5 rad), or else turned the way the
    small-deflection beam (or its stiffened version) turns, or hardly turned at all (other
    branches loop); and the branch check (large loads, warm starts, axial compression)."""
    if rtol != 1e-12:
        conv = res <= 1e-13 + rtol * max(_MAXR(phi), -_MINR(phi))
    if not (conv and np.all(np.isfinite(phi)) and math.isfinite(tip.real)
            and math.isfinite(tip.imag)):
        return False
    if not np.any(phi):
        return True
    th = float(phi.sum())
    if th_c is not None:
        if abs(th - th_c) >= 0.5:
            return False
    elif not (warm or abs(th_lin) < 0.1 or abs(th) < 0.1 or (th > 0) == (th_lin > 0)
              or (dense and _stiffened_sign(l, w, F, m, follower, clothoid, lin, bezier)
                  == (th > 0))):
        return False
    if warm or (dense and abs(th_lin) > 0.3) or _compressed(F, th, follower):
        # N > FAST_DENSE_MAX_N: on the coarse model, whose solution had the check for large loads
        return _stable_at(phi, J, w, None, L, EI, F, m, follower, clothoid, bezier)
    return True


def fast_solve(n: int, L: float, EI: float, F: complex, m: float, follower: bool,
               initial: Optional[np.ndarray] = None, spacing: str = 'uniform',
               clothoid: bool = False, rtol: Optional[float] = None,
               bezier: bool = False) -> Optional[Tuple]:
    """Whole single-case solve for tip loads (circular, clothoid or, with bezier=True, Bezier
    arcs), or None when it is not accepted (the caller then uses the general path).

    rtol: Newton's relative tolerance (None: 1e-12; the first pass of graded arcs 1e-9); a
    coarse solution that only starts a finer model uses _START_RTOL.

    Returns phi, converged, iterations, residual, tip (complex), stable, fractions (None:
    equal arcs), clothoid rates (None for circular arcs)."""
    if m == 0.0 and F == 0:
        return None
    mi = 12
    cl = clothoid
    dense = n <= FAST_DENSE_MAX_N
    l, w, lever = _equal_arcs(n, L, EI)
    lin = w * (m + F.imag * lever)    # small-deflection solution
    th_lin = float(lin.sum())
    graded = spacing == 'graded' and n > 1 and not follower
    th_c = None        # tip angle of the accepted coarse solution the start came from
    if initial is not None:
        phi0, it0 = initial, 0
    elif not dense:          # from the COARSE_N solution
        start = _coarse_start(n, L, EI, F, m, follower, cl, COARSE_N, bezier)
        if start is None:
            return None
        phi0, it0, th_c = start
    else:
        base = lin
        if dense and m != 0.0 and F.real > 0.0 and F.imag != 0.0 and not follower:
            # axial tension with a tip moment: the tension stiffens the response to the
            # force more than to the moment, so phi_lin can point the wrong way and Newton
            # from it lands on a looped equilibrium; start from the stiffened response
            stiff = _stiffened_linear(l, w, F, m, follower, cl, lin, bezier)
            if stiff is not None:
                base = stiff
        phi0, it0 = _linear_start(base, float(base.sum()), F, m, follower, L, EI), 0
    # graded: this equal-arc solution only places the arcs; stop it at 1e-9 (an iterate error
    # ~1e-9 moves the tip of the graded solution by ~1e-12 L) -- saves one Newton step
    if rtol is None:
        rtol = 1e-9 if graded else 1e-12
    phi, conv, it, res, tip, J, rho = fast_tip_newton(n, l, w, F, m, follower, phi0, mi,
                                                      rtol=rtol, clothoid=cl, bezier=bezier,
                                                      patience=_PATIENCE if th_c is None else mi)
    stepped = it > 0
    it += it0
    direct = _accepted(phi, conv, res, tip, rtol, th_c, initial is not None, dense, th_lin,
                       l, w, F, m, follower, cl, lin, L, EI, J, bezier)
    if not direct and initial is None and dense and n > _FALLBACK_N:
        # not the natural branch from this start: from the _FALLBACK_N solution instead
        start = _coarse_start(n, L, EI, F, m, follower, cl, _FALLBACK_N, bezier)
        if start is None:
            return None
        it += start[1]
        # the direct solution stands if it is on the coarse solution's branch ...
        direct = _accepted(phi, conv, res, tip, rtol, start[2], False, dense, th_lin,
                           l, w, F, m, follower, cl, lin, L, EI, J, bezier)
        if not direct:      # ... else Newton from the coarse solution
            phi, conv, it2, res, tip, J, rho = fast_tip_newton(n, l, w, F, m, follower, start[0],
                                                               mi, rtol=rtol, clothoid=cl,
                                                               bezier=bezier)
            it += it2
            stepped = it2 > 0
            direct = _accepted(phi, conv, res, tip, rtol, start[2], False, dense, th_lin,
                               l, w, F, m, follower, cl, lin, L, EI, J, bezier)
    elif not direct and initial is None and dense:
        # not the natural branch from this start. Bezier arcs: from the circular-arc solution
        # of the same N (few long Bezier arcs have equilibria near the small-deflection start
        # that circular arcs do not have); else load from zero on the fast path
        out = _bezier_from_circular(n, l, w, L, EI, F, m, follower, mi, lin, th_lin) \
            if bezier else None
        if out is not None:
            phi, it2, res, tip, J = out
            it += it2
            stepped, direct, rho = True, True, None
        else:
            out = _continuation(n, l, w, F, m, follower, cl, lin, mi, bezier)
            if out is not None:
                phi, it2, res, tip, rho = out
                it += it2
                J, stepped, direct = None, True, True
    if not direct:
        return None
    th = float(phi.sum())
    Jw = w
    frac = None
    if graded and not stepped and not res <= 1e-13 + 1e-12 * _MAXR(np.abs(phi)):
        # the loose first pass stopped without a Newton step (tiny loads): finish it
        phi, conv, it2, res, tip, J, rho = fast_tip_newton(n, l, w, F, m, follower, phi, mi,
                                                           clothoid=cl, bezier=bezier)
        it += it2
        if not conv:
            return None
    if graded and np.any(phi):
        # second pass on graded arcs from this equal-arc solution (see graded_fractions);
        # the stability check below then uses the graded Jacobian
        # (from the equal arcs' tangent angle interpolated by local cubics up to _CUBIC_MAX_N
        # arcs, mesh.cubic_start; beyond, linear in each equal arc, remap: design record,
        # round 7)
        f, start = fast_grade(phi, F, follower, _graded_start(n, cl))
        lg = L * f
        p2, c2, it2, r2, tip2, J2, rho2 = fast_tip_newton(n, lg, lg / EI, F, m, follower, start,
                                                          mi, clothoid=cl, bezier=bezier)
        it += it2
        if c2 and abs(float(p2.sum()) - th) < 0.5 and \
                math.isfinite(tip2.real) and math.isfinite(tip2.imag):
            phi, res, tip, frac, rho, J, Jw = p2, r2, tip2, f, rho2, J2, lg / EI
        else:   # keep the equal arcs: finish their solution to the full tolerance
            phi, conv, it2, res, tip, J, rho = fast_tip_newton(n, l, w, F, m, follower, phi, mi,
                                                               clothoid=cl, bezier=bezier)
            it += it2
            if not conv:
                return None
    # axial compression at the tip: stability matters
    if _compressed(F, th, follower):
        if not np.any(phi):
            return None      # straight under compression: the general path judges stability
        if not _stable_at(phi, J, Jw, frac, L, EI, F, m, follower, cl, bezier):
            return None      # unstable: let the general path decide and flag it
    return phi, True, it, res, tip, True, frac, rho


def _bezier_from_circular(n: int, l: np.ndarray, w: np.ndarray, L: float, EI: float, F: complex,
                          m: float, follower: bool, max_iter: int, lin: np.ndarray,
                          th_lin: float) -> Optional[Tuple]:
    """Bezier arcs, N <= FAST_DENSE_MAX_N: Newton from the circular-arc solution of the same N,
    accepted on its branch (tip angle within 0.5 rad, the branch check); phi, iterations (both
    solves), residual, tip, Jacobian, or None."""
    ex = fast_solve(n, L, EI, F, m, follower)
    if ex is None:
        return None
    p, c, it, res, tip, J, _ = fast_tip_newton(n, l, w, F, m, follower, ex[0], max_iter,
                                               bezier=True)
    if not _accepted(p, c, res, tip, 1e-12, float(ex[0].sum()), False, True, th_lin, l, w, F,
                     m, follower, False, lin, L, EI, J, True):
        return None
    return p, it + ex[2], res, tip, J


def _compressed(F: complex, th: float, follower: bool) -> bool:
    """The tip force pushes along the tip tangent (tip angle th): stability matters."""
    return (F if follower else F * complex(math.cos(th), -math.sin(th))).real < 0


def _stiffened_sign(l: np.ndarray, w: np.ndarray, F: complex, m: float, follower: bool,
                    clothoid: bool, lin: np.ndarray, bezier: bool = False) -> Optional[bool]:
    """Sign (True: > 0) of the tip angle of the small-deflection solution WITH the geometric
    stiffness of the loads (one Newton step from the straight shape, J(0)^-1 phi_lin), or
    None when the straight shape is not stable (past buckling). An axial tension stiffens the
    response to a lateral force more than to a moment, so with both the natural branch can
    turn against phi_lin; where phi_lin's sign disagrees with the direct solution, this sign
    may confirm it (how often, and that it never confirmed a solution load continuation does
    not reach: package README, design record)."""
    stiff = _stiffened_linear(l, w, F, m, follower, clothoid, lin, bezier)
    return None if stiff is None else float(np.sum(stiff)) > 0


def _stiffened_linear(l: np.ndarray, w: np.ndarray, F: complex, m: float, follower: bool,
                      clothoid: bool, lin: np.ndarray, bezier: bool = False
                      ) -> Optional[np.ndarray]:
    """The small-deflection solution WITH the geometric stiffness of the loads: one Newton
    step from the straight shape, J(0)^-1 phi_lin (N <= FAST_DENSE_MAX_N); None when the straight
    shape is not stable (past buckling)."""
    J0 = jacobian_at(np.zeros(l.size), l, w, F, m, follower, clothoid, bezier)
    if J0 is None or not energy_stable(J0, w):
        return None
    return _dgesv(J0, lin)[2]


def _stable_at(phi: np.ndarray, J: Optional[np.ndarray], Jw: np.ndarray,
               frac: Optional[np.ndarray], L: float, EI: float, F: complex, m: float,
               follower: bool, clothoid: bool, bezier: bool = False) -> bool:
    """Branch / stability check at the solution phi (on arcs L * frac, None: equal arcs): on
    J (the last Newton step's Jacobian, row weights Jw) when given, else on the Jacobian at
    phi; beyond FAST_DENSE_MAX_N on the COARSE_N model with the same curvature."""
    n = phi.size
    if n > FAST_DENSE_MAX_N:
        lc, Jw, _ = _equal_arcs(COARSE_N, L, EI)
        pc = _resample(phi if frac is None else _to_equal(phi, frac), COARSE_N)
        J = jacobian_at(pc, lc, Jw, F, m, follower, clothoid, bezier)
    elif J is None:
        lj = L / n if frac is None else L * frac
        lj = np.broadcast_to(lj, (n,))
        Jw = lj / EI
        J = jacobian_at(phi, lj, Jw, F, m, follower, clothoid, bezier)
    return J is None or energy_stable(J, Jw)


def _to_equal(phi: np.ndarray, frac: np.ndarray) -> np.ndarray:
    """Arc angles on equal arcs of the tangent-angle curve of phi on arcs ``frac``."""
    n = phi.size
    Th = np.concatenate([[0.0], np.add.accumulate(phi)])
    b = np.concatenate([[0.0], np.add.accumulate(frac)])
    b[-1] = 1.0
    return np.diff(np.interp(np.arange(n + 1) / n, b, Th))

"""Fast path: one load case with tip loads only (force, moment; dead or follower), circular
or clothoid arcs. The same equations as ``equations.evaluate`` / ``linsolve``, written with
1-D arrays and as few numpy calls as possible (numpy call overhead dominates at N = 12),
LAPACK called directly. Returns None when the direct attempt is not accepted; the caller then
uses the general path (``globalise``). No rclpy here.
"""
from __future__ import annotations

import math
from typing import Optional

import numpy as np
from scipy.linalg.lapack import dgeev as _dgeev, dgesv as _dgesv

from .arcs import _CCOEF, _CCOEF8, _K, SERIES_LIMIT, arc_funcs, clothoid_funcs
from .equations import RHO_MAX, clothoid_terms
from .mesh import fast_grade

_MAXR = np.maximum.reduce
_MINR = np.minimum.reduce
_FAST_CACHE = {}
_EQUAL_CACHE = {}


def _fast_consts(n):
    c = _FAST_CACHE.get(n)
    if c is None:
        idx = np.arange(n)
        lower = idx[:, None] > idx[None, :]
        c = (lower, np.eye(n), np.diag_indices(n))
        _FAST_CACHE[n] = c
    return c


def fast_tip_newton(n, l, w, F, m, follower, phi, max_iter, step_limit=0.3, rtol=1e-12,
                     clothoid=False):
    """Damped Newton for one tip-loaded case. F complex (base or tip frame), m float.
    Stops at max|r| <= 1e-13 + rtol max|phi| (converged is judged with rtol = 1e-12).
    clothoid: clothoid arcs (as in evaluate; the Jacobian has the rates' derivatives once
    max|r| < _QUASI_ABOVE).

    Returns phi (N,), converged, iterations, max|r|, tip position (complex) at phi, the
    Jacobian of the last Newton step (None if no step was taken) and the clothoid rates
    (N,) at phi (None for circular arcs)."""
    lower, eye, diag = _fast_consts(n)
    cF0 = F.conjugate()
    acc = np.add.accumulate
    best = (phi, math.inf, 0j, None)
    it = 0
    J = None
    th_r = None
    wc = w[:, None]
    w_r = w / RHO_MAX
    iR = 1j * RHO_MAX
    coef = _CCOEF8 if clothoid else _CCOEF
    V = np.empty((n, _K))       # powers phi^0..phi^(K-1) by a running product (** is 3x slower)
    V[:, 0] = 1.0
    V1 = V[:, 1:]
    for it in range(max_iter + 1):
        th_end = acc(phi)
        lE = l * np.exp(1j * (th_end - phi))
        pmax = _MAXR(np.abs(phi))
        if pmax < SERIES_LIMIT:
            V1[...] = phi[:, None]
            np.multiply.accumulate(V1, axis=1, out=V1)
            R = V @ coef                         # (N, 4 or 8): g, q, g', q' (, k, k-km, k', (k-km)')
        elif clothoid:
            R = np.stack(clothoid_funcs(phi), axis=1)
        else:
            R = np.stack(arc_funcs(phi), axis=1)
        R *= lE[:, None]                         # l e^{i theta_start} times those
        if follower:
            t = float(th_end[-1])
            cF = cF0 * complex(math.cos(t), -math.sin(t))
        else:
            cF = cF0
        if clothoid:
            z0 = R[:, 0] * cF
            th_r = np.tanh(w_r * z0.imag)     # clothoid_rates: w (chord x -F), saturated
            c = th_r * iR
            P = acc(R[:, 0] + c * R[:, 4])
            lever = R[:, 1] + c * R[:, 5]
        else:
            P = acc(R[:, 0])
            lever = R[:, 1]
        rel = P[-1] - P
        ZF = (rel + lever) * cF
        r = phi - w * (m - ZF.imag)
        res = _MAXR(np.abs(r))
        if not res < math.inf:
            res = math.inf
        if res < best[1]:
            best = (phi, res, complex(P[-1]), th_r)
        if res <= 1e-13 + rtol * pmax or it == max_iter:
            break
        Y = R[:, 2:] * cF                      # g', q' (, k, k-km, k', (k-km)') terms
        irc = (1j * rel * cF).imag
        Bd = irc + Y[:, 1].imag
        C = irc + Y[:, 0].imag
        if clothoid and res < _QUASI_ABOVE:
            # with the rates' own derivatives (see clothoid_terms): quadratic convergence
            rho_ = RHO_MAX * th_r
            Yr = Y.real
            lo_, dg_, up_, row_ = clothoid_terms(z0.real, Y[:, 0].imag, Yr[:, 2], Yr[:, 3],
                                                  w, th_r, follower, rho_ * Yr[:, 4],
                                                  rho_ * Yr[:, 5])
            Bd = Bd + dg_
            if follower:
                D = np.where(lower, 0.0, (C + up_) - (ZF.real - row_)[:, None])
                Bd = Bd - ZF.real
            else:
                D = np.where(lower, (ZF.real + lo_)[:, None], C + up_)
        elif follower:   # (clothoid far from the solution: circular-arc factors, cheaper)
            D = np.where(lower, 0.0, C - ZF.real[:, None])
            Bd = Bd - ZF.real
        else:
            D = np.where(lower, ZF.real[:, None], C)
        D *= wc
        D.flat[::n + 1] = w * Bd + 1.0    # J = I - w dMbar/dphi, dMbar/dphi = -D / w
        J = D
        dx = _dgesv(D, r)[2]
        mx = _MAXR(np.abs(dx))
        if not mx < math.inf:
            break
        if mx > step_limit:
            dx *= step_limit / mx
        phi = phi - dx
    phi, res, tip, th_r = best
    rho = None if th_r is None else RHO_MAX * th_r
    if not res < math.inf:
        phi, tip, rho = np.zeros(n), complex(float(np.sum(l))), None
    pmax = _MAXR(np.abs(phi))
    return phi, res <= 1e-13 + 1e-12 * pmax, it, res, tip, J, rho


#: fast path, clothoid arcs: the rates' Jacobian terms are added once max|r| < this (rad);
#: further out the circular-arc factors do as well and cost less
_QUASI_ABOVE = 1e-2


def fast_solve(n, L, EI, F, m, follower, initial=None, spacing='uniform', clothoid=False):
    """Whole single-case solve for tip loads (exact or clothoid arcs, N <= DENSE_MAX_N), or
    None when the direct attempt is not accepted (the caller then uses the general path).

    Returns phi, converged, iterations, residual, tip (complex), stable, fractions (None:
    equal arcs), clothoid rates (None for circular arcs)."""
    mi = 20 if clothoid else 12
    cl = clothoid
    key = (n, L, EI)
    c = _EQUAL_CACHE.get(key)
    if c is None:
        if len(_EQUAL_CACHE) > 64:
            _EQUAL_CACHE.clear()
        l = np.full(n, L / n)
        c = _EQUAL_CACHE[key] = (l, l / EI, L - (np.cumsum(l) - 0.5 * l))
    l, w, lever = c
    lin = w * (m + F.imag * lever)    # small-deflection solution
    th_lin = float(lin.sum())
    if m == 0.0 and F == 0:
        return None
    if initial is not None:
        phi0 = initial
    else:
        ath = abs(th_lin)
        target = min(ath, 1.5)
        beta = math.atan2(F.imag, F.real)
        if not follower and m == 0.0 and beta != 0.0 and (beta > 0) == (th_lin > 0):
            a_ax = max(0.0, -math.cos(beta)) * abs(F) * L * L / EI / 2
            target = abs(beta) * -math.expm1(-(ath + a_ax) / abs(beta))
        phi0 = (lin / ath) * target if ath > 0 else lin   # not target / ath: overflows for denormal loads
    # graded: this equal-arc solution only places the arcs; stop it at 1e-9 (an iterate error
    # ~1e-9 moves the tip of the graded solution by ~1e-12 L) -- saves one Newton step
    graded = spacing == 'graded' and n > 1 and not follower
    phi, conv, it, res, tip, J, rho = fast_tip_newton(n, l, w, F, m, follower, phi0, mi,
                                                       rtol=1e-9 if graded else 1e-12, clothoid=cl)
    if graded:
        conv = res <= 1e-13 + 1e-9 * max(_MAXR(phi), -_MINR(phi))
    if not conv or not (np.all(np.isfinite(phi)) and math.isfinite(tip.real) and math.isfinite(tip.imag)):
        return None
    th = float(phi.sum())
    if not np.any(phi):
        J = None
    elif initial is None and abs(th_lin) >= 0.1 and (th > 0) != (th_lin > 0):
        return None
    # axial compression at the tip -> stability matters; large loads -> branch check
    Ft = F if follower else F * complex(math.cos(th), -math.sin(th))
    compress = Ft.real < 0
    stable = True
    frac = None
    if graded and J is None and not res <= 1e-13 + 1e-12 * _MAXR(np.abs(phi)):
        # the loose first pass stopped without a Newton step (tiny loads): finish it
        phi, conv, it2, res, tip, J, rho = fast_tip_newton(n, l, w, F, m, follower, phi, mi,
                                                            clothoid=cl)
        it += it2
        if not conv:
            return None
    if graded and np.any(phi):
        # second pass on graded arcs from this equal-arc solution (see graded_fractions);
        # the branch check below then uses the graded Jacobian
        f, start = fast_grade(phi, F, follower)
        lg = L * f
        p2, c2, it2, r2, tip2, J2, rho2 = fast_tip_newton(n, lg, lg / EI, F, m, follower, start,
                                                           mi, clothoid=cl)
        it += it2
        if c2 and abs(float(p2.sum()) - th) < 0.5 and \
                math.isfinite(tip2.real) and math.isfinite(tip2.imag):
            phi, res, tip, frac, rho = p2, r2, tip2, f, rho2
            J = J2 if J2 is not None else J
        else:   # keep the equal arcs: finish their solution to the full tolerance
            phi, conv, it2, res, tip, J1, rho = fast_tip_newton(n, l, w, F, m, follower, phi, mi,
                                                                 clothoid=cl)
            it += it2
            J = J1 if J1 is not None else J
            if not conv:
                return None
    if J is not None and (compress or abs(th_lin) > 0.3 or initial is not None):
        wr = _dgeev(J, compute_vl=0, compute_vr=0)[0]
        stable = bool(_MINR(wr) > 1e-9)
        if not stable:
            return None      # possibly another branch: let continuation decide
    elif J is None and compress:
        return None          # straight under compression: the general path judges stability
    return phi, True, it, res, tip, stable, frac, rho

"""The single-case Newton kernel of the fast path: the FAM residual and Jacobian for tip loads
(force, moment; dead or follower), circular or clothoid arcs, written with 1-D arrays and as
few numpy calls as possible (numpy call overhead dominates at N = 12), LAPACK called
directly: dense Jacobian for N <= FAST_DENSE_MAX_N, the O(N) banded solve beyond. The same
equations as ``equations.evaluate`` / ``linsolve`` (tests check that). No rclpy here.
"""
from __future__ import annotations

import bisect
import math
from typing import Optional

import numpy as np
from scipy.linalg.lapack import dgesv as _dgesv, dgetrs as _dgetrs

from .arcs import row_product
from .equations import RHO_MAX, clothoid_terms
from .fast_bezier import bezier_tip_newton
from .linsolve import banded_solve, chord_pays, limited_step

_MAXR = np.maximum.reduce
_FAST_CACHE = {}
#: the fast path's switch from the dense Newton step (and the direct start) to the O(N)
#: banded step started from the COARSE_N solution. Cost model: dense ~ a + b N^2 + c N^3 per
#: step, banded ~ the coarse solve + d N; measured (package README, design record) they cross
#: at N ~ 80-88 for plain tip forces but at ~64-70 for tip force + moment loads (more dense
#: iterations), so at 64 one more arc never costs less. The general path: linsolve.DENSE_MAX_N.
FAST_DENSE_MAX_N = 64
#: clothoid arcs: the rates' Jacobian terms are added once max|r| < this (rad); further out
#: the circular-arc factors do as well and cost less
QUASI_ABOVE = 1e-2
#: ... and from the first step below this N: the rates, ~ load / N^2, are large there, and on
#: the Python-float path (N <= SMALL_N) their terms cost little. At N = 3-4 a step from a start
#: with max|r| above QUASI_ABOVE (the graded second pass's on 6 of the cliff bench's 9 Blazer
#: loads) converged linearly without them: 5-11 % more iterations at N = 3-4 on random loads,
#: the N = 4 -> 8 graded drop of issue 15 (package README, round 10)
_QUASI_MIN_N = 5
#: up to this N the Newton step's Jacobian is built in Python floats (``_small_jacobian``)
SMALL_N = 4
#: ... while every arc is turned by less than this (rad; beyond, the array form: it gives NaN
#: where Python's math raises)
_SMALL_PMAX = 1e6
#: a damped step may turn the tip by at least this much (rad) whatever N: the per-arc limit
#: (0.3 rad) times 4 arcs, so N = 1-3 arcs are damped no more than N = 4. Not for Bezier
#: arcs: few long Bezier arcs have extra equilibria near the start, and larger steps reached
#: another one on 4 of 800 random loads at N = 1-2 (package README, design record)
STEP_TURN = 1.2

# Every function the arcs need is linear in E_k = integral_0^1 v^k e^{i phi v} dv, k = 0..4
# (see ``arcs``): g = E0, q = E1, g' = i E1, q' = i E2, k = (E2 - E1)/2, k - km = (E3 - E2)/2,
# k' = i (E3 - E2)/2, (k - km)' = i (E4 - E3)/2. Below |phi| < _SERIES_LIMIT the Taylor series
# E_k = sum_j (i phi)^j / (j! (k + j + 1)) (_K_FAST terms: truncation < 1e-20, rounding
# ~e^|phi| 1e-16), as ONE Vandermonde product; beyond it the closed forms
# E_0 = (e^{i phi} - 1)/(i phi), E_k = (e^{i phi} - k E_{k-1}) / (i phi). The series reaches
# further than in ``arcs`` so that few-arc models (N = 1-4, arcs of 1-3 rad) stay on the
# cheap product.
_EMAP = np.zeros((5, 8), dtype=complex)
_EMAP[0, 0] = _EMAP[1, 1] = 1.0
_EMAP[1, 2] = _EMAP[2, 3] = 1j
_EMAP[1:3, 4] = (-0.5, 0.5)
_EMAP[2:4, 5] = (-0.5, 0.5)
_EMAP[2:4, 6] = (-0.5j, 0.5j)
_EMAP[3:5, 7] = (-0.5j, 0.5j)
_SERIES_LIMIT = 3.0
_K_FAST = 34
_EC = np.array([[1j ** j / math.factorial(j) / (k + j + 1) for k in range(5)]
                for j in range(_K_FAST)])
_COEF4 = _EC[:, :3] @ _EMAP[:3, :4]     # g, q, g', q'
_COEF8 = _EC @ _EMAP                    # ... and k, k - km, k', (k - km)'
# fewer terms where all arcs are short (many arcs): k terms while max|phi|^k / k! <= 1e-17
_TERMS_FOR = list(range(6, _K_FAST + 1))
_PHI_FOR_TERMS = [(1e-17 * math.factorial(k)) ** (1.0 / k) for k in _TERMS_FOR]


def _fast_consts(n: int):
    c = _FAST_CACHE.get(n)
    if c is None:
        idx = np.arange(n)
        c = (idx[:, None] > idx[None, :],)
        _FAST_CACHE[n] = c
    return c


def _arc_values(phi: np.ndarray, pmax: float, V: np.ndarray, coef: np.ndarray) -> np.ndarray:
    """(N, 4) g, q, g', q' (or (N, 8) with k, k-km, k', (k-km)' when coef has 8 columns):
    the series (one Vandermonde product; V (N, _K_FAST) holds the powers' storage) for
    |phi| < _SERIES_LIMIT, the closed forms from E_0..E_4 elsewhere."""
    if pmax < _SERIES_LIMIT:
        k = _TERMS_FOR[bisect.bisect_left(_PHI_FOR_TERMS, pmax)]
        V1 = V[:, 1:k]
        V1[...] = phi[:, None]
        np.multiply.accumulate(V1, axis=1, out=V1)
        return row_product(V[:, :k], coef[:k])
    V1 = V[:, 1:]
    m = coef.shape[1]
    k = 5 if m == 8 else 3
    big = np.abs(phi) >= _SERIES_LIMIT
    a = 1j * np.where(big, phi, 1.0)
    e = np.exp(a)
    ia = 1.0 / a
    E = np.empty((phi.size, k), dtype=complex)
    E[:, 0] = (e - 1.0) * ia
    for j in range(1, k):
        E[:, j] = (e - j * E[:, j - 1]) * ia
    R = E @ _EMAP[:k, :m]
    if big.all():
        return R
    V1[...] = np.where(big, 0.0, phi)[:, None]
    np.multiply.accumulate(V1, axis=1, out=V1)
    return np.where(big[:, None], R, row_product(V, coef))


def fast_tip_newton(n: int, l: np.ndarray, w: np.ndarray, F: complex, m: float, follower: bool,
                    phi: np.ndarray, max_iter: int, step_limit: float = 0.3, rtol: float = 1e-12,
                    clothoid: bool = False, patience: int = 1 << 30, bezier: bool = False):
    """Damped Newton for one tip-loaded case. F complex (base or tip frame), m float.
    Stops at max|r| <= 1e-13 + rtol max|phi| (converged is judged with rtol = 1e-12).
    clothoid: clothoid arcs (as in evaluate; the Jacobian has the rates' derivatives once
    max|r| < QUASI_ABOVE). N <= FAST_DENSE_MAX_N: dense Jacobian (returned); beyond: the O(N)
    banded solve (no Jacobian returned). Gives up after ``patience`` iterations while max|r|
    is still above QUASI_ABOVE and fell less than 10x in the last two (a start that leads
    nowhere near a solution). Dense: near the solution a step may be a chord step, the last
    Jacobian's LU factors again (``linsolve.chord_pays``: when predicted to reach the
    tolerance in no more steps than Newton); the iterations count both kinds.

    Returns phi (N,), converged, iterations, max|r|, tip position (complex) at phi, the
    Jacobian of the last Newton (not chord) step (None if no step was taken or
    N > FAST_DENSE_MAX_N) and the clothoid rates (N,) at phi (None for circular arcs).
    bezier: the thesis' Bezier arcs (``fast_bezier.bezier_tip_newton``, the same interface;
    clothoid is ignored)."""
    dense = n <= FAST_DENSE_MAX_N
    # step_limit bounds each arc's change: a step may turn the tip by up to n step_limit, so
    # few long arcs would be damped far more than many short ones -- give every N the tip
    # turn of STEP_TURN per step at least (not Bezier arcs: see STEP_TURN)
    if not bezier:
        step_limit = max(step_limit, STEP_TURN / n)
    if bezier:
        return bezier_tip_newton(n, l, w, F, m, follower, phi, max_iter, step_limit, rtol,
                                 patience, QUASI_ABOVE, dense)
    lower = _fast_consts(n)[0] if dense else None
    cF0 = F.conjugate()
    acc = np.add.accumulate
    best = (phi, math.inf, 0j, None)
    it = 0
    J = None
    th_r = None
    wc = w[:, None]
    w_r = w / RHO_MAX
    iR = 1j * RHO_MAX
    coef = _COEF8 if clothoid else _COEF4
    # powers phi^0..phi^(K-1) by a running product (cheaper than **)
    V = np.empty((n, _K_FAST))
    V[:, 0] = 1.0
    hist = [math.inf] * 3          # max|r| of the last iterations (for ``patience``)
    lu = piv = None                # LU factors of the last Jacobian (dense), for chord steps
    res_prev = res_jac = math.inf
    chord = False
    few = n <= SMALL_N
    if few:
        ll, wl, wrl = l.tolist(), w.tolist(), w_r.tolist()
    for it in range(max_iter + 1):
        pmax = _MAXR(np.abs(phi))
        small = few and pmax < _SMALL_PMAX
        if small:       # the same residual in Python floats (_small_residual; its Jacobian too)
            Rl = _arc_values(phi, pmax, V, coef).tolist()
            E, cF, rel, ZF, rl, Pn, th_r = _small_residual(phi.tolist(), Rl, ll, wl, wrl, cF0,
                                                           m, follower, clothoid)
            r = np.array(rl)
        else:
            th_end = acc(phi)
            lE = l * np.exp(1j * (th_end - phi))
            R = _arc_values(phi, pmax, V, coef)  # (N, 4|8): g, q, g', q' (, k, k-km, k', (k-km)')
            R *= lE[:, None]                     # l e^{i theta_start} times those
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
            Pn = P[-1]
            rel = Pn - P
            ZF = (rel + lever) * cF
            r = phi - w * (m - ZF.imag)
        res = _MAXR(np.abs(r))
        if not res < math.inf:
            res = math.inf
        if res < best[1]:
            best = (phi, res, complex(Pn), th_r)
        tol = 1e-13 + rtol * pmax
        if res <= tol or it == max_iter or \
                (it >= patience and res > QUASI_ABOVE and res > 0.1 * hist[(it - 2) % 3]):
            break
        hist[it % 3] = res
        chord = lu is not None and chord_pays(res, res_prev, res_jac, tol, chord)
        if chord:
            res_prev = res
            phi = limited_step(phi, _dgetrs(lu, piv, r)[0], step_limit)
            if phi is None:
                break
            continue
        res_prev = res_jac = res
        # clothoid arcs: with the rates' own derivatives (see clothoid_terms), quadratic
        # convergence; far from the solution the circular-arc factors do as well, cheaper
        terms = clothoid and (res < QUASI_ABOVE or n < _QUASI_MIN_N)
        if small:
            J = _small_jacobian(Rl, E, rel, ZF, wl, cF, follower, terms, th_r)
            lu, piv, dx, _ = _dgesv(J, r)
            phi = limited_step(phi, dx, step_limit)
            if phi is None:
                break
            continue
        # -dMbar/dphi = D: D_ij = a_i (j < i), d_i (j = i), c_j + e_i (j > i); J = I + W D
        Y = R[:, 2:] * cF                      # g', q' (, k, k-km, k', (k-km)') terms
        irc = (1j * rel * cF).imag
        d = irc + Y[:, 1].imag
        c = irc + Y[:, 0].imag
        e = None
        if terms:
            rho_ = RHO_MAX * th_r
            Yr = Y.real
            lo_, dg_, up_, row_ = clothoid_terms(z0.real, Y[:, 0].imag, Yr[:, 2], Yr[:, 3],
                                                 w, th_r, follower, rho_ * Yr[:, 4],
                                                 rho_ * Yr[:, 5])
            d = d + dg_
            c = c + up_
            if follower:
                a, e = 0.0, row_ - ZF.real
                d = d - ZF.real
            else:
                a = ZF.real + lo_
        elif follower:   # (clothoid far from the solution: circular-arc factors, cheaper)
            a, e = 0.0, -ZF.real
            d = d - ZF.real
        else:
            a = ZF.real
        if dense:
            if follower:
                D = np.where(lower, 0.0, c + e[:, None])
            else:
                D = np.where(lower, a[:, None], c)
            D *= wc
            D.flat[::n + 1] = w * d + 1.0
            J = D
            lu, piv, dx, _ = _dgesv(D, r)
        else:   # J = I - (-W) D: the banded solver's convention
            dx = banded_solve(-w, (np.broadcast_to(a, (n,)), d, c, e), r)
        phi = limited_step(phi, dx, step_limit)
        if phi is None:
            break
    phi, res, tip, th_r = best
    rho = None if th_r is None else RHO_MAX * np.asarray(th_r)
    if not res < math.inf:
        phi, tip, rho = np.zeros(n), complex(float(np.sum(l))), None
    pmax = _MAXR(np.abs(phi))
    return phi, res <= 1e-13 + 1e-12 * pmax, it, res, tip, J, rho


def _small_residual(phi: list, R: list, l: list, w: list, w_r: list, cF0: complex, m: float,
                    follower: bool, clothoid: bool):
    """The residual of ``fast_tip_newton`` for few arcs (N <= SMALL_N) in Python floats, from
    the arc functions R (N rows, unscaled: g, q, g', q' (, k, k - km, k', (k - km)')): the same
    formulas as the array form (numpy's per-call overhead is most of its cost on 1-4 arcs).
    Returns E = l e^{i theta_start} per arc, cF (conj F, turned with the tip for a follower
    force), rel = P_N - P_i, ZF = (rel + lever) cF, r, the tip P_N and the clothoid rates'
    tanh(rho / RHO_MAX) (None for circular arcs), all lists but P_N."""
    n = len(phi)
    E = [0j] * n
    th = 0.0
    for i in range(n):
        E[i] = l[i] * complex(math.cos(th), math.sin(th))
        th += phi[i]
    cF = cF0 * complex(math.cos(th), -math.sin(th)) if follower else cF0
    th_r = [0.0] * n if clothoid else None
    lever = [0j] * n
    Ps = [0j] * n
    P = 0j
    iR = 1j * RHO_MAX
    for i in range(n):
        Ri, e = R[i], E[i]
        if clothoid:        # clothoid_rates: w (chord x -F), saturated
            t = math.tanh(w_r[i] * (Ri[0] * e * cF).imag)
            th_r[i] = t
            c = t * iR
            P += (Ri[0] + c * Ri[4]) * e
            lever[i] = (Ri[1] + c * Ri[5]) * e
        else:
            P += Ri[0] * e
            lever[i] = Ri[1] * e
        Ps[i] = P
    rel = [P - x for x in Ps]
    ZF = [(rel[i] + lever[i]) * cF for i in range(n)]
    r = [phi[i] - w[i] * (m - ZF[i].imag) for i in range(n)]
    return E, cF, rel, ZF, r, P, th_r


def _small_jacobian(R: list, E: list, rel: list, ZF: list, w: list, cF: complex,
                    follower: bool, terms: bool, th_r: Optional[list]) -> np.ndarray:
    """The dense Jacobian J = I + W D of ``fast_tip_newton``'s Newton step for few arcs
    (N <= SMALL_N), in Python floats: on one or two arcs numpy's per-call overhead is most of
    the cost of the ~40 array operations of the general form (and all of it for the clothoid
    rates' terms, which N < _QUASI_MIN_N adds at every step). The same formulas in the same
    order (``clothoid_terms`` for the rates); R: N rows (g, q, g', q' (, k, k - km, k',
    (k - km)')), to be scaled by E (l e^{i theta_start} per arc); rel = P_N - P_i;
    ZF = (rel + lever) cF; terms: add the rates' derivatives (th_r = tanh(rho / RHO_MAX))."""
    n = len(w)
    a = [0.0] * n
    c = [0.0] * n
    d = [0.0] * n
    e = [0.0] * n
    eF = [E[i] * cF for i in range(n)]
    for i in range(n):
        Ri = R[i]
        irc = (rel[i] * cF).real
        zr = ZF[i].real
        y0 = (Ri[2] * eF[i]).imag
        c[i] = irc + y0
        d[i] = irc + (Ri[3] * eF[i]).imag
        if follower:
            d[i] -= zr
            e[i] = -zr
        else:
            a[i] = zr
    if terms:
        # clothoid_terms: sigma_j = w'_j sg_j, tau_j = w'_j tg_j, u_j = a_j sigma_j
        cs = 0.0
        us = [0.0] * n
        for i in range(n):
            Ri, ef = R[i], eF[i]
            t = th_r[i]
            ws = w[i] * (1.0 - t * t)
            sig = ws * (Ri[0] * ef).real
            tau = ws * (Ri[2] * ef).imag
            ka = (Ri[4] * ef).real
            kb = (Ri[5] * ef).real
            rho = RHO_MAX * t
            ap = rho * (Ri[6] * ef).real
            bp = rho * (Ri[7] * ef).real
            u = ka * sig
            us[i] = (u, ka, kb, sig, tau, ap, bp)
        if follower:
            for i in range(n):
                u, ka, kb, sig, tau, ap, bp = us[i]
                cs += u                           # sum over j <= i
                d[i] += kb * (tau - sig) + bp
                c[i] += ka * (tau - sig) - (cs - u) + ap
                e[i] += cs - kb * sig
        else:
            S = 0.0
            for i in range(n - 1, -1, -1):        # S: sum over j > i
                u, ka, kb, sig, tau, ap, bp = us[i]
                a[i] += S + kb * sig
                d[i] += S + kb * tau + bp
                c[i] += S + ka * tau + ap
                S += u
    J = [[0.0] * n for _ in range(n)]
    for i in range(n):
        wi = w[i]
        Ji = J[i]
        for j in range(n):
            if j < i:
                Ji[j] = 0.0 if follower else wi * a[i]
            elif j > i:
                Ji[j] = wi * (c[j] + e[i])
        Ji[i] = wi * d[i] + 1.0
    return np.array(J)


def jacobian_at(phi: np.ndarray, l: np.ndarray, w: np.ndarray, F: complex, m: float,
                 follower: bool, clothoid: bool, bezier: bool = False) -> Optional[np.ndarray]:
    """The dense Jacobian (N <= FAST_DENSE_MAX_N) at phi: the one a Newton step from phi uses."""
    J = fast_tip_newton(phi.size, l, w, F, m, follower, phi, 1, step_limit=math.inf, rtol=-1.0,
                        clothoid=clothoid, bezier=bezier)[5]
    return J

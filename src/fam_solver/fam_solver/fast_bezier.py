"""The thesis' Bezier arcs (``bezier``) on the fast path: the single-case Newton kernel for tip
loads, with every quadrature of Eq. 23 replaced by power series in the arc angle. No rclpy.

Arc i (length l, angle phi, end wrench M and Floc in its own frame) has the Eq. 23 residual
r = (l/EI)^2 integral R dR/dphi dt (``bezier.BezierModel._local``). With m = M l/EI and
f = Floc l^2/EI, and the unit-length arc's lever p3 - c(t) = (lx, ly) and curvature k,

    R l/EI = m + fy lx - fx ly - k = sum_p a_p u_p,   a = (m, fy, -fx, -1), u = (1, lx, ly, k)
    dR/dphi l/EI = sum_q b_q du_q/dphi,                b = (fy, -fx, -1),  q over (lx, ly, k)

so r = sum_pq a_p b_q H_pq(phi) with the twelve integrals H_pq = integral u_p du_q/dphi dt of
the (8-point Gauss-Legendre) quadrature, which depend on phi alone. Their derivatives
dr/dm, dr/df and dr/dphi (the exact Jacobian's pieces, ``BezierModel.factors``) are the same
bilinear forms in H and dH/dphi. H is analytic in phi (singularities at +-4.59i, where
|c'(t)| vanishes for complex phi, and at the tan pole phi = 2 pi), so it is a power series:
about 0 for |phi| <= _SPLIT, about +-_SIDE for _SPLIT < |phi| <= MAX_PHI. The coefficients are
computed once at import from values of the u_p on circles in the complex phi plane (FFT;
the curves written with real and imaginary parts separately, as analytic functions) and
checked against the quadrature (tests: <= 1e-13). A Newton step is then one matrix product
and some 40 elementwise operations on (N,) arrays, as for circular arcs. Arcs beyond MAX_PHI
(one or two arcs turned by more than 4.9 rad) are left to the general path.
"""
from __future__ import annotations

import bisect
import math
from typing import Optional

import numpy as np
from scipy.linalg.lapack import dgesv as _dgesv, dgetrs as _dgetrs

from .arcs import row_product
from .bezier import unit_nodes
from .linsolve import banded_solve, chord_pays, limited_step

_MAXR = np.maximum.reduce
_MINR = np.minimum.reduce
#: series about 0 up to this |phi|, about +-_SIDE beyond, up to MAX_PHI
_SPLIT = 2.3
_SIDE = 3.6
MAX_PHI = 4.9
#: FFT sampling radii (inside the radii of convergence, 4.59 about 0 and 2.68 about 3.6)
_RHO = {0.0: 3.6, _SIDE: 2.2, -_SIDE: 2.2}
_FFT = 512
_K0 = 72                  # terms kept about 0 (enough for |phi| = _SPLIT: tail < 1e-17)
_KS = 64                  # terms kept about +-_SIDE (|phi -+ _SIDE| <= 1.3)
_COLS = 18                # complex: h (4), dh (4), H_k (4), dH_k (4), g, g'
#: up to this N the Newton step's Jacobian is built in Python floats (``_small_step``)
SMALL_N = 4


def _unit_funcs(z: np.ndarray, t: np.ndarray):
    """u_p (4, P, Q) = 1, lever x, lever y, curvature of the unit-length Bezier arc at the nodes
    t for (complex) angles z (P,), and g = (e^{iz} - 1)/(iz) as (gx, gy): the curves of
    ``bezier.BezierModel._curves`` with x and y parts kept apart (analytic in z)."""
    z = z[:, None]
    u = 1.0 - t
    b0 = (u ** 3, 3 * t * u ** 2, 3 * t ** 2 * u, t ** 3)
    b1 = (-3 * u ** 2, 3 * u ** 2 - 6 * t * u, 6 * t * u - 3 * t ** 2, 3 * t ** 2)
    b2 = (6 * u, -12 * u + 6 * t, 6 * u - 12 * t, 6 * t)
    c, s = np.cos(z), np.sin(z)
    lam = (4.0 / 3.0) * np.tan(0.25 * z) / z
    gx, gy = s / z, (1.0 - c) / z
    zero = 0.0 * z
    px = (zero, lam, gx - lam * c, gx)
    py = (zero, zero, gy - lam * s, gy)

    def comb(p, b):
        return sum(pk * bk for pk, bk in zip(p, b, strict=True))
    cx, cy = comb(px, b0), comb(py, b0)
    c1x, c1y, c2x, c2y = comb(px, b1), comb(py, b1), comb(px, b2), comb(py, b2)
    sp2 = c1x * c1x + c1y * c1y
    kap = (c1x * c2y - c1y * c2x) / (sp2 * np.sqrt(sp2))
    return np.stack([np.ones_like(cx), gx - cx, gy - cy, kap]), gx[:, 0], gy[:, 0]


def _series(center: float, rho: float, k: int) -> np.ndarray:
    """(k, _COLS) complex Taylor coefficients about ``center``, the columns of ``arc_terms``."""
    t, wq = unit_nodes()
    z = center + rho * np.exp(2j * np.pi * np.arange(_FFT) / _FFT)
    U, gx, gy = _unit_funcs(z, t)                        # (4, P, Q)
    kk = np.arange(_FFT)
    # d/dphi on the circle: the Taylor coefficients (FFT), times k, back (inverse FFT)
    cu = np.fft.fft(U[1:], axis=1)
    cu[:, _FFT // 2:] = 0.0
    dU = np.fft.ifft(cu * kk[None, :, None], axis=1) / (z - center)[None, :, None]
    H = np.einsum('ipq,jpq,q->ijp', U, dU, wq)          # (4, 3, P): H_pq
    vals = np.concatenate([H.reshape(12, _FFT), [gx, gy]])
    c = np.fft.fft(vals, axis=1)[:, :k + 1] / _FFT / rho ** np.arange(k + 1)
    c = c.real.T                                         # (k + 1, 14): real functions
    d = c[1:] * np.arange(1, k + 1)[:, None]             # derivative's coefficients
    c = c[:k]
    h, hd = c[:, :12].reshape(k, 4, 3), d[:, :12].reshape(k, 4, 3)
    return np.concatenate([h[..., 0] + 1j * h[..., 1], hd[..., 0] + 1j * hd[..., 1],
                           h[..., 2], hd[..., 2], c[:, 12:13] + 1j * c[:, 13:14],
                           d[:, 12:13] + 1j * d[:, 13:14]], axis=1)


_COEF = {c: _series(c, r, _K0 if c == 0.0 else _KS) for c, r in _RHO.items()}
#: the three series for arcs beyond _SPLIT, padded to _K0 terms: (3, _K0, _COLS)
_COEF3 = np.zeros((3, _K0, _COLS), dtype=complex)
for _j, _c in enumerate((-_SIDE, 0.0, _SIDE)):
    _COEF3[_j, :_COEF[_c].shape[0]] = _COEF[_c]
_MAG = np.max(np.abs(_COEF[0.0]), axis=1)
#: terms about 0 for a largest |phi|: k terms while every left-out coefficient x |phi|^j is
#: below 1e-17 (the H are O(1)); _K0 terms up to _SPLIT
_PHI_FOR_TERMS = [min([(1e-17 / max(float(_MAG[j]), 1e-300)) ** (1.0 / j)
                       for j in range(k, _K0)] + [_SPLIT]) for k in range(1, _K0 + 1)]


#: sums along an axis without ndarray.sum's Python wrapper (the same ufunc, the same numbers)
_ADD = np.add.reduce
_LOWER = {}


def _lower(n: int) -> np.ndarray:
    """The strictly lower triangle (n, n) bool, cached per n (allocated once, not per call)."""
    m = _LOWER.get(n)
    if m is None:
        m = _LOWER[n] = np.tri(n, n, -1, dtype=bool)
    return m


def _powers(x: np.ndarray, k: int) -> np.ndarray:
    V = np.empty((x.size, k))
    V[:, 0] = 1.0
    V[:, 1:] = x[:, None]
    np.multiply.accumulate(V[:, 1:], axis=1, out=V[:, 1:])
    return V


def arc_terms(phi: np.ndarray, pmax: float) -> Optional[np.ndarray]:
    """(N, _COLS) complex, per arc of the unit length at the angles phi: h_p = H_px + i H_py
    (4, p over (1, lx, ly, k)), dh_p/dphi (4), H_pk (4), dH_pk/dphi (4), g, g' (H_pq =
    integral u_p du_q/dphi dt); None when pmax > MAX_PHI."""
    if pmax <= _SPLIT:
        k = 1 + bisect.bisect_left(_PHI_FOR_TERMS, pmax)
        return row_product(_powers(phi, k), _COEF[0.0][:k])
    if not pmax <= MAX_PHI:
        return None
    # few arcs: each its own series (about -_SIDE, 0 or _SIDE)
    j = (phi > _SPLIT).astype(int) - (phi < -_SPLIT)
    V = _powers(phi - j * _SIDE, _K0)
    return np.matmul(V[:, None, :], _COEF3[j + 1])[:, 0]


def bezier_tip_newton(n: int, l: np.ndarray, w: np.ndarray, F: complex, m: float,
                      follower: bool, phi: np.ndarray, max_iter: int, step_limit: float = 0.3,
                      rtol: float = 1e-12, patience: int = 1 << 30, quasi_above: float = 1e-2,
                      dense: bool = True):
    """Damped Newton on the Bezier residual (exact Jacobian) for one tip-loaded case; the
    interface and the stopping rules of ``fast_newton.fast_tip_newton`` (``dense``: the dense
    Jacobian, returned; else the O(N) banded solve). Returns phi, converged, iterations,
    max|r|, tip (complex), J (or None), None (no clothoid rates)."""
    acc = np.add.accumulate
    lower = _lower(n) if dense else None
    best = (phi, math.inf, 0j)
    hist = [math.inf] * 3
    it = 0
    J = None
    lw = l * w
    lu = piv = None                  # LU factors of the last (scaled) Jacobian: chord steps
    lu_scaled = chord = False
    res_prev = res_jac = math.inf
    a = np.empty((n, 1, 4))          # (m, fy, -fx, -1) per arc
    a[:, 0, 3] = -1.0
    for it in range(max_iter + 1):
        pmax = _MAXR(np.abs(phi))
        T = arc_terms(phi, pmax)
        if T is None:
            break
        th_end = acc(phi)
        E = np.exp(1j * (th_end - phi))
        lE = l * E
        P = acc(lE * T[:, 16])                           # arc end points (g = T[:, 16])
        rel = P[-1] - P
        Ft = F * complex(math.cos(th_end[-1]), math.sin(th_end[-1])) if follower else F
        cF = Ft.conjugate()
        RF = rel * cF
        f = (Ft * lw) * E.conjugate()                    # F l^2/EI in the arc frames
        fx, fy = f.real, f.imag
        a[:, 0, 0] = (m - RF.imag) * w                   # end moment M l/EI
        a[:, 0, 1] = fy
        np.negative(fx, out=a[:, 0, 2])
        # B_p = sum_q b_q H_pq and its phi-derivative (n, 2, 4); r, dr/dphi = sum_p a_p B_p
        BB = ((T[:, :8].conjugate() * f[:, None]).imag - T[:, 8:16].real).reshape(n, 2, 4)
        RG = _ADD(BB * a, axis=2)
        r = RG[:, 0]
        res = _MAXR(np.abs(r))
        if not res < math.inf:
            res = math.inf
        if res < best[1]:
            best = (phi, res, complex(P[-1]))
        tol = 1e-13 + rtol * pmax
        if res <= tol or it == max_iter or \
                (it >= patience and res > quasi_above and res > 0.1 * hist[(it - 2) % 3]):
            break
        hist[it % 3] = res
        sc = -BB[:, 0, 0]           # -dr/dM EI/l (1 to leading order)
        chord = lu is not None and chord_pays(res, res_prev, res_jac, tol, chord)
        if chord:   # the last Jacobian's factors again (fast_newton: the same rule)
            res_prev = res
            phi = limited_step(phi, _dgetrs(lu, piv, r / sc if lu_scaled else r)[0],
                               step_limit)
            if phi is None:
                break
            continue
        res_prev = res_jac = res
        if dense and n <= SMALL_N:
            out = _small_step(BB.tolist(), T.tolist(), a.tolist(), f.tolist(), RF.tolist(),
                              lE.tolist(), RG.tolist(), r.tolist(), w.tolist(), cF, follower)
            if out is None:
                break
            J, lu, piv, dx, lu_scaled = out
            phi = limited_step(phi, dx, step_limit)
            if phi is None:
                break
            continue
        W = sc * w                  # -dr/dM: the Jacobian's row weights (linsolve's w)
        if not _MINR(np.abs(W)) > 0:
            break
        ig = -1.0 / W
        # dr = Im(conj K df), K = sum_q b_q (h_1q + i h_2q) + sum_p a_p (H_px + i H_py)
        Kn = BB[:, 0, 1] + 1j * BB[:, 0, 2] + _ADD(a[:, 0] * T[:, :4], axis=1)
        kK = (Kn.conjugate() * f).real
        Mlow = -RF.real
        Mcol = Mlow - (lE * T[:, 17] * cF).imag       # g' = T[:, 17]
        gP1 = RG[:, 1] - 1.0
        if follower:     # the force turns with the tip (Mall = -Mlow; see BezierModel.factors)
            A = 0.0
            e = kK * ig - Mlow
            Bd = (gP1 + kK) * ig
        else:
            A = Mlow - kK * ig
            e = None
            Bd = gP1 * ig + Mlow
        # Newton on r / s, s = sc: the same roots, but close to the circular arcs'
        # phi - (l/EI) Mbar, so it converges like them from far away (r itself is a product,
        # R times dR/dphi). Its Jacobian: J / s + (r / s^2) ds/dphi; ds_i/dphi_j through
        # H(phi_i) (sig) and through the force in arc i's frame (rho: phi_j, j < i, turn a
        # dead force; a follower force turns with phi_j, j >= i).
        scaled = _MINR(sc) > 0.1
        if scaled:
            rho_ = (T[:, 0].conjugate() * f).real
            sig = BB[:, 1, 0]
            isc = 1.0 / sc
            rt = r * isc
            c = rt * isc
        if dense:
            D = np.where(lower, A if follower else A[:, None],
                         Mcol if e is None else Mcol + e[:, None])
            D.flat[::n + 1] = Bd
            D *= -W[:, None]
            D.flat[::n + 1] += 1.0
            J = D
            if scaled:
                Jt = J * isc[:, None]
                if follower:
                    Jt += np.where(lower, 0.0, (c * rho_)[:, None])
                else:
                    Jt -= np.where(lower, (c * rho_)[:, None], 0.0)
                Jt.flat[::n + 1] += c * sig
                lu, piv, dx, _ = _dgesv(Jt, rt)
            else:
                lu, piv, dx, _ = _dgesv(D, r)
            lu_scaled = scaled
        elif scaled:
            u = rt / W
            if follower:
                e = e - u * rho_
                Bd = Bd + (sc - 1.0) / W - u * (sig + rho_)
            else:
                A = A + u * rho_
                Bd = Bd + (sc - 1.0) / W - u * sig
            dx = banded_solve(W * isc, (np.broadcast_to(A, (n,)), Bd, Mcol, e), rt)
        else:
            dx = banded_solve(W, (np.broadcast_to(A, (n,)), Bd, Mcol, e), r)
        phi = limited_step(phi, dx, step_limit)
        if phi is None:
            break
    phi, res, tip = best
    if not res < math.inf:
        phi, tip = np.zeros(n), complex(float(np.sum(l)))
    return phi, res <= 1e-13 + 1e-12 * _MAXR(np.abs(phi)), it, res, tip, J, None


def _small_step(BB: list, T: list, a: list, f: list, RF: list, lE: list, RG: list, r: list,
                w: list, cF: complex, follower: bool):
    """The dense Newton step of ``bezier_tip_newton`` for few arcs (N <= SMALL_N) with the
    Jacobian built in Python floats (numpy's per-call overhead is most of the cost of its ~40
    array operations on one to four arcs): the same formulas in the same order. Arguments:
    the loop's arrays as lists. Returns J (unscaled, as the loop keeps it), the LU factors and
    pivots of the matrix solved, the step dx, whether it was the scaled (r / s) system; None
    when a row weight -dr/dM vanishes (the loop stops)."""
    n = len(w)
    sc = [-BB[i][0][0] for i in range(n)]
    W = [sc[i] * w[i] for i in range(n)]
    if not all(abs(x) > 0 for x in W):
        return None
    A = [0.0] * n
    e = [0.0] * n
    Bd = [0.0] * n
    Mcol = [0.0] * n
    for i in range(n):
        ig = -1.0 / W[i]
        Ti = T[i]
        ai = a[i][0]
        Kn = BB[i][0][1] + 1j * BB[i][0][2] + (ai[0] * Ti[0] + ai[1] * Ti[1] + ai[2] * Ti[2]
                                               + ai[3] * Ti[3])
        kK = (Kn.conjugate() * f[i]).real
        Mlow = -RF[i].real
        Mcol[i] = Mlow - (lE[i] * Ti[17] * cF).imag
        gP1 = RG[i][1] - 1.0
        if follower:
            e[i] = kK * ig - Mlow
            Bd[i] = (gP1 + kK) * ig
        else:
            A[i] = Mlow - kK * ig
            Bd[i] = gP1 * ig + Mlow
    J = [[0.0] * n for _ in range(n)]
    for i in range(n):
        Ji = J[i]
        mw = -W[i]
        for j in range(n):
            if j < i:
                Ji[j] = 0.0 if follower else A[i] * mw
            elif j > i:
                Ji[j] = (Mcol[j] + e[i]) * mw
        Ji[i] = Bd[i] * mw + 1.0
    scaled = min(sc) > 0.1
    if not scaled:
        D = np.array(J)
        lu, piv, dx, _ = _dgesv(D, np.array(r))
        return D, lu, piv, dx, False
    rt = [0.0] * n
    Jt = [[0.0] * n for _ in range(n)]
    for i in range(n):
        isc = 1.0 / sc[i]
        rt[i] = r[i] * isc
        c = rt[i] * isc
        cr = c * (T[i][0].conjugate() * f[i]).real
        Ji, Jti = J[i], Jt[i]
        for j in range(n):
            x = Ji[j] * isc
            if follower and j >= i:
                x += cr
            elif not follower and j < i:
                x -= cr
            Jti[j] = x
        Jti[i] += c * BB[i][1][0]
    lu, piv, dx, _ = _dgesv(np.array(Jt), np.array(rt))
    return np.array(J), lu, piv, dx, True

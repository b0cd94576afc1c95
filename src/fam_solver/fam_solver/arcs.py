"""Closed forms of one circular arc, written in complex numbers, with series near phi = 0.

An arc of length ``l`` that starts at ``P`` with heading ``theta`` and turns by ``phi``
(constant curvature ``phi / l``) has, at arc-length fraction ``t`` in [0, 1],

    p(t) = P + l * exp(i theta) * t * g(phi t),      g(phi) = (exp(i phi) - 1) / (i phi)
                                                            = sin(phi)/phi + i (1 - cos(phi))/phi

(the thesis' Eq. 25 in complex form: g * l is the chord ``(r sin phi, r (1 - cos phi))``).
The mean position over the arc is ``P + l e^{i theta} h(phi)`` with

    h(phi) = integral_0^1 t g(phi t) dt ... = (g(phi) - 1) / (i phi)
           = (1 - cos phi)/phi^2 + i (phi - sin phi)/phi^2,

and the lever from the mean point to the arc end is ``l e^{i theta} q(phi)`` with q = g - h.
For a load at fraction ``tau`` inside the arc, the mean over t in [0, tau] of (p(tau) - p(t))
is ``l e^{i theta} tau^2 q(phi tau)``.

All four functions g, q and their phi-derivatives g', q' are entire; as phi -> 0 the closed
forms cancel (0/0), so |phi| < 1 uses their Taylor series (18 terms: truncation below
3e-16 relative) evaluated as ONE Vandermonde matrix product (few numpy calls; this matters
for small N). Larger |phi| uses the closed forms, which are exact there.

    g  = sum_n (i phi)^n / (n+1)!          q  = sum_n (i phi)^n (n+1)/(n+2)!
    g' = sum_{n>=1} n i^n phi^(n-1)/(n+1)!  q' = sum_{n>=1} n(n+1) i^n phi^(n-1)/(n+2)!

No rclpy here.
"""
from __future__ import annotations

import math

import numpy as np

SERIES_LIMIT = 1.0
_K = 18
_n = np.arange(_K + 1)
_fact = np.array([math.factorial(k) for k in range(_K + 3)], dtype=float)
_ipow = 1j ** _n  # i^n


def _coef_matrix():
    """(K, 8) real matrix: columns Re/Im of g, q, g', q' as polynomials in phi (powers 0..K-1)."""
    C = np.zeros((_K, 8))
    for n in range(_K):
        cg = _ipow[n] / _fact[n + 1]
        cq = _ipow[n] * (n + 1) / _fact[n + 2]
        C[n, 0], C[n, 1] = cg.real, cg.imag
        C[n, 2], C[n, 3] = cq.real, cq.imag
        m = n + 1  # derivative: term m contributes m * c_m phi^(m-1) to power n
        cgp = m * _ipow[m] / _fact[m + 1]
        cqp = m * (m + 1) * _ipow[m] / _fact[m + 2]
        C[n, 4], C[n, 5] = cgp.real, cgp.imag
        C[n, 6], C[n, 7] = cqp.real, cqp.imag
    return C


_COEF = _coef_matrix()
_POW = np.arange(_K, dtype=float)


_CCOEF = _COEF[:, 0::2] + 1j * _COEF[:, 1::2]   # (K, 4) complex: g, q, g', q'


def _powers(phi):
    """(..., K) powers phi^0 .. phi^(K-1) by a running product (np.power is ~10x slower)."""
    V = np.empty(phi.shape + (_K,))
    V[..., 0] = 1.0
    V[..., 1:] = phi[..., None]
    np.multiply.accumulate(V[..., 1:], axis=-1, out=V[..., 1:])
    return V


#: rows per block of ``row_product``
_BLOCK = 256


def row_product(V: np.ndarray, coef: np.ndarray) -> np.ndarray:
    """V (n, k) @ coef (k, m) in row blocks of _BLOCK: a large product would start BLAS
    threads, which stall when the machine's cores are busy (measured: 3-10x the CPU time of
    the Bezier model at N = 1000 on a shared 2-core machine, with a wide spread); blocks this
    small stay in one thread."""
    n = V.shape[0]
    if n <= _BLOCK:
        return V @ coef
    out = np.empty((n, coef.shape[1]), dtype=np.result_type(V, coef))
    for i in range(0, n, _BLOCK):
        np.matmul(V[i:i + _BLOCK], coef, out=out[i:i + _BLOCK])
    return out


def _switch(x, coef, closed):
    """Columns of ``coef`` (Taylor coefficients, (K, m)) summed at x where |x| < SERIES_LIMIT,
    ``closed(x)`` (m arrays) elsewhere: a tuple of m complex arrays shaped like x. One
    Vandermonde product and one closed-form call at most (few numpy calls at small N)."""
    small = np.abs(x) < SERIES_LIMIT
    if x.size == 0 or np.all(small):
        R = (row_product(_powers(x).reshape(-1, _K), coef).reshape(x.shape + (-1,))
             if x.size > 64 else x[..., None] ** _POW @ coef)
        return tuple(R[..., j] for j in range(coef.shape[1]))
    c = closed(np.where(small, 1.0, x))
    if not np.any(small):
        return tuple(c)
    R = row_product(_powers(np.where(small, x, 0.0)).reshape(-1, _K),
                    coef).reshape(x.shape + (-1,))
    return tuple(np.where(small, R[..., j], cj) for j, cj in enumerate(c))


def _closed(phi):
    e = np.exp(1j * phi)
    g = (e - 1.0) / (1j * phi)
    h = (g - 1.0) / (1j * phi)
    gp = (e - g) / phi
    hp = (gp - 1j * h) / (1j * phi)
    return g, g - h, gp, gp - hp


def arc_funcs(phi):
    """g, q, g', q' (complex arrays, same shape as the real array ``phi``) for arc angles phi
    [rad]."""
    return _switch(np.asarray(phi, dtype=float), _CCOEF, _closed)


def g_only(phi):
    """g(phi) = (e^{i phi} - 1)/(i phi), the unit-length chord of an arc turning by phi
    (complex)."""
    phi = np.asarray(phi, dtype=float)
    small = np.abs(phi) < 1e-3
    p = np.where(small, 1.0, phi)
    closed = np.sin(p) / p + 1j * (2.0 * np.sin(0.5 * p) ** 2) / p
    p2 = phi * phi
    ser = ((1.0 - p2 / 6.0 + p2 * p2 / 120.0)
           + 1j * (phi / 2.0 - phi * p2 / 24.0 + phi * p2 * p2 / 720.0))
    return np.where(small, ser, closed)


def bezier_lambda(phi):
    """Handle-length ratio lambda(phi) = h / l of the cubic Bezier that follows a circular arc.

    Derivation (replaces the thesis' garbled Eq. 10): an arc of length l turning by phi has
    radius r = l / phi. Put the Bezier control points as in Eq. 9, p1 = p0 + h t0 and
    p2 = p3 - h t3 (t0, t3 the end tangents). By symmetry the Bezier midpoint c(1/2) =
    (p0 + 3 p1 + 3 p2 + p3)/8 lies on the arc's symmetry axis; requiring it to lie ON the
    circle gives, in the frame with the chord along x and the circle centre on the axis,
    h = (4/3) tan(phi/4) r  (the classic circular-arc handle). Hence

        lambda = h / l = (4/3) tan(phi/4) / phi  -> 1/3 + phi^2/144 + ... as phi -> 0,

    which is exact at the midpoint and the two ends (positions and tangents) and has a
    radial error of about 2.7e-4 r at phi = pi/2 (tests check both). Series below |phi| < 1e-3.
    """
    phi = np.asarray(phi, dtype=float)
    small = np.abs(phi) < 1e-3
    p = np.where(small, 1.0, phi)
    closed = (4.0 / 3.0) * np.tan(p / 4.0) / p
    ser = 1.0 / 3.0 + phi * phi / 144.0
    return np.where(small, ser, closed)


# ---------------------------------------------------------------------------------------
# Clothoid arcs: the first-order effect of a LINEAR change of curvature along an arc.
# ---------------------------------------------------------------------------------------
# An arc of length l, turning by phi in total, whose curvature changes linearly,
# kappa(s) = phi/l + kappa1 (s - l/2), has the heading theta(u) = theta + phi u + rho (u^2 - u)/2
# (u = s/l, rho = kappa1 l^2); to first order in rho its points move off the circular arc by
#     l e^{i theta} i rho K(phi, u),    K(phi, u) = integral_0^u (v^2 - v)/2 e^{i phi v} dv,
# so the end moves by l e^{i theta} i rho k(phi), k = K(phi, 1) (k(0) = -1/12: the classic
# -kappa' l^3 / 12 chord offset), and the mean point by l e^{i theta} i rho km(phi),
# km = integral_0^1 K(phi, u) du = integral_0^1 (1 - v)(v^2 - v)/2 e^{i phi v} dv (km(0) = -1/24).
# With E_n(a) = integral_0^1 v^n e^{i a v} dv:  k = (E2 - E1)/2,  km = (-E3 + 2 E2 - E1)/2,
# E_0 = g, E_n = (e^{ia} - n E_{n-1}) / (i a) (upward recursion: stable for |a| >= 1, error
# growth n!/|a|^n <= 6), and the series E_n = sum_j (i a)^j / (j! (n + j + 1)) below |a| < 1.


def _rate_coef():
    C = np.zeros((_K, 2), dtype=complex)
    for j in range(_K):
        c = _ipow[j] / _fact[j]
        C[j, 0] = c * (1.0 / (j + 3) - 1.0 / (j + 2)) / 2.0
        C[j, 1] = c * (-1.0 / (j + 4) + 2.0 / (j + 3) - 1.0 / (j + 2)) / 2.0
    return C


_RCOEF = _rate_coef()
_KKM = np.concatenate([_RCOEF[:, :1], _RCOEF[:, :1] - _RCOEF[:, 1:]], axis=1)   # k, k - km
_KKMP = np.zeros_like(_KKM)                      # their phi-derivatives (series differentiated;
_KKMP[:-1] = _KKM[1:] * np.arange(1, _K)[:, None]   # the dropped term is below 1e-17 for |phi| < 1)
#: (K, 8) complex: series coefficients of g, q, g', q', k, k - km, k', (k - km)'
_CCOEF8 = np.concatenate([_CCOEF, _KKM, _KKMP], axis=1)


def _rate_closed(phi, derivatives=False):
    """k, km (and k' = i (E3 - E2)/2, (k - km)' = i (E4 - E3)/2 when ``derivatives``) for
    |phi| >= 1 (E4 by the same recursion: error growth 4!/|phi|^4 <= 24)."""
    a = 1j * phi
    e = np.exp(a)
    e0 = (e - 1.0) / a
    e1 = (e - e0) / a
    e2 = (e - 2.0 * e1) / a
    e3 = (e - 3.0 * e2) / a
    k, km = 0.5 * (e2 - e1), 0.5 * (-e3 + 2.0 * e2 - e1)
    if not derivatives:
        return k, km
    e4 = (e - 4.0 * e3) / a
    return k, km, 0.5j * (e3 - e2), 0.5j * (e4 - e3)


def rate_funcs(phi):
    """k(phi), km(phi) (complex, same shape as the real array ``phi``): end and mean-point
    offsets of a clothoid arc per unit rho (see the comment above)."""
    return _switch(np.asarray(phi, dtype=float), _RCOEF, _rate_closed)


_E12 = np.stack([_ipow[:_K] / _fact[:_K] / (np.arange(_K) + 2),
                 _ipow[:_K] / _fact[:_K] / (np.arange(_K) + 3)], axis=1)   # series of E1, E2


def _e12_closed(a):
    ac = 1j * a
    e = np.exp(ac)
    e1 = (e - (e - 1.0) / ac) / ac
    return e1, (e - 2.0 * e1) / ac


def rate_offset(phi, tau):
    """K(phi, tau) = tau (tau^2 E2(phi tau) - tau E1(phi tau)) / 2 (complex): the point at
    fraction ``tau`` of a clothoid arc, off the circular arc per unit rho and l e^{i theta} i."""
    tau = np.asarray(tau, dtype=float)
    E1, E2 = _switch(np.asarray(phi, dtype=float) * tau, _E12, _e12_closed)
    return 0.5 * tau * (tau * tau * E2 - tau * E1)


def clothoid_funcs(phi):
    """g, q, g', q', k, k - km, k', (k - km)' (complex, same shape as ``phi``) from ONE
    Vandermonde product (clothoid arcs: the circular-arc functions, the rate offsets and
    their derivatives together)."""
    return _switch(np.asarray(phi, dtype=float), _CCOEF8, _clothoid_closed)


def _clothoid_closed(p):
    k, km, kp, kkmp = _rate_closed(p, derivatives=True)
    return _closed(p) + (k, k - km, kp, kkmp)

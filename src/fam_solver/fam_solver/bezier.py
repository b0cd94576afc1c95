"""The thesis' Bezier arc model (Eqs. 7-12, 19, 23) as residuals for the FAM Newton solver.

Arc i in its own frame (start at the origin, heading +x), length l, bending angle phi:
control points (Eq. 9, complex, the thesis' L is the arc length l)

    p0 = 0,  p1 = lambda l,  p2 = l g(phi) - lambda l e^{i phi},  p3 = l g(phi),

with lambda = (4/3) tan(phi/4)/phi (``arcs.bezier_lambda``), so p3 and the end tangents
are those of the circular arc (Eqs. 8, 11, 25). Curvature (Eq. 12, counter-clockwise
positive) kappa(t) = Im(conj(c') c'') / |c'|^3, t the Bezier parameter.

Moment along the arc (Eq. 18, local frame): M(t) = M_end + (p3 - c(t)) x F_end + point
loads inside the arc, where the arc's end wrench (M_end, F_end) comes from the distal arcs
(Eqs. 26-27). Eq. 19: Pi_i(phi) = integral_0^1 (M(t) - EI kappa(t))^2 dt, minimised over
phi with the end wrench held fixed in the arc frame (the thesis' sequential algorithm);
Eq. 23 gives G_i = dPi_i/dphi / 2 = integral R dR/dphi dt = 0, R = M - EI kappa, with
analytic phi-derivatives of the control points. Quadrature: 8-point Gauss-Legendre on each
piece of [0, 1] between interior point-load positions.

The residual handed to Newton is r_i = G_i (l/EI)^2, which equals the exact model's
phi_i - (l/EI) Mbar_i to leading order. With loads at arc ends only its exact Jacobian has
the circular arcs' structure (``BezierModel.factors``: the chain rule through each arc's end
wrench in its own frame), so ``linsolve`` solves with it in O(N); with a point force inside
an arc the circular arcs' Jacobian is a good approximate one (quasi-Newton, linear but fast
convergence) or, for few arcs, finite differences.

The assembled global shape (arc end points and headings) is the same as for circular arcs:
Bezier and circle share their ends and end tangents (they differ inside the arc by at most
2.7e-4 r at phi = pi/2). No rclpy here.
"""
from __future__ import annotations

from typing import Optional

import numpy as np

from .arcs import arc_funcs, row_product
from .problem import Problem, repeat_problem

N_GAUSS = 8
_GAUSS = np.polynomial.legendre.leggauss(N_GAUSS)
#: quadrature nodes, weights and Bernstein bases per set of point-load fractions inside arcs
_BASIS = {}


def _lambdas(phi):
    """lambda(phi) (``arcs.bezier_lambda``) and its first and second phi-derivatives, from one
    tangent (closed forms; Taylor series below |phi| < 1e-2)."""
    small = np.abs(phi) < 1e-2
    p = np.where(small, 1.0, phi) if small.any() else phi
    tn = np.tan(0.25 * p)
    sec2 = 1.0 + tn * tn
    ip = 1.0 / p
    q = tn * ip
    lam = (4.0 / 3.0) * q
    dlam = (1.0 / 3.0) * sec2 * ip - lam * ip
    d2lam = ((1.0 / 6.0) * sec2 * tn - (2.0 / 3.0) * sec2 * ip + (8.0 / 3.0) * q * ip) * ip
    if p is not phi:
        p2 = phi * phi
        lam = np.where(small, 1.0 / 3.0 + p2 / 144.0 + p2 * p2 / 5760.0, lam)
        dlam = np.where(small, phi / 72.0 + phi * p2 / 1440.0, dlam)
        d2lam = np.where(small, 1.0 / 72.0 + p2 / 480.0, d2lam)
    return lam, dlam, d2lam


def _nodes(taus=()):
    """Quadrature nodes and weights on [0, 1]: N_GAUSS-point Gauss-Legendre on each piece
    between the point-load fractions ``taus`` inside the arc."""
    edges = [0.0, *taus, 1.0]
    xg, wg = _GAUSS
    ts, ws = [], []
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        ts.append(a + (b - a) * (xg + 1) / 2)
        ws.append(wg * (b - a) / 2)
    return np.concatenate(ts), np.concatenate(ws)


def unit_nodes():
    """Nodes and weights (Q,) of the quadrature of an arc without point loads inside."""
    return _nodes()


class BezierModel:
    """Residuals of the Bezier arc model for a given Problem (loads fixed per case)."""

    def __init__(self, prob: Problem):
        self.prob = prob
        taus = tuple(sorted({t for a, t, _ in prob.point_forces if t < 1.0}))
        cached = _BASIS.get(taus)
        if cached is not None:
            self.t, self.wq, self.b0, self.b1, self.b2, self.bcat = cached
            return
        self.t, self.wq = _nodes(taus)       # (Q,)
        t = self.t
        u = 1 - t
        # Bernstein basis and derivatives, (Q, 4)
        self.b0 = np.stack([u ** 3, 3 * t * u ** 2, 3 * t ** 2 * u, t ** 3], axis=1)
        self.b1 = np.stack([-3 * u ** 2, 3 * u ** 2 - 6 * t * u, 6 * t * u - 3 * t ** 2,
                            3 * t ** 2], axis=1)
        self.b2 = np.stack([6 * u, -12 * u + 6 * t, 6 * u - 12 * t, 6 * t], axis=1)
        if len(_BASIS) > 64:
            _BASIS.clear()
        self.bcat = np.concatenate([self.b0.T, self.b1.T, self.b2.T], axis=1) + 0j   # (4, 3Q)
        _BASIS[taus] = (self.t, self.wq, self.b0, self.b1, self.b2, self.bcat)

    def _basis_at(self, tau):
        u = 1 - tau
        return np.array([u ** 3, 3 * tau * u ** 2, 3 * tau ** 2 * u, tau ** 3])

    def _quad(self, X):
        """Gauss quadrature over t of X (..., Q): (...,), in one thread (``row_product``)."""
        return row_product(X.reshape(-1, X.shape[-1]), self.wq[:, None]).reshape(X.shape[:-1])

    def _curves(self, phi, l):
        """Control points (local frame) and their first and second phi-derivatives
        (B, N, 3, 4), the curve and its phi-derivative at the quadrature nodes (B, N, Q), the
        curvature and its phi-derivative, and the pieces ``_second`` needs."""
        G, _, GP, QP = arc_funcs(phi)
        lam, dlam, d2lam = _lambdas(phi)
        eph = np.exp(1j * phi)
        GPP = 1j * QP                      # g'' = -E_2 = i q'
        P = np.empty(phi.shape + (3, 4), dtype=complex)
        P[..., 0] = 0.0
        P[..., 0, 1] = lam
        P[..., 1, 1] = dlam
        P[..., 2, 1] = d2lam
        P[..., 0, 3] = G
        P[..., 1, 3] = GP
        P[..., 2, 3] = GPP
        P[..., 0, 2] = G - lam * eph
        P[..., 1, 2] = GP - (dlam + 1j * lam) * eph
        P[..., 2, 2] = GPP - (d2lam + 2j * dlam - lam) * eph
        P *= np.asarray(l)[..., None, None]
        Q = self.t.size
        X = row_product(P.reshape(-1, 4), self.bcat).reshape(P.shape[:-1] + (3 * Q,))
        c, c1, c2 = X[..., 0, :Q], X[..., 0, Q:2 * Q], X[..., 0, 2 * Q:]
        dc, dc1, dc2 = X[..., 1, :Q], X[..., 1, Q:2 * Q], X[..., 1, 2 * Q:]
        cc1 = np.conj(c1)
        cr = (cc1 * c2).imag
        sp2 = (cc1 * c1).real
        sp3 = sp2 * np.sqrt(sp2)
        kap = cr / sp3
        dcr = (np.conj(dc1) * c2 + cc1 * dc2).imag
        dsp2 = 2.0 * (cc1 * dc1).real
        dkap = dcr / sp3 - 1.5 * kap * dsp2 / sp2
        cp, dcp = P[..., 0, :], P[..., 1, :]
        extra = (X, P, cc1, c2, dc1, dc2, sp2, sp3, dcr, dsp2)
        return G, GP, cp, dcp, c, dc, kap, dkap, extra

    def _second(self, curves):
        """Second phi-derivatives of the curve at the quadrature nodes (B, N, Q), of its end
        point (B, N, 1) and of the curvature (B, N, Q), from ``_curves``' pieces."""
        kap, dkap = curves[6], curves[7]
        X, P, cc1, c2, dc1, dc2, sp2, sp3, dcr, dsp2 = curves[8]
        Q = self.t.size
        d2c, d2c1, d2c2 = X[..., 2, :Q], X[..., 2, Q:2 * Q], X[..., 2, 2 * Q:]
        d2cr = (np.conj(d2c1) * c2 + 2.0 * np.conj(dc1) * dc2 + cc1 * d2c2).imag
        d2sp2 = 2.0 * ((dc1 * np.conj(dc1)).real + (cc1 * d2c1).real)
        r2 = dsp2 / sp2
        d2kap = (d2cr - 1.5 * dcr * r2) / sp3 - 1.5 * (dkap * r2 + kap * d2sp2 / sp2
                                                        - kap * r2 * r2)
        return d2c, P[..., 2, 3:4], d2kap

    def residual(self, phi, loads, m):
        prob = self.prob
        l, EI = prob.l, prob.EI          # l: arc lengths (N,)
        B, N = phi.shape
        th_end = np.cumsum(phi, axis=1)
        th_start = th_end - phi
        E = np.exp(1j * th_start)
        G, _, cp, dcp, c, dc, kap, dkap, _ = self._curves(phi, l)
        d = l * E * G
        P_end = np.cumsum(d, axis=1)
        # end wrench of each arc (global), full loads only; partial loads handled per node
        M_end = np.repeat(m[:, None], N, axis=1).astype(float)
        F_end = np.zeros((B, N), dtype=complex)
        Mq = np.zeros((B, N, self.t.size))
        dMq = np.zeros_like(Mq)
        tip_rot = None
        Einv = np.conj(E)
        for ld in loads:
            F = ld.F
            if ld.follower:
                if tip_rot is None:
                    tip_rot = np.exp(1j * th_end[:, -1])
                F = F * tip_rot
            a, tau = ld.a, ld.tau
            full_upto = a if tau >= 1.0 else a - 1      # arcs 0..full_upto carry it fully
            if tau >= 1.0:
                pk = P_end[:, a]
            else:
                gt = arc_funcs(phi[:, a] * tau)[0]
                pk = P_end[:, a] - d[:, a] + l[..., a] * E[:, a] * tau * gt
            if full_upto >= 0:
                sl = slice(0, full_upto + 1)
                M_end[:, sl] += ((np.conj(pk[:, None] - P_end[:, sl])) * F[:, None]).imag
                F_end[:, sl] += F[:, None]
            if tau < 1.0:
                Floc = F * Einv[:, a]
                bt = self._basis_at(tau)
                ck = cp[:, a] @ bt               # (B,)
                dck = dcp[:, a] @ bt
                H = (self.t < tau).astype(float)
                lever = ck[:, None] - c[:, a]
                Mq[:, a] += H * (np.conj(lever) * Floc[:, None]).imag
                dMq[:, a] += H * (np.conj(dck[:, None] - dc[:, a]) * Floc[:, None]).imag
        Floc = F_end * Einv                      # (B, N)
        lever = cp[..., 3:4] - c                 # (B, N, Q)
        Mq += M_end[..., None] + (np.conj(lever) * Floc[..., None]).imag
        dMq += (np.conj(dcp[..., 3:4] - dc) * Floc[..., None]).imag
        R = Mq - EI * kap
        dR = dMq - EI * dkap
        Gi = self._quad(R * dR)
        return Gi * (l / EI) ** 2


    def _local(self, phi, l, M, Floc, curves=None):
        """Eq. 23 per arc for end wrenches (M, Floc) held fixed in the arc frame (B, N): the
        residual G (scaled by (l/EI)^2), dG/dM and K with dG = Im(conj(K) dFloc)."""
        EI = self.prob.EI
        _, _, cp, dcp, c, dc, kap, dkap, _ = self._curves(phi, l) if curves is None else curves
        lever = cp[..., 3:4] - c                 # (B, N, Q)
        dlever = dcp[..., 3:4] - dc
        Fq = Floc[..., None]
        R = M[..., None] + (np.conj(lever) * Fq).imag - EI * kap
        dR = (np.conj(dlever) * Fq).imag - EI * dkap
        s = (l / EI) ** 2
        q = self._quad
        return (q(R * dR) * s, q(dR) * s, q(lever * dR + dlever * R) * s,
                R, dR)

    def residual_state(self, phi, loads, m):
        """Residual (B, N) for loads at arc ends only (tip loads; None when a point force
        lies inside an arc), and what ``factors`` needs for the exact Jacobian."""
        if any(ld.tau < 1.0 for ld in loads):
            return None
        l = self.prob.l
        B, N = phi.shape
        th_end = np.cumsum(phi, axis=1)
        E = np.exp(1j * (th_end - phi))
        curves = self._curves(phi, l)
        G, GP = curves[0], curves[1]
        lE = l * E
        P_end = np.cumsum(lE * G, axis=1)
        M = np.repeat(np.asarray(m, dtype=float)[:, None], N, axis=1)
        Fdead = np.zeros((B, N), dtype=complex)
        Ffol = np.zeros((B, N), dtype=complex)
        Mlow = np.zeros((B, N))
        Mall = np.zeros((B, N))
        Mcol = np.zeros((B, N))
        for ld in loads:
            F = ld.F
            if ld.follower:
                F = F * np.exp(1j * th_end[:, -1])
            k = ld.a + 1
            Fc = np.conj(F)[:, None]
            RF = (P_end[:, ld.a:k] - P_end[:, :k]) * Fc         # rel_i conj(F), i <= a
            M[:, :k] -= RF.imag                                 # Im(conj(rel) F)
            Mlow[:, :k] -= RF.real
            if ld.follower:
                Mall[:, :k] += RF.real
                Ffol[:, :k] += F[:, None]
            else:
                Fdead[:, :k] += F[:, None]
            Mcol[:, :k] -= RF.real + (lE[:, :k] * GP[:, :k] * Fc).imag
        Einv = np.conj(E)
        Fdl, Ffl = Fdead * Einv, Ffol * Einv
        r, gM, K, R, dR = self._local(phi, l, M, Fdl + Ffl, curves)
        return r, (phi, curves, R, dR, Fdl + Ffl, Fdl, Ffl, gM, K, Mlow, Mall, Mcol)

    def factors(self, state):
        """The exact Jacobian of the residual of ``residual_state`` in the factor form of
        ``equations.evaluate``: w, (A, Bd, C, e) with J = I - diag(w) D, D_ij = A_i (j < i),
        Bd_i (j = i), C_j + e_i (j > i), as ``linsolve`` solves it; None if degenerate.

        G_i depends on phi_i and on arc i's end wrench in its own frame, M_i and
        Floc_i = F_i e^{-i theta_start,i}; the chain rule through them gives, with w = -dG/dM
        (= l/EI to leading order): dM_i/dphi_j = Mlow_i (j <= i: the distal arcs turn about
        the end of arc i) + Mall_i (follower: the force turns with the tip) + Mcol_j (j > i:
        arc j bends); dFloc_i/dphi_j = -i Floc_dead,i (j < i), +i Floc_fol,i (j >= i). The
        partial dG_i/dphi_i at fixed end wrench is integral (dR^2 + R d2R/dphi^2) dt, with
        the second phi-derivatives of the control points and curvature (``_second``)."""
        phi, curves, R, dR, Floc, Fdl, Ffl, gM, K, Mlow, Mall, Mcol = state
        if not np.all(np.abs(gM) > 0):
            return None
        l, EI = self.prob.l, self.prob.EI
        d2c, d2end, d2kap = self._second(curves)
        d2R = (np.conj(d2end - d2c) * Floc[..., None]).imag - EI * d2kap
        gP = self._quad(dR * dR + R * d2R) * (l / EI) ** 2
        kd = -(np.conj(K) * Fdl).real
        kf = (np.conj(K) * Ffl).real
        A = Mlow + Mall + kd / gM
        Bd = (gP - 1.0) / gM + Mlow + Mall + kf / gM
        e = Mall + kf / gM
        return -gM, (A, Bd, Mcol, e)

class BezierResidual:
    """Bezier residual and its Jacobian. Loads at arc ends (tip loads, point forces on arc
    boundaries): the exact Jacobian (``residual_state`` / ``factors``, any N, quadratic
    convergence). A point force inside an arc: for N <= FD_MAX_N the finite-difference
    Jacobian; beyond, Newton uses the circular-arc model's analytic Jacobian (quasi-Newton: a
    few more iterations, each far cheaper than the O(N^2) finite differences)."""
    FD_MAX_N = 12

    def __init__(self, prob: Problem):
        self.prob = prob
        self.model = BezierModel(prob)
        self._rep = None

    def residual(self, phi: np.ndarray, loads, m: np.ndarray) -> np.ndarray:
        return self.model.residual(phi, loads, m)

    def residual_state(self, phi: np.ndarray, loads, m: np.ndarray):
        """``BezierModel.residual_state``: residual and state, or None (point force inside an
        arc)."""
        return self.model.residual_state(phi, loads, m)

    def factors(self, state):
        """``BezierModel.factors``: the exact Jacobian's factors, or None."""
        return self.model.factors(state)

    def jacobian(self, phi: np.ndarray, scale) -> Optional[np.ndarray]:
        B, N = phi.shape
        if N > self.FD_MAX_N:
            return None
        if self._rep is None or self._rep[0] != B:
            rp = repeat_problem(self.prob, N + 1)
            self._rep = (B, rp, BezierModel(rp))
        _, rp, model = self._rep
        h = 1e-7 * np.maximum(1.0, np.abs(phi))
        P = np.repeat(phi, N + 1, axis=0).reshape(B, N + 1, N)
        idx = np.arange(N)
        P[:, idx + 1, idx] += h
        loads, m = rp.loads(np.repeat(scale, N + 1) if np.ndim(scale) else scale)
        R = model.residual(P.reshape(B * (N + 1), N), loads, m).reshape(B, N + 1, N)
        return np.transpose((R[:, 1:, :] - R[:, :1, :]) / h[:, :, None], (0, 2, 1))

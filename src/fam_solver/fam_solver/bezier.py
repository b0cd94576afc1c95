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
phi_i - (l/EI) Mbar_i to leading order, so the exact model's analytic Jacobian is a good
approximate Jacobian (quasi-Newton, linear but fast convergence).

The assembled global shape (arc end points and headings) is the same as for circular arcs:
Bezier and circle share their ends and end tangents (they differ inside the arc by at most
2.7e-4 r at phi = pi/2). No rclpy here.
"""
from __future__ import annotations

from typing import Optional

import numpy as np

from .arcs import arc_funcs, bezier_lambda
from .problem import Problem, repeat_problem

N_GAUSS = 8
_GAUSS = np.polynomial.legendre.leggauss(N_GAUSS)


def _lambda_and_derivative(phi):
    lam = bezier_lambda(phi)
    small = np.abs(phi) < 1e-2
    p = np.where(small, 1.0, phi)
    x = p / 4.0
    closed = (4.0 / 3.0) * (0.25 / (np.cos(x) ** 2 * p) - np.tan(x) / (p * p))
    ser = phi / 72.0 + phi ** 3 / 1440.0
    return lam, np.where(small, ser, closed)


class BezierModel:
    """Residuals of the Bezier arc model for a given Problem (loads fixed per case)."""

    def __init__(self, prob: Problem):
        self.prob = prob
        taus = sorted({t for a, t, _ in prob.point_forces if t < 1.0})
        edges = [0.0] + taus + [1.0]
        xg, wg = _GAUSS
        ts, ws = [], []
        for a, b in zip(edges[:-1], edges[1:], strict=True):
            ts.append(a + (b - a) * (xg + 1) / 2)
            ws.append(wg * (b - a) / 2)
        self.t = np.concatenate(ts)          # (Q,)
        self.wq = np.concatenate(ws)
        t = self.t
        u = 1 - t
        # Bernstein basis and derivatives, (Q, 4)
        self.b0 = np.stack([u ** 3, 3 * t * u ** 2, 3 * t ** 2 * u, t ** 3], axis=1)
        self.b1 = np.stack([-3 * u ** 2, 3 * u ** 2 - 6 * t * u, 6 * t * u - 3 * t ** 2,
                            3 * t ** 2], axis=1)
        self.b2 = np.stack([6 * u, -12 * u + 6 * t, 6 * u - 12 * t, 6 * t], axis=1)

    def _basis_at(self, tau):
        u = 1 - tau
        return np.array([u ** 3, 3 * tau * u ** 2, 3 * tau ** 2 * u, tau ** 3])

    def residual(self, phi, loads, m):
        prob = self.prob
        l, EI = prob.l, prob.EI          # l: arc lengths (N,)
        B, N = phi.shape
        th_end = np.cumsum(phi, axis=1)
        th_start = th_end - phi
        E = np.exp(1j * th_start)
        G, _, GP, _ = arc_funcs(phi)
        d = l * E * G
        P_end = np.cumsum(d, axis=1)
        lam, dlam = _lambda_and_derivative(phi)
        eph = np.exp(1j * phi)
        # control points (local frame) and their phi-derivatives, (B, N, 4)
        zero = np.zeros_like(G)
        cp = np.stack([zero, l * lam + 0j, l * G - l * lam * eph, l * G], axis=-1)
        dcp = np.stack([zero, l * dlam + 0j, l * GP - l * dlam * eph - 1j * l * lam * eph,
                        l * GP], axis=-1)
        c = cp @ self.b0.T            # (B, N, Q)
        c1 = cp @ self.b1.T
        c2 = cp @ self.b2.T
        dc = dcp @ self.b0.T
        dc1 = dcp @ self.b1.T
        dc2 = dcp @ self.b2.T
        cr = np.imag(np.conj(c1) * c2)
        sp2 = (c1 * np.conj(c1)).real
        sp = np.sqrt(sp2)
        kap = cr / (sp2 * sp)
        dcr = np.imag(np.conj(dc1) * c2 + np.conj(c1) * dc2)
        dsp2 = 2.0 * np.real(np.conj(c1) * dc1)
        dkap = dcr / (sp2 * sp) - 1.5 * cr * dsp2 / (sp2 * sp2 * sp)
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
        Gi = (R * dR) @ self.wq
        return Gi * (l / EI) ** 2


class BezierResidual:
    """Bezier residual and (for N <= FD_MAX_N) its finite-difference Jacobian; beyond, Newton
    uses the circular-arc model's analytic Jacobian (quasi-Newton: a few more iterations,
    each far cheaper than the O(N^2) finite differences; the switch sits where the two cost
    about the same). Tip loads start from the circular-arc solution (``fam.solve_fam``), so
    both need few iterations; a Broyden correction of the quasi-Newton Jacobian was measured
    and saved at most one of them (not used)."""
    FD_MAX_N = 12

    def __init__(self, prob: Problem):
        self.prob = prob
        self.model = BezierModel(prob)
        self._rep = None

    def residual(self, phi: np.ndarray, loads, m: np.ndarray) -> np.ndarray:
        return self.model.residual(phi, loads, m)

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

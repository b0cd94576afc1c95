"""The FAM's arc equations: the residual of the N arc-angle equations and its Jacobian factors.

The catheter (length L, rigidity EI) is cut into N arcs of lengths l_i (sum L); arc i turns
by phi_i. Headings and positions are rebuilt base -> tip (thesis Eq. 28):
theta_i = phi_1 + ... + phi_i, P_i = P_{i-1} + l_i e^{i theta_{i-1}} g(phi_i) (complex
notation, see ``arcs``). The internal moment at a point p(s) is (Eq. 16)

    M(s) = m_tip + sum over loads k distal to s of (p_k - p(s)) x F_k,

which is what carrying the loads tip -> base by rotation and translation (Eqs. 24-27)
produces. Each arc's angle minimises the moment-balance functional Eq. 19 over that arc.
For a circular arc (``arc_model='exact'``, EI kappa = EI phi_i / l_i constant) the minimiser
is the mean-moment equation

    r_i(phi) = phi_i - (l_i / EI) Mbar_i(phi) = 0,     Mbar_i = mean over arc i of M(s);

the mean of p(s) over an arc is closed form (``arcs``), also for a point load inside an arc
(``tau^2 q(phi tau)``).

Clothoid arcs (``arc_model='clothoid'``): each arc's curvature changes LINEARLY along it,
kappa(s) = phi_i/l_i + kappa1_i (s - l_i/2), with kappa1_i the moment change the balance
prescribes, kappa1_i l_i^2 = rho_i = (l_i/EI)(M_end,i - M_start,i) (taken on the arc's
circular chord; smoothly saturated at |rho| = RHO_MAX so that 1-2 arcs under huge loads stay
solvable). phi_i solves the same mean-moment equation; the arc's end and mean point move off
the circular arc by l e^{i theta} i rho k(phi) and l e^{i theta} i rho km(phi) (first order
in rho, closed forms in ``arcs``; k(0) = -1/12 is the classic -kappa' l^3/12 chord offset).
That removes the leading error term of circular arcs: the FAM becomes fourth order. A point
force INSIDE an arc kinks the moment there: that arc keeps an O(l^3) error.

Jacobian structure: d Mbar_i / d phi_j depends only on i for j < i (everything distal rotates
rigidly) and only on j, plus a follower term depending on i, for j > i; ``evaluate`` returns
those factors (A, Bd, C, e) and ``linsolve`` assembles or solves with them. For dead loads
and circular arcs the residual is r = W grad(Pi) (W = diag(l/EI), Pi the potential energy),
so W^-1 J is symmetric (the energy Hessian); ``linsolve.energy_stable`` uses that.
No rclpy here.
"""
from __future__ import annotations

from typing import Optional, Sequence, Tuple

import numpy as np

from .arcs import arc_funcs, clothoid_funcs, g_only, rate_offset

#: clothoid arcs: |rho| = |kappa1| l^2 is saturated smoothly at RHO_MAX (rad), see clothoid_rates
RHO_MAX = 1.0


class Load:
    """One force in the core: arc index ``a`` (0-based), fraction ``tau`` in (0, 1] inside it,
    complex force F (B,) (base frame, or tip frame if ``follower``)."""
    __slots__ = ('a', 'tau', 'F', 'follower')

    def __init__(self, a: int, tau: float, F: np.ndarray, follower: bool):
        self.a, self.tau, self.F, self.follower = a, tau, F, follower


def clothoid_rates(phi: np.ndarray, lE: np.ndarray, G: np.ndarray, th_end: np.ndarray,
                   w: np.ndarray, loads: Sequence[Load]) -> np.ndarray:
    """Clothoid curvature rates rho_i = kappa1_i l_i^2 (B, N) of the arcs at angles phi:
    rho = RHO_MAX tanh(w_i (M_end,i - M_start,i) / RHO_MAX), the moment change along the arc
    taken on its circular chord lE G (see ``arcs``, clothoid arcs). The clothoid offsets are
    first order in rho, valid for |rho| << 1 (N >= 4 up to F L^2/EI = 50); the saturation
    (relative change rho^2/3 below 1e-2 for |rho| < 0.17) keeps the one- and two-arc models
    solvable under huge loads, where the unsaturated first-order offsets have no equilibrium."""
    dM = np.zeros(phi.shape)
    chord = lE * G
    for ld in loads:
        a, tau = ld.a, ld.tau
        F = ld.F * np.exp(1j * th_end[:, -1]) if ld.follower else ld.F
        Fs = np.conj(F)[:, None]
        k = a + 1 if tau >= 1.0 else a
        dM[:, :k] += (chord[:, :k] * Fs).imag       # -(chord x F): the load is beyond the arc
        if tau < 1.0:                                # M_start - M_end = (p_k - P_start) x F
            dM[:, a] += (lE[:, a] * tau * g_only(phi[:, a] * tau) * Fs[:, 0]).imag
    return RHO_MAX * np.tanh(w * dM / RHO_MAX)


Factors = Tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]


def evaluate(phi: np.ndarray, l: np.ndarray, w: np.ndarray, loads: Sequence[Load], m: np.ndarray,
             jac: bool = True, clothoid: bool = False
             ) -> Tuple[np.ndarray, Optional[Factors], np.ndarray]:
    """Residual r (B, N) of the exact (or clothoid) arc model and the Jacobian factors.

    Returns r, (A, Bd, C, e), th_end where dMbar_i/dphi_j = A_i (j < i), Bd_i (j = i),
    C_j + e_i (j > i); Im(conj(X) F) is written -Im(X conj(F)) (fewer numpy calls).
    clothoid: arcs whose curvature changes linearly (rates from ``clothoid_rates`` at phi). The
    factors include the rates' own derivatives (``clothoid_terms``: Newton converges
    quadratically) except for a follower tip force together with point forces (then those
    of circular arcs at the clothoid positions: the rates' derivatives, O(l^2) relative,
    left out; Newton converges linearly, fast).
    """
    B, N = phi.shape
    th_end = np.cumsum(phi, axis=1)
    lE = l * np.exp(1j * (th_end - phi))
    if clothoid:
        G, Q, GP, QP, rk, rkk, rkp, rkkp = clothoid_funcs(phi)     # rkk = k - km; ' = d/dphi
        rho = clothoid_rates(phi, lE, G, th_end, w, loads)
        d = lE * (G + 1j * rho * rk)
        lEq = lE * (Q + 1j * rho * rkk)
    else:
        G, Q, GP, QP = arc_funcs(phi)
        d = lE * G
        lEq = lE * Q
    P_end = np.cumsum(d, axis=1)
    Mbar = np.repeat(m[:, None], N, axis=1) if m.ndim == 1 else m.copy()
    if jac:
        A = np.zeros((B, N))
        Bd = np.zeros((B, N))
        C = np.zeros((B, N))
        e = np.zeros((B, N))
    tip_rot = None
    for ld in loads:
        a, tau = ld.a, ld.tau
        F = ld.F
        if ld.follower:
            if tip_rot is None:
                tip_rot = np.exp(1j * th_end[:, -1])
            F = F * tip_rot
        Fs = np.conj(F)[:, None]
        if tau >= 1.0:
            k = a + 1
            rel = P_end[:, a:a + 1] - P_end[:, :k]     # p_k - P_end,i for i <= a (0 at a)
            Z = rel + lEq[:, :k]
            ZF = Z * Fs                                  # Im(conj(Z) F) = -Im(Z conj F)
            Mbar[:, :k] -= ZF.imag
            if jac:
                if ld.follower:
                    e[:, :k] += ZF.real
                    Bd[:, :k] += ZF.real
                else:
                    A[:, :k] -= ZF.real
                Bd[:, :k] -= ((1j * rel + lE[:, :k] * QP[:, :k]) * Fs).imag
                C[:, :k] -= ((lE[:, :k] * GP[:, :k] + 1j * rel) * Fs).imag
            continue
        gt, qt, gpt, qpt = arc_funcs(phi[:, a] * tau)
        pk = P_end[:, a] - d[:, a] + lE[:, a] * tau * gt
        if clothoid:
            pk = pk + lE[:, a] * 1j * rho[:, a] * rate_offset(phi[:, a], tau)
        rel = pk[:, None] - P_end[:, :a]
        Z = np.empty((B, a + 1), dtype=complex)
        Z[:, :a] = rel + lEq[:, :a]
        Z[:, a] = lE[:, a] * (tau * tau) * qt
        ZF = Z * Fs
        Mbar[:, :a + 1] -= ZF.imag
        if jac:
            A[:, :a + 1] -= ZF.real
            Bd[:, :a] -= ((1j * rel + lE[:, :a] * QP[:, :a]) * Fs).imag
            Bd[:, a] -= (lE[:, a] * (tau ** 3) * qpt * Fs[:, 0]).imag
            C[:, :a] -= ((lE[:, :a] * GP[:, :a] + 1j * rel) * Fs).imag
            C[:, a] -= (lE[:, a] * (tau * tau) * gpt * Fs[:, 0]).imag
    r = phi - w * Mbar
    follower = any(ld.follower for ld in loads)
    if jac and clothoid and loads and (not follower or len(loads) == 1):
        # the rates' own derivatives (clothoid_terms) with the force beyond each arc, Fd
        # (exact for a tip force alone; with point forces the offsets' effect on the loads
        # inside an arc is left out: still close to quadratic)
        Fd = np.zeros((B, N), dtype=complex)
        sg_in = np.zeros((B, N))
        tg_in = np.zeros((B, N))
        for ld in loads:
            F = ld.F * np.exp(1j * th_end[:, -1]) if ld.follower else ld.F
            k = ld.a + 1 if ld.tau >= 1.0 else ld.a
            Fd[:, :k] += F[:, None]
            if ld.tau < 1.0:
                a, tau = ld.a, ld.tau
                gt, _, gpt, _ = arc_funcs(phi[:, a] * tau)
                z = lE[:, a] * np.conj(F)
                sg_in[:, a] += (z * tau * gt).real
                tg_in[:, a] += (z * (tau * tau) * gpt).imag
        lc = lE * np.conj(Fd)
        lo, dg, up, row = clothoid_terms((lc * G).real + sg_in, (lc * GP).imag + tg_in,
                                          (lc * rk).real, (lc * rkk).real, w, rho / RHO_MAX,
                                          follower, rho * (lc * rkp).real, rho * (lc * rkkp).real)
        Bd -= dg         # clothoid_terms gives -dMbar/dphi
        C -= up
        if follower:
            e -= row
        else:
            A -= lo
    if jac:
        return r, (A, Bd, C, e), th_end
    return r, None, th_end


def clothoid_terms(sg: np.ndarray, tg: np.ndarray, a: np.ndarray, b: np.ndarray, w: np.ndarray,
                   th_r: np.ndarray, follower: bool, ap: np.ndarray, bp: np.ndarray) -> tuple:
    """The part of the Jacobian that comes from the clothoid rates' dependence on the arc
    headings and angles; with it Newton converges quadratically. Arrays (N,) or (B, N).

    rho_j = RHO_MAX tanh(w_j dM_j / RHO_MAX), dM_j = Im(chord_j conj Fd_j) (+ the part of
    the loads inside arc j), Fd_j the force beyond arc j (conj F turned with the tip for a
    follower force). Inputs: sg = d dM_j / d theta_j (arc j turned rigidly, loads fixed:
    Re(chord_j conj Fd_j) + ...), tg = d dM_j / d phi_j (Im(l e^{i theta_j} g'_j conj Fd_j) + ...),
    a = Re(l e^{i theta_j} k_j conj Fd_j), b = Re(l e^{i theta_j} (k_j - km_j) conj Fd_j);
    th_r = tanh(rho / RHO_MAX); ap, bp: rho_j Re(l e^{i theta_j} k'_j conj Fd_j) and the same with
    (k - km)': the offsets' change with the arc's own angle (end offset: columns l > i; lever
    offset: the diagonal). Returns (lower by row, diagonal, upper by column, upper by
    row) terms of -dMbar/dphi (the sign of ``D`` in fast_tip_newton before the w scaling);
    the unused ones are None.

    With X_i = (P_N - P_i) + lever_i, Mbar_i = m - Im(X_i cF), the offsets i rho_j l e^{i theta_j}
    k_j
    in P and i rho_i l e^{i theta_i} (k_i - km_i) in lever_i: d rho_j / d phi_l is
    sigma_j = w'_j sg_j for l < j (base-fixed forces), tau_j = w'_j tg_j for l = j, 0 for
    l > j (w' = w (1 - tanh^2)); a follower force turns with the tip: 0, tau_j - sigma_j,
    -sigma_j. Im(i x) = Re(x) makes every term real.
    """
    ws = w * (1.0 - th_r * th_r)
    sig = ws * sg
    tau = ws * tg
    u = a * sig
    cs = np.add.accumulate(u, axis=-1)     # (np.cumsum: the same, a slower Python wrapper)
    if not follower:
        S = cs[..., -1:] - cs         # sum over j > i
        return S + b * sig, S + b * tau + bp, S + a * tau + ap, None
    return None, b * (tau - sig) + bp, a * (tau - sig) - (cs - u) + ap, cs - b * sig

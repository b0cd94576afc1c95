"""Mesh grading (``spacing='graded'``): per-case arc lengths that equidistribute the
curvature change of the equal-arc solution, and the second Newton pass on them.

A circular arc replaces a curve whose curvature changes along it, kappa' = dM/ds / EI =
-(t x F_distal) / EI; its chord is off by -i e^{i theta} kappa' l^3 / 12, so the FAM with
circular arcs is second order in N. ``graded_fractions`` places N arcs so that each holds an
equal share of the monitor rho = sqrt(kappa'^2 + (GRADE_FLOOR max|kappa'|)^2) of the
equal-arc solution (shorter arcs at the base for a lateral tip force, mid-length for a
post-buckled compression; equal arcs for a pure moment or no load; arc-length ratio <= 5.1);
``regrade`` solves again from the first solution mapped onto them (``remap``; the fast
path's ``fast_grade`` starts from the first solution's tangent angle interpolated by local
cubics instead, ``cubic_start``, or from its curvature, ``curvature_start``). It stays a FAM
(N arcs, the same equations with per-arc l_i, still second order). Stability and the
branch checks use the equal-arc solution; the graded one is accepted only if its tip angle
is within 0.5 rad of it (a failed graded pass keeps the equal arcs). Follower tip forces keep
equal arcs (the follower's coupling of the shape to the tip angle is not in the monitor).
The measurements behind these choices are in the package README. No rclpy here.
"""
from __future__ import annotations

import math
from typing import Tuple

import numpy as np

from .bezier import BezierResidual
from .globalise import newton
from .linsolve import DENSE_MAX_N
from .problem import Problem, make_problem

#: monitor exponent p and floor of the grading (see graded_fractions)
GRADE_POWER = 1.0
GRADE_FLOOR = 0.2
_MAXR = np.maximum.reduce


def graded_fractions(phi: np.ndarray, tip_force, follower: bool = False,
                     point_forces=()) -> np.ndarray:
    """Arc lengths (B, N), as fractions of L, for a graded FAM mesh of each case.

    phi: (B, N) arc angles [rad] of the EQUAL-arc solution; tip_force: complex (B,) N (base
    frame, or tip frame if ``follower``); point_forces: list of (s, complex (B,)) base-fixed.

    The error of a circular arc of length l is its chord's offset from the true curve,
    -i e^{i theta} kappa' l^3 / 12, with kappa' = dM/ds / EI = -(t x F_distal) / EI (t the
    tangent, F_distal the resultant of the forces beyond s; a tip moment does not change
    kappa'). The arcs are placed so that each holds an equal share of the monitor
    rho = (kappa'^2 + (GRADE_FLOOR max|kappa'|)^2)^(GRADE_POWER / 2) (p = 1, floor 0.2),
    evaluated at the equal-arc solution's midpoints (rho piecewise constant on the equal
    arcs; the floor keeps every arc within sqrt(1 + f^2)/f = 5.1x of the others and the map
    continuous in the load). Zero kappa' (pure moment, straight catheter) gives equal arcs.
    p = 1 (density ~ |kappa'|) rather than p = 1/2 (the minimiser of sum l^3 |kappa'|): see
    the design record in the package README. Shorter arcs where the curvature changes
    fastest: near the base for a lateral tip force, mid-length for a post-buckled compression.
    """
    phi = np.asarray(phi, dtype=float)
    B, N = phi.shape
    th_end = np.cumsum(phi, axis=1)
    t = np.exp(1j * (th_end - 0.5 * phi))
    Fd = np.asarray(tip_force, dtype=complex)[:, None]
    if follower:
        Fd = Fd * np.exp(1j * th_end[:, -1:])
    Fd = np.broadcast_to(Fd, (B, N))
    if point_forces:
        mid = (np.arange(N) + 0.5) / N
        for s, F in point_forces:
            Fd = Fd + np.where(mid[None, :] < s, np.asarray(F, dtype=complex)[:, None], 0.0)
    # scale-free: normalise the forces first (a denormal force, e.g. 5e-324 N, would
    # otherwise lose its direction in t x F)
    fmax = np.max(np.abs(Fd), axis=1, keepdims=True)
    fmax = np.where(fmax > 0, fmax, 1.0)
    Fd = Fd.real / fmax + 1j * (Fd.imag / fmax)     # (complex / real divides via 1/x: overflows)
    kp = np.abs((np.conj(t) * Fd).imag)
    mx = np.max(kp, axis=1)
    flat = ~(mx > 0) | ~np.isfinite(mx)
    kp = kp / np.where(flat, 1.0, mx)[:, None]          # scale-free, no underflow of kp^2
    rho = (kp * kp + GRADE_FLOOR * GRADE_FLOOR) ** (0.5 * GRADE_POWER)
    rho[flat] = 1.0
    C = np.zeros((B, N + 1))
    np.cumsum(rho, axis=1, out=C[:, 1:])
    C /= C[:, -1:]
    u = np.arange(N + 1) / N
    if N <= DENSE_MAX_N:
        k = np.minimum(np.sum(C[:, None, 1:-1] <= u[None, :, None], axis=2), N - 1)
        rows = np.arange(B)[:, None]
        c0, c1 = C[rows, k], C[rows, k + 1]
        b = (k + (u[None, :] - c0) / (c1 - c0)) / N
    else:
        b = np.stack([np.interp(u, C[i], u) for i in range(B)])
    b[:, 0], b[:, -1] = 0.0, 1.0
    frac = np.diff(b, axis=1)
    frac[flat] = 1.0 / N
    return frac


def remap(phi: np.ndarray, frac_new: np.ndarray, frac_old=None) -> np.ndarray:
    """Arc angles (B, N) of the same tangent-angle curve on arcs frac_new (B, N): theta(s)
    is linear inside each old arc (old arcs: equal, or frac_old (B, N))."""
    B, N = phi.shape
    Th = np.zeros((B, N + 1))
    np.cumsum(phi, axis=1, out=Th[:, 1:])
    b = np.zeros((B, N + 1))
    np.cumsum(frac_new, axis=1, out=b[:, 1:])
    b[:, -1] = 1.0
    if frac_old is None:
        x = b * N
        k = np.clip(np.floor(x).astype(int), 0, N - 1)
        f = x - k
        rows = np.arange(B)[:, None]
        th = Th[rows, k] + f * (Th[rows, k + 1] - Th[rows, k])
    else:
        bo = np.zeros((B, N + 1))
        np.cumsum(frac_old, axis=1, out=bo[:, 1:])
        bo[:, -1] = 1.0
        th = np.stack([np.interp(b[i], bo[i], Th[i]) for i in range(B)])
    return np.diff(th, axis=1)


def regrade(prob: Problem, phi: np.ndarray, arc_model: str) -> tuple:
    """Second pass of spacing='graded' for B cases solved on equal arcs (prob, phi (B, N)):
    graded arcs from the equal-arc solution, Newton from that solution mapped onto them.
    Returns phi (B, N), fractions (B, N), ok (B,) (converged, tip angle within 0.5 rad of the
    equal-arc one), iterations (B,), residual (B,)."""
    pfl = [(s, F) for s, (_, _, F) in zip(prob.pf_s, prob.point_forces, strict=True)]
    frac = graded_fractions(phi, prob.tip_force, prob.follower, pfl)
    gprob = make_problem(prob.n, prob.L, prob.EI, prob.tip_force, prob.follower,
                          prob.tip_moment, pfl, frac, prob.clothoid)
    start = remap(phi, frac)
    bez = BezierResidual(gprob) if arc_model == 'bezier' else None
    p, c, it, r, _ = newton(gprob, start, 1.0, 12 if bez is None else 30, bezier=bez)
    ok = c & np.all(np.isfinite(p), axis=1) & (np.abs(p.sum(axis=1) - phi.sum(axis=1)) < 0.5)
    return p, frac, ok, it, r


_U_CACHE = {}
_STARTS = ('remap', 'curvature', 'cubic')
#: up to this N ``fast_grade`` works in Python floats (``_small_grade``): on few arcs its ~30
#: numpy calls (the cubic start's ~20 of them) cost 18-26 us of a 220-280 us graded solve,
#: about what a Newton step costs there (package README, round 10); = fast_newton.SMALL_N
SMALL_GRADE_N = 4


def fast_grade(phi: np.ndarray, F: complex, follower: bool,
               start: str = 'remap') -> Tuple[np.ndarray, np.ndarray]:
    """graded_fractions and the start of the second pass for one case with 1-D arrays (few
    numpy calls): fractions (N,) and the start angles (N,) on those arcs.

    start: 'remap' (the tangent angle linear in each equal arc, as ``remap``), 'curvature'
    (``curvature_start``: exact for a curvature linear in s, as the small-deflection FAM has;
    remap's piecewise-constant curvature is off by O(l) per arc there) or 'cubic'
    (``cubic_start``: the tangent angle by a local cubic through the equal arcs' ends, the
    fast path's start: package README, round 7). Up to SMALL_GRADE_N arcs in Python floats
    (``_small_grade``), beyond with 1-D arrays (``_array_grade``): the same results."""
    if start not in _STARTS:
        raise ValueError(f"fast_grade: start must be one of {_STARTS}, got {start!r}")
    n = phi.size
    if n <= SMALL_GRADE_N:
        return _small_grade(phi, F, follower, start)
    return _array_grade(phi, F, follower, start)


def _array_grade(phi: np.ndarray, F: complex, follower: bool,
                 start: str) -> Tuple[np.ndarray, np.ndarray]:
    """``fast_grade`` with 1-D arrays (any N)."""
    n = phi.size
    u = _U_CACHE.get(n)
    if u is None:
        u = _U_CACHE[n] = np.arange(n + 1) / n
    th_end = np.add.accumulate(phi)
    t = np.exp(1j * (th_end - 0.5 * phi))
    if follower:
        F = F * complex(math.cos(th_end[-1]), math.sin(th_end[-1]))
    kp = np.abs((t.conjugate() * F).imag)
    mx = float(_MAXR(kp))
    if not (mx > 0 and mx < math.inf):
        return np.full(n, 1.0 / n), phi
    kp /= mx
    rho = (kp * kp + GRADE_FLOOR * GRADE_FLOOR) ** (0.5 * GRADE_POWER)
    C = np.empty(n + 1)
    C[0] = 0.0
    np.add.accumulate(rho, out=C[1:])
    C /= C[-1]
    b = np.interp(u, C, u)
    b[0], b[-1] = 0.0, 1.0
    if start == 'cubic' and n > 1:
        return np.diff(b), cubic_start(phi, th_end, b)
    if start == 'curvature' and n > 1:
        f = np.diff(b)
        return f, curvature_start(phi, b, f)
    Th = np.empty(n + 1)
    Th[0] = 0.0
    Th[1:] = th_end
    return np.diff(b), np.diff(np.interp(b, u, Th))


_MID_CACHE = {}


def curvature_start(phi: np.ndarray, b: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Start angles (N,) on arcs f (N,) (ends b (N + 1,), fractions of L) from the equal-arc
    solution phi (N >= 2): each arc's angle is its length times the curvature at its midpoint,
    the curvature interpolated linearly between the equal arcs' midpoints (phi_j N / L there)
    and extrapolated linearly to the ends. A circular arc's angle is (l/EI) x the mean moment
    over it, which is the moment at its midpoint when the moment is linear in s (small
    deflections under a tip load): then this is the graded solution itself, while ``remap``
    (the tangent angle linear in each equal arc: piecewise-constant curvature) is off by
    O(l / L) relative per arc. On the cliff bench's 16 loaded cases (circular arcs; package
    README, round 6): the start 2.5x (N = 2), 6x (N = 8), 9x (N = 16) closer to the graded
    solution (median, max-norm), the second pass's iterations 55 -> 49, 45 -> 39, 38 -> 32."""
    n = phi.size
    xp = _MID_CACHE.get(n)
    if xp is None:
        xp = _MID_CACHE[n] = np.concatenate([[0.0], (np.arange(n) + 0.5) / n, [1.0]])
    fp = np.empty(n + 2)
    k = fp[1:-1]
    np.multiply(phi, n, out=k)
    fp[0] = 1.5 * k[0] - 0.5 * k[1]
    fp[-1] = 1.5 * k[-1] - 0.5 * k[-2]
    return f * np.interp(0.5 * (b[1:] + b[:-1]), xp, fp)


def cubic_start(phi: np.ndarray, th_end: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Start angles (N,) on arcs with ends b (N + 1,) (fractions of L, b[0] = 0, b[-1] = 1)
    from the equal-arc solution phi (N >= 2; th_end: its tangent angles at the arc ends,
    cumsum(phi)): the tangent angle theta(s), known at the equal arcs' ends j/N (0, th_end),
    interpolated in each equal arc by the cubic through the four nearest ends (the one-sided
    cubic in the first and last arc; N = 2: the parabola through the three), and each new
    arc's angle the difference of theta at its ends. Exact for a cubic theta (a curvature
    quadratic in s); remap (theta linear in each equal arc) is off by O(l^2) per arc and the
    curvature start (``curvature_start``) by O(l^3) where the moment is not linear in s. In
    Newton form on the arc k holding x = b N = k + t: theta = Th_k + t phi_k
    + t (t - 1) ((2 - t) D_k + (1 + t) D_{k+1}) / 6 with D_j = phi_j - phi_{j-1} the second
    difference of Th at the end j (linearly extrapolated to the ends 0 and N)."""
    n = phi.size
    D = np.empty(n + 2)
    np.subtract(phi[1:], phi[:-1], out=D[1:-2])
    if n > 2:
        D[0] = 2.0 * D[1] - D[2]
        D[n] = 2.0 * D[n - 1] - D[n - 2]
    else:
        D[0] = D[2] = D[1]
    D[n + 1] = 0.0
    # per arc k (and a padding entry for x = N): theta = c0 + t phi + t (t - 1) (A + t B)
    c0 = np.empty(n + 1)
    c0[0] = 0.0
    c0[1:] = th_end
    ph = np.empty(n + 1)
    ph[:n] = phi
    ph[n] = 0.0
    A = D[:-1] * (1.0 / 3.0)
    A += D[1:] * (1.0 / 6.0)
    B = np.subtract(D[1:], D[:-1])
    B *= 1.0 / 6.0
    x = b * n
    k = x.astype(np.intp)
    t = x - k
    th = B[k]
    th *= t
    th += A[k]
    th *= t * (t - 1.0)
    th += c0[k]
    th += t * ph[k]
    return np.diff(th)


def _small_grade(phi: np.ndarray, F: complex, follower: bool,
                 start: str) -> Tuple[np.ndarray, np.ndarray]:
    """``fast_grade`` for few arcs (N <= SMALL_GRADE_N) in Python floats: the same formulas as
    ``_array_grade`` (``np.interp``'s slope form included), the same fractions and starts to
    rounding (tests)."""
    p = phi.tolist()
    n = len(p)
    th = [0.0] * (n + 1)           # tangent angle at the equal arcs' ends
    acc = 0.0
    for i in range(n):
        acc += p[i]
        th[i + 1] = acc
    if follower:
        F = F * complex(math.cos(acc), math.sin(acc))
    fr, fi = F.real, F.imag
    kp = [0.0] * n
    for i in range(n):
        a = th[i + 1] - 0.5 * p[i]
        kp[i] = abs(math.cos(a) * fi - math.sin(a) * fr)     # |Im(conj(t) F)|
    mx = max(kp)
    if not (mx > 0 and mx < math.inf):
        return np.full(n, 1.0 / n), phi
    C = [0.0] * (n + 1)
    c = 0.0
    e = 0.5 * GRADE_POWER
    f2 = GRADE_FLOOR * GRADE_FLOOR
    for i in range(n):
        k = kp[i] / mx
        c += (k * k + f2) ** e
        C[i + 1] = c
    C = [x / c for x in C]
    b = [0.0] * (n + 1)
    k = 0
    for j in range(1, n):          # b = interp(u, C, u), u = j / n
        x = j / n
        while k < n - 1 and C[k + 1] <= x:
            k += 1
        b[j] = (1.0 / n) / (C[k + 1] - C[k]) * (x - C[k]) + k / n
    b[n] = 1.0
    f = [b[j + 1] - b[j] for j in range(n)]
    if n == 1:
        return np.array(f), phi
    if start == 'curvature':
        kc = [x * n for x in p]
        xp = [0.0] + [(i + 0.5) / n for i in range(n)] + [1.0]
        fp = [1.5 * kc[0] - 0.5 * kc[1]] + kc + [1.5 * kc[-1] - 0.5 * kc[-2]]
        out = [0.0] * n
        q = 0
        for j in range(n):
            x = 0.5 * (b[j + 1] + b[j])
            while q < n and xp[q + 1] <= x:
                q += 1
            out[j] = f[j] * ((fp[q + 1] - fp[q]) / (xp[q + 1] - xp[q]) * (x - xp[q]) + fp[q])
        return np.array(f), np.array(out)
    if start == 'cubic':
        D = [0.0] * (n + 2)
        for j in range(1, n):
            D[j] = p[j] - p[j - 1]
        if n > 2:      # the second differences extrapolated linearly to the ends 0 and n
            D[0], D[n] = 2.0 * D[1] - D[2], 2.0 * D[n - 1] - D[n - 2]
        else:
            D[0] = D[2] = D[1]
        ph = p + [0.0]
        tb = [0.0] * (n + 1)
        for j in range(n + 1):
            x = b[j] * n
            k = int(x)
            t = x - k
            A = D[k] * (1.0 / 3.0) + D[k + 1] * (1.0 / 6.0)
            B = (D[k + 1] - D[k]) * (1.0 / 6.0)
            tb[j] = (B * t + A) * (t * (t - 1.0)) + th[k] + t * ph[k]
        return np.array(f), np.array([tb[j + 1] - tb[j] for j in range(n)])
    # remap: the tangent angle linear in each equal arc (np.interp(b, u, Th))
    tb = [0.0] * (n + 1)
    q = 0
    for j in range(n + 1):
        x = b[j]
        while q < n - 1 and (q + 1) / n <= x:
            q += 1
        tb[j] = (th[q + 1] - th[q]) / (1.0 / n) * (x - q / n) + th[q]
    return np.array(f), np.array([tb[j + 1] - tb[j] for j in range(n)])

"""The Finite Arc Method (thesis Chapter 3, Eqs. 7-28), solved by Newton on all arc angles.

Model
-----
The catheter (length L, rigidity EI) is cut into N arcs of lengths l_i (sum L; equal,
l = L/N, or graded, see below); arc i turns by phi_i (constant curvature phi_i / l_i).
Headings and positions are rebuilt base -> tip
(Eq. 28): theta_i = phi_1 + ... + phi_i, P_i = P_{i-1} + l_i e^{i theta_{i-1}} g(phi_i)
(complex notation, see ``arcs``). The internal moment at a point p(s) is (Eq. 16)

    M(s) = m_tip + sum over loads k distal to s of (p_k - p(s)) x F_k,

which is exactly what carrying the loads tip -> base by rotation and translation (Eqs. 24-27)
produces. Each arc's angle minimises the moment-balance functional Eq. 19 over that arc:

* ``arc_model="exact"``: a true circular arc, EI kappa = EI phi_i / l constant, so the
  minimiser of  integral over the arc of (M(s) - EI phi_i / l_i)^2 ds  is
  ``phi_i = (l_i / EI) * mean over the arc of M(s)``; the mean of p(s) over an arc is closed
  form (``arcs.h``), also for a point load inside an arc (``tau^2 q(phi tau)``).
* ``arc_model="clothoid"`` (the default): each arc's curvature changes LINEARLY along it,
  kappa(s) = phi_i/l_i + kappa1_i (s - l_i/2), with kappa1_i the moment change the balance
  prescribes, kappa1_i l_i^2 = rho_i = (l_i/EI)(M_end,i - M_start,i) (taken on the arc's
  circular chord; smoothly saturated at |rho| = 1 rad so that 1-2 arcs under huge loads stay
  solvable). phi_i is the same mean-moment equation; the arc's end and mean point move off
  the circular arc by l e^{i theta} i rho k(phi) and l e^{i theta} i rho km(phi) (first order
  in rho, closed forms in ``arcs``; k(0) = -1/12 is the classic -kappa' l^3/12 chord
  offset). That removes the leading error of circular arcs: the FAM becomes FOURTH order
  (the tip error falls 16x per doubling of N, to ~1e-12 L by N ~ 1000: the accuracy of the
  reference rod solver, below which the benchmark cannot follow it).
  N = 12: 0.0006 / 0.0015 % L on the thesis / Blazer sets (circular arcs: 0.12 / 0.09 % L
  graded, 0.17 / 0.20 % L uniform) at ~1.3x the time of equal circular arcs (bench medians
  0.16 / 0.14 ms vs 0.13 / 0.11 ms); Newton keeps its quadratic rate (the rates' derivatives are in the Jacobian for a tip
  force; with point forces the offsets' effect on loads inside an arc is left out,
  ``_clothoid_terms``). A point force INSIDE an arc kinks the moment there: that arc keeps an
  O(l^3) error (still ~10x below circular arcs). ``Shape.arc_rates`` holds rho.
* ``arc_model="bezier"`` (the thesis): each arc is the cubic Bezier of Eqs. 7-9 with
  lambda = (4/3) tan(phi/4)/phi (``arcs.bezier_lambda``), the curvature is Eq. 12, and
  phi_i solves d Pi_i / d phi_i = 0 (Eq. 23) with the arc's END wrench held fixed in the
  arc's own frame (the thesis' sequential tip -> base algorithm), Pi_i evaluated with
  8-point Gauss-Legendre quadrature in the Bezier parameter. See ``bezier``.

Arc model and spacing (decision): clothoid arcs, equal lengths, by default
-------------------------------------------------------------------------
Circular arcs (the thesis's FAM, 'exact') missed the N = 12 target of 0.1 % L on a
post-buckled compression whatever the spacing (below); the clothoid arcs remove the error
term itself and meet it 100x over, on equal arcs (grading them adds ~1.7x time and does not
pay: Blazer set 0.0008 vs 0.0015 % L, thesis set 0.0010 vs 0.0006 % L; the kappa' monitor
targets the circular arcs' error term, which the clothoid arcs no longer have). The graded
mesh stays available for both models.

Each circular arc's angle is exact given the positions (mean moment); the error is in the positions:
a circular arc replaces a curve whose curvature changes along it, kappa' = dM/ds / EI =
-(t x F_distal) / EI, and its chord is off by -i e^{i theta} kappa' l^3 / 12. Both the chord
errors and the lever-arm errors they cause are O(l^2) overall (second order in N).
``spacing="graded"`` first solves on N equal arcs, then places N arcs that
equidistribute rho = sqrt(kappa'^2 + (0.2 max|kappa'|)^2) of that solution
(``graded_fractions``: shorter arcs at the base for a lateral tip force, mid-length for a
post-buckled compression; equal arcs for a pure moment or no load; arc-length ratio <= 5.1)
and solves again from the first solution mapped onto them (2-3 Newton steps). A fixed
grading was tried first: a geometric one (ratio e^c, best c ~ 1.0-1.5) reaches 0.12-0.13 %
L on the benchmark sets at N = 12 but doubles the error of near-buckling compressions
(their kappa' is largest at the tip); the per-case grading is better on 90 % of 300 random
tip loads (F L^2/EI <= 21, moments), mean error 0.103 -> 0.060 % L, never much worse.
It stays a FAM: N arcs of constant curvature, the same equations with per-arc l_i; still
second order (the monitor converges with N); point forces sit inside arcs at their fraction
(closed form, as before). Stability and the branch checks use the equal-arc solution (the
graded one is on the same branch: accepted only if its tip angle is within 0.5 rad); a
failed graded pass keeps the equal arcs (``shape.arc_lengths`` says which). Follower tip
forces keep equal arcs too: there the grading helped 69 % of 80 random cases (alpha <= 8)
but made the worst ones up to 2.9x worse (0.15 -> 0.44 % L, forces near the tip tangent):
the follower's coupling of the whole shape to the tip angle is not in the kappa' monitor.
``spacing="uniform"`` is the equal-arc FAM (half the single-solve time, 1.5x the batch
throughput, ~1.5-2.2x the tip error). Measured at N = 12 (bench_fam): Blazer set 0.203 ->
0.091 % L, thesis set 0.171 -> 0.122 % L (its post-buckled 170 deg compression; all other
cases <= 0.096 % L); a 6-knot density optimised against the reference for that case
reaches only 0.089 % L, so no arc placement meets 0.1 % L there by a wide margin.

Loads fixed in the base frame (decision)
----------------------------------------
With base-fixed loads the arc orientations are unknown during the tip -> base sweep, so
the N equations r_i(phi) = phi_i - (l/EI) Mbar_i(phi) = 0 are coupled. They are solved
together by Newton's method on all N angles with the ANALYTIC Jacobian. It has a
semiseparable structure (d Mbar_i / d phi_j depends only on i for j < i -- everything
distal rotates rigidly -- and only on j, plus a follower term depending on i, for j > i),
so it is assembled densely for N <= 64 (np.linalg.solve on (B, N, N), vectorised over a
batch) and solved in O(N) by a forward sweep with two shooting unknowns beyond.
Follower tip forces (tendon pull) are the same system: the force turns with theta_N.

Globalisation (which equilibrium): Newton starts from the small-deflection beam shape
(the moments of the loads on the straight catheter, without the geometric stiffness of
axial loads) rescaled to a plausible tip angle (towards the force for a dead tip force),
with steps limited to 0.3 rad per arc. The result is accepted when it converged, turned
the way the small-deflection beam turns, and (load parameter > 2) every eigenvalue of the
Jacobian has a positive real part -- J = I at zero load, so the natural loading branch
keeps them there until a critical point. Otherwise the load is applied by continuation
from zero (vectorised over cases, secant predictor, <= 0.5 rad tip-angle change per step,
the same eigenvalue check after every step). N > 64 starts from the N = 32 solution
interpolated onto the arcs. Tolerance: max |r_i| <= 1e-13 + 1e-12 max|phi|.

Snap-through: where the loading path has a fold (no nearby equilibrium beyond it), the
solver looks for an equilibrium at the full load from the last shape and from shapes turned
to tip angles up to 2 pi, prefers a stable one, and says so in ``warning``.

Speed: one tip-loaded case with N <= 64 uses ``_fast_tip_newton`` (1-D arrays, ~35 numpy
calls per iteration, LAPACK dgesv/dgeev directly); batches run the same Newton vectorised
over cases, dropping converged cases from the active set.

Buckling (decision)
-------------------
A purely axial compression leaves the straight shape an equilibrium for every load (the
residual is exactly zero there), so loading from zero stays straight. Past the first
critical load that straight equilibrium is unstable: it is returned (converged=True), but
``stable=False`` and ``warning`` says so. Stability is judged from the Newton Jacobian
at the solution (an eigenvalue with non-positive real part), checked only when some load
compresses the catheter along its tangent.

Non-convergence returns the best iterate (finite numbers) with ``converged=False``.
No rclpy here.
"""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from .arcs import arc_funcs, clothoid_funcs, g_only, rate_offset
from .model import SPACINGS, BatchShape, Catheter, Loads, Shape, arc_shape, uniform_fractions

ARC_MODELS = ('exact', 'bezier', 'clothoid')
#: The default arc model: 'clothoid' (fourth order; N = 12 ~100x more accurate than the
#: circular arcs at ~1.4x their time). 'exact' and 'bezier' are second order and equally
#: accurate (within ~7 %); 'exact' is ~10-17x faster than 'bezier' (N = 12: ~0.1-0.2 ms vs
#: ~1.6-3.4 ms).
DEFAULT_ARC_MODEL = 'clothoid'
#: The default arc spacing: 'uniform' (equal arcs) or 'graded' (per-case arc lengths, see
#: graded_fractions; ~2x more accurate for circular arcs at ~1.6x the time).
DEFAULT_SPACING = 'uniform'
DENSE_MAX_N = 64
MAX_N = 100_000

_TRIL_CACHE = {}


def _masks(n):
    m = _TRIL_CACHE.get(n)
    if m is None:
        idx = np.arange(n)
        m = (idx[:, None] > idx[None, :], np.eye(n, dtype=bool), np.eye(n))
        _TRIL_CACHE[n] = m
    return m


class _Load:
    """One force in the core: arc index ``a`` (0-based), fraction ``tau`` in (0, 1] inside it,
    complex force F (B,) (base frame, or tip frame if ``follower``)."""
    __slots__ = ('a', 'tau', 'F', 'follower')

    def __init__(self, a, tau, F, follower):
        self.a, self.tau, self.F, self.follower = a, tau, F, follower


#: clothoid arcs: |rho| = |kappa1| l^2 is saturated smoothly at RHO_MAX (rad), see _rates
RHO_MAX = 1.0


def _rates(phi, lE, G, th_end, w, loads: Sequence[_Load]):
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


def _evaluate(phi, l, w, loads: Sequence[_Load], m, jac=True, clothoid=False):
    """Residual r (B, N) of the exact (or clothoid) arc model and the Jacobian factors.

    Returns r, (A, Bd, C, e), th_end where dMbar_i/dphi_j = A_i (j < i), Bd_i (j = i),
    C_j + e_i (j > i); Im(conj(X) F) is written -Im(X conj(F)) (fewer numpy calls).
    clothoid: arcs whose curvature changes linearly (rates from ``_rates`` at phi). The
    factors include the rates' own derivatives (``_clothoid_terms``: Newton converges
    quadratically) except for a follower tip force together with point forces (then those
    of circular arcs at the clothoid positions: the rates' derivatives, O(l^2) relative,
    left out; Newton converges linearly, fast).
    """
    B, N = phi.shape
    th_end = np.cumsum(phi, axis=1)
    lE = l * np.exp(1j * (th_end - phi))
    if clothoid:
        G, Q, GP, QP, rk, rkk, rkp, rkkp = clothoid_funcs(phi)     # rkk = k - km; ' = d/dphi
        rho = _rates(phi, lE, G, th_end, w, loads)
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
        # the rates' own derivatives (_clothoid_terms) with the force beyond each arc, Fd
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
        lo, dg, up, row = _clothoid_terms((lc * G).real + sg_in, (lc * GP).imag + tg_in,
                                          (lc * rk).real, (lc * rkk).real, w, rho / RHO_MAX,
                                          follower, rho * (lc * rkp).real, rho * (lc * rkkp).real)
        Bd -= dg         # _clothoid_terms gives -dMbar/dphi
        C -= up
        if follower:
            e -= row
        else:
            A -= lo
    if jac:
        return r, (A, Bd, C, e), th_end
    return r, None, th_end


def _dense_jacobian(w, fac):
    A, Bd, C, e = fac
    B, N = A.shape
    lower, diag, eye = _masks(N)
    D = np.where(lower, A[:, :, None], C[:, None, :] + e[:, :, None])
    D[:, diag] = Bd
    w = np.asarray(w, dtype=float)
    J = eye - (w[..., :, None] if w.ndim else w) * D    # row i scaled by w_i = l_i / EI
    return J


def _structured_solve(w, fac, rhs):
    """Solve J x = rhs for J = I - w D (D semiseparable, see _evaluate) in O(N), batched."""
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


def _newton_step(w, fac, r):
    B, N = r.shape
    if N <= DENSE_MAX_N:
        J = _dense_jacobian(w, fac)
        try:
            dx = np.linalg.solve(J, -r[:, :, None])[:, :, 0]
        except np.linalg.LinAlgError:
            dx = np.linalg.lstsq(J[0], -r[0], rcond=None)[0][None] if B == 1 else \
                np.stack([np.linalg.lstsq(J[b], -r[b], rcond=None)[0] for b in range(B)])
        return dx, J
    return _structured_solve(w, fac, -r), None


class _Problem:
    """Loads scaled by a continuation factor; builds _Load lists for a given scale.

    l: arc lengths (N,) m, or (B, N) per case (graded arcs); w = l / EI, same shape;
    L: catheter length; EI; point_forces: (arc index, fraction inside the arc, complex (B,))
    (a point force needs arcs common to all cases: l (N,) or B = 1); pf_s: their arc-length
    fractions of the whole catheter."""

    def __init__(self, n, l, w, tip_force, follower, tip_moment, point_forces, L, EI, pf_s,
                 clothoid=False):
        self.n, self.l, self.w = n, l, w
        self.clothoid = clothoid          # arc model 'clothoid' (else circular arcs)
        self.L, self.EI = L, EI
        self.pf_s = pf_s
        self.tip_force = tip_force      # complex (B,)
        self.follower = follower
        self.tip_moment = tip_moment    # (B,)
        self.point_forces = point_forces  # list of (a, tau, complex (B,))

    def loads(self, scale):
        out = []
        for a, tau, F in self.point_forces:
            out.append(_Load(a, tau, F * scale, False))
        if np.any(self.tip_force != 0):
            out.append(_Load(self.n - 1, 1.0, self.tip_force * scale, self.follower))
        return out, self.tip_moment * scale


def _make_problem(n, L, EI, tip_force, follower, tip_moment, point_forces, fractions=None,
                  clothoid=False):
    """Core problem of n arcs of lengths L * fractions ((N,) or (B, N); None: equal arcs);
    point_forces: list of (s fraction, complex (B,)). A point force inside an arc is carried
    at its fraction tau of that arc (closed form); at an arc end tau = 1."""
    frac = uniform_fractions(n) if fractions is None else fractions
    l = L * frac
    w = l / EI
    fr = frac if frac.ndim == 1 else frac[0]          # point forces: B = 1 when per case
    bounds = np.concatenate([[0.0], np.cumsum(fr)])
    bounds[-1] = 1.0
    frac = fr
    pfs, pf_s = [], []
    for s, F in point_forces:
        a = int(np.searchsorted(bounds, s - 1e-9 / n, side='left')) - 1
        a = min(max(a, 0), n - 1)
        tau = min(max((s - bounds[a]) / frac[a], 0.0), 1.0)
        if tau >= 1.0 - 1e-9:
            tau = 1.0
        pfs.append((a, tau, F))
        pf_s.append(s)
    return _Problem(n, l, w, tip_force, follower, tip_moment, pfs, L, EI, pf_s, clothoid)


def _build_problem(cat: Catheter, n: int, tip_force, follower, tip_moment, point_forces,
                   fractions=None, clothoid=False):
    return _make_problem(n, cat.length, cat.ei, tip_force, follower, tip_moment, point_forces,
                         fractions, clothoid)


def _tol(phi):
    return 1e-13 + 1e-12 * np.max(np.abs(phi), axis=1)


def _alpha(prob: _Problem):
    """Dimensionless load size per case: sum |F| L^2/EI + |m| L/EI, (B,)."""
    L = prob.L
    EI = prob.EI
    f = np.abs(prob.tip_force)
    for _, _, F in prob.point_forces:
        f = f + np.abs(F)
    return f * L * L / EI + np.abs(prob.tip_moment) * L / EI


def _repeat(prob: _Problem, k):
    rep = lambda x: np.repeat(x, k)  # noqa: E731
    rl = (lambda x: np.repeat(x, k, axis=0)) if np.ndim(prob.l) == 2 else (lambda x: x)  # noqa: E731
    return _Problem(prob.n, rl(prob.l), rl(prob.w), rep(prob.tip_force), prob.follower,
                    rep(prob.tip_moment), [(a, t, rep(F)) for a, t, F in prob.point_forces],
                    prob.L, prob.EI, prob.pf_s, prob.clothoid)


class _BezierResidual:
    """Bezier residual and (for small N) its finite-difference Jacobian."""
    FD_MAX_N = 24

    def __init__(self, prob):
        from .bezier import BezierModel
        self.prob = prob
        self.model = BezierModel(prob)
        self._rep = None

    def residual(self, phi, loads, m):
        return self.model.residual(phi, loads, m)

    def jacobian(self, phi, scale):
        B, N = phi.shape
        if N > self.FD_MAX_N:
            return None
        if self._rep is None or self._rep[0] != B:
            rp = _repeat(self.prob, N + 1)
            from .bezier import BezierModel
            self._rep = (B, rp, BezierModel(rp))
        _, rp, model = self._rep
        h = 1e-7 * np.maximum(1.0, np.abs(phi))
        P = np.repeat(phi, N + 1, axis=0).reshape(B, N + 1, N)
        idx = np.arange(N)
        P[:, idx + 1, idx] += h
        loads, m = rp.loads(np.repeat(scale, N + 1) if np.ndim(scale) else scale)
        R = model.residual(P.reshape(B * (N + 1), N), loads, m).reshape(B, N + 1, N)
        return np.transpose((R[:, 1:, :] - R[:, :1, :]) / h[:, :, None], (0, 2, 1))


def _newton(prob: _Problem, phi, scale, max_iter, step_limit=0.6, bezier=None):
    """Damped Newton at a fixed load scale (scalar or (B,)), vectorised over the cases;
    converged cases drop out of the active set.

    Returns phi (best iterate), converged (B,), iterations (B,), max|r| (B,), Jacobian
    factors of the exact model at the returned phi (for the branch check).
    """
    B, N = phi.shape
    scale = np.broadcast_to(np.asarray(scale, dtype=float), (B,))
    best = phi.copy()
    best_res = np.full(B, np.inf)
    fac_best = tuple(np.zeros((B, N)) for _ in range(4))
    iters = np.zeros(B, dtype=int)
    act = np.arange(B)
    sub, sc, ph = prob, scale, phi.copy()
    bz = bezier
    for it in range(max_iter + 1):
        loads, m = sub.loads(sc)
        r, fac, _ = _evaluate(ph, sub.l, sub.w, loads, m, jac=True, clothoid=sub.clothoid)
        if bz is not None:
            r = bz.residual(ph, loads, m)
        res = np.max(np.abs(r), axis=1)
        res = np.where(np.isfinite(res), res, np.inf)
        improve = res < best_res[act]
        if np.any(improve):
            ii = act[improve]
            best[ii] = ph[improve]
            best_res[ii] = res[improve]
            for fb, f in zip(fac_best, fac):
                fb[ii] = f[improve]
        conv = res <= _tol(ph)
        if np.all(conv) or it == max_iter:
            break
        iters[act] += 1
        Jb = bz.jacobian(ph, sc) if bz is not None else None
        if Jb is not None:
            try:
                dx = np.linalg.solve(Jb, -r[:, :, None])[:, :, 0]
            except np.linalg.LinAlgError:
                dx, _ = _newton_step(sub.w, fac, r)
        else:
            dx, _ = _newton_step(sub.w, fac, r)
        dx = np.where(np.isfinite(dx), dx, 0.0)
        mx = np.max(np.abs(dx), axis=1)
        dx *= np.where(mx > step_limit, step_limit / np.maximum(mx, 1e-300), 1.0)[:, None]
        ph = ph + dx
        if np.any(conv):
            keep = ~conv
            act, ph, sc = act[keep], ph[keep], sc[keep]
            sub = _subproblem(sub, keep)
            if bz is not None:
                bz = _BezierResidual(sub)
    conv = best_res <= _tol(best)
    return best, conv, iters, best_res, fac_best


def _principal_ok(prob: _Problem, fac):
    """Branch check for a directly solved case: every eigenvalue of the Newton Jacobian has a
    positive real part (J = I at zero load; reaching another branch means an eigenvalue
    crossed zero). (B,) bool; N <= DENSE_MAX_N only."""
    J = _dense_jacobian(prob.w, fac)
    ev = np.linalg.eigvals(J)
    return np.min(ev.real, axis=1) > 1e-9


COARSE_N = 32


def _linear_guess(prob: _Problem):
    """Small-deflection beam solution phi_lin = (l/EI) Mbar(straight) (B, N) -- the moments
    of the loads on the UNDEFORMED catheter, without the geometric stiffness of axial loads
    (so its sign is the natural loading direction even past buckling) -- its tip angle
    theta_lin (B,), and a start for Newton: phi_lin rescaled to a plausible tip angle.

    For a dead tip force at angle beta (no moment, no point forces) the natural branch turns
    the tip towards the force, so the start uses theta = beta (1 - exp(-theta_lin / beta));
    otherwise |theta| <= 1.5 rad."""
    B, N = prob.tip_force.shape[0], prob.n
    loads, m = prob.loads(1.0)
    r0, _, _ = _evaluate(np.zeros((B, N)), prob.l, prob.w, loads, m, jac=False)
    lin = -r0
    th = lin.sum(axis=1)
    ath = np.abs(th)
    target = np.minimum(ath, 1.5)
    if not prob.follower and not prob.point_forces:
        beta = np.angle(prob.tip_force)
        same = (np.sign(beta) == np.sign(th)) & (prob.tip_moment == 0) & (beta != 0)
        ab = np.where(same, np.abs(beta), 1.0)
        # an axial compression past buckling turns the tip further than the linear beam says
        L = prob.L
        a_ax = np.maximum(0.0, -np.cos(beta)) * np.abs(prob.tip_force) * L * L / prob.EI / 2
        target = np.where(same, ab * -np.expm1(-(ath + a_ax) / ab), target)
    # (lin / ath) * target, not lin * (target / ath): with a denormal lateral load the ratio
    # target / ath overflows to inf, while lin / ath stays a finite direction
    safe = np.where(ath > 0, ath, 1.0)
    start = np.where((ath > 0)[:, None], lin / safe[:, None] * target[:, None], lin)
    return lin, th, start


def _accept(prob: _Problem, phi, conv, th_lin, fac=None):
    """Direct-solve acceptance: converged, tip turned the way the linear beam turns (when that
    is clear), and the branch check (all Jacobian eigenvalues in the right half plane)."""
    th = phi.sum(axis=1)
    ok = conv & ((np.sign(th) == np.sign(th_lin)) | (np.abs(th_lin) < 0.1))
    big = ok & ((np.abs(th_lin) > 0.3) | (_alpha(prob) > 2.0))
    if np.any(big) and prob.n <= DENSE_MAX_N:
        idx = np.nonzero(big)[0]
        if fac is None:
            sub = _subproblem(prob, idx)
            loads, m = sub.loads(1.0)
            _, f, _ = _evaluate(phi[idx], sub.l, sub.w, loads, m, clothoid=sub.clothoid)
        else:
            f = tuple(x[idx] for x in fac)
        good = _principal_ok(prob, f)
        ok[idx[~good]] = False
    return ok


def _solve(prob: _Problem, B, arc_model='exact'):
    """Globalised solve for B cases.

    1. zero load -> exactly straight;
    2. N <= 64: damped Newton from the rescaled small-deflection solution, accepted by
       ``_accept``; N > 64: Newton from the coarse (N = 32) solution interpolated onto the
       arcs (that solution is accepted already);
    3. otherwise load continuation from zero (per case). A result that is exactly straight
       is kept (loading from zero keeps an axially loaded catheter straight).
    """
    N = prob.n
    bez = _BezierResidual(prob) if arc_model == 'bezier' else None
    alpha = _alpha(prob)
    zero = alpha == 0
    iters = np.zeros(B, dtype=int)
    snapped = np.zeros(B, dtype=bool)
    lin, th_lin, guess = _linear_guess(prob)
    if N <= DENSE_MAX_N:
        phi0 = guess
    else:
        coarse = _coarse_problem(prob)
        pc, cc, ic, _, _ = _solve(coarse, B, 'exact')
        iters += ic
        # curvature at the coarse midpoints -> fine arcs (piecewise linear), phi = kappa l
        sc, sf = _midpoints(coarse), _midpoints(prob)
        phi0 = np.stack([np.interp(sf, sc, pc[b] / coarse.l) for b in range(B)]) * prob.l
    phi, conv, it, res, fac = _newton(prob, phi0, 1.0, 12 if bez is None else 30, bezier=bez)
    iters += it
    ok = _accept(prob, phi, conv, th_lin, fac) if N <= DENSE_MAX_N else conv.copy()
    straight = conv & ~np.any(phi != 0.0, axis=1)
    ok |= zero | straight
    phi[zero] = 0.0
    res[zero] = 0.0
    conv |= zero
    if not np.all(ok):
        idx = np.nonzero(~ok)[0]
        sub = _subproblem(prob, idx)
        p2, c2, it2, r2, sn2 = _continuation(sub, len(idx), arc_model, lin[idx])
        # keep the continuation result unless it failed and the direct one converged
        take = c2 | ~conv[idx]
        phi[idx[take]] = p2[take]
        conv[idx[take]] = c2[take]
        res[idx[take]] = r2[take]
        snapped[idx[take]] = sn2[take]
        iters[idx] += it2
    return phi, conv, iters, res, snapped


def _subproblem(prob: _Problem, idx):
    per_case = np.ndim(prob.l) == 2
    return _Problem(prob.n, prob.l[idx] if per_case else prob.l, prob.w[idx] if per_case else prob.w,
                    prob.tip_force[idx], prob.follower,
                    prob.tip_moment[idx], [(a, t, F[idx]) for a, t, F in prob.point_forces],
                    prob.L, prob.EI, prob.pf_s, prob.clothoid)


def _coarse_problem(prob: _Problem):
    """The same loads on COARSE_N equal arcs (start and stability model for N > 64)."""
    return _make_problem(COARSE_N, prob.L, prob.EI, prob.tip_force, prob.follower, prob.tip_moment,
                         [(s, F) for s, (_, _, F) in zip(prob.pf_s, prob.point_forces)],
                         clothoid=prob.clothoid)


def _midpoints(prob: _Problem):
    """Arc-length fractions (N,) of the arc midpoints (equal arcs)."""
    c = np.cumsum(prob.l)
    return (c - 0.5 * prob.l) / prob.L


MAX_CONTINUATION_ITERS = 600


def _continuation(prob: _Problem, B, arc_model, lin=None):
    """Load every case from zero in adaptive steps, vectorised over the cases (each has its
    own load scale s and step ds): secant predictor (the small-deflection solution for the
    first step), at most 0.5 rad change of the tip angle per step, the branch check after
    each step (a critical point is crossed only with steps < 1e-3, then the case is marked
    unstable and followed), at most MAX_CONTINUATION_ITERS Newton iterations per case."""
    N = prob.n
    if lin is None:
        lin = _linear_guess(prob)[0]
    th_lin = np.max(np.abs(np.cumsum(lin, axis=1)), axis=1)
    s = np.zeros(B)
    ds = np.minimum(0.25, 0.3 / np.maximum(th_lin, 1e-12))
    phi = np.zeros((B, N))
    prev = np.zeros((B, N))
    prev_s = np.zeros(B)
    has_prev = np.zeros(B, dtype=bool)
    unstable = np.zeros(B, dtype=bool)
    total = np.zeros(B, dtype=int)
    res = np.zeros(B)
    while True:
        act = np.nonzero((s < 1.0) & (ds >= 1e-5) & (total < MAX_CONTINUATION_ITERS))[0]
        if act.size == 0:
            break
        sub = _subproblem(prob, act)
        bez = _BezierResidual(sub) if arc_model == 'bezier' else None
        s_new = np.minimum(1.0, s[act] + ds[act])
        hp = has_prev[act]
        denom = np.where(hp, s[act] - prev_s[act], 1.0)
        guess = np.where(hp[:, None],
                         phi[act] + (phi[act] - prev[act]) * ((s_new - s[act]) / denom)[:, None],
                         lin[act] * s_new[:, None])
        p, c, it, r, fac = _newton(sub, guess, s_new, 8 if bez is None else 20, bezier=bez)
        total[act] += it
        small = ds[act] < 1e-3
        okstep = c & ((np.abs(np.sum(p - phi[act], axis=1)) <= 0.5) | small)
        chk = okstep & ~unstable[act]
        if N <= DENSE_MAX_N and np.any(chk):
            ci = np.nonzero(chk)[0]
            good = _principal_ok(sub, tuple(x[ci] for x in fac))
            bad = ci[~good]
            unstable[act[bad[small[bad]]]] = True
            okstep[bad[~small[bad]]] = False
        acc_i, rej_i = act[okstep], act[~okstep]
        prev[acc_i] = phi[acc_i]
        prev_s[acc_i] = s[acc_i]
        has_prev[acc_i] = True
        phi[acc_i] = p[okstep]
        s[acc_i] = s_new[okstep]
        res[acc_i] = r[okstep]
        ds[acc_i] = np.minimum(ds[acc_i] * 2.0, 0.5)
        ds[rej_i] *= 0.5
    conv = s >= 1.0
    snapped = np.zeros(B, dtype=bool)
    left = np.nonzero(~conv)[0]
    for b in left:
        # the path stopped at a fold (snap-through) or could not be followed: look for an
        # equilibrium at the full load from the last point and from starts turned further
        # along the path; prefer a stable one
        sub = _subproblem(prob, np.array([b]))
        bez = _BezierResidual(sub) if arc_model == 'bezier' else None
        step = phi[b] - prev[b] if has_prev[b] else lin[b] * 0.1
        starts = [phi[b]] + [phi[b] + k * step / max(np.abs(step.sum()), 1e-12) for k in (0.5, 1.0, 2.0, 3.0)]
        # then the last shape and the small-deflection shape turned to tip angles up to 2 pi
        for base in (phi[b], lin[b]):
            tb = base.sum()
            if abs(tb) > 1e-12:
                for t in (0.5, 1.0, 1.5, 2.0, -0.5, -1.0, -1.5, -2.0):
                    starts.append(base * (t * np.pi / tb))
        found = None
        for st in starts:
            p, c, it, r, fac = _newton(sub, st[None], 1.0, 40, step_limit=0.3, bezier=bez)
            total[b] += it[0]
            if not (c[0] and np.isfinite(r[0])):
                continue
            stable = N > DENSE_MAX_N or bool(_principal_ok(sub, fac)[0])
            if found is None or (stable and not found[2]):
                found = (p[0], r[0], stable)
            if stable:
                break
        if found is not None:
            phi[b], res[b] = found[0], found[1]
            conv[b] = True
            snapped[b] = s[b] > 0.0
        else:   # report the residual at the full load, not at the last load step
            loads, m = sub.loads(1.0)
            r_full, _, _ = _evaluate(phi[b:b + 1], sub.l, sub.w, loads, m, jac=False,
                                     clothoid=sub.clothoid)
            res[b] = float(np.max(np.abs(r_full)))
    return phi, conv, total, res, snapped


def _stability(prob: _Problem, phi):
    """False when the Newton Jacobian at the solution has an eigenvalue with Re <= 0 and some
    load compresses the catheter along its local tangent (buckling); (B,) bool.

    N > DENSE_MAX_N: judged on the N = 32 arc model with the same curvature (a dense
    eigenproblem of size N would be slow, and multithreaded LAPACK stalls a shared machine);
    buckling loads differ between the two discretisations by O(1/32^2) only."""
    B, N = phi.shape
    if N > DENSE_MAX_N:
        coarse = _coarse_problem(prob)
        sf, sc = _midpoints(prob), _midpoints(coarse)
        phic = np.stack([np.interp(sc, sf, phi[b] / prob.l) for b in range(B)]) * coarse.l
        return _stability(coarse, phic)
    loads, m = prob.loads(1.0)
    th_end = np.cumsum(phi, axis=1)
    compress = np.zeros(B, dtype=bool)
    for ld in loads:
        F = ld.F
        if ld.follower:
            compress |= F.real < 0
        else:
            t = np.exp(1j * (th_end[:, ld.a] - phi[:, ld.a] * (1 - ld.tau)))
            compress |= (np.conj(t) * F).real < 0
    stable = np.ones(B, dtype=bool)
    if not np.any(compress):
        return stable
    idx = np.nonzero(compress)[0]
    sub = _subproblem(prob, idx)
    sl, sm = sub.loads(1.0)
    _, fac, _ = _evaluate(phi[idx], sub.l, sub.w, sl, sm, jac=True, clothoid=sub.clothoid)
    stable[idx] = _principal_ok(sub, fac)
    return stable


# ---------------------------------------------------------------------------------------
# Graded arcs: per-case arc lengths that equidistribute the curvature change.
# ---------------------------------------------------------------------------------------
#: monitor exponent p and floor of the grading (see graded_fractions)
GRADE_POWER = 1.0
GRADE_FLOOR = 0.2


def graded_fractions(phi, tip_force, follower=False, point_forces=()):
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
    p = 1 (density ~ |kappa'|) measured better than p = 1/2 (the minimiser of
    sum l^3 |kappa'|): mean tip error over 300 random tip loads at N = 12 0.060 vs 0.066 % L
    (that run: floor 0.1 x rms|kappa'|). Shorter arcs where the curvature changes fastest:
    near the base for a lateral tip force, mid-length for a post-buckled compression.
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


def _remap(phi, frac_new, frac_old=None):
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


def _regrade(prob: _Problem, phi, arc_model):
    """Second pass of spacing='graded' for B cases solved on equal arcs (prob, phi (B, N)):
    graded arcs from the equal-arc solution, Newton from that solution mapped onto them.
    Returns phi (B, N), fractions (B, N), ok (B,) (converged, tip angle within 0.5 rad of the
    equal-arc one), iterations (B,), residual (B,)."""
    pfl = [(s, F) for s, (_, _, F) in zip(prob.pf_s, prob.point_forces)]
    frac = graded_fractions(phi, prob.tip_force, prob.follower, pfl)
    gprob = _make_problem(prob.n, prob.L, prob.EI, prob.tip_force, prob.follower,
                          prob.tip_moment, pfl, frac, prob.clothoid)
    start = _remap(phi, frac)
    bez = _BezierResidual(gprob) if arc_model == 'bezier' else None
    p, c, it, r, _ = _newton(gprob, start, 1.0, 12 if bez is None else 30, bezier=bez)
    ok = c & np.all(np.isfinite(p), axis=1) & (np.abs(p.sum(axis=1) - phi.sum(axis=1)) < 0.5)
    return p, frac, ok, it, r


def _problem_rates(prob: _Problem, phi, frac=None):
    """Clothoid rates (B, N) of the solution phi (B, N) of ``prob`` (on arcs ``frac`` (B, N)
    of L when given: a graded solution), or None for circular arcs."""
    if not prob.clothoid:
        return None
    if frac is not None:
        prob = _make_problem(prob.n, prob.L, prob.EI, prob.tip_force, prob.follower,
                             prob.tip_moment,
                             [(s, F) for s, (_, _, F) in zip(prob.pf_s, prob.point_forces)],
                             frac, True)
    loads, _ = prob.loads(1.0)
    th_end = np.cumsum(phi, axis=1)
    lE = prob.l * np.exp(1j * (th_end - phi))
    return _rates(phi, lE, g_only(phi), th_end, prob.w, loads)


def _check_common(cat, n_arcs, arc_model, spacing='uniform'):
    if not isinstance(cat, Catheter):
        raise ValueError(f'cat must be a Catheter, got {type(cat).__name__}')
    if isinstance(n_arcs, bool) or not isinstance(n_arcs, (int, np.integer)):
        raise ValueError(f'n_arcs must be an integer, got {n_arcs!r}')
    if not 1 <= int(n_arcs) <= MAX_N:
        raise ValueError(f'n_arcs must be in [1, {MAX_N}], got {n_arcs}')
    if arc_model not in ARC_MODELS:
        raise ValueError(f'arc_model must be one of {ARC_MODELS}, got {arc_model!r}')
    if not (isinstance(spacing, str) and spacing in SPACINGS):
        raise ValueError(f'spacing must be one of {SPACINGS}, got {spacing!r}')


def solve_fam(cat: Catheter, loads: Loads, n_arcs: int = 12, arc_model: str = DEFAULT_ARC_MODEL,
              initial=None, spacing: str = DEFAULT_SPACING) -> Shape:
    """Solve the FAM for one load case; returns a Shape (see ``model.Shape``).

    cat: Catheter (m, N m^2). loads: Loads (N, N m; base frame, or tip frame if follower).
    n_arcs: number of arcs N (1..100000). arc_model: 'clothoid' (default: arcs whose
    curvature changes linearly, fourth order), 'exact' (true circular arcs, the FAM of the
    thesis with exact arcs) or 'bezier' (the thesis' Bezier arcs, Eqs. 7-12). spacing:
    'uniform' (default, N equal arcs) or 'graded' (per-case arc lengths from the curvature
    change of the equal-arc solution, ~2x more accurate for circular arcs);
    ``shape.arc_lengths`` (N,) m gives the arcs.
    Never returns NaN: a case that does not converge has converged=False and the best
    finite iterate.
    initial: optional warm start (a previous Shape, or arc angles (N,) of EQUAL arcs); used
    (exact or clothoid model, tip loads, N <= 64) when Newton from it converges to an equilibrium whose
    Jacobian eigenvalues all have positive real parts, else ignored (cold start).
    """
    _check_common(cat, n_arcs, arc_model, spacing)
    if not isinstance(loads, Loads):
        raise ValueError(f'loads must be a Loads, got {type(loads).__name__}')
    n = int(n_arcs)
    tip = complex(*loads.tip_force)
    pfs = []
    for s, fx, fy in loads.point_forces:
        if s >= 1.0 and not loads.follower:
            tip += complex(fx, fy)
        else:
            pfs.append((s, np.array([complex(fx, fy)])))
    if initial is not None:
        init_frac = getattr(initial, 'arc_lengths', None)
        init_len = getattr(initial, 'length', None)
        initial = np.asarray(getattr(initial, 'arc_angles', initial), dtype=float)
        if initial.shape != (n,) or not np.all(np.isfinite(initial)):
            raise ValueError(f'initial must be finite arc angles of shape ({n},)')
        if init_frac is not None and init_len and np.ptp(init_frac) > 0:
            # a graded Shape: the same tangent-angle curve on equal arcs (the first pass)
            initial = _remap(initial[None], np.full((1, n), 1.0 / n),
                             (np.asarray(init_frac) / init_len)[None])[0]
    clothoid = arc_model == 'clothoid'
    if arc_model != 'bezier' and not pfs and n <= DENSE_MAX_N:
        out = _fast_solve(n, cat.length, cat.ei, tip, loads.tip_moment, loads.follower, initial,
                          spacing, clothoid)
        if out is None and initial is not None:
            out = _fast_solve(n, cat.length, cat.ei, tip, loads.tip_moment, loads.follower,
                              spacing=spacing, clothoid=clothoid)
        if out is not None:
            phi, conv, it, res, tipc, stable, frac, rho = out
            return arc_shape(cat.length, phi, tip=tipc, tip_angle=float(phi.sum()),
                             converged=True, iterations=it, stable=stable, warning='',
                             residual=res, arc_model=arc_model, spacing=spacing, fractions=frac,
                             rates=rho, _trusted=True)
    prob = _build_problem(cat, n, np.array([tip]), loads.follower,
                          np.array([loads.tip_moment]), pfs, clothoid=clothoid)
    phi, conv, iters, res, snapped = _solve(prob, 1, arc_model)
    stable = _stability(prob, phi)
    frac = None
    if spacing == 'graded' and conv[0] and n > 1 and not loads.follower:
        pg, fg, okg, itg, rg = _regrade(prob, phi, arc_model)
        iters = iters + itg
        if okg[0]:
            phi, res, frac = pg, rg, fg[0]
    warning = ''
    if not conv[0]:
        warning = f'not converged: max residual {res[0]:.3g} rad'
    elif snapped[0]:
        warning = ('snap-through: the loading path from zero has a fold; returned the '
                   'equilibrium found beyond it')
    if not stable[0]:
        warning = (warning + '; ' if warning else '') + \
            'unstable equilibrium (compressed past buckling; loading from zero kept this shape)'
    rho = _problem_rates(prob, phi, None if frac is None else frac[None])
    return arc_shape(cat.length, phi[0], converged=bool(conv[0]), iterations=int(iters[0]),
                     stable=bool(stable[0]), warning=warning, residual=float(res[0]),
                     arc_model=arc_model, spacing=spacing, fractions=frac,
                     rates=None if rho is None else rho[0])


def solve_fam_batch(cat: Catheter, tip_forces, tip_moments=None, n_arcs: int = 12,
                    follower: bool = False, arc_model: str = DEFAULT_ARC_MODEL,
                    chunk: int = 4096, spacing: str = DEFAULT_SPACING) -> BatchShape:
    """Solve B tip-load cases at once (vectorised Newton over the batch).

    tip_forces: (B, 2) N (base frame, or tip frame if ``follower``); tip_moments: (B,) N m
    or None (zeros). arc_model and spacing as in ``solve_fam`` (graded: each case gets its
    own arcs; the results equal solve_fam's to ~1e-13 m). Returns a BatchShape:
    tips (B, 2), tip_angles (B,), arc_angles (B, N), arc_lengths (B, N), converged (B,),
    stable (B,), iterations (B,), centerlines(k) -> (B, k, 2).
    """
    _check_common(cat, n_arcs, arc_model, spacing)
    tf = np.asarray(tip_forces, dtype=float)
    if tf.ndim != 2 or tf.shape[1] != 2:
        raise ValueError(f'tip_forces must have shape (B, 2), got {tf.shape}')
    if not np.all(np.isfinite(tf)):
        raise ValueError('tip_forces must be finite')
    B = tf.shape[0]
    if tip_moments is None:
        tm = np.zeros(B)
    else:
        tm = np.asarray(tip_moments, dtype=float)
        if tm.shape != (B,):
            raise ValueError(f'tip_moments must have shape ({B},), got {tm.shape}')
        if not np.all(np.isfinite(tm)):
            raise ValueError('tip_moments must be finite')
    if not isinstance(follower, (bool, np.bool_)):
        raise ValueError(f'follower must be a bool, got {follower!r}')
    n = int(n_arcs)
    phi = np.zeros((B, n))
    conv = np.zeros(B, dtype=bool)
    iters = np.zeros(B, dtype=int)
    res = np.zeros(B)
    stable = np.ones(B, dtype=bool)
    frac = np.full((B, n), 1.0 / n)
    clothoid = arc_model == 'clothoid'
    rates = np.zeros((B, n)) if clothoid else None
    F = tf[:, 0] + 1j * tf[:, 1]
    for lo in range(0, B, chunk):
        hi = min(B, lo + chunk)
        prob = _build_problem(cat, n, F[lo:hi], bool(follower), tm[lo:hi], [],
                              clothoid=clothoid)
        p, c, it, r, _ = _solve(prob, hi - lo, arc_model)
        stable[lo:hi] = _stability(prob, p)
        if spacing == 'graded' and np.any(c) and n > 1 and not follower:
            idx = np.nonzero(c)[0]
            pg, fg, okg, itg, rg = _regrade(_subproblem(prob, idx), p[idx], arc_model)
            it[idx] += itg
            take = idx[okg]
            p[take], r[take] = pg[okg], rg[okg]
            frac[lo + take] = fg[okg]
        phi[lo:hi], conv[lo:hi], iters[lo:hi], res[lo:hi] = p, c, it, r
        if clothoid:
            rates[lo:hi] = _problem_rates(prob, p, frac[lo:hi] if spacing == 'graded' else None)
    return BatchShape(cat.length, phi, conv, iters, stable, res, arc_model, spacing=spacing,
                      fractions=frac, rates=rates)


# ---------------------------------------------------------------------------------------
# Fast path: one case, tip force and moment only, exact arcs, N <= DENSE_MAX_N.
# Same equations as _evaluate/_dense_jacobian, written with 1-D arrays and as few numpy
# calls as possible (numpy call overhead dominates at N = 12).
# ---------------------------------------------------------------------------------------
from .arcs import _CCOEF, _CCOEF8, _K, SERIES_LIMIT  # noqa: E402

_FAST_CACHE = {}


def _fast_consts(n):
    c = _FAST_CACHE.get(n)
    if c is None:
        idx = np.arange(n)
        lower = idx[:, None] > idx[None, :]
        c = (lower, np.eye(n), np.diag_indices(n))
        _FAST_CACHE[n] = c
    return c


def _fast_tip_newton(n, l, w, F, m, follower, phi, max_iter, step_limit=0.3, rtol=1e-12,
                     clothoid=False):
    """Damped Newton for one tip-loaded case. F complex (base or tip frame), m float.
    Stops at max|r| <= 1e-13 + rtol max|phi| (converged is judged with rtol = 1e-12).
    clothoid: clothoid arcs (as in _evaluate; the Jacobian has the rates' derivatives once
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
            th_r = np.tanh(w_r * z0.imag)     # _rates: w (chord x -F), saturated
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
            # with the rates' own derivatives (see _clothoid_terms): quadratic convergence
            rho_ = RHO_MAX * th_r
            Yr = Y.real
            lo_, dg_, up_, row_ = _clothoid_terms(z0.real, Y[:, 0].imag, Yr[:, 2], Yr[:, 3],
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


def _clothoid_terms(sg, tg, a, b, w, th_r, follower, ap, bp):
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
    row) terms of -dMbar/dphi (the sign of ``D`` in _fast_tip_newton before the w scaling);
    the unused ones are None.

    With X_i = (P_N - P_i) + lever_i, Mbar_i = m - Im(X_i cF), the offsets i rho_j l e^{i theta_j} k_j
    in P and i rho_i l e^{i theta_i} (k_i - km_i) in lever_i: d rho_j / d phi_l is
    sigma_j = w'_j sg_j for l < j (base-fixed forces), tau_j = w'_j tg_j for l = j, 0 for
    l > j (w' = w (1 - tanh^2)); a follower force turns with the tip: 0, tau_j - sigma_j,
    -sigma_j. Im(i x) = Re(x) makes every term real.
    """
    ws = w * (1.0 - th_r * th_r)
    sig = ws * sg
    tau = ws * tg
    u = a * sig
    cs = np.cumsum(u, axis=-1)
    if not follower:
        S = cs[..., -1:] - cs         # sum over j > i
        return S + b * sig, S + b * tau + bp, S + a * tau + ap, None
    return None, b * (tau - sig) + bp, a * (tau - sig) - (cs - u) + ap, cs - b * sig


#: fast path, clothoid arcs: the rates' Jacobian terms are added once max|r| < this (rad);
#: further out the circular-arc factors do as well and cost less
_QUASI_ABOVE = 1e-2


def _fast_solve(n, L, EI, F, m, follower, initial=None, spacing='uniform', clothoid=False):
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
    phi, conv, it, res, tip, J, rho = _fast_tip_newton(n, l, w, F, m, follower, phi0, mi,
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
        phi, conv, it2, res, tip, J, rho = _fast_tip_newton(n, l, w, F, m, follower, phi, mi,
                                                            clothoid=cl)
        it += it2
        if not conv:
            return None
    if graded and np.any(phi):
        # second pass on graded arcs from this equal-arc solution (see graded_fractions);
        # the branch check below then uses the graded Jacobian
        f, start = _fast_grade(phi, F, follower)
        lg = L * f
        p2, c2, it2, r2, tip2, J2, rho2 = _fast_tip_newton(n, lg, lg / EI, F, m, follower, start,
                                                           mi, clothoid=cl)
        it += it2
        if c2 and abs(float(p2.sum()) - th) < 0.5 and \
                math.isfinite(tip2.real) and math.isfinite(tip2.imag):
            phi, res, tip, frac, rho = p2, r2, tip2, f, rho2
            J = J2 if J2 is not None else J
        else:   # keep the equal arcs: finish their solution to the full tolerance
            phi, conv, it2, res, tip, J1, rho = _fast_tip_newton(n, l, w, F, m, follower, phi, mi,
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


_U_CACHE = {}
_EQUAL_CACHE = {}


def _fast_grade(phi, F, follower):
    """graded_fractions and _remap for one case with 1-D arrays (few numpy calls):
    fractions (N,) and the start angles (N,) on those arcs."""
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
    Th = np.empty(n + 1)
    Th[0] = 0.0
    Th[1:] = th_end
    return np.diff(b), np.diff(np.interp(b, u, Th))


from scipy.linalg.lapack import dgesv as _dgesv, dgeev as _dgeev  # noqa: E402

_MAXR = np.maximum.reduce
_MINR = np.minimum.reduce

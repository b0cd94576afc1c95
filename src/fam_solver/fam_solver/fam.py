"""The Finite Arc Method (thesis Chapter 3, Eqs. 7-28), solved by Newton on all arc angles.

Model
-----
The catheter (length L, rigidity EI) is cut into N equal arcs of length l = L/N; arc i turns
by phi_i (constant curvature phi_i / l). Headings and positions are rebuilt base -> tip
(Eq. 28): theta_i = phi_1 + ... + phi_i, P_i = P_{i-1} + l e^{i theta_{i-1}} g(phi_i)
(complex notation, see ``arcs``). The internal moment at a point p(s) is (Eq. 16)

    M(s) = m_tip + sum over loads k distal to s of (p_k - p(s)) x F_k,

which is exactly what carrying the loads tip -> base by rotation and translation (Eqs. 24-27)
produces. Each arc's angle minimises the moment-balance functional Eq. 19 over that arc:

* ``arc_model="exact"``: a true circular arc, EI kappa = EI phi_i / l constant, so the
  minimiser of  integral over the arc of (M(s) - EI phi_i / l)^2 ds  is
  ``phi_i = (l / EI) * mean over the arc of M(s)``; the mean of p(s) over an arc is closed
  form (``arcs.h``), also for a point load inside an arc (``tau^2 q(phi tau)``).
* ``arc_model="bezier"`` (the thesis): each arc is the cubic Bezier of Eqs. 7-9 with
  lambda = (4/3) tan(phi/4)/phi (``arcs.bezier_lambda``), the curvature is Eq. 12, and
  phi_i solves d Pi_i / d phi_i = 0 (Eq. 23) with the arc's END wrench held fixed in the
  arc's own frame (the thesis' sequential tip -> base algorithm), Pi_i evaluated with
  8-point Gauss-Legendre quadrature in the Bezier parameter. See ``bezier``.

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

Globalisation: Newton from the straight shape with the full load, the step limited to
0.6 rad per arc; if that does not converge quickly or the sign of det(J) flips (a
bifurcation or fold was crossed, i.e. possibly another equilibrium branch), the load is
applied by continuation from zero (adaptive steps, secant predictor), which is how the
reference solver is loaded too. Tolerance: max |r_i| <= 1e-13 + 1e-12 max|phi|.

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
from typing import List, Optional, Sequence, Tuple

import numpy as np

from .arcs import arc_funcs
from .model import BatchShape, Catheter, Loads, Shape, arc_shape

ARC_MODELS = ('exact', 'bezier')
#: The default arc model (chosen from the benchmark: see the package README).
DEFAULT_ARC_MODEL = 'exact'
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


def _evaluate(phi, l, w, loads: Sequence[_Load], m, jac=True):
    """Residual r (B, N) of the exact arc model and the Jacobian factors.

    Returns r, (A, Bd, C, e), th_end where dMbar_i/dphi_j = A_i (j < i), Bd_i (j = i),
    C_j + e_i (j > i); Im(conj(X) F) is written -Im(X conj(F)) (fewer numpy calls).
    """
    B, N = phi.shape
    th_end = np.cumsum(phi, axis=1)
    lE = l * np.exp(1j * (th_end - phi))
    G, Q, GP, QP = arc_funcs(phi)
    d = lE * G
    P_end = np.cumsum(d, axis=1)
    lEq = lE * Q
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
    if jac:
        return r, (A, Bd, C, e), th_end
    return r, None, th_end


def _dense_jacobian(w, fac):
    A, Bd, C, e = fac
    B, N = A.shape
    lower, diag, eye = _masks(N)
    D = np.where(lower, A[:, :, None], C[:, None, :] + e[:, :, None])
    D[:, diag] = Bd
    J = eye - w * D
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
    for i in range(N):
        wi = w
        gam = 1.0 - wi * Bd[:, i] + wi * C[:, i] + wi * e[:, i]
        R[:, 0] = rhs[:, i]
        xi = (R + wi * A[:, i, None] * P + wi * U + wi * e[:, i, None] * S) / gam[:, None]
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


def _sign_det(w, fac, J):
    if J is None:
        J = _dense_jacobian(w, fac) if fac[0].shape[1] <= 400 else None
    if J is None:
        return None
    sign, _ = np.linalg.slogdet(J)
    return sign


class _Problem:
    """Loads scaled by a continuation factor; builds _Load lists for a given scale."""

    def __init__(self, n, l, w, tip_force, follower, tip_moment, point_forces):
        self.n, self.l, self.w = n, l, w
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


def _make_problem(n, L, EI, tip_force, follower, tip_moment, point_forces):
    """Core problem of n equal arcs; point_forces: list of (s fraction, complex (B,))."""
    l = L / n
    w = l / EI
    pfs = []
    for s, F in point_forces:
        x = s * n
        a = min(max(int(math.ceil(x - 1e-9)) - 1, 0), n - 1)
        tau = min(max(x - a, 0.0), 1.0)
        if tau >= 1.0 - 1e-9:
            tau = 1.0
        pfs.append((a, tau, F))
    return _Problem(n, l, w, tip_force, follower, tip_moment, pfs)


def _build_problem(cat: Catheter, n: int, tip_force, follower, tip_moment, point_forces):
    return _make_problem(n, cat.length, cat.ei, tip_force, follower, tip_moment, point_forces)


def _tol(phi):
    return 1e-13 + 1e-12 * np.max(np.abs(phi), axis=1)


def _alpha(prob: _Problem, cat_len_over_ei_l2=None):
    """Dimensionless load size per case: sum |F| L^2/EI + |m| L/EI, (B,)."""
    L = prob.l * prob.n
    EI = prob.l / prob.w
    f = np.abs(prob.tip_force)
    for _, _, F in prob.point_forces:
        f = f + np.abs(F)
    return f * L * L / EI + np.abs(prob.tip_moment) * L / EI


def _repeat(prob: _Problem, k):
    rep = lambda x: np.repeat(x, k)  # noqa: E731
    return _Problem(prob.n, prob.l, prob.w, rep(prob.tip_force), prob.follower,
                    rep(prob.tip_moment), [(a, t, rep(F)) for a, t, F in prob.point_forces])


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
            self._rep = (B, rp, BezierModel_for(rp))
        _, rp, model = self._rep
        h = 1e-7 * np.maximum(1.0, np.abs(phi))
        P = np.repeat(phi, N + 1, axis=0).reshape(B, N + 1, N)
        idx = np.arange(N)
        P[:, idx + 1, idx] += h
        loads, m = rp.loads(scale)
        R = model.residual(P.reshape(B * (N + 1), N), loads, m).reshape(B, N + 1, N)
        return np.transpose((R[:, 1:, :] - R[:, :1, :]) / h[:, :, None], (0, 2, 1))


def BezierModel_for(prob):
    from .bezier import BezierModel
    return BezierModel(prob)


def _newton(prob: _Problem, phi, scale, max_iter, step_limit=0.6, bezier=None):
    """Damped Newton at a fixed load scale.

    Returns phi (best iterate), converged (B,), iterations, max|r| (B,), Jacobian factors
    of the exact model at the returned phi (for the branch check).
    """
    loads, m = prob.loads(scale)
    B, N = phi.shape
    best = phi.copy()
    best_res = np.full(B, np.inf)
    it = 0
    fac = fac_best = None
    for it in range(max_iter + 1):
        r, fac, _ = _evaluate(phi, prob.l, prob.w, loads, m, jac=True)
        if bezier is not None:
            r = bezier.residual(phi, loads, m)
        res = np.max(np.abs(r), axis=1)
        res = np.where(np.isfinite(res), res, np.inf)
        improve = res < best_res
        if np.all(improve):
            best, best_res, fac_best = phi, res, fac
        else:
            best = np.where(improve[:, None], phi, best)
            best_res = np.where(improve, res, best_res)
            fac_best = tuple(np.where(improve[:, None], x, y) for x, y in zip(fac, fac_best))
        conv = res <= _tol(phi)
        if np.all(conv) or it == max_iter:
            break
        Jb = bezier.jacobian(phi, scale) if bezier is not None else None
        if Jb is not None:
            try:
                dx = np.linalg.solve(Jb, -r[:, :, None])[:, :, 0]
            except np.linalg.LinAlgError:
                dx, _ = _newton_step(prob.w, fac, r)
        else:
            dx, _ = _newton_step(prob.w, fac, r)
        dx = np.where(np.isfinite(dx), dx, 0.0)
        mx = np.max(np.abs(dx), axis=1)
        dx *= np.where(mx > step_limit, step_limit / np.maximum(mx, 1e-300), 1.0)[:, None]
        dx[conv] = 0.0
        phi = phi + dx
    conv = best_res <= _tol(best)
    return best, conv, it, best_res, fac_best


def _principal_ok(prob: _Problem, fac):
    """Branch check for a directly solved case: every eigenvalue of the Newton Jacobian has a
    positive real part (J = I at zero load; reaching another branch means an eigenvalue
    crossed zero). (B,) bool; N <= DENSE_MAX_N only."""
    J = _dense_jacobian(prob.w, fac)
    ev = np.linalg.eigvals(J)
    return np.min(ev.real, axis=1) > 1e-9


COARSE_N = 32


def _solve(prob: _Problem, B, arc_model='exact'):
    """Globalised solve for B cases.

    1. zero load -> exactly straight;
    2. N <= 64: damped Newton from the straight shape with the full load; accepted when it
       converges and (load parameter <= 2, or the branch check passes);
       N > 64: Newton from the coarse (N = 32) solution interpolated onto the arcs;
    3. otherwise load continuation from zero (per case).
    """
    N = prob.n
    bez = _BezierResidual(prob) if arc_model == 'bezier' else None
    alpha = _alpha(prob)
    zero = alpha == 0
    iters = np.zeros(B, dtype=int)
    if N <= DENSE_MAX_N:
        phi0 = np.zeros((B, N))
    else:
        L = prob.l * N
        coarse = _make_problem(COARSE_N, L, prob.l / prob.w, prob.tip_force, prob.follower,
                               prob.tip_moment, [((a + t) / N, F) for a, t, F in prob.point_forces])
        pc, cc, ic, _ = _solve(coarse, B, 'exact')
        iters += ic
        # curvature at the coarse midpoints -> fine arcs (piecewise linear), phi = kappa l
        sc = (np.arange(COARSE_N) + 0.5) / COARSE_N
        sf = (np.arange(N) + 0.5) / N
        phi0 = np.stack([np.interp(sf, sc, pc[b]) for b in range(B)]) * (COARSE_N / N)
    maxit = 10 if bez is None else 30
    phi, conv, it, res, fac = _newton(prob, phi0, 1.0, maxit, bezier=bez)
    iters += it
    ok = conv & ~zero
    check = ok & (alpha > 2.0)
    if np.any(check) and N <= DENSE_MAX_N:
        idx = np.nonzero(check)[0]
        good = _principal_ok(prob, tuple(x[idx] for x in fac))
        ok[idx[~good]] = False
    phi[zero] = 0.0
    res[zero] = 0.0
    conv |= zero
    ok |= zero
    if not np.all(ok):
        idx = np.nonzero(~ok)[0]
        sub = _subproblem(prob, idx)
        p2, c2, it2, r2 = _continuation(sub, len(idx), arc_model)
        # keep the continuation result unless it failed and the direct one converged
        take = c2 | ~conv[idx]
        phi[idx[take]] = p2[take]
        conv[idx[take]] = c2[take]
        res[idx[take]] = r2[take]
        iters[idx] += it2
    return phi, conv, iters, res


def _subproblem(prob: _Problem, idx):
    return _Problem(prob.n, prob.l, prob.w, prob.tip_force[idx], prob.follower,
                    prob.tip_moment[idx], [(a, t, F[idx]) for a, t, F in prob.point_forces])


MAX_CONTINUATION_ITERS = 600


def _continuation(prob: _Problem, B, arc_model):
    """Load each case from zero in adaptive steps (secant predictor, at most 0.8 rad change
    of the tip angle per step, at most MAX_CONTINUATION_ITERS Newton iterations)."""
    N = prob.n
    out = np.zeros((B, N))
    conv = np.zeros(B, dtype=bool)
    iters = np.zeros(B, dtype=int)
    res_out = np.zeros(B)
    for b in range(B):
        sub = _subproblem(prob, np.array([b]))
        bez = _BezierResidual(sub) if arc_model == 'bezier' else None
        # first step: the linear (small deflection) tip angle at full load sets its size
        loads, m = sub.loads(1.0)
        r0, fac0, _ = _evaluate(np.zeros((1, N)), sub.l, sub.w, loads, m)
        lin, _ = _newton_step(sub.w, fac0, r0)
        th_lin = float(np.max(np.abs(np.cumsum(lin[0]))))
        s, ds = 0.0, min(0.25, 0.3 / max(th_lin, 1e-12))
        phi = np.zeros((1, N))
        prev, prev_s = None, 0.0
        total = 0
        res = np.array([0.0])
        unstable = False
        while s < 1.0 and ds >= 1e-5 and total < MAX_CONTINUATION_ITERS:
            s_new = min(1.0, s + ds)
            if prev is not None:
                guess = phi + (phi - prev) * ((s_new - s) / (s - prev_s))
            else:
                guess = lin * s_new
            p, c, it, r, fac = _newton(sub, guess, s_new, 8 if bez is None else 20, bezier=bez)
            total += it
            okstep = bool(c[0]) and (abs(float(np.sum(p - phi))) <= 0.5 or ds < 1e-3)
            if okstep and N <= DENSE_MAX_N and not unstable:
                if not _principal_ok(sub, fac)[0]:
                    if ds < 1e-3:
                        unstable = True       # crossed a critical load: keep following
                    else:
                        okstep = False
            if okstep:
                prev, prev_s = phi, s
                phi, s, res = p, s_new, r
                ds = min(ds * 2.0, 0.5)
            else:
                ds *= 0.5
        ok = s >= 1.0
        if not ok:
            p, c, it, r, _ = _newton(sub, phi, 1.0, 30, bezier=bez)
            total += it
            if np.isfinite(r[0]):
                phi, res, ok = p, r, bool(c[0])
        out[b] = phi[0]
        conv[b] = ok
        iters[b] = total
        res_out[b] = res[0]
    return out, conv, iters, res_out


def _stability(prob: _Problem, phi):
    """False when the Newton Jacobian at the solution has an eigenvalue with Re <= 0 and some
    load compresses the catheter along its local tangent (buckling); (B,) bool."""
    B, N = phi.shape
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
    if not np.any(compress) or N > 400:
        return stable
    idx = np.nonzero(compress)[0]
    sub = _subproblem(prob, idx)
    sl, sm = sub.loads(1.0)
    _, fac, _ = _evaluate(phi[idx], sub.l, sub.w, sl, sm, jac=True)
    J = _dense_jacobian(sub.w, fac)
    ev = np.linalg.eigvals(J)
    stable[idx] = np.min(ev.real, axis=1) > 1e-9
    return stable


def _check_common(cat, n_arcs, arc_model):
    if not isinstance(cat, Catheter):
        raise ValueError(f'cat must be a Catheter, got {type(cat).__name__}')
    if isinstance(n_arcs, bool) or not isinstance(n_arcs, (int, np.integer)):
        raise ValueError(f'n_arcs must be an integer, got {n_arcs!r}')
    if not 1 <= int(n_arcs) <= MAX_N:
        raise ValueError(f'n_arcs must be in [1, {MAX_N}], got {n_arcs}')
    if arc_model not in ARC_MODELS:
        raise ValueError(f'arc_model must be one of {ARC_MODELS}, got {arc_model!r}')


def solve_fam(cat: Catheter, loads: Loads, n_arcs: int = 12, arc_model: str = DEFAULT_ARC_MODEL,
              max_iter: int = 60) -> Shape:
    """Solve the FAM for one load case; returns a Shape (see ``model.Shape``).

    cat: Catheter (m, N m^2). loads: Loads (N, N m; base frame, or tip frame if follower).
    n_arcs: number of equal arcs N (1..100000). arc_model: 'exact' (default, true circular
    arcs) or 'bezier' (the thesis' Bezier arcs, Eqs. 7-12). Never returns NaN: a case that
    does not converge has converged=False and the best finite iterate.
    """
    _check_common(cat, n_arcs, arc_model)
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
    prob = _build_problem(cat, n, np.array([tip]), loads.follower,
                          np.array([loads.tip_moment]), pfs)
    phi, conv, iters, res = _solve(prob, 1, arc_model)
    stable = _stability(prob, phi)
    warning = ''
    if not conv[0]:
        warning = f'not converged: max residual {res[0]:.3g} rad'
    if not stable[0]:
        warning = (warning + '; ' if warning else '') + \
            'unstable equilibrium (compressed past buckling; loading from zero kept this shape)'
    return arc_shape(cat.length, phi[0], converged=bool(conv[0]), iterations=int(iters[0]),
                     stable=bool(stable[0]), warning=warning, residual=float(res[0]),
                     arc_model=arc_model)


def solve_fam_batch(cat: Catheter, tip_forces, tip_moments=None, n_arcs: int = 12,
                    follower: bool = False, arc_model: str = DEFAULT_ARC_MODEL,
                    chunk: int = 4096) -> BatchShape:
    """Solve B tip-load cases at once (vectorised Newton over the batch).

    tip_forces: (B, 2) N (base frame, or tip frame if ``follower``); tip_moments: (B,) N m
    or None (zeros). Returns a BatchShape: tips (B, 2), tip_angles (B,), arc_angles (B, N),
    converged (B,), stable (B,), iterations (B,), centerlines(k) -> (B, k, 2).
    """
    _check_common(cat, n_arcs, arc_model)
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
    F = tf[:, 0] + 1j * tf[:, 1]
    for lo in range(0, B, chunk):
        hi = min(B, lo + chunk)
        prob = _build_problem(cat, n, F[lo:hi], bool(follower), tm[lo:hi], [])
        p, c, it, r = _solve(prob, hi - lo, arc_model)
        phi[lo:hi], conv[lo:hi], iters[lo:hi], res[lo:hi] = p, c, it, r
        stable[lo:hi] = _stability(prob, p)
    return BatchShape(cat.length, phi, conv, iters, stable, res, arc_model)

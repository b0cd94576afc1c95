"""Which equilibrium: damped Newton vectorised over cases, the direct attempt and its
acceptance, load continuation from zero, snap-through, and the stability (buckling) check.

Direct attempt: Newton starts from the small-deflection beam shape (the moments of the loads
on the straight catheter, without the geometric stiffness of axial loads) rescaled to a
plausible tip angle (towards the force for a dead tip force), steps limited per arc. The
result is accepted when it converged, turned the way the small-deflection beam turns, and
(large loads) every eigenvalue of the Jacobian has a positive real part -- J = I at zero
load, so the natural loading branch keeps them there until a critical point. N > DENSE_MAX_N
starts from the COARSE_N solution interpolated onto the arcs.

Otherwise the load is applied by continuation from zero (vectorised over cases, secant
predictor, bounded tip-angle change per step, the same eigenvalue check after every step).
Where the loading path has a fold (no nearby equilibrium beyond it: snap-through), the solver
looks for an equilibrium at the full load from the last shape and from shapes turned to tip
angles up to 2 pi, and prefers a stable one.

Buckling: a purely axial compression leaves the straight shape an equilibrium for every load
(the residual is exactly zero there), so loading from zero stays straight. Past the first
critical load that equilibrium is unstable: it is returned (converged) but flagged by
``stability`` (an eigenvalue of the Newton Jacobian with non-positive real part, checked
only when some load compresses the catheter along its tangent). No rclpy here.
"""
from __future__ import annotations

from typing import Optional, Tuple

import numpy as np

from .bezier import BezierResidual
from .equations import Factors, evaluate
from .linsolve import DENSE_MAX_N, newton_step, principal_ok
from .problem import (Problem, coarse_problem, load_size, midpoints, subproblem,
                      tolerance)

MAX_CONTINUATION_ITERS = 600


def case_w(prob: Problem, idx) -> np.ndarray:
    """w = l/EI of the cases ``idx``: (N,) for arcs common to all cases, else (len(idx), N)."""
    return prob.w if np.ndim(prob.w) == 1 else prob.w[idx]


def newton(prob: Problem, phi: np.ndarray, scale, max_iter: int, step_limit: float = 0.6,
           bezier: Optional[BezierResidual] = None
           ) -> Tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, Factors]:
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
    # Bezier arcs with loads at arc ends: the exact Bezier Jacobian (factors only where a step
    # is taken); the exact model's factors (branch check) once, at the returned phi
    analytic = bz is not None and all(t >= 1.0 for _, t, _ in prob.point_forces)
    for it in range(max_iter + 1):
        loads, m = sub.loads(sc)
        fac = state = None
        if analytic:
            r, state = bz.residual_state(ph, loads, m)
        else:
            r, fac, _ = evaluate(ph, sub.l, sub.w, loads, m, jac=True, clothoid=sub.clothoid)
            if bz is not None:
                r = bz.residual(ph, loads, m)
        res = np.max(np.abs(r), axis=1)
        res = np.where(np.isfinite(res), res, np.inf)
        improve = res < best_res[act]
        if np.any(improve):
            ii = act[improve]
            best[ii] = ph[improve]
            best_res[ii] = res[improve]
            if fac is not None:
                for fb, f in zip(fac_best, fac, strict=True):
                    fb[ii] = f[improve]
        conv = res <= tolerance(ph)
        if np.all(conv) or it == max_iter:
            break
        iters[act] += 1
        exact = bz.factors(state) if state is not None else None
        if state is not None and exact is None:     # degenerate: the circular-arc Jacobian
            _, fac, _ = evaluate(ph, sub.l, sub.w, loads, m, jac=True, clothoid=sub.clothoid)
        Jb = bz.jacobian(ph, sc) if bz is not None and not analytic else None
        if exact is not None:
            dx, _ = newton_step(exact[0], exact[1], r)
        elif Jb is not None:
            try:
                dx = np.linalg.solve(Jb, -r[:, :, None])[:, :, 0]
            except np.linalg.LinAlgError:
                dx, _ = newton_step(sub.w, fac, r)
        else:
            dx, _ = newton_step(sub.w, fac, r)
        dx = np.where(np.isfinite(dx), dx, 0.0)
        mx = np.max(np.abs(dx), axis=1)
        dx *= np.where(mx > step_limit, step_limit / np.maximum(mx, 1e-300), 1.0)[:, None]
        ph = ph + dx
        if np.any(conv):
            keep = ~conv
            act, ph, sc = act[keep], ph[keep], sc[keep]
            sub = subproblem(sub, keep)
            if bz is not None:
                bz = BezierResidual(sub)
    if analytic:
        loads, m = prob.loads(scale)
        fac_best = evaluate(best, prob.l, prob.w, loads, m, jac=True, clothoid=prob.clothoid)[1]
    conv = best_res <= tolerance(best)
    return best, conv, iters, best_res, fac_best


def linear_guess(prob: Problem) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Small-deflection beam solution phi_lin = (l/EI) Mbar(straight) (B, N) -- the moments
    of the loads on the UNDEFORMED catheter, without the geometric stiffness of axial loads
    (so its sign is the natural loading direction even past buckling) -- its tip angle
    theta_lin (B,), and a start for Newton: phi_lin rescaled to a plausible tip angle.

    For a dead tip force at angle beta (no moment, no point forces) the natural branch turns
    the tip towards the force, so the start uses theta = beta (1 - exp(-theta_lin / beta));
    otherwise |theta| <= 1.5 rad."""
    B, N = prob.tip_force.shape[0], prob.n
    loads, m = prob.loads(1.0)
    r0, _, _ = evaluate(np.zeros((B, N)), prob.l, prob.w, loads, m, jac=False)
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


def accept_direct(prob: Problem, phi: np.ndarray, conv: np.ndarray, th_lin: np.ndarray,
                  fac: Optional[Factors] = None) -> np.ndarray:
    """Direct-solve acceptance: converged, tip turned the way the linear beam turns (when that
    is clear), and the branch check (all Jacobian eigenvalues in the right half plane)."""
    th = phi.sum(axis=1)
    ok = conv & ((np.sign(th) == np.sign(th_lin)) | (np.abs(th_lin) < 0.1))
    big = ok & ((np.abs(th_lin) > 0.3) | (load_size(prob) > 2.0))
    if np.any(big) and prob.n <= DENSE_MAX_N:
        idx = np.nonzero(big)[0]
        if fac is None:
            sub = subproblem(prob, idx)
            loads, m = sub.loads(1.0)
            _, f, _ = evaluate(phi[idx], sub.l, sub.w, loads, m, clothoid=sub.clothoid)
        else:
            f = tuple(x[idx] for x in fac)
        good = principal_ok(case_w(prob, idx), f)
        ok[idx[~good]] = False
    return ok


def solve_cases(prob: Problem, B: int, arc_model: str = 'exact',
                start: Optional[np.ndarray] = None
                ) -> Tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Globalised solve for B cases.

    1. zero load -> exactly straight;
    2. N <= 64: damped Newton from the rescaled small-deflection solution, accepted by
       ``accept_direct``; N > 64: Newton from the coarse (N = 32) solution interpolated onto the
       arcs (that solution is accepted already); ``start`` (B, N), when given, replaces
       either start (the Bezier model starts from the accepted circular-arc solution);
    3. otherwise load continuation from zero (per case). A result that is exactly straight
       is kept (loading from zero keeps an axially loaded catheter straight).
    """
    N = prob.n
    bez = BezierResidual(prob) if arc_model == 'bezier' else None
    alpha = load_size(prob)
    zero = alpha == 0
    iters = np.zeros(B, dtype=int)
    snapped = np.zeros(B, dtype=bool)
    lin, th_lin, guess = linear_guess(prob)
    if start is not None:
        phi0 = start
    elif N <= DENSE_MAX_N:
        phi0 = guess
    else:
        coarse = coarse_problem(prob)
        pc, cc, ic, _, snapped_c = solve_cases(coarse, B, 'exact')
        iters += ic
        snapped |= snapped_c & cc      # the fine solution continues the coarse one's branch
        # curvature at the coarse midpoints -> fine arcs (piecewise linear), phi = kappa l
        sc, sf = midpoints(coarse), midpoints(prob)
        phi0 = np.stack([np.interp(sf, sc, pc[b] / coarse.l) for b in range(B)]) * prob.l
    phi, conv, it, res, fac = newton(prob, phi0, 1.0, 12 if bez is None else 30, bezier=bez)
    iters += it
    ok = accept_direct(prob, phi, conv, th_lin, fac) if N <= DENSE_MAX_N else conv.copy()
    straight = conv & ~np.any(phi != 0.0, axis=1)
    ok |= zero | straight
    phi[zero] = 0.0
    res[zero] = 0.0
    conv |= zero
    if not np.all(ok):
        idx = np.nonzero(~ok)[0]
        sub = subproblem(prob, idx)
        p2, c2, it2, r2, sn2 = continuation(sub, len(idx), arc_model, lin[idx])
        # keep the continuation result unless it failed and the direct one converged
        take = c2 | ~conv[idx]
        phi[idx[take]] = p2[take]
        conv[idx[take]] = c2[take]
        res[idx[take]] = r2[take]
        snapped[idx[take]] = sn2[take]
        iters[idx] += it2
    return phi, conv, iters, res, snapped


def continuation(prob: Problem, B: int, arc_model: str, lin: Optional[np.ndarray] = None
                 ) -> Tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Load every case from zero in adaptive steps, vectorised over the cases (each has its
    own load scale s and step ds): secant predictor (the small-deflection solution for the
    first step), at most 0.5 rad change of the tip angle per step, the branch check after
    each step (a critical point is crossed only with steps < 1e-3, then the case is marked
    unstable and followed), at most MAX_CONTINUATION_ITERS Newton iterations per case."""
    N = prob.n
    if lin is None:
        lin = linear_guess(prob)[0]
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
        sub = subproblem(prob, act)
        bez = BezierResidual(sub) if arc_model == 'bezier' else None
        s_new = np.minimum(1.0, s[act] + ds[act])
        hp = has_prev[act]
        denom = np.where(hp, s[act] - prev_s[act], 1.0)
        guess = np.where(hp[:, None],
                         phi[act] + (phi[act] - prev[act]) * ((s_new - s[act]) / denom)[:, None],
                         lin[act] * s_new[:, None])
        p, c, it, r, fac = newton(sub, guess, s_new, 8 if bez is None else 20, bezier=bez)
        total[act] += it
        small = ds[act] < 1e-3
        okstep = c & ((np.abs(np.sum(p - phi[act], axis=1)) <= 0.5) | small)
        chk = okstep & ~unstable[act]
        if N <= DENSE_MAX_N and np.any(chk):
            ci = np.nonzero(chk)[0]
            good = principal_ok(case_w(sub, ci), tuple(x[ci] for x in fac))
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
        sub = subproblem(prob, np.array([b]))
        bez = BezierResidual(sub) if arc_model == 'bezier' else None
        step = phi[b] - prev[b] if has_prev[b] else lin[b] * 0.1
        unit = step / max(np.abs(step.sum()), 1e-12)
        starts = [phi[b]] + [phi[b] + k * unit for k in (0.5, 1.0, 2.0, 3.0)]
        # then the last shape and the small-deflection shape turned to tip angles up to 2 pi
        for base in (phi[b], lin[b]):
            tb = base.sum()
            if abs(tb) > 1e-12:
                for t in (0.5, 1.0, 1.5, 2.0, -0.5, -1.0, -1.5, -2.0):
                    starts.append(base * (t * np.pi / tb))
        found = None
        for st in starts:
            p, c, it, r, fac = newton(sub, st[None], 1.0, 40, step_limit=0.3, bezier=bez)
            total[b] += it[0]
            if not (c[0] and np.isfinite(r[0])):
                continue
            stable = N > DENSE_MAX_N or bool(principal_ok(sub.w, fac)[0])
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
            r_full, _, _ = evaluate(phi[b:b + 1], sub.l, sub.w, loads, m, jac=False,
                                     clothoid=sub.clothoid)
            res[b] = float(np.max(np.abs(r_full)))
    return phi, conv, total, res, snapped


def stability(prob: Problem, phi: np.ndarray) -> np.ndarray:
    """False when the Newton Jacobian at the solution has an eigenvalue with Re <= 0 and some
    load compresses the catheter along its local tangent (buckling); (B,) bool.

    N > DENSE_MAX_N: judged on the N = 32 arc model with the same curvature (a dense
    eigenproblem of size N would be slow, and multithreaded LAPACK stalls a shared machine);
    buckling loads differ between the two discretisations by O(1/32^2) only."""
    B, N = phi.shape
    if N > DENSE_MAX_N:
        coarse = coarse_problem(prob)
        sf, sc = midpoints(prob), midpoints(coarse)
        phic = np.stack([np.interp(sc, sf, phi[b] / prob.l) for b in range(B)]) * coarse.l
        return stability(coarse, phic)
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
    sub = subproblem(prob, idx)
    sl, sm = sub.loads(1.0)
    _, fac, _ = evaluate(phi[idx], sub.l, sub.w, sl, sm, jac=True, clothoid=sub.clothoid)
    stable[idx] = principal_ok(sub.w, fac)
    return stable

"""Reference solution: the inextensible Kirchhoff (Euler elastica) rod, by shooting.

State along the arc length s in [0, L]: tangent angle theta, position (x, y), internal
moment M. With F_int(s) the sum of the forces distal to s (piecewise constant: point
forces make it jump),

    theta' = M / EI,   x' = cos theta,   y' = sin theta,   M' = -(x' F_int,y - y' F_int,x),

theta(0) = 0, x(0) = y(0) = 0, and at the tip M(L) = m_tip. Base-fixed loads: the only
shooting unknown is the base moment M(0). Follower tip force: the force is
e^{i theta(L)} F_tip, so theta(L) is a second unknown with the condition theta(L) = Theta.
Integration is base -> tip, segment by segment between point forces, with scipy
``solve_ivp`` (DOP853, rtol default 1e-12, atol 1e-14 L) and the variational equations
for the exact shooting Jacobian (Newton). Loads are applied by continuation from zero
(adaptive steps, secant predictor, branch checks): shooting from the small-deflection
guess lands on a looped equilibrium for F L^2/EI >= 14.

The result is a ``Shape`` (dense output: ``points_at``/``centerline`` interpolate the
DOP853 continuous extension); ``arc_angles`` are tangent-angle increments over 100 equal
pieces. No rclpy here.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp

from .model import Catheter, Loads, Shape


class _Rod:
    def __init__(self, cat: Catheter, loads: Loads, rtol: float, atol: float, method: str):
        self.cat, self.loads = cat, loads
        self.rtol, self.atol, self.method = rtol, atol, method
        L = cat.length
        # segment breakpoints (fractions) from point forces
        pts = sorted({s for s, _, _ in loads.point_forces if s < 1.0})
        self.breaks = [0.0] + pts + [1.0]
        self.pf = [(s, complex(fx, fy)) for s, fx, fy in loads.point_forces]
        self.tipF = complex(*loads.tip_force)
        self.L = L

    def _fixed_force(self, s_frac, scale):
        """Sum of base-fixed forces distal to fraction s (strictly beyond), complex."""
        F = 0j
        for s, f in self.pf:
            if s > s_frac + 1e-15:
                F += f
        if not self.loads.follower:
            F += self.tipF
        return F * scale

    def shoot(self, M0: float, Theta: float, scale: float, dense: bool = False) -> tuple:
        """Integrate; returns residual (1 or 2,), Jacobian, solutions."""
        EI = self.cat.ei
        follower = self.loads.follower
        Ff = self.tipF * scale * np.exp(1j * Theta) if follower else 0j
        dFf = 1j * Ff
        y0 = np.array([0.0, 0.0, 0.0, M0, 0.0, 1.0, 0.0, 0.0])
        sols = []
        for a, b in zip(self.breaks[:-1], self.breaks[1:], strict=True):
            F = self._fixed_force(a, scale) + Ff
            fx, fy = F.real, F.imag
            dfx, dfy = dFf.real, dFf.imag

            def rhs(s, y, fx=fx, fy=fy, dfx=dfx, dfy=dfy):
                th, _, _, M, tha, Ma, thb, Mb = y
                c, sn = math.cos(th), math.sin(th)
                k = sn * fy + c * fx
                return [M / EI, c, sn, -(c * fy - sn * fx),
                        Ma / EI, k * tha, Mb / EI, k * thb - (c * dfy - sn * dfx)]

            sol = solve_ivp(rhs, (a * self.L, b * self.L), y0, method=self.method,
                            rtol=self.rtol, atol=self.atol, dense_output=dense)
            if not sol.success:
                raise RuntimeError(sol.message)
            y0 = sol.y[:, -1].copy()
            sols.append(sol)
        th, x, y, M, tha, Ma, thb, Mb = y0
        mt = self.loads.tip_moment * scale
        if follower:
            r = np.array([M - mt, th - Theta])
            J = np.array([[Ma, Mb], [tha, thb - 1.0]])
        else:
            r = np.array([M - mt])
            J = np.array([[Ma]])
        return r, J, sols, y0


def solve_elastica(cat: Catheter, loads: Loads, rtol: float = 1e-12, atol: float = None,
                   method: str = 'DOP853', max_iter: int = 50) -> Shape:
    """Reference rod solution with the same Shape interface as ``solve_fam``.

    rtol/atol: solve_ivp tolerances (atol defaults to 0.01 rtol min(L, EI/L), applied to
    theta [rad], x, y [m] and M [N m]). Newton on the shooting unknowns to
    |M(L) - m_tip| <= max(1e-13, 10 rtol) EI/L (and |theta(L) - Theta| <= 1e-12 for follower
    forces). Continuation from zero in adaptive steps, each accepted only if the tip angle
    moved <= 0.4 rad and the sign of the shooting Jacobian's determinant is unchanged (the
    natural branch; a crossing is followed only with steps <= 1e-4, e.g. a straight rod past
    buckling). A loading path with a fold (snap-through) is not followed: converged=False.
    """
    if not isinstance(cat, Catheter):
        raise ValueError(f'cat must be a Catheter, got {type(cat).__name__}')
    if not isinstance(loads, Loads):
        raise ValueError(f'loads must be a Loads, got {type(loads).__name__}')
    if not (isinstance(rtol, float) and 0 < rtol < 1):
        raise ValueError(f'rtol must be a float in (0, 1), got {rtol!r}')
    L, EI = cat.length, cat.ei
    if atol is None:
        atol = rtol * 1e-2 * min(L, EI / L)
    rod = _Rod(cat, loads, rtol, atol, method)
    follower = loads.follower
    mscale = EI / L
    tol_m = max(1e-13, 10 * rtol) * mscale
    alpha = loads.load_parameter(cat)
    if alpha == 0.0:
        M0, Th = 0.0, 0.0
        total = 0
        conv = True
    else:
        M0, Th = 0.0, 0.0
        s = 0.0
        ds = min(1.0, 0.6 / alpha)
        prev = None
        th_tip = 0.0
        # sign of the shooting Jacobian's determinant along the path: it is that of the
        # unloaded rod on the stable natural branch; a change means a critical point was
        # crossed (bifurcation onto the complementary branch, or a fold)
        jsign = np.sign(np.linalg.det(rod.shoot(0.0, 0.0, 0.0)[1]))
        total = 0
        conv = True
        while s < 1.0:
            s_new = min(1.0, s + ds)
            if prev is not None:
                ps, pM, pT = prev
                fr = (s_new - s) / (s - ps)
                gM, gT = M0 + (M0 - pM) * fr, Th + (Th - pT) * fr
            else:
                gM, gT = M0, Th
            ok = False
            x = np.array([gM, gT]) if follower else np.array([gM])
            for it in range(max_iter):
                r, J, _, yend = rod.shoot(x[0], x[1] if follower else 0.0, s_new)
                total += 1
                err = abs(r[0]) <= tol_m and (not follower or abs(r[1]) <= 1e-12)
                if err:
                    ok = True
                    break
                try:
                    dx = np.linalg.solve(J, -r)
                except np.linalg.LinAlgError:
                    break
                # limit the step in base curvature / tip angle
                lim = np.array([2.0 * mscale, 1.0]) if follower else np.array([2.0 * mscale])
                f = np.max(np.abs(dx) / lim)
                if f > 1:
                    dx /= f
                x = x + dx
                if it >= 12 and ds > 1e-4:
                    break
            if ok and abs(yend[0] - th_tip) > 0.4:
                ok = False  # too large a jump of the tip angle: possibly another branch
            if ok and np.sign(np.linalg.det(J)) != jsign:
                if ds > 1e-4:
                    ok = False
                else:
                    # crossed with a tiny step: follow (e.g. straight past buckling)
                    jsign = -jsign
            if ok:
                th_tip = yend[0]
                prev = (s, M0, Th)
                M0 = x[0]
                Th = x[1] if follower else 0.0
                s = s_new
                ds = min(ds * 1.5, 0.25)
            else:
                ds *= 0.5
                if ds < 1e-7:
                    conv = False
                    break
    r, J, sols, yend = rod.shoot(M0, Th, 1.0, dense=True)
    conv = conv and abs(r[0]) <= tol_m * 10 and (not follower or abs(r[1]) <= 1e-10)
    bounds = [sol.t[-1] for sol in sols]

    def state(s):
        sv = np.asarray(s, dtype=float) * L
        out = np.empty((sv.size, 3))
        for k, val in enumerate(sv):
            j = 0
            while j < len(sols) - 1 and val > bounds[j]:
                j += 1
            out[k] = sols[j].sol(val)[:3]
        return out

    def points(s):
        st = state(s)
        return st[:, 1:3].copy()

    def angles(s):
        return state(s)[:, 0].copy()

    th100 = angles(np.linspace(0, 1, 101))
    return Shape(L, (yend[1], yend[2]), yend[0], np.diff(th100), conv, total,
                 points_fn=points, angles_fn=angles, residual=float(np.max(np.abs(r))),
                 arc_model='elastica', warning='' if conv else 'reference not converged')

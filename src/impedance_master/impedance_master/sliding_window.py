"""The thesis's identifier done well: least squares of ``f = m x'' + c x' + k x + offset``
(thesis Eqs. 29-34) over a sliding window, O(1) per sample.

Running sums of the normal equations (add the newest sample, remove the oldest; an exact
re-summation once per window removes round-off drift), columns scaled to unit diagonal,
a ridge toward the last good estimate (so weakly excited directions, typically the mass,
stay where they were and the solve is never singular), conditioning checked on the
Cholesky pivots, and "at rest" detection (no velocity excitation in the window: the last
good estimate is held and `status` says so). The same 2nd-order low-pass filter is applied
to x, x', x'' and f, so the linear relation between them is preserved (consistent
filtering) while sensor noise and differentiation noise are cut. Physically impossible
samples (`gating.SampleGate`: a force of 1e6 N, a velocity of 1e300) are refused and
counted (`gate.n_rejected`); otherwise the fit is the thesis's plain least squares (an
outlier that passes the gate weighs in until it leaves the window).
"""
from __future__ import annotations

import math
from typing import Optional

from catheter_common.checks import finite, positive
from impedance_master.filters import Biquad, Differentiator
from impedance_master.gating import SampleGate
from impedance_master.impedance import Impedance


class SlidingWindowIdentifier:
    """Thesis identification (Eq. 34) over a sliding window, O(1) per sample.

    Args:
        window: s, window length w (thesis: 1 s).
        rate: Hz, sample rate (thesis: 1 kHz); the window holds round(window * rate) samples.
        cutoff: Hz, cutoff of the common low-pass filter on x, x', x'', f (None or 0: none).
        ridge: relative ridge toward the last good estimate (in the unit-diagonal scaled
            problem); directions whose information is below it stay near the last estimate.
        min_velocity_rms: m/s, window RMS of x' below which the catheter counts as at rest
            (the estimate is held, status 'at_rest').
        max_condition: largest accepted condition estimate of the scaled normal matrix.
        offset: fit the constant term (True, default) or the thesis's pure (m, c, k) (False).
        mass_ridge: extra relative ridge pulling the mass toward 0 (the mass is barely
            identifiable at catheter accelerations; unpulled it absorbs friction reversals
            and renders kilograms at the master). 0: the plain thesis fit.
        stiffness_ridge: the same toward k = 0 (when the window spans a few mm, x and the
            offset are nearly collinear and k x + offset, evaluated at the master's position
            a delay away, extrapolates wildly). Both ridges act in the unit-diagonal scaled
            problem, so a well-excited parameter is biased by about ridge / (1 + ridge).
    Attributes after update: `status` ('filling', 'ok', 'at_rest', 'ill_conditioned'),
    `n_held` (solves replaced by the last good estimate), `condition` (last estimate).
    """

    def __init__(self, window: float = 1.0, rate: float = 1000.0, cutoff: Optional[float] = 20.0,
                 ridge: float = 1e-4, min_velocity_rms: float = 1e-3,
                 max_condition: float = 1e9, offset: bool = True, mass_ridge: float = 1.0,
                 stiffness_ridge: float = 0.01):
        self.window = positive('window', window)
        self.rate = positive('rate', rate)
        self.n = int(round(window * rate))
        if self.n < 8:
            raise ValueError(f'window * rate must give at least 8 samples, got {self.n}')
        if cutoff:
            cutoff = positive('cutoff', cutoff)
            if cutoff >= 0.5 * rate:
                raise ValueError(f'cutoff must be below rate / 2, got {cutoff!r}')
        self.cutoff = cutoff or None
        self.ridge = positive('ridge', ridge)
        self.min_velocity_rms = positive('min_velocity_rms', min_velocity_rms)
        self.max_condition = positive('max_condition', max_condition)
        self.use_offset = bool(offset)
        self.mass_ridge = finite('mass_ridge', mass_ridge)
        if self.mass_ridge < 0:
            raise ValueError(f'mass_ridge must be >= 0, got {mass_ridge!r}')
        self.stiffness_ridge = finite('stiffness_ridge', stiffness_ridge)
        if self.stiffness_ridge < 0:
            raise ValueError(f'stiffness_ridge must be >= 0, got {stiffness_ridge!r}')
        # column scales (fixed, physical): regressors [x''/A, x'/V, x/X, 1]
        self._scale = (1.0, 0.04, 0.05, 1.0)
        self.reset()

    def reset(self) -> None:
        """Forget every sample and the last estimate."""
        self.gate = SampleGate(rate=self.rate)
        self._filters = [Biquad(self.cutoff, self.rate) for _ in range(4)] if self.cutoff else None
        self._dv = Differentiator(self.rate)
        self._da = Differentiator(self.rate)
        self._buf = [None] * self.n
        self._i = 0
        self._count = 0
        self._since_resum = 0
        self._S = [0.0] * 14  # 10 entries of the symmetric 4x4 A, then 4 of b
        self.status = 'filling'
        self.condition = float('nan')
        self.n_held = 0
        self.last: Optional[Impedance] = None
        self._theta = None  # last good estimate (m, c, k, offset), unscaled

    # ------------------------------------------------------------------ sample input
    def _filtered(self, x, xd, xdd, f):
        x = finite('x', x)
        f = finite('f', f)
        if xd is None:
            xd = self._dv(x)
        else:
            xd = finite('xd', xd)
        if xdd is None:
            xdd = self._da(xd)
        else:
            xdd = finite('xdd', xdd)
        if self._filters is not None:
            fa, fv, fx, ff = self._filters
            return fa(xdd), fv(xd), fx(x), ff(f)
        return xdd, xd, x, f

    def update(self, x: float, xd: Optional[float], xdd: Optional[float], f: float
               ) -> Optional[Impedance]:
        """Add one sample (x m, x' m/s, x'' m/s^2, measured force f N); return the model.

        xd or xdd None: computed by backward differences at `rate` (then filtered).
        Returns None until the window has filled once, then an `Impedance` (linear kind)
        whose `valid` is False only while no good estimate exists yet.
        """
        x, f = finite('x', x), finite('f', f)
        xd = None if xd is None else finite('xd', xd)
        xdd = None if xdd is None else finite('xdd', xdd)
        if self.gate.check(x, 0.0 if xd is None else xd, xdd, f) is not None:
            return self.last if self._count >= self.n else None
        a, v, xx, ff = self._filtered(x, xd, xdd, f)
        s0, s1, s2, _ = self._scale
        p0, p1, p2 = a / s0, v / s1, xx / s2
        p3 = 1.0 if self.use_offset else 0.0
        new = (p0, p1, p2, p3, ff)
        S = self._S
        old = self._buf[self._i]
        self._buf[self._i] = new
        self._i = (self._i + 1) % self.n
        self._count += 1
        self._since_resum += 1
        if old is not None and self._since_resum >= self.n:
            self._resum()
        else:
            self._accumulate(S, new, 1.0)
            if old is not None:
                self._accumulate(S, old, -1.0)
        if self._count < self.n:
            return None
        return self._solve()

    @staticmethod
    def _accumulate(S, s, sign):
        p0, p1, p2, p3, f = s
        q0, q1, q2, q3 = sign * p0, sign * p1, sign * p2, sign * p3
        S[0] += q0 * p0
        S[1] += q0 * p1
        S[2] += q0 * p2
        S[3] += q0 * p3
        S[4] += q1 * p1
        S[5] += q1 * p2
        S[6] += q1 * p3
        S[7] += q2 * p2
        S[8] += q2 * p3
        S[9] += q3 * p3
        S[10] += q0 * f
        S[11] += q1 * f
        S[12] += q2 * f
        S[13] += q3 * f

    def _resum(self):
        """Exact re-summation of the window (once per window: amortised O(1), no drift)."""
        S = [0.0] * 14
        for s in self._buf:
            if s is not None:
                self._accumulate(S, s, 1.0)
        self._S = S
        self._since_resum = 0

    # ------------------------------------------------------------------ solve
    def _hold(self, status: str) -> Impedance:
        self.status = status
        self.n_held += 1
        if self._theta is None:
            imp = Impedance(0.0, 0.0, 0.0, 0.0, valid=False, status=status)
        else:
            m, c, k, o = self._theta
            imp = Impedance(m, c, k, o, valid=True, status=status)
        self.last = imp
        return imp

    def _solve(self) -> Impedance:
        """Ridge-regularised, Jacobi-scaled Cholesky solve of the 4x4 normal equations,
        unrolled (pure Python, a few microseconds)."""
        S = self._S
        sx = self._scale
        # at rest: velocity column carries no information
        if S[4] / self.n * sx[1] * sx[1] < self.min_velocity_rms ** 2:
            return self._hold('at_rest')
        a00, a01, a02, a03, a11, a12, a13, a22, a23, a33 = S[:10]
        b0, b1, b2, b3 = S[10:14]
        if not self.use_offset:     # decouple the offset: unit row, zero right-hand side
            a03 = a13 = a23 = b3 = 0.0
            a33 = 1.0
        if a00 <= 0.0 or a11 <= 0.0 or a22 <= 0.0 or a33 <= 0.0:
            return self._hold('ill_conditioned')
        d0, d1, d2, d3 = math.sqrt(a00), math.sqrt(a11), math.sqrt(a22), math.sqrt(a33)
        mu = self.ridge
        th = self._theta
        if th is None:
            p0 = p1 = p2 = p3 = 0.0
        else:   # last good estimate in scaled coordinates
            p0, p1, p2, p3 = th[0] * sx[0] * d0, th[1] * sx[1] * d1, th[2] * sx[2] * d2, \
                th[3] * sx[3] * d3
        # unit-diagonal scaled matrix + ridge (and the pulls of m and k toward 0)
        r00 = 1.0 + mu + self.mass_ridge
        r11 = 1.0 + mu
        r22 = 1.0 + mu + self.stiffness_ridge
        r33 = 1.0 + mu
        r01, r02, r03 = a01 / (d0 * d1), a02 / (d0 * d2), a03 / (d0 * d3)
        r12, r13, r23 = a12 / (d1 * d2), a13 / (d1 * d3), a23 / (d2 * d3)
        y0, y1, y2, y3 = b0 / d0 + mu * p0, b1 / d1 + mu * p1, b2 / d2 + mu * p2, \
            b3 / d3 + mu * p3
        # Cholesky R = L L^T with pivot monitoring (pivots > 0 by the ridge in exact math)
        q0 = r00
        if q0 <= 0.0:
            return self._hold('ill_conditioned')
        l00 = math.sqrt(q0)
        l10, l20, l30 = r01 / l00, r02 / l00, r03 / l00
        q1 = r11 - l10 * l10
        if q1 <= 0.0:
            return self._hold('ill_conditioned')
        l11 = math.sqrt(q1)
        l21 = (r12 - l20 * l10) / l11
        l31 = (r13 - l30 * l10) / l11
        q2 = r22 - l20 * l20 - l21 * l21
        if q2 <= 0.0:
            return self._hold('ill_conditioned')
        l22 = math.sqrt(q2)
        l32 = (r23 - l30 * l20 - l31 * l21) / l22
        q3 = r33 - l30 * l30 - l31 * l31 - l32 * l32
        if q3 <= 0.0:
            return self._hold('ill_conditioned')
        l33 = math.sqrt(q3)
        self.condition = max(q0, q1, q2, q3) / min(q0, q1, q2, q3)
        if self.condition > self.max_condition:
            return self._hold('ill_conditioned')
        # forward and back substitution
        z0 = y0 / l00
        z1 = (y1 - l10 * z0) / l11
        z2 = (y2 - l20 * z0 - l21 * z1) / l22
        z3 = (y3 - l30 * z0 - l31 * z1 - l32 * z2) / l33
        t3 = z3 / l33
        t2 = (z2 - l32 * t3) / l22
        t1 = (z1 - l21 * t2 - l31 * t3) / l11
        t0 = (z0 - l10 * t1 - l20 * t2 - l30 * t3) / l00
        theta = (t0 / (d0 * sx[0]), t1 / (d1 * sx[1]), t2 / (d2 * sx[2]),
                 t3 / (d3 * sx[3]) if self.use_offset else 0.0)
        if not (math.isfinite(theta[0]) and math.isfinite(theta[1])
                and math.isfinite(theta[2]) and math.isfinite(theta[3])):
            return self._hold('ill_conditioned')
        self._theta = theta
        self.status = 'ok'
        imp = Impedance(theta[0], theta[1], theta[2], theta[3], valid=True, status='ok')
        self.last = imp
        return imp

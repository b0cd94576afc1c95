"""Slave-side identification of the catheter-vessel environment (thesis Eqs. 29-34 and beyond).

* `SlidingWindowIdentifier`: the thesis method done well. Least squares of
  ``f = m x'' + c x' + k x + offset`` over the last ``window`` seconds, O(1) per sample:
  running sums of the normal equations (add the newest sample, remove the oldest; an exact
  re-summation once per window removes round-off drift), columns scaled to unit diagonal,
  a ridge toward the last good estimate (so weakly excited directions, typically the mass,
  stay where they were and the solve is never singular), conditioning checked on the
  Cholesky pivots, and "at rest" detection (no velocity excitation in the window: the last
  good estimate is held and `status` says so). The same 2nd-order low-pass filter is applied
  to x, x', x'' and f, so the linear relation between them is preserved (consistent
  filtering) while sensor noise and differentiation noise are cut.
* `HistoryIdentifier` (what `make_identifier` returns, the project's default): a nonlinear
  environment model learned from the WHOLE history (exponentially weighted least squares
  with a long memory), see `impedance.Impedance` (table kind): static force, Coulomb and
  breakaway friction and viscous drag as functions of inserted length on a grid, a Dahl
  friction state for direction and presliding, the mass term. Smoothness priors make
  unvisited grid nodes extrapolate from visited ones (friction linearly, static force flat);
  parameters are physically bounded (friction, breakaway and drag >= 0, a static force that
  never pulls the catheter in, a mass of grams) by an active-set solve. Samples at rest are not learned from (the model is held).

Both have ``update(x, xd, xdd, f) -> Impedance | None`` (None before enough data).
Pure Python + numpy; time is implicit in the sample rate; deterministic.
"""
from __future__ import annotations

import math
from typing import Optional

import numpy as np

from catheter_common.checks import finite, nonneg, positive
from impedance_master.impedance import FrictionState, Impedance


class _Biquad:
    """2nd-order Butterworth low-pass (bilinear transform), direct form II transposed."""

    __slots__ = ('b0', 'b1', 'b2', 'a1', 'a2', 's1', 's2', 'primed')

    def __init__(self, cutoff: float, rate: float):
        wc = math.tan(math.pi * cutoff / rate)
        k = 1.0 / (1.0 + math.sqrt(2.0) * wc + wc * wc)
        self.b0 = wc * wc * k
        self.b1 = 2.0 * self.b0
        self.b2 = self.b0
        self.a1 = 2.0 * (wc * wc - 1.0) * k
        self.a2 = (1.0 - math.sqrt(2.0) * wc + wc * wc) * k
        self.s1 = self.s2 = 0.0
        self.primed = False

    def __call__(self, u: float) -> float:
        if not self.primed:  # start in steady state at the first input (no start transient)
            self.s2 = (self.b2 - self.a2) * u
            self.s1 = (self.b1 - self.a1) * u + self.s2
            self.primed = True
        y = self.b0 * u + self.s1
        self.s1 = self.b1 * u - self.a1 * y + self.s2
        self.s2 = self.b2 * u - self.a2 * y
        return y


class _Differentiator:
    """Backward difference of a sampled signal (first call returns 0)."""

    __slots__ = ('rate', 'last')

    def __init__(self, rate: float):
        self.rate = rate
        self.last: Optional[float] = None

    def __call__(self, u: float) -> float:
        d = 0.0 if self.last is None else (u - self.last) * self.rate
        self.last = u
        return d


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
        self._filters = [_Biquad(self.cutoff, self.rate) for _ in range(4)] if self.cutoff else None
        self._dv = _Differentiator(self.rate)
        self._da = _Differentiator(self.rate)
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


class HistoryIdentifier:
    """The project's default environment model, learned from the whole history (see module doc).

    Args:
        window: s; only sets how much motion (window * rate moving samples) is needed before
            the first model is declared valid.
        rate: Hz, sample rate.
        x_min, x_max: m, range of the inserted-length grid (outside: constant extrapolation).
        n_nodes: grid nodes (>= 3).
        sigma: m, presliding length of the friction states.
        v_s: m/s, velocity scale of the breakaway (Stribeck) state; beta: its relative height
            (the learned B table scales it; beta only shapes the state's dynamics).
        memory: s of MOTION after which old samples weigh 1/e (exponential forgetting that
            only advances while the catheter moves, so a rest does not erase the model).
        solve_every: samples between model solves (20 -> a new model every 20 ms).
        smoothness: weight (in samples) of the smoothness prior on the static table S:
            first differences (static_first_difference=True) or second differences. Weak
            (3) by default: a static force is a local contact (the tip against a wall or a
            bend), not a property of the whole length, so evidence for it at one depth (a
            reversal there) must not spread to depths seen in one direction only, where
            static force and friction cannot be told apart. With 30, S learned at the first
            reversal (56 mm) leaked down to 40 mm and the retraction there was rendered
            0.05 N too weak (Experiment II cold, seeds 0 and 2).
        friction_smoothness: weight of the second-difference prior on the friction,
            breakaway and drag tables (F, B, C): unvisited lengths extrapolate linearly.
        friction_kink: weight of a third-difference prior on F, B, C (0: none).
        rest_velocity: m/s; samples slower than this are not learned from (the model holds).
        max_mass: kg, upper bound of the mass term (0.05: what moves beyond the slave's
            force sensor is the catheter, a few grams; a generous bound). With 1 kg the barely
            excited mass column absorbed friction transients at reversals and rendered up to
            0.035 N of m x'' at the master (Experiment II cold, seed 0, in the outage).
        max_force: N, bound of |S|.
        origin_weight: weight (samples) of the prior F = B = C = 0 at zero inserted length
            (only if x_min <= 0 <= x_max). It anchors the friction's growth with length: from
            the first 8-15 mm of motion the rise was otherwise split between friction and a
            static bump and friction extrapolated too flat (Experiment II with 1 s delay,
            seed 1, at 3.6 s and 53 mm: 0.11 N rendered without it, 0.19 N with it, against
            0.30 N; that run's normal max error 0.233 -> 0.155 N).
        static_min: N, lower bound of S (0: a vessel pushes back on a catheter, it does not
            pull it in; what a one-direction fit would put as negative static force is
            friction or drag). Without it S went negative where insertion alone was seen and
            the renderer overestimated the retraction force there.
        static_ridge: ridge (samples) pulling S toward 0: force seen in one direction only
            is attributed to friction, the dominant term of catheter insertion.
        breakaway_ridge: ridge pulling B toward 0 (a refinement seen only near reversals).
        viscous_ridge: ridge pulling C toward 0: insertion seen at one speed is explained by
            friction, which holds at other speeds, rather than by drag.
    Forgetting, priors and bounds make the solve well posed whatever the data: the matrix
    is the data's information plus a positive definite prior, never singular.
    """

    def __init__(self, window: float = 1.0, rate: float = 1000.0, x_min: float = 0.0,
                 x_max: float = 0.08, n_nodes: int = 17, sigma: float = 3e-4,
                 v_s: float = 0.002, beta: float = 0.5, memory: float = 60.0, solve_every: int = 20,
                 smoothness: float = 3.0, rest_velocity: float = 2e-4,
                 max_mass: float = 0.05, max_force: float = 5.0, static_ridge: float = 1.0,
                 friction_smoothness: float = 1e3, static_first_difference: bool = True,
                 breakaway_ridge: float = 1.0, viscous_ridge: float = 100.0,
                 friction_kink: float = 0.0, static_min: float = 0.0,
                 origin_weight: float = 1e3):
        self.window = positive('window', window)
        self.rate = positive('rate', rate)
        self.x_min = finite('x_min', x_min)
        self.x_max = finite('x_max', x_max)
        if self.x_max <= self.x_min:
            raise ValueError(f'x_max must be > x_min, got {x_max!r} <= {x_min!r}')
        if isinstance(n_nodes, bool) or not isinstance(n_nodes, int) or not 3 <= n_nodes <= 128:
            raise ValueError(f'n_nodes must be an int in 3..128, got {n_nodes!r}')
        self.n_nodes = n_nodes
        self.sigma = positive('sigma', sigma)
        self.v_s = positive('v_s', v_s)
        self.beta = positive('beta', beta)
        self.memory = positive('memory', memory)
        if isinstance(solve_every, bool) or not isinstance(solve_every, int) or solve_every < 1:
            raise ValueError(f'solve_every must be an int >= 1, got {solve_every!r}')
        self.solve_every = solve_every
        self.smoothness = positive('smoothness', smoothness)
        self.rest_velocity = positive('rest_velocity', rest_velocity)
        self.max_mass = positive('max_mass', max_mass)
        self.max_force = positive('max_force', max_force)
        self.static_ridge = positive('static_ridge', static_ridge)
        self.friction_smoothness = positive('friction_smoothness', friction_smoothness)
        self.static_first_difference = bool(static_first_difference)
        self.breakaway_ridge = positive('breakaway_ridge', breakaway_ridge)
        self.viscous_ridge = positive('viscous_ridge', viscous_ridge)
        self.friction_kink = nonneg('friction_kink', friction_kink)
        self.static_min = finite('static_min', static_min)
        if not -self.max_force <= self.static_min < self.max_force:
            raise ValueError(f'static_min must be in [-max_force, max_force), got {static_min!r}')
        self.origin_weight = nonneg('origin_weight', origin_weight)
        self.dx = (self.x_max - self.x_min) / (n_nodes - 1)
        self._nodes = self.x_min + self.dx * np.arange(n_nodes)
        G = n_nodes
        self.P = 4 * G + 1
        # scales of the feature columns: velocity by V, acceleration by A (coefficients in N)
        self._V = 0.04
        self._A = 1.0
        self._lam = math.exp(-1.0 / (self.memory * self.rate))
        # second-difference prior on each of the four tables, small ridge on everything
        D = np.zeros((G - 2, G))
        for i in range(G - 2):
            D[i, i:i + 3] = (1.0, -2.0, 1.0)
        DtD = D.T @ D
        D1 = np.zeros((G - 1, G))
        for i in range(G - 1):
            D1[i, i:i + 2] = (-1.0, 1.0)
        D1tD1 = D1.T @ D1
        D3 = np.zeros((G - 3, G))
        for i in range(G - 3):
            D3[i, i:i + 4] = (-1.0, 3.0, -3.0, 1.0)
        D3tD3 = D3.T @ D3
        Pm = np.zeros((self.P, self.P))
        for g in range(4):
            if g == 0:
                blk = self.smoothness * (D1tD1 if self.static_first_difference else DtD)
            else:
                blk = self.friction_smoothness * DtD + self.friction_kink * D3tD3
            Pm[g * G:(g + 1) * G, g * G:(g + 1) * G] = blk
        Pm += 1e-6 * np.eye(self.P)
        # no inserted length, no friction, breakaway or drag: F, B, C vanish at x = 0 (when the
        # grid reaches it). Anchors the friction's slope when only a few mm have been seen
        # (else a static bump can take the rise and friction extrapolates flat)
        if self.origin_weight > 0.0 and self.x_min <= 0.0 <= self.x_max:
            u = -self.x_min / self.dx
            j = min(int(u), G - 2)
            h = np.zeros(G)
            h[j], h[j + 1] = 1.0 - (u - j), u - j
            for g in (1, 2, 3):
                Pm[g * G:(g + 1) * G, g * G:(g + 1) * G] += self.origin_weight * np.outer(h, h)
        # the static table is shrunk toward 0: a force seen in one direction only is
        # attributed to friction (which reverses), the usual case in catheter insertion
        Pm[:G, :G] += self.static_ridge * np.eye(G)
        # the breakaway table is a refinement seen only near reversals and stops: shrink it
        Pm[2 * G:3 * G, 2 * G:3 * G] += self.breakaway_ridge * np.eye(G)
        Pm[3 * G:4 * G, 3 * G:4 * G] += self.viscous_ridge * np.eye(G)
        self._prior = Pm
        lo = np.full(self.P, -np.inf)
        hi = np.full(self.P, np.inf)
        lo[:G], hi[:G] = self.static_min, self.max_force          # S
        lo[G:3 * G] = 0.0                                          # F, B >= 0
        hi[G:3 * G] = self.max_force
        lo[3 * G:4 * G] = 0.0                                      # C >= 0
        lo[4 * G], hi[4 * G] = 0.0, self.max_mass * self._A        # mass
        self._lo, self._hi = lo, hi
        self.reset()

    def reset(self) -> None:
        self._A_mat = np.zeros((self.P, self.P))
        self._b = np.zeros(self.P)
        self._Phi = np.zeros((self.solve_every, self.P))
        self._f = np.zeros(self.solve_every)
        self._rows = 0
        self._moving_in_batch = 0
        self._since_solve = 0
        self._z = FrictionState(self.sigma, self.v_s, self.beta)
        self._da = _Differentiator(self.rate)      # x'' from x' when not given
        self.n_samples = 0
        self.n_moving = 0
        self.n_solves = 0
        self.n_held = 0
        self.status = 'filling'
        self.theta = np.zeros(self.P)
        self.last: Optional[Impedance] = None

    # ------------------------------------------------------------------ persistence (JSON)
    STATE_VERSION = 1

    def get_state(self) -> dict:
        """The learned information (normal equations) as plain JSON-able values."""
        self._flush()
        return {'version': self.STATE_VERSION, 'kind': 'HistoryIdentifier',
                'grid': _json_ready(self), 'n_moving': int(self.n_moving),
                'A': self._A_mat.tolist(), 'b': self._b.tolist()}

    def set_state(self, state: dict) -> Optional[Impedance]:
        """Continue from `get_state()` output (same grid and friction hyper-parameters);
        returns the model solved from it (None if it holds too little motion)."""
        if not isinstance(state, dict) or state.get('kind') != 'HistoryIdentifier':
            raise ValueError('state must be a dict from HistoryIdentifier.get_state()')
        if state.get('version') != self.STATE_VERSION:
            raise ValueError(f'state version must be {self.STATE_VERSION}, '
                             f'got {state.get("version")!r}')
        grid = state.get('grid', {})
        mine = _json_ready(self)
        for k, v in mine.items():
            if k not in grid or not math.isclose(float(grid[k]), float(v), rel_tol=1e-12):
                raise ValueError(f'state grid {k}={grid.get(k)!r} differs from this '
                                 f'identifier\'s {v!r}')
        A = np.asarray(state.get('A'), dtype=float)
        b = np.asarray(state.get('b'), dtype=float)
        if A.shape != (self.P, self.P) or b.shape != (self.P,):
            raise ValueError(f'state A must be {self.P}x{self.P} and b {self.P}, got '
                             f'{A.shape} and {b.shape}')
        if not (np.all(np.isfinite(A)) and np.all(np.isfinite(b))):
            raise ValueError('state A and b must be finite')
        n = state.get('n_moving')
        if isinstance(n, bool) or not isinstance(n, int) or n < 0:
            raise ValueError(f'state n_moving must be an int >= 0, got {n!r}')
        self.reset()
        self._A_mat = 0.5 * (A + A.T)
        self._b = b
        self.n_moving = n
        if n >= self.window * self.rate:
            return self._solve(moved=True)
        return None

    def save_state(self, path: str) -> None:
        """Write `get_state()` as JSON (atomically: temporary file, then rename)."""
        import json
        import os
        tmp = f'{path}.tmp'
        with open(tmp, 'w', encoding='utf-8') as fh:
            json.dump(self.get_state(), fh)
        os.replace(tmp, path)

    def load_state(self, path: str) -> Optional[Impedance]:
        """Read a JSON file written by `save_state` and continue from it."""
        import json
        with open(path, encoding='utf-8') as fh:
            try:
                state = json.load(fh)
            except json.JSONDecodeError as exc:
                raise ValueError(f'path {path!r} is not a JSON state file: {exc}') from None
        return self.set_state(state)

    def update(self, x: float, xd: float, xdd: Optional[float], f: float) -> Optional[Impedance]:
        """Add one sample (x m, x' m/s, x'' m/s^2 or None, measured force f N).

        x'' None: the backward difference of x' at `rate` (what a node fed a JointState, which
        has no acceleration field, passes; the simulated robot's x'' is exactly that
        difference). Leaving it at 0 instead removes the mass column from the fit, which
        doubled the outage error of the ROS graph against the pure experiment.

        Returns None until `window` seconds of motion have been seen, then the latest model
        (a new one every `solve_every` samples; the same object in between).
        """
        x = finite('x', x)
        xd = finite('xd', xd)
        xdd_diff = self._da(xd)
        xdd = xdd_diff if xdd is None else finite('xdd', xdd)
        f = finite('f', f)
        z1, z2 = self._z.update(x, xd)
        self.n_samples += 1
        if abs(xd) >= self.rest_velocity:
            G = self.n_nodes
            u = (x - self.x_min) / self.dx
            if u <= 0.0:
                j, w = 0, 0.0
            elif u >= G - 1:
                j, w = G - 2, 1.0
            else:
                j = int(u)
                w = u - j
            w0 = 1.0 - w
            dz = z2 - z1
            vz = xd / self._V
            row = self._Phi[self._rows]
            row[j] = w0
            row[j + 1] = w
            row[G + j] = w0 * z1
            row[G + j + 1] = w * z1
            row[2 * G + j] = w0 * dz
            row[2 * G + j + 1] = w * dz
            row[3 * G + j] = w0 * vz
            row[3 * G + j + 1] = w * vz
            row[4 * G] = xdd / self._A
            self._f[self._rows] = f
            self._rows += 1
            self.n_moving += 1
        self._since_solve += 1
        if self._since_solve >= self.solve_every or self._rows >= self.solve_every:
            self._flush()
            self._since_solve = 0
            if self.n_moving >= self.window * self.rate:
                return self._solve(moved=self._moving_in_batch > 0)
            return None
        return self.last

    def _flush(self) -> None:
        k = self._rows
        self._moving_in_batch = k
        if k == 0:
            return
        Phi = self._Phi[:k]
        decay = self._lam ** k
        self._A_mat *= decay
        self._b *= decay
        self._A_mat += Phi.T @ Phi
        self._b += Phi.T @ self._f[:k]
        self._Phi[:k] = 0.0
        self._rows = 0

    def _solve(self, moved: bool) -> Impedance:
        if not moved and self.last is not None:
            self.status = 'at_rest'
            self.n_held += 1
            self.last.status = 'at_rest'
            return self.last
        M = self._A_mat + self._prior
        b = self._b.copy()
        free = np.ones(self.P, dtype=bool)
        theta = np.zeros(self.P)
        for _ in range(4):  # active set: clamp violated bounds, re-solve the rest
            idx = np.flatnonzero(free)
            rhs = b[idx] - M[np.ix_(idx, ~free)] @ theta[~free]
            theta[idx] = np.linalg.solve(M[np.ix_(idx, idx)], rhs)
            bad = free & ((theta < self._lo) | (theta > self._hi))
            if not bad.any():
                break
            theta[bad] = np.clip(theta[bad], self._lo[bad], self._hi[bad])
            free &= ~bad
        theta = np.clip(theta, self._lo, self._hi)
        if not np.all(np.isfinite(theta)):
            self.status = 'ill_conditioned'
            self.n_held += 1
            return self.last if self.last is not None else Impedance(valid=False,
                                                                     status=self.status)
        self.theta = theta
        self.n_solves += 1
        self.status = 'ok'
        G = self.n_nodes
        # report the linear part in m, c, k, offset (the thesis's terms): the straight line
        # through the static table and the mean drag, weighted by how much data each node
        # has seen; the tables keep the rest, so force() is unchanged on the grid (outside
        # it the linear part continues while the tables hold their end values)
        S = theta[:G]
        C = theta[3 * G:4 * G] / self._V
        info = np.diag(self._A_mat)
        w = info[:G] + 1e-9
        k, off = np.polyfit(self._nodes, S, 1, w=np.sqrt(w))
        wc = info[3 * G:4 * G] + 1e-9
        c = float(np.sum(wc * C) / np.sum(wc))
        self.last = Impedance(
            m=float(theta[4 * G]) / self._A, c=c, k=float(k), offset=float(off), valid=True,
            x0=self.x_min, dx=self.dx, sigma=self.sigma, v_s=self.v_s, beta=self.beta,
            S=(S - (k * self._nodes + off)).tolist(), F=theta[G:2 * G].tolist(),
            B=theta[2 * G:3 * G].tolist(), C=(C - c).tolist(), status='ok')
        return self.last


def _json_ready(ident: 'HistoryIdentifier') -> dict:
    return {'x_min': ident.x_min, 'x_max': ident.x_max, 'n_nodes': ident.n_nodes,
            'sigma': ident.sigma, 'v_s': ident.v_s, 'beta': ident.beta}


def make_identifier(window: float = 1.0, rate: float = 1000.0, **kwargs) -> HistoryIdentifier:
    """The project's default identifier (what impedance_identifier_node runs)."""
    return HistoryIdentifier(window=window, rate=rate, **kwargs)

"""Scripted operator hand trajectories (seeded, analytic x, x', x''): three families of
motion, selectable by name (`make_operator`), so that force feedback tuned on one kind of
motion can be tried on the others.

* ``minjerk`` (`OperatorTrajectory`, the thesis's experiments): a chain of minimum-jerk
  segments (Flash & Hogan 1985, the shape of human point-to-point hand movements:
  x(t) = a + D (10 s^3 - 15 s^4 + 6 s^5), s = t / T, peak speed 1.875 |D| / T, zero velocity
  and acceleration at both ends) between random targets, with occasional pauses; the first
  segment inserts to the maximum depth. Experiment I (thesis 4.3.1): 20 s; Experiment II
  (4.3.2): 12 s (the runner adds 200 ms delay and 1 s outages at 4 s and 8 s).
* ``sines`` (`SinesTrajectory`): a slow sum of four sines (0.08-0.5 Hz, random phases)
  scaled into [x_lo, x_hi] and under v_max, faded in from rest over the first 1.5 s: no
  pauses, frequent reversals at every depth, never at rest.
* ``human`` (`HumanTrajectory`): minimum-jerk submovements to random targets (the deepest
  point is NOT visited first), with hesitations (a stop part-way, a short back-off, then
  on), variable speed, and physiological tremor (two 8-12 Hz components of 15-50 um,
  faded in over the first second).

All stay within [x_lo, x_hi] (default 4-56 mm, or x_start-56 mm for minjerk) at up to
v_max (41.3 mm/s, the thesis's fastest insertion). x in m, x' m/s, x'' m/s^2, t s.
"""
from __future__ import annotations

import math
import random
from typing import List, Tuple

import numpy as np

from catheter_common.checks import finite, integer, positive, probability, seed as check_seed

X_MAX = 0.056        # m, thesis maximum insertion
V_MAX = 0.0413       # m/s, thesis maximum insertion speed
X_MIN = 0.004        # m, shallowest point of the sines and human families


def _min_jerk(tau: float, T: float, x0: float, D: float) -> Tuple[float, float, float]:
    s = tau / T
    s2 = s * s
    return (x0 + D * s2 * s * (10.0 - 15.0 * s + 6.0 * s2),
            D / T * 30.0 * s2 * (1.0 - 2.0 * s + s2),
            D / (T * T) * 60.0 * s * (1.0 - 3.0 * s + 2.0 * s2))


class _Segments:
    """A chain of minimum-jerk segments (t0, T, x0, D); D = 0 is a pause."""

    duration: float

    def _set_segments(self, segs: List[Tuple[float, float, float, float]]) -> None:
        self._segs = segs
        self._t0 = np.array([s[0] for s in segs])

    def _base(self, t: float) -> Tuple[float, float, float]:
        i = max(int(np.searchsorted(self._t0, t, side='right')) - 1, 0)
        t0, T, x0, D = self._segs[i]
        if D == 0.0 or T <= 0.0:
            return x0, 0.0, 0.0
        if t - t0 > T:
            return x0 + D, 0.0, 0.0
        return _min_jerk(min(max(t - t0, 0.0), T), T, x0, D)

    def sample(self, t: float) -> Tuple[float, float, float]:
        """(x m, x' m/s, x'' m/s^2) at time t in s (the segment running at `duration`
        runs to its end; the hand is held there after it)."""
        return self._base(finite('t', t))

    def arrays(self, rate: float = 1000.0):
        """Sampled (t, x, xd, xdd) arrays, shape (n,), n = round(duration * rate)."""
        rate = positive('rate', rate)
        n = int(round(self.duration * rate))
        t = np.arange(n) / rate
        out = np.array([self.sample(ti) for ti in t]).reshape(n, 3)
        return t, out[:, 0].copy(), out[:, 1].copy(), out[:, 2].copy()


class OperatorTrajectory(_Segments):
    """Minimum-jerk insert/retract segments with pauses (the thesis's experiments).

    Args:
        duration: s.
        seed: int >= 0 (same seed, same trajectory).
        x_start: m, initial insertion (the catheter already in the introducer).
        x_max: m, deepest target; v_max: m/s, fastest segment peak speed.
        pause_probability: chance of a pause after a segment; pauses last 0.2-0.8 s.
        min_travel: m, smallest segment displacement.
    """

    def __init__(self, duration: float = 12.0, seed: int = 0, x_start: float = 0.008,
                 x_max: float = X_MAX, v_max: float = V_MAX, pause_probability: float = 0.25,
                 min_travel: float = 0.008):
        self.duration = positive('duration', duration)
        self.seed = check_seed('seed', seed)
        self.x_start = finite('x_start', x_start)
        self.x_max = positive('x_max', x_max)
        self.v_max = positive('v_max', v_max)
        probability('pause_probability', pause_probability)
        self.min_travel = positive('min_travel', min_travel)
        if not 0.0 <= self.x_start < self.x_max - self.min_travel:
            raise ValueError('x_start must be in [0, x_max - min_travel)')
        rng = random.Random(seed)
        segs: List[Tuple[float, float, float, float]] = []  # (t0, T, x0, D)
        t, x = 0.0, self.x_start
        segs.append((t, 0.3, x, 0.0))          # short rest at the start
        t += 0.3
        first = True
        while t < self.duration:
            if first:
                target = self.x_max
                first = False
            else:
                for _ in range(100):
                    target = rng.uniform(self.x_start, self.x_max)
                    if abs(target - x) >= self.min_travel:
                        break
            D = target - x
            v_peak = self.v_max * rng.uniform(0.45, 1.0)
            T = 1.875 * abs(D) / v_peak
            segs.append((t, T, x, D))
            t += T
            x = target
            if rng.random() < pause_probability:
                T = rng.uniform(0.2, 0.8)
                segs.append((t, T, x, 0.0))
                t += T
        self._set_segments(segs)


def _check_range(x_lo: float, x_hi: float) -> Tuple[float, float]:
    x_lo = finite('x_lo', x_lo)
    x_hi = finite('x_hi', x_hi)
    if not 0.0 <= x_lo < x_hi:
        raise ValueError(f'x_lo, x_hi must satisfy 0 <= x_lo < x_hi, got {x_lo!r}, {x_hi!r}')
    return x_lo, x_hi


class SinesTrajectory:
    """A slow sum of sines (see module doc): x = x_c + A q(t) with
    ``q(t) = s0 + b(t) (s(t) - s0)``, ``s(t) = sum_i w_i sin(2 pi f_i t + phi_i)``,
    ``s0 = s(0)`` and b the minimum-jerk fade-in over `fade` s (so the hand starts at rest).
    A and x_c are chosen on a 1 ms grid so that x stays in [x_lo, x_hi] and |x'| <= v_max.

    Args: duration s, seed, x_lo / x_hi m, v_max m/s, n_sines (>= 1), f_lo / f_hi Hz
    (frequencies log-uniform between), fade s.
    """

    def __init__(self, duration: float = 12.0, seed: int = 0, x_lo: float = X_MIN,
                 x_hi: float = X_MAX, v_max: float = V_MAX, n_sines: int = 4,
                 f_lo: float = 0.08, f_hi: float = 0.5, fade: float = 1.5):
        self.duration = positive('duration', duration)
        self.seed = check_seed('seed', seed)
        self.x_lo, self.x_hi = _check_range(x_lo, x_hi)
        self.v_max = positive('v_max', v_max)
        integer('n_sines', n_sines, 1, 16)
        f_lo, f_hi = positive('f_lo', f_lo), positive('f_hi', f_hi)
        if f_hi < f_lo:
            raise ValueError(f'f_hi must be >= f_lo, got {f_hi!r} < {f_lo!r}')
        self.fade = positive('fade', fade)
        rng = random.Random(seed)
        self._f = [2.0 * math.pi * f_lo * (f_hi / f_lo) ** rng.random() for _ in range(n_sines)]
        self._phi = [rng.uniform(0.0, 2.0 * math.pi) for _ in range(n_sines)]
        self._w = [rng.uniform(0.5, 1.0) * (2.0 * math.pi * f_lo) / w for w in self._f]
        self._s0 = self._sines(0.0)[0]
        self._amp, self._xc = 1.0, 0.0
        tt = np.arange(int(round(self.duration * 1000.0)) + 1) / 1000.0
        q = np.array([self._unit(t) for t in tt])
        span = q[:, 0].max() - q[:, 0].min()
        vpk = np.abs(q[:, 1]).max()
        self._amp = min((self.x_hi - self.x_lo) / span if span > 0 else math.inf,
                        self.v_max / vpk if vpk > 0 else math.inf)
        self._xc = 0.5 * (self.x_lo + self.x_hi) - 0.5 * self._amp * (q[:, 0].max()
                                                                       + q[:, 0].min())

    def _sines(self, t: float) -> Tuple[float, float, float]:
        s = v = a = 0.0
        for w, f, ph in zip(self._w, self._f, self._phi, strict=True):
            arg = f * t + ph
            s += w * math.sin(arg)
            v += w * f * math.cos(arg)
            a -= w * f * f * math.sin(arg)
        return s, v, a

    def _unit(self, t: float) -> Tuple[float, float, float]:
        s, v, a = self._sines(t)
        if t < self.fade:
            b, bd, bdd = _min_jerk(max(t, 0.0), self.fade, 0.0, 1.0)
        else:
            b, bd, bdd = 1.0, 0.0, 0.0
        d = s - self._s0
        return self._s0 + b * d, bd * d + b * v, bdd * d + 2.0 * bd * v + b * a

    def sample(self, t: float) -> Tuple[float, float, float]:
        """(x m, x' m/s, x'' m/s^2) at time t in s."""
        q, qd, qdd = self._unit(finite('t', t))
        A = self._amp
        return self._xc + A * q, A * qd, A * qdd

    arrays = _Segments.arrays


class HumanTrajectory(_Segments):
    """Human-like motion (see module doc): minimum-jerk submovements with hesitations and
    physiological tremor.

    Args: duration s, seed, x_lo / x_hi m, v_max m/s (segment peak speeds 0.3-0.8 v_max,
    leaving room for the tremor; segments last at least 0.25 s), hesitation_probability (a
    segment stops part-way for 0.1-0.5 s, backs off 0.5-2 mm and goes on), tremor m
    (largest amplitude of each of the two tremor components, default 0.05 mm: physiological
    hand tremor is tens of micrometres at 8-12 Hz), min_travel m.
    """

    def __init__(self, duration: float = 12.0, seed: int = 0, x_lo: float = X_MIN,
                 x_hi: float = X_MAX, v_max: float = V_MAX,
                 hesitation_probability: float = 0.4, tremor: float = 5e-5,
                 min_travel: float = 0.006):
        self.duration = positive('duration', duration)
        self.seed = check_seed('seed', seed)
        self.x_lo, self.x_hi = _check_range(x_lo, x_hi)
        self.v_max = positive('v_max', v_max)
        probability('hesitation_probability', hesitation_probability)
        self.tremor = finite('tremor', tremor)
        if not 0.0 <= self.tremor <= 1e-3:
            raise ValueError(f'tremor must be in [0, 1e-3] m, got {tremor!r}')
        self.min_travel = positive('min_travel', min_travel)
        if self.min_travel >= self.x_hi - self.x_lo:
            raise ValueError('min_travel must be below x_hi - x_lo')
        rng = random.Random(seed)
        span = self.x_hi - self.x_lo
        x = self.x_lo + 0.1 * span
        x = min(max(x, self.x_lo + 0.003), self.x_hi)
        t = 0.0
        segs: List[Tuple[float, float, float, float]] = [(t, 0.3, x, 0.0)]
        t += 0.3
        edge = min(0.002, 0.25 * span)

        def move(x0: float, target: float) -> float:
            nonlocal t
            D = target - x0
            T = max(1.875 * abs(D) / (self.v_max * rng.uniform(0.3, 0.8)), 0.25)
            segs.append((t, T, x0, D))
            t += T
            return target

        while t < self.duration:
            for _ in range(100):
                target = rng.uniform(self.x_lo + edge, self.x_hi - edge)
                if abs(target - x) >= self.min_travel:
                    break
            if rng.random() < hesitation_probability:
                mid = x + (target - x) * rng.uniform(0.3, 0.7)
                x = move(x, mid)
                segs.append((t, rng.uniform(0.1, 0.5), x, 0.0))
                t += segs[-1][1]
                back = math.copysign(rng.uniform(0.5e-3, min(2e-3, edge)), x - target)
                x = move(x, min(max(x + back, self.x_lo), self.x_hi))
            x = move(x, target)
            if rng.random() < 0.2:
                segs.append((t, rng.uniform(0.1, 0.4), x, 0.0))
                t += segs[-1][1]
        self._set_segments(segs)
        self._tremor = [(rng.uniform(0.3, 1.0) * self.tremor,
                         2.0 * math.pi * rng.uniform(8.0, 12.0), rng.uniform(0.0, 2.0 * math.pi))
                        for _ in range(2)]

    def sample(self, t: float) -> Tuple[float, float, float]:
        """(x m, x' m/s, x'' m/s^2) at time t in s (tremor faded in over the first second)."""
        t = finite('t', t)
        x, v, a = self._base(t)
        if self.tremor > 0.0:
            b, bd, bdd = _min_jerk(min(max(t, 0.0), 1.0), 1.0, 0.0, 1.0)
            for amp, w, ph in self._tremor:
                s, c = math.sin(w * t + ph), math.cos(w * t + ph)
                x += b * amp * s
                v += amp * (bd * s + b * w * c)
                a += amp * (bdd * s + 2.0 * bd * w * c - b * w * w * s)
        return x, v, a


#: the operator families by name
OPERATORS = {'minjerk': OperatorTrajectory, 'sines': SinesTrajectory, 'human': HumanTrajectory}
#: s, duration of the thesis's experiments
EXPERIMENT_DURATION = {'I': 20.0, 'II': 12.0}


def make_operator(name: str = 'minjerk', duration: float = 12.0, seed: int = 0, **params):
    """The named operator family's trajectory (see module doc): ``minjerk``, ``sines`` or
    ``human``; keyword parameters as each class documents. ValueError naming a bad name."""
    if not isinstance(name, str) or name not in OPERATORS:
        raise ValueError(f'operator must be one of {tuple(OPERATORS)}, got {name!r}')
    try:
        return OPERATORS[name](duration=duration, seed=seed, **params)
    except TypeError as exc:
        raise ValueError(f'bad operator parameters for {name!r}: {exc}') from None


def experiment_trajectory(experiment: str = 'II', seed: int = 0, operator: str = 'minjerk',
                          **params):
    """The scripted hand of thesis Experiment 'I' (20 s) or 'II' (12 s); `operator` picks
    the family (default the thesis's minimum-jerk motion)."""
    if experiment not in EXPERIMENT_DURATION:
        raise ValueError(f"experiment must be 'I' or 'II', got {experiment!r}")
    return make_operator(operator, EXPERIMENT_DURATION[experiment], seed, **params)

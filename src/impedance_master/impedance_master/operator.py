"""Scripted operator hand trajectories for the thesis's experiments (seeded, analytic).

Experiment I (thesis 4.3.1): arbitrary insertion / retraction up to 56 mm at up to 41.3 mm/s.
Experiment II (thesis 4.3.2): the same style of motion for 12 s (the runner adds 200 ms delay
and 1 s outages at t = 4 s and 8 s).

A trajectory is a chain of minimum-jerk segments (Flash & Hogan 1985, the shape of human
point-to-point hand movements: x(t) = a + D (10 s^3 - 15 s^4 + 6 s^5), s = t / T, peak
speed 1.875 |D| / T, zero velocity and acceleration at both ends) between random targets,
with occasional pauses. x, x', x'' are exact at any time; the first segment inserts to the
maximum depth.
"""
from __future__ import annotations

import random
from typing import List, Tuple

import numpy as np

from catheter_common.checks import finite, positive, seed as check_seed

X_MAX = 0.056        # m, thesis maximum insertion
V_MAX = 0.0413       # m/s, thesis maximum insertion speed


class OperatorTrajectory:
    """Piecewise cosine-profile insertion trajectory.

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
        if not 0.0 <= pause_probability <= 1.0:
            raise ValueError(f'pause_probability must be in [0, 1], got {pause_probability!r}')
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
        self._segs = segs
        self._t0 = np.array([s[0] for s in segs])

    def sample(self, t: float) -> Tuple[float, float, float]:
        """(x m, x' m/s, x'' m/s^2) at time t in s (held at the end after `duration`)."""
        t = finite('t', t)
        i = int(np.searchsorted(self._t0, t, side='right')) - 1
        i = max(i, 0)
        t0, T, x0, D = self._segs[i]
        tau = min(max(t - t0, 0.0), T)
        if D == 0.0 or T <= 0.0:
            return x0, 0.0, 0.0
        if t - t0 > T:
            return x0 + D, 0.0, 0.0
        s = tau / T
        s2 = s * s
        return (x0 + D * s2 * s * (10.0 - 15.0 * s + 6.0 * s2),
                D / T * 30.0 * s2 * (1.0 - 2.0 * s + s2),
                D / (T * T) * 60.0 * s * (1.0 - 3.0 * s + 2.0 * s2))

    def arrays(self, rate: float = 1000.0):
        """Sampled (t, x, xd, xdd) arrays, shape (n,), n = round(duration * rate)."""
        rate = positive('rate', rate)
        n = int(round(self.duration * rate))
        t = np.arange(n) / rate
        out = np.array([self.sample(ti) for ti in t]).reshape(n, 3)
        return t, out[:, 0].copy(), out[:, 1].copy(), out[:, 2].copy()


def experiment_trajectory(experiment: str = 'II', seed: int = 0) -> OperatorTrajectory:
    """The scripted hand of thesis Experiment 'I' (20 s) or 'II' (12 s)."""
    if experiment == 'I':
        return OperatorTrajectory(duration=20.0, seed=seed)
    if experiment == 'II':
        return OperatorTrajectory(duration=12.0, seed=seed)
    raise ValueError(f"experiment must be 'I' or 'II', got {experiment!r}")

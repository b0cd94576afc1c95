"""Helpers shared by the sim_slave tests: an Experiment-I-like insertion trajectory."""
import math

import numpy as np
import pytest

#: thesis Experiment I: insertion up to 56 mm at up to 41.3 mm/s
X_MAX = 0.056
V_MAX = 0.0413


def min_jerk(x0, x1, duration, t):
    """Minimum-jerk move from x0 to x1 over `duration` s, evaluated at t in [0, duration]."""
    s = np.clip(t / duration, 0.0, 1.0)
    return x0 + (x1 - x0) * (10 * s ** 3 - 15 * s ** 4 + 6 * s ** 5)


def exp1_trajectory(rate=1000.0):
    """Arbitrary insert/retract moves to 56 mm, peak speed 41.3 mm/s; returns (t, x) arrays.

    Minimum-jerk segments (peak speed 1.875 D / T) with pauses between them.
    """
    moves = [(0.0, X_MAX), (X_MAX, 0.020), (0.020, 0.045), (0.045, X_MAX), (X_MAX, 0.0)]
    ts, xs = [], []
    t0 = 0.0
    dt = 1.0 / rate
    for a, b in moves:
        dur = 1.875 * abs(b - a) / V_MAX
        n = int(math.ceil(dur / dt))
        tt = np.arange(n) * dt
        ts.append(t0 + tt)
        xs.append(min_jerk(a, b, dur, tt))
        t0 += n * dt
        hold = int(0.4 * rate)             # a pause at each end point
        ts.append(t0 + np.arange(hold) * dt)
        xs.append(np.full(hold, b))
        t0 += hold * dt
    return np.concatenate(ts) + dt, np.concatenate(xs)


@pytest.fixture(scope='session')
def exp1():
    return exp1_trajectory()

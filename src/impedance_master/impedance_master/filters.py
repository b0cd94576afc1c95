"""Sample-by-sample signal filters shared by the identifiers (pure Python, no numpy).

* `Biquad`: a 2nd-order Butterworth low-pass (bilinear transform, direct form II
  transposed) that starts in steady state at its first input (no start transient);
* `Differentiator`: the backward difference of a sampled signal at a given rate.
"""
from __future__ import annotations

import math
from typing import Optional


class Biquad:
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


class Differentiator:
    """Backward difference of a sampled signal (first call returns 0)."""

    __slots__ = ('rate', 'last')

    def __init__(self, rate: float):
        self.rate = rate
        self.last: Optional[float] = None

    def __call__(self, u: float) -> float:
        d = 0.0 if self.last is None else (u - self.last) * self.rate
        self.last = u
        return d

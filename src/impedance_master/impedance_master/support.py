"""Data support of the rendered model, as the master can know it: where (depth) and in
which direction of motion the slave has measured (issue 12, third round).

Every model the identifier sends carries its `Anchor`: the slave's state at the sample the
model was made at. The renderer counts these anchors (one per distinct model, i.e. one per
identifier solve, 50 per second) in a histogram over inserted length, one row per
direction of motion (the anchor's velocity sign; anchors at rest, |x'| below
`min_speed`, are not counted: the identifier does not learn from them either). Each count
is spread over the neighbouring bins with a triangular kernel of half-width `width`, so
the support at a depth is the data within about `width` of it.

Two confidences in [0, 1) follow, both n / (n + n_half) of a count n:

* `confidence(x, d)`: data in the direction d near x: does the model know the force
  HERE when moving THIS way (else it extrapolates from other depths);
* `both(x)`: data in BOTH directions near x (the smaller of the two counts): can the model
  tell a static force (the same in both directions) from friction (which reverses) here.
  A force seen in one direction only cannot be split: the identifier's prior calls it
  friction, which is wrong at a wall.

No rclpy, no numpy: O(kernel) per anchor, O(1) per query.
"""
from __future__ import annotations

import bisect
import math
from typing import Optional

from catheter_common.checks import positive

#: m, bin width of the support histogram
BIN = 0.001


class Support:
    """Anchor counts over depth x direction.

    Args:
        x_lo, x_hi: m, the range of depths counted (outside: the nearest end bin).
        width: m, half-width of the triangular spreading kernel.
        n_half: anchors at which a confidence is 1/2.
        min_speed: m/s, anchors slower than this are not counted (at rest).
    """

    __slots__ = ('x_lo', 'n_bins', 'width', 'n_half', 'min_speed', '_w', '_k', 'n',
                 '_seen', 'min_depth')

    def __init__(self, x_lo: float = -0.07, x_hi: float = 0.25, width: float = 0.003,
                 n_half: float = 10.0, min_speed: float = 0.001, min_depth: float = 0.005):
        if not x_lo < x_hi:
            raise ValueError(f'x_lo must be below x_hi, got {x_lo!r}, {x_hi!r}')
        self.x_lo = float(x_lo)
        self.n_bins = int(math.ceil((x_hi - x_lo) / BIN)) + 1
        self.width = positive('width', width)
        self.n_half = positive('n_half', n_half)
        self.min_speed = positive('min_speed', min_speed)
        h = max(1, int(round(width / BIN)))
        self._k = [(j, 1.0 - abs(j) / (h + 1)) for j in range(-h, h + 1)]
        self._w = ([0.0] * self.n_bins, [0.0] * self.n_bins)      # [retracting, inserting]
        self.n = 0
        self.min_depth = positive('min_depth', min_depth)
        # sorted depths (bins) with at least n_half anchors: retracting, inserting, both
        self._seen: tuple = ([], [], [])

    def _bin(self, x: float) -> int:
        i = int(round((x - self.x_lo) / BIN))
        return 0 if i < 0 else (self.n_bins - 1 if i >= self.n_bins else i)

    def add(self, x: float, xd: float) -> bool:
        """Count a slave sample at depth x (m) moving at xd (m/s); False if at rest."""
        if not (math.isfinite(x) and math.isfinite(xd)) or abs(xd) < self.min_speed:
            return False
        row = self._w[1 if xd > 0.0 else 0]
        i0 = self._bin(x)
        last = self.n_bins - 1
        for j, w in self._k:
            i = i0 + j
            if 0 <= i <= last:
                row[i] += w
        self.n += 1
        self._update_both(i0)
        return True

    def _update_both(self, i0: int) -> None:
        """Add the bins near i0 whose counts now reach n_half to the sorted lists of depths
        seen (retracting, inserting, both ways; counts only grow: a bin once in stays)."""
        h = len(self._k) // 2
        w0, w1 = self._w
        for i in range(max(0, i0 - h), min(self.n_bins, i0 + h + 1)):
            xb = self.x_lo + i * BIN
            if xb < self.min_depth:
                continue
            for lst, n in zip(self._seen, (w0[i], w1[i], min(w0[i], w1[i])), strict=True):
                if n >= self.n_half:
                    j = bisect.bisect_left(lst, xb)
                    if j == len(lst) or lst[j] != xb:
                        lst.insert(j, xb)

    def nearest(self, x: float, direction) -> Optional[float]:
        """The depth (m, at least min_depth) nearest x with at least n_half anchors moving in
        the direction's sign (direction None: in both directions), or None if none."""
        b = self._seen[2 if direction is None else (1 if direction > 0.0 else 0)]
        if not b:
            return None
        j = bisect.bisect_left(b, x)
        if j == 0:
            return b[0]
        if j == len(b):
            return b[-1]
        return b[j] if b[j] - x < x - b[j - 1] else b[j - 1]

    def _at(self, x: float):
        """(i, u): x lies between bins i and i + 1 at the fraction u (clamped at the ends)."""
        s = (x - self.x_lo) / BIN
        if not s > 0.0:                 # below the range (or NaN: the renderer checks x)
            return 0, 0.0
        if s >= self.n_bins - 1:
            return self.n_bins - 2, 1.0
        i = int(s)
        return i, s - i

    def count(self, x: float, direction: float) -> float:
        """Kernel-weighted anchors near depth x (m) moving in the direction sign(direction)
        (linear between bins: continuous in x)."""
        row = self._w[1 if direction > 0.0 else 0]
        i, u = self._at(x)
        return row[i] + u * (row[i + 1] - row[i])

    def confidence(self, x: float, z1: float) -> float:
        """n / (n + n_half) of the anchors near x in the direction of motion z1 in [-1, 1]
        (a friction direction state: +1 inserting, -1 retracting; in between, during a
        reversal, the two directions' confidences mixed: continuous in z1)."""
        a = 0.5 * (1.0 + max(-1.0, min(1.0, z1)))
        h = self.n_half
        n1 = self.count(x, 1.0)
        n0 = self.count(x, -1.0)
        return a * n1 / (n1 + h) + (1.0 - a) * n0 / (n0 + h)

    def anywhere(self, x: float) -> float:
        """n / (n + n_half) of both directions' counts near x together."""
        n = self.count(x, 1.0) + self.count(x, -1.0)
        return n / (n + self.n_half)

    def nearest_any(self, x: float) -> Optional[float]:
        """The depth nearest x seen (n_half anchors) in either direction, or None."""
        a = self.nearest(x, 1.0)
        b = self.nearest(x, -1.0)
        if a is None or b is None:
            return b if a is None else a
        return a if abs(a - x) <= abs(b - x) else b

    def both(self, x: float) -> float:
        """n / (n + n_half) of the smaller of the two directions' counts near x."""
        n = min(self.count(x, 1.0), self.count(x, -1.0))
        return n / (n + self.n_half)

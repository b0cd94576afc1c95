"""Data support of the rendered model, as the master can know it: at which depths the
slave has measured (issue 12, third round).

Every model the identifier sends carries its `Anchor`: the slave's state at the sample the
model was made at. The renderer counts these anchors (one per distinct model, i.e. one per
identifier solve, 50 per second) in a histogram over inserted length (1 mm bins), one row
per direction of motion (the anchor's velocity sign; anchors at rest, |x'| below
`min_speed`, are not counted: the identifier does not learn from them either). Each count
is spread over the neighbouring bins with a triangular kernel of half-width `width`, so
the count at a depth is the data within about `width` of it; between bins it is linear
(continuous in depth, so a renderer using it does not step).

`anywhere(x)` = n / (n + n_half) of the count n of both directions near x: does the model
know the force HERE, or do its tables there only repeat its priors (smoothness, the
static force's pull to 0) beyond the data. `nearest_any(x)`: the depth nearest x with at
least n_half anchors (the edge of the data to extend the model from). Counts only grow.

`DepthSlope` (fourth round): the slope of the anchors' MEASURED force over depth along the
slave's latest few millimetres of path, per direction: how steeply the force rose where
the data end (the model's tables flatten there toward their priors).

`ElasticShare` (sixth round): the part of the force met while inserting that rose above
the trend of the force met shallower (friction grows with the length from the entry): a
wall's, which does not reverse when the catheter is pulled back.

No rclpy, no numpy: O(kernel) per anchor, O(1) per query (a bisection for `nearest`).
"""
from __future__ import annotations

import bisect
import math
from typing import Optional, Tuple

from catheter_common.checks import nonneg, positive

#: m, bin width of the support histogram
BIN = 0.001
# The renderer's defaults for its support weighting and its extension beyond the data:
#: anchors (slave samples, one per model) near a depth at which its support is 1/2
SUPPORT_HALF = 3.0
#: m, reach in depth of one anchor's support
SUPPORT_WIDTH = 0.003
#: m, depth step of the slope with which a model is extended beyond its data (support)
SLOPE_STEP = 0.005
#: m, path length over which the measured force's slope in depth is taken (`DepthSlope`)
SLOPE_LENGTH = 0.005
#: N/m, the steepest measured slope a model is extended with: above the steepest wall or
#: friction growth of the drawn vessels (about 40 N/m at 10 mm/s); a steeper rise is a local
#: bump (a stenosis: up to 230 N/m over half a millimetre), not to be extended
MAX_SLOPE = 50.0
#: N/m, the steepest slope of the MODEL's own tables at the edge of its data that the
#: extension beyond the data keeps (eighth round of issue 12): above the friction growth
#: with length of the drawn vessels (a few N/m), below their walls; a steeper rise of
#: the model there (its fit of a stenosis' bump, 30-50 N/m, where the slave stopped on
#: it) is thrown ahead only as far as the MEASURED slope (`DepthSlope`, at most
#: MAX_SLOPE) shows it
MAX_MODEL_SLOPE = 10.0
#: m, the elastic share's friction trend is fitted to the forces met at least this much
#: shallower than the depth it is asked at (`ElasticShare`)
ELASTIC_MARGIN = 0.015
#: the F ratio a fitted wall (`wall_fit.fit_hinge`, `ElasticShare.hinge`) must reach
#: (seventeenth round of issue 12: at 100 and 200 walls were also read into soft,
#: stenosis and quadratic-friction vessels; README, Benchmark)
HINGE_F = 300.0
#: the share of the fitted wall's force (`ElasticShare.hinge`) a first outward reversal
#: keeps at least (`ImaRenderer` elastic_hinge; seventeenth round of issue 12: 0.7 met the
#: keep rule on the 720 seen worlds, 1.0 lost three of them to the anchored baseline)
HINGE_GAIN = 0.7
#: the share of the estimated elastic force a first outward reversal keeps (`ImaRenderer`
#: elastic_gain): 0.5, the largest of 0.5 / 0.7 / 1.0 that keeps the project's
#: vessel's Experiment II outage within 10 % (the estimate reads a friction growing
#: faster than the length, the phantom's capstan, partly as elastic)
ELASTIC_GAIN = 0.5
#: keep at least the inserting force above a square-law friction fitted to the forces met
#: well shallower at a first outward reversal (`ElasticShare.square_excess`, thirteenth
#: round of issue 12; the default since the fourteenth, with SQUARE_SIGMAS)
ELASTIC_SQUARE = True
#: N, with ELASTIC_SQUARE: the force above the square law counted only above this band
#: (`ElasticShare` square_band, fourteenth round of issue 12; screened at 0.03 N, not kept)
SQUARE_BAND = 0.0
#: with ELASTIC_SQUARE: ... and above this many times the shallow forces' rms scatter about
#: the law (`ElasticShare` square_sigmas, `square_scatter`: the sensor noise, cardiac and
#: breathing and the law's misfit the data themselves show; fourteenth round of issue 12)
SQUARE_SIGMAS = 2.0


class Support:
    """Anchor counts over depth x direction.

    Args:
        x_lo, x_hi: m, the range of depths counted (outside: the nearest end bin).
        width: m, half-width of the triangular spreading kernel.
        n_half: anchors at which the support `anywhere` is 1/2, and the count from which
            a depth is 'seen' (`nearest`).
        min_speed: m/s, anchors slower than this are not counted (at rest).
        min_depth: m, depths shallower are never 'seen' (a renderer extends the model
            toward the entry in proportion to depth / seen depth).
    """

    __slots__ = ('x_lo', 'n_bins', 'width', 'n_half', 'min_speed', 'min_depth', '_w', '_k',
                 '_seen', 'n')

    def __init__(self, x_lo: float = -0.07, x_hi: float = 0.25, width: float = 0.003,
                 n_half: float = 3.0, min_speed: float = 0.001, min_depth: float = 0.005):
        if not x_lo < x_hi:
            raise ValueError(f'x_lo must be below x_hi, got {x_lo!r}, {x_hi!r}')
        self.x_lo = float(x_lo)
        self.n_bins = int(math.ceil((x_hi - x_lo) / BIN)) + 1
        self.width = positive('width', width)
        self.n_half = positive('n_half', n_half)
        self.min_speed = positive('min_speed', min_speed)
        self.min_depth = positive('min_depth', min_depth)
        h = max(1, int(round(width / BIN)))
        self._k = [(j, 1.0 - abs(j) / (h + 1)) for j in range(-h, h + 1)]
        self._w = ([0.0] * self.n_bins, [0.0] * self.n_bins)      # [retracting, inserting]
        self._seen = ([], [])           # sorted depths with >= n_half anchors, same order
        self.n = 0

    def _bin(self, x: float) -> int:
        i = int(round((x - self.x_lo) / BIN))
        return 0 if i < 0 else (self.n_bins - 1 if i >= self.n_bins else i)

    def add(self, x: float, xd: float) -> bool:
        """Count a slave sample at depth x (m) moving at xd (m/s); False if at rest (or
        not finite: not counted)."""
        if not (math.isfinite(x) and math.isfinite(xd)) or abs(xd) < self.min_speed:
            return False
        d = 1 if xd > 0.0 else 0
        row = self._w[d]
        seen = self._seen[d]
        i0 = self._bin(x)
        for j, w in self._k:
            i = i0 + j
            if 0 <= i < self.n_bins:
                row[i] += w
                xb = self.x_lo + i * BIN
                if row[i] >= self.n_half and xb >= self.min_depth:
                    k = bisect.bisect_left(seen, xb)
                    if k == len(seen) or seen[k] != xb:
                        seen.insert(k, xb)
        self.n += 1
        return True

    def count(self, x: float, direction: float) -> float:
        """Kernel-weighted anchors near depth x (m) moving in the direction sign(direction)
        (linear between bins: continuous in x)."""
        row = self._w[1 if direction > 0.0 else 0]
        s = (x - self.x_lo) / BIN
        if not s > 0.0:                 # below the range (the renderer checks x is finite)
            return row[0]
        if s >= self.n_bins - 1:
            return row[-1]
        i = int(s)
        return row[i] + (s - i) * (row[i + 1] - row[i])

    def anywhere(self, x: float) -> float:
        """n / (n + n_half) of both directions' counts near x together, in [0, 1)."""
        n = self.count(x, 1.0) + self.count(x, -1.0)
        return n / (n + self.n_half)

    def nearest(self, x: float, direction: float) -> Optional[float]:
        """The depth (m, a bin at least min_depth deep) nearest x with at least n_half
        anchors moving in the direction's sign, or None if there is none."""
        b = self._seen[1 if direction > 0.0 else 0]
        if not b:
            return None
        j = bisect.bisect_left(b, x)
        if j == 0:
            return b[0]
        if j == len(b):
            return b[-1]
        return b[j] if b[j] - x < x - b[j - 1] else b[j - 1]

    def bracket(self, x: float) -> Tuple[Optional[float], Optional[float]]:
        """(lo, hi): the deepest depth at or above x and the shallowest at or below it
        seen (n_half anchors) in either direction; None where there is none. The
        renderer interpolates between them (a gap in the data) or extends from the one
        there is: continuous in x (the nearest seen depth jumps at a gap's middle)."""
        lo = hi = None
        for b in self._seen:
            if b:
                j = bisect.bisect_right(b, x)
                if j > 0 and (lo is None or b[j - 1] > lo):
                    lo = b[j - 1]
                j = bisect.bisect_left(b, x)
                if j < len(b) and (hi is None or b[j] < hi):
                    hi = b[j]
        return lo, hi

    def nearest_any(self, x: float) -> Optional[float]:
        """The depth nearest x seen (n_half anchors) in either direction, or None."""
        a = self.nearest(x, 1.0)
        b = self.nearest(x, -1.0)
        if a is None or b is None:
            return b if a is None else a
        return a if abs(a - x) <= abs(b - x) else b


class DepthSlope:
    """How the MEASURED force changes with depth along the slave's latest path, per
    direction of motion (fourth round of issue 12): a weighted straight line f = a + b x
    through the anchors (x, f) moving in that direction, each weighed by
    exp(-(path length travelled since, in that direction) / `length`): the force's slope
    over the last few millimetres the slave moved through. Beyond the deepest point the
    slave has reached, this is the honest extrapolation of what it met there (a wall's
    rise, the friction's growth), where the model's tables only repeat their priors.

    Args:
        length: m, the path length over which older anchors fade (e-fold).
        min_spread: m, the weighted standard deviation of the anchors' depths below which
            there is no slope (None): a line through one depth is not a slope.
        min_speed: m/s, anchors slower than this are not counted (at rest).
    """

    __slots__ = ('length', 'min_spread', 'min_speed', 'min_state', '_s', '_last')

    def __init__(self, length: float = 0.005, min_spread: float = 0.001,
                 min_speed: float = 0.005, min_state: float = 0.95):
        self.min_state = float(min_state)
        self.length = positive('length', length)
        self.min_spread = positive('min_spread', min_spread)
        self.min_speed = positive('min_speed', min_speed)
        self._s = ([0.0] * 5, [0.0] * 5)        # [retracting, inserting]: w, wx, wf, wxx, wxf
        self._last = [None, None]

    def add(self, x: float, xd: float, f: float, z1: float = 1.0) -> bool:
        """Count an anchor at depth x (m) moving at xd (m/s) with measured force f (N) and
        the identifier's friction direction state z1 there; False if slower than
        min_speed, not finite, or with a friction state not yet turned to the direction
        of motion (|z1| < min_state: a reversal's transition is not a slope in depth)."""
        if not (math.isfinite(x) and math.isfinite(xd) and math.isfinite(f)
                and math.isfinite(z1)) or abs(xd) < self.min_speed:
            return False
        d = 1 if xd > 0.0 else 0
        if (z1 if d else -z1) < self.min_state:
            return False
        s = self._s[d]
        last = self._last[d]
        lam = 1.0 if last is None else math.exp(-abs(x - last) / self.length)
        self._last[d] = x
        for i, v in enumerate((1.0, x, f, x * x, x * f)):
            s[i] = lam * s[i] + v
        return True

    def slope(self, direction: float) -> Optional[float]:
        """N/m, the slope of the measured force over depth along the latest path in the
        direction sign(direction), or None (no anchors, or their depths spread less than
        min_spread)."""
        w, wx, wf, wxx, wxf = self._s[1 if direction > 0.0 else 0]
        if w <= 0.0:
            return None
        mx = wx / w
        var = wxx / w - mx * mx
        if not var >= self.min_spread ** 2:
            return None
        return (wxf / w - mx * wf / w) / var


class ElasticShare:
    """How much of the force met while inserting is elastic (a wall: it does not reverse
    at a reversal) rather than friction (it does), from the shape of the MEASURED force
    over depth (sixth round of issue 12).

    Friction and drag grow with the inserted length from 0 at the entry, about in
    proportion to it; a wall adds a force that rises from its onset on. The anchors
    moving inward (at least `min_speed`, friction state turned) are binned by depth
    (1 mm) with their measured force less the model's velocity terms (drag, mass) at
    that sample. At depth x the friction trend is the least-squares line through the
    entry, f = mu x, over the binned anchors at least `margin` shallower than x (and at
    least `min_depth` deep; at least `min_bins` bins): what the force did well before x.
    The elastic share of an inserting force f there is s = 1 - mu x / f, in [0, 1]: the
    part of the force above the shallow trend. A friction growing faster than in
    proportion to the length (a capstan, a square law) reads partly as elastic.

    The square law (thirteenth round): `square_rate` c of f = c x^2 through the same bins,
    `square_excess` the force above it. Fourteenth round: that excess is counted only
    above `square_band` N plus `square_sigmas` x `square_scatter` (the anchors' rms
    scatter about the law).
    """

    __slots__ = ('x_lo', 'margin', 'min_depth', 'min_bins', 'min_speed', 'min_state',
                 'square_band', 'square_sigmas', '_n', '_f', '_f2', '_cum', '_cum2', '_cum3',
                 '_built', '_v', '_count', '_hinge', '_hinge_key')

    def __init__(self, x_lo: float = -0.07, x_hi: float = 0.25, margin: float = ELASTIC_MARGIN,
                 min_depth: float = 0.005, min_bins: int = 3, min_speed: float = 0.005,
                 min_state: float = 0.95, square_band: float = 0.0,
                 square_sigmas: float = 0.0):
        if not x_lo < x_hi:
            raise ValueError(f'x_lo must be below x_hi, got {x_lo!r}, {x_hi!r}')
        self.x_lo = float(x_lo)
        self.margin = positive('margin', margin)
        self.min_depth = positive('min_depth', min_depth)
        self.min_bins = int(positive('min_bins', min_bins))
        self.min_speed = positive('min_speed', min_speed)
        self.min_state = float(min_state)
        self.square_band = nonneg('square_band', square_band)
        self.square_sigmas = nonneg('square_sigmas', square_sigmas)
        n = int(math.ceil((x_hi - x_lo) / BIN)) + 1
        self._n = [0.0] * n
        self._f = [0.0] * n
        self._f2 = [0.0] * n
        self._v = [0.0] * n         # the anchors' speeds per bin (`hinge`: a wall's damper)
        self._count = 0
        self._hinge = None
        self._hinge_key = None
        self._cum = ([0.0] * n, [0.0] * n, [0] * n)    # running sums of f x, n x^2, bins
        self._cum2 = ([0.0] * n, [0.0] * n)            # running sums of f x^2, n x^4
        self._cum3 = ([0.0] * n, [0.0] * n)            # running sums of n, f^2
        #: the running sums hold for the bins below this index (an anchor makes those from
        #: its bin on stale; a query extends them only as far as it reads)
        self._built = 0

    def add(self, x: float, xd: float, f: float, z1: float = 1.0) -> bool:
        """Count an anchor at depth x (m) moving at xd (m/s) whose force less the model's
        velocity terms is f (N), friction state z1; False if not counted (not inserting at
        min_speed with a turned friction state, not finite, or outside the range)."""
        if not (math.isfinite(x) and math.isfinite(xd) and math.isfinite(f)
                and math.isfinite(z1)) or xd < self.min_speed or z1 < self.min_state:
            return False
        i = int(round((x - self.x_lo) / BIN))
        if not 0 <= i < len(self._n):
            return False
        self._n[i] += 1.0
        self._f[i] += f
        self._f2[i] += f * f
        self._v[i] += xd
        self._count += 1
        if i < self._built:
            self._built = i
        return True

    def _trend(self, x: float, square: bool = False) -> Tuple[Optional[float], float]:
        """(mu, ramp): the friction trend at depth x (None: no bins at least `margin`
        shallower) and the weight of the share there, min(1, bins - (min_bins - 1))
        counted continuously in x (a hard threshold stepped the rendered force as the
        master crossed it). square: the square law c (`square_rate`) instead of mu."""
        c, _, ramp = self._fit(x, square)
        return c, ramp

    def _extend(self, j: int) -> None:
        """The running sums of the bins from `_built` up to j (inclusive), continued from the
        sums below: the same additions in the same order as one pass from the entry (an
        anchor near the master's depth leaves the sums 15 mm shallower, which the trend
        reads, as they were: rebuilding all 320 bins on every new model cost 25-40 us)."""
        fx, nxx, nb = self._cum
        fxx, nx4 = self._cum2
        ns, f2s = self._cum3
        k = self._built
        if k > 0:
            a, b, c = fx[k - 1], nxx[k - 1], nb[k - 1]
            a2, b2 = fxx[k - 1], nx4[k - 1]
            a3, b3 = ns[k - 1], f2s[k - 1]
        else:
            a = b = a2 = b2 = a3 = b3 = 0.0
            c = 0
        for i in range(k, j + 1):
            n = self._n[i]
            xb = self.x_lo + i * BIN
            if n > 0.0 and xb >= self.min_depth:
                x2 = xb * xb
                a += self._f[i] * xb
                b += n * x2
                a2 += self._f[i] * x2
                b2 += n * x2 * x2
                a3 += n
                b3 += self._f2[i]
                c += 1
            fx[i], nxx[i], nb[i] = a, b, c
            fxx[i], nx4[i] = a2, b2
            ns[i], f2s[i] = a3, b3
        self._built = j + 1

    def _fit(self, x: float, square: bool, scatter: bool = False
             ) -> Tuple[Optional[float], float, float]:
        """(mu or c, sigma, ramp) of `_trend`; with `scatter` and `square`: sigma (N), the
        rms scatter of the binned anchors' forces about the square law c x^2 (n - 1 degrees
        of freedom); else 0."""
        fx, nxx, nb = self._cum
        u = (x - self.margin - self.x_lo) / BIN
        if not u >= 0.0:
            return None, 0.0, 0.0
        i = int(u)
        if i >= len(nb) - 1:
            i, u = len(nb) - 1, float(len(nb) - 1)
        t = u - i if i + 1 < len(nb) else 0.0     # linear between bins: continuous in x
        j = min(i + 1, len(nb) - 1)
        if self._built <= j:
            self._extend(j)
        den = nxx[i] + t * (nxx[j] - nxx[i])
        if not den > 0.0:
            return None, 0.0, 0.0
        ramp = min(1.0, max(0.0, nb[i] + t * (nb[j] - nb[i]) - (self.min_bins - 1)))
        if not square:
            return (fx[i] + t * (fx[j] - fx[i])) / den, 0.0, ramp
        # the square law c of f = c x^2 instead of the line's mu
        fxx, nx4 = self._cum2
        sfx = fxx[i] + t * (fxx[j] - fxx[i])
        c = sfx / (nx4[i] + t * (nx4[j] - nx4[i]))
        if not scatter:
            return c, 0.0, ramp
        # the least-squares residual sum: sum f^2 - c sum f x^2
        ns, f2s = self._cum3
        rss = f2s[i] + t * (f2s[j] - f2s[i]) - c * sfx
        n = ns[i] + t * (ns[j] - ns[i])
        return c, math.sqrt(max(0.0, rss) / max(1.0, n - 1.0)), ramp

    def square_rate(self, x: float) -> Optional[float]:
        """N/m^2, the square law c of f = c x^2 (least squares through the entry) fitted to
        the same binned forces as `rate` (at least `margin` shallower than x, `min_bins`
        bins), or None: the steepest friction growth with length the drawn vessels have
        (thirteenth round of issue 12)."""
        c, ramp = self._trend(x, True)
        return c if ramp >= 1.0 else None

    def square_scatter(self, x: float) -> Optional[float]:
        """N, the rms scatter of the anchors' forces (each anchor, not the bins' means)
        about the square law `square_rate` at x, or None where there is no square law:
        the sensor noise, the cardiac and breathing disturbances and the law's misfit
        together (fourteenth round of issue 12)."""
        _, sig, ramp = self._fit(x, True, True)
        return sig if ramp >= 1.0 else None

    def square_excess(self, x: float, f: float) -> float:
        """N, the part of an inserting force f (N) at depth x (m) above the square-law
        friction c x^2 fitted to the forces met well shallower (`square_rate`; the
        steepest friction growth with length the drawn vessels have, so a lower bound of
        a wall's force; thirteenth round of issue 12) and above the band of the forces'
        disturbances, `square_band` N plus `square_sigmas` x `square_scatter` (what the
        shallow forces themselves scatter about the law is no evidence of a wall;
        fourteenth round): 0 without a trend, faded in as `share` is."""
        c, sig, ramp = self._fit(x, True, self.square_sigmas > 0.0)
        if c is None or ramp <= 0.0 or not f > 0.0:
            return 0.0
        band = self.square_band + self.square_sigmas * sig
        return ramp * max(0.0, f - max(0.0, c) * x * x - band)

    def hinge(self, min_f: float):
        """The wall (`wall_fit.Hinge`: onset, stiffness) of the binned inward forces at
        least `min_depth` deep, or None (`wall_fit.fit_hinge` with F ratio `min_f`;
        seventeenth round of issue 12). Refitted only when anchors were added since the
        last call (the renderer asks at every step of a retraction, which adds none)."""
        key = (self._count, min_f)
        if key != self._hinge_key:
            from impedance_master.wall_fit import fit_hinge
            idx = [i for i, c in enumerate(self._n)
                   if c > 0.0 and self.x_lo + i * BIN >= self.min_depth]
            self._hinge = fit_hinge([self.x_lo + i * BIN for i in idx],
                                    [self._n[i] for i in idx], [self._f[i] for i in idx],
                                    [self._v[i] for i in idx], min_f)
            self._hinge_key = key
        return self._hinge

    def rate(self, x: float) -> Optional[float]:
        """N/m, the friction trend mu at depth x (m): the least-squares slope through the
        entry of the binned forces at least `margin` shallower, or None (fewer than
        `min_bins` bins there)."""
        mu, ramp = self._trend(x)
        return mu if ramp >= 1.0 else None

    def share(self, x: float, f: float) -> float:
        """The elastic share (in [0, 1]) of an inserting force f (N) at depth x (m): 0 where
        there is no friction trend yet or f is not positive (faded in over one bin as the
        bins shallower than x - margin reach `min_bins`)."""
        if not f > 0.0:
            return 0.0
        mu, ramp = self._trend(x)
        if mu is None or ramp <= 0.0:
            return 0.0
        return ramp * min(1.0, max(0.0, 1.0 - max(0.0, mu) * max(0.0, x) / f))

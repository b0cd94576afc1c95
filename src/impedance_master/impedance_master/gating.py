"""Input gating of the identifiers: samples that cannot be physical are refused before they
touch any state (bounded influence, issue 10).

A single absurd sample (a force of 1e6 N, a position or velocity of 1e300) used to enter the
normal equations of the default identifier and poison it for good (inf in the information
matrix never decays), or leave it 'ill_conditioned' for ever. `SampleGate` refuses:

* ``range``: a position outside ``x_range`` m, a speed above ``max_speed`` m/s, an
  acceleration above ``max_accel`` m/s^2, a force above ``max_force`` N (the defaults are
  2-10x beyond what the insertion axis and the sensor can produce: stroke -20..200 mm,
  0.1 m/s, 2 m/s^2, clinical forces 0-2 N);
* ``jump``: a position more than ``max_jump`` m (plus ``max_speed`` times the time since the
  last accepted sample) from the last accepted one (a teleport, not a motion). If the new
  position persists for ``confirm`` consecutive mutually consistent samples it is accepted
  (the axis really is there: ``resync`` tells the identifier to restart its friction state
  and differentiator from it), so a gate can never lock the identifier out for ever.

`Despiker` then takes the running median of 5 samples of every channel, so one or two
outliers in a row that are physically possible (a force spike of a few newtons, a position
glitch of a millimetre) never reach the fit either.

Non-finite values are not gated here: the identifiers refuse them with a ValueError naming
the argument (the nodes check them first).
"""
from __future__ import annotations

from typing import Dict, Optional, Tuple

from catheter_common.checks import positive


class SampleGate:
    """Refuses physically impossible samples (see module doc); counts why.

    Args:
        rate: Hz, sample rate.
        x_range: (lo, hi) m accepted positions.
        max_speed: m/s; max_accel: m/s^2 (x'' is checked only when given); max_force: N.
        max_jump: m, largest position step between consecutive accepted samples (beyond the
            max_speed travel).
        confirm: consecutive consistent samples after which a jumped-to position is accepted.
    Attributes: `n_rejected` (total), `rejected` {reason: count}, `resync` (True on the
    sample that re-accepted a jumped-to position).
    """

    def __init__(self, rate: float = 1000.0, x_range: Tuple[float, float] = (-0.05, 0.5),
                 max_speed: float = 1.0, max_accel: float = 100.0, max_force: float = 20.0,
                 max_jump: float = 0.005, confirm: int = 3):
        self.dt = 1.0 / positive('rate', rate)
        lo, hi = (float(v) for v in x_range)
        if not lo < hi:
            raise ValueError(f'x_range must be (lo, hi) with lo < hi, got {x_range!r}')
        self.x_range = (lo, hi)
        self.max_speed = positive('max_speed', max_speed)
        self.max_accel = positive('max_accel', max_accel)
        self.max_force = positive('max_force', max_force)
        self.max_jump = positive('max_jump', max_jump)
        if isinstance(confirm, bool) or not isinstance(confirm, int) or confirm < 1:
            raise ValueError(f'confirm must be an int >= 1, got {confirm!r}')
        self.confirm = confirm
        self.reset()

    def reset(self) -> None:
        self._x_ok: Optional[float] = None
        self._since_ok = 0
        self._cand = []
        self.n_rejected = 0
        self.rejected: Dict[str, int] = {}
        self.resync = False

    def _refuse(self, why: str) -> str:
        self.n_rejected += 1
        self.rejected[why] = self.rejected.get(why, 0) + 1
        self._since_ok += 1
        return why

    def check(self, x: float, xd: float, xdd: Optional[float], f: float) -> Optional[str]:
        """None if the (finite) sample is acceptable, else the reason ('range' or 'jump')."""
        self.resync = False
        lo, hi = self.x_range
        if (not lo <= x <= hi or abs(xd) > self.max_speed or abs(f) > self.max_force
                or (xdd is not None and abs(xdd) > self.max_accel)):
            self._cand = []
            return self._refuse('range')
        last = self._x_ok
        if last is not None:
            allowed = self.max_jump + self.max_speed * self.dt * (self._since_ok + 1)
            if abs(x - last) > allowed:
                cand = self._cand
                if cand and abs(x - cand[-1]) > self.max_jump + self.max_speed * self.dt:
                    cand.clear()
                cand.append(x)
                if len(cand) < self.confirm:
                    return self._refuse('jump')
                self.resync = True
        self._cand = []
        self._x_ok = x
        self._since_ok = 0
        return None


class Despiker:
    """Running median of 5 on each channel of the accepted samples (x, xd, xdd, f): an
    isolated outlier, or two in a row, on any channel never reaches the fit (a median of 5
    ignores up to 2 values), while a smooth or monotone signal passes delayed by exactly 2
    samples (all channels alike, so their relations are kept). ``xdd`` may be None
    (then it stays None). `reset(sample)` refills the window with one sample (start, or a
    re-accepted jump)."""

    def __init__(self):
        self._buf = None
        self._i = 0

    def reset(self, sample=None) -> None:
        self._buf = None if sample is None else [tuple(sample)] * 5
        self._i = 0

    def __call__(self, x: float, xd: float, xdd: Optional[float], f: float):
        if self._buf is None:
            self.reset((x, xd, xdd, f))
        buf = self._buf
        i = self._i
        buf[i] = (x, xd, xdd, f)
        self._i = 0 if i == 4 else i + 1
        a, b, c, d, e = buf
        dd = (a[2], b[2], c[2], d[2], e[2])
        mdd = None if xdd is None or None in dd else sorted(dd)[2]
        return (sorted((a[0], b[0], c[0], d[0], e[0]))[2],
                sorted((a[1], b[1], c[1], d[1], e[1]))[2], mdd,
                sorted((a[3], b[3], c[3], d[3], e[3]))[2])

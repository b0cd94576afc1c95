"""The last stage of every renderer: what reaches the operator's hand (issue 10).

Invariants, whatever goes in (NaN, inf, 1e308, models that overflow):

* the output is a finite float in [-limit, limit] (a NaN can never pass the clamp: the
  clamp refuses anything that is not a finite number before comparing);
* it changes by at most max_rate * dt per call (when a slew limit is set);
* a fault (a non-finite or absurd candidate force) starts the FALLBACK: the last safe
  output is held and ramps linearly to 0 N over `fallback_time` seconds; the renderer
  leaves the fallback by itself when it has a good force again (bumpless: it takes over
  from the fallback's current value);
* `limit`, `max_rate` and `fallback_time` can be changed at any time and apply from the
  next call.

`RendererStatus` is what a node maps to diagnostics: `level` 'ok' | 'warn' | 'error',
`state`, a one-line `message`, counters and the model's age.
"""
from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field
from typing import Dict

from catheter_common.checks import Checked, nonneg, positive, positive_or_inf

#: N, a candidate force beyond this is absurd (no accepted model gives it inside the
#: renderer's state box): a fault, whatever the limit
ABSURD_FORCE = 1e3

OK, WARN, ERROR = 'ok', 'warn', 'error'
#: N/s, the slew-rate limit the nodes and the experiments use (a safety net): at 1 kHz at most
#: 0.01 N per period reaches the hand, whatever the model does (issue 12's bound)
SAFE_MAX_RATE = 10.0


@dataclass(frozen=True)
class RendererStatus:
    """Snapshot of a renderer's health (for diagnostics).

    level: 'ok', 'warn' (rendering, but on a held or refused model, or no model yet) or
    'error' (fallback active: a fault was detected); state: 'ok', 'no_model', 'held',
    'refused', 'fallback', 'bad_input'; message: one line; counters: cumulative counts
    (see the renderer's doc); model_age: s since the model in use was last received (inf:
    none); limit: N in force.
    """
    level: str
    state: str
    message: str
    counters: Dict[str, int] = field(default_factory=dict)
    model_age: float = math.inf
    limit: float = 0.0


class SafeOutput:
    """Clamp, slew limit and fallback of a renderer's output (see module doc).

    Args: limit N (> 0), max_rate N/s (inf: none), dt s (call period), fallback_time s
    (>= 0; 0: drop to 0 N at once).
    Attributes: `last` (N, the last output), `in_fallback`, `n_clamped`, `n_faults`
    (candidates refused as non-finite or absurd), `n_fallbacks` (fallbacks started).
    """

    def __init__(self, limit: float = 2.0, max_rate: float = math.inf, dt: float = 1e-3,
                 fallback_time: float = 0.5):
        self.limit = limit
        self.max_rate = max_rate
        self.dt = positive('dt', dt)
        self.fallback_time = fallback_time
        self.last = 0.0
        self.in_fallback = False
        self._hold = 0.0
        self._t_fb = 0.0
        self.n_clamped = 0
        self.n_faults = 0
        self.n_fallbacks = 0

    # runtime-settable parameters (validated; apply from the next call)
    limit = Checked(positive)
    max_rate = Checked(positive_or_inf)
    fallback_time = Checked(nonneg)

    def fault(self) -> None:
        """Start (or continue) the fallback from the last safe output."""
        if not self.in_fallback:
            self.in_fallback = True
            self.n_fallbacks += 1
            self._hold = self.last
            self._t_fb = 0.0

    def fallback_force(self) -> float:
        """The fallback's output now (N): the held force ramping to 0 over fallback_time."""
        T = self._fallback_time
        if T <= 0.0 or self._t_fb >= T:
            return 0.0
        return self._hold * (1.0 - self._t_fb / T)

    def recover(self) -> None:
        self.in_fallback = False

    def output(self, f, post=None) -> float:
        """The safe output for candidate force f (N; anything): a fault if f is not a finite
        number or absurd; then slew-limited from the last output, passed through `post`
        (a callable f -> f, e.g. a passivity controller; a non-finite result is a fault
        too) and clamped to the limit."""
        ok = isinstance(f, numbers.Real) and math.isfinite(f) and abs(f) <= ABSURD_FORCE
        if not ok:
            self.n_faults += 1
            self.fault()
        if self.in_fallback:
            f = self.fallback_force()
            self._t_fb += self.dt
        last = self.last
        rate = self._max_rate
        if rate != math.inf:
            step = rate * self.dt
            if f > last + step:
                f = last + step
            elif f < last - step:
                f = last - step
        if post is not None and not self.in_fallback:
            g = post(f)
            if isinstance(g, numbers.Real) and math.isfinite(g) and abs(g) <= ABSURD_FORCE:
                f = g
            else:
                self.n_faults += 1
                self.fault()
                f = self.fallback_force()
        lim = self._limit
        if f > lim:
            self.n_clamped += 1
            f = lim
        elif f < -lim:
            self.n_clamped += 1
            f = -lim
        self.last = float(f)
        return self.last

    def counters(self) -> Dict[str, int]:
        return {'clamped': self.n_clamped, 'faults': self.n_faults,
                'fallbacks': self.n_fallbacks}


def check_number(name: str, value) -> float:
    """float(value) or ValueError naming `name` if it is not a number at all (non-finite
    numbers pass: the renderers treat them as bad input, not as a programming error)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ValueError(f'{name} must be a number, got {value!r}')
    return float(value)


__all__ = ['SafeOutput', 'RendererStatus', 'ABSURD_FORCE', 'OK', 'WARN', 'ERROR',
           'check_number']

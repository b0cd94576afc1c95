"""The force-feedback error metric of the teleoperation experiments (no rclpy, numpy + sim_slave).

ONE definition, used by the pure closed-loop experiment (`impedance_master.experiment`) and by
the ROS graph's analysis (`catheter_bringup.analyze`):

* reference(t) at master time t = the TRUE (noise-free) vessel force that the master's own
  motion produces at the slave, time-aligned by the command delay: a twin
  `sim_slave.vessel.VesselModel` with the slave's vessel parameters and seed, driven by the
  master's trajectory (x(t), x'(t)) at time t + delay (`twin_reference`). In normal intervals
  it equals the slave's own force at t + delay up to the robot's tracking error; during an
  outage and the catch-up after it (the slave is not following the master) it is the force the
  operator's motion would have produced, which is what the feedback should convey;
* error e(t) = f(t) - reference(t) for a rendered force or the force at the hand f(t);
* outage intervals: for each link outage (start, length) the span
  [start + delay, start + length + 2 delay) in which the master's feedback is missing or stale
  (`outage_mask`); normal: the rest;
* evaluated from t_eval0 = 1.5 s + 2 delay (`default_eval_start`: time for the first model to
  be identified and delivered) unless the caller gives another start.

Times in s (relative to the experiment's first control period), positions in m, velocities in
m/s, forces in N.
"""
from __future__ import annotations

import math
from typing import Dict, Iterable, Optional, Tuple

import numpy as np

#: s, identification time before evaluation starts (plus two link delays)
EVAL_START_BASE = 1.5


def default_eval_start(delay: float) -> float:
    """Start of the evaluation in s: 1.5 s + 2 delay (first model identified and delivered)."""
    return EVAL_START_BASE + 2.0 * _delay(delay)


def _delay(delay) -> float:
    try:
        d = float(delay)
    except (TypeError, ValueError):
        raise ValueError(f'delay must be a number >= 0, got {delay!r}') from None
    if not (math.isfinite(d) and d >= 0.0):
        raise ValueError(f'delay must be finite and >= 0, got {delay!r}')
    return d


def _vec(name: str, a, n: Optional[int] = None) -> np.ndarray:
    a = np.asarray(a, dtype=float)
    if a.ndim != 1:
        raise ValueError(f'{name} must be 1-D, got shape {a.shape}')
    if n is not None and a.size != n:
        raise ValueError(f'{name} must have {n} entries, got {a.size}')
    return a


def _outages(outages) -> Tuple[Tuple[float, float], ...]:
    out = []
    for o in outages or ():
        try:
            a, b = (float(v) for v in o)
        except (TypeError, ValueError):
            raise ValueError(f'outages entries must be (start, length), got {o!r}') from None
        if not (math.isfinite(a) and math.isfinite(b)) or b < 0.0:
            raise ValueError(f'outages entry must be finite with length >= 0, got {o!r}')
        out.append((a, b))
    return tuple(out)


def outage_mask(t, outages, delay: float) -> np.ndarray:
    """Boolean mask (same shape as t) of the outage intervals [start + delay, start + length +
    2 delay) for each (start s, length s) in ``outages``."""
    t = np.asarray(t, dtype=float)
    d = _delay(delay)
    m = np.zeros(t.shape, dtype=bool)
    for start, length in _outages(outages):
        m |= (t >= start + d) & (t < start + length + 2.0 * d)
    return m


def error_stats(err) -> Dict[str, float]:
    """MAE, RMSE, max |e| (N) and count of the finite entries of ``err`` (NaN and n = 0 if none)."""
    e = np.asarray(err, dtype=float).ravel()
    e = e[np.isfinite(e)]
    if e.size == 0:
        return {'mae': float('nan'), 'rmse': float('nan'), 'max': float('nan'), 'n': 0}
    a = np.abs(e)
    return {'mae': float(a.mean()), 'rmse': float(np.sqrt(np.mean(e * e))),
            'max': float(a.max()), 'n': int(e.size)}


def twin_reference(t, x, xd, delay: float, vessel_params=None, seed: Optional[int] = 0
                   ) -> np.ndarray:
    """The reference force (N) along the master's motion.

    t (n,) s increasing, x (n,) m, xd (n,) m/s: the master's trajectory (sampled at the control
    rate, in order: the twin's friction state integrates it). A fresh
    `VesselModel(vessel_params, seed)` (the slave's parameters and seed) gives, for each k, the
    true force at time t[k] + delay for (x[k], xd[k]). Returns (n,) N.
    ``vessel_params``: a `sim_slave.vessel.VesselParams` (the phantom's structure), a
    `sim_slave.vessels.VesselSpec` (any vessel of the family) or None (the phantom).
    """
    from sim_slave.vessel import VesselModel
    from sim_slave.vessels import VesselSpec
    t = _vec('t', t)
    x = _vec('x', x, t.size)
    xd = _vec('xd', xd, t.size)
    for name, a in (('t', t), ('x', x), ('xd', xd)):
        if not np.all(np.isfinite(a)):
            raise ValueError(f'{name} must be finite')
    if t.size > 1 and np.any(np.diff(t) < 0.0):
        raise ValueError('t must be non-decreasing')
    d = _delay(delay)
    twin = (vessel_params.build(seed) if isinstance(vessel_params, VesselSpec)
            else VesselModel(vessel_params, seed=seed))
    force = twin.force
    out = np.empty(t.size)
    for k, (tk, xk, vk) in enumerate(zip(t.tolist(), x.tolist(), xd.tolist(), strict=True)):
        out[k] = force(tk + d, xk, vk)
    return out


def tracking_metrics(t, f, reference, outages, delay: float,
                     t_eval0: Optional[float] = None) -> Dict[str, Dict[str, float]]:
    """Error statistics of f - reference in normal, outage and all evaluated intervals.

    t (n,) s, f (n,) N, reference (n,) N (NaN entries are left out, e.g. samples without a
    reference); outages ((start, length), ...) s; delay s; t_eval0 s (default
    `default_eval_start(delay)`). Returns {'normal'|'outage'|'all': error_stats}.
    """
    t = _vec('t', t)
    f = _vec('f', f, t.size)
    reference = _vec('reference', reference, t.size)
    d = _delay(delay)
    t0 = default_eval_start(d) if t_eval0 is None else float(t_eval0)
    if not math.isfinite(t0):
        raise ValueError(f't_eval0 must be finite, got {t_eval0!r}')
    out_m = outage_mask(t, outages, d)
    evaluated = t >= t0
    err = f - reference
    return {'normal': error_stats(err[evaluated & ~out_m]),
            'outage': error_stats(err[evaluated & out_m]),
            'all': error_stats(err[evaluated])}


def intervals(outages: Iterable[Tuple[float, float]], delay: float):
    """The outage intervals [(a, b), ...] in s that `outage_mask` uses (for plots)."""
    d = _delay(delay)
    return [(a + d, a + b + 2.0 * d) for a, b in _outages(outages)]

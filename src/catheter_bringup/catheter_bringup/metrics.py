"""Run metrics (no rclpy, numpy only): force tracking against the slave's force, alignment of
streams, rates, periods and latencies. Times in s, forces in N.

The error statistics and the outage windows are `impedance_master.metrics`' (ONE convention
for the pure experiment and the graph's analysis: outage = [start + delay, start + length +
2 delay) on the master's clock); this module adds what only recordings need.
"""
from __future__ import annotations

import math
from typing import Dict, Iterable, Optional, Sequence, Tuple

import numpy as np

from impedance_master.metrics import error_stats, outage_mask  # noqa: F401 (re-exported)

#: The thesis's figures (Chapter 4, Experiment II: 200 ms delay, 1 s outages at 4 s and 8 s;
#: Chapter 2: ex-vivo tip force estimation), printed beside this project's.
THESIS = {
    'ima_mae': 0.046, 'ima_mae_normal': 0.052, 'ima_mae_outage': 0.041, 'ima_max': 0.074,
    'dfr_mae_normal': 0.061, 'dfr_mae_outage': 0.171, 'dfr_max': 0.374,
    'svr_mae': 0.0178, 'mlp_mae': 0.0217, 'svr_rate_hz': 917.0, 'mlp_rate_hz': 646.0,
    'identification_ms': 0.32,
}


def _arr(name, x, ndim=1):
    a = np.asarray(x, dtype=float)
    if a.ndim != ndim:
        raise ValueError(f'{name} must be {ndim}-D, got shape {a.shape}')
    if not np.all(np.isfinite(a)):
        raise ValueError(f'{name} must be finite')
    return a


def align(t_ref: Sequence[float], t_sig: Sequence[float], sig: Sequence[float],
          shift: float = 0.0) -> np.ndarray:
    """``sig`` sampled at times ``t_ref + shift`` (linear interpolation; NaN outside its span).

    t_ref (N,), t_sig (M,) increasing, sig (M,) -> (N,).
    """
    t_ref = _arr('t_ref', t_ref)
    t_sig = _arr('t_sig', t_sig)
    sig = _arr('sig', sig)
    if t_sig.shape != sig.shape:
        raise ValueError(f't_sig and sig must have one shape, got {t_sig.shape}, {sig.shape}')
    if not math.isfinite(shift):
        raise ValueError('shift must be finite')
    if len(t_sig) == 0:
        return np.full(t_ref.shape, np.nan)
    q = t_ref + shift
    out = np.interp(q, t_sig, sig)
    out[(q < t_sig[0]) | (q > t_sig[-1])] = np.nan
    return out


def force_tracking(t_master: Sequence[float], f_master: Sequence[float],
                   t_slave: Sequence[float], f_slave: Sequence[float], delay: float,
                   outages: Iterable[Tuple[float, float]] = (), t0: float = 0.0,
                   skip: float = 0.0) -> Dict[str, Dict[str, float]]:
    """Error of the force rendered at the master against the slave's force for the same motion.

    The slave executes the master's motion of time t at t + delay (one-way command delay), so
    the rendered force f_master(t) is compared with f_slave(t + delay). Intervals: for each link
    outage ``(start, length)`` (s after ``t0``) the window [start + delay, start + length +
    2 delay) in which the master's feedback is missing or stale (`outage_mask`, the
    experiment's convention), and the rest ('normal'); the first ``skip`` seconds are left out
    (start-up). Returns {'all'|'normal'|'outage': error_stats}.
    """
    tm = _arr('t_master', t_master)
    fm = _arr('f_master', f_master)
    if not (math.isfinite(delay) and delay >= 0):
        raise ValueError(f'delay must be finite and >= 0, got {delay!r}')
    fs = align(tm, t_slave, f_slave, shift=delay)
    err = fm - fs
    rel = tm - t0
    keep = rel >= skip
    out_m = outage_mask(rel, outages, delay)
    return {'all': error_stats(err[keep]), 'normal': error_stats(err[keep & ~out_m]),
            'outage': error_stats(err[keep & out_m])}


def percentiles(x: Sequence[float], qs: Sequence[float] = (50, 99)) -> Dict[str, float]:
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    if x.size == 0:
        return {f'p{q}': float('nan') for q in qs}
    return {f'p{q}': float(np.percentile(x, q)) for q in qs}


def stream_stats(t_log: Sequence[float], t_stamp: Optional[Sequence[float]] = None
                 ) -> Dict[str, float]:
    """Rate (Hz), period p50/p99/max (s) of a stream from its times; latency p50/p99 (s) =
    log time - header stamp when stamps are given."""
    t = np.asarray(t_log, dtype=float)
    out = {'count': int(t.size)}
    if t.size >= 2:
        span = t[-1] - t[0]
        out['rate_hz'] = float((t.size - 1) / span) if span > 0 else float('nan')
        d = np.diff(t)
        p = percentiles(d)
        out['period_p50'], out['period_p99'], out['period_max'] = p['p50'], p['p99'], float(d.max())
    else:
        out.update(rate_hz=float('nan'), period_p50=float('nan'), period_p99=float('nan'),
                   period_max=float('nan'))
    if t_stamp is not None and len(t_stamp) == t.size and t.size:
        lat = t - np.asarray(t_stamp, dtype=float)
        p = percentiles(lat)
        out['latency_p50'], out['latency_p99'] = p['p50'], p['p99']
    return out

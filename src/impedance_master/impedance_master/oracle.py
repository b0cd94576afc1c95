"""ORACLE renderers for the generalisation protocol (issue 12, ninth round): an ANALYSIS
tool, never a renderer of the nodes or a mode of the default.

The question it answers: is the target (the default beats DFR in 90 % of the worlds) reachable
with what the master can know? An oracle renders, at the master, the world's TRUE vessel law:
a copy of the world's `sim_slave` vessel (`VesselSpec.build(seed)`: the same parameters,
its own friction state) driven along the MASTER's present trajectory, as the metric's
reference is (`metrics.twin_reference`, the time t + delay). Kinds (`ORACLES`):

* ``'law'``: the law alone, without the disturbances (cardiac and breathing amplitudes 0,
  `law_spec`) and without sensor noise: everything a perfect identifier could know about
  the vessel;
* ``'law_anchored'``: the anchored baseline's structure with the true law instead of the
  model: the latest RECEIVED measured force plus the law's change from the slave's state
  when it was measured to the master's present state
  (f = f_meas + law(master) - law(slave at the sample)). The miss it carries is one sample's
  sensor noise and the disturbance 2 delays ago (held through an outage);
* ``'law_anchored_lp'``: as ``'law_anchored'``, the miss (f_meas - law at the slave)
  low-passed at the slave (first order, `ANCHOR_LOWPASS` s) before it is sent: the noise
  averaged out, the disturbance delayed further;
* ``'law_disturbed'``: the law WITH the world's disturbances (the reference itself): a
  sanity check, its error is the haptic device's tracking of the rendered force;
* ``'law_seen'``: the law, but only where the data could have shown it: the master's depth
  is clipped to the range of depths the slave had reached in the samples RECEIVED so far
  (its velocity is the master's): beyond the deepest point it renders the law there, flat
  (the force ahead of the data is not known); everything a perfect identifier of the
  received data could know.

Every oracle's output passes the renderers' safe output stage (`safety.SafeOutput`: clamp
to `limit`, slew limit `max_rate`, default `SAFE_MAX_RATE` as the default IMA's) and the
same haptic device, links and seeds as `experiment.run_experiment` (`run_oracles`). Where
even ``'law'`` and ``'law_anchored'`` miss the criterion, the miss is a floor of the
protocol (what is unknowable at the master: the disturbances ahead, the noise); where an
oracle wins and the default loses, the gap is in the identifier or the renderer.

Pure Python (numpy for the metrics), no rclpy.
"""
from __future__ import annotations

import math
from dataclasses import replace
from typing import Dict, Iterable, Optional

import numpy as np

from catheter_common.checks import nonneg, positive
from impedance_master.experiment import ExperimentConfig, experiment_world
from impedance_master.haptic import DeviceParams, HapticDevice
from impedance_master.metrics import tracking_metrics, twin_reference
from impedance_master.safety import SAFE_MAX_RATE, SafeOutput
from sim_slave.vessels import VesselSpec

ORACLES = ('law', 'law_anchored', 'law_anchored_lp', 'law_disturbed', 'law_seen')
#: s, time constant of the slave-side low-pass of the anchor's miss ('law_anchored_lp'),
#: the identifier's residual filter's (`Anchor.r`, 0.1 s)
ANCHOR_LOWPASS = 0.1


def law_spec(spec: VesselSpec) -> VesselSpec:
    """The same vessel without its disturbances (cardiac and breathing amplitudes 0) and
    without sensor noise: the vessel's law."""
    if not isinstance(spec, VesselSpec):
        raise ValueError(f'spec must be a sim_slave.vessels.VesselSpec, got '
                         f'{type(spec).__name__}')
    return replace(spec, params=replace(spec.params, cardiac_amplitude=0.0),
                   extras=replace(spec.extras, breathing_amplitude=0.0), noise_std=0.0)


class OracleRenderer:
    """One oracle (see the module doc): the desired force from a copy of the world's vessel
    driven along the master's trajectory.

    Args: kind (one of `ORACLES`), spec (the world's `VesselSpec`), seed (the world's: the
    disturbances' phases), delay s (the copy is evaluated at t + delay, as the reference),
    limit N, max_rate N/s, dt s (the safe output stage's).
    `set_anchor(miss)`: the latest received sample's miss (its measured force less the law
    at the slave's state then; 'law_anchored*' only use it); `see(x)`: a received sample's
    slave depth (m; 'law_seen' clips to the range seen).
    `desired_force(t, x, xd)` -> N, once per period with non-decreasing t.
    """

    def __init__(self, kind: str, spec: VesselSpec, seed: int, delay: float,
                 limit: float = 2.0, max_rate: float = SAFE_MAX_RATE, dt: float = 1e-3):
        if kind not in ORACLES:
            raise ValueError(f'kind must be one of {ORACLES}, got {kind!r}')
        if not isinstance(spec, VesselSpec):
            raise ValueError(f'spec must be a sim_slave.vessels.VesselSpec, got '
                             f'{type(spec).__name__}')
        self.kind = kind
        self.delay = nonneg('delay', delay)
        self._twin = (spec if kind == 'law_disturbed' else law_spec(spec)).build(seed)
        self._out = SafeOutput(positive('limit', limit), max_rate, dt, 0.0)
        self._anchored = kind.startswith('law_anchored')
        self._miss = 0.0
        self._seen = kind == 'law_seen'
        self.seen_lo = math.inf
        self.seen_hi = -math.inf

    def set_anchor(self, miss: float) -> None:
        """The latest received sample's miss in N: its measured force less the law at the
        slave's state then (low-passed at the slave for 'law_anchored_lp')."""
        if not (isinstance(miss, (int, float)) and math.isfinite(miss)):
            raise ValueError(f'miss must be a finite number, got {miss!r}')
        self._miss = float(miss)

    def see(self, x: float) -> None:
        """A received sample's slave depth x (m): the range seen grows to include it."""
        if not (isinstance(x, (int, float)) and math.isfinite(x)):
            raise ValueError(f'x must be a finite number, got {x!r}')
        self.seen_lo = min(self.seen_lo, float(x))
        self.seen_hi = max(self.seen_hi, float(x))

    def desired_force(self, t: float, x: float, xd: float) -> float:
        if self._seen and self.seen_lo <= self.seen_hi:
            x = min(max(x, self.seen_lo), self.seen_hi)
        f = self._twin.force(t + self.delay, x, xd)
        if self._anchored:
            f += self._miss
        return self._out.output(f)


def run_oracles(config: ExperimentConfig, kinds: Iterable[str] = ORACLES,
                max_rate: Optional[float] = None) -> Dict[str, dict]:
    """Experiment ``config`` (its world, operator, seeds, links and device; its mode and
    renderer settings are not used) with each oracle of ``kinds`` rendering at the master.
    Returns {kind: `metrics.tracking_metrics` dict} ('normal' / 'outage' / 'all'), comparable
    with `run_experiment(config).metrics` of the other modes (same seeds). max_rate N/s of the
    oracles' slew limit (None: `config.max_rate`)."""
    if not isinstance(config, ExperimentConfig):
        raise ValueError(f'config must be an ExperimentConfig, got {type(config).__name__}')
    kinds = tuple(kinds)
    for k in kinds:
        if k not in ORACLES:
            raise ValueError(f'kinds must be among {ORACLES}, got {k!r}')
    if not kinds:
        raise ValueError('kinds must name at least one oracle')
    cfg = config
    seed = cfg.seed
    dt = 1.0 / cfg.rate
    traj, n, x0, to_slave, to_master, vspec, slave = experiment_world(cfg)
    slave_law = law_spec(vspec).build(seed)      # the law along the SLAVE's path
    rate = cfg.max_rate if max_rate is None else max_rate
    oracles = [OracleRenderer(k, vspec, seed, cfg.delay, cfg.limit, rate, dt) for k in kinds]
    # every oracle its own device (a compliant hand moves with the rendered force);
    # the slave follows the first one's position
    devices = [HapticDevice(DeviceParams(), dt=dt,
                            hand_stiffness=cfg.hand_stiffness if cfg.compliant_hand else None,
                            hand_damping=cfg.hand_damping, seed=seed) for _ in kinds]
    f_des = [0.0] * len(kinds)
    xs = np.zeros((len(kinds), n))
    vs = np.zeros((len(kinds), n))
    fh = np.zeros((len(kinds), n))
    cmd = x0
    lp = math.exp(-dt / ANCHOR_LOWPASS)
    miss_lp = None
    for k in range(n):
        t = k * dt
        xh, vh, ah = traj.sample(t)
        dev = [d.step(f, xh, vh, ah) for d, f in zip(devices, f_des, strict=True)]
        to_slave.send(t, dev[0].x)
        got = to_slave.receive(t)
        if got is not None:
            cmd = got
        s = slave.step(t, cmd)
        miss = s.f_meas - slave_law.force(t, s.x, s.xd)
        miss_lp = miss if miss_lp is None else lp * miss_lp + (1.0 - lp) * miss
        to_master.send(t, (miss, miss_lp, s.x))
        pkt = to_master.receive(t)
        for i, (o, d) in enumerate(zip(oracles, dev, strict=True)):
            if pkt is not None:
                o.set_anchor(pkt[1] if o.kind == 'law_anchored_lp' else pkt[0])
                o.see(pkt[2])
            f_des[i] = o.desired_force(t, d.x, d.xd)
            xs[i, k], vs[i, k], fh[i, k] = d.x, d.xd, d.f_hand
    t = np.arange(n) * dt
    out = {}
    for i, kind in enumerate(kinds):
        ref = twin_reference(t, xs[i], vs[i], cfg.delay, vspec, seed)
        out[kind] = tracking_metrics(t, fh[i], ref, cfg.outages, cfg.delay)
    return out

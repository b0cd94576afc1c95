"""Closed-loop teleoperation experiment, pure Python at 1 kHz (thesis Ch. 4, Experiments I/II).

Per control period k (t = k dt):

1. the operator's hand (scripted) and the haptic device (motor, current loop, Eq. 36 PID)
   give the master state (x_m, x_m', x_m'') and the force at the hand;
2. the master sends its position over the master->slave link (delay, jitter, loss,
   outages, latest wins); the slave robot follows the newest delivered command (and holds
   still while nothing arrives);
3. the vessel gives the true force, the sensor the measured one; the slave's identifier
   (mode ima: `make_identifier`; ima_thesis: `SlidingWindowIdentifier`) updates;
4. the slave sends (model, measured force) over the slave->master link;
5. the master's renderer (ImaRenderer or DfrRenderer) computes the desired force for the
   next period from what has arrived and (IMA) the local trajectory.

Error metric (documented choice; implemented once in `impedance_master.metrics`, which
`catheter_bringup.analyze` uses for the ROS graph's recordings too): the reference at master time t
is the TRUE (noise-free)
vessel force that the master's motion produces at the slave, time-aligned by the command
delay: a twin VesselModel with the slave's parameters and seed is driven by the master's
trajectory at time t + delay. In normal intervals this equals the slave's own force at
t + delay up to the robot's tracking error (reported as `reference_check`); during outages,
when the slave holds still, it is the force the operator's motion would have produced. The
error is e(t) = f_hand(t) - reference(t), evaluated from t_eval0 = 1.5 s + 2 delay (time for
the first model to be identified and delivered). Outage intervals: for each outage
(start, length) the span [start + delay, start + length + 2 delay) in which the master's
feedback is missing or stale; normal: the rest.

Every mode of a comparison uses the same seeds (trajectory, links, vessel, sensor, device).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Dict, Optional, Tuple

import numpy as np

from catheter_common.checks import check_fields, finite, nonneg, positive
from impedance_master.haptic import DeviceParams, HapticDevice
from impedance_master.identification import SlidingWindowIdentifier, make_identifier
from impedance_master.metrics import (default_eval_start, error_stats, outage_mask,
                                      tracking_metrics, twin_reference)
from impedance_master.operator import OPERATORS, experiment_trajectory
from impedance_master.rendering import SAFE_MAX_RATE, DfrRenderer, ImaRenderer
from sim_slave.vessels import vessel_spec

MODES = ('ima', 'ima_thesis', 'dfr', 'anchored')
EXPERIMENT_II_OUTAGES = ((4.0, 1.0), (8.0, 1.0))


@dataclass(frozen=True)
class ExperimentConfig:
    """One closed-loop run.

    experiment: 'I' (20 s) or 'II' (12 s) scripted hand; mode: 'ima' | 'ima_thesis' | 'dfr';
    delay s, jitter s, loss probability, outages ((start s, length s), ...) of BOTH link
    directions; seed (trajectory, links, vessel, sensor, device noise); rate Hz;
    compliant_hand (spring-damper hand of hand_stiffness N/m and hand_damping N s/m around
    the script);
    impedance_rate Hz (model packets per second; the force goes at `rate`);
    limit N (renderer clamp); duration s (None: the experiment's);
    pretrain: None, or 'I' / 'II': before the run the slave's identifier learns from that
    experiment's motion on the same phantom (seed + 1000), as when Experiment II follows
    Experiment I in the thesis; the renderer starts without a model either way;
    thesis_offset: the ima_thesis identifier fits the constant term (True) or exactly the
    thesis's Eq. 29 f = m x'' + c x' + k x (False); blend_time s and max_rate N/s of the
    ImaRenderer (bumpless model switch and slew limit; 0 and inf: switch at once);
    passivity: the renderer's time-domain passivity controller;
    sensor_seed: seed of the slave's force-sensor noise (None: `seed`; sim_slave_node uses
    seed + 1, so a comparison with the ROS graph passes seed + 1 here);
    vessel: a name of `sim_slave.vessels` (default 'phantom', the project's phantom);
    vessel_params: {field: value} overrides of that vessel (VesselParams / VesselExtras
    fields, noise_std); sensor noise: the vessel's ``noise_std`` (phantom 0.01 N);
    operator: the hand's motion family, a name of `operator.OPERATORS` ('minjerk', the
    thesis's, default; 'sines'; 'human'), over the experiment's duration;
    operator_params: {name: value} keyword parameters of that family;
    anchoring, anchor_length: the ImaRenderer's (default 'local', None: its default 5 mm);
    mode 'anchored' renders 'full' at any distance (the anchored baseline);
    ident_params: {name: value} HistoryParams overrides of the default identifier;
    render_params: {name: value} further keyword arguments of the ImaRenderer (modes ima
    and ima_thesis; e.g. support_half);
    sensor_faults: ((start s, samples, value N), ...): the slave's force sensor reads
    `value` for `samples` samples from `start` (a sensor burst: an electrical glitch, a
    corrupted frame). The identifier and DFR get the faulty reading; the reference is the
    true force (twentieth round of issue 12; README, Fail-safe invariants).
    """
    experiment: str = 'II'
    mode: str = 'ima'
    delay: float = 0.2
    jitter: float = 0.0
    loss: float = 0.0
    outages: Tuple[Tuple[float, float], ...] = EXPERIMENT_II_OUTAGES
    seed: int = 0
    rate: float = 1000.0
    compliant_hand: bool = False
    hand_stiffness: float = 300.0
    hand_damping: float = 15.0
    impedance_rate: float = 1000.0
    limit: float = 2.0
    duration: Optional[float] = None
    pretrain: Optional[str] = None
    thesis_offset: bool = True
    blend_time: float = 0.05
    max_rate: float = SAFE_MAX_RATE
    passivity: bool = False
    sensor_seed: Optional[int] = None
    vessel: str = 'phantom'
    vessel_params: Tuple[Tuple[str, float], ...] = ()
    operator: str = 'minjerk'
    operator_params: Tuple[Tuple[str, object], ...] = ()
    anchoring: str = 'local'
    anchor_length: Optional[float] = None
    ident_params: Tuple[Tuple[str, object], ...] = ()
    render_params: Tuple[Tuple[str, object], ...] = ()
    sensor_faults: Tuple[Tuple[float, int, float], ...] = ()

    def __post_init__(self):
        for name in ('vessel_params', 'operator_params', 'ident_params', 'render_params'):
            v = getattr(self, name)
            if isinstance(v, dict):
                object.__setattr__(self, name, tuple(sorted(v.items())))
        vessel_spec(self.vessel, **dict(self.vessel_params))     # ValueError if bad
        if self.operator not in OPERATORS:
            raise ValueError(f'operator must be one of {tuple(OPERATORS)}, got '
                             f'{self.operator!r}')
        if self.mode not in MODES:
            raise ValueError(f'mode must be one of {MODES}, got {self.mode!r}')
        if self.experiment not in ('I', 'II'):
            raise ValueError(f"experiment must be 'I' or 'II', got {self.experiment!r}")
        check_fields(self, nonneg=('delay', 'jitter'), probability=('loss',),
                     positive=('rate', 'impedance_rate', 'limit'))
        if self.duration is not None:
            positive('duration', self.duration)
        if self.pretrain not in (None, 'I', 'II'):
            raise ValueError(f"pretrain must be None, 'I' or 'II', got {self.pretrain!r}")
        faults = []
        for i, fault in enumerate(self.sensor_faults):
            try:
                start, count, value = fault
            except (TypeError, ValueError):
                raise ValueError(f'sensor_faults[{i}] must be (start s, samples, value N), '
                                 f'got {fault!r}') from None
            if isinstance(count, bool) or not isinstance(count, int) or count < 1:
                raise ValueError(f'sensor_faults[{i}] samples must be an int >= 1, '
                                 f'got {count!r}')
            faults.append((nonneg(f'sensor_faults[{i}] start', start), count,
                           finite(f'sensor_faults[{i}] value', value)))
        object.__setattr__(self, 'sensor_faults', tuple(faults))


@dataclass
class ExperimentResult:
    """Time series (arrays of shape (n,)) and metrics of one run.

    t s; x_hand, x_master, x_slave m; f_hand N (force at the operator's hand); f_desired N
    (renderer output); reference N (see module doc); f_slave_true, f_slave_meas N (the
    slave's forces at t); outage bool (in an outage interval); evaluated bool.
    metrics: {'normal': {...}, 'outage': {...}, 'all': {...}} with mae, rmse, max (N), n;
    plus 'reference_check' (|reference(t) - f_slave_true(t + delay)| in normal intervals),
    'max_reference' N, 'id_status' counts, 'renderer' counters.
    """
    config: ExperimentConfig
    series: Dict[str, np.ndarray]
    metrics: Dict[str, object] = field(default_factory=dict)


def experiment_world(cfg: ExperimentConfig):
    """The world of experiment ``cfg``, built from its seed as every run of it builds it:
    (operator trajectory, number of periods n, start position x0 m, the link to the slave,
    the link to the master, the vessel spec, the slave simulation). One place, so that
    `run_experiment` and the oracles (`impedance_master.oracle`) meet the same world."""
    from sim_slave.link import Link, LinkConfig
    from sim_slave.robot import SlaveRobot
    from sim_slave.slave import SlaveSimulation

    seed = cfg.seed
    traj = experiment_trajectory(cfg.experiment, seed=seed, operator=cfg.operator,
                                 **dict(cfg.operator_params))
    n = int(round((cfg.duration or traj.duration) * cfg.rate))
    x0 = traj.sample(0.0)[0]
    link_cfg = LinkConfig(delay=cfg.delay, jitter=cfg.jitter, loss=cfg.loss,
                          outages=tuple(cfg.outages))
    to_slave = Link(link_cfg, seed=2 * seed + 1)
    to_master = Link(link_cfg, seed=2 * seed + 2)
    vspec = vessel_spec(cfg.vessel, **dict(cfg.vessel_params))
    slave = SlaveSimulation(vessel=vspec.build(seed),
                            sensor=vspec.sensor(seed if cfg.sensor_seed is None
                                                else cfg.sensor_seed),
                            robot=SlaveRobot(rate=cfg.rate, x0=x0))
    return traj, n, x0, to_slave, to_master, vspec, slave


def run_experiment(config: Optional[ExperimentConfig] = None, **overrides) -> ExperimentResult:
    """Run one closed-loop experiment (see module doc); keyword overrides patch `config`."""
    cfg = config or ExperimentConfig()
    if overrides:
        cfg = replace(cfg, **overrides)
    seed = cfg.seed
    dt = 1.0 / cfg.rate
    traj, n, x0, to_slave, to_master, vspec, slave = experiment_world(cfg)
    device = HapticDevice(DeviceParams(), dt=dt,
                          hand_stiffness=cfg.hand_stiffness if cfg.compliant_hand else None,
                          hand_damping=cfg.hand_damping,
                          seed=seed)
    ident = None
    if cfg.mode in ('ima', 'anchored'):
        ident = make_identifier(window=1.0, rate=cfg.rate, **dict(cfg.ident_params))
    elif cfg.mode == 'ima_thesis':
        ident = SlidingWindowIdentifier(window=1.0, rate=cfg.rate, offset=cfg.thesis_offset)
    if ident is not None and cfg.pretrain is not None:
        pretrain_identifier(ident, cfg.pretrain, seed + 1000, cfg.rate)
    if cfg.mode == 'dfr':
        renderer = DfrRenderer(limit=cfg.limit)
    else:
        renderer = ImaRenderer(limit=cfg.limit, dt=dt, blend_time=cfg.blend_time,
                               max_rate=cfg.max_rate, passivity=cfg.passivity,
                               anchoring='full' if cfg.mode == 'anchored' else cfg.anchoring,
                               anchor_length=(math.inf if cfg.mode == 'anchored'
                                              else cfg.anchor_length),
                               **({} if cfg.mode == 'anchored' else dict(cfg.render_params)))
    imp_every = max(1, int(round(cfg.rate / cfg.impedance_rate)))

    keys = ('t', 'x_hand', 'x_master', 'xd_master', 'x_slave', 'f_hand', 'f_desired', 'reference',
            'f_slave_true', 'f_slave_meas')
    S = {k: np.zeros(n) for k in keys}
    id_status: Dict[str, int] = {}
    cmd = x0
    f_des = 0.0
    imp = None
    ima = cfg.mode != 'dfr'
    delay = cfg.delay
    faulty = {}
    for start, count, value in cfg.sensor_faults:
        k0 = int(round(start * cfg.rate))
        faulty.update((k, value) for k in range(k0, k0 + count))
    for k in range(n):
        t = k * dt
        xh, vh, ah = traj.sample(t)
        dev = device.step(f_des, xh, vh, ah)
        to_slave.send(t, dev.x)
        got = to_slave.receive(t)
        if got is not None:
            cmd = got
        s = slave.step(t, cmd)
        if k in faulty:
            s = s._replace(f_meas=faulty[k])
        if ident is not None:
            out = ident.update(s.x, s.xd, s.xdd, s.f_meas)
            if out is not None:
                imp = out
            id_status[ident.status] = id_status.get(ident.status, 0) + 1
        to_master.send(t, (imp if (k % imp_every == 0) else None, s.f_meas))
        pkt = to_master.receive(t)
        if pkt is not None:
            if ima:
                if pkt[0] is not None:
                    renderer.set_impedance(pkt[0])
            else:
                renderer.set_force(pkt[1])
        f_des = (renderer.desired_force(dev.x, dev.xd, dev.xdd) if ima
                 else renderer.desired_force())
        S['t'][k] = t
        S['x_hand'][k] = xh
        S['x_master'][k] = dev.x
        S['xd_master'][k] = dev.xd
        S['x_slave'][k] = s.x
        S['f_hand'][k] = dev.f_hand
        S['f_desired'][k] = f_des
        S['f_slave_true'][k] = s.f_true
        S['f_slave_meas'][k] = s.f_meas

    t = S['t']
    # the reference: a twin vessel (the slave's parameters and seed) along the master's motion
    S['reference'] = twin_reference(t, S['x_master'], S['xd_master'], delay, vspec, seed)
    out_m = outage_mask(t, cfg.outages, delay)
    evaluated = t >= default_eval_start(delay)
    S['outage'] = out_m
    S['evaluated'] = evaluated
    metrics: Dict[str, object] = dict(tracking_metrics(t, S['f_hand'], S['reference'],
                                                       cfg.outages, delay))
    metrics['max_reference'] = float(np.abs(S['reference']).max())
    # reference check: twin (master motion, t + delay) vs the slave's own true force at t + delay
    d = int(round(delay * cfg.rate))
    if d < n:
        chk = S['reference'][:n - d] - S['f_slave_true'][d:]
        sel = (evaluated & ~out_m)[:n - d]
        metrics['reference_check'] = error_stats(chk[sel])
    metrics['id_status'] = id_status
    if ima:
        metrics['renderer'] = {'switches': renderer.n_switches, 'ignored': renderer.n_ignored,
                               'pre_anchors': renderer.n_pre_anchors,
                               'clamped': renderer.n_clamped,
                               'passivity_steps': renderer.n_passivity}
    else:
        metrics['renderer'] = {'updates': renderer.n_updates, 'clamped': renderer.n_clamped}
    metrics['link'] = {'to_slave': to_slave.stats.as_dict(),
                       'to_master': to_master.stats.as_dict()}
    return ExperimentResult(cfg, S, metrics)


def pretrain_identifier(ident, experiment: str, seed: int, rate: float = 1000.0) -> None:
    """Feed `ident` the slave data of a scripted experiment on the default phantom (no link)."""
    from sim_slave.robot import SlaveRobot
    from sim_slave.sensor import ForceSensor
    from sim_slave.slave import SlaveSimulation
    from sim_slave.vessel import VesselModel, VesselParams

    traj = experiment_trajectory(experiment, seed=seed)
    slave = SlaveSimulation(vessel=VesselModel(VesselParams(), seed=seed),
                            sensor=ForceSensor(noise_std=0.01, seed=seed),
                            robot=SlaveRobot(rate=rate, x0=traj.sample(0.0)[0]))
    for k in range(int(round(traj.duration * rate))):
        t = k / rate
        s = slave.step(t, traj.sample(t)[0])
        ident.update(s.x, s.xd, s.xdd, s.f_meas)


def compare_modes(modes=MODES, **config) -> Dict[str, ExperimentResult]:
    """Run the same configuration (same seeds) for each mode."""
    return {m: run_experiment(ExperimentConfig(mode=m, **config)) for m in modes}

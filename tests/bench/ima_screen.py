"""Screening tool of issue 12's rounds: record the slave side of Experiment II once per
world, then replay renderer variants against the recording (not a benchmark: `scripts/bench`
runs bench_*.py only).

Why a replay is exact: the operator's hand is rigid in the generalisation protocol
(`ExperimentConfig.compliant_hand` False), so the master's motion is the script's and does
not depend on the rendered force; the slave, the identifier and both links therefore see
the same inputs whatever the master renders. `record` runs that side once (the identifier
with the given `HistoryParams` overrides) and stores, per world, every packet the master
receives (the master's step, the model, the measured force) and the reference;
`replay` rebuilds the haptic device and the renderer (mode 'ima' with renderer keyword
arguments, 'anchored', 'dfr') and feeds them the recorded packets. The result is the same
`CaseResult` that `generalisation.run_case` gives (`tests/impedance_master/
test_ima_screen.py` checks it on one world per mode), in about a third of the time.

Usage (from the repository root, after `. scripts/env.sh`):

    python tests/bench/ima_screen.py record DIR [--ident JSON] [--sets f1,f2,...] [--jobs N]
    python tests/bench/ima_screen.py replay DIR MODE OUT.pkl [--render JSON] [--sets ...]
    python tests/bench/ima_screen.py score DFR.pkl ANCHORED.pkl RESULT.pkl [...]
    python tests/bench/ima_screen.py replay DIR ima OUT.pkl --oracle deep[,first_out,visited]
        [--oracle-everywhere]

`--oracle` (eighteenth round) bounds what a better renderer could gain where: in the named
classes of the master's state (`sample_class`: 'deep', deeper than the slave's data;
'first_out', moving outward deeper than the slave ever moved outward; 'visited', the rest)
the replay renders the reference itself, during the outage intervals of the error metric
only (everywhere with `--oracle-everywhere`). It is a bound, not a renderer: the reference
is the future the master cannot know.

Sets are the seen fresh sets by name (f1 = FRESH_SEEDS 100-104, f2 = 200-204, ..., f10 =
1000-1004); the default is every set seen by the sixteenth round (f1-f6, f9, f10: 720
worlds). Never list a held-out set that has not been run blind.
On 2 cores: recording 720 worlds about 7 min, a replay of them 1.5 min (dfr) to 3.5 min
(ima).
"""
from __future__ import annotations

import argparse
import collections
import json
import math
import os
import pathlib
import pickle
import sys
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[2]
for pkg in ('impedance_master', 'sim_slave', 'catheter_common'):
    p = str(ROOT / 'src' / pkg)
    if p not in sys.path:
        sys.path.insert(0, p)

import impedance_master.generalisation as G  # noqa: E402
from impedance_master.experiment import ExperimentConfig, experiment_world  # noqa: E402
from impedance_master.generalisation import beats_dfr, case_result, drawn_cases  # noqa: E402
from impedance_master.haptic import DeviceParams, HapticDevice  # noqa: E402
from impedance_master.identification import make_identifier  # noqa: E402
from impedance_master.metrics import outage_mask, tracking_metrics, twin_reference  # noqa: E402
from impedance_master.operator import experiment_trajectory  # noqa: E402
from impedance_master.rendering import DfrRenderer, ImaRenderer  # noqa: E402

SETS = {'f1': G.FRESH_SEEDS, 'f2': G.FRESH2_SEEDS, 'f3': G.FRESH3_SEEDS,
        'f4': G.FRESH4_SEEDS, 'f5': G.FRESH5_SEEDS, 'f6': G.FRESH6_SEEDS,
        'f7': G.FRESH7_SEEDS, 'f8': G.FRESH8_SEEDS, 'f9': G.FRESH9_SEEDS,
        'f10': G.FRESH10_SEEDS, 'f11': G.FRESH11_SEEDS}
#: the sets the sixteenth and seventeenth rounds screened on (seen; f11, run blind in the
#: seventeenth, is seen and may be named; f7 and f8 were run blind but never
#: recorded for screening, kept so for comparability with the rounds before)
SEEN = 'f1,f2,f3,f4,f5,f6,f9,f10'
REPLAY_MODES = ('ima', 'anchored', 'dfr')
#: classes of the master's state for `--oracle` (`sample_class`)
ORACLE_CLASSES = ('deep', 'first_out', 'visited')
#: m, how far beyond the slave's deepest anchor a state counts as unseen
ORACLE_MARGIN = 1e-3


def sample_class(x: float, xd: float, deepest_in: float, deepest_out: float,
                 margin: float = ORACLE_MARGIN) -> str:
    """Where the master's state (x m, xd m/s) is against the slave's data so far (the
    deepest anchor moving inward, `deepest_in`, and outward, `deepest_out`, m; -inf if
    none): 'deep' more than `margin` deeper than the deepest inward one (the model
    extrapolates in depth), 'first_out' moving outward more than `margin` deeper than the
    deepest outward one (the friction's reversal there is unseen), 'visited' otherwise."""
    if x > deepest_in + margin:
        return 'deep'
    if xd < 0.0 and x > deepest_out + margin:
        return 'first_out'
    return 'visited'


class SlaveReach:
    """The slave's deepest anchors so far, moving inward and outward (m; -inf before any),
    from the models the master received; `of(x, xd)` the `sample_class` of a master state."""

    def __init__(self):
        self.deepest_in = -math.inf
        self.deepest_out = -math.inf

    def add(self, anchor) -> None:
        """Count a model's `Anchor` (None, or at rest: nothing)."""
        if anchor is None or anchor.xd == 0.0:
            return
        if anchor.xd > 0.0:
            self.deepest_in = max(self.deepest_in, anchor.x)
        else:
            self.deepest_out = max(self.deepest_out, anchor.x)

    def of(self, x: float, xd: float) -> str:
        return sample_class(x, xd, self.deepest_in, self.deepest_out)


def _oracle_classes(oracle, mode: str) -> frozenset:
    """The set of oracle classes, checked (known names; mode 'ima', whose models carry the
    anchors that `sample_class` needs)."""
    names = frozenset(oracle)
    bad = sorted(names - set(ORACLE_CLASSES))
    if bad:
        raise ValueError(f'unknown oracle class {bad[0]!r}; known: {", ".join(ORACLE_CLASSES)}')
    if names and mode != 'ima':
        raise ValueError(f'an oracle needs mode ima, got {mode!r}')
    return names


def worlds(sets: str = SEEN):
    """The drawn worlds (vessel, operator, seed, vessel_params) of comma-separated set names."""
    out = []
    for name in sets.split(','):
        if name not in SETS:
            raise ValueError(f'unknown set {name!r}; known: {", ".join(SETS)}')
        out += drawn_cases(SETS[name])
    return out


def key(world) -> str:
    return f'{world[0]}_{world[1]}_{world[2]}'


def _config(world) -> ExperimentConfig:
    v, op, s, params = world
    return ExperimentConfig(vessel=v, operator=op, seed=s, vessel_params=params)


def record(world, ident_params=None) -> dict:
    """Run the slave side of one world's Experiment II; returns the recording: 'n' steps,
    'arrivals' [(master step, model or None, measured force N)], 'reference' (n,) N."""
    cfg = _config(world)
    if cfg.compliant_hand:
        raise ValueError('a replay needs the rigid hand')
    traj, n, x0, to_slave, to_master, vspec, slave = experiment_world(cfg)
    dt = 1.0 / cfg.rate
    ident = make_identifier(window=1.0, rate=cfg.rate, **(ident_params or {}))
    x = np.zeros(n)
    xd = np.zeros(n)
    arrivals = []
    cmd, imp = x0, None
    for k in range(n):
        t = k * dt
        xh, vh, _ = traj.sample(t)
        to_slave.send(t, xh)          # the rigid hand: the device is at the script's state
        got = to_slave.receive(t)
        if got is not None:
            cmd = got
        s = slave.step(t, cmd)
        out = ident.update(s.x, s.xd, s.xdd, s.f_meas)
        if out is not None:
            imp = out
        to_master.send(t, (imp, s.f_meas))
        pkt = to_master.receive(t)
        if pkt is not None:
            arrivals.append((k, pkt[0], pkt[1]))
        x[k], xd[k] = xh, vh
    ref = twin_reference(np.arange(n) * dt, x, xd, cfg.delay, vspec, cfg.seed)
    return {'world': world, 'n': n, 'arrivals': arrivals, 'reference': ref}


def replay(world, rec: dict, mode: str, render_params=None, oracle=(),
           oracle_everywhere: bool = False):
    """The `CaseResult` of one mode ('ima' with `render_params`, 'anchored', 'dfr') on a
    recording, built as `run_experiment` builds it. `oracle`: classes (`ORACLE_CLASSES`)
    of the master's state in which the reference is rendered instead, in the outage
    intervals of the metric (everywhere if `oracle_everywhere`): a bound, see the module
    doc."""
    if mode not in REPLAY_MODES:
        raise ValueError(f'mode must be one of {REPLAY_MODES}, got {mode!r}')
    oracle = _oracle_classes(oracle, mode)
    cfg = _config(world)
    traj = experiment_trajectory(cfg.experiment, seed=cfg.seed, operator=cfg.operator)
    n, dt = rec['n'], 1.0 / cfg.rate
    device = HapticDevice(DeviceParams(), dt=dt, hand_stiffness=None, seed=cfg.seed)
    if mode == 'dfr':
        r = DfrRenderer(limit=cfg.limit)
    else:
        anchored = mode == 'anchored'
        r = ImaRenderer(limit=cfg.limit, dt=dt, blend_time=cfg.blend_time,
                        max_rate=cfg.max_rate, passivity=cfg.passivity,
                        anchoring='full' if anchored else cfg.anchoring,
                        anchor_length=math.inf if anchored else cfg.anchor_length,
                        **({} if anchored else (render_params or {})))
    arr, i, na = rec['arrivals'], 0, len(rec['arrivals'])
    t = np.arange(n) * dt
    ref = rec['reference']
    where = (np.ones(n, dtype=bool) if oracle_everywhere
             else outage_mask(t, cfg.outages, cfg.delay))
    reach = SlaveReach()
    f_hand = np.zeros(n)
    f_des = 0.0
    for k in range(n):
        xh, vh, ah = traj.sample(k * dt)
        dev = device.step(f_des, xh, vh, ah)
        while i < na and arr[i][0] == k:
            _, imp, f = arr[i]
            i += 1
            if mode == 'dfr':
                r.set_force(f)
            elif imp is not None:
                r.set_impedance(imp)
                reach.add(imp.anchor)
        f_des = r.desired_force() if mode == 'dfr' else r.desired_force(dev.x, dev.xd, dev.xdd)
        if oracle and where[k] and reach.of(dev.x, dev.xd) in oracle:
            f_des = float(ref[k])
        f_hand[k] = dev.f_hand
    return case_result(tracking_metrics(t, f_hand, ref, cfg.outages, cfg.delay))


def _record_job(args):
    world, ident, d = args
    path = os.path.join(d, key(world) + '.pkl')
    if not os.path.exists(path):
        with open(path, 'wb') as fh:
            pickle.dump(record(world, ident), fh, protocol=pickle.HIGHEST_PROTOCOL)
    return key(world)


def _replay_job(args):
    world, d, mode, render, oracle, everywhere = args
    with open(os.path.join(d, key(world) + '.pkl'), 'rb') as fh:
        rec = pickle.load(fh)
    return key(world), replay(world, rec, mode, render, oracle, everywhere)


def score(dfr: dict, anchored: dict, result: dict) -> str:
    """One line: worlds beating DFR, no worse than the anchored baseline (all-interval MAE),
    the averages' ratios to DFR (normal / outage / max), the misses per vessel."""
    ks = sorted(result)
    beat = [beats_dfr(result[k], dfr[k]) for k in ks]
    no_worse = sum(result[k].all <= anchored[k].all for k in ks)

    def ratio(field):
        return (np.mean([getattr(result[k], field) for k in ks])
                / np.mean([getattr(dfr[k], field) for k in ks]))
    miss = collections.Counter(k.rsplit('_', 2)[0] for k, b in zip(ks, beat, strict=True)
                               if not b)
    return (f'n={len(ks)} beat {sum(beat)} <=anchored {no_worse} ratios '
            f'{ratio("normal"):.4f}/{ratio("outage"):.4f}/{ratio("max"):.4f} mean '
            f'{np.mean([result[k].all for k in ks]):.5f} misses {dict(sorted(miss.items()))}')


def main(argv=None):
    from multiprocessing import Pool
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    sub = ap.add_subparsers(dest='cmd', required=True)
    a = sub.add_parser('record')
    a.add_argument('dir')
    a.add_argument('--ident', default='{}', help='HistoryParams overrides, JSON')
    b = sub.add_parser('replay')
    b.add_argument('dir')
    b.add_argument('mode', choices=REPLAY_MODES)
    b.add_argument('out')
    b.add_argument('--render', default='{}', help='ImaRenderer keyword arguments, JSON')
    b.add_argument('--oracle', default='',
                   help=f'render the reference in these classes ({",".join(ORACLE_CLASSES)})')
    b.add_argument('--oracle-everywhere', action='store_true',
                   help='the oracle in every interval, not the outages only')
    for p in (a, b):
        p.add_argument('--sets', default=SEEN)
        p.add_argument('--jobs', type=int, default=2)
    c = sub.add_parser('score')
    c.add_argument('dfr')
    c.add_argument('anchored')
    c.add_argument('results', nargs='+')
    args = ap.parse_args(argv)
    t0 = time.time()
    if args.cmd == 'score':
        def load(path):
            with open(path, 'rb') as fh:
                return pickle.load(fh)
        dfr, anc = load(args.dfr), load(args.anchored)
        for path in args.results:
            print(f'{path}: {score(dfr, anc, load(path))}')
        return 0
    todo = worlds(args.sets)
    if args.cmd == 'record':
        os.makedirs(args.dir, exist_ok=True)
        ident = json.loads(args.ident)
        with Pool(args.jobs) as pool:
            for _ in pool.imap_unordered(_record_job, [(w, ident, args.dir) for w in todo],
                                         chunksize=4):
                pass
    else:
        render = json.loads(args.render)
        try:
            oracle = _oracle_classes((c for c in args.oracle.split(',') if c), args.mode)
        except ValueError as e:
            ap.error(str(e))
        jobs = [(w, args.dir, args.mode, render, oracle, args.oracle_everywhere) for w in todo]
        with Pool(args.jobs) as pool:
            res = dict(pool.imap_unordered(_replay_job, jobs, chunksize=4))
        with open(args.out, 'wb') as fh:
            pickle.dump(res, fh)
    print(f'{args.cmd}: {len(todo)} worlds, {time.time() - t0:.0f} s', file=sys.stderr)
    return 0


if __name__ == '__main__':
    sys.exit(main())

"""Fuzz benchmark of the haptic path's core (issue 10): `scripts/bench ima` runs it after
bench_ima.py; alone: `python tests/bench/bench_ima_fuzz.py [--n 100000]`.

In-process, deterministic (numpy generator, seed 0), no ROS: the node-level fuzz suite is
the nodes' engineer's. Per input stream:

* ImaRenderer (mode ima as the node builds it, passivity on) and DfrRenderer: >= n
  generated operations (master states, models, slave forces, limit changes) drawn from
  good values, extreme finite values (+-1e308, 1e300), NaN and inf, absurd models;
  counted: inputs sent, refused (models refused or ignored, bad master states, forces
  refused), non-finite outputs (target 0), outputs above the limit in force (target 0),
  crashes (any exception; target 0);
* the default identifier (make_identifier): >= n samples of Experiment II slave data on
  the phantom, and of a smooth_coulomb x human world where it selects the stateless
  friction law (issue 12, round 15), with 5 % of them corrupted on one channel (range
  from the absurd to the plausible); counted: samples sent, refused (gated; non-finite
  values raise the documented ValueError and are counted as refused), non-finite model
  values (target 0), models outside the envelope (target 0), crashes (target 0), samples
  after which the latest model is the stateless law;
* the identifier's worst deviation after a single outlier (or a short burst) from the
  clean run's model at three probe states, and the recovery times (after which it stays
  below 5 mN and below 1 mN; inf: not within the 12 s run);
* what reaches the operator's hand after force-sensor bursts at the slave (5 N, 1-20
  samples, at 3, 6 and 9 s of Experiment II, `ExperimentConfig.sensor_faults`): the
  largest change of the hand force from the clean run and the last time it exceeds 5 mN,
  for the default IMA, the IMA without the identifier's burst hold (burst_samples 0, the
  nineteenth round) and DFR.
"""
from __future__ import annotations

import argparse
import math
import pathlib
import sys
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[2]
for pkg in ('impedance_master', 'sim_slave', 'catheter_common'):
    p = str(ROOT / 'src' / pkg)
    if p not in sys.path:
        sys.path.insert(0, p)

from impedance_master.envelope import DEFAULT_ENVELOPE  # noqa: E402
from impedance_master.experiment import ExperimentConfig, run_experiment  # noqa: E402
from impedance_master.identification import make_identifier  # noqa: E402
from impedance_master.impedance import Impedance  # noqa: E402
from impedance_master.rendering import DfrRenderer, ImaRenderer  # noqa: E402

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / 'impedance_master'))
from streams import phantom_samples  # noqa: E402

sys.path.pop(0)

EXTREME = np.array([1e308, -1e308, 1.7e308, -1.7e308, 1e300, -1e300, 5e-324, 1e6, -1e6,
                    math.nan, math.inf, -math.inf])
PROBES = ((0.02, 0.02, 0.0), (0.035, -0.02, 0.0), (0.05, 0.01, 0.0))


def value(rng, good):
    """A good value 80 % of the time, else an extreme one or a random huge magnitude."""
    u = rng.random()
    if u < 0.8:
        return good
    if u < 0.92:
        return float(rng.choice(EXTREME))
    return float(rng.normal() * 10.0 ** rng.uniform(-3, 300))


def random_model(rng, good):
    u = rng.random()
    try:
        if u < 0.5:
            return good
        if u < 0.75:
            return Impedance(*(value(rng, v) for v in (0.001, 2.0, 3.0, 0.02)))
        n = 17
        t = [value(rng, 0.01) for _ in range(4)]
        return good.copy(S=[t[0]] * n, F=[t[1]] * n, B=[t[2]] * n, C=[t[3]] * n,
                         m=value(rng, 0.0), k=value(rng, 0.0))
    except ValueError:
        return None             # the constructor refused it (non-finite): not offered


def fuzz_renderers(n, seed=0):
    rng = np.random.default_rng(seed)
    good = Impedance(0.001, 0.1, 1.0, 0.01, x0=0.0, dx=0.005, S=[0.0] * 17,
                     F=[0.005 * i for i in range(17)], B=[0.002] * 17, C=[0.1] * 17)
    rows = []
    for name in ('ImaRenderer', 'DfrRenderer'):
        ren = (ImaRenderer(limit=2.0, blend_time=0.05, max_rate=20.0, passivity=True)
               if name == 'ImaRenderer' else DfrRenderer(limit=2.0))
        sent = refused = nonfinite = over = crashes = 0
        limit = 2.0
        x = 0.03
        for _ in range(n):
            u = rng.random()
            sent += 1
            try:
                if u < 0.02:
                    limit = float(rng.uniform(0.05, 3.0))
                    ren.limit = limit
                    continue
                if u < 0.12:
                    if name == 'ImaRenderer':
                        imp = random_model(rng, good)
                        if imp is None or not ren.set_impedance(imp):
                            refused += 1
                    elif not ren.set_force(value(rng, float(rng.normal(0.2, 0.1)))):
                        refused += 1
                    continue
                x = min(max(x + float(rng.normal(0.0, 1e-4)), 0.005), 0.06)
                state = (value(rng, x), value(rng, float(rng.normal(0, 0.02))),
                         value(rng, float(rng.normal(0, 0.2))))
                before = getattr(ren, 'n_bad_input', 0)
                f = ren.desired_force(*state)
                refused += getattr(ren, 'n_bad_input', 0) - before
                if not (isinstance(f, float) and math.isfinite(f)):
                    nonfinite += 1
                elif abs(f) > limit:
                    over += 1
            except Exception:   # noqa: BLE001 - counting crashes is the point
                crashes += 1
        rows.append((name, sent, refused, nonfinite, over, crashes))
    return rows


def stateless_samples():
    """The identifier's inputs in a world whose friction is stateless (smooth_coulomb x
    human 302, drawn as the generalisation protocol draws it), where the default selects
    the stateless law (sigma 0) once the slave has retracted (issue 12, round 15)."""
    from impedance_master.generalisation import drawn_cases
    from streams import experiment_inputs
    v, op, s, params = [c for c in drawn_cases((302,))
                        if c[:2] == ('smooth_coulomb', 'human')][0]
    return experiment_inputs(vessel=v, operator=op, seed=s, vessel_params=params)


def fuzz_identifier(n, seed=0, clean=None):
    """(sent, refused, non-finite models, models outside the envelope, crashes, samples
    after which the latest model is the stateless law) over n inputs: `clean` (default:
    the phantom's Experiment II samples) repeated, 5 % corrupted on one channel."""
    rng = np.random.default_rng(seed)
    clean = phantom_samples() if clean is None else clean
    ident = make_identifier()
    sent = refused = nonfinite = outside = crashes = stateless = 0
    for i in range(n):
        s = list(clean[i % len(clean)])
        if i and i % len(clean) == 0:
            ident = make_identifier()          # a new run on the same data
        if rng.random() < 0.05:
            ch = int(rng.integers(0, 4))
            s[ch] = value(rng, s[ch]) if rng.random() < 0.5 else s[ch] + float(
                rng.normal() * [0.01, 0.2, 5.0, 2.0][ch])
        sent += 1
        before = ident.n_rejected
        try:
            out = ident.update(*s)
        except ValueError:
            refused += 1
            continue
        except Exception:       # noqa: BLE001
            crashes += 1
            continue
        refused += ident.n_rejected - before
        if out is not None:
            stateless += out.sigma == 0.0
            if not all(math.isfinite(v) for v in out.to_fields().values()):
                nonfinite += 1
            elif out.valid and not DEFAULT_ENVELOPE.accepts(out):
                outside += 1
    return sent, refused, nonfinite, outside, crashes, stateless


def outlier_deviation():
    """Worst deviation (N) from the clean run's model after one corrupted sample (or a
    burst), and the times (s) after which it stays below 5 mN (the sensor noise's order)
    and below 1 mN (inf: not within the rest of the 12 s run)."""
    clean = phantom_samples()
    ref = make_identifier()
    ref_models = [ref.update(*s) for s in clean]
    kinds = [('force 1e6 N', 3, 1e6, 1), ('force 5 N', 3, 5.0, 1), ('force 5 N x2', 3, 5.0, 2),
             ('force 5 N x5', 3, 5.0, 5), ('force 5 N x10', 3, 5.0, 10),
             ('force 5 N x20', 3, 5.0, 20), ('position 1e300', 0, 1e300, 1),
             ('position +2 cm', 0, 0.02, 1), ('velocity 1e300', 1, 1e300, 1),
             ('velocity 0.5 m/s', 1, 0.5, 1), ('acceleration 50 m/s^2', 2, 50.0, 1)]
    rows = []
    for label, ch, val, burst in kinds:
        worst, rec5, rec1 = 0.0, 0.0, 0.0
        for at in (3000, 6000, 9000):
            ident = make_identifier()
            last5 = last1 = None
            for i, s in enumerate(clean):
                if at <= i < at + burst:
                    s = list(s)
                    s[ch] = s[ch] + val if label.startswith('position +') else val
                out = ident.update(*s)
                r = ref_models[i]
                if i >= at and out is not None and r is not None:
                    d = max(abs(out.force(*p) - r.force(*p)) for p in PROBES)
                    worst = max(worst, d)
                    if d >= 5e-3:
                        last5 = i
                    if d >= 1e-3:
                        last1 = i
            end = len(clean) - 1
            for last, key in ((last5, 5), (last1, 1)):
                t = 0.0 if last is None else (math.inf if last == end
                                              else (last + 1 - at) / 1000.0)
                if key == 5:
                    rec5 = max(rec5, t)
                else:
                    rec1 = max(rec1, t)
        rows.append((label, worst, rec5, rec1))
    return rows


def burst_at_hand(lengths=(1, 3, 5, 10, 20), value=5.0):
    """[(label, burst samples, largest |change of the hand force| N, last time s it is
    above 5 mN or None)] for bursts of `value` N at 3, 6 and 9 s (Experiment II seed 0)."""
    variants = (('IMA default', 'ima', ()), ('IMA, no burst hold', 'ima', (('burst_samples', 0),)),
                ('DFR', 'dfr', ()))
    rows = []
    for label, mode, ident in variants:
        clean = run_experiment(ExperimentConfig(mode=mode, ident_params=ident))
        for n in lengths:
            r = run_experiment(ExperimentConfig(
                mode=mode, ident_params=ident,
                sensor_faults=tuple((t, n, value) for t in (3.0, 6.0, 9.0))))
            d = np.abs(r.series['f_hand'] - clean.series['f_hand'])
            above = np.nonzero(d > 5e-3)[0]
            rows.append((label, n, float(d.max()),
                         float(r.series['t'][above[-1]]) if above.size else None))
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--n', type=int, default=100_000, help='inputs per stream')
    a = ap.parse_args(argv)
    t0 = time.perf_counter()
    print(f'# bench_ima_fuzz: {a.n} generated inputs per stream, seed 0, in-process core')
    print('\n## Renderers (ImaRenderer as the node builds it in mode ima, DfrRenderer)')
    print(f'{"stream":<14} {"sent":>8} {"refused":>8} {"non-finite out":>14} '
          f'{"over limit":>10} {"crashes":>8}   (targets: 0, 0, 0)')
    for row in fuzz_renderers(a.n):
        print(f'{row[0]:<14} {row[1]:8d} {row[2]:8d} {row[3]:14d} {row[4]:10d} {row[5]:8d}')
    print('\n## Default identifier (5 % of samples corrupted): Experiment II phantom data; '
          'smooth_coulomb x human 302 data (the stateless law selected)')
    print(f'{"data":<16} {"sent":>8} {"refused":>8} {"non-finite model":>16} '
          f'{"outside envelope":>16} {"crashes":>8} {"stateless":>9}   (targets: 0, 0, 0)')
    for name, clean in (('phantom', None), ('smooth_coulomb', stateless_samples())):
        s = fuzz_identifier(a.n, clean=clean)
        print(f'{name:<16} {s[0]:8d} {s[1]:8d} {s[2]:16d} {s[3]:16d} {s[4]:8d} {s[5]:9d}')
    print('\n## Identifier: worst deviation of the published model after an outlier (at 3, 6, '
          '9 s; probes at 20/35/50 mm) and the time until it stays below 1 mN')
    print(f'{"outlier":<24} {"worst deviation N":>17} {"< 5 mN after s":>15} '
          f'{"< 1 mN after s":>15}')
    for label, worst, rec5, rec1 in outlier_deviation():
        print(f'{label:<24} {worst:17.5f} {rec5:15.3f} {rec1:15.3f}')
    print('\n## At the hand: force-sensor bursts of 5 N at the slave at 3, 6 and 9 s '
          '(Experiment II seed 0), change of the hand force from the clean run')
    print(f'{"renderer":<20} {"samples":>7} {"largest change N":>16} {"last > 5 mN at s":>17}')
    for label, n, worst, last in burst_at_hand():
        print(f'{label:<20} {n:7d} {worst:16.4f} '
              f'{"-" if last is None else format(last, ".3f"):>17}')
    print(f'\n(total {time.perf_counter() - t0:.0f} s)')


if __name__ == '__main__':
    main()

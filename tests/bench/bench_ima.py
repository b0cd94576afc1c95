"""Benchmark of impedance matching (thesis Ch. 4): `scripts/bench ima`.

Closed-loop runs of the pure-Python experiment (impedance_master.experiment) at 1 kHz with
the same seeds for every mode: default IMA (`make_identifier` + bumpless ImaRenderer), the
thesis IMA (SlidingWindowIdentifier, linear model) and DFR (last received force).

Error = force at the operator's hand - reference, the reference being the true vessel force
for the master's motion time-aligned by the command delay (see experiment.py); normal and
outage intervals ([start + d, start + length + 2 d)); evaluated from 1.5 s + 2 d.

Tables: Experiment I; Experiment II (cold start, and after Experiment I on the same phantom);
compliant hand; the delay x loss sweep; behaviour at model switches and at rest;
identification time per sample, and its per-sample distribution against the pre-rework
re-fit (issue 15). Thesis numbers beside.
Options: --seeds N (default 3), --quick (1 seed, fewer sweep cells), --timing-only (the
identification timing sections alone).
"""
from __future__ import annotations

import argparse
import os
import pathlib
import sys
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[2]
for pkg in ('impedance_master', 'sim_slave', 'catheter_common'):
    p = str(ROOT / 'src' / pkg)
    if p not in sys.path:
        sys.path.insert(0, p)

from impedance_master.experiment import (ExperimentConfig,  # noqa: E402
                                         run_experiment)
from impedance_master.identification import (SlidingWindowIdentifier,  # noqa: E402
                                             make_identifier)

MODES = ('ima', 'ima_thesis', 'dfr')      # the generalisation protocol adds 'anchored'
LABEL = {'ima': 'IMA default', 'ima_thesis': 'IMA thesis', 'dfr': 'DFR'}
THESIS = {  # thesis Ch. 4 (Experiment II unless noted), N
    ('ima', 'normal'): 0.052, ('ima', 'outage'): 0.041, ('ima', 'max'): 0.074,
    ('dfr', 'normal'): 0.061, ('dfr', 'outage'): 0.171, ('dfr', 'max'): 0.374,
    ('ima', 'exp1'): 0.046,
}


def runs(seeds, **cfg):
    """{mode: [ExperimentResult per seed]}"""
    return {m: [run_experiment(ExperimentConfig(mode=m, seed=s, **cfg)) for s in seeds]
            for m in MODES}


def agg(results, part):
    """Mean MAE, mean RMSE, worst max over seeds of one interval kind."""
    ms = [r.metrics[part] for r in results if r.metrics[part]['n'] > 0]
    if not ms:
        return float('nan'), float('nan'), float('nan')
    return (float(np.mean([m['mae'] for m in ms])), float(np.mean([m['rmse'] for m in ms])),
            float(np.max([m['max'] for m in ms])))


def ratio(a, b):
    return f'{a / b:6.2f}' if b and np.isfinite(a) and np.isfinite(b) else '     -'


def table_modes(title, res, outages=True):
    print(f'\n## {title}')
    print(f'{"mode":<12} {"interval":<8} {"MAE N":>8} {"RMSE N":>8} {"max N":>8} | '
          f'{"ref (thesis)":>12} {"ratio":>6} | {"DFR same run":>12} {"ratio":>6}')
    for m in MODES:
        for part in (('normal', 'outage') if outages else ('normal',)):
            mae, rmse, mx = agg(res[m], part)
            th = THESIS.get((m if m != 'ima_thesis' else 'ima', part)) if outages else (
                THESIS[('ima', 'exp1')] if m != 'dfr' else None)
            dmae = agg(res['dfr'], part)[0]
            print(f'{LABEL[m]:<12} {part:<8} {mae:8.4f} {rmse:8.4f} {mx:8.4f} | '
                  f'{(f"{th:.3f}" if th else "-"):>12} {ratio(mae, th) if th else "     -"} | '
                  f'{dmae:12.4f} {ratio(mae, dmae)}')
    if outages:
        for m in ('ima', 'dfr'):
            mx = max(agg(res[m], 'normal')[2], agg(res[m], 'outage')[2])
            th = THESIS[(m, 'max')]
            print(f'{LABEL[m]:<12} max over both intervals {mx:.4f} N (thesis {th:.3f} N, '
                  f'ratio {mx / th:.2f})')


def switch_and_rest(res, resw):
    print('\n## Model switches and rest (Experiment II, seed 0; rest = |x_m\'| < 1 mm/s)')
    print(f'{"mode":<30} {"largest step of f_d per ms N":>29} {"rest MAE N":>11} '
          f'{"rest max N":>11} {"rest samples":>13}')
    raw = run_experiment(ExperimentConfig(mode='ima', seed=0, blend_time=0.0,
                                          max_rate=float('inf')))
    rows = [(LABEL[m] + ' (cold)', res[m][0]) for m in MODES]
    rows.append(('IMA default, no bumpless/slew', raw))
    rows.append(('IMA default (after Exp. I)', resw['ima'][0]))
    for label, r in rows:
        s = r.series
        ev = s['evaluated']
        step = np.abs(np.diff(s['f_desired']))[ev[1:]].max()
        vel = np.gradient(s['x_master'], s['t'])
        rest = ev & (np.abs(vel) < 1e-3)
        e = np.abs(s['f_hand'] - s['reference'])[rest]
        print(f'{label:<30} {step:29.4f} {e.mean():11.4f} {e.max():11.4f} {rest.sum():13d}')
    ren = res['ima'][0].metrics
    print(f'IMA default: {ren["renderer"]["switches"]} model switches delivered, identifier '
          f'status counts {ren["id_status"]}')
    for m in ('ima', 'ima_thesis'):
        rs = [run_experiment(ExperimentConfig(mode=m, seed=r.config.seed, passivity=True))
              for r in res[m]]
        n, o = agg(rs, 'normal'), agg(rs, 'outage')
        print(f'{LABEL[m]} with the passivity controller (TDPA): normal {n[0]:.4f}, outage '
              f'{o[0]:.4f}, max {max(n[2], o[2]):.4f} N; damping active in '
              f'{sum(r.metrics["renderer"]["passivity_steps"] for r in rs)} steps')


def where_max(results, delay=0.2, margin=1e-3):
    """Diagnostics: where the largest error of each seed and interval happens, and why it can
    happen there (the master's state against what the slave's data covered 2 delays earlier:
    the deepest inserted length so far, and whether the master has reversed at this depth
    before, i.e. whether the slave data can separate static force from friction there)."""
    print('\n## Where the largest errors are (IMA default, Experiment II cold; slave data seen '
          'by the master lag 2 delays)')
    print(f'{"seed":>4} {"interval":<8} {"t s":>6} {"error N":>8} {"f_hand N":>9} {"ref N":>7} '
          f'{"x_m mm":>7} {"v_m mm/s":>9} {"deepest data mm":>16} {"since 1st retract s":>20}')
    for r in results:
        s = r.series
        t, xm, vm, xs = s['t'], s['x_master'], s['xd_master'], s['x_slave']
        err = s['f_hand'] - s['reference']
        lag = int(round(2 * delay / (t[1] - t[0])))
        retract = np.flatnonzero(vm < -1e-3)
        t_retract = t[retract[0]] if retract.size else float('nan')
        for part, sel in (('normal', s['evaluated'] & ~s['outage']),
                          ('outage', s['evaluated'] & s['outage'])):
            idx = np.flatnonzero(sel)
            if not idx.size:
                continue
            k = idx[np.argmax(np.abs(err[idx]))]
            deepest = xs[:max(k - lag, 1)].max()
            print(f'{r.config.seed:4d} {part:<8} {t[k]:6.3f} {err[k]:+8.4f} {s["f_hand"][k]:9.4f} '
                  f'{s["reference"][k]:7.4f} {xm[k] * 1e3:7.2f} {vm[k] * 1e3:9.1f} '
                  f'{deepest * 1e3:16.2f} {t[k] - t_retract:20.3f}'
                  + ('  (never visited)' if xm[k] > deepest + margin else ''))


def visited(res_by_label, delay=0.2, margin=1e-3):
    """Error where the master goes where the slave's last second did not go, and where the
    slave has never been (as seen from the master: slave data are >= 2 delays old)."""
    print('\n## Where the master goes (Experiment II, all seeds): error by what the slave had '
          'visited 2 delays earlier')
    print(f'{"mode":<30} {"outside last 1 s MAE/max":>25} {"never visited MAE/max":>22} '
          f'{"elsewhere MAE/max":>18} {"samples (out 1 s, never)":>25}')
    for label, results in res_by_label:
        e1, e2, e3 = [], [], []
        for r in results:
            s = r.series
            lag = int(round(2 * delay * 1000))
            xs, xm = s['x_slave'], s['x_master']
            run_lo = np.minimum.accumulate(xs)
            run_hi = np.maximum.accumulate(xs)
            err = np.abs(s['f_hand'] - s['reference'])
            for k in np.flatnonzero(s['evaluated']):
                j = k - lag
                if j < 1000:
                    continue
                w = xs[j - 1000:j]
                out1 = xm[k] < w.min() - margin or xm[k] > w.max() + margin
                never = xm[k] < run_lo[j] - margin or xm[k] > run_hi[j] + margin
                (e2 if never else e1 if out1 else e3).append(err[k])
        def f(e):
            return f'{np.mean(e):.4f}/{np.max(e):.4f}' if e else '-'
        print(f'{label:<30} {f(e1):>25} {f(e2):>22} {f(e3):>18} {len(e1):>14d} {len(e2):>10d}')


def sweep(seeds, delays, losses):
    """The delay x loss table; returns {(delay, loss): {mode: (normal, outage)}} mean MAE."""
    print('\n## Delay x loss sweep (Experiment II motion, outages at 4 s and 8 s; mean MAE / '
          'worst max over seeds, N)')
    table = {}
    print(f'{"delay ms":>8} {"loss %":>6} | ' + ' | '.join(
        f'{LABEL[m]:^27}' for m in MODES) + ' | IMA/DFR MAE normal, outage')
    print(f'{"":>8} {"":>6} | ' + ' | '.join(f'{"normal":^13} {"outage":^13}' for _ in MODES)
          + ' |')
    worse = 0
    for d in delays:
        for lo in losses:
            res = runs(seeds, experiment='II', delay=d, loss=lo)
            cells = []
            vals = {}
            for m in MODES:
                n = agg(res[m], 'normal')
                o = agg(res[m], 'outage')
                vals[m] = (n, o)
                cells.append(f'{n[0]:.3f}/{n[2]:.3f} {o[0]:.3f}/{o[2]:.3f}')
            table[(d, lo)] = {m: (vals[m][0][0], vals[m][1][0]) for m in MODES}
            rn = vals['ima'][0][0] / vals['dfr'][0][0]
            ro = vals['ima'][1][0] / vals['dfr'][1][0]
            worse += (rn >= 1) + (ro >= 1)
            print(f'{d * 1e3:8.0f} {lo * 100:6.0f} | ' + ' | '.join(f'{c:^27}' for c in cells)
                  + f' | {rn:.2f}, {ro:.2f}')
    print(f'cells where the default IMA is not below DFR: {worse} '
          f'(of {2 * len(delays) * len(losses)})')
    return table


def sweep_figure(table, path):
    """MAE against delay, one line per mode and loss, normal and outage panels (PNG)."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    delays = sorted({d for d, _ in table})
    losses = sorted({lo for _, lo in table})
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2), sharey=False)
    styles = {'ima': '-', 'ima_thesis': ':', 'dfr': '--'}
    for ax, k, title in ((axes[0], 0, 'normal intervals'), (axes[1], 1, 'outage intervals')):
        for m in MODES:
            for j, lo in enumerate(losses):
                ys = [table[(d, lo)][m][k] for d in delays]
                ax.plot([d * 1e3 for d in delays], ys, styles[m], marker='o', ms=3,
                        color=f'C{j}', label=f'{LABEL[m]}, loss {lo * 100:.0f} %')
        ax.set_xlabel('one-way delay (ms)')
        ax.set_ylabel('MAE (N)')
        ax.set_yscale('log')
        ax.set_title(f'Experiment II, {title}')
        ax.grid(True, which='both', alpha=0.3)
    axes[1].legend(fontsize=7, ncol=1, loc='upper left', bbox_to_anchor=(1.02, 1.0))
    fig.tight_layout()
    pathlib.Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    print(f'(figure: {path})')


def _same_models(data, new_cls, ref_cls):
    """(models, selections, largest relative difference of any model number) of the two
    identifiers fed the same samples; AssertionError if they ever differ in kind (one has a
    model, the other none; status, selection, solve count)."""
    def numbers(m):
        return np.array([m.m, m.c, m.k, m.offset, m.sigma, *m.S, *m.F, *m.B, *m.C,
                         *(m.anchor or ())])
    a, b = new_cls(), ref_cls()
    n, worst, last = 0, 0.0, None
    for i, smp in enumerate(data):
        ma, mb = a.update(*smp), b.update(*smp)
        assert (ma is None) == (mb is None) and (a.status, a.selected, a.n_solves) == \
            (b.status, b.selected, b.n_solves), f'sample {i}'
        if mb is None or not mb.valid or mb is last:
            continue
        last = mb
        n += 1
        x, y = numbers(ma), numbers(mb)
        worst = max(worst, float(np.max(np.abs(x - y) / np.maximum(np.abs(y), 1e-3))))
    return n, b.n_selections, worst


def refit_tail(rounds=5):
    """Issue 15: the per-sample cost distribution of the default identifier against the
    pre-rework re-fit (tests/impedance_master/history_reference.py, main before issue 15's
    rework) on the same inputs, alternated in this run; ratio = this / reference."""
    import gc
    sys.path.insert(0, str(ROOT / 'tests' / 'impedance_master'))
    try:
        from history_reference import BatchHistoryIdentifier
        from streams import experiment_inputs
    finally:
        sys.path.pop(0)
    from impedance_master.generalisation import drawn_cases
    from impedance_master.history import HistoryIdentifier
    worlds = [c for c in drawn_cases((300,))
              if c[:2] in (('soft', 'human'), ('stribeck_kv', 'sines'), ('stiff_wall', 'minjerk'))]
    streams = [(f'Exp. II seed {s}', experiment_inputs(experiment='II', seed=s))
               for s in (0, 1, 2)]
    streams += [(f'{v} x {op} {seed}', experiment_inputs(
        experiment='II', vessel=v, operator=op, seed=seed, vessel_params=vp))
        for v, op, seed, vp in worlds]
    print('\n## Identification: the published models against the pre-rework re-fit (issue 15)')
    print(f'{"stream (12 s, closed loop)":<34} {"models":>6} {"selections":>10} '
          f'{"max |this - ref| / max(|ref|, 1e-3)":>36}')
    for label, data in streams:
        n, sel, worst = _same_models(data, HistoryIdentifier, BatchHistoryIdentifier)
        print(f'{label:<34} {n:6d} {sel:>10} {worst:36.1e}')
    pc = time.perf_counter
    qs = (50, 90, 99, 99.9)
    print(f'\n## Identification per-sample cost: the re-fit tail (issue 15), {rounds} rounds '
          f'alternated, us per update() (load average at start {os.getloadavg()[0]:.1f})')
    print(f'{"stream, identifier":<52} {"p50":>6} {"p90":>6} {"p99":>7} {"p99.9":>7} '
          f'{"max":>7} {"mean":>6}')
    for label, data in streams:
        per = {'this': [], 'ref': []}
        for _ in range(rounds):
            for key, cls in (('this', HistoryIdentifier), ('ref', BatchHistoryIdentifier)):
                ident = cls()
                t = np.empty(len(data))
                gc.collect()
                for i, smp in enumerate(data):
                    t0 = pc()
                    ident.update(*smp)
                    t[i] = pc() - t0
                per[key].append(t * 1e6)
        rows = {}
        for key in per:
            # per statistic the median over the rounds (one round's preemptions do not rule)
            stats = [[np.percentile(t, q) for q in qs] + [t.max(), t.mean()] for t in per[key]]
            rows[key] = np.median(np.array(stats), axis=0)
        for key, name in (('this', 'default (this checkout)'),
                          ('ref', 'reference: pre-rework re-fit')):
            print(f'{label + ", " + name:<52} ' + ' '.join(
                f'{v:{w}.1f}' for v, w in zip(rows[key], (6, 6, 7, 7, 7, 6), strict=True)))
        print(f'{label + ", ratio this / reference":<52} ' + ' '.join(
            f'{a / b:{w}.2f}' for a, b, w in zip(rows['this'], rows['ref'],
                                                (6, 6, 7, 7, 7, 6), strict=True)))
    print('(per statistic the median over the rounds; p99.9 is the 12th largest of 12 000 '
          'samples, max the largest: both hold the machine\'s preemptions too)')


def timing():
    print('\n## Identification time per sample (Experiment II slave data, 12 000 samples)')
    from impedance_master.experiment import pretrain_identifier  # noqa: F401
    from impedance_master.operator import experiment_trajectory
    from sim_slave.slave import SlaveSimulation
    from sim_slave.robot import SlaveRobot
    traj = experiment_trajectory('II', seed=0)
    sl = SlaveSimulation(robot=SlaveRobot(x0=traj.sample(0.0)[0]))
    data = []
    for k in range(12000):
        s = sl.step(k * 1e-3, traj.sample(k * 1e-3)[0])
        data.append((s.x, s.xd, s.xdd, s.f_meas))

    def measure(ident, reps=5):
        """(best-of-reps amortised us per sample of the whole loop, per-sample times of the
        best repetition). The amortised figure includes the periodic re-summations/solves;
        the per-sample percentiles show their spread (and the shared machine's noise)."""
        best_total, best_per = None, None
        pc = time.perf_counter
        for _ in range(reps):
            ident.reset()
            t0 = pc()
            for smp in data:
                ident.update(*smp)
            total = (pc() - t0) / len(data)
            if best_total is None or total < best_total:
                best_total = total
        for _ in range(2):
            ident.reset()
            per = np.empty(len(data))
            for i, smp in enumerate(data):
                t0 = pc()
                ident.update(*smp)
                per[i] = pc() - t0
            if best_per is None or np.median(per) < np.median(best_per):
                best_per = per
        return best_total, best_per

    # reference measured in the same run: Eq. 34 solved naively over the full window per sample
    X = np.array([[d[2], d[1], d[0]] for d in data])
    f = np.array([d[3] for d in data])
    n_ref = 2000
    ref_us = float('inf')
    for _ in range(3):
        t0 = time.perf_counter()
        for i in range(1000, 1000 + n_ref):
            np.linalg.lstsq(X[i - 1000:i], f[i - 1000:i], rcond=None)
        ref_us = min(ref_us, (time.perf_counter() - t0) / n_ref * 1e6)
    print(f'{"identifier":<34} {"amortised us":>12} {"median":>7} {"p99":>7} {"max":>8} | '
          f'{"ref us":>7} {"ratio":>6} | thesis 320 us/solve, target <= 30 us')
    for name, ident in (('default (make_identifier)', make_identifier()),
                        ('thesis (SlidingWindowIdentifier)', SlidingWindowIdentifier())):
        amort, per = measure(ident)
        amort *= 1e6
        per = per * 1e6
        print(f'{name:<34} {amort:12.2f} {np.median(per):7.2f} '
              f'{np.percentile(per, 99):7.2f} {per.max():8.1f} | {ref_us:7.2f} '
              f'{amort / ref_us:6.3f} | {amort / 320:.3f} of thesis')
    print('(ref: numpy lstsq of Eq. 34 over the 1000-sample window, per sample, same run)')


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--seeds', type=int, default=3)
    ap.add_argument('--quick', action='store_true')
    ap.add_argument('--timing-only', action='store_true')
    a = ap.parse_args(argv)
    if a.timing_only:
        timing()
        refit_tail(rounds=3 if a.quick else 5)
        return
    seeds = list(range(1 if a.quick else a.seeds))
    t_start = time.perf_counter()
    print(f'# bench_ima: seeds {seeds}; error vs the true vessel force along the master motion '
          f'(t + delay); machine shared, timings noisy')
    res1 = runs(seeds, experiment='I', outages=())
    table_modes('Experiment I (20 s, 200 ms delay, no outages)', res1, outages=False)
    res2 = runs(seeds, experiment='II')
    table_modes('Experiment II (12 s, 200 ms delay, 1 s outages at 4 s and 8 s), cold start',
                res2)
    res2w = runs(seeds, experiment='II', pretrain='I')
    table_modes('Experiment II after Experiment I on the same phantom (identifier keeps its '
                'history)', res2w)
    eq29 = [run_experiment(ExperimentConfig(mode='ima_thesis', seed=s, thesis_offset=False))
            for s in seeds]
    mae_n, _, mx_n = agg(eq29, 'normal')
    mae_o, _, mx_o = agg(eq29, 'outage')
    print(f'IMA thesis without offset (Eq. 29 exactly): normal {mae_n:.4f} (max {mx_n:.4f}), '
          f'outage {mae_o:.4f} (max {mx_o:.4f}) N')
    resc = runs(seeds, experiment='II', compliant_hand=True)
    table_modes('Experiment II, compliant hand (300 N/m, 15 N s/m)', resc)
    switch_and_rest(res2, res2w)
    where_max(res2['ima'])
    visited([('IMA default (cold)', res2['ima']), ('IMA thesis (cold)', res2['ima_thesis']),
             ('DFR', res2['dfr']), ('IMA default (after Exp. I)', res2w['ima'])])
    if a.quick:
        table = sweep(seeds, (0.0, 0.2, 1.0), (0.0, 0.3))
    else:
        table = sweep(seeds, (0.0, 0.05, 0.2, 0.5, 1.0), (0.0, 0.1, 0.3))
    sweep_figure(table, ROOT / 'out' / 'bench' / 'ima_delay_loss.png')
    timing()
    refit_tail(rounds=3 if a.quick else 5)
    print(f'\n(total {time.perf_counter() - t_start:.0f} s)')


if __name__ == '__main__':
    main()

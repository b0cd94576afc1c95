"""Generalisation benchmark of impedance matching (issue 12): `scripts/bench ima` runs it
after bench_ima.py; alone: `python tests/bench/bench_ima_general.py [--section dev|fresh]`.

Protocol (impedance_master.generalisation): the default identifier and renderer were tuned
on ONE family, the project's phantom with the thesis's minimum-jerk operator; other vessel
x operator combinations are reported here, cold start, Experiment II timing, for the
default IMA, the thesis IMA, DFR and the anchored baseline. Two sections:

* ``dev``: every family's own vessel x every operator x the seeds 10, 11, 12 (the tuning
  family shown but not counted). These were the first round's held-out seeds; the second
  round looked at them while developing: they are a development set now.
* ``fresh``: the fresh held-out worlds (`drawn_cases(FRESH_SEEDS)`): a randomised physical
  draw of every vessel family for every operator and seeds 100-104, 90 worlds, run once
  after the second round's design was final (seen during the third round's development).
* ``fresh2``: the third round's held-out worlds (`drawn_cases(FRESH2_SEEDS)`, seeds
  200-204, the same families and operators, 90 worlds), committed before the third
  round's design work and run once, after its design was final. Not part of ``all``
  (run it explicitly: ``--section fresh2``). Seen during the fourth round's development.
* ``fresh3``: the fourth round's held-out worlds (`drawn_cases(FRESH3_SEEDS)`, seeds
  300-304, the same families and operators, 90 worlds), committed before the fourth
  round's design work and run once, after its design was final. Not part of ``all``.
  Seen during the fifth round's development.
* ``fresh4``: the fifth round's held-out worlds (`drawn_cases(FRESH4_SEEDS)`, seeds
  400-404, the same families and operators, 90 worlds), committed before the fifth
  round's design work and run once, after its design was final. Not part of ``all``.
  Seen from the sixth round on.
* ``fresh5``: the sixth round's held-out worlds (`drawn_cases(FRESH5_SEEDS)`, seeds
  500-504, the same families and operators, 90 worlds), committed before the sixth
  round's design work and run once, after its design was final. Not part of ``all``.
  Seen from the seventh round on.
* ``fresh6``: the seventh round's held-out worlds (`drawn_cases(FRESH6_SEEDS)`, seeds
  600-604, the same families and operators, 90 worlds), committed during the sixth round
  before its blind run, and run once, after the seventh round's design was final. Not
  part of ``all``. Seen from the eighth round on.
* ``fresh7``: the eighth round's held-out worlds (`drawn_cases(FRESH7_SEEDS)`, seeds
  700-704, the same families and operators, 90 worlds), committed during the seventh round
  before its blind run of fresh6, and run once, after the eighth round's design was final.
  Not part of ``all``. Seen from the ninth round on.
* ``fresh8``: the ninth round's held-out worlds (`drawn_cases(FRESH8_SEEDS)`, seeds
  800-804, the same families and operators, 90 worlds), committed during the eighth round
  before its blind run of fresh7, to be run once after a round's design is final (the
  ninth round kept no change and did not run it; run once after the eleventh round's
  design). Not part of ``all``.
* ``fresh9``: the next held-out worlds (`drawn_cases(FRESH9_SEEDS)`, seeds 900-904, the
  same families and operators, 90 worlds), committed during the eleventh round before its
  blind run of fresh8, and run once, after the fourteenth round's design was final. Not
  part of ``all``.
* ``fresh10``: the next held-out worlds (`drawn_cases(FRESH10_SEEDS)`, seeds 1000-1004, the
  same families and operators, 90 worlds), committed during the fourteenth round before its
  blind run of fresh9, and run once, after the fifteenth round's design was final. Not part
  of ``all``.
* ``fresh11``: the next held-out worlds (`drawn_cases(FRESH11_SEEDS)`, seeds 1100-1104, the
  same families and operators, 90 worlds), committed during the fifteenth round before its
  blind run of fresh10, to be run once after a later round's design is final. Not part of
  ``all``.
* ``fresh12``: the next held-out worlds (`drawn_cases(FRESH12_SEEDS)`, seeds 1200-1204, the
  same families and operators, 90 worlds), committed during the seventeenth round before
  its blind run of fresh11, to be run once after a later round's design is final. Not part
  of ``all``.
* ``fresh13``: the thirteenth held-out worlds (`drawn_cases(FRESH13_SEEDS)`, seeds
  1300-1304, the same families and operators, 90 worlds), committed during the nineteenth
  round before its blind run of fresh12, and run once in the twenty-second round. Not part
  of ``all``.
* ``fresh14``: the next held-out worlds (`drawn_cases(FRESH14_SEEDS)`, seeds 1400-1404, the
  same families and operators, 90 worlds), committed during the twenty-second round after
  its blind run of fresh13, to be run once after a later round's design is final. Not part
  of ``all``.

Tables per section: every case (MAE normal / outage / max, N); per vessel and per operator;
the count of cases where the default beats DFR (normal MAE < DFR's, outage MAE < DFR's /
2, max < DFR's) and where its mean error ('all' intervals) is no worse than the anchored
baseline's; the averages over cases with the ratios to DFR.
Options: --section dev|fresh|fresh2|...|fresh14|all (fresh2 to fresh14: the held-out sets)
(default all = dev and fresh), --quick (one seed), --jobs N (cases run in N processes;
default 1), --oracle (ninth round: also run the ORACLE renderers of
`impedance_master.oracle` on every case, the world's true vessel law at the master, and
print per vessel x operator how many worlds each beats DFR in beside the default: where
the oracles miss, the miss is a floor of the protocol; where they win and the default
loses, the gap is the identifier's or the renderer's).
"""
from __future__ import annotations

import argparse
import pathlib
import sys
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[2]
for pkg in ('impedance_master', 'sim_slave', 'catheter_common'):
    p = str(ROOT / 'src' / pkg)
    if p not in sys.path:
        sys.path.insert(0, p)

from impedance_master.generalisation import (DEVELOPMENT_SEEDS, FRESH2_SEEDS,  # noqa: E402
                                             FRESH3_SEEDS, FRESH4_SEEDS, FRESH5_SEEDS, FRESH6_SEEDS,
                                             FRESH7_SEEDS, FRESH8_SEEDS, FRESH9_SEEDS,
                                             FRESH10_SEEDS, FRESH11_SEEDS, FRESH12_SEEDS,
                                             FRESH13_SEEDS, FRESH14_SEEDS,
                                             FRESH_SEEDS,
                                             MODES,
                                             TUNING,
                                             beats_dfr, case_result, cases, drawn_cases,
                                             run_case)
from impedance_master.experiment import ExperimentConfig  # noqa: E402
from impedance_master.oracle import ORACLES, run_oracles  # noqa: E402

LABEL = {'ima': 'IMA default', 'ima_thesis': 'IMA thesis', 'dfr': 'DFR',
         'anchored': 'anchored'}


def fmt(r):
    return f'{r.normal:.3f}/{r.outage:.3f}/{r.max:.3f}'


def _run(case):
    v, op, s, params = case
    return run_case(v, op, s, vessel_params=params)


def _run_oracle(case):
    """The modes of `_run` and the oracles' results ({kind: CaseResult}) under 'oracle'."""
    v, op, s, params = case
    out = _run(case)
    out['oracle'] = {k: case_result(m) for k, m in run_oracles(ExperimentConfig(
        vessel=v, operator=op, seed=s, vessel_params=params)).items()}
    return out


def run_all(todo, jobs, oracle=False):
    fn = _run_oracle if oracle else _run
    if jobs <= 1:
        return [fn(c) for c in todo]
    from concurrent.futures import ProcessPoolExecutor
    with ProcessPoolExecutor(jobs) as ex:
        return list(ex.map(fn, todo, chunksize=1))


def oracle_report(title, todo, results):
    """Per vessel x operator: in how many worlds the default, each oracle and the law or
    the law anchored (either) beat DFR; 'gap': the default misses where the law or the
    law anchored wins; 'floor': both oracles miss too."""
    cols = ('default',) + ORACLES + ('law or anchored', 'gap', 'floor')
    print(f'\n## {title}: the ORACLES (impedance_master.oracle, the true vessel law at the '
          'master), worlds that beat DFR by the criterion')
    print(f'{"vessel x operator":<26} {"n":>3} | ' + ' | '.join(f'{c:>15}' for c in cols))
    groups, tot = {}, {}
    for c, r in zip(todo, results, strict=True):
        d = r['dfr']
        w = {'default': beats_dfr(r['ima'], d)}
        w.update({k: beats_dfr(r['oracle'][k], d) for k in ORACLES})
        w['law or anchored'] = w['law'] or w['law_anchored']
        w['gap'] = w['law or anchored'] and not w['default']
        w['floor'] = not (w['law or anchored'] or w['default'])
        g = groups.setdefault(f'{c[0]} x {c[1]}', {})
        for k, v in w.items():
            g[k] = g.get(k, 0) + int(v)
            tot[k] = tot.get(k, 0) + int(v)
        g['n'] = g.get('n', 0) + 1
        tot['n'] = tot.get('n', 0) + 1
    for name in sorted(groups):
        g = groups[name]
        print(f'{name:<26} {g["n"]:>3} | ' + ' | '.join(f'{g.get(k, 0):>15}' for k in cols))
    print(f'{"all":<26} {tot["n"]:>3} | ' + ' | '.join(f'{tot.get(k, 0):>15}' for k in cols),
          flush=True)


def report(title, todo, results, counted):
    """Print the tables of one section. todo: (vessel, operator, seed, params) cases;
    counted(case) -> whether the case counts (held out)."""
    res = dict(zip(todo, results, strict=True))
    print(f'\n## {title}: every case, MAE normal / MAE outage / max |e| (N); beats DFR = '
          'normal < DFR, outage < DFR/2, max < DFR; <= anchored = all-interval MAE no worse')
    print(f'{"vessel":<15} {"operator":<8} {"seed":>4} | ' + ' | '.join(
        f'{LABEL[m]:^17}' for m in MODES) + ' | beats DFR | <= anchored')
    held = []
    for c in todo:
        r = res[c]
        win = beats_dfr(r['ima'], r['dfr'])
        anch = r['ima'].all <= r['anchored'].all
        if counted(c):
            held.append((c, win, anch))
        print(f'{c[0]:<15} {c[1]:<8} {c[2]:>4} | ' + ' | '.join(f'{fmt(r[m]):^17}' for m in MODES)
              + f' | {"yes" if win else "NO":^9} | {"yes" if anch else "NO":^11}'
              + ('' if counted(c) else '  (tuning family, not counted)'))
    print(f'\n## {title}: per vessel and per operator (counted cases): beats DFR, no worse '
          'than anchored')
    for key, idx in (('vessel', 0), ('operator', 1)):
        for n in sorted({c[idx] for c, _, _ in held}):
            sel = [(w, an) for c, w, an in held if c[idx] == n]
            print(f'{key} {n:<15} beats DFR {sum(w for w, _ in sel):2d}/{len(sel):<2d}  '
                  f'<= anchored {sum(an for _, an in sel):2d}/{len(sel)}')
    n_win = sum(w for _, w, _ in held)
    n_anch = sum(an for _, _, an in held)
    print(f'\n{title}: cases where the default IMA beats DFR: {n_win} of {len(held)} '
          f'({100.0 * n_win / len(held):.0f} %, target >= 90 %)')
    print(f'{title}: cases where its mean error is no worse than the anchored baseline: '
          f'{n_anch} of {len(held)} (target: all)')
    worse = [(res[c]['ima'].all - res[c]['anchored'].all, c) for c, _, an in held if not an]
    if worse:
        d, c = max(worse)
        print(f'  largest excess over the anchored baseline: {1000 * d:.1f} mN ({c[0]} {c[1]} '
              f'{c[2]})')
    print(f'\n## {title}: averages over the counted cases (N) and ratio to DFR (same cases, '
          'same run)')
    print(f'{"mode":<12} {"normal MAE":>10} {"outage MAE":>10} {"max":>8} | {"normal/DFR":>10} '
          f'{"outage/DFR":>10} {"max/DFR":>8}')
    avg = {m: np.mean([[res[c][m].normal, res[c][m].outage, res[c][m].max]
                       for c, _, _ in held], axis=0) for m in MODES}
    dn, do, dx = avg['dfr']
    for m in MODES:
        n, o, x = avg[m]
        print(f'{LABEL[m]:<12} {n:10.4f} {o:10.4f} {x:8.4f} | {n / dn:10.4f} {o / do:10.4f} '
              f'{x / dx:8.4f}')
    print('(targets for the default: normal <= 0.5 x DFR, outage <= 0.25 x DFR)', flush=True)


#: the held-out sections run one at a time by --section NAME (each once, after a round's
#: design is final): name, seeds, title, note
HELD_OUT = (
    ('fresh2', FRESH2_SEEDS, 'second fresh held-out worlds',
     "; held out from the third round's design work (seen in the fourth's)"),
    ('fresh3', FRESH3_SEEDS, 'third fresh held-out worlds',
     "; held out from the fourth round's design work (seen in the fifth's)"),
    ('fresh4', FRESH4_SEEDS, 'fourth fresh held-out worlds',
     "; held out from the fifth round's design work (seen in the sixth's)"),
    ('fresh5', FRESH5_SEEDS, 'fifth fresh held-out worlds',
     "; held out from the sixth round's design work (seen in the seventh's)"),
    ('fresh6', FRESH6_SEEDS, 'sixth fresh held-out worlds',
     "; held out from the seventh round's design work (seen in the eighth's)"),
    ('fresh7', FRESH7_SEEDS, 'seventh fresh held-out worlds',
     "; held out from the eighth round's design work (seen in the ninth's)"),
    ('fresh8', FRESH8_SEEDS, 'eighth fresh held-out worlds',
     "; held out from the ninth to the eleventh round's design work"),
    ('fresh9', FRESH9_SEEDS, 'ninth fresh held-out worlds',
     "; held out from the eleventh to the fourteenth round's design work"),
    ('fresh10', FRESH10_SEEDS, 'tenth fresh held-out worlds',
     "; held out from the fourteenth and fifteenth rounds' design work"),
    ('fresh11', FRESH11_SEEDS, 'eleventh fresh held-out worlds',
     "; held out from the fifteenth round's design work on"),
    ('fresh12', FRESH12_SEEDS, 'twelfth fresh held-out worlds',
     "; held out from the seventeenth to the nineteenth round's design work"),
    ('fresh13', FRESH13_SEEDS, 'thirteenth fresh held-out worlds',
     "; held out from the nineteenth to the twenty-second round's design work"),
    ('fresh14', FRESH14_SEEDS, 'fourteenth fresh held-out worlds',
     "; held out from the twenty-second round's design work on"),
)

def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--section', default='all',
                    choices=('dev', 'fresh', *(h[0] for h in HELD_OUT), 'all'))
    ap.add_argument('--quick', action='store_true', help='one seed per section')
    ap.add_argument('--jobs', type=int, default=1, help='processes (cases in parallel)')
    ap.add_argument('--draw-seeds', default=None,
                    help='comma-separated seeds: the randomised section on these seeds '
                         'instead of the fresh ones (development draws, never the held-out '
                         '800-804, 900-904, 1000-1004, 1100-1104, 1200-1204, 1300-1304 '
                         'and 1400-1404)')
    ap.add_argument('--oracle', action='store_true',
                    help='also run the oracle renderers (impedance_master.oracle) on the '
                         'randomised sections and print their table')
    a = ap.parse_args(argv)
    t0 = time.perf_counter()
    if a.section in ('dev', 'all'):
        seeds = list(DEVELOPMENT_SEEDS)[:1 if a.quick else None]
        todo = [c + ((),) for c in cases(seeds, include_tuning=True)]
        print(f'# bench_ima_general, development set: {len(todo)} cases (vessels x operators '
              f'x seeds {seeds}), cold start, Experiment II timing; tuned on {TUNING[0]} x '
              f'{TUNING[1]} only; these seeds were seen during development')
        report('development set (seeds 10-12)', todo, run_all(todo, a.jobs),
               lambda c: (c[0], c[1]) != TUNING)
        print(f'(development set: {time.perf_counter() - t0:.0f} s)', flush=True)
    sections = []
    if a.section in ('fresh', 'all'):
        seeds = list(FRESH_SEEDS)[:1 if a.quick else None]
        title, note = 'fresh held-out worlds', ''
        if a.draw_seeds:
            seeds = [int(s) for s in a.draw_seeds.split(',')]
            if set(seeds) & (set(FRESH8_SEEDS) | set(FRESH9_SEEDS) | set(FRESH10_SEEDS)
                             | set(FRESH11_SEEDS) | set(FRESH12_SEEDS)
                             | set(FRESH13_SEEDS) | set(FRESH14_SEEDS)):
                ap.error('--draw-seeds must not name the held-out seeds 800-804, 900-904, '
                         '1000-1004, 1100-1104, 1200-1204, 1300-1304, 1400-1404')
            title = f'development draws (seeds {seeds})'
        sections.append((seeds, title, note))
    for name, all_seeds, title, note in HELD_OUT:
        if a.section == name:
            sections.append((list(all_seeds)[:1 if a.quick else None], title, note))
    for seeds, title, note in sections:
        t1 = time.perf_counter()
        todo = drawn_cases(seeds)
        print(f'\n# bench_ima_general, {title}: {len(todo)} randomised draws '
              f'(sim_slave.vessels.draw_vessel) of every vessel family x every operator x '
              f'seeds {seeds}, cold start, Experiment II timing{note}')
        results = run_all(todo, a.jobs, a.oracle)
        report(title, todo, results, lambda c: True)
        if a.oracle:
            oracle_report(title, todo, results)
        print(f'({title}: {time.perf_counter() - t1:.0f} s)')
    print(f'\n(total {time.perf_counter() - t0:.0f} s)', flush=True)


if __name__ == '__main__':
    main()

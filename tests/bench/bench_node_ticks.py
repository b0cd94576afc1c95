"""The nodes' own per-tick cost, A/B against another checkout's code in the same session.

    python tests/bench/bench_node_ticks.py [--against /path/to/other/checkout] [--rounds 3]
    scripts/bench node_ticks

Runs lockstep Experiment II (4 s simulated, not recorded, the vision chain left out: its
image outputs dropped, as bench_system's "without the vision chain" row) in a fresh
interpreter with each checkout's environment (its scripts/env.sh), alternating this
checkout and ``--against``, and prints per node the callback wall time per call (us; the
runner's per-callback cost: a timer's own work and its publishes, a delivery's callback;
deliveries a callback causes are not counted in it) and the whole run's wall time per
simulated second. Then per node the median over rounds of this / other. The machine is
shared: only the ratios of one session mean anything.
"""
from __future__ import annotations

import argparse
import pathlib
import statistics
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from bench_system_ab import ROOT, run_in  # noqa: E402

CHILD = r'''
import json, sys
from catheter_bringup.runner import ScenarioRunner
from catheter_bringup.scenario import load_scenario
VISION_OUTPUTS = {'/catheter/tip_wrench', '/catheter/tip_force', '/catheter/control_points',
                  '/camera/tip_force_truth'}
sc = load_scenario('experiment_ii')
sc['duration'] = float(sys.argv[1])
sc['outputs'] = [t for t in sc['outputs'] if t not in VISION_OUTPUTS]
r = ScenarioRunner(sc, record=False, progress=False, log=lambda *_: None).run()
out = {'run_s_per_sim_s': r.wall_time / r.sim_time,
       'us_per_call': {n: c['total_s'] / c['callbacks'] * 1e6 for n, c in r.cost.items()
                       if c['callbacks']},
       'calls': {n: c['callbacks'] for n, c in r.cost.items()}}
print(json.dumps(out))
'''


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--against', type=pathlib.Path, default=None)
    ap.add_argument('--rounds', type=int, default=3)
    ap.add_argument('--duration', type=float, default=4.0)
    a = ap.parse_args(argv)
    sides = [('this', ROOT)] + ([('other', a.against)] if a.against else [])
    res = {k: [] for k, _ in sides}
    for _ in range(a.rounds):
        for k, root in sides:
            res[k].append(run_in(root, a.duration, CHILD))
    nodes = sorted(res['this'][0]['us_per_call'])
    print(f'lockstep Experiment II {a.duration:g} s, vision chain left out, {a.rounds} rounds '
          'alternating; us per callback (run: wall s per simulated s)')
    print(f'{"code":6s} {"run":>6s} ' + ' '.join(f'{n[:18]:>18s}' for n in nodes))
    for i in range(a.rounds):
        for k, _ in sides:
            r = res[k][i]
            print(f'{k:6s} {r["run_s_per_sim_s"]:6.3f} '
                  + ' '.join(f'{r["us_per_call"].get(n, float("nan")):18.1f}' for n in nodes))
    if a.against:
        print('median over rounds of this / other (same session):')
        for n in ['run'] + nodes:
            def val(r, n=n):
                return r['run_s_per_sim_s'] if n == 'run' else r['us_per_call'].get(n)
            ratios = [val(t) / val(o) for t, o in zip(res['this'], res['other'], strict=True)
                      if val(t) and val(o)]
            calls = '' if n == 'run' else f'  ({res["this"][0]["calls"][n]} callbacks/run)'
            print(f'  {n:28s} {statistics.median(ratios):.2f}{calls}')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())

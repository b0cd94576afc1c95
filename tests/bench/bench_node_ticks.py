"""The nodes' own per-tick cost, A/B against another checkout's code in the same session.

    python tests/bench/bench_node_ticks.py [--against /path/to/other/checkout] [--rounds 3]
    scripts/bench node_ticks

Runs lockstep Experiment II (4 s simulated, recorded, the vision chain left out: its image
outputs dropped, as bench_system's "without the vision chain" row; recorded, so every
stream has a subscriber and is built and published, as in the main command) in a fresh
interpreter with each checkout's environment (its scripts/env.sh), alternating this
checkout and ``--against``, and prints the wall time per call (us) of each 1 kHz callback
of the teleoperation nodes (sim_haptic_node, ima / dfr_master_node, sim_slave_node,
impedance_identifier_node: their timers and subscription callbacks, timed by a wrapper
put on the class method before the nodes are built: a timer's publishes, which serialise
and queue, are inside it; deserialising a delivery is not) and the whole run's wall time
per simulated second. Then per callback the median over rounds of this / other. The
machine is shared: only the ratios of one session mean anything.
"""
from __future__ import annotations

import argparse
import pathlib
import statistics
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from bench_system_ab import ROOT, run_in  # noqa: E402

CHILD = r'''
import importlib, json, sys, tempfile, time
from catheter_bringup.runner import ScenarioRunner
from catheter_bringup.scenario import load_scenario
#: the 1 kHz callbacks of the nodes (timers first), wrapped on their class before the runner
#: builds the nodes: the wrapper times the method itself (a timer's publishes are serialised
#: and queued inside it; the bus delivers after it returns, deserialising outside it)
METHODS = {'impedance_master.sim_haptic_node': ('_tick', '_on_rendered', '_on_impedance',
                                                '_on_slave_force'),
           'impedance_master.ima_master_node': ('_render', '_on_command', '_on_impedance',
                                                '_on_force'),
           'sim_slave.sim_slave_node': ('_tick', '_on_command'),
           'impedance_master.impedance_identifier_node': ('_publish', '_on_state')}
VISION_OUTPUTS = {'/catheter/tip_wrench', '/catheter/tip_force', '/catheter/control_points',
                  '/camera/tip_force_truth'}
acc = {}
def timed(fn, key):
    clock = time.perf_counter
    def wrapper(self, *args):
        t = clock()
        try:
            return fn(self, *args)
        finally:
            a = acc.setdefault(f'{self.get_name()}.{key}', [0, 0.0])
            a[0] += 1
            a[1] += clock() - t
    return wrapper
for mod, names in METHODS.items():
    cls = importlib.import_module(mod).NODE_CLASS
    for n in names:
        setattr(cls, n, timed(getattr(cls, n), n))
sc = load_scenario('experiment_ii')
sc['duration'] = float(sys.argv[1])
sc['outputs'] = [t for t in sc['outputs'] if t not in VISION_OUTPUTS]
with tempfile.TemporaryDirectory() as tmp:      # recorded: every stream has a subscriber
    r = ScenarioRunner(sc, bag=f'{tmp}/run.mcap', progress=False, log=lambda *_: None).run()
out = {'run_s_per_sim_s': r.wall_time / r.sim_time,
       'us_per_call': {k: v[1] / v[0] * 1e6 for k, v in acc.items() if v[0]},
       'calls': {k: v[0] for k, v in acc.items()}}
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
    keys = sorted(res['this'][0]['us_per_call'])
    print(f'lockstep Experiment II {a.duration:g} s recorded, vision chain left out, '
          f'{a.rounds} rounds alternating; us per call, per round (run: wall s per simulated s)')
    head = '  '.join(f'{k} {i + 1:d}' for i in range(a.rounds) for k, _ in sides)
    print(f'{"callback":42s} {"calls":>6s}  {head}')
    rows = [('run', None)] + [(k, res['this'][0]['calls'][k]) for k in keys]
    for key, calls in rows:
        vals = []
        for i in range(a.rounds):
            for k, _ in sides:
                r = res[k][i]
                vals.append(r['run_s_per_sim_s'] if key == 'run'
                            else r['us_per_call'].get(key, float('nan')))
        ratio = ''
        if a.against:
            ts, os_ = vals[0::2], vals[1::2]
            med = statistics.median(t / o for t, o in zip(ts, os_, strict=True))
            ratio = f'   this/other {med:.2f}'
        print(f'{key:42s} {calls if calls else "":>6}  '
              + '  '.join(f'{v:7.3f}' if key == 'run' else f'{v:7.1f}' for v in vals) + ratio)
    return 0


if __name__ == '__main__':
    raise SystemExit(main())

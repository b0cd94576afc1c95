"""The main command (scripts/run): run the default scenario, record it, print its metrics beside
the thesis's numbers and write the plots.

    scripts/run [SCENARIO] [--mode lockstep|realtime] [--duration S] [--out out/] [--no-fam]

1. runs SCENARIO (default experiment_ii: the thesis's Experiment II, 200 ms delay, 1 s outages at
   4 s and 8 s, IMA rendered, DFR shadow, image-based force estimation alongside when its nodes
   exist) in one process, recording every topic into bags/<name>.mcap;
2. prints the metrics (analyze): IMA vs DFR in normal and outage intervals, the image force
   estimation error, rate and latency per node;
3. writes PNG plots into out/ (Figs. 24-25 like, and the FAM accuracy-against-time plot) and the
   metrics as out/<name>_metrics.json.
"""
from __future__ import annotations

import argparse
import json
import os
import pathlib
import sys
import time


def main(argv=None):
    from catheter_bringup.run_scenario import DEFAULT_SCENARIO, summarize
    ap = argparse.ArgumentParser(prog='scripts/run', description=__doc__.split('\n\n')[0])
    ap.add_argument('scenario', nargs='?', default=DEFAULT_SCENARIO)
    ap.add_argument('--mode', choices=('lockstep', 'realtime'), default=None)
    ap.add_argument('--duration', type=float, default=None)
    ap.add_argument('--out', default=None, help='plots and metrics folder (default out/)')
    ap.add_argument('--bag', default=None, help='recording (default bags/<scenario>.mcap)')
    ap.add_argument('--no-fam', action='store_true', help='skip the FAM accuracy plot')
    ap.add_argument('--no-plots', action='store_true')
    a = ap.parse_args(argv)
    root = pathlib.Path(os.environ.get('CATHETER_WS_ROOT', pathlib.Path.cwd()))
    out = pathlib.Path(a.out) if a.out else root / 'out'

    from catheter_common.ros_testing import isolate_ros_env
    if 'ROS_DOMAIN_ID' not in os.environ:
        isolate_ros_env()       # a run of its own: no cross-talk with other graphs on the host
    from catheter_bringup.analyze import _jsonable, analyze, format_report
    from catheter_bringup.runner import ScenarioRunner
    from catheter_bringup.scenario import load_scenario

    sc = load_scenario(a.scenario)
    print(f"== {sc['name']}: {sc.get('description', '')}", flush=True)
    runner = ScenarioRunner(sc, bag=a.bag, mode=a.mode, duration=a.duration, progress=True,
                            log=lambda m: print(m, flush=True))
    from catheter_bringup.run_scenario import install_stop_handlers, restore_handlers
    old = install_stop_handlers(runner)
    try:
        runner.setup()
        res = runner.run()
    finally:
        restore_handlers(old)
    print(summarize(res), flush=True)
    if res.bag is None or not pathlib.Path(res.bag).exists():
        return 1
    print('', flush=True)
    skip = (sc.get('metrics') or {}).get('skip')    # None: 1.5 s + 2 delay (the experiment's)
    metrics = analyze(res.bag, skip=None if skip is None else float(skip))
    metrics['run'] = {'wall_time_s': res.wall_time, 'realtime_factor': res.realtime_factor,
                      'nodes': res.nodes, 'skipped': res.skipped,
                      'missing_outputs': res.missing_outputs, 'lost': res.lost,
                      'cost': res.cost}
    print(format_report(metrics), flush=True)
    if res.cost:
        print(f'\nCompute per node (wall time inside its callbacks; run_scenario = the recorder; '
              f'{res.wall_time:.1f} s wall, 2 shared cores)', flush=True)
        print(f"{'node':<26} {'callbacks':>9} {'mean ms':>8} {'p99 ms':>8} {'max ms':>8} "
              f"{'total s':>8} {'share':>6}")
        for node, c in sorted(res.cost.items(), key=lambda kv: -kv[1]['total_s']):
            print(f"{node:<26} {c['callbacks']:>9} {c['mean_ms']:>8.3f} {c['p99_ms']:>8.3f} "
                  f"{c['max_ms']:>8.2f} {c['total_s']:>8.2f} {c['share'] * 100:>5.0f}%")
    out.mkdir(parents=True, exist_ok=True)
    mpath = out / f"{sc['name']}_metrics.json"
    with open(mpath, 'w') as f:
        json.dump(_jsonable(metrics), f, indent=1, sort_keys=True)
    files = [str(mpath)]
    if not a.no_plots:
        from catheter_bringup.plots import fam_accuracy_plot, run_plots
        files += run_plots(res.bag, out)
        if not a.no_fam:
            t = time.perf_counter()
            p = fam_accuracy_plot(out)
            if p:
                files.append(p)
            else:
                print('(FAM accuracy plot skipped: fam_solver not importable)')
    print('\nwritten:\n  ' + '\n  '.join([res.bag] + files), flush=True)
    return 1 if res.status == 'failed' else 0


if __name__ == '__main__':
    sys.exit(main())

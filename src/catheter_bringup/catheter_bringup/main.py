"""The main command (scripts/run): run the default scenario, record it, print its metrics beside
the thesis's numbers and write the plots.

    scripts/run [SCENARIO] [--mode lockstep|realtime] [--duration S] [--set KEY=VALUE ...]
                [--dds] [--name NAME] [--out out/] [--bag PATH] [--no-plots] [--no-fam | --fam]

1. runs SCENARIO (default experiment_ii: the thesis's Experiment II, 200 ms delay, 1 s outages at
   4 s and 8 s, IMA rendered, DFR shadow, image-based force estimation alongside when its nodes
   exist) in one process, recording every topic into bags/<run name>.mcap;
2. prints the metrics (analyze): IMA vs DFR in normal and outage intervals, the image force
   estimation error, rate and latency per node, with progress lines while it works;
3. writes PNG plots and the metrics into out/<run name>_*; the FAM accuracy plot
   (out/fam_accuracy.png: solve times measured on this machine, so a redraw changes it
   every time) only when it is missing or older than the fam_solver sources (``--fam``
   redraws it, ``--no-fam`` never draws it).

The run name is the scenario's, or says what was changed (``--set``, a copied YAML), so a
changed run never overwrites the default run's files (`catheter_bringup.overrides`).
"""
from __future__ import annotations

import argparse
import json
import os
import pathlib
import sys
import time
from typing import Optional, Sequence


def _say(msg: str) -> None:
    print(f'[analysis] {msg}', flush=True)


def main(argv: Optional[Sequence[str]] = None) -> int:
    from catheter_bringup.run_scenario import (DEFAULT_SCENARIO, add_run_arguments,
                                               prepare_scenario, summarize)
    ap = argparse.ArgumentParser(prog='scripts/run', description=__doc__.split('\n\n')[0])
    ap.add_argument('scenario', nargs='?', default=DEFAULT_SCENARIO)
    add_run_arguments(ap)
    ap.add_argument('--out', default=None, help='plots and metrics folder (default out/)')
    ap.add_argument('--bag', default=None, help='recording (default bags/<run name>.mcap)')
    fam = ap.add_mutually_exclusive_group()
    fam.add_argument('--no-fam', action='store_true', help='never draw the FAM accuracy plot')
    fam.add_argument('--fam', action='store_true', help='redraw the FAM accuracy plot')
    ap.add_argument('--no-plots', action='store_true')
    a = ap.parse_args(argv)
    root = pathlib.Path(os.environ.get('CATHETER_WS_ROOT', pathlib.Path.cwd()))
    out = pathlib.Path(a.out) if a.out else root / 'out'

    from catheter_common.ros_testing import isolate_ros_env
    if 'ROS_DOMAIN_ID' not in os.environ:
        isolate_ros_env()       # a run of its own: no cross-talk with other graphs on the host
    from catheter_bringup.analyze import _jsonable, analyze, format_report
    from catheter_bringup.recording import load
    from catheter_bringup.runner import ScenarioRunner

    try:
        sc, why = prepare_scenario(a)
    except ValueError as exc:
        print(f'scripts/run: {exc}', file=sys.stderr)
        return 2
    print(f"== {sc['name']}: {sc.get('description', '')}  [{why}]", flush=True)
    runner = ScenarioRunner(sc, bag=a.bag, mode=a.mode, duration=a.duration, progress=True,
                            log=lambda m: print(m, flush=True))
    from catheter_bringup.run_scenario import install_stop_handlers, restore_handlers
    old = install_stop_handlers(runner)
    try:
        runner.setup()                      # writes the run-start record into the bag
        res = runner.run()
    finally:
        restore_handlers(old)
    print(summarize(res), flush=True)
    if res.bag is None or not pathlib.Path(res.bag).exists():
        return 1
    print('', flush=True)
    t_analysis = time.perf_counter()
    skip = (sc.get('metrics') or {}).get('skip')    # None: 1.5 s + 2 delay (the experiment's)
    _say(f'reading {res.bag}')
    rec = load(res.bag)
    metrics = analyze(res.bag, skip=None if skip is None else float(skip), progress=_say,
                      rec=rec)
    metrics['run'] = {'wall_time_s': res.wall_time, 'realtime_factor': res.realtime_factor,
                      'nodes': res.nodes, 'skipped': res.skipped,
                      'missing_outputs': res.missing_outputs, 'lost': res.lost,
                      'cost': res.cost}
    out.mkdir(parents=True, exist_ok=True)
    mpath = out / f"{sc['name']}_metrics.json"
    with open(mpath, 'w') as f:
        json.dump(_jsonable(metrics), f, indent=1, sort_keys=True)
    files = [str(mpath)]
    if not a.no_plots:
        from catheter_bringup.plots import run_plots
        files += run_plots(res.bag, out, name=sc['name'], rec=rec, metrics=metrics,
                           progress=_say)
        files += _fam_plot(out, a)
    _say(f'done in {time.perf_counter() - t_analysis:.1f} s')
    print('', flush=True)
    print(format_report(metrics), flush=True)
    if res.cost:
        print(f'\nCompute per node (wall time inside its callbacks; run_scenario = the recorder; '
              f'{res.wall_time:.1f} s wall, 2 shared cores)', flush=True)
        print(f"{'node':<26} {'callbacks':>9} {'mean ms':>8} {'p99 ms':>8} {'max ms':>8} "
              f"{'total s':>8} {'share':>6}")
        for node, c in sorted(res.cost.items(), key=lambda kv: -kv[1]['total_s']):
            print(f"{node:<26} {c['callbacks']:>9} {c['mean_ms']:>8.3f} {c['p99_ms']:>8.3f} "
                  f"{c['max_ms']:>8.2f} {c['total_s']:>8.2f} {c['share'] * 100:>5.0f}%")
    print('\nwritten:\n  ' + '\n  '.join([res.bag] + files), flush=True)
    return 1 if res.status == 'failed' else 0


def _fam_plot(out: pathlib.Path, a) -> list:
    """The FAM accuracy plot when asked (--fam) or missing or stale; [] otherwise."""
    from catheter_bringup.fam_plot import FILE, fam_accuracy_plot, is_current
    if a.no_fam:
        return []
    if not a.fam and is_current(out):
        _say(f'FAM accuracy plot up to date ({out / FILE}; --fam redraws it)')
        return []
    _say('FAM accuracy plot: measuring fam_solver against solve_elastica')
    p = fam_accuracy_plot(out)
    if not p:
        _say('FAM accuracy plot skipped: fam_solver not importable')
        return []
    return [p]


if __name__ == '__main__':
    sys.exit(main())

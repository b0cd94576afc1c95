"""`run_scenario`: run a scenario (launchless, one process) and record it.

    run_scenario [SCENARIO] [--mode lockstep|realtime] [--duration S] [--bag PATH] [--no-record]
                 [--quiet] [--ros-args ...]

Without arguments it runs the default scenario (experiment_ii) in lockstep. The runner's own
node is named ``run_scenario``. Exit code 0 when the run completed or was stopped with Ctrl-C,
1 when a node failed.
"""
from __future__ import annotations

import argparse
import signal
import sys

DEFAULT_SCENARIO = 'experiment_ii'


def build_parser():
    p = argparse.ArgumentParser(prog='run_scenario', description=__doc__.split('\n\n')[0])
    p.add_argument('scenario', nargs='?', default=DEFAULT_SCENARIO,
                   help="name in catheter_bringup's config/ or path to a YAML file")
    p.add_argument('--mode', choices=('lockstep', 'realtime'), default=None)
    p.add_argument('--duration', type=float, default=None, help='override, s')
    p.add_argument('--bag', default=None,
                   help='output .mcap (default bags/<scenario>_<date>_<time>.mcap)')
    p.add_argument('--no-record', action='store_true')
    p.add_argument('--quiet', action='store_true', help='no progress bar')
    p.add_argument('--only', default=None,
                   help='comma-separated node instances: start only these (a worker process)')
    return p


def summarize(res) -> str:
    lines = [f'scenario {res.scenario}: {res.status}' + (f' ({res.reason})' if res.reason else ''),
             f'  simulated {res.sim_time:.3f} s in {res.wall_time:.2f} s wall '
             f'(real-time factor {res.realtime_factor:.2f}x)',
             f'  nodes: {", ".join(res.nodes) or "(none)"}']
    if res.skipped:
        lines.append(f'  not available (skipped): {", ".join(res.skipped)}')
    if res.missing_outputs:
        lines.append(f'  wanted outputs nobody produces: {", ".join(res.missing_outputs)}')
    if res.bag:
        total = sum(res.recorded.values())
        lost = sum(res.lost.values())
        lines.append(f'  recorded {total} messages on {len(res.recorded)} topics -> {res.bag} '
                     f'(lost: {lost})')
    return '\n'.join(lines)


def install_stop_handlers(runner) -> dict:
    """Ctrl-C and SIGTERM ask the runner to stop: it finishes the current step, closes the
    recording (status interrupted) and returns. The handler only sets a flag: an exception
    raised from a signal handler inside a C extension call (message (de)serialisation) would
    surface as an unrelated error."""
    def on_signal(signum, frame):
        runner.stop_requested = True

    old = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    return old


def restore_handlers(old) -> None:
    for sig, handler in (old or {}).items():
        signal.signal(sig, handler)


def main(args=None):
    from rclpy.utilities import remove_ros_args
    argv = list(sys.argv[1:] if args is None else args)
    argv = remove_ros_args(['x'] + argv)[1:]
    opts = build_parser().parse_args(argv)
    import datetime
    import os
    import pathlib
    from catheter_bringup.runner import ScenarioRunner
    from catheter_bringup.scenario import load_scenario
    sc = load_scenario(opts.scenario)
    bag = opts.bag
    if bag is None and not opts.no_record:
        root = pathlib.Path(os.environ.get('CATHETER_WS_ROOT', pathlib.Path.cwd()))
        stamp = datetime.datetime.now().strftime('%Y%m%d_%H%M%S')   # file name only
        bag = str(root / 'bags' / f"{sc['name']}_{stamp}.mcap")
    runner = ScenarioRunner(sc, bag=bag, mode=opts.mode,
                            duration=opts.duration, progress=not opts.quiet,
                            record=False if opts.no_record else None,
                            only=opts.only.split(',') if opts.only else None)
    install_stop_handlers(runner)
    runner.setup()
    res = runner.run()
    print(summarize(res), flush=True)
    return 1 if res.status == 'failed' else 0


if __name__ == '__main__':
    sys.exit(main())

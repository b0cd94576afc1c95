"""`run_scenario`: run a scenario (launchless, one process) and record it.

    run_scenario [SCENARIO] [--mode lockstep|realtime] [--duration S] [--set KEY=VALUE ...]
                 [--dds] [--name NAME] [--bag PATH] [--no-record] [--quiet] [--ros-args ...]

Without arguments it runs the default scenario (experiment_ii) in lockstep. ``--set`` changes
any scenario field (`catheter_bringup.overrides`: ``--set link.delay=0.5``); the run, its bag
and its outputs are then named after the change (``experiment_ii__link.delay-0.5``), never
after the default run unless ``--name`` says so. ``--dds`` publishes every message of a
lockstep run on DDS too (scenario field ``dds: true``), so tools outside the process (the
`catheter_topic` tool, rviz, Foxglove) see the run. The runner's own node is named
``run_scenario``. Exit code 0 when the run completed or was stopped with Ctrl-C or SIGTERM,
1 when a node failed, 2 when the scenario or an override is invalid.
"""
from __future__ import annotations

import argparse
import signal
import sys
from typing import Optional, Sequence, TYPE_CHECKING, Tuple

if TYPE_CHECKING:
    from catheter_bringup.result import RunResult
    from catheter_bringup.runner import ScenarioRunner

DEFAULT_SCENARIO = 'experiment_ii'


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog='run_scenario', description=__doc__.split('\n\n')[0])
    p.add_argument('scenario', nargs='?', default=DEFAULT_SCENARIO,
                   help="name in catheter_bringup's config/ or path to a YAML file")
    add_run_arguments(p)
    p.add_argument('--bag', default=None,
                   help='output .mcap (default bags/<run name>_<date>_<time>.mcap)')
    p.add_argument('--no-record', action='store_true')
    p.add_argument('--quiet', action='store_true', help='no progress bar')
    p.add_argument('--only', default=None,
                   help='comma-separated node instances: start only these (a worker process)')
    p.add_argument('--process', default='main',
                   help='name of this process in a multi-process run (master, slave, vision)')
    p.add_argument('--go', default=None,
                   help='wait until this file exists before starting the loop (a worker '
                        'process: its run starts with the others, once the recorder listens)')
    p.add_argument('--part-bag', default=None,
                   help='a worker process of layout split: record what its nodes publish '
                        'into this .mcap part (the runner merges the parts into the bag)')
    p.add_argument('--report', default=None,
                   help='write what this process published, took and spent to this JSON file')
    p.add_argument('--cpus', default=None,
                   help='comma-separated CPU numbers: keep this process (every thread) on '
                        'them (a worker of layout split started by the launch file; '
                        '`realtime.worker_cpus` says which)')
    return p


def parse_cpus(text: Optional[str]) -> Optional[frozenset]:
    """'0,1' -> frozenset({0, 1}); None -> None; ValueError naming --cpus otherwise."""
    if text is None:
        return None
    try:
        cpus = frozenset(int(c) for c in text.split(','))
    except ValueError:
        raise ValueError(f'--cpus must be comma-separated CPU numbers, got {text!r}') from None
    if not cpus or min(cpus) < 0:
        raise ValueError(f'--cpus must name CPUs numbered from 0, got {text!r}')
    return cpus


def add_run_arguments(p: argparse.ArgumentParser) -> None:
    """The options that say what runs (shared with the main command)."""
    p.add_argument('--mode', choices=('lockstep', 'realtime'), default=None)
    p.add_argument('--duration', type=float, default=None, help='override, s')
    p.add_argument('--set', dest='overrides', action='append', default=[], metavar='KEY=VALUE',
                   help='override a scenario field, e.g. --set link.delay=0.5 (repeatable)')
    p.add_argument('--dds', action='store_true',
                   help='also publish every message on DDS (for tools outside this process)')
    p.add_argument('--name', default=None,
                   help='name of the run and its outputs (default: the scenario\'s, plus '
                        'the overrides)')


def prepare_scenario(opts: argparse.Namespace) -> Tuple[dict, str]:
    """(scenario dict, why it is named so) from the parsed options; ValueError if invalid."""
    from catheter_bringup.overrides import apply_overrides, run_name
    from catheter_bringup.scenario import load_scenario
    sc = load_scenario(opts.scenario)
    items = list(opts.overrides)
    if opts.mode:
        items.append(f'mode={opts.mode}')      # validated with the rest (layout needs it)
    if opts.dds:
        items.append('dds=true')
    name, why = run_name(sc, opts.overrides, opts.name)
    sc = apply_overrides(sc, items)
    sc['name'] = name
    return sc, why


def summarize(res: RunResult) -> str:
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


def install_stop_handlers(runner: ScenarioRunner) -> dict:
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


def restore_handlers(old: Optional[dict]) -> None:
    for sig, handler in (old or {}).items():
        signal.signal(sig, handler)


def main(args: Optional[Sequence[str]] = None) -> int:
    from catheter_bringup.rclpy_adapter import without_ros_args
    argv = without_ros_args(sys.argv[1:] if args is None else args)
    opts = build_parser().parse_args(argv)
    import datetime
    import os
    import pathlib
    from catheter_bringup.runner import ScenarioRunner
    try:
        sc, why = prepare_scenario(opts)
        cpus = parse_cpus(opts.cpus)
    except ValueError as exc:
        print(f'run_scenario: {exc}', file=sys.stderr)
        return 2
    from catheter_bringup.realtime import pin_process, pins_loop_thread_only
    loop_only = bool(cpus) and pins_loop_thread_only(opts.process)
    pinned = None           # the CPUs this process keeps itself on, for the report
    if cpus and not loop_only and pin_process(os.getpid(), cpus, _log):
        pinned = cpus       # every thread: before rclpy makes its threads (they inherit it)
    if not opts.quiet:
        print(f"run {sc['name']} ({why})", flush=True)
    bag = opts.bag
    if bag is None and not opts.no_record:
        root = pathlib.Path(os.environ.get('CATHETER_WS_ROOT', pathlib.Path.cwd()))
        stamp = datetime.datetime.now().strftime('%Y%m%d_%H%M%S')   # file name only
        bag = str(root / 'bags' / f"{sc['name']}_{stamp}.mcap")
    runner = ScenarioRunner(sc, bag=bag, mode=opts.mode,
                            duration=opts.duration, progress=not opts.quiet,
                            record=False if opts.no_record else None,
                            only=opts.only.split(',') if opts.only else None,
                            part_bag=opts.part_bag)
    runner.process = opts.process
    runner.go_file = opts.go
    install_stop_handlers(runner)
    try:
        runner.setup()
    except (ValueError, RuntimeError) as exc:
        print(f'run_scenario: {exc}', file=sys.stderr)
        runner.close()
        return 2 if isinstance(exc, ValueError) else 1
    if loop_only and pin_process(os.getpid(), cpus, _log, main_only=True):
        pinned = cpus       # the loop thread only, once setup made the others
    res = runner.run()
    if opts.report:
        write_report(opts.report, opts.process, res, pinned)
    print(summarize(res), flush=True)
    return 1 if res.status == 'failed' else 0


def _log(line: str) -> None:
    print(line, file=sys.stderr, flush=True)     # a worker's stderr is its log


def write_report(path: str, process: str, res: RunResult,
                 cpus: Optional[frozenset] = None) -> None:
    """A worker process's report (read by `catheter_bringup.worker.Workers`); `cpus`: the
    CPUs it kept itself on (None: any)."""
    import json
    with open(path, 'w') as f:
        json.dump({'process': process, 'status': res.status, 'reason': res.reason,
                   'cpus': sorted(cpus) if cpus else None,
                   'nodes': res.nodes, 'published': res.published, 'recorded': res.recorded,
                   'received': res.received,
                   'cost': res.cost, 'realtime': res.realtime, 'wall_s': res.wall_time}, f)


if __name__ == '__main__':
    sys.exit(main())

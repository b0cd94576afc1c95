"""Benchmark of the node fuzz suite: every node that takes input, in-process, driven with at
least 100 000 hypothesis-built messages per input topic (plus clock ticks and runtime
parameter changes), with the invariants of tests/fuzz checked at every output.

    scripts/bench fuzz                       # or: python tests/bench/bench_fuzz.py [--quick]
    python tests/bench/bench_fuzz.py --per-topic 20000 --nodes ima_master_node,shape_node

Prints per node: messages sent (per input topic), refused as bad, outputs, non-finite floats
in outputs (target 0), outputs over the limit (rendered force above the renderer's limit,
or a tip force published for control points outside the estimator's envelope; target 0),
crashes (a callback or timer that raised; target 0), messages not accounted for by exactly
one diagnostics counter (target 0), parameter changes applied / refused; then the counters
of core failures the nodes caught (a non-finite renderer output replaced by 0 N, an exception
from numpy/OpenCV inside the identifier, the shape sensor, FAM or the camera), which go to 0
with the core fixes of other branches. Throughput: messages per second through the node
beside building the same messages without a node (the reference, same run): the ratio is
the share of time spent outside the node.
"""
from __future__ import annotations

import argparse
import os
import pathlib
import sys
import time

ROOT = pathlib.Path(__file__).resolve().parents[2]
for pkg in sorted((ROOT / 'src').iterdir()):
    if (pkg / 'package.xml').exists() and str(pkg) not in sys.path:
        sys.path.insert(0, str(pkg))
for d in (ROOT / 'tests' / 'fuzz', ROOT / 'tests' / 'nodes'):
    sys.path.insert(0, str(d))
os.environ.setdefault('CATHETER_WS_ROOT', str(ROOT))

from catheter_common.ros_testing import RosHarness, isolate_ros_env  # noqa: E402

isolate_ros_env()

from hypothesis import HealthCheck, given, seed, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

import strategies as S  # noqa: E402
from harness import FUZZ_NODES, Rig, events  # noqa: E402

#: per node, the diagnostics counter of core failures it caught (0 once the cores are fixed)
CORE_COUNTERS = {'ima_master_node': 'nonfinite_outputs', 'dfr_master_node': 'nonfinite_outputs',
                 'impedance_identifier_node': 'update_errors', 'shape_node': 'sensor_errors',
                 'fam_solver_node': 'solve_errors', 'camera_node': 'frame_errors'}
#: parameter values the benchmark keeps away from (they only make FAM slow: 1-2 s a solve
#: with bezier arcs, tens of ms an estimate by FAM inversion; robustness to them is in the
#: tests, tests/fuzz)
BENCH_PARAMS = {'fam_solver_node': {'arc_model': st.sampled_from(['clothoid', 'exact'])},
                'force_estimator_node': {'method': st.sampled_from(['svr', 'mlp', 'bogus'])}}


#: messages per input topic where the default is too slow to run (FAM inversion: ~20 ms
#: an estimate, 100 000 would take about half an hour)
BENCH_PER_TOPIC = {'fam_estimator_node': 10_000}


def fuzz_node(ros, key: str, per_topic: int, chunk: int = 100):
    """Run node `key` until every input topic had `per_topic` messages; returns (rig, s)."""
    spec = FUZZ_NODES[key]
    saved = dict(spec.param_values)
    spec.param_values.update(BENCH_PARAMS.get(key, {}))
    try:
        rig = Rig(ros, key)
        t0 = time.perf_counter()
        k = 0
        while min(rig.tally.sent.get(t, 0) for t in spec.inputs) < per_topic:
            @seed(k)
            @settings(max_examples=chunk, deadline=None, database=None, derandomize=False,
                      suppress_health_check=list(HealthCheck))
            @given(events(key))
            def run(evs):
                rig.run(evs)
            run()
            k += 1
        return rig, time.perf_counter() - t0
    finally:
        spec.param_values.clear()
        spec.param_values.update(saved)


def build_only_rate(key: str, n: int = 20000) -> float:
    """Messages per second built for node `key`'s inputs without a node (the reference)."""
    spec = FUZZ_NODES[key]
    topics = sorted(spec.inputs)
    p = S.Pick([0.1, -0.5, 1e308, float('nan'), 0.0, 0.3], 1)
    t0 = time.perf_counter()
    for i in range(n):
        spec.inputs[topics[i % len(topics)]].build(p)
    return n / (time.perf_counter() - t0)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--per-topic', type=int, default=100_000,
                    help='messages per input topic (default 100 000)')
    ap.add_argument('--quick', action='store_true', help='5 000 messages per input topic')
    ap.add_argument('--nodes', default=','.join(sorted(FUZZ_NODES)),
                    help='comma-separated keys of tests/fuzz/harness.FUZZ_NODES')
    a = ap.parse_args(argv)
    per_topic = 5000 if a.quick else a.per_topic
    keys = [k for k in a.nodes.split(',') if k]
    rows, core, speed = [], [], []
    # LAPACK writes its complaints about NaN arguments ("On entry to DLASCL ...") to the
    # process's stdout: keep them out of the tables while the nodes run
    sys.stdout.flush()
    saved_stdout = os.dup(1)
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 1)
    try:
        _run_all(keys, per_topic, rows, core, speed)
    finally:
        sys.stdout.flush()
        os.dup2(saved_stdout, 1)
        os.close(devnull)
        os.close(saved_stdout)
    _print_tables(per_topic, rows, core, speed)
    return 0


def _run_all(keys, per_topic, rows, core, speed) -> None:
    for key in keys:
        ros = RosHarness()
        try:
            rig, wall = fuzz_node(ros, key, min(per_topic, BENCH_PER_TOPIC.get(key, per_topic)))
            t = rig.tally
            sent = sum(t.sent.values())
            refused = sum(t.refused.values()) + t.refused_in_timer
            rows.append((key, sent, ', '.join(f'{tp} {n}' for tp, n in sorted(t.sent.items())),
                         refused, t.outputs, t.nonfinite, t.over_limit, t.crashes,
                         t.unaccounted, f'{t.params_set}/{t.params_refused}'))
            d = rig.node.diag
            if key in CORE_COUNTERS:
                core.append((key, f'{CORE_COUNTERS[key]} {d.get(CORE_COUNTERS[key])}'))
            ref = build_only_rate(key)
            speed.append((key, sent / wall, ref))
            if t.examples:
                print(f'# {key}: first violations: {t.examples}', file=sys.stderr, flush=True)
            print(f'# {key}: {sent} messages in {wall:.1f} s', file=sys.stderr, flush=True)
        finally:
            ros.close()


def _print_tables(per_topic, rows, core, speed) -> None:
    print(f'\nNode fuzz: >= {per_topic} messages per input topic (fam_estimator_node, the '
          f'force estimator in method fam: {min(per_topic, BENCH_PER_TOPIC["fam_estimator_node"])}'
          '), invariants checked at every output (targets: non-finite 0, over limit 0, '
          'crashes 0, unaccounted 0)')
    hdr = ('node', 'sent', 'refused', 'outputs', 'non-finite', 'over limit', 'crashes',
           'unaccounted', 'params set/refused')
    w = max(len(r[0]) for r in rows) + 2
    print(f'{hdr[0]:<{w}}' + ''.join(f'{h:>12}' for h in hdr[1:8]) + f'{hdr[8]:>20}')
    for r in rows:
        print(f'{r[0]:<{w}}{r[1]:>12}{r[3]:>12}{r[4]:>12}{r[5]:>12}{r[6]:>12}{r[7]:>12}'
              f'{r[8]:>12}{r[9]:>20}')
    print('\nMessages per input topic')
    for r in rows:
        print(f'{r[0]:<{w}}{r[2]}')
    print('\nCore failures the nodes caught (0 with the core fixes of issue 10)')
    for key, text in core:
        print(f'{key:<{w}}{text}')
    print('\nThroughput (messages per second; reference: building the same messages without '
          'a node, same run)')
    print(f'{"node":<{w}}{"through node":>14}{"build only":>14}{"ratio":>8}')
    for key, ours, ref in speed:
        print(f'{key:<{w}}{ours:>14.0f}{ref:>14.0f}{ours / ref:>8.2f}')


if __name__ == '__main__':
    raise SystemExit(main())

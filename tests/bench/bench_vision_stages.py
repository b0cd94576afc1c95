"""Where the split layout's image -> tip force latency goes, per stage and per frame.

    python tests/bench/bench_vision_stages.py [--duration 6] [--runs 1] [--load]

Runs real-time Experiment II in the split layout (as `bench_system --split-only`, 5 %
injected link loss) with the vision chain's stage trace on (`catheter_shape.stage_trace`),
and prints, per stage, p50 / p99 / max of its wall time and of the part of it the stage did
not run (wall - its thread's CPU time: preempted or blocked):

- camera: the camera tick from its header stamp (the clock read that stamps the frame) to
  the image's publish (the FAM shape and the rendering);
- hand-over: the image's publish -> shape_node's callback (the bus delivers in-process);
- wait: shape_node's callback -> the start of its processing (its timer tick, or at once);
- shape: the shape sensor (segmentation, centreline, Bezier fit);
- to estimator: end of the shape sensor -> the estimator's start (publishing the control
  points, delivery);
- estimate: the force estimate (by method and status);
- total: header stamp -> end of the estimate (the tip_wrench publish follows at once);
and the worker's own image -> tip force latency (stamp age at the tip_wrench publish), the
master's and slave's 1 kHz figures of the same run, and the CPU of each process.
`--load` adds a busy-loop process on one core. Only frames that went through every stage
count in the per-frame totals.
"""
from __future__ import annotations

import argparse
import glob
import json
import os
import pathlib
import sys
import tempfile

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / 'tests' / 'bench'))

import bench_system as B  # noqa: E402  (sets up the paths and the isolated ROS environment)

from catheter_shape import stage_trace  # noqa: E402

STAGES = ('camera', 'hand-over', 'wait', 'shape', 'to estimator', 'estimate', 'total')


def _pct(a, w=7):
    a = np.asarray(a, float)
    if a.size == 0:
        return 'n/a'
    return ' '.join(f'{v:{w}.2f}' for v in (np.percentile(a, 50), np.percentile(a, 99), a.max()))


def frames_from_trace(rows):
    """Per frame (by stamp) the stage times: {stamp: {stage: (wall ms, preempted ms, blocked
    ms, times off the CPU)}} (None where a stage is a gap between two others), and the
    estimates' (method, status) by stamp."""
    by = {}
    for name, rs in rows.items():
        for stamp, t0, t1, cpu, rq, sl, extra in rs:
            by.setdefault(stamp, {}).setdefault(name, []).append((t0, t1, cpu, rq, sl, extra))
    out, kinds, solves = {}, {}, {}
    ms = 1e-6

    def timed(r, t_from=None):
        t0 = r[0] if t_from is None else t_from
        wall = (r[1] - t0) * ms
        return (wall, r[3] * ms, max(0.0, (r[1] - r[0] - r[2] - r[3]) * ms), max(r[4] - 1, 0))

    for stamp, st in by.items():
        if not all(k in st for k in ('camera', 'arrive', 'shape', 'estimate')):
            continue
        cam, arr = st['camera'][0], st['arrive'][0]
        shp, est = st['shape'][-1], st['estimate'][-1]
        out[stamp] = {
            'camera': timed(cam, stamp),
            'hand-over': ((arr[0] - cam[1]) * ms, None, None, None),
            'wait': ((shp[0] - arr[0]) * ms, None, None, None),
            'shape': timed(shp),
            'to estimator': ((est[0] - shp[1]) * ms, None, None, None),
            'estimate': timed(est),
            'total': ((est[1] - stamp) * ms, None, None, None),
        }
        kinds[stamp] = tuple(est[5][:2]) if est[5] else ('?', '?')
        solves[stamp] = est[5][2] if est[5] and len(est[5]) > 2 else 0
    return out, kinds, solves


def run(duration, load, tmp, record=()):
    os.environ[stage_trace.ENV] = tmp
    try:
        if load:
            with B.CpuLoad():
                streams, lat, r = B.realtime_run('split', duration, tmp, record)
        else:
            streams, lat, r = B.realtime_run('split', duration, tmp, record)
    finally:
        os.environ.pop(stage_trace.ENV, None)
    rows = {}
    for path in glob.glob(os.path.join(tmp, 'stages.*.json')):
        with open(path) as f:
            for k, v in json.load(f).items():
                rows.setdefault(k, []).extend(v)
        os.unlink(path)
    return streams, lat, r, rows


def report(streams, lat, r, rows, label):
    frames, kinds, solves = frames_from_trace(rows)
    stamps = sorted(frames)[2:]                 # start-up left out (as latency_stats)
    print(f'-- {label}: {len(stamps)} frames through every stage '
          f'(camera {len(rows.get("camera", []))}, shape {len(rows.get("shape", []))}, '
          f'estimates {len(rows.get("estimate", []))})')
    print(f'{"stage, ms":14s} {"wall p50":>8s} {"p99":>6s} {"max":>6s} | {"preempted p50":>13s} '
          f'{"p99":>6s} {"max":>6s} | {"blocked p99":>11s} | {"off CPU: mean":>13s} {"max":>4s}')
    for s in STAGES:
        col = [frames[k][s] for k in stamps]
        w = [c[0] for c in col]
        line = f'{s:14s} {_pct(w, 6):>22s}'
        if col and col[0][1] is not None:
            line += (f' | {_pct([c[1] for c in col], 6):>27s} | '
                     f'{np.percentile([c[2] for c in col], 99):11.2f} | '
                     f'{np.mean([c[3] for c in col]):13.1f} {max(c[3] for c in col):4d}')
        print(line)
    tot = np.array([frames[k]['total'][0] for k in stamps])
    if tot.size:
        slow = [k for k in stamps if frames[k]['total'][0] >= np.percentile(tot, 95)]
        print(f'the slowest 5 % of frames ({len(slow)}), mean ms per stage (wall / preempted):')
        for s in STAGES[:-1]:
            w = np.mean([frames[k][s][0] for k in slow])
            o = [frames[k][s][1] for k in slow if frames[k][s][1] is not None]
            print(f'  {s:16s} {w:7.2f}' + (f' / {np.mean(o):6.2f}' if o else ''))
    counts = {}
    for k in stamps:
        counts[kinds[k]] = counts.get(kinds[k], 0) + 1
    print('estimates by method / status:',
          ', '.join(f'{m} {s}: {n}' for (m, s), n in sorted(counts.items())))
    for kind in sorted(counts):
        e = [frames[k]['estimate'] for k in stamps if kinds[k] == kind]
        print(f'  estimate {kind[0]:12s} {kind[1]:18s} wall p50/p99/max {_pct([x[0] for x in e])}'
              f', CPU p50/p99 {_pct([x[0] - x[1] - x[2] for x in e])[:15]}, FAM solves p50/max '
              f'{np.median([solves[k] for k in stamps if kinds[k] == kind]):.0f}/'
              f'{max(solves[k] for k in stamps if kinds[k] == kind)}')
    lt = lat.get('/catheter/tip_wrench')
    if lt:
        print(f'worker report: image -> tip force latency p50 {lt["p50_ms"]:.1f} ms, p99 '
              f'{lt["p99_ms"]:.1f} ms, max {lt["max_ms"]:.1f} ms ({lt["n"]} estimates)')
    for t in ('/master/rendered_force', '/slave/force', '/slave/impedance'):
        s = streams.get(t)
        if s:
            print(f'{t}: {s["rate_hz"]:.1f} Hz, period p99 {s["p99_ms"]:.3f} ms, max '
                  f'{s["max_ms"]:.2f} ms')
    for name, rep in sorted(r.processes.items()):
        if name != 'link':
            rt = rep.get('realtime', {})
            loop = rt.get('loop_s') or float('nan')
            threads = ', '.join(f'{t} {100 * c / loop:.1f}' for t, c in sorted(
                (rt.get('thread_cpu_s') or {}).items(), key=lambda kv: -kv[1])[:4])
            print(f'{name}: CPU {100 * B.cpu_share(rt):.0f} % of a core, {rt.get("scheduling")}, '
                  f'CPUs {rep.get("cpus") or "any"}; by thread, %: {threads}')


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--duration', type=float, default=6.0)
    ap.add_argument('--runs', type=int, default=1)
    ap.add_argument('--load', action='store_true', help='a busy-loop process on one core')
    ap.add_argument('--keep-bag', metavar='PATH', help='keep the (last) run\'s bag here, with '
                    'the control points and the camera\'s tip force truth recorded')
    a = ap.parse_args()
    record = ('/catheter/control_points', '/camera/tip_force_truth') if a.keep_bag else ()
    print(f'bench_vision_stages on {os.cpu_count()} cores, load average at start '
          f'{os.getloadavg()[0]:.1f}')
    for i in range(a.runs):
        with tempfile.TemporaryDirectory() as tmp:
            streams, lat, r, rows = run(a.duration, a.load, tmp, record)
            report(streams, lat, r, rows, f'run {i + 1}' + (' (loaded)' if a.load else ''))
            if a.keep_bag:
                import shutil
                shutil.copy(os.path.join(tmp, 'rt_split.mcap'), a.keep_bag)


if __name__ == '__main__':
    main()

"""CPU per frame of the vision process's per-frame work, offline (thread time: not the
machine's load, no preemption): camera_node's frame (the FAM shape and
`SyntheticCamera.render`), `ShapeSensor.process`, shape_node's `catheter/shape` message, and
force_estimator_node's estimate (its default estimator: the SVR with the FAM inversion as
fallback, 24 arcs).

    python tests/bench/bench_vision_cpu.py [--rounds 2] [--strides 1,2,3]

Frames: a `sim_slave.camera.TipCamera` (the system camera, 800 x 800) sweeping the insertion
8 -> 56 -> 8 mm (through the wall contact at 45 mm), 180 frames a round. The estimator runs
on the first round's control points as a stream, every frame and, for frames dropped while
the thread was busy (the real-time process drops stale frames, which changes the warm
starts), every k-th frame from each offset (`--strides`); per frame its CPU, the FAM solves
and, for the FAM fallback's normal estimates, the error against the camera's true tip force.
Where the inversion has `hold_unobservable` (round 10), both settings in the same run. To
compare with another checkout's code, run it there (or with that checkout's src/* first on
PYTHONPATH), alternating, in one session.
"""
from __future__ import annotations

import argparse
import os
import time

import numpy as np
from builtin_interfaces.msg import Time

from force_estimator.hybrid import make_estimator

import catheter_shape.shape_node as SN
from catheter_shape import ShapeSensor
from catheter_shape.camera import SYSTEM_CAMERA
from sim_slave.camera import TipCamera


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--rounds', type=int, default=2)
    ap.add_argument('--strides', default='1,2,3',
                    help='estimator streams: every k-th frame from each offset, k in this list')
    a = ap.parse_args()
    cam = TipCamera()
    sen = ShapeSensor(cam.psi, background=cam.camera.background,
                      base_px=SYSTEM_CAMERA['base_px'], length=0.065)
    path_out = SN.PathOut() if hasattr(SN, 'PathOut') else None     # older checkouts: none
    xs = np.concatenate([np.linspace(0.008, 0.056, 90), np.linspace(0.056, 0.008, 90)])
    cols = {'camera frame (FAM + render)': [], 'shape sensor': [], 'catheter/shape message': []}
    ok = 0
    cps, truth = [], []
    for rnd in range(a.rounds):
        for x in xs:
            t0 = time.thread_time()
            frame = cam.frame(x, 0.0)
            t1 = time.thread_time()
            obs = sen.process(frame.image)
            t2 = time.thread_time()
            if path_out is not None:
                path_out.fill(obs.points, Time(), 100)
            else:
                SN.points_to_path(obs.points, Time(), max_poses=100)
            t3 = time.thread_time()
            ok += obs.ok
            for k, dt in zip(cols, (t1 - t0, t2 - t1, t3 - t2), strict=True):
                cols[k].append(dt)
            if rnd == 0:
                cps.append(obs.control_points if obs.ok else None)
                truth.append(np.asarray(cam.tip_force(x, 0.0), dtype=float)[:2])
    print(f'bench_vision_cpu: {len(xs) * a.rounds} frames ({ok} ok), load average '
          f'{os.getloadavg()[0]:.1f}; CPU per frame, ms')
    print(f'{"":30s} {"median":>7s} {"mean":>7s} {"p99":>7s}')
    for k, v in cols.items():
        v = 1e3 * np.asarray(v)
        print(f'{k:30s} {np.median(v):7.2f} {v.mean():7.2f} {np.percentile(v, 99):7.2f}')
    # the chain's CPU per frame of the first round, without the estimate
    chain = 1e3 * np.sum([np.asarray(v[:len(xs)]) for v in cols.values()], axis=0)
    strides = [int(k) for k in a.strides.split(',')]
    estimate_table(cps, truth, chain, strides)


def estimate_stream(est, cps, truth, order):
    """The estimator on the frames `order` of a stream: per frame (CPU ms, FAM solves, method,
    status, error N or nan)."""
    out = []
    for i in order:
        cp = cps[i]
        if cp is None:
            continue
        t0 = time.thread_time()
        e = est.estimate(cp)
        dt = 1e3 * (time.thread_time() - t0)
        err = float(np.hypot(*(e.force - truth[i]))) if e.normal else float('nan')
        out.append((i, dt, int(getattr(e, 'solves', 0)), e.method, e.status, err))
    return out


def estimate_table(cps, truth, chain, strides):
    """Per setting of the FAM inversion's hold_unobservable (both where it exists, the
    settings alternated over the streams): the estimate's CPU and FAM solves per frame,
    the whole frame's CPU (camera + shape + message + estimate) and the FAM fallback's
    statuses and errors, over the streams of every stride and offset."""
    est = make_estimator('svr', n_arcs=24, fallback=True)
    fam = est.fam
    settings = [False, True] if hasattr(fam, 'hold_unobservable') else [None]
    streams = [list(range(off, len(cps), k)) for k in strides for off in range(k)]
    rows = {h: [] for h in settings}
    for j, order in enumerate(streams):
        for h in (settings if j % 2 == 0 else settings[::-1]):
            if h is not None:
                fam.hold_unobservable = h
            fam.reset()
            rows[h] += estimate_stream(est, cps, truth, order)
    print(f'estimator (svr + FAM fallback, 24 arcs) on {len(streams)} streams of the first '
          f'round (strides {strides}, every offset), CPU per frame, ms; FAM solves per frame')
    print(f'{"hold_unobservable":18s} {"frames":>6s} {"est p50":>7s} {"p99":>6s} {"max":>6s} '
          f'{"frame p50":>9s} {"p99":>6s} {"max":>6s} {"solves p50":>10s} {"p99":>4s} '
          f'{"max":>4s} {">= 9":>5s} {"all":>5s}  fallback statuses; error of its normal '
          f'estimates, mN: mean / p99 / max')
    for h, r in rows.items():
        cpu = np.array([x[1] for x in r])
        sol = np.array([x[2] for x in r])
        whole = cpu + chain[[x[0] for x in r]]
        fb = [x for x in r if x[3] == 'fam_fallback']
        st = {}
        for x in fb:
            st[x[4]] = st.get(x[4], 0) + 1
        err = 1e3 * np.array([x[5] for x in fb if np.isfinite(x[5])])
        e_txt = (f'{err.mean():.2f} / {np.percentile(err, 99):.2f} / {err.max():.2f}'
                 if err.size else 'n/a')
        print(f'{str(h):18s} {len(r):6d} {np.median(cpu):7.2f} {np.percentile(cpu, 99):6.2f} '
              f'{cpu.max():6.2f} {np.median(whole):9.2f} {np.percentile(whole, 99):6.2f} '
              f'{whole.max():6.2f} {np.median(sol):10.0f} {np.percentile(sol, 99):4.0f} '
              f'{sol.max():4d} {int(np.sum(sol >= 9)):5d} {int(sol.sum()):5d}  '
              f'{dict(sorted(st.items()))}; {e_txt}')


if __name__ == '__main__':
    main()

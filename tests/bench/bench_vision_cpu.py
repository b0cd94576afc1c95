"""CPU per frame of the vision process's per-frame work, offline (thread time: not the
machine's load, no preemption): camera_node's frame (the FAM shape and
`SyntheticCamera.render`), `ShapeSensor.process`, shape_node's `catheter/shape` message.

    python tests/bench/bench_vision_cpu.py [--rounds 2]

Frames: a `sim_slave.camera.TipCamera` (the system camera, 800 x 800) sweeping the insertion
8 -> 56 -> 8 mm (through the wall contact at 45 mm), 180 frames a round. To compare with
another checkout's code, run it there (or with that checkout's src/* first on PYTHONPATH),
alternating, in one session.
"""
from __future__ import annotations

import argparse
import os
import time

import numpy as np
from builtin_interfaces.msg import Time

import catheter_shape.shape_node as SN
from catheter_shape import ShapeSensor
from catheter_shape.camera import SYSTEM_CAMERA
from sim_slave.camera import TipCamera


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--rounds', type=int, default=2)
    a = ap.parse_args()
    cam = TipCamera()
    sen = ShapeSensor(cam.psi, background=cam.camera.background,
                      base_px=SYSTEM_CAMERA['base_px'], length=0.065)
    path_out = SN.PathOut() if hasattr(SN, 'PathOut') else None     # older checkouts: none
    xs = np.concatenate([np.linspace(0.008, 0.056, 90), np.linspace(0.056, 0.008, 90)])
    cols = {'camera frame (FAM + render)': [], 'shape sensor': [], 'catheter/shape message': []}
    ok = 0
    for _ in range(a.rounds):
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
    print(f'bench_vision_cpu: {len(xs) * a.rounds} frames ({ok} ok), load average '
          f'{os.getloadavg()[0]:.1f}; CPU per frame, ms')
    print(f'{"":30s} {"median":>7s} {"mean":>7s} {"p99":>7s}')
    for k, v in cols.items():
        v = 1e3 * np.asarray(v)
        print(f'{k:30s} {np.median(v):7.2f} {v.mean():7.2f} {np.percentile(v, 99):7.2f}')


if __name__ == '__main__':
    main()

"""Benchmark of catheter_shape: synthetic camera frames of Blazer shapes -> control points.

Blazer II-XP (65 mm, EI 6e-5 N m^2) under tip forces 0-0.3 N at angles in [0, pi] and
mirrored (fam_solver, follower False, 12 arcs), drawn by SyntheticCamera at several noise
levels, measured by ShapeSensor (background removal + threshold 132, base_px given).

Per configuration: median time per stage and end to end, frames/s; centreline error (mean
and max distance of the measured points to the true centreline), tip error; the fitted
curve's deviation from the true centreline beside the best cubic the true shape allows
(a fit of the true centreline itself); residual beside the thesis's 0.12 +- 0.05 mm.
Same-run references: the thesis's chord-length fit (refine=0) on the same points, and
scikit-image skeletonize on the full frame instead of the cropped mask.

    python tests/bench/bench_shape.py [--frames 240] [--seed 0]
"""
from __future__ import annotations

import argparse
import os
import time
from collections import Counter

import numpy as np
from scipy.spatial import cKDTree
from skimage.morphology import skeletonize

from catheter_shape import ShapeSensor, SyntheticCamera, bezier_eval, fit_bezier_detailed
from catheter_shape.segmentation import threshold_frame

L = 0.065
EI = 6.0e-5
F_MAX = 0.3
NOISES = (2.0, 6.0, 12.0)


def blazer_centerlines(n: int, seed: int, k: int = 400):
    """n FAM shapes (n, k, 2) m under random tip forces (|F| <= 0.3 N, angle in [-pi, pi])."""
    from fam_solver import Catheter, solve_fam_batch
    rng = np.random.default_rng(seed)
    mag = rng.uniform(0.0, F_MAX, n)
    ang = rng.uniform(0.0, np.pi, n) * rng.choice([-1.0, 1.0], n)     # [0, pi] and mirrored
    F = np.stack([mag * np.cos(ang), mag * np.sin(ang)], axis=1)
    b = solve_fam_batch(Catheter(length=L, ei=EI), F, np.zeros(n), n_arcs=12)
    return b.centerlines(k), F, np.asarray(b.converged, bool)


def densify(c: np.ndarray, step: float = 1e-5) -> np.ndarray:
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(c, axis=0), axis=1))])
    t = np.linspace(0.0, s[-1], int(s[-1] / step) + 2)
    return np.stack([np.interp(t, s, c[:, 0]), np.interp(t, s, c[:, 1])], axis=1)


def med(x):
    return float(np.median(x)) if len(x) else float('nan')


def run_config(name, cam_kw, centerlines, frames, seed, require_in_view):
    sensors = {nz: None for nz in NOISES}
    cams = {nz: SyntheticCamera(seed=seed, noise=nz, **cam_kw) for nz in NOISES}
    rng = np.random.default_rng(seed + 1)
    rows = []
    statuses = Counter()
    skipped = 0
    ref_skel = []
    i = 0
    for c in centerlines:
        if sum(statuses.values()) >= frames:
            break
        nz = NOISES[i % len(NOISES)]
        cm = cams[nz]
        t0 = time.perf_counter()
        f = cm.render(c, rng=rng)
        t_render = time.perf_counter() - t0
        if require_in_view and not f.in_view:
            skipped += 1
            continue
        i += 1
        if sensors[nz] is None:
            sensors[nz] = ShapeSensor(f.psi, background=f.background, base_px=cm.base_px)
        obs = sensors[nz].process(f.image)
        statuses[obs.status] += 1
        if not obs.ok:
            continue
        truth = densify(c)
        tree = cKDTree(truth)
        d_pts = tree.query(obs.points[:, :2])[0]
        curve = bezier_eval(obs.control_points[:, :2], np.linspace(0, 1, 400))
        d_bez = tree.query(curve)[0]
        d_bez_back = cKDTree(curve).query(truth[::10])[0]
        best = fit_bezier_detailed(c, 3, refine=30, correction='orthogonal')
        best_curve = bezier_eval(best.control_points, np.linspace(0, 1, 400))
        d_best = tree.query(best_curve)[0]
        # the thesis's fit of the same measured points: chord-length parameters, no correction
        t1 = time.perf_counter()
        thesis = fit_bezier_detailed(obs.points[:, :2], 3, refine=0)
        t_thesis = time.perf_counter() - t1
        thesis_curve = bezier_eval(thesis.control_points, np.linspace(0, 1, 400))
        d_thesis = tree.query(thesis_curve)[0]
        t1 = time.perf_counter()
        orth = fit_bezier_detailed(obs.points[:, :2], 3, refine=10, correction='orthogonal')
        t_orth = time.perf_counter() - t1
        d_orth = tree.query(bezier_eval(orth.control_points, np.linspace(0, 1, 400)))[0]
        # reference for the skeleton stage: skeletonize the full frame (no crop)
        if len(ref_skel) < 60:
            m, _, _ = threshold_frame(f.image, 132, f.background)
            t2 = time.perf_counter()
            skeletonize(m > 0)
            ref_skel.append(time.perf_counter() - t2)
        rows.append(dict(
            noise=nz, t=obs.timings, t_render=t_render, t_thesis=t_thesis, t_orth=t_orth,
            orth_mean=d_orth.mean(), orth_res=orth.residual,
            mean=d_pts.mean(), max=d_pts.max(), tip=np.linalg.norm(obs.points[-1, :2] - c[-1]),
            base=np.linalg.norm(obs.points[0, :2] - c[0]),
            bez_mean=d_bez.mean(), bez_max=max(d_bez.max(), d_bez_back.max()),
            best_mean=d_best.mean(), best_max=d_best.max(),
            thesis_mean=d_thesis.mean(), thesis_max=d_thesis.max(),
            residual=obs.residual, thesis_res=thesis.chord_residual))
    return rows, statuses, skipped, ref_skel


def table(title, lines):
    w = max(len(r[0]) for r in lines)
    out = [title, f'{"what".ljust(w)} | {"this project":>14} | {"reference":>28} | {"ratio":>7}',
           '-' * (w + 60)]
    for what, ours, ref, ratio in lines:
        out.append(f'{what.ljust(w)} | {ours:>14} | {ref:>28} | {ratio:>7}')
    print('\n'.join(out) + '\n')


def report(name, rows, statuses, skipped, ref_skel):
    n_ok = len(rows)
    n = sum(statuses.values())
    T = lambda k: [r['t'][k] * 1e3 for r in rows if k in r['t']]  # noqa: E731
    tot = med(T('total'))
    mm = lambda k, f=np.mean: f([r[k] for r in rows]) * 1e3  # noqa: E731
    skel_ours = med([r['t']['skeleton'] * 1e3 for r in rows])
    skel_ref = med(np.array(ref_skel) * 1e3)
    fit_ours = med(T('fit'))
    fit_ref = med([r['t_thesis'] * 1e3 for r in rows])
    lines = [
        ('frames measured / ok', f'{n} / {n_ok}', f'{skipped} out of view skipped', ''),
        ('statuses', ', '.join(f'{k}:{v}' for k, v in sorted(statuses.items())), '', ''),
    ]
    for k in ('threshold', 'component', 'skeleton', 'ends', 'fit'):
        lines.append((f'median {k} ms', f'{med(T(k)):.3f}', '', ''))
    lines += [
        ('median end to end ms', f'{tot:.3f}', 'target 5 ms', f'{tot / 5.0:.2f}'),
        ('frames/s (1 / median)', f'{1e3 / tot:.0f}', '', ''),
        ('p10 / min end to end ms (less preempted)',
         f'{np.percentile(T("total"), 10):.3f} / {np.min(T("total")):.3f}', 'target 5 ms',
         f'{np.percentile(T("total"), 10) / 5.0:.2f}'),
        ('median / p10 render ms (camera)',
         f'{med([r["t_render"] * 1e3 for r in rows]):.3f} / '
         f'{np.percentile([r["t_render"] * 1e3 for r in rows], 10):.3f}', '', ''),
        ('skeleton+order ms vs full-frame skeletonize', f'{skel_ours:.3f}',
         f'{skel_ref:.3f} (skeletonize only)', f'{skel_ours / skel_ref:.2f}'),
        ('fit ms (sensor: regularized) vs thesis chord fit', f'{fit_ours:.3f}',
         f'{fit_ref:.3f}', f'{fit_ours / fit_ref:.2f}'),
        ('  (orthogonal fit of the same points, ms)', f'{med([r["t_orth"] * 1e3 for r in rows]):.3f}',
         '', ''),
        ('centreline error mean mm', f'{mm("mean"):.4f}', 'target 0.1', f'{mm("mean") / 0.1:.2f}'),
        ('centreline error max mm (mean of frame max)', f'{mm("max"):.4f}', '', ''),
        ('centreline error max mm (worst frame)', f'{mm("max", np.max):.4f}', '', ''),
        ('tip error mm mean', f'{mm("tip"):.3f}', 'target 0.5', f'{mm("tip") / 0.5:.2f}'),
        ('tip error mm p95', f'{mm("tip", lambda x: np.percentile(x, 95)):.3f}', 'target 0.5',
         f'{mm("tip", lambda x: np.percentile(x, 95)) / 0.5:.2f}'),
        ('base error mm mean', f'{mm("base"):.3f}', '', ''),
        ('Bezier deviation mean mm vs best cubic', f'{mm("bez_mean"):.4f}',
         f'{mm("best_mean"):.4f} (best cubic)', f'{mm("bez_mean") / mm("best_mean"):.2f}'),
        ('Bezier deviation max mm vs best cubic', f'{mm("bez_max"):.4f}',
         f'{mm("best_max"):.4f} (best cubic)', f'{mm("bez_max") / mm("best_max"):.2f}'),
        ('Bezier deviation mean mm vs thesis fit', f'{mm("bez_mean"):.4f}',
         f'{mm("thesis_mean"):.4f} (chord-length fit)',
         f'{mm("bez_mean") / mm("thesis_mean"):.2f}'),
        ('Bezier deviation mean mm vs orthogonal fit', f'{mm("bez_mean"):.4f}',
         f'{mm("orth_mean"):.4f} (orthogonal fit)',
         f'{mm("bez_mean") / mm("orth_mean"):.2f}'),
        ('residual mm (perpendicular) mean +- std', f'{mm("residual"):.4f} +- '
         f'{mm("residual", np.std):.4f}', 'thesis 0.12 +- 0.05', f'{mm("residual") / 0.12:.2f}'),
        ('thesis-style residual mm (chord params)', f'{mm("thesis_res"):.4f}',
         'thesis 0.12 +- 0.05', f'{mm("thesis_res") / 0.12:.2f}'),
        ('residual mm of the orthogonal fit', f'{mm("orth_res"):.4f}', 'thesis 0.12 +- 0.05',
         f'{mm("orth_res") / 0.12:.2f}'),
    ]
    table(f'== {name} ==', lines)
    # per noise level
    print(f'{name}: per noise level (grey levels)')
    print(f'{"noise":>6} {"frames":>6} {"mean mm":>8} {"max mm":>8} {"tip mm":>7} '
          f'{"bez mm":>7} {"resid mm":>8} {"e2e ms":>7}')
    for nz in NOISES:
        rs = [r for r in rows if r['noise'] == nz]
        if not rs:
            continue
        print(f'{nz:6.0f} {len(rs):6d} {np.mean([r["mean"] for r in rs]) * 1e3:8.4f} '
              f'{np.max([r["max"] for r in rs]) * 1e3:8.4f} '
              f'{np.mean([r["tip"] for r in rs]) * 1e3:7.3f} '
              f'{np.mean([r["bez_mean"] for r in rs]) * 1e3:7.4f} '
              f'{np.mean([r["residual"] for r in rs]) * 1e3:8.4f} '
              f'{med([r["t"]["total"] * 1e3 for r in rs]):7.3f}')
    print()


def jitter(centerlines, seed, cam_kw, label, n_shapes=6):
    """Control-point spread over 20 noise draws of the same shape (noise 6): the sensor's
    default (regularized) fit vs the thesis's chord-length fit and the orthogonal fit
    (the control points are the force estimator's features)."""
    cam = SyntheticCamera(noise=6.0, seed=seed, **cam_kw)
    fits = {'regularized': dict(), 'thesis': dict(refine=0),
            'orthogonal': dict(correction='orthogonal', refine=10)}
    out = {k: [] for k in fits}
    used = 0
    for c in centerlines:
        if not cam.render(c).in_view:
            continue
        for name, kw in fits.items():
            s = ShapeSensor(cam.psi, background=cam.background, base_px=cam.base_px, **kw)
            rng = np.random.default_rng(seed)
            obs = [s.process(cam.render(c, rng=rng).image) for _ in range(20)]
            cps = np.array([o.control_points[:, :2] for o in obs if o.ok])
            out[name].append(cps.std(axis=0).mean(axis=1) * 1e3)        # (4,) mm
        used += 1
        if used >= n_shapes:
            break
    a = np.mean(out['regularized'], axis=0)
    b = np.mean(out['thesis'], axis=0)
    c = np.mean(out['orthogonal'], axis=0)
    lines = []
    for i in range(4):
        lines.append((f'p{i} spread mm vs thesis fit', f'{a[i]:.4f}', f'{b[i]:.4f} (thesis fit)',
                      f'{a[i] / b[i]:.2f}'))
        lines.append((f'p{i} spread mm vs orthogonal fit', f'{a[i]:.4f}',
                      f'{c[i]:.4f} (orthogonal)', f'{a[i] / c[i]:.2f}'))
    table(f'== control-point jitter (std over 20 noise draws, noise 6): {used} shapes, '
          f'{label} ==', lines)


def tissue(centerlines, seed, n=60):
    cam = SyntheticCamera(noise=6.0, seed=seed, width=1024, height=1024, angle=-np.pi / 2,
                          base_px=(512, 230))
    s = ShapeSensor(cam.psi, background=None, base_px=cam.base_px)
    rng = np.random.default_rng(seed)
    ok, tips, means = 0, [], []
    for c in centerlines[:n]:
        f = cam.render(c, rng=rng, tissue_depth=0.004)
        s.set_background(f.background)
        o = s.process(f.image)
        if not o.ok:
            continue
        ok += 1
        vis = densify(f.visible_centerline_m)
        tips.append(np.linalg.norm(o.points[-1, :2] - vis[-1]))
        means.append(cKDTree(vis).query(o.points[:, :2])[0].mean())
    table(f'== tissue hides the last 4 mm: {n} frames 1024x1024 @ 0.15 mm/px, noise 6 ==', [
        ('ok frames', f'{ok}/{n}', '', ''),
        ('tip error vs visible end mm mean', f'{np.mean(tips) * 1e3:.3f}', 'target 0.5',
         f'{np.mean(tips) * 1e3 / 0.5:.2f}'),
        ('centreline error vs visible part mm', f'{np.mean(means) * 1e3:.4f}', 'target 0.1',
         f'{np.mean(means) * 1e3 / 0.1:.2f}')])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--frames', type=int, default=240, help='frames per configuration')
    ap.add_argument('--seed', type=int, default=0)
    a = ap.parse_args()
    t0 = time.perf_counter()
    cl, F, conv = blazer_centerlines(4000, a.seed)
    cl = cl[conv]
    print(f'{len(cl)} converged FAM Blazer shapes (of 4000), |F| <= {F_MAX} N, all angles\n'
          'timings: one process on a 2-core machine shared with other jobs (noisy); load '
          f'average at the start: {" ".join(f"{x:.1f}" for x in os.getloadavg())}\n')
    configs = [
        ('640x480 @ 0.15 mm/px (shapes fully in view)',
         dict(width=640, height=480, mm_per_px=0.15), True),
        ('640x480 @ 0.25 mm/px (all shapes; catheter pointing down)',
         dict(width=640, height=480, mm_per_px=0.25, angle=-np.pi / 2, base_px=(320, 130)), False),
        ('1024x1024 @ 0.15 mm/px (all shapes; catheter pointing down)',
         dict(width=1024, height=1024, mm_per_px=0.15, angle=-np.pi / 2, base_px=(512, 230)),
         False),
    ]
    for k, (name, kw, in_view) in enumerate(configs):
        rows, st, skipped, ref = run_config(name, kw, cl, a.frames, a.seed + k, in_view)
        report(name, rows, st, skipped, ref)
    jitter(cl, a.seed, configs[0][1], '640x480 @ 0.15 mm/px')
    jitter(cl, a.seed, configs[2][1], '1024x1024 @ 0.15 mm/px')
    tissue(cl, a.seed)
    print(f'bench time {time.perf_counter() - t0:.0f} s; load average at the end: '
          f'{" ".join(f"{x:.1f}" for x in os.getloadavg())} (2 cores)')


if __name__ == '__main__':
    main()

"""Benchmark of tip force estimation (force_estimator), printed as tables.

Held-out data that no model saw: random tip forces off the thesis grid (magnitude uniform in
[0.01, 0.3] N, angle uniform in [0, pi]), shapes from the reference rod solver
`fam_solver.solve_elastica` (not FAM, which generated the training data), rendered by the
synthetic camera with a different seed and clamp position than the training camera, then
the full image pipeline (ShapeSensor: background removal, threshold, skeleton, Bezier fit)
-> estimator. Methods: the shipped blazer-svr and blazer-mlp, and FamInverseEstimator.

Also: single-sample latency of the numpy forward passes against scikit-learn's predict of
the same model (trained here on the rendered thesis grid), training times, FAM inversion
latency cold (table start) and warm (a slowly varying stream) beside the same estimator with
the previous forward-difference Jacobian (solver='single', three FAM solves per iteration)
measured in the same run, and the thesis's numbers.

Run: scripts/bench force   (or python tests/bench/bench_force.py [--n 150])
"""
from __future__ import annotations

import argparse
import pathlib
import sys
import time

ROOT = pathlib.Path(__file__).resolve().parents[2]
for _p in sorted((ROOT / 'src').iterdir()):
    if (_p / 'package.xml').exists() and str(_p) not in sys.path:
        sys.path.insert(0, str(_p))

import numpy as np  # noqa: E402

F_FULL = 0.3
#: the benchmark camera: same optics as training, another clamp pixel, another noise seed
BENCH_CAMERA = dict(width=800, height=800, mm_per_px=0.15, base_px=(270.0, 395.0), seed=777)


def table(title, rows, header=('what', 'this project', 'reference', 'ratio')):
    print(f'\n## {title}\n')
    w = [max(len(str(r[i])) for r in rows + [header]) for i in range(len(header))]
    print('| ' + ' | '.join(str(h).ljust(w[i]) for i, h in enumerate(header)) + ' |')
    print('|' + '|'.join('-' * (x + 2) for x in w) + '|')
    for r in rows:
        print('| ' + ' | '.join(str(c).ljust(w[i]) for i, c in enumerate(r)) + ' |')


def timeit(fn, n=2000, repeat=3):
    """Median-of-repeats time per call, s."""
    best = []
    for _ in range(repeat):
        t = time.perf_counter()
        for _ in range(n):
            fn()
        best.append((time.perf_counter() - t) / n)
    return float(np.median(best))


def held_out(n, seed, tissue_depth=0.0):
    from fam_solver import Catheter, Loads, solve_elastica

    from force_estimator import dataset as D
    rng = np.random.default_rng(seed)
    mag = rng.uniform(0.01, F_FULL, n)
    ang = rng.uniform(0.0, np.pi, n)
    F = np.stack([mag * np.cos(ang), mag * np.sin(ang)], axis=1)
    cat = Catheter(length=D.BLAZER_LENGTH, ei=D.BLAZER_EI)
    cls, ok = [], []
    t0 = time.perf_counter()
    for f in F:
        s = solve_elastica(cat, Loads(tip_force=(float(f[0]), float(f[1]))))
        ok.append(bool(s.converged))
        cls.append(s.centerline(200))
    t_ref = time.perf_counter() - t0
    cp, seen, t_sense = D.render_control_points(np.array(cls), seed=seed,
                                                camera_kwargs=BENCH_CAMERA, return_timing=True,
                                                tissue_depth=tissue_depth)
    keep = np.array(ok) & seen
    return F[keep], cp[keep], dict(n=n, ref_failed=int((~np.array(ok)).sum()),
                                   sensor_failed=int((np.array(ok) & ~seen).sum()),
                                   t_ref=t_ref, t_sense=np.nanmedian(t_sense))


def errors(est, true):
    e = np.hypot(*(est - true).T)
    m = np.abs(np.hypot(*est.T) - np.hypot(*true.T))
    return dict(mae=e.mean(), rmse=np.sqrt((e ** 2).mean()), max=e.max(), mag_mae=m.mean())


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument('--n', type=int, default=150, help='held-out frames')
    ap.add_argument('--seed', type=int, default=2024)
    ap.add_argument('--models', default='', help='folder with blazer-svr.npz / blazer-mlp.npz '
                    'to use instead of the shipped models')
    a = ap.parse_args(argv)
    from fam_solver import Catheter

    from force_estimator import FamInverseEstimator, load_estimator
    from force_estimator import dataset as D
    from force_estimator.training import fit_mlp, fit_svr, sklearn_predict

    t_all = time.perf_counter()
    print('fam = FamInverseEstimator with 24 arcs (the node default), fam12 = 12 arcs')
    print(f'# force_estimator benchmark ({a.n} held-out frames, seed {a.seed}); timings on a '
          f'shared 2-core machine are noisy')
    F, cp, info = held_out(a.n, a.seed)
    print(f'held-out: {len(F)} frames used ({info["ref_failed"]} reference solves failed, '
          f'{info["sensor_failed"]} frames rejected by the sensor); solve_elastica '
          f'{info["t_ref"]:.1f} s total, ShapeSensor median {1e3 * info["t_sense"]:.1f} ms/frame')

    if a.models:
        svr = load_estimator(str(pathlib.Path(a.models) / 'blazer-svr.npz'))
        mlp = load_estimator(str(pathlib.Path(a.models) / 'blazer-mlp.npz'))
    else:
        svr = load_estimator('blazer-svr')
        mlp = load_estimator('blazer-mlp')
    cat = Catheter(length=D.BLAZER_LENGTH, ei=D.BLAZER_EI)
    t = time.perf_counter()
    fam = FamInverseEstimator(cat, n_arcs=24)
    t_fam_init = time.perf_counter() - t
    fam12 = FamInverseEstimator(cat, n_arcs=12)
    fam_fd = FamInverseEstimator(cat, n_arcs=24, solver='single')   # same-run reference

    from force_estimator.train import fingerprint_drift
    print(f'camera-path drift since the shipped models were trained: '
          f'{1e3 * fingerprint_drift(svr):.3f} mm (control points of 3 fixed shapes; '
          f'retrain with python -m force_estimator.train if this is not ~0)')
    res, flags, lat = {}, {}, {}
    for name, est in (('svr', svr), ('mlp', mlp)):
        P, fl = est.predict(cp, return_flags=True)
        res[name], flags[name] = P, fl
    P, fl, tt, resid, solves = [], [], [], [], []
    for c in cp:
        fam.reset()                                 # independent frames: cold start each
        t = time.perf_counter()
        r = fam.estimate(c)
        tt.append(time.perf_counter() - t)
        P.append(r.force)
        fl.append(r.in_envelope)
        resid.append(r.residual)
        solves.append(r.solves)
    res['fam'], flags['fam'] = np.array(P), np.array(fl)
    lat['fam_cold'] = np.array(tt)
    P, tt, solves_fd = [], [], []
    for c in cp:
        fam_fd.reset()
        t = time.perf_counter()
        r = fam_fd.estimate(c)
        tt.append(time.perf_counter() - t)
        P.append(r.force)
        solves_fd.append(r.solves)
    res['fam_fd'] = np.array(P)
    lat['fam_fd_cold'] = np.array(tt)
    P, fl, tt = [], [], []
    for c in cp:
        fam12.reset()
        t = time.perf_counter()
        r = fam12.estimate(c)
        tt.append(time.perf_counter() - t)
        P.append(r.force)
        fl.append(r.in_envelope)
    res['fam12'], flags['fam12'] = np.array(P), np.array(fl)
    lat['fam12_cold'] = np.array(tt)

    # accuracy table
    ang = np.arctan2(F[:, 1], F[:, 0])
    lateral = np.abs(np.sin(ang)) >= np.sin(np.pi / 8)
    thesis = {'svr': (0.0178, 917.0), 'mlp': (0.0217, 646.0), 'fam': (None, None),
              'fam12': (None, None)}
    rows = []
    for name in ('svr', 'mlp', 'fam', 'fam12'):
        e = errors(res[name], F)
        el = errors(res[name][lateral], F[lateral])
        th = thesis[name][0]
        rows.append((f'{name}: MAE |f - f_true|, N (% of 0.3 N)',
                     f'{e["mae"]:.4f} ({100 * e["mae"] / F_FULL:.1f} %)',
                     f'{th:.4f} ({100 * th / F_FULL:.1f} %) thesis ex-vivo' if th else
                     '0.009 (3 %) target', f'{e["mae"] / (th or 0.009):.2f}'))
        rows.append((f'{name}: RMSE, N (%)', f'{e["rmse"]:.4f} ({100 * e["rmse"] / F_FULL:.1f} %)',
                     {'svr': '0.0166 (5.5 %)', 'mlp': '0.0191 (6.4 %)'}.get(name, '-'), ''))
        rows.append((f'{name}: max error, N (%)', f'{e["max"]:.4f} ({100 * e["max"] / F_FULL:.1f} %)',
                     '-', ''))
        rows.append((f'{name}: MAE of |f| (thesis metric), N', f'{e["mag_mae"]:.4f}',
                     f'{th:.4f}' if th else '-', f'{e["mag_mae"] / th:.2f}' if th else ''))
        rows.append((f'{name}: MAE off the axial cones (|sin angle| >= sin(pi/8), n={lateral.sum()})',
                     f'{el["mae"]:.4f} ({100 * el["mae"] / F_FULL:.1f} %)', '-', ''))
        rows.append((f'{name}: flagged out of envelope', f'{int((~flags[name]).sum())} / {len(F)}',
                     '-', ''))
    table('Accuracy on held-out elastica frames through the image pipeline', rows)

    # error by force direction (what limits the error)
    edges = np.linspace(0, np.pi, 9)
    rows = []
    for lo, hi in zip(edges[:-1], edges[1:]):
        k = (ang >= lo) & (ang < hi)
        if k.any():
            rows.append((f'{np.degrees(lo):.0f}-{np.degrees(hi):.0f} deg (n={k.sum()})',
                         *[f'{np.hypot(*(res[m][k] - F[k]).T).mean():.4f}'
                           for m in ('svr', 'mlp', 'fam', 'fam12')]))
    table('MAE (N) by force angle (0 deg = pure pull along the catheter)', rows,
          header=('force angle', 'svr', 'mlp', 'fam (24 arcs)', 'fam (12 arcs)'))

    # tissue hiding the tip (the thesis's ex-vivo frames): 3 mm of the tip not visible
    n_t = min(60, a.n)
    Ft, cpt, _ = held_out(n_t, a.seed + 1, tissue_depth=0.003)
    rows = []
    kt = np.abs(np.sin(np.arctan2(Ft[:, 1], Ft[:, 0]))) >= np.sin(np.pi / 8)
    for name, est in (('svr', svr), ('mlp', mlp), ('fam', fam)):
        if name == 'fam':
            P = []
            for c in cpt:
                fam.reset()
                P.append(fam.estimate(c).force)
            P, fl = np.array(P), None
        else:
            P, fl = est.predict(cpt, return_flags=True)
        e = errors(P, Ft)
        el = errors(P[kt], Ft[kt])
        rows.append((name, f'{e["mae"]:.4f} ({100 * e["mae"] / F_FULL:.1f} %)',
                     f'{el["mae"]:.4f} ({100 * el["mae"] / F_FULL:.1f} %)',
                     '-' if fl is None else f'{int((~fl).sum())} / {len(Ft)}'))
    table(f'3 mm of the tip hidden by tissue ({len(Ft)} held-out frames)', rows,
          header=('method', 'MAE, N (%)', 'MAE off the axial cones', 'flagged'))

    # latency: numpy forward vs sklearn predict of the same (grid-trained) model
    grid = D.make_dataset(D.thesis_grid(), render=True, seed=5, progress=False)
    tr = (grid['split'] == 0) & (np.abs(np.sin(grid['angle'])) > 1e-9)
    t = time.perf_counter()
    svr_g, _ = fit_svr(grid['X'][tr], grid['Y'][tr])
    t_svr = time.perf_counter() - t
    t = time.perf_counter()
    mlp_g, _ = fit_mlp(grid['X'][tr], grid['Y'][tr], n_init=3, max_iter=1000)
    t_mlp = time.perf_counter() - t
    x1 = cp[0]
    xf = x1.reshape(1, 12)
    rows = []
    for name, m, shipped, thz in (('svr', svr_g, svr, 917.0), ('mlp', mlp_g, mlp, 646.0)):
        t_np = timeit(lambda: m.predict(x1))
        t_sk = timeit(lambda: sklearn_predict(m, xf), n=300)
        t_sh = timeit(lambda: shipped.predict(x1))
        lat[name] = t_sh
        rows.append((f'{name} (grid model): numpy forward, us/estimate', f'{1e6 * t_np:.1f}',
                     f'{1e6 * t_sk:.1f} sklearn predict', f'{t_sk / t_np:.0f}x faster'))
        rows.append((f'{name} (shipped {shipped.name}): numpy, estimates/s', f'{1 / t_sh:,.0f}',
                     f'{thz:.0f} Hz thesis', f'{(1 / t_sh) / thz:.0f}x'))
        assert np.allclose(m.predict(cp), sklearn_predict(m, cp.reshape(-1, 12)), atol=1e-10)
    Pb = cp[:64]
    rows.append(('svr shipped: batch of 64, us/estimate',
                 f'{1e6 * timeit(lambda: svr.predict(Pb), n=200) / 64:.2f}', '-', ''))
    # FAM inversion, cold and warm (a stream whose force drifts 2 mN per frame)
    fam.reset()
    drift = np.array([[0.05 + 0.002 * i, 0.08 + 0.001 * i] for i in range(40)])
    from fam_solver import Loads, solve_fam
    stream = [solve_fam(cat, Loads(tip_force=tuple(f)), n_arcs=24).centerline(200) for f in drift]
    scp = D.render_control_points(np.array(stream), seed=9, camera_kwargs=BENCH_CAMERA)[0]
    fam_fd.reset()
    tw, tw_fd, sw, sw_fd = [], [], [], []
    for c in scp:
        if np.isfinite(c).all():
            t = time.perf_counter()
            sw.append(fam.estimate(c).solves)
            tw.append(time.perf_counter() - t)
            t = time.perf_counter()
            sw_fd.append(fam_fd.estimate(c).solves)
            tw_fd.append(time.perf_counter() - t)
    rows.append(('fam 12 arcs: cold start, median ms/estimate',
                 f'{1e3 * np.median(lat["fam12_cold"]):.2f}', '2 ms target',
                 f'{np.median(lat["fam12_cold"]) / 2e-3:.2f}'))
    rows.append(('fam 24 arcs: cold start (table), median ms/estimate',
                 f'{1e3 * np.median(lat["fam_cold"]):.2f}', '2 ms target',
                 f'{np.median(lat["fam_cold"]) / 2e-3:.2f}'))
    rows.append(('  the same beside the finite-difference Jacobian (solver=single), ms',
                 f'{1e3 * np.median(lat["fam_cold"]):.2f}',
                 f'{1e3 * np.median(lat["fam_fd_cold"]):.2f} fd',
                 f'{np.median(lat["fam_fd_cold"]) / np.median(lat["fam_cold"]):.1f}x faster'))
    rows.append(('fam 24 arcs: cold start, p90 ms',
                 f'{1e3 * np.percentile(lat["fam_cold"], 90):.2f}',
                 f'{1e3 * np.percentile(lat["fam_fd_cold"], 90):.2f} fd', ''))
    rows.append(('fam 24 arcs: warm start (stream), median ms/estimate', f'{1e3 * np.median(tw):.2f}',
                 '2 ms target', f'{np.median(tw) / 2e-3:.2f}'))
    rows.append(('  the same beside the finite-difference Jacobian, ms',
                 f'{1e3 * np.median(tw):.2f}', f'{1e3 * np.median(tw_fd):.2f} fd',
                 f'{np.median(tw_fd) / np.median(tw):.1f}x faster'))
    rows.append(('fam 24 arcs: FAM solves per estimate, mean, cold', f'{np.mean(solves):.1f}',
                 f'{np.mean(solves_fd):.1f} fd', ''))
    rows.append(('fam 24 arcs: FAM solves per estimate, mean, warm', f'{np.mean(sw):.1f}',
                 f'{np.mean(sw_fd):.1f} fd', ''))
    e_an, e_fd = errors(res['fam'], F), errors(res['fam_fd'], F)
    rows.append(('fam 24 arcs: MAE, N (analytic vs fd Jacobian, same frames)',
                 f'{e_an["mae"]:.5f}', f'{e_fd["mae"]:.5f} fd', f'{e_an["mae"] / e_fd["mae"]:.3f}'))
    rows.append(('fam 24 arcs: max |f_analytic - f_fd| over the frames, N',
                 f'{np.hypot(*(res["fam"] - res["fam_fd"]).T).max():.2e}', '-', ''))
    from fam_solver import solve_fam_batch
    f3 = np.array([[0.05, 0.1], [0.0501, 0.1], [0.05, 0.1001]])
    t_call = timeit(lambda: solve_fam_batch(cat, f3, np.zeros(3), n_arcs=24).points_at(
        np.linspace(0, 1, 24)), n=100)
    rows.append(('one solve_fam_batch call (3 forces, 24 arcs) + points, ms',
                 f'{1e3 * t_call:.2f}', '-', ''))
    from fam_solver import Loads as _L
    s0 = solve_fam(cat, _L(tip_force=(0.05, 0.1)), n_arcs=24)
    sfr = np.linspace(0, 1, 24)
    t_one = timeit(lambda: solve_fam(cat, _L(tip_force=(0.0501, 0.1)), n_arcs=24,
                                     initial=s0).points_at(sfr), n=200)
    rows.append(('one warm-started solve_fam (24 arcs) + points, ms (what the inversion uses)',
                 f'{1e3 * t_one:.3f}', '-', ''))
    from fam_solver.sensitivity import shape_sensitivity
    s1 = solve_fam(cat, _L(tip_force=(0.0501, 0.1)), n_arcs=24)
    t_sens = timeit(lambda: shape_sensitivity(s1, (0.0501, 0.1), sfr, cat.ei), n=500)
    rows.append(('one shape_sensitivity (24 arcs, 24 points): points, d points/d f, tangents, ms',
                 f'{1e3 * t_sens:.3f}', '-', ''))
    rows.append(('fam: residual median, mm', f'{1e3 * np.median(resid):.3f}', '-', ''))
    rows.append(('fam: start-table construction, s', f'{t_fam_init:.2f}', '-', ''))
    table('Speed (single sample unless stated)', rows)

    te = (grid['split'] == 1)
    rows = []
    for name, m, ref in (('SVR', svr_g, 0.010), ('MLP 1x10', mlp_g, 0.0113)):
        P = m.predict_features(grid['X'][te])
        mae = np.abs(np.hypot(*P.T) - grid['magnitude'][te]).mean()
        rows.append((f'{name} on the thesis grid, 30 % test part, MAE of |f|, N (rendered '
                     f'features, n={te.sum()})', f'{mae:.4f}', f'{ref:.4f} thesis (FE shapes)',
                     f'{mae / ref:.2f}'))
    table('The thesis experiment (16 x 25 grid, 70:30 split)', rows)
    rows = [('SVR fit (thesis grid, 70 %, with the epsilon/gamma search), s', f'{t_svr:.2f}', '-', ''),
            ('MLP 1x10 fit (thesis grid, 70 %, best of 3 inits), s', f'{t_mlp:.2f}', '-', '')]
    for m in (svr, mlp):
        h = m.header
        rows.append((f'shipped {m.name}: recipe {h.get("dataset", {}).get("features")}, '
                     f'{h.get("n_train")} samples, fit s', f'{h.get("fit_time_s", float("nan")):.1f}',
                     '-', ''))
    table('Training', rows)
    print(f'\nbenchmark wall time {time.perf_counter() - t_all:.0f} s')


if __name__ == '__main__':
    from threadpoolctl import threadpool_limits
    with threadpool_limits(limits=1):      # shared machine: one BLAS thread (see train.py)
        main()

"""Rebuild the shipped default models: ``python -m force_estimator.train``.

Recipe (deterministic, seeded; about a minute on one core):

1. The thesis data set: the 16 x 25 grid of tip forces on the Blazer II-XP catheter, FAM
   shapes, Bezier control points, 70:30 split. An SVR and the thesis MLP are trained on the
   70 % and scored on the 30 % (the thesis's own test: SVR MAE 0.010 N, MLP 0.0113 N).
2. The shipped training set: the thesis grid (its 70 % part, without the pure-tension row:
   a straight catheter looks the same under any axial pull) plus `--n-random` random forces
   (magnitude uniform in [0, 0.3] N, angle uniform in [pi/16, pi]: near-pure pulls are
   unobservable and tip contact forces push) plus 30 frames of the unloaded catheter (so a
   straight catheter reads 0 N instead of the mean of all pulls); half of the random frames
   have 0-5 mm of the tip hidden by tissue (as in the thesis's ex-vivo frames; without it the
   learned models lose 10x accuracy when the tip is hidden); every case also mirrored
   (fy -> -fy) so both bending directions are covered; features through the camera path
   (`--features render`: synthetic camera + ShapeSensor, the default when catheter_shape
   provides it) or the Bezier fit of the FAM centreline with Gaussian point noise
   (`--features noise`).
3. SVR (RBF, C = 100, epsilon and gamma by validation) -> ``blazer-svr``; the thesis MLP
   (10 ReLU) and a larger MLP (32, 32): whichever validates better -> ``blazer-mlp``.

Models are written to ``--out`` (default: the package's ``models/`` folder) as .npz files
(arrays + JSON header; no pickle).
"""
from __future__ import annotations

import argparse
import os
import time

import numpy as np

from force_estimator import dataset as D
from force_estimator.training import fit_mlp, fit_svr

DEFAULT_OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), 'models')
#: pixel-like noise of the centreline points for --features noise, m
POINT_NOISE = 5e-5
#: smallest force angle of the random set, rad (the pull cone below is unobservable)
ANGLE_MIN = np.pi / 16
#: frames of the unloaded catheter in the training set
N_ZERO = 30
#: largest tip length hidden by tissue in the augmented random frames, m
TISSUE_MAX = 0.005


def _mae(model, X, Y) -> float:
    return float(np.abs(model.predict_features(X) - Y).mean())


def _vec_mae(model, X, Y) -> float:
    return float(np.hypot(*(model.predict_features(X) - Y).T).mean())


#: forces of the fingerprint shapes, N
FINGERPRINT_FORCES = ((0.0, 0.05), (-0.1, 0.15), (0.1, 0.2))


def camera_path_fingerprint(features: str = 'render') -> dict:
    """Control points the feature path gives for three fixed shapes. Stored in the model
    header: if `catheter_shape` changes its segmentation or fit later, the features move
    (cubic control points are sensitive to the fit) and the models must be retrained;
    `fingerprint_drift` measures that."""
    F = np.array(FINGERPRINT_FORCES)
    cls, _ = D.fam_centerlines(F)
    if features == 'render':
        cp, _ = D.render_control_points(cls, seed=0)
    else:
        cp = D.fit_control_points(cls)
    return dict(features=features, forces=F.tolist(), control_points=cp.tolist())


def fingerprint_drift(model) -> float:
    """Largest change (m) of the fingerprint control points between the model's training
    time and the current camera path (nan if the model has no fingerprint)."""
    fp = model.header.get('camera_path_fingerprint')
    if not fp:
        return float('nan')
    now = camera_path_fingerprint(fp['features'])
    return float(np.nanmax(np.abs(np.array(now['control_points']) -
                                  np.array(fp['control_points']))))


def has_camera() -> bool:
    try:
        from catheter_shape import ShapeSensor, SyntheticCamera  # noqa: F401
        return True
    except ImportError:
        return False


def build(out: str = DEFAULT_OUT, n_random: int = 1000, features: str = 'auto',
          seed: int = 0, progress: bool = True, verbose: bool = True,
          tissue_frac: float = 0.5) -> dict:
    """Run the recipe; returns a report dict (metrics, hyper-parameters, times, paths)."""
    if features == 'auto':
        features = 'render' if has_camera() else 'noise'
    if features not in ('render', 'noise', 'exact'):
        raise ValueError(f'features must be render, noise or exact, got {features!r}')
    say = print if verbose else (lambda *a, **k: None)
    rep = dict(features=features, n_random=n_random, seed=seed)
    t0 = time.perf_counter()

    # 1. the thesis experiment (exact FAM features, as the thesis used exact FE shapes)
    grid = D.make_dataset(D.thesis_grid(), seed=seed, progress=progress, name='thesis-grid')
    tr, te = grid['split'] == 0, grid['split'] == 1
    svr_g, _ = fit_svr(grid['X'][tr], grid['Y'][tr], seed=seed)
    mlp_g, _ = fit_mlp(grid['X'][tr], grid['Y'][tr], seed=seed)
    rep['thesis_grid'] = dict(
        n_train=int(tr.sum()), n_test=int(te.sum()),
        svr_test_mae_n=_mae(svr_g, grid['X'][te], grid['Y'][te]),
        mlp_test_mae_n=_mae(mlp_g, grid['X'][te], grid['Y'][te]),
        svr_test_vec_mae_n=_vec_mae(svr_g, grid['X'][te], grid['Y'][te]),
        mlp_test_vec_mae_n=_vec_mae(mlp_g, grid['X'][te], grid['Y'][te]))
    say(f'thesis grid ({tr.sum()} train / {te.sum()} test), per-component MAE on the test part: '
        f'SVR {rep["thesis_grid"]["svr_test_mae_n"]:.4f} N, '
        f'MLP {rep["thesis_grid"]["mlp_test_mae_n"]:.4f} N (thesis: 0.010 N, 0.0113 N)')
    t_data0 = time.perf_counter()

    # 2. the shipped training set
    render = features == 'render'
    noise = POINT_NOISE if features == 'noise' else 0.0
    # angles from pi/16: a pull along the catheter leaves it straight whatever its size, so the
    # pull cone is unobservable; contact forces push. The unloaded catheter gets N_ZERO
    # independent noisy frames so that "straight" reads 0 N.
    F = np.concatenate([np.zeros((N_ZERO, 2)),
                        D.random_forces(n_random, seed=seed + 7, angle_range=(ANGLE_MIN, np.pi),
                                        include_zero=False)])
    depth = 0.0
    if render and tissue_frac > 0:
        rng = np.random.default_rng(seed + 11)
        depth = np.where(rng.random(len(F)) < tissue_frac,
                         rng.uniform(0.0, TISSUE_MAX, len(F)), 0.0)
        depth[:N_ZERO] = 0.0
    rnd = D.make_dataset(F, point_noise=noise, render=render, seed=seed + 7, progress=progress,
                         name='random', mirror=True, tissue_depth=depth)
    gridm = D.make_dataset(D.thesis_grid(), point_noise=noise, render=render, seed=seed,
                           progress=progress, name='thesis-grid', mirror=True)
    # the grid's pure-tension row (angle 0) is dropped: a straight catheter looks the same for
    # every axial pull, so those cases are identical inputs with different targets
    use = (gridm['split'] == 0) & (np.abs(np.sin(gridm['angle'])) > 1e-9)
    X = np.concatenate([rnd['X'], gridm['X'][use]])
    Y = np.concatenate([rnd['Y'], gridm['Y'][use]])
    rep['data_time_s'] = time.perf_counter() - t_data0
    rep['n_train'] = int(len(X))
    say(f'training set: {len(X)} cases ({features} features, mirrored), '
        f'generated in {rep["data_time_s"]:.1f} s')
    extra = dict(dataset=dict(features=features, point_noise=noise, n_random=n_random,
                              seed=seed, mirror=True, tissue_frac=tissue_frac,
                              tissue_max=TISSUE_MAX,
                              catheter=dict(length=D.BLAZER_LENGTH, ei=D.BLAZER_EI)),
                 camera_path_fingerprint=camera_path_fingerprint(features))

    # 3. models
    t = time.perf_counter()
    svr, rs = fit_svr(X, Y, seed=seed, extra_header=extra)
    rep['svr'] = dict(rs['hyper'], fit_time_s=time.perf_counter() - t,
                      n_sv=int(svr.arrays['sv'].shape[0]))
    say(f'SVR: {rep["svr"]}')
    cands = {}
    for name, hidden in (('thesis-10', (10,)), ('large-32x32', (32, 32))):
        t = time.perf_counter()
        m, r = fit_mlp(X, Y, hidden_layer_sizes=hidden, seed=seed, extra_header=extra,
                       n_init=3 if hidden == (10,) else 1, max_iter=1000)
        cands[name] = (m, dict(r['hyper'], fit_time_s=time.perf_counter() - t))
        say(f'MLP {name}: {cands[name][1]}')
    win = min(cands, key=lambda k: cands[k][1]['val_mae_n'])
    mlp = cands[win][0]
    mlp.header['candidates'] = {k: v[1] for k, v in cands.items()}
    mlp.header['chosen'] = win
    rep['mlp'] = dict(chosen=win, candidates={k: v[1] for k, v in cands.items()})
    os.makedirs(out, exist_ok=True)
    rep['paths'] = [svr.save(os.path.join(out, 'blazer-svr.npz')),
                    mlp.save(os.path.join(out, 'blazer-mlp.npz'))]
    rep['total_time_s'] = time.perf_counter() - t0
    say(f'blazer-mlp = {win}; wrote {", ".join(rep["paths"])} in {rep["total_time_s"]:.1f} s')
    return rep


def build_single_threaded(*args, **kwargs) -> dict:
    """`build` with BLAS limited to one thread: on a shared machine multi-threaded BLAS
    makes the L-BFGS MLP fits more than 10x slower (measured: 7 s vs > 120 s)."""
    from threadpoolctl import threadpool_limits
    with threadpool_limits(limits=1):
        return build(*args, **kwargs)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog='python -m force_estimator.train',
                                description='Rebuild the shipped blazer-svr / blazer-mlp models.')
    p.add_argument('--out', default=DEFAULT_OUT, help='output folder (default: package models/)')
    p.add_argument('--n-random', type=int, default=1000, help='random load cases (before mirroring)')
    p.add_argument('--features', choices=('auto', 'render', 'noise', 'exact'), default='auto',
                   help='render: synthetic camera + ShapeSensor; noise: FAM centreline + '
                        'point noise; exact: FAM centreline')
    p.add_argument('--seed', type=int, default=0)
    p.add_argument('--tissue-frac', type=float, default=0.5,
                   help='fraction of random frames with 0-5 mm of the tip hidden by tissue')
    p.add_argument('--quiet', action='store_true')
    a = p.parse_args(argv)
    build_single_threaded(a.out, a.n_random, a.features, a.seed, progress=not a.quiet,
                          verbose=not a.quiet, tissue_frac=a.tissue_frac)
    return 0


if __name__ == '__main__':
    raise SystemExit(main())

"""Learning-from-simulation data sets: tip forces -> FAM shapes -> Bezier control points.

Thesis section 2.3.1: the Blazer II-XP catheter (65 mm, EI 6.0e-5 N m^2) loaded at its tip
by 16 force angles in [0, pi) (step pi/16) x 25 magnitudes in (0, 0.3] N (step 12 mN),
400 cases, split 70:30. The thesis used finite elements; here the shapes come from the
batched Finite Arc Method (`fam_solver.solve_fam_batch`), and larger random sets are
available too.

Features are the 4 cubic-Bezier control points of the centreline, computed with the very
same fitting code the camera path uses (`catheter_shape.fit_bezier`), optionally after
adding pixel-like noise to the centreline points (`point_noise`, m) or by rendering each
shape with the synthetic camera and running the full `ShapeSensor` (`render=True`), so the
features carry the camera path's noise and bias.

Array file (``.npz``, no pickle; `save_dataset` / `load_dataset`):

==================  ============  ==========================================================
key                 shape         meaning
==================  ============  ==========================================================
control_points      (n, 4, 3)     Bezier control points p0..p3, m, catheter_base
X                   (n, 12)       control_points flattened (the model features), m
Y                   (n, 2)        tip force (fx, fy), N, catheter_base
magnitude           (n,)          |F|, N
angle               (n,)          force angle atan2(fy, fx), rad
split               (n,)          0 = train, 1 = test (70:30 random split, seeded)
converged           (n,)          bool, the FAM solve converged (non-converged are dropped)
header              ()            JSON: catheter, generator, fitter, noise, seed, counts
==================  ============  ==========================================================
"""
from __future__ import annotations

import json
import os
import time
from typing import Optional

import numpy as np

from catheter_shape.camera import SYSTEM_CAMERA

#: Blazer II-XP: 65 mm long, EI = 60 N mm^2
BLAZER_LENGTH = 0.065
BLAZER_EI = 6.0e-5
#: full scale of tip forces, N
F_MAX = 0.3
#: FAM arcs of the training shapes: 12 arcs leave a tip error of ~0.1 % L (0.07 mm), worth
#: 1-4 mN at these loads; 48 arcs cut it 16x at a small cost in the batched solver
N_ARCS = 48
#: centreline samples per shape fed to the Bezier fit
N_CENTERLINE = 200
#: the training camera: 800 x 800 at 0.15 mm/pixel, the clamp at pixel (260, 400) and +x to
#: the right, so every Blazer shape with |F| <= 0.3 N stays in view (FAM shapes span
#: x in [-36, 65] mm, y in [-50, 57] mm (post-buckled shapes can cross to the other side);
#: the view is x in [-39, 81] mm, y in [-60, 60] mm); fluoroscopy-like noise, blur and
#: texture as catheter_shape draws them
#: It is the system's camera, defined once in catheter_shape.camera.SYSTEM_CAMERA.
TRAIN_CAMERA = dict(SYSTEM_CAMERA)


def thesis_grid(n_angles: int = 16, n_magnitudes: int = 25, f_max: float = F_MAX) -> np.ndarray:
    """The thesis load grid: angles k pi / n_angles (k = 0..n_angles-1) x magnitudes
    f_max j / n_magnitudes (j = 1..n_magnitudes). Returns forces (n_angles*n_magnitudes, 2) N."""
    if n_angles < 1 or n_magnitudes < 1:
        raise ValueError('n_angles and n_magnitudes must be >= 1')
    if not (np.isfinite(f_max) and f_max > 0):
        raise ValueError(f'f_max must be positive, got {f_max}')
    ang = np.arange(n_angles) * np.pi / n_angles
    mag = f_max * np.arange(1, n_magnitudes + 1) / n_magnitudes
    A, M = np.meshgrid(ang, mag, indexing='ij')
    return np.stack([M.ravel() * np.cos(A.ravel()), M.ravel() * np.sin(A.ravel())], axis=1)


def random_forces(n: int, f_max: float = F_MAX, seed: int = 0, angle_range=(0.0, np.pi),
                  include_zero: bool = True) -> np.ndarray:
    """n tip forces, magnitude uniform in [0, f_max] N, angle uniform in angle_range rad.
    Returns (n, 2) N. With include_zero the first case is the unloaded catheter."""
    if n < 1:
        raise ValueError(f'n must be >= 1, got {n}')
    if not (np.isfinite(f_max) and f_max > 0):
        raise ValueError(f'f_max must be positive, got {f_max}')
    rng = np.random.default_rng(seed)
    mag = rng.uniform(0.0, f_max, n)
    ang = rng.uniform(angle_range[0], angle_range[1], n)
    if include_zero:
        mag[0] = 0.0
    return np.stack([mag * np.cos(ang), mag * np.sin(ang)], axis=1)


def _fitter():
    """The camera path's Bezier fit (catheter_shape.fit_bezier)."""
    try:
        from catheter_shape import fit_bezier
    except ImportError:     # older catheter_shape without the top-level export
        from catheter_shape.bezier import fit_bezier
    return fit_bezier


def fit_control_points(centerlines, point_noise: float = 0.0, seed: int = 0,
                       progress: bool = False) -> np.ndarray:
    """Control points of centrelines with the camera path's fit.

    centerlines: (B, k, 2) or (B, k, 3) m, base -> tip. point_noise: std of Gaussian noise
    added to every coordinate before fitting, m (0 = exact). Returns (B, 4, 3) m.
    """
    c = np.asarray(centerlines, dtype=float)
    if c.ndim != 3 or c.shape[2] not in (2, 3) or c.shape[1] < 4:
        raise ValueError(f'centerlines must have shape (B, k>=4, 2|3), got {c.shape}')
    if not np.isfinite(c).all():
        raise ValueError('centerlines contain non-finite values')
    if point_noise < 0 or not np.isfinite(point_noise):
        raise ValueError(f'point_noise must be >= 0, got {point_noise}')
    if c.shape[2] == 2:
        c = np.concatenate([c, np.zeros(c.shape[:2] + (1,))], axis=2)
    fit = _fitter()
    rng = np.random.default_rng(seed)
    out = np.empty((c.shape[0], 4, 3))
    it = range(c.shape[0])
    if progress:
        from tqdm import tqdm
        it = tqdm(it, desc='bezier fit', unit='shape', leave=False)
    for i in it:
        pts = c[i]
        if point_noise > 0:
            pts = pts.copy()
            pts[:, :2] += rng.normal(0.0, point_noise, (pts.shape[0], 2))
        out[i] = fit(pts, degree=3)
    return out


def fam_centerlines(forces, length: float = BLAZER_LENGTH, ei: float = BLAZER_EI,
                    n_arcs: int = N_ARCS, n_points: int = N_CENTERLINE, chunk: int = 2000,
                    progress: bool = False):
    """FAM shapes of tip forces (B, 2) N on a clamped catheter (no tip moment).

    Returns (centerlines (B, n_points, 2) m, converged (B,) bool)."""
    from fam_solver import Catheter, solve_fam_batch
    F = np.asarray(forces, dtype=float)
    if F.ndim != 2 or F.shape[1] != 2 or not np.isfinite(F).all():
        raise ValueError(f'forces must be finite with shape (B, 2), got {F.shape}')
    cat = Catheter(length=length, ei=ei)
    cls = np.empty((F.shape[0], n_points, 2))
    conv = np.empty(F.shape[0], dtype=bool)
    starts = range(0, F.shape[0], chunk)
    if progress:
        from tqdm import tqdm
        starts = tqdm(starts, desc='FAM batch', unit='chunk', leave=False)
    for s in starts:
        f = F[s:s + chunk]
        # circular arcs on the graded mesh: the shipped models were trained on these shapes
        # (rebuilt bit for bit); the clothoid default differs by ~7e-5 L at 48 arcs
        b = solve_fam_batch(cat, f, np.zeros(len(f)), n_arcs=n_arcs, arc_model='exact',
                            spacing='graded')
        cls[s:s + chunk] = b.centerlines(n_points)
        conv[s:s + chunk] = b.converged
    return cls, conv


def render_control_points(centerlines, seed: int = 0, progress: bool = False,
                          camera_kwargs: Optional[dict] = None,
                          sensor_kwargs: Optional[dict] = None,
                          return_timing: bool = False, tissue_depth: float = 0.0):
    """Control points through the full image pipeline: synthetic camera -> ShapeSensor
    (background removal, threshold 132, the clamp pixel known from calibration).

    centerlines: (B, k, 2) m, catheter_base. camera_kwargs: SyntheticCamera arguments
    (default TRAIN_CAMERA, seeded with `seed`); sensor_kwargs: ShapeSensor arguments (default:
    the camera's background frame and clamp pixel, as in training; pass background=None or
    base_px=None to measure without them).
    Returns (control_points (B, 4, 3) m, ok (B,) bool); frames the sensor rejects or that
    leave the view give ok = False and NaN control points. With return_timing also the
    sensor time per frame (B,) s. tissue_depth: m of the tip hidden under tissue (as in the
    thesis's ex-vivo frames; 0 = fully visible), one number or one per shape (B,).
    """
    from catheter_shape import ShapeSensor, SyntheticCamera
    kw = dict(TRAIN_CAMERA)
    kw.update(camera_kwargs or {})
    kw.setdefault('seed', seed)
    cam = SyntheticCamera(**kw)
    c = np.asarray(centerlines, dtype=float)
    depth = np.broadcast_to(np.asarray(tissue_depth, dtype=float), (c.shape[0],))
    if not (np.isfinite(depth).all() and (depth >= 0).all()):
        raise ValueError('tissue_depth must be finite and >= 0')
    out = np.full((c.shape[0], 4, 3), np.nan)
    ok = np.zeros(c.shape[0], dtype=bool)
    times = np.full(c.shape[0], np.nan)
    skw = dict(background=cam.background, base_px=cam.base_px)
    skw.update(sensor_kwargs or {})
    sensor = ShapeSensor(cam.psi, **skw)
    rng = np.random.default_rng(seed + 12345)
    it = range(c.shape[0])
    if progress:
        from tqdm import tqdm
        it = tqdm(it, desc='render+sense', unit='frame', leave=False)
    for i in it:
        frame = cam.render(c[i], rng=rng, tissue_depth=float(depth[i]))
        if not frame.in_view:
            continue
        t0 = time.perf_counter()
        obs = sensor.process(frame.image)
        times[i] = time.perf_counter() - t0
        if obs.ok:
            out[i] = obs.control_points
            ok[i] = True
    return (out, ok, times) if return_timing else (out, ok)


def styled_control_points(centerlines, styles=None, seed: int = 0, width: int = 640,
                          height: int = 480, length: float = BLAZER_LENGTH,
                          background: bool = True, progress: bool = False):
    """Control points through the image pipeline on a family of camera styles
    (catheter_shape.styles): frame i is drawn in style styles[i % len(styles)] (default the
    styles the sensor was tuned on, catheter_shape.styles.TUNING_STYLES) with randomised
    physics and geometry, the clamp always in view (the learned models cover curves that
    start at the clamp; others are outside their domain), and measured by ShapeSensor given
    the calibration (psi, base_px), the catheter length and (background=True) the style's
    background frame.

    centerlines: (B, k, 2) m. Returns (control_points (B, 4, 3) m, ok (B,) bool, style
    (B,) int index into styles, hidden (B,) m of the tip under tissue); frames the sensor
    refuses give ok False and NaN control points."""
    from catheter_shape import ShapeSensor
    from catheter_shape.styles import TUNING_STYLES, render_style, style_params
    styles = tuple(TUNING_STYLES if styles is None else styles)
    c = np.asarray(centerlines, dtype=float)
    if c.ndim != 3 or c.shape[2] not in (2, 3) or not np.isfinite(c).all():
        raise ValueError(f'centerlines must be finite with shape (B, k, 2|3), got {c.shape}')
    rng = np.random.default_rng(seed)
    out = np.full((len(c), 4, 3), np.nan)
    ok = np.zeros(len(c), bool)
    sty = np.arange(len(c)) % len(styles)
    hidden = np.zeros(len(c))
    it = range(len(c))
    if progress:
        from tqdm import tqdm
        it = tqdm(it, desc='styles+sense', unit='frame', leave=False)
    for i in it:
        p = style_params(styles[sty[i]], rng)
        p.update(base_out=False)            # the clamp in view: the curve starts at the base
        f = render_style(styles[sty[i]], c[i], rng=rng, width=width, height=height, params=p)
        hidden[i] = f.hidden_tip
        obs = ShapeSensor(f.psi, background=f.background if background else None,
                          base_px=f.base_px, length=length).process(f.image)
        if obs.ok:
            out[i] = obs.control_points
            ok[i] = True
    return out, ok, sty, hidden


def make_dataset(forces, length: float = BLAZER_LENGTH, ei: float = BLAZER_EI,
                 n_arcs: int = N_ARCS, point_noise: float = 0.0, render: bool = False,
                 test_frac: float = 0.3, seed: int = 0, progress: bool = True,
                 name: str = '', mirror: bool = False, tissue_depth=0.0) -> dict:
    """Build a data set from tip forces (n, 2) N: FAM shapes, control points, 70:30 split.

    Non-converged FAM solves (and failed renders) are dropped and counted in the header.
    mirror: also add the mirror image of every case (y -> -y, fy -> -fy; the catheter is
    symmetric), so a model covers deflections to both sides; a case and its mirror share
    the same split.
    Returns a dict with the keys documented in the module docstring.
    """
    F = np.asarray(forces, dtype=float)
    if not (0.0 <= test_frac < 1.0):
        raise ValueError(f'test_frac must be in [0, 1), got {test_frac}')
    cls, conv = fam_centerlines(F, length, ei, n_arcs, progress=progress)
    if render:
        cp, ok = render_control_points(cls, seed=seed, progress=progress,
                                       tissue_depth=tissue_depth)
    else:
        cp = fit_control_points(cls, point_noise=point_noise, seed=seed, progress=progress)
        ok = np.ones(len(F), dtype=bool)
    keep = conv & ok
    n_not_conv = int((~conv).sum())
    n_render_failed = int((conv & ~ok).sum())
    rng = np.random.default_rng(seed + 1)
    n = int(keep.sum())
    split = np.zeros(n, dtype=np.int8)
    split[rng.permutation(n)[:int(round(test_frac * n))]] = 1
    Fk = F[keep]
    cpk = cp[keep]
    if mirror:
        flip = np.array([1.0, -1.0, 1.0])
        cpk = np.concatenate([cpk, cpk * flip])
        Fk = np.concatenate([Fk, Fk * flip[:2]])
        split = np.concatenate([split, split])
        n = 2 * n
    header = dict(name=name, catheter=dict(length=length, ei=ei), n_arcs=n_arcs,
                  generator='fam_solver.solve_fam_batch',
                  fitter='render+ShapeSensor' if render else 'catheter_shape.fit_bezier',
                  point_noise=point_noise, seed=seed, test_frac=test_frac, mirror=mirror,
                  tissue_depth_max=float(np.max(tissue_depth)),
                  n_requested=int(len(F)), n_not_converged=n_not_conv,
                  n_render_failed=n_render_failed, n=n,
                  units=dict(control_points='m', X='m', Y='N', angle='rad'))
    return dict(control_points=cpk, X=cpk.reshape(n, 12), Y=Fk,
                magnitude=np.hypot(Fk[:, 0], Fk[:, 1]), angle=np.arctan2(Fk[:, 1], Fk[:, 0]),
                split=split, converged=np.ones(n, dtype=bool), header=header)


def save_dataset(path, ds: dict) -> str:
    """Write a data set (see module docstring) as .npz with a JSON header; returns the path."""
    path = os.fspath(path)
    arrays = {k: np.asarray(v) for k, v in ds.items() if k != 'header'}
    np.savez_compressed(path, header=np.array(json.dumps(ds.get('header', {}))), **arrays)
    return path if path.endswith('.npz') else path + '.npz'


def load_dataset(path) -> dict:
    """Read a data set written by `save_dataset` (allow_pickle=False)."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise ValueError(f'path {path!r} does not exist')
    with np.load(path, allow_pickle=False) as d:
        ds = {k: np.array(d[k]) for k in d.files if k != 'header'}
        ds['header'] = json.loads(str(d['header'][()])) if 'header' in d.files else {}
    for key in ('X', 'Y', 'split'):
        if key not in ds:
            raise ValueError(f'path {path!r} is not a data set (no {key!r})')
    return ds


def main(argv=None) -> int:
    """Command line: generate a data set file. See --help."""
    import argparse
    p = argparse.ArgumentParser(prog='python -m force_estimator.dataset',
                                description=__doc__.split('\n')[0])
    p.add_argument('out', help='output .npz file')
    p.add_argument('--kind', choices=('grid', 'random'), default='grid',
                   help='thesis grid (16 x 25) or random forces')
    p.add_argument('-n', type=int, default=2000, help='cases of a random set')
    p.add_argument('--f-max', type=float, default=F_MAX, help='largest force magnitude, N')
    p.add_argument('--noise', type=float, default=0.0, help='centreline point noise, m')
    p.add_argument('--render', action='store_true', help='through synthetic camera + ShapeSensor')
    p.add_argument('--seed', type=int, default=0)
    a = p.parse_args(argv)
    F = thesis_grid(f_max=a.f_max) if a.kind == 'grid' else random_forces(a.n, a.f_max, a.seed)
    ds = make_dataset(F, point_noise=a.noise, render=a.render, seed=a.seed, name=a.kind)
    path = save_dataset(a.out, ds)
    print(f'{path}: {ds["header"]["n"]} cases ({int((ds["split"] == 0).sum())} train, '
          f'{int((ds["split"] == 1).sum())} test), dropped {ds["header"]["n_not_converged"]} '
          f'non-converged, {ds["header"]["n_render_failed"]} failed renders')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())

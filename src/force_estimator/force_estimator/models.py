"""Learned tip-force models as plain numpy forward passes, saved without pickle.

A model maps the 4 cubic-Bezier control points of the catheter centreline (4, 3) m, in
`catheter_base`, to the tip force (fx, fy) N in `catheter_base`. Inside, features are the
12 control-point coordinates (p0x, p0y, p0z, p1x, ..., p3z), standardised with the training
mean and scale; targets are standardised the same way and un-scaled at the output.

Two kinds, both trained with scikit-learn (see `force_estimator.training`) and evaluated
here without scikit-learn:

* ``svr``: one epsilon-SVR with an RBF kernel per output;
  ``y_k = sum_i alpha_ki exp(-gamma_k |z - sv_i|^2) + b_k`` in standardised units.
  The support vectors of both outputs are stacked into one (n_sv, 12) array with a
  (n_sv, 2) coefficient matrix (zeros where a vector belongs to only one output), so a
  prediction is one distance computation, one exp and one matrix product.
* ``mlp``: ReLU hidden layers and an identity output, ``h = max(0, h W + b)``.

File format (``.npz``, loaded with ``allow_pickle=False``): the arrays of the model plus
``header``, a 0-d unicode array holding a JSON document with the model kind, format
version, feature/target description and units, hyper-parameters, training data summary and
metrics. Arrays: ``x_mean``, ``x_scale`` (12,), ``y_mean``, ``y_scale`` (2,),
``env_lo``, ``env_hi`` (12,) training envelope of the raw features (m), and for svr
``sv`` (n, 12), ``coef`` (n, 2), ``gamma`` (n,), ``intercept`` (2,); for mlp ``W0``,
``b0``, ``W1``, ``b1``, ...

The training envelope: a prediction is *in the envelope* when every raw feature lies in
the training range widened by `ENVELOPE_MARGIN` of that range (at least
`ENVELOPE_MIN_PAD` m) and the predicted force magnitude is at most
``(1 + ENVELOPE_MARGIN)`` times the largest training magnitude (plus 1 mN). Outside,
the model is extrapolating and the result is flagged, never silently trusted.
"""
from __future__ import annotations

import importlib.resources
import json
import os
from typing import Dict, Optional, Tuple

import numpy as np

FORMAT = 'force_estimator.model'
FORMAT_VERSION = 1
N_FEATURES = 12
N_TARGETS = 2
TARGET_NAMES = ('fx', 'fy')
SHIPPED_MODELS = ('blazer-svr', 'blazer-mlp')
#: relative widening of the training range for the envelope check
ENVELOPE_MARGIN = 0.05
#: minimal absolute widening of a feature's training range, m (pixel-noise scale)
ENVELOPE_MIN_PAD = 5e-4


def control_points_to_features(control_points) -> np.ndarray:
    """Validate control points and flatten them to features.

    control_points: (4, 3) or (B, 4, 3) m (a planar (4, 2) / (B, 4, 2) input gets z = 0).
    Returns (12,) or (B, 12) float64. Raises ValueError (naming `control_points`) on a
    wrong shape or non-finite values.
    """
    x = np.asarray(control_points, dtype=float)
    if x.ndim < 2 or x.ndim > 3 or x.shape[-2] != 4 or x.shape[-1] not in (2, 3):
        raise ValueError(f'control_points must have shape (4, 3) or (B, 4, 3), got {x.shape}')
    if x.shape[-1] == 2:
        x = np.concatenate([x, np.zeros(x.shape[:-1] + (1,))], axis=-1)
    if not np.isfinite(x).all():
        raise ValueError('control_points contain non-finite values')
    return x.reshape(x.shape[:-2] + (N_FEATURES,))


class ForceModel:
    """A trained force model: scaling, the numpy forward pass and the training envelope.

    Use `predict(control_points)` ((4, 3) -> (2,) N; (B, 4, 3) -> (B, 2) N), or
    `predict(..., return_flags=True)` -> (forces, in_envelope) with in_envelope a bool
    (single) or (B,) bool array.
    """

    def __init__(self, kind: str, arrays: Dict[str, np.ndarray], header: Optional[dict] = None,
                 name: str = ''):
        if kind not in ('svr', 'mlp'):
            raise ValueError(f'kind must be "svr" or "mlp", got {kind!r}')
        self.kind = kind
        self.name = name
        self.header = dict(header or {})
        self.header.setdefault('kind', kind)
        self.arrays = {k: np.ascontiguousarray(v, dtype=float) for k, v in arrays.items()}
        a = self.arrays
        for key, shape in (('x_mean', (N_FEATURES,)), ('x_scale', (N_FEATURES,)),
                           ('y_mean', (N_TARGETS,)), ('y_scale', (N_TARGETS,)),
                           ('env_lo', (N_FEATURES,)), ('env_hi', (N_FEATURES,))):
            if key not in a or a[key].shape != shape:
                raise ValueError(f'model array {key!r} must have shape {shape}')
            if not np.isfinite(a[key]).all():
                raise ValueError(f'model array {key!r} is not finite')
        if (a['x_scale'] <= 0).any() or (a['y_scale'] <= 0).any():
            raise ValueError('model scales must be positive')
        self._xm = a['x_mean']
        self._xis = 1.0 / a['x_scale']
        self._ym = a['y_mean']
        self._ys = a['y_scale']
        self._lo = a['env_lo']
        self._hi = a['env_hi']
        self.max_force = float(self.header.get('envelope', {}).get('max_force', np.inf))
        self._fmax2 = ((1.0 + ENVELOPE_MARGIN) * self.max_force + 1e-3) ** 2
        if kind == 'svr':
            for key in ('sv', 'coef', 'gamma', 'intercept'):
                if key not in a:
                    raise ValueError(f'svr model lacks array {key!r}')
            self._sv = a['sv']
            self._coef = a['coef']
            self._gamma = a['gamma']
            self._b = a['intercept']
            if self._sv.ndim != 2 or self._sv.shape[1] != N_FEATURES:
                raise ValueError('svr array "sv" must have shape (n, 12)')
            n = self._sv.shape[0]
            if self._coef.shape != (n, N_TARGETS) or self._gamma.shape != (n,):
                raise ValueError('svr arrays "coef" (n, 2) and "gamma" (n,) do not match "sv"')
            self._sv2 = np.einsum('ij,ij->i', self._sv, self._sv)
            self._ng = -self._gamma
            self._sv2g = -self._gamma * self._sv2
            self._svg2 = (2.0 * self._gamma)[:, None] * self._sv   # (n, 12)
        else:
            layers = []
            i = 0
            while f'W{i}' in a:
                layers.append((a[f'W{i}'], a[f'b{i}']))
                i += 1
            if not layers:
                raise ValueError('mlp model has no layers (W0, b0, ...)')
            width = N_FEATURES
            for W, b in layers:
                if W.ndim != 2 or W.shape[0] != width or b.shape != (W.shape[1],):
                    raise ValueError('mlp layer shapes do not chain')
                width = W.shape[1]
            if width != N_TARGETS:
                raise ValueError('mlp output layer must have 2 units')
            self._layers = layers
        for key, v in a.items():
            if not np.isfinite(v).all():
                raise ValueError(f'model array {key!r} is not finite')

    # -- forward passes in standardised units ------------------------------------------
    def _forward(self, z: np.ndarray) -> np.ndarray:
        """z: (B, 12) standardised features -> (B, 2) standardised targets."""
        if self.kind == 'svr':
            # exp(-g |z - s|^2) = exp(-g|s|^2 + 2g s.z - g|z|^2)
            zz = np.einsum('ij,ij->i', z, z)
            e = z @ self._svg2.T
            e += self._sv2g
            e += np.outer(zz, self._ng)
            np.minimum(e, 0.0, out=e)   # |z - s|^2 >= 0 (round-off guard)
            np.exp(e, out=e)
            return e @ self._coef + self._b
        return self._mlp(z)

    def _forward1(self, z: np.ndarray) -> np.ndarray:
        """z: (12,) -> (2,) standardised; the single-sample fast path."""
        if self.kind == 'svr':
            e = self._svg2 @ z
            e += self._sv2g
            e -= self._gamma * (z @ z)
            np.minimum(e, 0.0, out=e)
            np.exp(e, out=e)
            return e @ self._coef + self._b
        return self._mlp(z)

    def _mlp(self, z: np.ndarray) -> np.ndarray:
        """ReLU layers on standardised input z (..., 12) -> (..., 2), linear output layer."""
        h = z
        last = len(self._layers) - 1
        for i, (W, b) in enumerate(self._layers):
            h = h @ W + b
            if i < last:
                np.maximum(h, 0.0, out=h)
        return h

    # -- public API -----------------------------------------------------------------------
    def predict_features(self, features, return_flags: bool = False):
        """features: (12,) or (B, 12) raw features (m) -> (2,) or (B, 2) N."""
        x = np.asarray(features, dtype=float)
        if x.shape[-1:] != (N_FEATURES,) or x.ndim > 2:
            raise ValueError(f'features must have shape (12,) or (B, 12), got {x.shape}')
        if not np.isfinite(x).all():
            raise ValueError('features contain non-finite values')
        return self._predict_valid(x, return_flags)

    def _predict_valid(self, x: np.ndarray, return_flags: bool):
        if x.ndim == 1:
            y = self._forward1((x - self._xm) * self._xis) * self._ys + self._ym
            if not return_flags:
                return y
            ok = bool((x >= self._lo).all() and (x <= self._hi).all()
                      and y @ y <= self._fmax2)
            return y, ok
        y = self._forward((x - self._xm) * self._xis) * self._ys + self._ym
        if not return_flags:
            return y
        ok = ((x >= self._lo) & (x <= self._hi)).all(axis=1)
        ok &= np.einsum('ij,ij->i', y, y) <= self._fmax2
        return y, ok

    def predict(self, control_points, return_flags: bool = False):
        """Tip force from Bezier control points.

        control_points: (4, 3) m -> (2,) N (fx, fy) in catheter_base; (B, 4, 3) -> (B, 2).
        return_flags: also return in_envelope (bool, or (B,) bool): False when the input
        lies outside the training envelope or the force exceeds the trained range.
        Raises ValueError (naming `control_points`) on wrong shapes or non-finite values.
        """
        x = np.asarray(control_points, dtype=float)
        if x.shape == (4, 3):           # fast path: a handful of cheap checks only
            x = x.reshape(N_FEATURES)
            if not np.isfinite(x).all():
                raise ValueError('control_points contain non-finite values')
            return self._predict_valid(x, return_flags)
        return self._predict_valid(control_points_to_features(x), return_flags)

    def in_envelope(self, control_points) -> np.ndarray:
        """True where the input lies inside the training envelope (and the force in range)."""
        return self.predict(control_points, return_flags=True)[1]

    def save(self, path: str) -> str:
        """Write the model as .npz (arrays + JSON header; no pickle). Returns the path."""
        path = os.fspath(path)
        if not path.endswith('.npz'):
            path += '.npz'
        header = dict(self.header)
        header.update(format=FORMAT, version=FORMAT_VERSION, kind=self.kind)
        np.savez(path, header=np.array(json.dumps(header, sort_keys=True)), **self.arrays)
        return path

    def __repr__(self) -> str:
        size = (f'{self._sv.shape[0]} support vectors' if self.kind == 'svr' else
                'layers ' + 'x'.join(str(W.shape[1]) for W, _ in self._layers))
        return f'ForceModel({self.name or self.kind!r}, {size})'


def load_model(path) -> ForceModel:
    """Load a model file written by `ForceModel.save` (never unpickles)."""
    path = os.fspath(path)
    if not path.endswith('.npz'):
        raise ValueError(f'path must name a .npz model file, got {path!r}')
    if not os.path.isfile(path):
        raise ValueError(f'path {path!r} does not exist')
    with np.load(path, allow_pickle=False) as data:
        if 'header' not in data.files:
            raise ValueError(f'path {path!r} is not a force_estimator model (no header)')
        header = json.loads(str(data['header'][()]))
        arrays = {k: np.array(data[k]) for k in data.files if k != 'header'}
    if header.get('format') != FORMAT:
        raise ValueError(f'path {path!r} is not a force_estimator model file')
    if int(header.get('version', -1)) > FORMAT_VERSION:
        raise ValueError(f'model file version {header.get("version")} is newer than '
                         f'this reader ({FORMAT_VERSION})')
    name = os.path.splitext(os.path.basename(path))[0]
    return ForceModel(header['kind'], arrays, header, name=name)


def shipped_model_path(name: str) -> str:
    """Filesystem path of a shipped model ("blazer-svr", "blazer-mlp") in the package data."""
    if name not in SHIPPED_MODELS:
        raise ValueError(f'name must be one of {SHIPPED_MODELS}, got {name!r}')
    res = importlib.resources.files('force_estimator') / 'models' / f'{name}.npz'
    return os.fspath(res)


def load_estimator(name_or_path) -> ForceModel:
    """A shipped model by name ("blazer-svr", "blazer-mlp") or a model file by path (.npz)."""
    s = os.fspath(name_or_path)
    if s in SHIPPED_MODELS:
        model = load_model(shipped_model_path(s))
        model.name = s
        return model
    if not s.endswith('.npz'):
        raise ValueError(f'name_or_path must be one of {SHIPPED_MODELS} or a .npz model '
                         f'file, got {s!r}')
    return load_model(s)


def envelope_bounds(X: np.ndarray, margin: float = ENVELOPE_MARGIN,
                    min_pad: float = ENVELOPE_MIN_PAD) -> Tuple[np.ndarray, np.ndarray]:
    """Training envelope of raw features X (n, 12): (lo, hi), each widened by
    max(margin * range, min_pad)."""
    lo, hi = X.min(axis=0), X.max(axis=0)
    pad = np.maximum(margin * (hi - lo), min_pad)
    return lo - pad, hi + pad

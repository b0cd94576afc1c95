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

Format version 2 adds: ``domain_X`` (n, 12) and ``domain_Y`` (n, 2) float32, the reference
training inputs of the domain check (force_estimator.domain) and their forces, and ``obs_angles``,
``obs_magnitudes``, ``obs_cov``,
the observability table (force_estimator.uncertainty); the header adds ``domain``
(threshold), ``model_cov`` (2x2 N^2, the validation error covariance of the model on
observable inputs) and ``selftest`` (inputs and the outputs the model gave for them when it
was written).

The training envelope: a prediction is *in the envelope* when every raw feature lies in
the training range widened by `ENVELOPE_MARGIN` of that range (at least
`ENVELOPE_MIN_PAD` m) and the predicted force magnitude is at most
``(1 + ENVELOPE_MARGIN)`` times the largest training magnitude (plus 1 mN). Outside,
the model is extrapolating and the result is flagged, never silently trusted; and it is
BOUNDED: the features are clipped into the envelope box before the forward pass (a ReLU
network cannot extrapolate to kilonewtons from a bounded box) and the force's magnitude is
clipped to the envelope's (`ForceModel.f_bound`).

Validation on load (`ForceModel(...)`, `load_model`): every array finite; the stored
training range plausible (0 < max force <= `MAX_PLAUSIBLE_FORCE`, the envelope box within
`MAX_COORD` m); the largest output the weights can produce over the envelope box (interval
arithmetic through the layers, or the sum of the SVR's coefficients) at most
`MAX_OUTPUT_RATIO` times the trained force; and the self-test: the stored inputs give the
stored outputs (a file with weights x 1e6, or 1e200, is refused).

`ForceModel.estimate(cp)` returns a `force_estimator.estimate.ForceEstimate`: the bounded
force, its covariance (the observability table at the estimate or at the training force of
one of the input's 8 nearest neighbours, whichever is the least determined, plus the model's
own error),
the status ('out_of_domain' beyond the domain check, 'out_of_envelope' when the output was
clipped, 'non_finite_input' / 'bad_input', else 'ok' or 'axial_unobservable') and the domain
distance.
"""
from __future__ import annotations

import importlib.resources
import json
import os
import zipfile
from typing import Dict, Optional, Tuple

import numpy as np

from force_estimator.domain import DomainCheck
from force_estimator.estimate import (ForceEstimate, bounded, domain_distance,
                                      failed_estimate, status_of)
from force_estimator.inputs import (MAX_COORD, N_FEATURES, check_control_points,
                                    control_points_to_features)
from force_estimator.uncertainty import FORCE_PRIOR, ObservabilityTable

FORMAT = 'force_estimator.model'
FORMAT_VERSION = 2
N_TARGETS = 2
TARGET_NAMES = ('fx', 'fy')
SHIPPED_MODELS = ('blazer-svr', 'blazer-mlp')
#: relative widening of the training range for the envelope check
ENVELOPE_MARGIN = 0.05
#: minimal absolute widening of a feature's training range, m (pixel-noise scale)
ENVELOPE_MIN_PAD = 5e-4
#: largest trained force magnitude a model file may claim, N
MAX_PLAUSIBLE_FORCE = 10.0
#: largest output the weights may produce over the envelope box, times the trained force
#: (a rigorous but loose bound: an RBF SVR's is the sum of its |coefficients|; weights of
#: 1e200 exceed it, tampered weights of plausible size are caught by the self-test)
MAX_OUTPUT_RATIO = 1e6


class ForceModel:
    """A trained force model: scaling, the numpy forward pass, the training envelope, the
    domain check and the uncertainty.

    Use `predict(control_points)` ((4, 3) -> (2,) N; (B, 4, 3) -> (B, 2) N), or
    `predict(..., return_flags=True)` -> (forces, in_envelope) with in_envelope a bool
    (single) or (B,) bool array; forces are bounded (see the module docstring).
    `estimate(control_points)` -> ForceEstimate (one sample, with covariance and status).
    Raises ValueError naming the array when the model's arrays are inconsistent,
    non-finite or implausible (see the module docstring).
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
        for key, v in a.items():
            if not np.isfinite(v).all():
                raise ValueError(f'model array {key!r} is not finite')
        for key, shape in (('x_mean', (N_FEATURES,)), ('x_scale', (N_FEATURES,)),
                           ('y_mean', (N_TARGETS,)), ('y_scale', (N_TARGETS,)),
                           ('env_lo', (N_FEATURES,)), ('env_hi', (N_FEATURES,))):
            if key not in a or a[key].shape != shape:
                raise ValueError(f'model array {key!r} must have shape {shape}')
        if (a['x_scale'] <= 0).any() or (a['y_scale'] <= 0).any():
            raise ValueError('model scales must be positive')
        if (a['env_hi'] < a['env_lo']).any() or np.abs(a['env_lo']).max() > MAX_COORD \
                or np.abs(a['env_hi']).max() > MAX_COORD:
            raise ValueError(f'model arrays "env_lo"/"env_hi" must be a box within '
                             f'{MAX_COORD} m')
        self._xm = a['x_mean']
        self._xis = 1.0 / a['x_scale']
        self._ym = a['y_mean']
        self._ys = a['y_scale']
        self._lo = a['env_lo']
        self._hi = a['env_hi']
        self.max_force = float(self.header.get('envelope', {}).get('max_force', np.nan))
        if not (np.isfinite(self.max_force) and 0 < self.max_force <= MAX_PLAUSIBLE_FORCE):
            raise ValueError(f'model header envelope.max_force must be in (0, '
                             f'{MAX_PLAUSIBLE_FORCE}] N, got {self.max_force!r}')
        #: the largest force magnitude the model returns, N
        self.f_bound = (1.0 + ENVELOPE_MARGIN) * self.max_force + 1e-3
        self._fmax2 = self.f_bound ** 2
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
            if (self._gamma <= 0).any():
                raise ValueError('svr array "gamma" must be positive')
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
        bound = self.output_bound()
        if not bound <= MAX_OUTPUT_RATIO * self.max_force:
            raise ValueError(f'model weights can produce {bound:.3g} N over the training '
                             f'envelope, more than {MAX_OUTPUT_RATIO:g} x the trained '
                             f'{self.max_force:g} N: implausible weights')
        self._selftest()
        self.domain = DomainCheck.from_model(a, self.header)
        self.table = (ObservabilityTable.from_arrays(a) if 'obs_cov' in a else None)
        # the table at every reference input's training force, once (estimate() takes the
        # least determined of its neighbours')
        self._ref_cov = self._ref_weak = None
        if self.table is not None and self.domain is not None \
                and self.domain.targets is not None:
            self._ref_cov = self.table.lookup(self.domain.targets)
            self._ref_weak = np.linalg.eigvalsh(self._ref_cov)[:, -1]
        mc = np.asarray(self.header.get('model_cov', np.zeros((2, 2))), dtype=float)
        if mc.shape != (2, 2) or not np.isfinite(mc).all() \
                or np.linalg.eigvalsh(0.5 * (mc + mc.T))[0] < -1e-12:
            raise ValueError('model header model_cov must be a finite PSD 2x2 covariance')
        self.model_cov = 0.5 * (mc + mc.T)

    # -- validation -----------------------------------------------------------------------
    def output_bound(self) -> float:
        """An upper bound (N) of |each force component| the weights can produce for inputs
        in the envelope box (interval arithmetic; for an SVR the sum of |coefficients|)."""
        if self.kind == 'svr':
            std = np.abs(self._coef).sum(axis=0) + np.abs(self._b)
        else:
            lo = (self._lo - self._xm) * self._xis
            hi = (self._hi - self._xm) * self._xis
            last = len(self._layers) - 1
            for i, (W, b) in enumerate(self._layers):
                Wp, Wn = np.maximum(W, 0.0), np.minimum(W, 0.0)
                lo, hi = lo @ Wp + hi @ Wn + b, hi @ Wp + lo @ Wn + b
                if i < last:
                    lo, hi = np.maximum(lo, 0.0), np.maximum(hi, 0.0)
            std = np.maximum(np.abs(lo), np.abs(hi))
        with np.errstate(over='ignore', invalid='ignore'):
            out = std * self._ys + np.abs(self._ym)
        return float(np.max(out)) if np.all(np.isfinite(out)) else float('inf')

    def _selftest(self) -> None:
        st = self.header.get('selftest')
        if not st:
            return
        X = np.asarray(st.get('features'), dtype=float)
        Y = np.asarray(st.get('forces'), dtype=float)
        if X.ndim != 2 or X.shape[1] != N_FEATURES or Y.shape != (X.shape[0], N_TARGETS):
            raise ValueError('model header selftest must hold features (k, 12) and forces (k, 2)')
        got = self._forward((X - self._xm) * self._xis) * self._ys + self._ym
        if not np.allclose(got, Y, rtol=1e-6, atol=1e-9):
            raise ValueError('model self-test failed: the stored inputs do not give the stored '
                             'forces (the weights were changed after training)')

    def make_selftest(self, X: np.ndarray) -> None:
        """Store inputs X (k, 12) and the model's outputs for them in the header."""
        X = np.asarray(X, dtype=float)
        Y = self._forward((X - self._xm) * self._xis) * self._ys + self._ym
        self.header['selftest'] = dict(features=X.tolist(), forces=Y.tolist())

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
        """features: (12,) or (B, 12) raw features (m) -> (2,) or (B, 2) N (bounded)."""
        x = np.asarray(features, dtype=float)
        if x.shape[-1:] != (N_FEATURES,) or x.ndim > 2:
            raise ValueError(f'features must have shape (12,) or (B, 12), got {x.shape}')
        if not np.isfinite(x).all():
            raise ValueError('features contain non-finite values')
        return self._predict_valid(x, return_flags)

    def _predict_valid(self, x: np.ndarray, return_flags: bool):
        xc = np.clip(x, self._lo, self._hi)          # bounded: no extrapolation
        if x.ndim == 1:
            y = self._forward1((xc - self._xm) * self._xis) * self._ys + self._ym
            y2 = float(y @ y)
            ok = bool(y2 <= self._fmax2)
            if not ok:
                y = y * np.sqrt(self._fmax2 / y2)
            if not return_flags:
                return y
            return y, ok and bool((x == xc).all())
        y = self._forward((xc - self._xm) * self._xis) * self._ys + self._ym
        y2 = np.einsum('ij,ij->i', y, y)
        ok = y2 <= self._fmax2
        if not ok.all():
            y[~ok] *= np.sqrt(self._fmax2 / y2[~ok])[:, None]
        if not return_flags:
            return y
        return y, ok & (x == xc).all(axis=1)

    def predict(self, control_points, return_flags: bool = False):
        """Tip force from Bezier control points.

        control_points: (4, 3) m -> (2,) N (fx, fy) in catheter_base; (B, 4, 3) -> (B, 2).
        The force is bounded: |f| <= f_bound whatever the input (see the module docstring).
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

    def _domain(self, x: np.ndarray):
        """(domain distance, indices of the k nearest reference inputs) of features x
        (12,): the distance
        is the larger of the nearest-neighbour distance over its threshold
        (force_estimator.domain) and, outside the envelope box, 1 + how far outside (over the
        box's padding); <= 1 inside. Files without a domain reference: 0 inside the box."""
        out = np.maximum(self._lo - x, x - self._hi)
        pad = np.maximum(ENVELOPE_MARGIN * (self._hi - self._lo) / (1 + 2 * ENVELOPE_MARGIN),
                         ENVELOPE_MIN_PAD)
        box = 1.0 + float(np.max(out / pad)) if (out > 0).any() else 0.0
        if self.domain is None:
            return box, None
        d, idx = self.domain.neighbours(x)
        return max(d / self.domain.threshold, box), idx

    def domain_distance(self, control_points) -> float:
        """The input's distance beyond the training domain (0 inside; see _domain and
        force_estimator.estimate.domain_distance)."""
        return domain_distance(self._domain(control_points_to_features(control_points))[0])

    def covariance(self, force, neighbours=None) -> np.ndarray:
        """Covariance (2, 2) N^2 of an estimate `force`: the observability table (the
        shape's information about the force) at the estimate or at the training force of one
        of the input's nearest reference inputs (indices `neighbours`), whichever is the
        least determined, plus the model's own error covariance."""
        if self.table is None:
            return np.eye(2) * FORCE_PRIOR ** 2
        C = self.table.lookup(force)
        if neighbours is not None and self._ref_weak is not None and len(neighbours):
            j = neighbours[int(np.argmax(self._ref_weak[neighbours]))]
            if self._ref_weak[j] > np.linalg.eigvalsh(C)[-1]:
                C = self._ref_cov[j]
        return C + self.model_cov

    def estimate(self, control_points) -> ForceEstimate:
        """One estimate with uncertainty and status (see force_estimator.estimate).

        control_points: (4, 3) m (or (4, 2)). Raises ValueError for a wrong shape only;
        non-finite or absurd inputs give a failed estimate (force 0, status)."""
        bad = check_control_points(control_points)
        if bad is not None:
            return failed_estimate(bad[0], self.kind, bad[1], self.f_bound)
        x = control_points_to_features(control_points)
        ratio, nb = self._domain(x)
        raw = self._forward1((np.clip(x, self._lo, self._hi) - self._xm) * self._xis) \
            * self._ys + self._ym
        force, clipped = bounded(raw, self.f_bound)
        cov = self.covariance(force, nb)
        status, msg = status_of(
            cov, (not ratio <= 1.0, 'out_of_domain', lambda: f'the control points are '
                  f'{ratio:.3g} x the domain threshold from the training inputs'),
            (clipped, 'out_of_envelope', lambda: f'the model gave |f| = {np.hypot(*raw):.3g} N '
             f'> {self.f_bound:.3g} N (scaled back)'))
        return ForceEstimate(force=force, covariance=cov, status=status, method=self.kind,
                             primary=self.kind, domain_distance=domain_distance(ratio),
                             message=msg)

    def save(self, path: str) -> str:
        """Write the model as .npz (arrays + JSON header; no pickle). Returns the path."""
        path = os.fspath(path)
        if not path.endswith('.npz'):
            path += '.npz'
        header = dict(self.header)
        header.update(format=FORMAT, version=FORMAT_VERSION, kind=self.kind)
        arrays = dict(self.arrays)
        for k in ('domain_X', 'domain_Y'):
            if k in arrays:
                arrays[k] = arrays[k].astype(np.float32)
        np.savez(path, header=np.array(json.dumps(header, sort_keys=True)), **arrays)
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
    try:
        with np.load(path, allow_pickle=False) as data:
            files = list(data.files) if hasattr(data, 'files') else None
            if files is not None and 'header' in files:
                header = json.loads(str(data['header'][()]))
                arrays = {k: np.array(data[k]) for k in files if k != 'header'}
    except (OSError, EOFError, ValueError, KeyError, AttributeError, TypeError,
            zipfile.BadZipFile) as exc:
        raise ValueError(f'path {path!r} is not a readable model file: {exc}') from None
    if files is None or 'header' not in files:
        raise ValueError(f'path {path!r} is not a force_estimator model (no header)')
    if not isinstance(header, dict):
        raise ValueError(f'path {path!r} has a header that is not a JSON object')
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

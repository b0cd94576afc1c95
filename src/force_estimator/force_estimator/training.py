"""Training of the learned force models with scikit-learn, exported to `ForceModel`.

Inputs X (n, 12) are raw control-point features (m), targets Y (n, 2) tip forces (N).
Both are standardised (mean / scale) before fitting; a feature whose training spread is
below `MIN_FEATURE_SCALE` (e.g. z of a planar data set, or p0 which sits at the clamp) gets
that scale instead, so it carries no weight rather than amplifying camera noise.

* SVR (thesis section 2.3.2.2): RBF kernel, C = 100, one regressor per output; epsilon
  (given in newtons, i.e. target units) and gamma are chosen by validation on a held-out
  part of the training set (mean absolute error in N), then refitted on all of it.
* MLP (thesis section 2.3.2.1): one hidden layer of 10 ReLU units, L-BFGS; several
  initialisations, the best on validation wins. A larger MLP is available through
  `hidden_layer_sizes`; `n_ensemble` > 1 trains that many networks from different
  initialisations and stores their average as ONE ReLU network (`merge_mlps`: the members
  side by side, block-diagonal hidden weights, the output layer divided by their number),
  so the model file's format and its forward pass are those of a single MLP.

scikit-learn is imported only here, never by the inference path.
"""
from __future__ import annotations

import time
from typing import Dict, Iterable, Optional, Sequence, Tuple

import numpy as np

from force_estimator.models import (N_FEATURES, N_TARGETS, TARGET_NAMES, ForceModel,
                                    envelope_bounds)

#: scale floor of a feature, m: spreads below this are treated as noise, not signal
MIN_FEATURE_SCALE = 1e-3
#: thesis regularisation constant
SVR_C = 100.0
#: candidate epsilons, N (target units)
SVR_EPSILONS_N = (2.5e-4, 1e-3, 4e-3)
#: candidate RBF widths in standardised feature units
SVR_GAMMAS = (0.01, 0.03, 0.1, 0.3, 1.0)
#: at most this many samples take part in the hyper-parameter search (speed)
MAX_SEARCH = 800
#: relative slack of the validation MAE within which a sparser SVR (larger epsilon) wins
SPARSE_TOL = 0.05


def _check_xy(X, Y) -> Tuple[np.ndarray, np.ndarray]:
    X = np.asarray(X, dtype=float)
    Y = np.asarray(Y, dtype=float)
    if X.ndim != 2 or X.shape[1] != N_FEATURES:
        raise ValueError(f'X must have shape (n, 12), got {X.shape}')
    if Y.shape != (X.shape[0], N_TARGETS):
        raise ValueError(f'Y must have shape ({X.shape[0]}, 2), got {Y.shape}')
    if X.shape[0] < 10:
        raise ValueError(f'X needs at least 10 samples, got {X.shape[0]}')
    if not (np.isfinite(X).all() and np.isfinite(Y).all()):
        raise ValueError('X and Y must be finite')
    return X, Y


def scaling(X: np.ndarray, Y: np.ndarray) -> Dict[str, np.ndarray]:
    """Standardisation arrays and the training envelope of (X, Y)."""
    lo, hi = envelope_bounds(X)
    return dict(x_mean=X.mean(axis=0), x_scale=np.maximum(X.std(axis=0), MIN_FEATURE_SCALE),
                y_mean=Y.mean(axis=0), y_scale=np.maximum(Y.std(axis=0), 1e-6),
                env_lo=lo, env_hi=hi)


def _split(n: int, frac: float, seed: int) -> Tuple[np.ndarray, np.ndarray]:
    idx = np.random.default_rng(seed).permutation(n)
    n_val = max(1, int(round(frac * n)))
    return idx[n_val:], idx[:n_val]


def _header(kind: str, X, Y, hyper: dict, extra: Optional[dict]) -> dict:
    import sklearn
    h = dict(kind=kind, features='bezier control points p0..p3 (x, y, z), m, catheter_base',
             targets=list(TARGET_NAMES), target_units='N', feature_units='m',
             hyper=hyper, n_train=int(X.shape[0]), sklearn_version=sklearn.__version__,
             envelope=dict(max_force=float(np.sqrt((Y ** 2).sum(axis=1)).max()),
                           margin='see force_estimator.models.ENVELOPE_MARGIN'))
    if extra:
        h.update(extra)
    return h


def svr_arrays(models: Sequence, ) -> Dict[str, np.ndarray]:
    """Stack fitted sklearn SVRs (one per output, RBF, numeric gamma) into sv/coef/gamma/intercept.

    Support vectors shared by outputs with the same gamma are stored once.
    """
    rows: Dict[Tuple[float, int], int] = {}
    sv, coef, gamma = [], [], []
    for k, m in enumerate(models):
        g = float(m._gamma)
        for j, (idx, vec) in enumerate(zip(m.support_, m.support_vectors_, strict=True)):
            key = (g, int(idx))
            if key not in rows:
                rows[key] = len(sv)
                sv.append(vec)
                coef.append(np.zeros(len(models)))
                gamma.append(g)
            coef[rows[key]][k] += m.dual_coef_[0, j]
    return dict(sv=np.array(sv), coef=np.array(coef), gamma=np.array(gamma),
                intercept=np.array([float(m.intercept_[0]) for m in models]))


def _standardised(X, Y, val_frac: float, seed: int):
    """Checked (X, Y), their scaling, the standardised Z, T and the (train, validation)
    index split both trainers use."""
    X, Y = _check_xy(X, Y)
    sc = scaling(X, Y)
    Z = (X - sc['x_mean']) / sc['x_scale']
    T = (Y - sc['y_mean']) / sc['y_scale']
    tr, va = _split(len(X), val_frac, seed)
    return X, Y, sc, Z, T, tr, va


def fit_svr(X, Y, C: float = SVR_C, epsilons_n: Iterable[float] = SVR_EPSILONS_N,
            gammas: Iterable[float] = SVR_GAMMAS, val_frac: float = 0.2, seed: int = 0,
            extra_header: Optional[dict] = None,
            max_search: int = MAX_SEARCH) -> Tuple[ForceModel, dict]:
    """Train one RBF SVR per output; epsilon (N) and gamma by validation MAE (N).

    The search fits on at most `max_search` samples of the training part (the validation
    part is always the held-out `val_frac`). Among the pairs within `SPARSE_TOL` of the best
    validation MAE the largest epsilon wins (fewer support vectors: faster, smoother); it
    is refitted on all samples.

    Returns (model, report) with report = chosen hyper-parameters, validation table, fit time.
    """
    from sklearn.svm import SVR
    t0 = time.perf_counter()
    X, Y, sc, Z, T, tr, va = _standardised(X, Y, val_frac, seed)
    tr = tr[:max_search]
    chosen, table = [], []
    for k in range(N_TARGETS):
        cand = []
        for eps in epsilons_n:
            for g in gammas:
                m = SVR(kernel='rbf', C=C, epsilon=eps / sc['y_scale'][k], gamma=g)
                m.fit(Z[tr], T[tr, k])
                mae = float(np.abs(m.predict(Z[va]) * sc['y_scale'][k] - T[va, k]
                                   * sc['y_scale'][k]).mean())
                table.append((TARGET_NAMES[k], eps, g, mae))
                cand.append((mae, eps, g))
        best = min(c[0] for c in cand)
        ok = [c for c in cand if c[0] <= (1.0 + SPARSE_TOL) * best]
        chosen.append(min(ok, key=lambda c: (-c[1], c[0])))
    models = []
    for k, (_, eps, g) in enumerate(chosen):
        m = SVR(kernel='rbf', C=C, epsilon=eps / sc['y_scale'][k], gamma=g)
        m.fit(Z, T[:, k])
        models.append(m)
    fit_time = time.perf_counter() - t0
    hyper = dict(C=C, kernel='rbf', epsilon_n=[c[1] for c in chosen],
                 gamma=[c[2] for c in chosen], val_mae_n=[c[0] for c in chosen])
    model = ForceModel('svr', {**sc, **svr_arrays(models)},
                       _header('svr', X, Y, hyper, extra_header))
    model.header['fit_time_s'] = fit_time
    model.sklearn = models
    return model, dict(hyper=hyper, table=table, fit_time_s=fit_time)


def mlp_arrays(mlp) -> Dict[str, np.ndarray]:
    """Weights of a fitted sklearn MLPRegressor (ReLU hidden, identity output) as W0, b0, ..."""
    if mlp.activation != 'relu' or mlp.out_activation_ != 'identity':
        raise ValueError('mlp must use ReLU hidden layers and an identity output')
    out = {}
    for i, (W, b) in enumerate(zip(mlp.coefs_, mlp.intercepts_, strict=True)):
        out[f'W{i}'] = np.array(W)
        out[f'b{i}'] = np.array(b)
    return out


def merge_mlps(mlps: Sequence) -> Dict[str, np.ndarray]:
    """The average of K fitted MLPRegressors of one architecture (ReLU hidden layers, identity
    output, the same input and target scaling) as the arrays of ONE ReLU network: the first
    layer's units side by side, the hidden layers block-diagonal (member k's units see only
    member k's), the output layer stacked and divided by K, the output bias averaged. Its
    output equals the members' mean exactly (up to round-off)."""
    if len(mlps) == 0:
        raise ValueError('mlps must hold at least one fitted network')
    parts = [mlp_arrays(m) for m in mlps]
    n_layers = len(parts[0]) // 2
    if any(len(p) != 2 * n_layers or any(p[f'W{i}'].shape != parts[0][f'W{i}'].shape
                                         for i in range(n_layers)) for p in parts):
        raise ValueError('mlps must share one architecture')
    k = len(parts)
    out = {}
    for i in range(n_layers):
        Ws = [p[f'W{i}'] for p in parts]
        bs = [p[f'b{i}'] for p in parts]
        if i == 0:
            W = np.concatenate(Ws, axis=1)
        elif i < n_layers - 1:
            W = np.zeros((sum(w.shape[0] for w in Ws), sum(w.shape[1] for w in Ws)))
            r = c = 0
            for w in Ws:
                W[r:r + w.shape[0], c:c + w.shape[1]] = w
                r, c = r + w.shape[0], c + w.shape[1]
        else:
            W = np.concatenate(Ws, axis=0) / k
        out[f'W{i}'] = W
        out[f'b{i}'] = np.mean(bs, axis=0) if i == n_layers - 1 else np.concatenate(bs)
    return out


def fit_mlp(X, Y, hidden_layer_sizes: Tuple[int, ...] = (10,), alpha: float = 1e-4,
            n_init: int = 5, max_iter: int = 5000, val_frac: float = 0.2, seed: int = 0,
            extra_header: Optional[dict] = None, n_ensemble: int = 1,
            sample_weight=None) -> Tuple[ForceModel, dict]:
    """Train an MLP (ReLU, L-BFGS) on standardised data.

    n_ensemble == 1: the best of `n_init` seeds on validation (the held-out `val_frac` of
    X), refitted on all training data. n_ensemble > 1: that many networks (seeds seed,
    seed + 1, ...) fitted on all training data and stored as their average, one network
    (`merge_mlps`); n_init is then unused. sample_weight: (n,) >= 0 weights of the squared
    error per sample (None: all 1; see `observability_weights`). Returns (model, report).
    """
    import warnings

    from sklearn.exceptions import ConvergenceWarning
    from sklearn.neural_network import MLPRegressor
    if int(n_ensemble) != n_ensemble or n_ensemble < 1:
        raise ValueError(f'n_ensemble must be an integer >= 1, got {n_ensemble!r}')
    t0 = time.perf_counter()
    X, Y, sc, Z, T, tr, va = _standardised(X, Y, val_frac, seed)
    w = np.ones(len(X)) if sample_weight is None else np.asarray(sample_weight, dtype=float)
    if w.shape != (len(X),) or not np.isfinite(w).all() or (w < 0).any() or w.sum() <= 0:
        raise ValueError(f'sample_weight must be (n,) = ({len(X)},) finite, >= 0 and not all '
                         f'0, got shape {w.shape}')

    def make(rs):
        return MLPRegressor(hidden_layer_sizes=tuple(hidden_layer_sizes), activation='relu',
                            solver='lbfgs', alpha=alpha, max_iter=max_iter, random_state=rs)
    best, table = None, []
    with warnings.catch_warnings():
        warnings.simplefilter('ignore', ConvergenceWarning)
        if n_ensemble > 1:
            members = [make(rs).fit(Z, T, sample_weight=w)
                       for rs in range(seed, seed + int(n_ensemble))]
            arrays, mlp, best = merge_mlps(members), members, (None, seed)
        else:
            for rs in range(seed, seed + n_init):
                m = make(rs).fit(Z[tr], T[tr], sample_weight=w[tr])
                mae = float(np.average(np.abs((m.predict(Z[va]) - T[va]) * sc['y_scale'])
                                       .mean(axis=1), weights=w[va]))
                table.append((rs, mae))
                if best is None or mae < best[0]:
                    best = (mae, rs)
            mlp = make(best[1]).fit(Z, T, sample_weight=w)
            arrays = mlp_arrays(mlp)
    fit_time = time.perf_counter() - t0
    hyper = dict(hidden_layer_sizes=list(hidden_layer_sizes), activation='relu',
                 solver='lbfgs', alpha=alpha, max_iter=max_iter, random_state=best[1],
                 val_mae_n=best[0], n_ensemble=int(n_ensemble),
                 sample_weight='uniform' if sample_weight is None else 'given')
    model = ForceModel('mlp', {**sc, **arrays}, _header('mlp', X, Y, hyper, extra_header))
    model.header['fit_time_s'] = fit_time
    model.sklearn = mlp
    return model, dict(hyper=hyper, table=table, fit_time_s=fit_time)


def observability_weights(Y, table, std_n: float) -> np.ndarray:
    """Per-sample weights of the squared error for the MLP: 1 / (1 + (s / std_n)^2), where s
    (N) is the std of the weakest direction of the observability table at the sample's force
    (force_estimator.uncertainty). A near-axial pull's shape hardly depends on the pull, so
    its target is noise the network cannot fit; with equal weights those residuals (tens of
    mN) dominate the squared loss and the fit of the directions the shape determines
    suffers. An unloaded sample (f = 0) keeps weight 1: the training set's unloaded
    catheters are the prior that a shape which does not determine the axial force means no
    force (as the FAM inversion's weak force prior); down-weighted with the pulls, the MLP
    read a straight catheter as a 49 mN pull. Normalised to mean 1. Y: (n, 2) N;
    std_n > 0."""
    if not (np.isfinite(std_n) and std_n > 0):
        raise ValueError(f'std_n must be positive, got {std_n!r}')
    Y = np.asarray(Y, dtype=float)
    if Y.ndim != 2 or Y.shape[1] != N_TARGETS or not np.isfinite(Y).all():
        raise ValueError(f'Y must be finite with shape (n, 2), got {Y.shape}')
    weak = np.sqrt(np.linalg.eigvalsh(table.lookup(Y))[:, -1])
    w = 1.0 / (1.0 + (weak / std_n) ** 2)
    w[(Y == 0.0).all(axis=1)] = 1.0
    return w / w.mean()


def calibrate(model: ForceModel, X_train, X_val, Y_val, table=None, seed: int = 0,
              n_selftest: int = 8, observable_std: float = None, Y_train=None) -> dict:
    """Attach what a shipped model needs besides its weights, measured on held-out data
    of the training distribution (X_val, Y_val, never trained on):

    * the domain check (force_estimator.domain): reference = the training inputs (and their
      forces Y_train, for the neighbours' spread), threshold from the held-out inputs'
      nearest-neighbour distances;
    * the observability table (force_estimator.uncertainty.ObservabilityTable, optional);
    * model_cov: the covariance of the held-out errors where the force is observable (the
      table's weakest std below `observable_std`, default UNOBSERVABLE_STD), without the 5 %
      largest, i.e. the model's own error on top of what the shape cannot tell;
    * the self-test: n_selftest training inputs and the model's outputs for them.

    Modifies the model in place (arrays and header) and re-validates it by rebuilding it
    from its arrays. Returns a report (domain threshold, model std, counts)."""
    from force_estimator.domain import DomainCheck
    from force_estimator.estimate import UNOBSERVABLE_STD
    lim = UNOBSERVABLE_STD if observable_std is None else observable_std
    X_train = np.asarray(X_train, dtype=float)
    X_val = np.asarray(X_val, dtype=float)
    Y_val = np.asarray(Y_val, dtype=float)
    dc = DomainCheck.calibrate(X_train, X_val, seed=seed, Y_train=Y_train)
    model.arrays.update(dc.arrays())
    model.header['domain'] = dc.header()
    if table is not None:
        model.arrays.update(table.arrays())
    P = model.predict_features(X_val)
    E = P - Y_val
    if table is not None:
        weak = np.array([np.linalg.eigvalsh(table.lookup(f))[-1] for f in Y_val])
        use = weak < lim ** 2
    else:
        use = np.ones(len(E), bool)
    # trimmed: the 5 % largest errors (a few inputs far from any training input) would
    # dominate the covariance of the typical estimate
    if use.sum() > 20:
        n = np.hypot(*E.T)
        use &= n <= np.quantile(n[use], 0.95)
    C = np.cov(E[use].T) if use.sum() > 2 else np.eye(2) * lim ** 2
    model.header['model_cov'] = (0.5 * (C + C.T)).tolist()
    idx = np.random.default_rng(seed).choice(len(X_train), min(n_selftest, len(X_train)),
                                             replace=False)
    model.make_selftest(X_train[idx])
    rebuilt = ForceModel(model.kind, model.arrays, model.header, name=model.name)
    model.__dict__.update({k: v for k, v in rebuilt.__dict__.items() if k != 'sklearn'})
    return dict(domain_threshold_m=dc.threshold, model_std_n=np.sqrt(np.diag(C)).tolist(),
                n_observable_val=int(use.sum()), n_val=int(len(E)),
                val_mae_n=float(np.hypot(*E.T).mean()),
                val_mae_observable_n=float(np.hypot(*E[use].T).mean()) if use.any() else None)


def sklearn_predict(model: ForceModel, X) -> np.ndarray:
    """The scikit-learn prediction of a freshly trained model (for equivalence tests and
    benchmarks): X (B, 12) raw features -> (B, 2) N."""
    a = model.arrays
    Z = (np.asarray(X, dtype=float) - a['x_mean']) / a['x_scale']
    if model.kind == 'svr':
        T = np.stack([m.predict(Z) for m in model.sklearn], axis=1)
    elif isinstance(model.sklearn, (list, tuple)):       # an ensemble: the members' mean
        T = np.mean([m.predict(Z).reshape(-1, N_TARGETS) for m in model.sklearn], axis=0)
    else:
        T = model.sklearn.predict(Z).reshape(-1, N_TARGETS)
    return T * a['y_scale'] + a['y_mean']

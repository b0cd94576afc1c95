"""Shared fixtures of the force_estimator tests: a toy data set and models trained on it."""
import numpy as np
import pytest


def toy_data(n=160, seed=0):
    """Planar control-point-like features (z = 0), (n, 12) m, and a smooth nonlinear force
    map (n, 2) N."""
    rng = np.random.default_rng(seed)
    cp = np.zeros((n, 4, 3))
    cp[:, 1, 0] = 0.02 + 0.003 * rng.standard_normal(n)
    cp[:, 2, :2] = [0.04, 0.0] + 0.01 * rng.standard_normal((n, 2))
    cp[:, 3, :2] = [0.06, 0.0] + 0.015 * rng.standard_normal((n, 2))
    X = cp.reshape(n, 12)
    Y = np.stack([3.0 * (cp[:, 3, 0] - 0.06) + 20 * (cp[:, 2, 1]) ** 2,
                  10.0 * cp[:, 3, 1] * (1 + 10 * cp[:, 2, 1])], axis=1)
    return X, Y


def toy_table(std=0.002):
    """A flat observability table: every force known to `std` N per axis."""
    from force_estimator.uncertainty import ObservabilityTable
    ang = np.linspace(-np.pi, np.pi, 8, endpoint=False)
    cov = np.broadcast_to(np.eye(2) * std ** 2, (8, 2, 2, 2)).copy()
    return ObservabilityTable(ang, np.array([0.0, 1.0]), cov)


@pytest.fixture(scope='session')
def toy_models():
    """(X, Y, {'svr', 'mlp', 'big'} models, svr training report); trained on the first 130
    samples, calibrated (domain, model error, self-test, a flat table) on the last 30."""
    from threadpoolctl import threadpool_limits

    from force_estimator.training import calibrate, fit_mlp, fit_svr
    X, Y = toy_data()
    tr, va = slice(0, 130), slice(130, None)
    with threadpool_limits(limits=1):        # multi-threaded BLAS is slower when shared
        svr, rep_s = fit_svr(X[tr], Y[tr], epsilons_n=(1e-3, 4e-3), gammas=(0.02, 0.1))
        mlp, _ = fit_mlp(X[tr], Y[tr], n_init=2, max_iter=500)
        big, _ = fit_mlp(X[tr], Y[tr], hidden_layer_sizes=(16, 16), n_init=1, max_iter=300)
    for m in (svr, mlp, big):
        calibrate(m, X[tr], X[va], Y[va], table=toy_table(), Y_train=Y[tr])
    return X, Y, {'svr': svr, 'mlp': mlp, 'big': big}, rep_s


@pytest.fixture(scope='session')
def toy_model_files(toy_models, tmp_path_factory):
    """Paths of the toy svr and mlp models saved as .npz."""
    d = tmp_path_factory.mktemp('models')
    return {k: toy_models[2][k].save(d / f'toy-{k}.npz') for k in ('svr', 'mlp')}

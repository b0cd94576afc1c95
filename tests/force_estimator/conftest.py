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


@pytest.fixture(scope='session')
def toy_models():
    """(X, Y, {'svr', 'mlp', 'big'} models, svr training report)."""
    from force_estimator.training import fit_mlp, fit_svr
    X, Y = toy_data()
    svr, rep_s = fit_svr(X, Y, epsilons_n=(1e-3, 4e-3), gammas=(0.02, 0.1))
    mlp, _ = fit_mlp(X, Y, n_init=2, max_iter=500)
    big, _ = fit_mlp(X, Y, hidden_layer_sizes=(16, 16), n_init=1, max_iter=300)
    return X, Y, {'svr': svr, 'mlp': mlp, 'big': big}, rep_s


@pytest.fixture(scope='session')
def toy_model_files(toy_models, tmp_path_factory):
    """Paths of the toy svr and mlp models saved as .npz."""
    d = tmp_path_factory.mktemp('models')
    return {k: toy_models[2][k].save(d / f'toy-{k}.npz') for k in ('svr', 'mlp')}

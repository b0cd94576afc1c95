"""An ensemble of MLPs stored as ONE ReLU network (force_estimator.training.merge_mlps):
the merged forward pass equals the members' mean (an independent reference: scikit-learn's
own predict of each member), the file format stays that of a single MLP, and bad input to
the merge and to fit_mlp is refused with the argument named."""
import warnings

import numpy as np
import pytest

from force_estimator.models import ForceModel, load_estimator
from force_estimator.training import fit_mlp, merge_mlps, sklearn_predict



@pytest.fixture(autouse=True)
def _one_blas_thread():
    """Multi-threaded BLAS is many times slower on the shared machine (see train.py)."""
    from threadpoolctl import threadpool_limits
    with threadpool_limits(limits=1):
        yield


def toy_data(n, seed=0):
    """Random control-point-like features (n, 12) m and a smooth nonlinear map (n, 2) N."""
    rng = np.random.default_rng(seed)
    X = rng.normal(0.0, 0.01, (n, 12)) + np.tile([0.0, 0.0, 0.0, 0.02, 0, 0, 0.04, 0, 0,
                                                  0.06, 0, 0], (n, 1))
    Y = np.stack([5.0 * X[:, 9] + 30.0 * X[:, 7] ** 2, 8.0 * X[:, 10] * (1 + 20 * X[:, 7])],
                 axis=1)
    return X, Y


def _members(hidden, k, seed=0):
    from sklearn.exceptions import ConvergenceWarning
    from sklearn.neural_network import MLPRegressor
    X, Y = toy_data(80, seed=seed)
    Z = (X - X.mean(0)) / np.maximum(X.std(0), 1e-3)
    with warnings.catch_warnings():
        warnings.simplefilter('ignore', ConvergenceWarning)
        return Z, [MLPRegressor(hidden_layer_sizes=hidden, solver='lbfgs', max_iter=60,
                                random_state=s).fit(Z, Y) for s in range(k)]


@pytest.mark.parametrize('hidden', [(5,), (6, 4), (3, 5, 4)])
@pytest.mark.parametrize('k', [1, 3])
def test_merged_network_equals_the_members_mean(hidden, k):
    Z, ms = _members(hidden, k)
    a = merge_mlps(ms)
    # the merged weights are k times as wide, hidden-to-hidden block-diagonal
    assert a['W0'].shape == (12, k * hidden[0])
    for i in range(1, len(hidden)):
        assert a[f'W{i}'].shape == (k * hidden[i - 1], k * hidden[i])
    h = Z
    for i in range(len(hidden) + 1):
        h = h @ a[f'W{i}'] + a[f'b{i}']
        if i < len(hidden):
            h = np.maximum(h, 0.0)
    ref = np.mean([m.predict(Z) for m in ms], axis=0)
    assert np.allclose(h, ref, rtol=1e-10, atol=1e-12)
    # each member alone is not the mean (the test would pass for a merge that kept one)
    if k > 1:
        assert not np.allclose(ms[0].predict(Z), ref, atol=1e-6)


def test_merge_refuses_empty_and_mixed_architectures():
    with pytest.raises(ValueError, match='mlps'):
        merge_mlps([])
    _, a = _members((4,), 1)
    _, b = _members((5,), 1)
    with pytest.raises(ValueError, match='mlps'):
        merge_mlps(a + b)
    _, c = _members((4, 4), 1)
    with pytest.raises(ValueError, match='mlps'):
        merge_mlps(a + c)


def test_fit_mlp_ensemble_is_one_network_in_the_model_format(tmp_path):
    X, Y = toy_data(120)
    m, rep = fit_mlp(X, Y, hidden_layer_sizes=(8, 8), n_ensemble=3, max_iter=200, seed=4)
    assert rep['hyper']['n_ensemble'] == 3 and rep['hyper']['hidden_layer_sizes'] == [8, 8]
    assert len(m.sklearn) == 3 and [s.random_state for s in m.sklearn] == [4, 5, 6]
    # the numpy forward of the merged network is the scikit-learn members' mean
    assert np.allclose(m.predict_features(X[:40]), sklearn_predict(m, X[:40]), atol=1e-10)
    m.make_selftest(X[:4])
    back = load_estimator(m.save(tmp_path / 'ens.npz'))
    assert isinstance(back, ForceModel) and back.kind == 'mlp'
    assert back.arrays['W1'].shape == (24, 24)
    assert np.allclose(back.predict_features(X[:40]), m.predict_features(X[:40]), atol=1e-12)


@pytest.mark.parametrize('bad', [0, -1, 2.5])
def test_fit_mlp_refuses_a_bad_ensemble_size(bad):
    X, Y = toy_data(40)
    with pytest.raises(ValueError, match='n_ensemble'):
        fit_mlp(X, Y, n_ensemble=bad)


def _axial_table():
    """Pulls and pushes (angle 0, pi) known to 0.05 N in their weakest direction, lateral
    forces (+-pi/2) to 0.002 N, the diagonals to 0.01 N; the same at every magnitude."""
    from force_estimator.uncertainty import ObservabilityTable
    ang = np.linspace(-np.pi, np.pi, 8, endpoint=False)      # -180, -135, ..., 135 deg
    weak = {0: 0.05, 4: 0.05, 2: 0.002, 6: 0.002}
    cov = np.zeros((8, 2, 2, 2))
    for i in range(8):
        s = weak.get(i, 0.01)
        cov[i] = np.diag([s ** 2, 1e-6 ** 2])
    return ObservabilityTable(ang, np.array([0.0, 0.3]), cov)


def test_observability_weights_hand_checked():
    from force_estimator.training import observability_weights
    Y = np.array([[0.3, 0.0], [0.0, 0.3], [0.0, -0.3], [-0.3 / np.sqrt(2), 0.3 / np.sqrt(2)]])
    w = observability_weights(Y, _axial_table(), 0.01)
    raw = 1.0 / (1.0 + (np.array([0.05, 0.002, 0.002, 0.01]) / 0.01) ** 2)
    assert np.allclose(w, raw / raw.mean(), rtol=1e-9)
    assert w[1] > w[3] > w[0] and np.isclose(w.mean(), 1.0)
    # an unloaded sample keeps weight 1 (the prior: no force) however weak the table is there
    w0 = observability_weights(np.r_[Y, [[0.0, 0.0]]], _axial_table(), 0.01)
    raw0 = np.r_[raw, 1.0]
    assert np.allclose(w0, raw0 / raw0.mean(), rtol=1e-9)


@pytest.mark.parametrize('Y, std, match', [
    (np.zeros((3, 2)), 0.0, 'std_n'), (np.zeros((3, 2)), np.nan, 'std_n'),
    (np.zeros((3, 3)), 0.01, 'Y'), (np.array([[np.nan, 0.0]]), 0.01, 'Y')])
def test_observability_weights_refuse_bad_input(Y, std, match):
    from force_estimator.training import observability_weights
    with pytest.raises(ValueError, match=match):
        observability_weights(Y, _axial_table(), std)


@pytest.mark.parametrize('n_ensemble', [1, 2])
def test_fit_mlp_sample_weight_is_used_and_checked(n_ensemble):
    X, Y = toy_data(120, seed=2)
    with pytest.raises(ValueError, match='sample_weight'):
        fit_mlp(X, Y, sample_weight=np.ones(5))
    with pytest.raises(ValueError, match='sample_weight'):
        fit_mlp(X, Y, sample_weight=-np.ones(len(X)))
    # weight only the first half: the fit follows those samples, not the others
    Yb = Y.copy()
    Yb[60:] += 0.05                  # the second half disagrees by 50 mN
    w = np.r_[np.ones(60), np.full(60, 1e-6)]
    m, rep = fit_mlp(X, Yb, hidden_layer_sizes=(8,), n_init=1, max_iter=300,
                     sample_weight=w, n_ensemble=n_ensemble)
    assert rep['hyper']['sample_weight'] == 'given'
    err_first = np.abs(m.predict_features(X) - Y).mean()
    err_second = np.abs(m.predict_features(X) - Yb).mean()
    assert err_first < 0.01 < err_second

"""Learned models: the numpy forward pass equals scikit-learn's predict, files round-trip
without pickle, bad input is refused, the training envelope flags extrapolation."""
import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from force_estimator.models import (ForceModel, control_points_to_features, load_estimator,
                                    load_model)
from force_estimator.training import sklearn_predict


@pytest.fixture(scope='module')
def trained(toy_models):
    return toy_models


def _inside(m, X):
    return ((X >= m.arrays['env_lo']) & (X <= m.arrays['env_hi'])).all(axis=1)


@pytest.mark.parametrize('kind', ['svr', 'mlp', 'big'])
def test_numpy_forward_matches_sklearn(trained, kind):
    """Inside the training envelope the numpy forward pass is scikit-learn's predict."""
    X, _, models, _ = trained
    m = models[kind]
    rng = np.random.default_rng(1)
    Xq = np.concatenate([X, X[:20] + 0.002 * rng.standard_normal((20, 12))])
    Xq = Xq[_inside(m, Xq)]
    assert len(Xq) >= 100
    ref = sklearn_predict(m, Xq)
    small = np.hypot(*ref.T) <= m.f_bound          # the force bound is not reached
    np.testing.assert_allclose(m.predict_features(Xq)[small], ref[small], rtol=1e-9, atol=1e-12)
    # single-sample fast path and batch path agree with sklearn too
    for i in np.flatnonzero(small)[[0, 5, -1]]:
        np.testing.assert_allclose(m.predict(Xq[i].reshape(4, 3)), ref[i], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(m.predict(Xq.reshape(-1, 4, 3))[small], ref[small], rtol=1e-9,
                               atol=1e-12)


def test_models_learn_the_map(trained):
    X, Y, models, rep = trained
    scale = np.abs(Y).max()
    for kind in ('svr', 'mlp'):
        err = np.abs(models[kind].predict_features(X) - Y).mean()
        assert err < 0.05 * scale, (kind, err, scale)
    # hyper-parameters came from the validation grid, epsilon in newtons
    assert set(rep['hyper']['epsilon_n']) <= {1e-3, 4e-3}
    assert set(rep['hyper']['gamma']) <= {0.02, 0.1}
    assert models['svr'].header['hyper']['C'] == 100.0
    assert models['mlp'].header['hyper']['hidden_layer_sizes'] == [10]


@pytest.mark.parametrize('kind', ['svr', 'mlp', 'big'])
def test_save_load_roundtrip_without_pickle(trained, kind, tmp_path):
    X, _, models, _ = trained
    m = models[kind]
    path = m.save(tmp_path / f'model-{kind}')
    assert path.endswith('.npz')
    with np.load(path, allow_pickle=False) as d:       # readable with pickle disabled
        header = json.loads(str(d['header'][()]))
        assert all(d[k].dtype != object for k in d.files)
    assert header['kind'] == m.kind and header['format'] == 'force_estimator.model'
    m2 = load_estimator(path)
    assert m2.kind == m.kind
    np.testing.assert_array_equal(m2.predict_features(X), m.predict_features(X))


def test_bad_files_refused(tmp_path):
    with pytest.raises(ValueError, match='name_or_path'):
        load_estimator('no-such-model')
    with pytest.raises(ValueError, match='name_or_path'):
        load_estimator(str(tmp_path / 'm.pkl'))
    with pytest.raises(ValueError, match='does not exist'):
        load_estimator(str(tmp_path / 'missing.npz'))
    np.savez(tmp_path / 'other.npz', a=np.zeros(3))
    with pytest.raises(ValueError, match='header'):
        load_model(tmp_path / 'other.npz')
    np.savez(tmp_path / 'objs.npz', header=np.array([{'a': 1}], dtype=object))
    with pytest.raises(ValueError):
        load_model(tmp_path / 'objs.npz')      # object arrays would need pickle: refused


def test_bad_input_refused(trained):
    _, _, models, _ = trained
    m = models['svr']
    good = np.zeros((4, 3))
    for bad in (np.zeros((3, 3)), np.zeros(12), np.zeros((2, 4, 4)), np.zeros((1, 2, 4, 3))):
        with pytest.raises(ValueError, match='control_points'):
            m.predict(bad)
    for val in (np.nan, np.inf, -np.inf):
        x = good.copy()
        x[2, 1] = val
        with pytest.raises(ValueError, match='control_points'):
            m.predict(x)
        with pytest.raises(ValueError, match='control_points'):
            m.predict(np.stack([good, x]))
    with pytest.raises(ValueError, match='features'):
        m.predict_features(np.full(12, np.nan))


def test_planar_input_gets_zero_z(trained):
    X, _, models, _ = trained
    cp = X[3].reshape(4, 3)
    m = models['mlp']
    np.testing.assert_array_equal(m.predict(cp[:, :2]), m.predict_features(X[3:4])[0])
    assert control_points_to_features(cp[:, :2]).shape == (12,)


def test_envelope_flags_extrapolation(trained):
    X, _, models, _ = trained
    for m in models.values():
        _, flags = m.predict(X[:130].reshape(-1, 4, 3), return_flags=True)
        assert flags.dtype == bool and flags.all()           # every training input is inside
        far = X[0].reshape(4, 3).copy()
        far[3, 1] += 0.2                                     # 20 cm beyond any training tip
        f, inside = m.predict(far, return_flags=True)
        assert inside is False and f.shape == (2,)
        assert not m.in_envelope(np.stack([far, X[1].reshape(4, 3)]))[0]
        assert m.in_envelope(X[1].reshape(4, 3))


def test_model_arrays_are_validated(trained):
    _, _, models, _ = trained
    a = dict(models['svr'].arrays)
    a['x_scale'] = -a['x_scale']
    with pytest.raises(ValueError, match='scale'):
        ForceModel('svr', a)
    a = dict(models['mlp'].arrays)
    del a['W1']
    with pytest.raises(ValueError):
        ForceModel('mlp', a)
    with pytest.raises(ValueError, match='kind'):
        ForceModel('tree', models['mlp'].arrays)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-0.08, 0.08), min_size=12, max_size=12),
       st.sampled_from(['svr', 'mlp', 'big']))
def test_property_forward_equals_sklearn_inside_bounded_anywhere(trained, x, kind):
    """For any finite input: inside the envelope numpy == sklearn (below the force bound);
    anywhere the force is finite and bounded, and the single-sample path equals the batch
    path."""
    m = trained[2][kind]
    x = np.array(x)
    one, inside = m.predict(x.reshape(4, 3), return_flags=True)
    assert np.all(np.isfinite(one)) and np.hypot(*one) <= m.f_bound * (1 + 1e-12)
    ref = sklearn_predict(m, x[None])[0]
    if _inside(m, x[None])[0] and np.hypot(*ref) <= m.f_bound:
        np.testing.assert_allclose(one, ref, rtol=1e-8, atol=1e-11)
        assert inside
    else:
        assert not inside
    np.testing.assert_allclose(m.predict(np.stack([x.reshape(4, 3)] * 2))[1], one,
                               rtol=1e-12, atol=1e-14)

"""The training recipe's data (force_estimator.train, module doc step 2), fast: N_ZERO
unloaded cases then forces in every direction up to 0.3 N; mirroring is y -> -y of every
control point with fy -> -fy; VAL_FRAC of the cases held out; frames the sensor refuses and
non-converged shapes are not kept (the FAM and camera stages are stubbed here)."""
import numpy as np
import pytest

from force_estimator import dataset as D
from force_estimator import train


def test_full_range_forces_are_the_unloaded_cases_then_every_direction():
    F = train.full_range_forces(2000, seed=3)
    assert F.shape == (train.N_ZERO + 2000, 2) and train.N_ZERO == 300
    assert np.all(F[:300] == 0.0) and np.all(np.hypot(*F[300:].T) > 0.0)
    mag = np.hypot(*F[300:].T)
    assert mag.max() <= D.F_MAX
    ang = np.arctan2(F[300:, 1], F[300:, 0])
    quadrant = np.digitize(ang, [-np.pi / 2, 0.0, np.pi / 2])
    counts = np.bincount(quadrant, minlength=4) / 2000
    assert counts == pytest.approx([0.25] * 4, abs=0.04)       # uniform over [-pi, pi)


def test_mirror_negates_y_and_fy():
    cp = np.array([[0.0, 0.0, 0.0], [0.02, 0.001, 0.0], [0.04, 0.01, 0.0],
                   [0.06, 0.02, 0.001]])
    X, Y = train._mirror(cp.reshape(1, 12), np.array([[0.05, 0.1]]))
    np.testing.assert_array_equal(X[0], cp.reshape(12))
    np.testing.assert_array_equal(X[1].reshape(4, 3), cp * [1.0, -1.0, 1.0])
    np.testing.assert_array_equal(Y, [[0.05, 0.1], [0.05, -0.1]])


def test_training_set_keeps_converged_accepted_frames_and_holds_out_val_frac(monkeypatch):
    n_random = 3000
    n = train.N_ZERO + n_random
    conv = np.ones(n, bool)
    conv[[5, 700, 701]] = False
    ok = np.ones(n, bool)
    ok[[5, 40, 2000]] = False
    cp = np.where(ok[:, None, None], 0.01, np.nan) * np.ones((n, 4, 3))

    def centerlines(F, progress=False):
        assert len(F) == n
        return np.zeros((len(F), 10, 2)), conv

    def styled(cls, seed=0, progress=False):
        return cp, ok, np.zeros(n, int), np.zeros(n)

    monkeypatch.setattr(D, 'fam_centerlines', centerlines)
    monkeypatch.setattr(D, 'styled_control_points', styled)
    ds = train.training_set(n_random, 'styles', seed=0, progress=False)
    np.testing.assert_array_equal(ds['keep'], ok & conv)
    assert np.isfinite(ds['X'][ds['keep']]).all()
    assert ds['n_refused'] == 2 and ds['n_not_converged'] == 3
    assert ds['val'].mean() == pytest.approx(train.VAL_FRAC, abs=0.02)


def _fake_training_set(calls):
    def make(n_random, features, seed, progress):
        calls.append((n_random, features, seed))
        n = train.N_ZERO + n_random
        return dict(X=np.full((n, 12), float(seed)), Y=np.zeros((n, 2)), keep=np.ones(n, bool),
                    val=np.zeros(n, bool), style=np.zeros(n, int), hidden=np.zeros(n),
                    n_requested=n, n_refused=seed, n_not_converged=0)
    return make


def test_the_data_cache_is_used_only_for_the_same_recipe(monkeypatch, tmp_path):
    calls, said = [], []
    monkeypatch.setattr(train, 'training_set', _fake_training_set(calls))
    # no cache named: generated every time, nothing written
    train.cached_training_set('', 5, 'exact', 1)
    train.cached_training_set('', 5, 'exact', 1)
    assert calls == [(5, 'exact', 1)] * 2 and not list(tmp_path.iterdir())
    cache = str(tmp_path / 'set.npz')
    first = train.cached_training_set(cache, 5, 'exact', 1, say=said.append)
    assert len(calls) == 3 and (tmp_path / 'set.npz').is_file()
    again = train.cached_training_set(cache, 5, 'exact', 1, say=said.append)
    assert len(calls) == 3 and said[-1] == f'training set from {cache}'
    assert set(again) == set(first)
    for k in first:
        np.testing.assert_array_equal(again[k], first[k])
    assert type(again['n_refused']) is int and again['n_refused'] == 1
    # another recipe (each step differs from the file's in one part of the key: the number,
    # the seed, the features): regenerated and the file overwritten
    for other in ((6, 'exact', 1), (6, 'exact', 2), (6, 'noise', 2)):
        ds = train.cached_training_set(cache, *other, say=said.append)
        assert calls[-1] == other and said[-1] == f'{cache} holds another recipe: regenerating'
        assert ds['n_refused'] == other[2]
    n = len(calls)
    train.cached_training_set(cache, 6, 'noise', 2)          # the last one written
    assert len(calls) == n
    # a .npz that is not a cache (no key): regenerated, not a crash
    np.savez(cache, X=np.zeros(3))
    train.cached_training_set(cache, 6, 'noise', 2)
    assert len(calls) == n + 1


def test_the_command_passes_its_options_to_the_build(monkeypatch):
    got = []
    monkeypatch.setattr(train, 'build_single_threaded',
                        lambda *a, **k: got.append((a, k)) or {})
    assert train.main(['--out', '/x', '--n-random', '40', '--features', 'noise', '--seed', '3',
                       '--quiet', '--data-cache', '/c.npz']) == 0
    assert got == [(('/x', 40, 'noise', 3),
                     dict(progress=False, verbose=False, data_cache='/c.npz'))]
    got.clear()
    assert train.main([]) == 0
    assert got == [((train.DEFAULT_OUT, 2400, 'auto', 0),
                     dict(progress=True, verbose=True, data_cache=''))]
    with pytest.raises(SystemExit):
        train.main(['--features', 'pixels'])

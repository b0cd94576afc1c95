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

"""force_estimator.dataset's contract beyond the features (module doc): the angle column is
atan2(fy, fx); a case and its mirror share one split; non-converged shapes are dropped and
counted; point_noise is in metres; load_dataset refuses a file that is not a data set."""
import numpy as np
import pytest

from force_estimator import dataset as D

pytest.importorskip('fam_solver')
pytest.importorskip('catheter_shape')


def test_angle_and_magnitude_columns():
    F = np.array([[0.0, 0.1], [-0.1, 0.0], [0.05, -0.05]])
    ds = D.make_dataset(F, test_frac=0.0, progress=False)
    np.testing.assert_allclose(ds['angle'], [np.pi / 2, np.pi, -np.pi / 4], atol=1e-12)
    np.testing.assert_allclose(ds['magnitude'], [0.1, 0.1, 0.05 * np.sqrt(2)], rtol=1e-12)


def test_a_case_and_its_mirror_share_their_split():
    F = D.random_forces(10, seed=2)
    ds = D.make_dataset(F, test_frac=0.3, progress=False, mirror=True)
    s = ds['split']
    assert len(s) == 20 and s[:10].sum() == 3                  # 30 % of the 10 cases
    np.testing.assert_array_equal(s[10:], s[:10])


def test_non_converged_shapes_are_dropped_and_counted(monkeypatch):
    F = np.array([[0.0, 0.05], [0.1, 0.1], [-0.05, 0.02]])
    real = D.fam_centerlines

    def one_fails(*args, **kw):
        cls, conv = real(*args, **kw)
        conv = conv.copy()
        conv[1] = False
        return cls, conv

    monkeypatch.setattr(D, 'fam_centerlines', one_fails)
    ds = D.make_dataset(F, test_frac=0.0, progress=False)
    assert ds['header']['n_not_converged'] == 1 and ds['header']['n'] == 2
    np.testing.assert_array_equal(ds['Y'], F[[0, 2]])
    assert ds['X'].shape == (2, 12)


def test_point_noise_is_in_metres():
    """1 mm of noise on each of 200 points moves the fitted curve by about
    1 mm * sqrt(8 parameters / 200 points) = 0.2 mm (RMS), not by micrometres."""
    from catheter_shape import bezier_eval
    cls, _ = D.fam_centerlines(np.array([[0.0, 0.1]]))
    exact = D.fit_control_points(cls)[0]
    noisy = D.fit_control_points(cls, point_noise=1e-3, seed=1)[0]
    t = np.linspace(0.0, 1.0, 200)
    d = bezier_eval(noisy[:, :2], t) - bezier_eval(exact[:, :2], t)
    rms = float(np.sqrt(np.mean(np.sum(d ** 2, axis=1))))
    assert 5e-5 < rms < 1e-3


def test_load_dataset_refuses_a_file_that_is_not_a_data_set(tmp_path):
    path = tmp_path / 'other.npz'
    np.savez(path, X=np.zeros((2, 12)), weights=np.ones(3))
    with pytest.raises(ValueError, match='not a data set'):
        D.load_dataset(path)

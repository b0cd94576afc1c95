"""Learning-from-simulation data sets: the thesis grid, random sets, FAM shapes fitted with
the camera path's Bezier code, the 70:30 split, mirroring, and the array file."""
import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from force_estimator import dataset as D

fam_solver = pytest.importorskip('fam_solver')
catheter_shape = pytest.importorskip('catheter_shape')


def test_thesis_grid():
    F = D.thesis_grid()
    assert F.shape == (400, 2)
    mag = np.hypot(F[:, 0], F[:, 1])
    ang = np.arctan2(F[:, 1], F[:, 0])
    np.testing.assert_allclose(np.unique(np.round(mag, 12)), 0.012 * np.arange(1, 26), rtol=1e-12)
    np.testing.assert_allclose(np.unique(np.round(ang, 12)), np.pi / 16 * np.arange(16), atol=1e-12)
    assert (F[:, 1] >= 0).all()
    with pytest.raises(ValueError, match='f_max'):
        D.thesis_grid(f_max=-1.0)


@settings(max_examples=30, deadline=None)
@given(st.integers(1, 200), st.floats(0.01, 2.0), st.integers(0, 10 ** 6))
def test_random_forces_in_range(n, f_max, seed):
    F = D.random_forces(n, f_max=f_max, seed=seed)
    assert F.shape == (n, 2)
    assert (np.hypot(F[:, 0], F[:, 1]) <= f_max * (1 + 1e-12)).all()
    assert (F[:, 1] >= -1e-15).all()
    np.testing.assert_array_equal(F[0], [0.0, 0.0])
    np.testing.assert_array_equal(F, D.random_forces(n, f_max=f_max, seed=seed))


def test_features_are_the_camera_fit_of_the_fam_centreline():
    from catheter_shape import fit_bezier
    from fam_solver import Catheter, Loads, solve_fam
    F = np.array([[0.0, 0.0], [0.0, 0.1], [-0.1, 0.05], [0.2, 0.2]])
    ds = D.make_dataset(F, test_frac=0.25, progress=False)
    assert ds['X'].shape == (4, 12) and ds['control_points'].shape == (4, 4, 3)
    np.testing.assert_array_equal(ds['X'], ds['control_points'].reshape(4, 12))
    np.testing.assert_array_equal(ds['Y'], F)
    np.testing.assert_allclose(ds['magnitude'], np.hypot(F[:, 0], F[:, 1]))
    assert (ds['split'] == 1).sum() == 1
    cat = Catheter(length=D.BLAZER_LENGTH, ei=D.BLAZER_EI)
    for f, cp in zip(F, ds['control_points'], strict=True):
        cl = solve_fam(cat, Loads(tip_force=tuple(f)), n_arcs=D.N_ARCS,
                       arc_model='exact', spacing='graded').centerline(D.N_CENTERLINE)
        ref = fit_bezier(np.c_[cl, np.zeros(len(cl))], degree=3)
        np.testing.assert_allclose(cp, ref, atol=1e-9)
    # unloaded: a straight catheter along +x, p0 at the clamp and p3 at x = L
    np.testing.assert_allclose(ds['control_points'][0][[0, 3]],
                               [[0, 0, 0], [D.BLAZER_LENGTH, 0, 0]],
                               atol=1e-9)
    # a positive fy bends the catheter towards +y
    assert ds['control_points'][1][3, 1] > 0.01


def test_mirror_and_file_roundtrip(tmp_path):
    F = np.array([[0.05, 0.1], [-0.1, 0.05], [0.0, 0.2]])
    ds = D.make_dataset(F, test_frac=0.0, progress=False, mirror=True, point_noise=1e-5)
    assert ds['X'].shape == (6, 12)
    np.testing.assert_allclose(ds['control_points'][3:, :, 1], -ds['control_points'][:3, :, 1])
    np.testing.assert_allclose(ds['Y'][3:], ds['Y'][:3] * [1, -1])
    path = D.save_dataset(tmp_path / 'ds.npz', ds)
    with np.load(path, allow_pickle=False) as d:
        assert json.loads(str(d['header'][()]))['mirror'] is True
    back = D.load_dataset(path)
    for k in ('X', 'Y', 'split', 'control_points', 'angle'):
        np.testing.assert_array_equal(back[k], ds[k])
    assert back['header']['n'] == 6 and back['header']['point_noise'] == 1e-5


def test_rendered_features_follow_the_shape():
    """Through the synthetic camera and ShapeSensor the Bezier curve still lies on the
    true centreline (control points themselves may slide along it)."""
    from catheter_shape import bezier_eval
    F = np.array([[0.0, 0.05], [-0.15, 0.1]])
    cls, conv = D.fam_centerlines(F)
    cp, ok = D.render_control_points(cls, seed=3)
    assert ok.all() and conv.all()
    for c, cl in zip(cp, cls, strict=True):
        curve = bezier_eval(c[:, :2], np.linspace(0, 1, 400))
        d = np.sqrt(((curve[:, None, :] - cl[None, :, :]) ** 2).sum(-1)).min(axis=1)
        assert d.max() < 1e-3 and d.mean() < 2.5e-4          # m


def test_bad_arguments():
    with pytest.raises(ValueError, match='forces'):
        D.fam_centerlines(np.array([[np.nan, 0.0]]))
    with pytest.raises(ValueError, match='centerlines'):
        D.fit_control_points(np.zeros((2, 3, 2)))
    with pytest.raises(ValueError, match='point_noise'):
        D.fit_control_points(np.zeros((1, 10, 2)) + np.linspace(0, 1, 10)[:, None], point_noise=-1)
    with pytest.raises(ValueError, match='test_frac'):
        D.make_dataset(np.zeros((2, 2)), test_frac=1.5)
    with pytest.raises(ValueError, match='n'):
        D.random_forces(0)


def test_tissue_hides_the_tip():
    F = np.array([[0.0, 0.05], [0.0, 0.05]])
    cls, _ = D.fam_centerlines(F)
    cp, ok = D.render_control_points(cls, seed=4, tissue_depth=np.array([0.0, 0.004]))
    assert ok.all()
    # the visible catheter is shorter: the tip control point moves back towards the base
    assert np.hypot(*cp[1, 3, :2]) < np.hypot(*cp[0, 3, :2]) - 0.002
    with pytest.raises(ValueError, match='tissue_depth'):
        D.render_control_points(cls, tissue_depth=-1.0)


def test_styled_features_follow_the_shape_in_every_tuning_style():
    """The shipped models' training path (features 'styles'): frame i is drawn in style
    i % len(styles), measured by ShapeSensor; the Bezier curve lies on the true centreline
    in every style, the same seed gives the same frames, a frame the sensor refuses is NaN."""
    from catheter_shape import bezier_eval
    from catheter_shape.styles import TUNING_STYLES
    F = np.array([[0.0, 0.05], [-0.15, 0.1], [0.1, 0.2], [0.0, 0.0], [0.2, -0.1]])
    cls, conv = D.fam_centerlines(F)
    assert conv.all()
    cp, ok, sty, hidden = D.styled_control_points(cls, seed=3)
    assert cp.shape == (5, 4, 3) and ok.shape == sty.shape == hidden.shape == (5,)
    assert sty.tolist() == [i % len(TUNING_STYLES) for i in range(5)]
    assert ok.all() and (hidden >= 0).all()
    assert hidden[sty == TUNING_STYLES.index('occluded')].max() > 0    # tip under tissue
    for c, cl in zip(cp, cls, strict=True):
        curve = bezier_eval(c[:, :2], np.linspace(0, 1, 400))
        d = np.sqrt(((curve[:, None, :] - cl[None, :, :]) ** 2).sum(-1)).min(axis=1)
        assert d.max() < 1.5e-3 and d.mean() < 4e-4                      # m
    again = D.styled_control_points(cls, seed=3)
    np.testing.assert_array_equal(again[0], cp)
    np.testing.assert_array_equal(again[3], hidden)
    only = D.styled_control_points(cls[:2], styles=('xray',), seed=3)
    assert only[2].tolist() == [0, 0]



def test_a_frame_the_sensor_refuses_is_nan_and_not_ok(monkeypatch):
    import catheter_shape
    orig = catheter_shape.ShapeSensor.process
    calls = []

    def every_second_refused(self, image):
        obs = orig(self, image)
        calls.append(1)
        if len(calls) % 2 == 0:
            obs.ok = False
        return obs

    monkeypatch.setattr(catheter_shape.ShapeSensor, 'process', every_second_refused)
    cls, _ = D.fam_centerlines(np.array([[0.0, 0.05], [0.1, 0.1], [-0.1, 0.2]]))
    cp, ok, _, _ = D.styled_control_points(cls, seed=1)
    assert ok.tolist() == [True, False, True] and len(calls) == 3
    assert np.isnan(cp[1]).all() and np.isfinite(cp[[0, 2]]).all()
    with pytest.raises(ValueError, match='centerlines'):
        D.styled_control_points(np.zeros((2, 10)))
    with pytest.raises(ValueError, match='centerlines'):
        D.styled_control_points(np.full((1, 10, 2), np.nan))

"""The shipped default models: load by name from package data (no pickle), carry their
recipe, and estimate forces of frames they never saw through the image pipeline."""
import json

import numpy as np
import pytest

from force_estimator import load_estimator
from force_estimator.models import SHIPPED_MODELS, shipped_model_path


@pytest.mark.parametrize('name', SHIPPED_MODELS)
def test_shipped_models_load_by_name(name):
    est = load_estimator(name)
    assert est.name == name and est.kind == name.split('-')[1]
    with np.load(shipped_model_path(name), allow_pickle=False) as d:
        header = json.loads(str(d['header'][()]))
    assert header['format'] == 'force_estimator.model'
    assert header['dataset']['catheter'] == {'length': 0.065, 'ei': 6.0e-5}
    assert header['targets'] == ['fx', 'fy'] and header['target_units'] == 'N'
    if est.kind == 'svr':
        assert header['hyper']['C'] == 100.0 and header['hyper']['kernel'] == 'rbf'
    else:
        assert header['chosen'] in header['candidates']
    far = np.array([[0, 0, 0], [0.02, 0.05, 0], [0.04, 0.2, 0], [0.065, 0.3, 0]])
    assert not est.predict(far, return_flags=True)[1]


def test_shipped_models_carry_a_camera_path_fingerprint():
    pytest.importorskip('fam_solver')
    pytest.importorskip('catheter_shape')
    from force_estimator.train import fingerprint_drift
    for name in SHIPPED_MODELS:
        fp = load_estimator(name).header['camera_path_fingerprint']
        assert np.array(fp['control_points']).shape == (3, 4, 3)
        assert np.isfinite(fingerprint_drift(load_estimator(name)))


def test_shipped_models_on_unseen_rendered_frames():
    pytest.importorskip('fam_solver')
    pytest.importorskip('catheter_shape')
    from force_estimator import dataset as D
    F = np.array([[0.0, 0.0], [0.0, 0.05], [-0.05, 0.15], [0.05, -0.1], [-0.1, 0.2]])
    cls, conv = D.fam_centerlines(F)
    cp, ok = D.render_control_points(cls, seed=99, camera_kwargs=dict(base_px=(265.0, 405.0)))
    assert ok.all()
    for name in SHIPPED_MODELS:
        est = load_estimator(name)
        P, inside = est.predict(cp, return_flags=True)
        err = np.hypot(*(P - F).T)
        assert err.max() < 0.04, (name, err)          # N; the benchmark measures accuracy
        assert err.mean() < 0.02, (name, err)
        assert inside.all()


@pytest.mark.parametrize('name', SHIPPED_MODELS)
def test_shipped_models_know_a_straight_catheter_is_ambiguous(name):
    """A straight catheter: any axial pull (or none) gives this shape. The learned model's
    estimate is flagged axial_unobservable (its nearest training inputs were pulls of every
    size, whatever its own output), and make_estimator hands it to the FAM inversion, whose
    weak force prior answers ~0 with the axial uncertainty."""
    pytest.importorskip('fam_solver')
    from force_estimator import make_estimator
    L = 0.065
    cp = np.array([[0, 0, 0], [L / 3, 0, 0], [2 * L / 3, 0, 0], [L, 0, 0]], dtype=float)
    e = load_estimator(name).estimate(cp)
    assert e.status == 'axial_unobservable' and e.normal and e.max_std > 0.03
    h = make_estimator(name.split('-')[1])
    e = h.estimate(cp)
    assert e.method == 'fam_fallback' and e.primary == name.split('-')[1]
    assert e.status == 'axial_unobservable' and np.hypot(*e.force) < 0.02
    assert abs(e.weak_direction[0]) > 0.9


@pytest.mark.parametrize('name', SHIPPED_MODELS)
def test_shipped_models_answer_lateral_forces_themselves(name):
    pytest.importorskip('fam_solver')
    from force_estimator import dataset as D
    from force_estimator import make_estimator
    F = np.array([[0.0, 0.1], [-0.1, 0.15], [0.05, -0.2]])
    cls, _ = D.fam_centerlines(F)
    cp, ok = D.render_control_points(cls, seed=3)
    h = make_estimator(name.split('-')[1])
    for c, f in zip(cp[ok], F[ok], strict=True):
        e = h.estimate(c)
        assert e.method == name.split('-')[1] and e.status == 'ok', (e.status, e.message)
        assert np.hypot(*(e.force - f)) < 0.01
        assert e.max_std < 0.02

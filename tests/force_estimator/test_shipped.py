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

"""The training command end to end on a small recipe (exact FAM features): it writes both
models, they load by path and predict held-out FAM shapes; the data-set command writes a
readable file."""
import numpy as np
import pytest

pytest.importorskip('fam_solver')
pytest.importorskip('catheter_shape')

from force_estimator import dataset as D  # noqa: E402
from force_estimator import load_estimator  # noqa: E402
from force_estimator.train import build_single_threaded  # noqa: E402

pytestmark = pytest.mark.slow


def test_build_small_recipe(tmp_path):
    rep = build_single_threaded(str(tmp_path), n_random=60, features='exact', progress=False,
                                verbose=False)
    assert rep['thesis_grid']['n_train'] == 280 and rep['thesis_grid']['n_test'] == 120
    # the thesis experiment (exact FAM features, 70:30) learns the grid well
    assert rep['thesis_grid']['svr_test_mae_n'] < 0.01
    svr = load_estimator(str(tmp_path / 'blazer-svr.npz'))
    mlp = load_estimator(str(tmp_path / 'blazer-mlp.npz'))
    assert svr.kind == 'svr' and mlp.kind == 'mlp'
    assert mlp.header['chosen'] in ('thesis-10', 'weighted-64x64-x4')
    F = np.array([[0.0, 0.07], [-0.05, 0.12], [0.03, -0.09]])
    ds = D.make_dataset(F, test_frac=0.0, progress=False)
    for est in (svr, mlp):
        err = np.hypot(*(est.predict(ds['control_points']) - F).T)
        assert err.max() < 0.03, (est.kind, err)


def test_dataset_command(tmp_path):
    out = tmp_path / 'set.npz'
    assert D.main([str(out), '--kind', 'random', '-n', '12', '--seed', '3']) == 0
    ds = D.load_dataset(out)
    assert ds['X'].shape == (12, 12) and ds['header']['n'] == 12
    assert set(np.unique(ds['split'])) <= {0, 1}

"""A failed estimate (force 0 for input the method cannot use) states what is known: the
force lies somewhere in the disc |f| <= f_max. Its covariance must be that of a force
uniform on the disc (per axis R^2 / 4), not a tighter one that a fusion or the operator's
display would trust."""
import numpy as np
import pytest

from force_estimator.estimate import failed_estimate


def _disc_variance_mc(R, n=400_000, seed=0):
    """Independent reference: per-axis variance of points uniform on the disc |f| <= R."""
    rng = np.random.default_rng(seed)
    r = R * np.sqrt(rng.random(n))
    a = 2 * np.pi * rng.random(n)
    return np.var(r * np.cos(a)), np.var(r * np.sin(a))


@pytest.mark.parametrize('f_max', [0.05, 0.45, 2.0])
def test_failed_estimate_covariance_is_the_force_disc(f_max):
    e = failed_estimate('non_finite_input', 'svr', 'nan in the input', f_max)
    assert np.all(e.force == 0) and not e.normal
    vx, vy = _disc_variance_mc(f_max)
    np.testing.assert_allclose(np.diag(e.covariance), [vx, vy], rtol=0.01)
    assert e.covariance[0, 1] == 0.0


@pytest.mark.parametrize('kind', ['svr', 'mlp'])
def test_estimators_report_the_disc_covariance_for_unusable_input(toy_models, kind):
    m = toy_models[2][kind]
    cp = np.zeros((4, 3))
    cp[2, 1] = np.inf
    e = m.estimate(cp)
    assert e.status == 'non_finite_input'
    # no smaller than the disc of every force the model may output
    assert np.all(np.sqrt(np.diag(e.covariance)) >= 0.5 * m.f_bound * (1 - 1e-12))

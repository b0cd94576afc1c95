"""force_estimator.domain.DomainCheck: distances (RMS per control point) by hand, the
neighbours of a small reference set, the calibrated threshold, the subset's forces and the
refusals of bad arguments."""
import numpy as np
import pytest

from force_estimator.domain import DOMAIN_MARGIN, DOMAIN_QUANTILE, DomainCheck


def _ref():
    """Three reference inputs (4 control points of 3 coordinates, m)."""
    R = np.zeros((3, 4, 3))
    R[1, :, 0] = 1.0              # every control point 1 m along x
    R[2, 3, 1] = 2.0              # the last control point 2 m along y
    return R.reshape(3, 12)


def test_distance_is_the_rms_over_control_points_of_the_nearest_reference():
    dc = DomainCheck(_ref(), threshold=0.5)
    x = np.zeros((4, 3))
    x[:, :2] = [0.3, 0.4]         # every control point 0.5 m from reference 0
    x = x.reshape(12)
    assert dc.nearest(x) == pytest.approx([0.5], rel=1e-12)
    assert dc.distance(x) == pytest.approx([1.0], rel=1e-12)
    d, idx = dc.neighbours(x, k=1)
    assert d == pytest.approx(0.5, rel=1e-12) and list(idx) == [0]
    # one control point 4 m away from reference 2's: RMS over the 4 points = 4 / 2 = 2 m
    # (reference 0: 6 / 2 = 3 m, reference 1: sqrt(3 + 37) / 2 = 3.2 m)
    y = _ref()[2].reshape(4, 3).copy()
    y[3, 1] += 4.0
    y = y.reshape(12)
    assert dc.nearest(y) == pytest.approx([2.0], rel=1e-12)
    assert dc.neighbours(y, k=1)[0] == pytest.approx(2.0, rel=1e-12)
    # batch: one row each, the reference inputs themselves at distance 0
    np.testing.assert_allclose(dc.nearest(np.stack([x, y, _ref()[1]])), [0.5, 2.0, 0.0],
                               atol=1e-7)


def test_neighbours_of_a_reference_set_smaller_than_k():
    dc = DomainCheck(_ref(), threshold=1.0)
    d, idx = dc.neighbours(np.zeros(12))          # k = NEIGHBOURS = 8 > 3 inputs
    assert d == 0.0 and sorted(idx) == [0, 1, 2]
    d, idx = dc.neighbours(_ref()[1], k=2)
    assert d == 0.0 and sorted(idx) == [0, 1]     # reference 1 itself and reference 0


def test_calibrated_threshold_is_the_margin_times_the_held_out_quantile():
    """Held-out inputs at known distances 0.001 .. 0.2 m (RMS per control point) from a
    single reference input: the threshold is DOMAIN_MARGIN times their DOMAIN_QUANTILE, so
    every held-out input (of the training distribution) is inside."""
    ref = np.zeros((1, 12))
    dist = np.arange(1, 201) * 1e-3
    held = np.zeros((200, 12))
    held[:, 0::3] = dist[:, None]              # every control point moved by dist along x
    dc = DomainCheck.calibrate(ref, held)
    assert dc.threshold == pytest.approx(DOMAIN_MARGIN * np.quantile(dist, DOMAIN_QUANTILE),
                                         rel=1e-9)
    assert np.all(dc.distance(held) <= 1.0)
    assert dc.distance(np.full(12, 1e3))[0] > 1e3          # a tip 1 km away: far outside


def test_calibrated_subset_keeps_each_input_with_its_force():
    """A random subset of at most max_reference training inputs: each kept input with the
    force it was trained on (targets[i] belongs to reference[i])."""
    rng = np.random.default_rng(3)
    X = rng.standard_normal((50, 12))
    Y = np.stack([X[:, 0] + 2 * X[:, 5], X[:, 11]], axis=1)
    dc = DomainCheck.calibrate(X, X[:5], max_reference=10, Y_train=Y, seed=1)
    R = dc.reference
    assert R.shape == (10, 12) and dc.targets.shape == (10, 2)
    np.testing.assert_array_equal(dc.targets, np.stack([R[:, 0] + 2 * R[:, 5], R[:, 11]], 1))
    assert len({tuple(r) for r in R}) == 10
    assert not np.array_equal(R, X[:10])                    # a random subset, not the first


@pytest.mark.parametrize('args,name', [
    ((np.zeros((3, 12)), 0.0), 'threshold'), ((np.zeros((3, 12)), -1.0), 'threshold'),
    ((np.zeros((3, 12)), np.nan), 'threshold'), ((np.zeros((3, 12)), np.inf), 'threshold'),
    ((np.zeros((3, 11)), 1.0), 'reference'), ((np.zeros((0, 12)), 1.0), 'reference'),
    ((np.full((3, 12), np.nan), 1.0), 'reference'),
    ((np.zeros((3, 12)), 1.0, np.zeros((2, 2))), 'targets'),
    ((np.zeros((3, 12)), 1.0, np.full((3, 2), np.inf)), 'targets'),
])
def test_bad_arguments_raise_value_error_naming_them(args, name):
    with pytest.raises(ValueError, match=name):
        DomainCheck(*args)


def test_from_model():
    dc = DomainCheck(_ref(), 0.25, targets=np.ones((3, 2)))
    arrays = dc.arrays()
    back = DomainCheck.from_model(arrays, dict(domain=dc.header()))
    assert back.threshold == 0.25 and back.targets.shape == (3, 2)
    np.testing.assert_array_equal(back.reference, _ref())
    assert DomainCheck.from_model({}, {}) is None
    with pytest.raises(ValueError, match='threshold'):
        DomainCheck.from_model(arrays, {})

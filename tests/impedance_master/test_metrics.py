"""impedance_master.metrics: the one definition of the force-feedback error (experiment and
ROS graph analysis), against exact answers."""
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from impedance_master.metrics import (default_eval_start, error_stats, outage_mask,
                                      tracking_metrics, twin_reference)
from sim_slave.vessel import VesselModel, VesselParams


def test_twin_reference_is_the_steady_sliding_force_at_constant_speed():
    # no cardiac term: after the bristles settle the force is the exact steady-sliding force
    p = VesselParams(cardiac_amplitude=0.0)
    t = np.arange(3000) * 1e-3
    v = 0.02
    x = 0.01 + v * t
    ref = twin_reference(t, x, np.full_like(t, v), 0.2, p, seed=3)
    exact = np.array([VesselModel(p).steady_force(xi, v) for xi in x])
    np.testing.assert_allclose(ref[500:], exact[500:], rtol=1e-6, atol=1e-9)


def test_twin_reference_uses_time_plus_delay_for_the_cardiac_term():
    p = VesselParams()
    t = np.arange(200) * 1e-3
    x = np.full_like(t, 0.05)
    a = twin_reference(t, x, np.zeros_like(t), 0.2, p, seed=5)
    b = twin_reference(t + 0.2, x, np.zeros_like(t), 0.0, p, seed=5)
    np.testing.assert_array_equal(a, b)
    assert np.ptp(a) > 1e-3           # the cardiac ripple is there


def test_outage_mask_and_eval_start():
    t = np.array([4.19, 4.2, 5.39, 5.4])
    np.testing.assert_array_equal(outage_mask(t, [(4.0, 1.0)], 0.2), [False, True, True, False])
    assert default_eval_start(0.2) == pytest.approx(1.9)


def test_tracking_metrics_recover_known_errors():
    t = np.arange(10000) * 1e-3
    ref = 0.3 * np.sin(t)
    sign = np.where(np.arange(t.size) % 2, 1.0, -1.0)
    out = outage_mask(t, [(4.0, 1.0)], 0.2)
    f = ref + sign * np.where(out, 0.05, 0.01)
    m = tracking_metrics(t, f, ref, [(4.0, 1.0)], 0.2)
    assert m['normal']['mae'] == pytest.approx(0.01)
    assert m['outage']['mae'] == pytest.approx(0.05) and m['outage']['n'] == 1200   # [4.2, 5.4)
    assert m['all']['n'] == t.size - 1900
    m0 = tracking_metrics(t, f, ref, [(4.0, 1.0)], 0.2, t_eval0=0.0)
    assert m0['all']['n'] == t.size


def test_bad_input_is_refused():
    with pytest.raises(ValueError, match='delay'):
        outage_mask([0.0], [(1.0, 1.0)], -0.1)
    with pytest.raises(ValueError, match='x'):
        twin_reference([0.0, 1e-3], [0.0], [0.0, 0.0], 0.2)
    with pytest.raises(ValueError, match='xd'):
        twin_reference([0.0, 1e-3], [0.0, 0.0], [0.0, np.nan], 0.2)
    with pytest.raises(ValueError, match='t must be non-decreasing'):
        twin_reference([1e-3, 0.0], [0.0, 0.0], [0.0, 0.0], 0.2)
    with pytest.raises(ValueError, match='outages'):
        outage_mask([0.0], [(1.0,)], 0.2)


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(-1, 1), min_size=1, max_size=60))
def test_error_stats_invariants(errs):
    s = error_stats(np.asarray(errs))
    assert s['mae'] <= s['rmse'] + 1e-12 <= s['max'] + 2e-12
    assert s['n'] == len(errs)


def test_error_stats_by_hand():
    # mutation sweep W03: RMSE and MAE differ as soon as the errors differ in size
    s = error_stats([3.0, -4.0])
    assert s == {'mae': 3.5, 'rmse': pytest.approx(12.5 ** 0.5), 'max': 4.0, 'n': 2}


def test_error_stats_leave_out_missing_references():
    # mutation sweep W04: a sample without a reference (NaN) is left out, not propagated
    s = error_stats([1.0, np.nan, -3.0, np.inf])
    assert s == {'mae': 2.0, 'rmse': pytest.approx(5.0 ** 0.5), 'max': 3.0, 'n': 2}
    empty = error_stats([np.nan])
    assert empty['n'] == 0 and np.isnan(empty['mae'])

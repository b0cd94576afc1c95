"""The closed-loop experiment runner (pure Python): the issue's claims checked on Experiment II
(200 ms delay, 1 s outages at 4 s and 8 s), same seeds for every mode."""
import math

import numpy as np
import pytest

from impedance_master.experiment import (ExperimentConfig, compare_modes, outage_mask,
                                         run_experiment)


@pytest.fixture(scope='module')
def exp2():
    return compare_modes(experiment='II', seed=0)


def test_default_ima_beats_dfr_in_normal_and_outage_intervals(exp2):
    ima, dfr = exp2['ima'].metrics, exp2['dfr'].metrics
    for part in ('normal', 'outage'):
        assert ima[part]['n'] > 500
        assert ima[part]['mae'] < dfr[part]['mae']
        assert ima[part]['max'] < dfr[part]['max']
    # DFR is stale during outages: its error rises there (the thesis's observation)
    assert dfr['outage']['mae'] > dfr['normal']['mae']


def test_same_seeds_give_the_same_motion_and_reference(exp2):
    a, b = exp2['ima'].series, exp2['dfr'].series
    assert np.array_equal(a['x_hand'], b['x_hand'])
    # rigid hand: the master follows the script whatever the rendered force
    assert np.array_equal(a['x_master'], b['x_master'])
    assert np.array_equal(a['reference'], b['reference'])
    assert 0.3 < exp2['ima'].metrics['max_reference'] < 0.45     # thesis: 0.387 N


def test_slave_holds_during_outages_and_reference_matches_slave_otherwise(exp2):
    s = exp2['ima'].series
    t = s['t']
    hold = (t > 4.3) & (t < 5.1)
    assert np.ptp(s['x_slave'][hold]) < 1e-6
    chk = exp2['ima'].metrics['reference_check']
    assert chk['mae'] < 0.02
    # sample by sample, away from the catch-ups after the outages (which the mean and the
    # largest difference are made of): the reference is the slave's own force a delay later
    # (median 0.2 mN measured; with the reference's time not delayed with the command, its
    # cardiac term 0.2 s off, 9.3 mN: mutation sweep W53)
    d = 200
    sel = (s['evaluated'] & ~s['outage'])[:-d]
    diff = (s['reference'][:-d] - s['f_slave_true'][d:])[sel]
    assert np.median(np.abs(diff)) < 0.002


def test_the_error_is_measured_at_the_operators_hand(exp2):
    """The metrics are the force at the hand's (device's output, not the renderer's
    command) against the reference (mutation sweep W54)."""
    from impedance_master.metrics import tracking_metrics
    for r in exp2.values():
        s = r.series
        m = tracking_metrics(s['t'], s['f_hand'], s['reference'], r.config.outages,
                             r.config.delay)
        for part in ('normal', 'outage', 'all'):
            assert r.metrics[part] == m[part]
        assert not np.array_equal(s['f_hand'], s['f_desired'])


def test_models_reach_the_master_at_the_impedance_rate():
    """impedance_rate 20 Hz: at most 20 models a second reach the renderer (mutation sweep
    W55: a model in every packet); the force still goes every period."""
    r = run_experiment(ExperimentConfig(mode='ima', seed=0, impedance_rate=20.0, duration=3.0))
    got = r.metrics['renderer']['switches'] + r.metrics['renderer']['pre_anchors']
    assert 0 < got <= 3.0 * 20 + 1
    assert r.metrics['link']['to_master']['sent'] == 3000


def test_outage_mask_covers_the_stale_feedback_span():
    t = np.arange(0, 12, 0.001)
    m = outage_mask(t, ((4.0, 1.0), (8.0, 1.0)), 0.2)
    assert m.sum() == pytest.approx(2 * 1200, abs=2)   # [start + d, start + len + 2 d)
    assert not m[(t < 4.2)].any() and m[(t >= 4.2) & (t < 5.4)].all()


def test_pretrained_default_ima_meets_the_targets():
    r = run_experiment(ExperimentConfig(experiment='II', mode='ima', pretrain='I', seed=0))
    for part in ('normal', 'outage'):
        assert r.metrics[part]['mae'] <= 0.02
        assert r.metrics[part]['max'] <= 0.05


@pytest.mark.parametrize('seed', [0, 1, 2])
def test_cold_default_ima_meets_the_mae_target(seed):
    """Experiment II from a cold start (no pretraining): MAE <= 0.02 N in normal and outage
    intervals. Before the static force was bounded at 0 and the mass at 50 g the outage MAE
    was 0.031 (seed 1) and 0.026 N (seed 2). The max error is not asserted at the target
    (0.05 N): the first reversal at the deepest point, where the wall contact was only seen
    in insertion, costs about the wall force (0.08 N) until the reversal's data arrive
    (README); it is bounded here against regressions."""
    r = run_experiment(ExperimentConfig(experiment='II', mode='ima', seed=seed))
    for part in ('normal', 'outage'):
        assert r.metrics[part]['mae'] <= 0.02
        assert r.metrics[part]['max'] <= 0.1


def test_first_model_extrapolates_friction_growing_with_length(monkeypatch):
    """With 1 s delay the first model arrives when the slave has seen only 8-26 mm and the
    master is at 52 mm. Friction, breakaway and drag vanish at zero inserted length (prior
    `origin_weight`): the friction's growth with length is anchored and the rendered
    force is not extrapolated flat. Measured: normal max 0.155 N with the prior, 0.233 N
    without it (seed 1, first round); with the third round's renderer 0.167 / 0.193 N;
    with the fourth round's (the measured slope also extends the rise beyond the data)
    0.156 / 0.175 N; eighteenth round 0.158 / 0.172 N (the prior's mechanism, tested below
    without the warm-up anchors). Since the nineteenth round the renderer also counts the
    identifier's warm-up anchors (`pre_anchors`): the measured slope over 8-26 mm extends
    the rise either way, 0.152 / 0.150 N, and the prior no longer decides this case."""
    import impedance_master.experiment as experiment
    from impedance_master.identification import HistoryIdentifier

    def max_error(pre_anchors):
        cfg = ExperimentConfig(experiment='II', mode='ima', seed=1, delay=1.0,
                               render_params={'pre_anchors': pre_anchors})
        return run_experiment(cfg).metrics['normal']['max']
    with_prior = {keep: max_error(keep) for keep in (False, True)}
    monkeypatch.setattr(experiment, 'make_identifier',
                        lambda window, rate: HistoryIdentifier(window=window, rate=rate,
                                                               origin_weight=0.0))
    without = {keep: max_error(keep) for keep in (False, True)}
    assert with_prior[False] < 0.165 < without[False]
    assert max(with_prior[True], without[True]) < 0.155


def test_compliant_hand_and_lossy_link_stay_finite_and_bounded():
    r = run_experiment(ExperimentConfig(experiment='II', mode='ima', compliant_hand=True,
                                        loss=0.3, jitter=0.01, duration=6.0, seed=2))
    f = r.series['f_hand']
    assert np.all(np.isfinite(f)) and np.abs(r.series['f_desired']).max() <= 2.0
    assert r.metrics['link']['to_master']['lost_random'] > 0
    assert math.isfinite(r.metrics['all']['mae']) and r.metrics['all']['mae'] < 0.1


def test_config_refuses_bad_values():
    with pytest.raises(ValueError, match='mode'):
        ExperimentConfig(mode='pid')
    with pytest.raises(ValueError, match='loss'):
        ExperimentConfig(loss=1.5)
    with pytest.raises(ValueError, match='pretrain'):
        ExperimentConfig(pretrain='III')


def test_runs_are_deterministic_for_a_seed():
    cfg = ExperimentConfig(experiment='II', mode='ima', duration=3.0, loss=0.1, jitter=0.005,
                           seed=4)
    a, b = run_experiment(cfg), run_experiment(cfg)
    for key in ('f_hand', 'reference', 'x_slave', 'f_slave_meas'):
        assert np.array_equal(a.series[key], b.series[key])
    c = run_experiment(cfg, seed=5)
    assert not np.array_equal(a.series['x_hand'], c.series['x_hand'])


def test_vessel_and_operator_are_selected_by_name():
    with pytest.raises(ValueError, match='vessel must be one of'):
        ExperimentConfig(vessel='aorta')
    with pytest.raises(ValueError, match='unknown vessel parameter'):
        ExperimentConfig(vessel='soft', vessel_params={'colour': 1.0})
    with pytest.raises(ValueError, match='operator must be one of'):
        ExperimentConfig(operator='robot')
    cfg = ExperimentConfig(vessel='soft', vessel_params={'noise_std': 0.0}, operator='human',
                           duration=3.0, outages=())
    assert cfg.vessel_params == (('noise_std', 0.0),)       # a dict is stored as pairs
    r = run_experiment(cfg)
    s = r.series
    # noise-free sensor: the slave's measured force is its true force; the reference in a
    # normal interval is the soft vessel's force (not the phantom's)
    assert np.array_equal(s['f_slave_meas'], s['f_slave_true'])
    assert r.metrics['reference_check']['mae'] < 0.01
    assert np.all(np.isfinite(s['f_hand']))
    human = run_experiment(ExperimentConfig(vessel='phantom', operator='human', duration=3.0,
                                            outages=()))
    assert not np.array_equal(human.series['reference'], s['reference'])


def test_the_generalisation_criterion_is_the_issues():
    from impedance_master.generalisation import CaseResult, beats_dfr, cases
    dfr = CaseResult(normal=0.1, outage=0.2, all=0.12, max=0.5)
    assert beats_dfr(CaseResult(0.09, 0.09, 0.09, 0.49), dfr)
    assert not beats_dfr(CaseResult(0.1, 0.09, 0.09, 0.49), dfr)       # normal not below
    assert not beats_dfr(CaseResult(0.09, 0.1, 0.09, 0.49), dfr)       # outage not < half
    assert not beats_dfr(CaseResult(0.09, 0.09, 0.09, 0.5), dfr)       # max not below
    held = cases([0, 1])
    assert ('phantom', 'minjerk', 0) not in held and ('phantom', 'sines', 1) in held
    assert len(cases([0], include_tuning=True)) == len(held) // 2 + 1

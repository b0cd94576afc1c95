"""The ORACLE renderers of the generalisation protocol (issue 12, ninth round;
`impedance_master.oracle`): the world's true vessel law at the master, an analysis tool.
References: the vessel's own `steady_force` (a separate code path from the stateful
`force`) for a stateless vessel, the metric's `twin_reference`, and exact identities on a
world without disturbances and noise."""
import math

import numpy as np
import pytest

from impedance_master.experiment import ExperimentConfig, run_experiment
from impedance_master.metrics import twin_reference
from impedance_master.oracle import ORACLES, OracleRenderer, law_spec, run_oracles
from sim_slave.vessels import vessel_spec


def _path(n=3000, dt=1e-3):
    """A motion with reversals and rests in 8-50 mm (t s, x m, x' m/s)."""
    t = np.arange(n) * dt
    x = 0.029 + 0.021 * np.sin(2 * np.pi * 0.7 * t) * np.cos(2 * np.pi * 0.23 * t)
    xd = np.gradient(x, dt)
    return t, x, xd


def test_law_spec_removes_the_disturbances_and_the_noise_only():
    spec = vessel_spec('stribeck_kv', cardiac_amplitude=0.012, noise_std=0.015)
    law = law_spec(spec)
    assert law.params.cardiac_amplitude == 0.0
    assert law.extras.breathing_amplitude == 0.0
    assert law.noise_std == 0.0
    assert spec.params.cardiac_amplitude == 0.012       # the world's spec is not changed
    assert law.params.wall_stiffness == spec.params.wall_stiffness
    assert law.extras.friction_quadratic == spec.extras.friction_quadratic
    with pytest.raises(ValueError, match='spec must be a sim_slave.vessels.VesselSpec'):
        law_spec('stribeck_kv')


def test_law_oracle_is_the_steady_force_of_a_stateless_vessel_with_its_cardiac_term_left_out():
    """smooth_coulomb is stateless: the law at (x, x') is `steady_force(x, x')` (no
    disturbance), whatever the time; the world's cardiac term (12 mN here) is not in it."""
    spec = vessel_spec('smooth_coulomb', cardiac_amplitude=0.012)
    ref = spec.build(0)
    o = OracleRenderer('law', spec, seed=3, delay=0.2, max_rate=math.inf)
    t, x, xd = _path()
    got = np.array([o.desired_force(tk, xk, vk) for tk, xk, vk in zip(t, x, xd, strict=True)])
    want = np.array([ref.steady_force(xk, vk) for xk, vk in zip(x, xd, strict=True)])
    assert np.max(np.abs(got - want)) < 1e-12
    assert np.max(np.abs(want)) > 0.1                    # a real force, not zeros


def test_disturbed_oracle_is_the_metric_reference():
    """'law_disturbed' is the reference of the metric: the same twin at t + delay."""
    spec = vessel_spec('stribeck_kv')
    t, x, xd = _path(2000)
    o = OracleRenderer('law_disturbed', spec, seed=5, delay=0.2, max_rate=math.inf)
    got = np.array([o.desired_force(tk, xk, vk) for tk, xk, vk in zip(t, x, xd, strict=True)])
    ref = twin_reference(t, x, xd, 0.2, spec, 5)
    assert np.max(np.abs(got - ref)) < 1e-12
    # on a stateless vessel the difference from the law is the cardiac term (12 mN, full
    # amplitude beyond 30 mm; the stick-slip of stribeck_kv's compliant shaft would move too)
    spec = vessel_spec('smooth_coulomb', cardiac_amplitude=0.012)
    ref = twin_reference(t, x, xd, 0.2, spec, 5)
    law = OracleRenderer('law', spec, seed=5, delay=0.2, max_rate=math.inf)
    lf = np.array([law.desired_force(tk, xk, vk) for tk, xk, vk in zip(t, x, xd, strict=True)])
    assert 0.011 < np.max(np.abs(ref - lf)) <= 0.012 + 1e-12


def test_oracle_output_is_slew_limited_and_clamped():
    spec = vessel_spec('stenosis')
    o = OracleRenderer('law', spec, seed=0, delay=0.2, limit=0.05, max_rate=10.0)
    t, x, xd = _path()
    f = np.array([o.desired_force(tk, xk, vk) for tk, xk, vk in zip(t, x, xd, strict=True)])
    assert np.max(np.abs(np.diff(f))) <= 0.01 + 1e-12
    assert np.max(np.abs(f)) <= 0.05
    assert np.max(f) == pytest.approx(0.05)              # the clamp did bind


def test_anchored_oracle_adds_the_received_miss():
    spec = vessel_spec('stiff_wall')
    a = OracleRenderer('law_anchored', spec, seed=0, delay=0.2, max_rate=math.inf)
    b = OracleRenderer('law', spec, seed=0, delay=0.2, max_rate=math.inf)
    assert a.desired_force(0.0, 0.03, 0.01) == b.desired_force(0.0, 0.03, 0.01)
    a.set_anchor(0.025)
    assert a.desired_force(0.001, 0.03, 0.01) - b.desired_force(0.001, 0.03, 0.01) == \
        pytest.approx(0.025, abs=1e-15)


def _quiet_world(**kw):
    """A world without disturbances and without sensor noise."""
    return ExperimentConfig(vessel='smooth_coulomb', operator='sines', seed=2, duration=6.0,
                            vessel_params=(('cardiac_amplitude', 0.0), ('noise_std', 0.0)),
                            **kw)


def test_every_oracle_is_exact_up_to_the_device_on_a_world_without_disturbances_and_noise():
    """Without disturbances and noise the law is the reference: every oracle's error is the
    haptic device's tracking of the rendered force (a few mN at most), and the anchored
    oracles carry a miss of exactly 0."""
    m = run_oracles(_quiet_world())
    dfr = run_experiment(_quiet_world(mode='dfr')).metrics
    assert set(m) == set(ORACLES)
    for k in ('law', 'law_anchored', 'law_anchored_lp', 'law_disturbed'):
        assert m[k]['all']['mae'] < 0.002, (k, m[k]['all'])
        assert m[k]['all']['max'] < 0.012, (k, m[k]['all'])
        assert m[k]['outage']['n'] > 500                 # the 4 s outage is in the 6 s
        assert m[k]['all']['mae'] < 0.1 * dfr['all']['mae']
    for k in ('law_anchored', 'law_anchored_lp', 'law_disturbed'):
        assert m[k] == m['law']
    # the law clipped to the depths seen misses where the master goes beyond them
    assert m['law_seen']['outage']['mae'] > m['law']['outage']['mae']


def test_seen_oracle_renders_the_law_flat_beyond_the_depths_received():
    spec = vessel_spec('smooth_coulomb')
    ref = spec.build(0)
    o = OracleRenderer('law_seen', spec, seed=0, delay=0.2, max_rate=math.inf)
    assert o.desired_force(0.0, 0.05, 0.01) == pytest.approx(ref.steady_force(0.05, 0.01))
    o.see(0.03)
    o.see(0.02)
    o.see(0.025)
    assert (o.seen_lo, o.seen_hi) == (0.02, 0.03)
    for t, x, xd, xc in ((0.001, 0.05, 0.01, 0.03), (0.002, 0.025, -0.02, 0.025),
                         (0.003, 0.01, -0.005, 0.02), (0.004, 0.031, 0.0, 0.03)):
        assert o.desired_force(t, x, xd) == pytest.approx(ref.steady_force(xc, xd), abs=1e-15)
    with pytest.raises(ValueError, match='x must be a finite number'):
        o.see(math.inf)


def test_anchored_oracle_carries_the_noise_and_the_lowpass_averages_it():
    """With 20 mN sensor noise and no disturbances the law alone is still exact; anchored to
    each received sample it renders that sample's noise (normal MAE near
    sqrt(2 / pi) 20 mN = 16 mN, the device smoothing a little); the low-passed miss
    averages the noise out."""
    cfg = ExperimentConfig(vessel='smooth_coulomb', operator='sines', seed=2, duration=6.0,
                           vessel_params=(('cardiac_amplitude', 0.0), ('noise_std', 0.02)))
    m = run_oracles(cfg)
    law, raw, lp = (m[k]['normal']['mae'] for k in ('law', 'law_anchored', 'law_anchored_lp'))
    assert law < 0.002
    assert 0.006 < raw < 0.018
    assert lp < 0.5 * raw


def test_run_oracles_refuses_bad_arguments():
    with pytest.raises(ValueError, match='kind must be one of'):
        OracleRenderer('perfect', vessel_spec('soft'), 0, 0.2)
    with pytest.raises(ValueError, match='spec must be'):
        OracleRenderer('law', 'soft', 0, 0.2)
    with pytest.raises(ValueError, match='delay'):
        OracleRenderer('law', vessel_spec('soft'), 0, -0.1)
    with pytest.raises(ValueError, match='miss must be a finite number'):
        OracleRenderer('law_anchored', vessel_spec('soft'), 0, 0.2).set_anchor(math.nan)
    with pytest.raises(ValueError, match='kinds must be among'):
        run_oracles(ExperimentConfig(), kinds=('law', 'magic'))
    with pytest.raises(ValueError, match='kinds must name at least one'):
        run_oracles(ExperimentConfig(), kinds=())
    with pytest.raises(ValueError, match='config must be an ExperimentConfig'):
        run_oracles({'vessel': 'soft'})


def test_anchored_oracle_carries_the_disturbance_two_delays_old():
    """With a 12 mN cardiac term and no sensor noise the law alone misses by the cardiac
    term (its MAE about 2 / pi of the amplitude, less where it is ramped in); the miss the
    anchored oracle receives is the disturbance 2 delays (0.4 s, half a beat) ago, so it
    adds rather than cancels: its error is larger."""
    cfg = ExperimentConfig(vessel='smooth_coulomb', operator='sines', seed=2, duration=6.0,
                           vessel_params=(('cardiac_amplitude', 0.012), ('noise_std', 0.0)))
    m = run_oracles(cfg, kinds=('law', 'law_anchored', 'law_disturbed'))
    law, anch, dist = (m[k]['normal']['mae'] for k in ('law', 'law_anchored',
                                                        'law_disturbed'))
    assert dist < 0.002
    assert 0.003 < law < 0.0085
    assert anch > law + 0.002

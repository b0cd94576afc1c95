"""The operator families (impedance_master.operator): by name, within the thesis's limits,
exact derivatives, deterministic, and different in kind (reversals, rest, tremor)."""
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from impedance_master.operator import (OPERATORS, V_MAX, X_MAX, HumanTrajectory,
                                       OperatorTrajectory, SinesTrajectory,
                                       experiment_trajectory, make_operator)


def reversals(v, thresh=1e-3):
    s = np.sign(v[np.abs(v) > thresh])
    return int(np.sum(s[1:] != s[:-1]))


@settings(max_examples=12, deadline=None)
@given(st.sampled_from(sorted(OPERATORS)), st.integers(0, 10_000))
def test_every_family_stays_in_the_thesis_limits_with_exact_derivatives(name, seed):
    tr = make_operator(name, duration=12.0, seed=seed)
    t, x, v, a = tr.arrays()
    assert np.all(np.isfinite(x)) and x.min() >= 0.0 and x.max() <= X_MAX + 1e-9
    assert np.abs(v).max() <= V_MAX * (1.0 + 1e-6)
    # derivatives against central differences (independent of the closed forms)
    dv = (x[2:] - x[:-2]) / (t[2:] - t[:-2])
    da = (v[2:] - v[:-2]) / (t[2:] - t[:-2])
    assert np.abs(dv - v[1:-1]).max() < 2e-4
    assert np.abs(da - a[1:-1]).max() < 0.05
    assert tr.sample(0.0)[1] == pytest.approx(0.0, abs=1e-12)      # starts at rest


def test_families_differ_in_kind():
    """minjerk pauses and reverses rarely; sines never rests and reverses at every depth;
    human trembles (many small reversals) and hesitates."""
    stats = {}
    for name in OPERATORS:
        rest, rev, deep = [], [], []
        for seed in range(4):
            t, x, v, a = make_operator(name, 12.0, seed).arrays()
            rest.append(np.mean(np.abs(v) < 1e-4))
            rev.append(reversals(v))
            deep.append(t[np.argmax(x)])
        stats[name] = (np.mean(rest), np.mean(rev), np.mean(deep))
    assert stats['minjerk'][0] > 0.05 and stats['sines'][0] < 0.2 * stats['minjerk'][0]
    assert stats['human'][1] > 3 * stats['minjerk'][1]
    assert stats['sines'][1] >= stats['minjerk'][1]
    # the human family does not insert to the deepest point first
    assert stats['human'][2] > stats['minjerk'][2]


def test_deterministic_for_a_seed_and_named():
    for name in OPERATORS:
        a, b = make_operator(name, 5.0, 3), make_operator(name, 5.0, 3)
        c = make_operator(name, 5.0, 4)
        assert a.sample(2.345) == b.sample(2.345) != c.sample(2.345)
    assert isinstance(make_operator('sines'), SinesTrajectory)
    assert isinstance(make_operator('human'), HumanTrajectory)
    assert isinstance(experiment_trajectory('II', 0), OperatorTrajectory)
    assert experiment_trajectory('I', 0).duration == 20.0
    e = experiment_trajectory('II', 1, operator='human')
    assert isinstance(e, HumanTrajectory) and e.duration == 12.0


def test_bad_names_and_parameters_are_refused():
    with pytest.raises(ValueError, match='operator must be one of'):
        make_operator('robot')
    with pytest.raises(ValueError, match="bad operator parameters for 'sines'"):
        make_operator('sines', pause_probability=0.1)
    with pytest.raises(ValueError, match='n_sines'):
        SinesTrajectory(n_sines=0)
    with pytest.raises(ValueError, match='tremor'):
        HumanTrajectory(tremor=0.01)
    with pytest.raises(ValueError, match='x_lo'):
        SinesTrajectory(x_lo=0.05, x_hi=0.04)
    with pytest.raises(ValueError, match='experiment'):
        experiment_trajectory('III')
    with pytest.raises(ValueError, match='t'):
        make_operator('human').sample(float('nan'))


def test_human_tremor_is_physiological():
    """Tremor at 8-12 Hz of tens of micrometres: the spectrum of x - (the motion without
    tremor) peaks there."""
    tr = HumanTrajectory(duration=8.0, seed=2)
    still = HumanTrajectory(duration=8.0, seed=2, tremor=0.0)
    t = np.arange(2000, 8000) / 1000.0
    d = np.array([tr.sample(ti)[0] - still.sample(ti)[0] for ti in t])
    assert 1e-5 < np.abs(d).max() <= 1e-4
    spec = np.abs(np.fft.rfft(d))
    f = np.fft.rfftfreq(d.size, 1e-3)
    assert 8.0 <= f[np.argmax(spec)] <= 12.0


@pytest.mark.parametrize('name', ['minjerk', 'human'])
def test_the_hand_comes_to_rest_where_the_script_ends_without_a_jump(name):
    """Sampled past `duration`, the last segment runs to its end and the hand stays there
    (mutation sweep W52: it jumped back to that segment's start when the segment ended)."""
    traj = make_operator(name, duration=6.0, seed=3, **({'tremor': 0.0} if name == 'human'
                                                         else {}))
    t = np.arange(5000, 20000) * 1e-3
    x = np.array([traj.sample(ti)[0] for ti in t])
    assert np.max(np.abs(np.diff(x))) <= V_MAX * 1e-3 * 1.01
    assert x[-1] == x[-2000] and traj.sample(t[-1])[1] == 0.0

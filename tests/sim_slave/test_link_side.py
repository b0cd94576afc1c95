"""sim_slave.link_side: the run clock both link-holding nodes share (run time since the first
tick; a clock jump back restarts the run; events between ticks are timed on the same run) and
the link's diagnostics."""
import pytest
from hypothesis import given, strategies as st

from catheter_common.diagnostics import WARN
from sim_slave.link import Link, LinkConfig
from sim_slave.link_side import (LINK_COUNTERS, RunClock, apply_link_changes, link_config,
                                 link_to_diag)


def test_run_time_counts_from_the_first_tick_and_restarts_when_the_clock_jumps_back():
    c = RunClock()
    assert c.at(5.0) is None                           # before the first tick
    assert c.tick(100.0) == (0.0, False) and c.t0 == 100.0
    assert c.tick(100.5) == (0.5, False)
    assert c.at(100.7) == 100.7 - 100.0
    assert c.at(100.2) is None                         # behind the latest tick: a jump back
    assert c.tick(100.2) == (0.0, True) and c.t0 == 100.2 and c.t_last == 0.0
    assert c.tick(100.3)[1] is False and c.at(100.4) == 100.4 - 100.2


@given(st.lists(st.floats(0.0, 1e6), min_size=1, max_size=30))
def test_run_time_is_never_negative_and_restarts_only_on_a_jump_back(times):
    c = RunClock()
    before = None                          # (t0, run time) after the previous tick
    for now in times:
        t, restarted = c.tick(now)
        assert t >= 0.0 and c.t_last == t
        assert restarted == (before is not None and now - before[0] < before[1])
        if restarted:
            assert t == 0.0 and c.t0 == now
        before = (c.t0, t)


class _Diag:
    def __init__(self):
        self.values, self.conditions = {}, {}

    def set(self, key, value):
        self.values[key] = value

    def condition(self, name, level, message=''):
        self.conditions[name] = (level, message)


def test_link_diagnostics_name_each_counter_and_warn_during_an_outage():
    cfg = LinkConfig.from_flat(0.1, 0.0, 0.0, [1.0, 0.5])
    a, b = Link(cfg, seed=1), Link(cfg, seed=2)
    a.send(0.0, 'x')
    a.send(1.2, 'y')                                   # lost in the outage
    d = _Diag()
    link_to_diag(d, [('link_a', a), ('link_b', b)], 1.2, 'nothing arrives')
    assert [k for k in d.values if k.startswith('link_a_')] == \
        [f'link_a_{c}' for c in LINK_COUNTERS]
    assert d.values['link_a_sent'] == 2 and d.values['link_a_lost_outage'] == 1
    assert d.values['link_b_sent'] == 0
    assert d.values['link_in_outage'] == 'True'
    assert d.conditions['link_outage'] == (WARN, 'link outage: nothing arrives')
    d = _Diag()
    link_to_diag(d, [('link', a)], None, 'x', counters=('dropped_stale',))
    assert set(d.values) == {'link_dropped_stale', 'link_in_outage'}
    assert d.conditions['link_outage'][0] == 0 and d.values['link_in_outage'] == 'False'


def test_link_parameter_changes_reach_every_link_or_none():
    values = {'link.delay': 0.3, 'link.jitter': 0.01, 'link.loss': 0.5, 'link.outages': [2.0, 1.0]}
    cfg = link_config(values)
    assert (cfg.delay, cfg.jitter, cfg.loss, cfg.outages) == (0.3, 0.01, 0.5, ((2.0, 1.0),))
    a, b = Link(), Link()
    assert apply_link_changes(['rate', 'linked'], values, a, b) is None
    assert a.config.delay == b.config.delay == 0.2
    assert apply_link_changes(['rate', 'link.loss'], values, a, b) == cfg
    assert a.config == b.config == cfg
    bad = dict(values, **{'link.outages': [1.0]})                # odd length: refused whole
    with pytest.raises(ValueError):
        apply_link_changes(['link.outages'], bad, a, b)
    assert a.config == b.config == cfg

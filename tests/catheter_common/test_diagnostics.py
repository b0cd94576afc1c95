"""catheter_common.diagnostics: levels rise with their conditions and fall when the conditions
clear (held conditions when the node clears them, events after their hold time on the node
clock), bad inputs are counted and logged rate-limited, and what is published says it."""
import pytest
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticStatus
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock

from catheter_bringup.rclpy_adapter import detach_clock, set_time
from catheter_common.diagnostics import ERROR, OK, WARN, Diagnostics

pytestmark = pytest.mark.ros


class SimClockNode:
    def __init__(self, ros, name='diag_test'):
        import rclpy
        self.node = ros.add(rclpy.create_node(name, context=ros.context, parameter_overrides=[
            Parameter('use_sim_time', value=True)]))
        self.ts = detach_clock(self.node)
        self.at(1.0)

    def at(self, t: float):
        ns = int(round(t * 1e9))
        set_time(self.ts, Clock(clock=Time(sec=ns // 10 ** 9, nanosec=ns % 10 ** 9)))


def test_held_conditions_rise_and_clear(ros):
    c = SimClockNode(ros)
    d = Diagnostics(c.node)
    assert d.level() == (OK, 'ok')
    d.condition('link_outage', WARN, 'link outage')
    assert d.level() == (WARN, 'link outage')
    d.condition('stuck', ERROR, 'stuck for 10 s')
    lvl, msg = d.level()
    assert lvl == ERROR and msg.index('stuck') < msg.index('link outage')   # worst first
    c.at(100.0)                                         # held: time does not clear them
    assert d.level()[0] == ERROR
    d.condition('stuck', OK)
    assert d.level() == (WARN, 'link outage')
    d.condition('link_outage', OK)
    assert d.level() == (OK, 'ok')


def test_events_clear_after_their_hold_on_the_node_clock(ros):
    c = SimClockNode(ros, 'diag_events')
    d = Diagnostics(c.node)
    d.event('clamped', WARN, 'clamped', hold=0.5)
    c.at(1.4)
    assert d.level()[0] == WARN
    d.event('clamped', WARN, 'clamped again', hold=0.5)    # refreshed
    c.at(1.8)
    assert d.level() == (WARN, 'clamped again')
    c.at(1.95)
    assert d.level() == (OK, 'ok')
    d.event('x', ERROR, 'boom', hold=1.0)
    c.at(0.5)                                               # the clock jumped back: cleared
    assert d.level()[0] == OK


def test_bad_input_counts_logs_rate_limited_and_warns(ros):
    c = SimClockNode(ros, 'diag_bad')
    d = Diagnostics(c.node, log_period=60.0)
    from catheter_common.ros_testing import CapturedLog
    logged = CapturedLog(d._node)
    for k in range(5):
        d.bad_input('command', f'position[0] must be finite, got nan ({k})')
    assert d.get('bad_messages') == 5 and d.get('bad_command') == 5
    assert len(logged) == 1 and 'bad command' in logged.texts('warning')[0]
    assert d.level()[0] == WARN
    c.at(3.5)
    assert d.level()[0] == OK


def test_published_status_has_level_message_counters_and_conditions(ros):
    c = SimClockNode(ros, 'diag_pub')
    d = Diagnostics(c.node)
    d.count('frames', 3)
    d.set('mode', 'ima')
    polled = {'n': 0}

    def updater():
        polled['n'] += 1
        d.condition('no_model', WARN, 'no valid model yet')
    d.add_updater(updater)
    st = d.status()
    assert polled['n'] >= 1
    assert st.level == DiagnosticStatus.WARN and st.message == 'no valid model yet'
    kv = {x.key: x.value for x in st.values}
    assert kv['frames'] == '3' and kv['mode'] == 'ima'
    assert kv['condition.no_model'] == 'WARN: no valid model yet'
    d._updaters.clear()
    d.condition('no_model', OK)
    st = d.status()
    assert st.level == DiagnosticStatus.OK and st.message == 'ok'
    assert not any(x.key.startswith('condition.') for x in st.values)


def test_log_limited_logs_warnings_and_errors_of_one_kind(ros):
    """rclpy refuses two severities from one line of code ('Logger severity cannot be changed
    between calls'): found by the node fuzz."""
    c = SimClockNode(ros, 'diag_sev')
    d = Diagnostics(c.node, log_period=0.0)
    d.log_limited('k', 'a warning', WARN)
    d.log_limited('k', 'an error', ERROR)
    d.log_limited('k', 'a warning again', WARN)


def test_an_event_clears_exactly_hold_seconds_after_it_was_raised(ros):
    """Active for hold s of node clock, [t, t + hold): one ns before the end still active, at
    the end cleared (mutant K08 kept it at t + hold and survived)."""
    c = SimClockNode(ros, 'diag_hold')
    d = Diagnostics(c.node, period=1000.0)
    d.event('clamped', WARN, 'clamped', hold=0.5)          # at 1.0 s
    c.at(1.5 - 1e-9)
    assert d.level()[0] == WARN
    c.at(1.5)
    assert d.level() == (OK, 'ok')


def test_a_lower_event_does_not_replace_a_held_condition_of_the_same_name(ros):
    """A held ERROR stays (held, not timed) when an event of a lower level with its name
    comes (mutant K09 let the WARN replace it, which then cleared by itself)."""
    c = SimClockNode(ros, 'diag_keep')
    d = Diagnostics(c.node, period=1000.0)
    d.condition('link', ERROR, 'link down')
    d.event('link', WARN, 'one late packet', hold=0.5)
    assert d.level() == (ERROR, 'link down')
    c.at(5.0)
    assert d.level() == (ERROR, 'link down')
    d.event('link', ERROR, 'still down', hold=0.5)         # an event of the same level
    assert d.level() == (ERROR, 'still down')              # replaces it (and times out)
    c.at(6.0)
    assert d.level() == (OK, 'ok')


def test_published_rates_are_the_increase_over_the_period(ros):
    """<counter>_rate_hz: the counter's increase since the last status over the node-clock
    time since then (mutant K11 published the total over dt and survived)."""
    c = SimClockNode(ros, 'diag_rate')
    d = Diagnostics(c.node, period=1000.0)                 # built at 1.0 s
    d.count('frames', 3)
    c.at(3.0)
    kv = {x.key: x.value for x in d.status().values}
    assert kv['frames'] == '3' and kv['frames_rate_hz'] == '1.50'     # 3 in 2 s
    d.count('frames', 2)
    c.at(3.5)
    kv = {x.key: x.value for x in d.status().values}
    assert kv['frames'] == '5' and kv['frames_rate_hz'] == '4.00'     # 2 more in 0.5 s

"""Process-level real-time settings and the figures a real-time run reports
(catheter_bringup.realtime), and the bus's immediate delivery used by the worker processes:
hand-checked values, invariants (hypothesis), bad input refused by name."""
import gc
import os

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from catheter_bringup import realtime as R


def test_stream_stats_hand_checked():
    s = R.stream_stats([0.0, 0.001, 0.002, 0.004], skip_fraction=0.0)
    assert s['n'] == 4
    assert s['rate_hz'] == pytest.approx(3 / 0.004)
    assert s['p50_ms'] == pytest.approx(1.0)
    assert s['p99_ms'] == pytest.approx(1.98)       # linear between the periods 1 and 2 ms
    assert s['max_ms'] == pytest.approx(2.0)
    # the start-up tenth is left out
    t = np.r_[0.0, 0.5, np.arange(1.0, 1.0 + 18 * 0.001, 0.001)]
    assert R.stream_stats(t)['max_ms'] == pytest.approx(1.0)
    assert np.isnan(R.stream_stats([1.0, 2.0], 0.0)['rate_hz'])


def test_stream_stats_refuses_bad_input():
    with pytest.raises(ValueError, match='skip_fraction'):
        R.stream_stats([0.0, 1.0, 2.0], skip_fraction=1.0)
    with pytest.raises(ValueError, match='times_s'):
        R.stream_stats([0.0, float('nan'), 2.0])
    with pytest.raises(ValueError, match='times_s'):
        R.stream_stats([0.0, 2.0, 1.0, 3.0], 0.0)


def test_latency_stats_hand_checked():
    s = R.latency_stats([5.0, 5.0, 0.010, 0.020, 0.030])   # the first two (start-up) left out
    assert s['n'] == 3 and s['p50_ms'] == pytest.approx(20.0)
    assert s['max_ms'] == pytest.approx(30.0)
    assert R.latency_stats([1.0])['n'] == 0
    with pytest.raises(ValueError, match='lat_s'):
        R.latency_stats([0.0, 0.0, float('inf')])


def test_link_loss_counts_inside_the_common_window():
    sent = list(range(0, 100))
    taken = [s for s in sent if s >= 10 and s not in (40, 41, 77)]   # started late, lost 3
    # stamps in ns: the run 40-41 starts 30 ns after the window's start (10)
    assert R.link_loss(sent, taken) == {'sent': 90, 'taken': 87, 'lost': 3,
                                        'longest_run': 2, 'run_at_s': pytest.approx(30e-9)}
    # a burst (a stalled or stopping receiver that takes one late sample) is one long run
    burst = R.link_loss(sent, [s for s in sent if not 90 <= s <= 98])
    assert (burst['lost'], burst['longest_run']) == (9, 9)
    assert burst['run_at_s'] == pytest.approx(90e-9)
    # the receiver stopped early: what it never waited for is not lost
    assert R.link_loss(sent, sent[:50])['lost'] == 0
    assert R.link_loss(sent, [])['lost'] == 100
    with pytest.raises(ValueError, match='sent_ns'):
        R.link_loss([[1, 2]], [1])


@given(st.lists(st.integers(0, 10**6), min_size=1, max_size=200, unique=True),
       st.sets(st.integers(0, 199)))
def test_link_loss_invariants(sent, drop):
    sent = sorted(sent)
    taken = [s for k, s in enumerate(sent) if k not in drop]
    r = R.link_loss(sent, taken)
    assert 0 <= r['lost'] <= len(drop)
    assert r['taken'] + r['lost'] == r['sent'] <= len(sent)
    # the longest run of lost stamps: no longer than the losses, and there when any is
    assert (r['longest_run'] > 0) == (r['lost'] > 0)
    assert r['longest_run'] <= r['lost']
    assert r['run_at_s'] >= 0.0
    # duplicates delivered twice do not hide a loss
    assert R.link_loss(sent, taken + taken) == r


def test_counts_since_subtracts_the_totals_at_the_start():
    before = {'/a': 3, '/b': 1}
    now = {'/a': 10, '/b': 1, '/c': 4, '/other': 9}
    assert R.counts_since(before, now, {'/a', '/b', '/c'}) == {'/a': 7, '/b': 0, '/c': 4}
    assert R.counts_since({}, {}, {'/a'}) == {}


def test_bus_sums_what_dds_reported_lost_over_a_topics_subscriptions():
    """Each subscription's handler reports its running total; the topic's figure is the sum
    of the latest totals (a second report of one subscription replaces its first)."""
    from catheter_bringup.bus import LocalBus
    bus = LocalBus()
    bus.note_dds_lost(1, '/slave/force', 3)
    bus.note_dds_lost(2, '/slave/force', 4)
    bus.note_dds_lost(1, '/slave/force', 5)
    bus.note_dds_lost(3, '/slave/impedance', 2)
    assert bus.dds_lost == {'/slave/force': 9, '/slave/impedance': 2}


def test_fifo_priority_falls_back_with_one_log_line(monkeypatch):
    def refuse(*_a):
        raise PermissionError(1, 'Operation not permitted')
    monkeypatch.setattr(os, 'sched_setscheduler', refuse)
    logs = []
    assert R.set_fifo_priority(10, logs.append) is None
    assert len(logs) == 1 and 'not permitted' in logs[0] and 'normal scheduling' in logs[0]
    with pytest.raises(ValueError, match='priority'):
        R.set_fifo_priority(0)
    with pytest.raises(ValueError, match='priority'):
        R.set_fifo_priority(True)


def test_fifo_priority_applies_to_every_thread_and_is_undone():
    """Where permitted (root here): every thread of the process under SCHED_FIFO, and back."""
    if os.geteuid() != 0:
        pytest.skip('SCHED_FIFO needs root or CAP_SYS_NICE; the fallback is tested above')
    import threading
    import time
    stop = threading.Event()
    th = threading.Thread(target=stop.wait)
    th.start()
    try:
        assert R.set_fifo_priority(3, print) == 'SCHED_FIFO 3'
        assert os.sched_getscheduler(0) == os.SCHED_FIFO
        assert os.sched_getscheduler(th.native_id) == os.SCHED_FIFO
        R.reset_priority()
        assert os.sched_getscheduler(0) == os.SCHED_OTHER
        assert os.sched_getscheduler(th.native_id) == os.SCHED_OTHER
    finally:
        R.reset_priority()
        stop.set()
        th.join()
        time.sleep(0)


def test_quiet_gc_freezes_raises_the_threshold_and_undoes():
    old = gc.get_threshold()
    undo = R.quiet_gc(12345)
    try:
        assert gc.get_freeze_count() > 0
        assert gc.get_threshold() == (12345,) + old[1:]
    finally:
        undo()
    assert gc.get_threshold() == old and gc.get_freeze_count() == 0


def test_gc_watch_times_a_collection():
    w = R.GcWatch().start()
    gc.collect()
    w.stop()
    s = w.summary()
    assert s['gen2_count'] >= 1 and s['total_ms'] > 0 and s['max_ms'] <= s['total_ms']
    gc.collect()
    assert w.summary() == s                      # stopped: nothing more counted


@pytest.mark.ros
def test_immediate_bus_delivers_inside_publish_in_order(ros):
    """Worker processes: a publish reaches this process's subscribers before publish()
    returns (no executor turn), a publish made during delivery is delivered after the current
    message, what DDS still delivers to a taken subscription arrives raw (not deserialised),
    and a subscription nobody in the process publishes to is left to DDS and counted."""
    from std_msgs.msg import String
    from catheter_bringup.bus import LocalBus
    from catheter_common.qos import QOS_DEFAULT
    a, b, c = ros.node('imm_a'), ros.node('imm_b'), ros.node('imm_c')
    pub_t = a.create_publisher(String, 'imm/t', QOS_DEFAULT)
    pub_u = b.create_publisher(String, 'imm/u', QOS_DEFAULT)
    order = []

    def on_t(msg):
        order.append('t:' + msg.data)
        pub_u.publish(String(data=msg.data + '!'))
        order.append('t-done')
    sub_t = b.create_subscription(String, 'imm/t', on_t, QOS_DEFAULT)
    seen_u = []
    c.create_subscription(String, 'imm/u', lambda m: (order.append('u:' + m.data),
                                                      seen_u.append(m)), QOS_DEFAULT)
    a.create_subscription(String, 'imm/u', seen_u.append, QOS_DEFAULT)
    ext = c.create_subscription(String, 'imm/ext', lambda m: order.append(('ext', m)),
                                QOS_DEFAULT)
    bus = LocalBus(immediate=True)
    for n in (a, b, c):
        bus.wrap_publishers(n)
    for n in (a, b, c):
        bus.wrap_subscriptions(n)
    # ext: taken raw from DDS and decoded by the bus (`cdr_decode`)
    assert sub_t.raw is True and ext.raw is True
    pub_t.publish(String(data='x'))
    assert order == ['t:x', 't-done', 'u:x!']
    # one deserialised message for both subscribers of /imm/u (share), a copy each without
    assert len(seen_u) == 2 and seen_u[0] is seen_u[1] and seen_u[0].data == 'x!'
    bus.share = False
    pub_u.publish(String(data='z'))
    assert len(seen_u) == 4 and seen_u[2] is not seen_u[3] and seen_u[2] == seen_u[3]
    assert bus.counts['/imm/t'] == 1 and bus.counts['/imm/u'] == 2
    other = ros.node('imm_other').create_publisher(String, 'imm/ext', QOS_DEFAULT)
    assert ros.spin_until(lambda: other.get_subscription_count() > 0, 10.0)
    other.publish(String(data='y'))
    assert ros.spin_until(lambda: bus.received.get('/imm/ext') == 1, 10.0)
    assert order[-1][0] == 'ext' and order[-1][1] == String(data='y')


@pytest.mark.ros
def test_immediate_bus_decodes_what_it_takes_from_dds(ros):
    """Worker processes: a subscription of a topic another process publishes is taken raw and
    decoded by the type's generated decoder: the callback (message only, or with message
    info) gets what rclpy's take would have built, field for field and in each value's
    type; a type without a decoder, or with `decode_dds` off, is taken by rclpy as before."""
    from geometry_msgs.msg import WrenchStamped
    from sensor_msgs.msg import JointState
    from catheter_interfaces.msg import TipForceEstimate
    from catheter_bringup.bus import LocalBus
    from catheter_common.qos import QOS_DEFAULT
    from test_message_copy import _typed
    n = ros.node('dec_sub')
    got = []
    subs = [n.create_subscription(WrenchStamped, 'dec/w', lambda m: got.append(('w', m)),
                                  QOS_DEFAULT),
            n.create_subscription(JointState, 'dec/j', lambda m, info: got.append(('j', m)),
                                  QOS_DEFAULT),
            n.create_subscription(TipForceEstimate, 'dec/t', lambda m: got.append(('t', m)),
                                  QOS_DEFAULT)]
    bus = LocalBus(immediate=True)
    bus.wrap_subscriptions(n)
    assert [s.raw for s in subs] == [True, True, False]
    other = ros.node('dec_pub')
    pw = other.create_publisher(WrenchStamped, 'dec/w', QOS_DEFAULT)
    pj = other.create_publisher(JointState, 'dec/j', QOS_DEFAULT)
    pt = other.create_publisher(TipForceEstimate, 'dec/t', QOS_DEFAULT)
    assert ros.spin_until(lambda: min(p.get_subscription_count() for p in (pw, pj, pt)) > 0,
                          10.0)
    w = WrenchStamped()
    w.header.frame_id, w.header.stamp.sec, w.wrench.torque.z = 'base', 7, -2.5
    j = JointState(name=['a', 'bb'], position=[1.0, 2.0], velocity=[], effort=[0.5])
    t = TipForceEstimate()
    t.force.x = 0.25
    pw.publish(w)
    pj.publish(j)
    pt.publish(t)
    assert ros.spin_until(lambda: len(got) == 3, 10.0)
    by = dict(got)
    assert _typed(by['w']) == _typed(w) and _typed(by['j']) == _typed(j)
    assert by['t'] == t
    assert bus.received == {'/dec/w': 1, '/dec/j': 1, '/dec/t': 1}
    off = LocalBus(immediate=True)
    off.decode_dds = False
    m = ros.node('dec_off')
    s_off = m.create_subscription(WrenchStamped, 'dec/w', lambda msg: None, QOS_DEFAULT)
    off.wrap_subscriptions(m)
    assert s_off.raw is False


@pytest.mark.ros
def test_immediate_bus_delivers_a_callbacks_publishes_when_it_returns(ros):
    """Worker processes: a timer (or a DDS delivery) run through `LocalBus.timed` publishes
    back to back; its subscribers run after it returns, in publish order (as lockstep
    delivers after a timer), before `timed` returns; its cost is its own work only. A
    publish made during that delivery is delivered by the same loop; an exception in the
    callback still delivers what it published and propagates."""
    import time
    from std_msgs.msg import String
    from catheter_bringup.bus import LocalBus
    from catheter_common.qos import QOS_DEFAULT
    a, b = ros.node('hold_a'), ros.node('hold_b')
    pub_s, pub_f = (a.create_publisher(String, f'hold/{t}', QOS_DEFAULT) for t in 'sf')
    pub_u = b.create_publisher(String, 'hold/u', QOS_DEFAULT)
    order = []

    def on_s(msg):
        time.sleep(0.002)                    # the subscriber's work (the identifier)
        order.append('s:' + msg.data)
        pub_u.publish(String(data='u'))
    b.create_subscription(String, 'hold/s', on_s, QOS_DEFAULT)
    b.create_subscription(String, 'hold/f', lambda m: order.append('f:' + m.data), QOS_DEFAULT)
    a.create_subscription(String, 'hold/u', lambda m: order.append('u'), QOS_DEFAULT)
    bus = LocalBus(immediate=True)
    for n in (a, b):
        bus.wrap_publishers(n)
    for n in (a, b):
        bus.wrap_subscriptions(n)
    sent = []

    def tick():
        pub_s.publish(String(data='1'))
        sent.append(time.perf_counter())
        order.append('tick: state sent')
        pub_f.publish(String(data='2'))
        sent.append(time.perf_counter())
        order.append('tick: force sent')
        return 'ret'
    assert bus.timed('hold_a', tick) == 'ret'
    assert order == ['tick: state sent', 'tick: force sent', 's:1', 'f:2', 'u']
    assert sent[1] - sent[0] < 0.002         # the force went out before the state's work
    assert bus.cost.samples['hold_a'][0] < 0.002 and bus.cost.samples['hold_b'][0] >= 0.002
    assert not bus.queue and bus.counts['/hold/u'] == 1
    # outside a timed callback: delivered inside publish(), as before
    order.clear()
    pub_f.publish(String(data='3'))
    assert order == ['f:3']

    def failing():
        pub_f.publish(String(data='4'))
        raise RuntimeError('node failed')
    order.clear()
    with pytest.raises(RuntimeError, match='node failed'):
        bus.timed('hold_a', failing)
    assert order == ['f:4'] and not bus._holding
    # a second run through timed holds again (the flag was cleared)
    order.clear()
    bus.timed('hold_a', tick)
    assert order[:2] == ['tick: state sent', 'tick: force sent']


@pytest.mark.ros
def test_align_timers_puts_timers_of_one_period_on_one_grid(ros):
    """Timers created at different phases fall due together after `align_timers`; a canceled
    timer stays canceled, a destroyed one is skipped."""
    import time
    node = ros.node('align')
    timers = []
    for _ in range(3):
        timers.append(node.create_timer(0.01, lambda: None))
        time.sleep(0.0033)
    canceled = node.create_timer(0.01, lambda: None)
    canceled.cancel()
    gone = node.create_timer(0.01, lambda: None)
    node.destroy_timer(gone)

    def spread_ns():
        due = [t.time_until_next_call() for t in timers]
        return max(due) - min(due)
    assert spread_ns() > 5_000_000                # 3.3 ms apart, twice
    assert R.align_timers(timers + [canceled, gone]) == 3
    assert spread_ns() < 1_000_000               # microseconds apart (a loaded machine: < 1 ms)
    assert canceled.is_canceled()


def test_nice_applies_to_every_thread_falls_back_and_refuses_bad_values(monkeypatch):
    with pytest.raises(ValueError, match='nice'):
        R.set_nice(-21)
    with pytest.raises(ValueError, match='nice'):
        R.set_nice(1.5)
    old = os.getpriority(os.PRIO_PROCESS, 0)
    import threading
    stop = threading.Event()
    th = threading.Thread(target=stop.wait)
    th.start()
    try:
        assert R.set_nice(old + 1, print) == old             # raising nice is always allowed
        assert os.getpriority(os.PRIO_PROCESS, 0) == old + 1
        assert os.getpriority(os.PRIO_PROCESS, th.native_id) == old + 1
    finally:
        if os.geteuid() == 0:
            R.set_nice(old, print)
        stop.set()
        th.join()

    def refuse(*_a):
        raise PermissionError(1, 'Operation not permitted')
    monkeypatch.setattr(os, 'setpriority', refuse)
    logs = []
    assert R.set_nice(-5, logs.append) is None
    assert len(logs) == 1 and 'not permitted' in logs[0]


def test_own_autogroup_writes_the_group_nice_and_refuses_bad_values(tmp_path, monkeypatch):
    f = tmp_path / 'autogroup'
    f.write_text('/autogroup-1 nice 0\n')
    # no new session in the test process: setsid is stubbed (it would detach pytest)
    monkeypatch.setattr(os, 'setsid', lambda: None)
    assert R.own_autogroup(-10, log=lambda m: None, path=str(f)) == 'autogroup nice -10'
    assert f.read_text() == '-10'
    # no autogroup file (kernel without autogroups): nothing done, nothing said
    logs = []
    assert R.own_autogroup(-10, log=logs.append, path=str(tmp_path / 'none')) is None
    assert logs == []
    # a refused write: one log line, None
    d = tmp_path / 'dir'
    d.mkdir()
    assert R.own_autogroup(-5, log=logs.append, path=str(d)) is None
    assert len(logs) == 1 and 'autogroup nice -5 not permitted' in logs[0]
    for bad in (-21, 20, 1.5, True, '3'):
        with pytest.raises(ValueError, match='nice'):
            R.own_autogroup(bad, path=str(f))


def test_thread_cpu_sees_a_busy_thread_and_cpu_delta_keeps_positive_use():
    import threading
    import time

    def spin():
        t_end = time.process_time() + 0.3
        while time.process_time() < t_end:
            pass

    before = R.thread_cpu()
    th = threading.Thread(target=spin, name='busy_probe')
    th.start()
    th.join()
    after = R.thread_cpu()
    if not before:                                   # no /proc here
        pytest.skip('no /proc/self/task on this system')
    # the busy thread has ended: its time is not counted; this thread's time is >= 0
    d = R.cpu_delta(before, after)
    assert all(v > 0 for v in d.values())
    assert R.cpu_delta({'a': 1.0}, {'a': 1.5, 'b': 0.2}) == {'a': 0.5, 'b': 0.2}
    assert R.cpu_delta({'a': 1.0}, {'a': 1.0}) == {}


def test_worker_cpus_places_master_first_vision_last_only_when_both_run():
    both = ['master', 'slave', 'vision']
    assert R.worker_cpus('master', both, {3, 1, 2}) == {1}
    assert R.worker_cpus('vision', both, {3, 1, 2}) == {3}
    assert R.worker_cpus('slave', both, {0, 1}) is None
    assert R.worker_cpus('recorder', both, {0, 1}) is None
    # one CPU, or not both of master and vision: nowhere in particular
    assert R.worker_cpus('master', both, {0}) is None
    assert R.worker_cpus('vision', ['vision'], {0, 1}) is None      # layout one's worker
    assert R.worker_cpus('master', ['master', 'slave'], {0, 1}) is None


def _thread_affinities():
    """(tid, CPU set) of this process's threads, skipping a thread that ends between the
    listing and the query (threads of earlier tests' executors end at their own pace: the
    clean-up's ProcessLookupError seen once under load)."""
    out = []
    for tid in os.listdir('/proc/self/task'):
        try:
            out.append((int(tid), os.sched_getaffinity(int(tid))))
        except ProcessLookupError:
            pass
    return out


def test_pin_process_pins_every_thread_and_says_when_it_cannot(monkeypatch):
    import threading
    before = os.sched_getaffinity(0)
    cpu = min(before)
    stop = threading.Event()
    t = threading.Thread(target=stop.wait)
    t.start()
    logs = []
    try:
        if len(before) > 1:          # the loop (main) thread only: the other keeps its CPUs
            assert R.pin_process(os.getpid(), {cpu}, logs.append, main_only=True)
            assert os.sched_getaffinity(0) == {cpu}
            assert os.sched_getaffinity(t.native_id) == before
        assert R.pin_process(os.getpid(), {cpu}, logs.append)
        for tid, cpus in _thread_affinities():
            assert cpus == {cpu}, tid
        assert not logs
        # a CPU that does not exist: refused, one log line
        assert not R.pin_process(os.getpid(), {4096}, logs.append)
        assert len(logs) == 1 and 'refused' in logs[0]
        # a process that is gone: nothing pinned
        assert not R.pin_process(2 ** 22 + 12345, {cpu}, logs.append)
    finally:
        stop.set()
        t.join()
        for tid, _ in _thread_affinities():
            try:
                os.sched_setaffinity(tid, before)
            except ProcessLookupError:   # ended since it was listed
                pass


def test_workers_pin_the_split_layouts_master_and_vision(monkeypatch):
    from catheter_bringup import worker as W
    made = {}

    class Fake:
        def __init__(self, scenario, nodes, log, name, part=None, cpus=None):
            made[name] = cpus
    monkeypatch.setattr(W, 'Worker', Fake)
    monkeypatch.setattr(W.os, 'sched_getaffinity', lambda _pid: {0, 1})
    groups = {'master': ['a'], 'slave': ['b'], 'vision': ['c']}
    W.Workers({'realtime_priority': 30}, groups, print)
    assert made == {'master': {0}, 'slave': None, 'vision': {1}}
    W.Workers({'realtime_priority': 0}, groups, print)       # no real-time loops: no placement
    assert made == {'master': None, 'slave': None, 'vision': None}


def test_a_placed_worker_is_asked_to_pin_itself(monkeypatch):
    """Workers pin themselves (`run_scenario --cpus`, the launch file's way too): the 1 kHz
    processes their loop thread only (`pins_loop_thread_only`), vision every thread."""
    from catheter_bringup import worker as W
    cmds = []

    class Proc:
        pid = 1

        def __init__(self, cmd, **_kw):
            cmds.append(cmd)

        def poll(self):
            return None
    monkeypatch.setattr(W.subprocess, 'Popen', Proc)
    assert R.pins_loop_thread_only('master') and R.pins_loop_thread_only('slave')
    assert not R.pins_loop_thread_only('vision')
    for cpus, want in ((frozenset({1, 0}), '0,1'), (None, None)):
        w = W.Worker({'duration': 1.0}, ['x'], lambda *_: None, 'master', cpus=cpus)
        cmd = cmds[-1]
        assert (cmd[cmd.index('--cpus') + 1] if '--cpus' in cmd else None) == want
        w.proc = None
        w.cleanup()


def test_worker_scenario_turns_on_processing_on_arrival(monkeypatch, tmp_path):
    """A worker's scenario: shape_node processes frames as they arrive, unless the scenario
    says otherwise."""
    import yaml
    from catheter_bringup import worker as W
    seen = []

    class Proc:
        pid = 1

        def __init__(self, cmd, **_kw):
            with open(cmd[cmd.index('catheter_bringup.run_scenario') + 1]) as f:
                seen.append(yaml.safe_load(f))
    monkeypatch.setattr(W.subprocess, 'Popen', Proc)
    for params, want in (({}, True), ({"process_on_arrival": False}, False)):
        w = W.Worker({'duration': 1.0, 'global_params': dict(params)}, ['shape_node'],
                     lambda *_: None)
        assert seen[-1]['global_params']['process_on_arrival'] is want
        w.cleanup()

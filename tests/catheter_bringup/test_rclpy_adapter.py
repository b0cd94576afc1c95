"""Pins every rclpy behaviour the runner relies on (catheter_bringup.rclpy_adapter). A new
rclpy that changes one of them fails the test named after it, not a lockstep run somewhere
downstream."""
import pytest
from builtin_interfaces.msg import Time
from rosgraph_msgs.msg import Clock
from std_msgs.msg import String

from catheter_bringup import rclpy_adapter as A
from catheter_common.qos import QOS_DEFAULT, QOS_FAST

pytestmark = pytest.mark.ros


def _clock(ns: int) -> Clock:
    return Clock(clock=Time(sec=ns // 10 ** 9, nanosec=ns % 10 ** 9))


def _sim_node(ros, name):
    from rclpy.parameter import Parameter
    import rclpy
    node = rclpy.create_node(name, context=ros.context,
                             parameter_overrides=[Parameter('use_sim_time', value=True)])
    return ros.add(node)


def test_installed_rclpy_is_a_tested_version():
    tested, version = A.check_rclpy()
    assert tested, (f'rclpy {version} is not in rclpy_adapter.TESTED_RCLPY '
                    f'{A.TESTED_RCLPY}: check every function of rclpy_adapter against it')


def test_intercept_publish_replaces_what_the_node_calls(ros):
    node = ros.node('adapter_pub')
    pub = node.create_publisher(String, 'adapter/pub', QOS_DEFAULT)
    seen = []
    orig = A.intercept_publish(pub, seen.append)
    pub.publish(String(data='a'))                      # what a node's code does
    assert [m.data for m in seen] == ['a']
    got = []
    probe = ros.node('adapter_pub_probe')
    probe.create_subscription(String, 'adapter/pub', got.append, QOS_DEFAULT)
    assert ros.spin_until(lambda: pub.get_subscription_count() > 0, 10.0)
    orig(String(data='b'))                             # the original still goes out on DDS
    assert ros.spin_until(lambda: got, 10.0) and got[0].data == 'b'


def test_count_extra_subscriber_adds_one_to_what_dds_knows(ros):
    node = ros.node('adapter_count')
    pub = node.create_publisher(String, 'adapter/count', QOS_DEFAULT)
    A.count_extra_subscriber(pub)
    assert pub.get_subscription_count() == 1          # what a node's code calls
    probe = ros.node('adapter_count_probe')
    probe.create_subscription(String, 'adapter/count', lambda m: None, QOS_DEFAULT)
    assert ros.spin_until(lambda: pub.get_subscription_count() == 2, 10.0)


def test_callback_type_tells_message_only_from_message_info(ros):
    node = ros.node('adapter_cbtype')
    one = node.create_subscription(String, 'adapter/a', lambda m: None, QOS_DEFAULT)
    two = node.create_subscription(String, 'adapter/b', lambda m, info: None, QOS_DEFAULT)
    assert A.callback_wants_info(one) is False
    assert A.callback_wants_info(two) is True


def test_take_and_wrap_callback_redirect_what_the_executor_delivers(ros):
    node = ros.node('adapter_sub')
    first, taken, wrapped = [], [], []
    sub = node.create_subscription(String, 'adapter/sub', first.append, QOS_DEFAULT)
    old, wants = A.take_callback(sub, taken.append)
    assert old == first.append and wants is False

    def wrapper(cb):
        def inner(msg):
            wrapped.append(msg.data)
            return cb(msg)
        return inner
    A.wrap_callback(sub, wrapper)
    pub = ros.node('adapter_sub_pub').create_publisher(String, 'adapter/sub', QOS_DEFAULT)
    assert ros.spin_until(lambda: pub.get_subscription_count() > 0, 10.0)
    pub.publish(String(data='x'))
    assert ros.spin_until(lambda: taken, 10.0)
    assert first == [] and [m.data for m in taken] == ['x'] and wrapped == ['x']


def test_wrap_callback_keeps_the_message_info_of_a_callback_that_takes_it(ros):
    node = ros.node('adapter_info')
    infos, wrapped = [], []
    sub = node.create_subscription(String, 'adapter/info', lambda m, info: infos.append(info),
                                   QOS_DEFAULT)

    def wrapper(cb):
        def inner(*args):
            wrapped.append(len(args))
            return cb(*args)
        return inner
    A.wrap_callback(sub, wrapper)
    assert A.callback_wants_info(sub) is True
    pub = ros.node('adapter_info_pub').create_publisher(String, 'adapter/info', QOS_DEFAULT)
    assert ros.spin_until(lambda: pub.get_subscription_count() > 0, 10.0)
    pub.publish(String(data='x'))
    assert ros.spin_until(lambda: infos, 10.0)
    assert wrapped == [2] and infos[0]['publication_sequence_number'] == 1


def test_detach_clock_removes_the_clock_subscription_and_set_time_sets_the_clock(ros):
    node = _sim_node(ros, 'adapter_clock')
    clock_subs = [s for s in node.subscriptions if s.topic_name == '/clock']
    assert len(clock_subs) == 1
    ts = A.detach_clock(node)
    assert ts is not None
    assert not [s for s in node.subscriptions if s.topic_name == '/clock']
    A.set_time(ts, _clock(5_000_000_123))
    assert node.get_clock().now().nanoseconds == 5_000_000_123
    # a /clock message published now does not move the node's time any more
    pub = ros.node('adapter_clock_pub').create_publisher(Clock, '/clock', QOS_DEFAULT)
    pub.publish(_clock(1))
    ros.spin_for(0.2)
    assert node.get_clock().now().nanoseconds == 5_000_000_123
    assert A.detach_clock(node) is ts                  # idempotent


def test_set_times_sets_every_clock_of_every_time_source(ros):
    """set_times does what set_time with a /clock message of that time does, for several
    TimeSources at once: every node's clock, and a clock attached afterwards starts there."""
    from rclpy.clock import ROSClock
    nodes = [_sim_node(ros, f'adapter_times_{k}') for k in range(3)]
    sources = [A.detach_clock(n) for n in nodes]
    A.set_times(sources, 7_000_000_321)
    assert [n.get_clock().now().nanoseconds for n in nodes] == [7_000_000_321] * 3
    late = ROSClock()
    sources[1].attach_clock(late)
    assert late.now().nanoseconds == 7_000_000_321
    A.set_times(sources, 7_000_001_000)
    assert late.now().nanoseconds == 7_000_001_000
    assert [n.get_clock().now().nanoseconds for n in nodes] == [7_000_001_000] * 3
    # the same state as set_time's
    A.set_time(sources[0], _clock(9_000_000_000))
    assert nodes[0].get_clock().now().nanoseconds == 9_000_000_000


def test_fire_timer_runs_the_callback_and_advances_the_timer(ros):
    node = _sim_node(ros, 'adapter_timer')
    ts = A.detach_clock(node)
    A.set_time(ts, _clock(1_000_000_000))
    calls = []
    tmr = node.create_timer(0.010, lambda: calls.append(node.get_clock().now().nanoseconds))
    assert A.timer_ready(tmr) is False
    assert A.timer_due_in_ns(tmr) == 10_000_000
    A.set_time(ts, _clock(1_010_000_000))
    assert A.timer_ready(tmr) is True
    assert A.timer_due_in_ns(tmr) <= 0
    A.fire_timer(tmr)
    assert calls == [1_010_000_000]
    assert A.timer_ready(tmr) is False                 # the period was marked as called
    assert A.timer_due_in_ns(tmr) == 10_000_000
    node.destroy_timer(tmr)
    assert A.timer_ready(tmr) is None and A.timer_due_in_ns(tmr) is None


def test_spin_ready_runs_ready_callbacks_and_raises_their_exceptions(ros):
    node = _sim_node(ros, 'adapter_spin')
    ts = A.detach_clock(node)
    A.set_time(ts, _clock(0))
    calls = []
    node.create_timer(0.001, lambda: calls.append(1))
    assert A.spin_ready(ros.executor, 10) == 0         # nothing due: returns at once
    A.set_time(ts, _clock(1_000_000))
    assert A.spin_ready(ros.executor, 10) >= 1 and calls == [1]

    def boom():
        raise RuntimeError('boom in a callback')
    node.create_timer(0.001, boom)
    A.set_time(ts, _clock(2_000_000))
    with pytest.raises(RuntimeError, match='boom in a callback'):
        A.spin_ready(ros.executor, 10)


@pytest.mark.parametrize('kind', ['single', 'events'])
def test_executors_call_replaced_callbacks_and_take_raw_after_creation(ros, kind):
    """The worker processes spin an EventsExecutor: it must call a subscription's and a timer's
    callback as they are at call time (take_callback, wrap_timer_callback) and take a
    subscription switched to raw after creation as bytes (take_callback(raw=True))."""
    import time
    from catheter_common.ros_node import make_executor
    node = ros.node(f'adapter_raw_{kind}')
    sub = node.create_subscription(String, f'adapter/raw_{kind}', lambda m: None, QOS_DEFAULT)
    got, fired = [], []
    A.take_callback(sub, got.append, raw=True)
    tmr = node.create_timer(0.01, lambda: None)
    A.wrap_timer_callback(tmr, lambda f: (lambda: fired.append(1)))
    ex = make_executor(kind, context=ros.context)
    try:
        ex.add_node(node)
        pub = ros.node(f'adapter_raw_pub_{kind}').create_publisher(
            String, f'adapter/raw_{kind}', QOS_DEFAULT)
        t_end = time.monotonic() + 10
        while pub.get_subscription_count() == 0 and time.monotonic() < t_end:
            ex.spin_once(timeout_sec=0.01)
        pub.publish(String(data='r'))
        while (not got or not fired) and time.monotonic() < t_end:
            ex.spin_once(timeout_sec=0.01)
    finally:
        ex.remove_node(node)
        ex.shutdown()
    assert got and isinstance(got[0], bytes) and fired


def test_without_ros_args_drops_the_ros_arguments_only():
    argv = ['smoke', '--ros-args', '-r', '__node:=x', '--', '--duration', '2']
    assert A.without_ros_args(argv) == ['smoke', '--duration', '2']
    assert A.without_ros_args(['smoke']) == ['smoke']


def test_serializer_round_trips_a_message():
    ser, de = A.serializer()
    msg = String(data='catheter')
    assert de(ser(msg), String) == msg


def test_spin_for_runs_the_events_executor_for_about_the_time_asked():
    import time
    import rclpy
    from rclpy.context import Context
    from rclpy.experimental import EventsExecutor
    ctx = Context()
    rclpy.init(context=ctx)
    try:
        node = rclpy.create_node('spin_for_probe', context=ctx)
        ex = EventsExecutor(context=ctx)
        ex.add_node(node)
        ticks = []
        node.create_timer(0.01, lambda: ticks.append(1))
        never = A.never_done()
        t0 = time.monotonic()
        A.spin_for(ex, 0.2, never)
        took = time.monotonic() - t0
        assert 0.15 <= took < 2.0          # returned after its slice, not at once or never
        assert len(ticks) >= 5             # the executor ran the timer inside the slice
        assert not never.done()
        ex.shutdown()
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=ctx)


_LOST_CHILD = r'''
import json, sys, time
import rclpy
from rclpy.experimental import EventsExecutor
from std_msgs.msg import String
from catheter_bringup import rclpy_adapter as A
from catheter_common.qos import QOS_FAST
rclpy.init()
node = rclpy.create_node('lost_watch_child')
got, lost = [], []
sub = node.create_subscription(String, '/lost_watch/probe', lambda m: got.append(m.data), QOS_FAST)
A.watch_message_lost(node, sub, lost.append)
ex = EventsExecutor()
ex.add_node(node)
print('ready', flush=True)
end = time.monotonic() + float(sys.argv[1])
while time.monotonic() < end:
    ex.spin_once(timeout_sec=0.05)
n_handlers = len(sub.event_handlers)
node.destroy_subscription(sub)          # the added handlers go with it
print(json.dumps({'got': len(got), 'lost': lost, 'handlers': n_handlers}), flush=True)
ex.shutdown()
node.destroy_node()
rclpy.try_shutdown()
'''


def test_watch_message_lost_reports_what_dds_lost_to_a_subscription(ros):
    """A subscriber process frozen (SIGSTOP) 2.5 s while ~1 kHz samples keep coming: its DDS
    transport drops what does not fit (the shared-memory port holds 512), and the handler
    added after the subscription was made reports the total (the samples its own depth-10
    queue dropped are not in it); the handler is destroyed with the subscription."""
    import json
    import signal
    import subprocess
    import sys
    import time
    pub = ros.node('lost_watch_pub').create_publisher(String, '/lost_watch/probe', QOS_FAST)
    child = subprocess.Popen([sys.executable, '-c', _LOST_CHILD, '7.0'], stdout=subprocess.PIPE,
                             text=True)
    try:
        assert child.stdout.readline().strip() == 'ready'
        assert ros.spin_until(lambda: pub.get_subscription_count() > 0, 20.0)
        sent = 0

        def publish_for(s):
            nonlocal sent
            end = time.monotonic() + s
            while time.monotonic() < end:
                pub.publish(String(data=str(sent)))
                sent += 1
                time.sleep(0.001)
        publish_for(0.3)
        child.send_signal(signal.SIGSTOP)
        publish_for(2.5)
        child.send_signal(signal.SIGCONT)
        publish_for(0.3)
        out = json.loads(child.communicate(timeout=60)[0].strip().splitlines()[-1])
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()
    assert child.returncode == 0
    assert out['handlers'] >= 1
    assert out['lost'] and out['lost'] == sorted(out['lost']), out      # running totals
    total = out['lost'][-1]
    # what DDS reported is part of what never arrived
    assert 0 < total <= sent - out['got'], (total, sent, out['got'])

"""replay without a ROS graph: a stand-in node records what replay publishes, with which QoS,
so --start and the recorded QoS are checked in milliseconds."""
from rclpy.qos import QoSDurabilityPolicy, QoSReliabilityPolicy
from rclpy.serialization import serialize_message

from catheter_bringup.recorder import McapRecorder
from catheter_bringup.replay import replay


class _Pub:
    def __init__(self, topic, qos, sink):
        self.topic, self.qos, self.sink = topic, qos, sink

    def publish(self, msg):
        self.sink.append((self.topic, msg))


class _Node:
    """What replay() uses of an rclpy node: create_publisher."""

    def __init__(self):
        self.sent, self.pubs = [], {}

    def create_publisher(self, cls, topic, qos):
        self.pubs[topic] = _Pub(topic, qos, self.sent)
        return self.pubs[topic]


def _bag(path):
    from geometry_msgs.msg import WrenchStamped
    from std_msgs.msg import String
    rec = McapRecorder(path)
    rec.add_topic('/slave/force', 'geometry_msgs/msg/WrenchStamped',
                  qos=[{'history': 'keep_last', 'depth': 5, 'reliability': 'best_effort',
                        'durability': 'volatile'}])
    rec.add_topic('/scenario', 'std_msgs/msg/String',
                  qos=[{'history': 'keep_last', 'depth': 1, 'reliability': 'reliable',
                        'durability': 'transient_local'}])
    rec.write('/scenario', serialize_message(String(data='latched')), 1_000_000_000)
    for k in range(100):                          # 1.000 ... 1.099 s, 1 ms apart
        m = WrenchStamped()
        m.wrench.force.x = float(k)
        rec.write('/slave/force', serialize_message(m), 1_000_000_000 + k * 1_000_000)
    rec.close('complete')
    return path


def test_start_skips_seconds_of_the_recording(tmp_path):
    from geometry_msgs.msg import WrenchStamped
    from rclpy.serialization import deserialize_message
    bag = _bag(tmp_path / 'r.mcap')
    node = _Node()
    res = replay(bag, rate=100.0, clock=False, node=node, start=0.05)
    assert res['published'] == {'/slave/force': 50}      # 1.050 ... 1.099 s
    first = deserialize_message(node.sent[0][1], WrenchStamped)
    assert first.wrench.force.x == 50.0


def test_each_topic_is_republished_with_its_recorded_qos(tmp_path):
    node = _Node()
    res = replay(_bag(tmp_path / 'q.mcap'), rate=100.0, clock=False, node=node)
    assert res['published'] == {'/scenario': 1, '/slave/force': 100}
    latched, force = node.pubs['/scenario'].qos, node.pubs['/slave/force'].qos
    assert latched.durability == QoSDurabilityPolicy.TRANSIENT_LOCAL
    assert latched.reliability == QoSReliabilityPolicy.RELIABLE and latched.depth == 1
    assert force.durability == QoSDurabilityPolicy.VOLATILE
    assert force.reliability == QoSReliabilityPolicy.BEST_EFFORT and force.depth == 5


def test_bad_rate_and_start_are_refused_by_name(tmp_path):
    import pytest
    bag = _bag(tmp_path / 'v.mcap')
    for kw, name in ((dict(rate=0.0), 'rate'), (dict(rate=float('nan')), 'rate'),
                     (dict(start=-0.1), 'start'), (dict(start=float('nan')), 'start')):
        with pytest.raises(ValueError, match=name):
            replay(bag, clock=False, node=_Node(), **kw)


def test_should_stop_ends_the_replay_between_messages_and_while_waiting(tmp_path):
    import time
    bag = _bag(tmp_path / 's.mcap')
    node = _Node()
    res = replay(bag, rate=1e4, clock=False, node=node, should_stop=lambda: len(node.sent) >= 30)
    assert sum(res['published'].values()) == 30 == len(node.sent)
    # at 0.001x the second message is due 1 s of wall time later: a stop while waiting for it
    node, t0 = _Node(), time.perf_counter()
    calls = []

    def stop_in_the_wait():         # calls 1-3: before each of the first three messages
        calls.append(1)
        return len(calls) >= 4

    res = replay(bag, rate=0.001, clock=False, node=node, should_stop=stop_in_the_wait)
    assert time.perf_counter() - t0 < 0.5 and len(node.sent) == 2 and len(calls) == 4
    assert sum(res['published'].values()) == len(node.sent)


def test_loop_starts_again_and_the_clock_follows_the_log_time(tmp_path):
    bag = _bag(tmp_path / 'l.mcap')
    node = _Node()
    res = replay(bag, rate=1e4, clock=True, node=node, loop=True,
                 should_stop=lambda: len([t for t, _ in node.sent if t != '/clock']) >= 250)
    assert res['published'] == {'/scenario': 3, '/slave/force': 247}
    ticks = [m for t, m in node.sent if t == '/clock']
    # one tick per distinct log time: 100 per pass (the latched message shares 1.000 s), 47
    # in the third (up to 1.046 s)
    assert len(ticks) == 247 and ticks[0].clock.sec == 1 and ticks[0].clock.nanosec == 0
    assert ticks[99].clock.nanosec == 99_000_000 and ticks[100].clock.nanosec == 0


def test_unreadable_qos_metadata_falls_back_to_the_default_profile():
    from catheter_bringup.replay import _qos_from_metadata
    for meta in ({}, {'offered_qos_profiles': '- [unclosed'}, {'offered_qos_profiles': ''}):
        q = _qos_from_metadata(meta)
        assert q.depth == 10 and q.reliability == QoSReliabilityPolicy.RELIABLE
        assert q.durability == QoSDurabilityPolicy.VOLATILE
    # depth 0 (rosbag2's "system default") is the default 10; a negative depth is at least 1
    q = _qos_from_metadata({'offered_qos_profiles': '- {depth: 0, reliability: 2}'})
    assert q.depth == 10 and q.reliability == QoSReliabilityPolicy.BEST_EFFORT
    q = _qos_from_metadata({'offered_qos_profiles': '- {depth: -3, durability: 1}'})
    assert q.depth == 1 and q.durability == QoSDurabilityPolicy.TRANSIENT_LOCAL

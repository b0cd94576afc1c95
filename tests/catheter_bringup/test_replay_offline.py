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

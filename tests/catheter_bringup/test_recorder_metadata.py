"""What the recorder promises about each message's MCAP record and the run's metadata, read
back with the independent `mcap` reader: per-topic sequence numbers, the publish time given,
first/last log times, the offered QoS (durability too) and how a run ended (Ctrl-C is
'interrupted', not 'failed'). Written to kill the recorder mutants of issue 14."""
import pathlib

import pytest
from mcap.reader import make_reader
from rclpy.qos import (QoSDurabilityPolicy, QoSHistoryPolicy, QoSProfile,
                       QoSReliabilityPolicy)
from rclpy.serialization import serialize_message

from catheter_bringup.recorder import McapRecorder, read_run_metadata
from catheter_bringup.ros_recording import qos_to_dict


def _wrench(fx):
    from geometry_msgs.msg import WrenchStamped
    m = WrenchStamped()
    m.wrench.force.x = float(fx)
    return serialize_message(m)


def _records(path):
    with open(path, 'rb') as f:
        return [(c.topic, m.sequence, m.log_time, m.publish_time)
                for _, c, m in make_reader(f).iter_messages(log_time_order=False)]


def test_sequence_numbers_count_each_topic_from_zero(tmp_path):
    path = tmp_path / 'seq.mcap'
    with McapRecorder(path) as rec:
        rec.add_topic('/a', 'geometry_msgs/msg/WrenchStamped')
        rec.add_topic('/b', 'geometry_msgs/msg/WrenchStamped')
        for i in range(7):
            rec.write('/a', _wrench(i), 10 * i)
            if i % 2:
                rec.write('/b', _wrench(i), 10 * i + 1)
    recs = _records(path)
    for topic, n in (('/a', 7), ('/b', 3)):
        assert [s for t, s, _, _ in recs if t == topic] == list(range(n))


def test_publish_time_is_the_one_given_and_defaults_to_the_log_time(tmp_path):
    path = tmp_path / 'pub.mcap'
    with McapRecorder(path) as rec:
        rec.add_topic('/a', 'geometry_msgs/msg/WrenchStamped')
        rec.write('/a', _wrench(1), 5_000, publish_time_ns=4_250)
        rec.write('/a', _wrench(2), 6_000)
    assert [(lt, pt) for _, _, lt, pt in _records(path)] == [(5_000, 4_250), (6_000, 6_000)]


def test_first_and_last_log_time_span_the_messages_also_out_of_order(tmp_path):
    path = tmp_path / 'span.mcap'
    times = [2_000, 3_000, 9_000, 4_000]       # a late message last: the span still ends at 9000
    with McapRecorder(path) as rec:
        rec.add_topic('/a', 'geometry_msgs/msg/WrenchStamped')
        for i, t in enumerate(times):
            rec.write('/a', _wrench(i), t)
    meta = read_run_metadata(path)
    assert meta['first_log_time_ns'] == '2000'
    assert meta['last_log_time_ns'] == '9000'
    assert meta['messages'] == '4' and meta['counts'] == '{"/a": 4}'


def test_an_empty_run_says_so_in_its_times(tmp_path):
    path = tmp_path / 'empty.mcap'
    McapRecorder(path).close()
    meta = read_run_metadata(path)
    assert meta['first_log_time_ns'] == meta['last_log_time_ns'] == '-1'
    assert meta['messages'] == '0'


@pytest.mark.parametrize('durability, name', [
    (QoSDurabilityPolicy.TRANSIENT_LOCAL, 'transient_local'),
    (QoSDurabilityPolicy.VOLATILE, 'volatile')])
def test_offered_durability_is_recorded_as_offered(tmp_path, durability, name):
    q = QoSProfile(history=QoSHistoryPolicy.KEEP_LAST, depth=3, durability=durability,
                   reliability=QoSReliabilityPolicy.RELIABLE)
    d = qos_to_dict(q)
    assert d == {'history': 'keep_last', 'depth': 3, 'reliability': 'reliable',
                 'durability': name}
    path = tmp_path / 'qos.mcap'
    with McapRecorder(path) as rec:
        rec.add_topic('/latched', 'geometry_msgs/msg/WrenchStamped', [d])
        rec.write('/latched', _wrench(0), 1)
    from rosbags.highlevel import AnyReader
    from rosbags.interfaces import QosDurability
    with AnyReader([pathlib.Path(path)]) as reader:
        offered = reader.connections[0].ext.offered_qos_profiles[0]
    want = (QosDurability.TRANSIENT_LOCAL if name == 'transient_local'
            else QosDurability.VOLATILE)
    assert offered.durability == want and offered.depth == 3


def test_ctrl_c_inside_the_with_block_is_an_interrupted_run_not_a_failed_one(tmp_path):
    path = tmp_path / 'int.mcap'
    with pytest.raises(KeyboardInterrupt):
        with McapRecorder(path) as rec:
            rec.add_topic('/a', 'geometry_msgs/msg/WrenchStamped')
            rec.write('/a', _wrench(0), 1)
            raise KeyboardInterrupt
    meta = read_run_metadata(path)
    assert meta['status'] == 'interrupted' and meta['reason'] == 'KeyboardInterrupt'


@pytest.mark.parametrize('offered', [
    ['reliable'], ['best_effort'], ['reliable', 'best_effort'], ['best_effort', 'reliable']])
def test_the_recording_subscription_is_compatible_with_every_offered_publisher(offered):
    """A reliable subscription to a best-effort publisher receives nothing: the recorder's
    subscription must be compatible (rclpy's own check) with each publisher it records."""
    from rclpy.qos import QoSCompatibility, qos_check_compatible
    from catheter_bringup.ros_recording import recording_qos
    rel = {'reliable': QoSReliabilityPolicy.RELIABLE,
           'best_effort': QoSReliabilityPolicy.BEST_EFFORT}
    pubs = [QoSProfile(history=QoSHistoryPolicy.KEEP_LAST, depth=1, reliability=rel[r],
                       durability=d)
            for r in offered for d in (QoSDurabilityPolicy.VOLATILE,
                                       QoSDurabilityPolicy.TRANSIENT_LOCAL)]
    sub = recording_qos(pubs)
    for pub in pubs:
        compat, why = qos_check_compatible(pub, sub)
        # WARNING only says that liveliness is left to the system default on both sides
        assert compat != QoSCompatibility.ERROR, why
    assert sub.depth >= 100          # deep enough not to drop while the executor is busy
    if offered == ['reliable']:
        assert sub.reliability == QoSReliabilityPolicy.RELIABLE   # no loss it could avoid

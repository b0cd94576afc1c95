"""The MCAP recorder read back by independent readers (rosbags, mcap_ros2)."""
import pathlib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from rclpy.serialization import serialize_message

from catheter_bringup.recorder import (SEPARATOR, McapRecorder, message_definition,
                                       read_run_metadata)


def _wrench(fx, sec=0):
    from geometry_msgs.msg import WrenchStamped
    m = WrenchStamped()
    m.header.frame_id = 'catheter_base'
    m.header.stamp.sec = sec
    m.wrench.force.x = float(fx)
    return m


def test_message_definition_has_dependencies_once_in_rosbag2_layout():
    text = message_definition('geometry_msgs/msg/WrenchStamped')
    blocks = text.split(SEPARATOR + '\n')
    assert blocks[0].rstrip().endswith('Wrench wrench')
    names = [b.splitlines()[0] for b in blocks[1:]]
    assert names == ['MSG: std_msgs/Header', 'MSG: builtin_interfaces/Time',
                     'MSG: geometry_msgs/Wrench', 'MSG: geometry_msgs/Vector3']
    with pytest.raises(ValueError, match='type_name'):
        message_definition('no_pkg/msg/Nothing')
    with pytest.raises(ValueError, match='type_name'):
        message_definition('bad')


def test_rosbags_and_mcap_ros2_read_what_was_written(tmp_path):
    from sensor_msgs.msg import Image
    path = tmp_path / 'run.mcap'
    rec = McapRecorder(path)
    rec.add_topic('/slave/force', 'geometry_msgs/msg/WrenchStamped',
                  [{'reliability': 'best_effort', 'depth': 1}])
    rec.add_topic('/camera/image_raw', 'sensor_msgs/msg/Image')
    forces = np.linspace(0, 0.4, 250)
    for i, f in enumerate(forces):
        rec.write('/slave/force', serialize_message(_wrench(f)), i * 1_000_000)
        if i % 33 == 0:
            img = Image(height=4, width=5, encoding='mono8', step=5, data=bytes(range(20)))
            rec.write('/camera/image_raw', serialize_message(img), i * 1_000_000)
    rec.close('complete', 'test', extra={'scenario': 'unit'})

    from rosbags.highlevel import AnyReader
    from rosbags.interfaces import QosReliability
    with AnyReader([pathlib.Path(path)]) as reader:
        conns = {c.topic: c for c in reader.connections}
        assert conns['/slave/force'].msgtype == 'geometry_msgs/msg/WrenchStamped'
        assert conns['/slave/force'].msgcount == 250
        qos = conns['/slave/force'].ext.offered_qos_profiles[0]
        assert qos.reliability == QosReliability.BEST_EFFORT and qos.depth == 1
        got = [reader.deserialize(raw, c.msgtype).wrench.force.x
               for c, t, raw in reader.messages([conns['/slave/force']])]
        imgs = [reader.deserialize(raw, c.msgtype)
                for c, t, raw in reader.messages([conns['/camera/image_raw']])]
    np.testing.assert_array_equal(got, forces)
    assert len(imgs) == 8 and bytes(imgs[0].data) == bytes(range(20))

    from mcap_ros2.reader import read_ros2_messages
    got2 = [m.ros_msg.wrench.force.x for m in read_ros2_messages(str(path), ['/slave/force'])]
    np.testing.assert_array_equal(got2, forces)
    meta = read_run_metadata(path)
    assert meta['status'] == 'complete' and meta['scenario'] == 'unit'
    assert meta['messages'] == '258' and meta['last_log_time_ns'] == str(249 * 1_000_000)


def test_bad_arguments_are_refused(tmp_path):
    with pytest.raises(ValueError, match='path'):
        McapRecorder(tmp_path / 'x.bag')
    rec = McapRecorder(tmp_path / 'x.mcap')
    with pytest.raises(ValueError, match='topic'):
        rec.add_topic('relative', 'std_msgs/msg/String')
    with pytest.raises(ValueError, match='not registered'):
        rec.write('/nope', b'', 0)
    rec.add_topic('/a', 'std_msgs/msg/String')
    with pytest.raises(ValueError, match='log_time_ns'):
        rec.write('/a', b'', -1)
    with pytest.raises(ValueError, match='status'):
        rec.close('weird')
    rec.close('failed', 'because')
    rec.close('complete')      # idempotent: the first close wins
    assert read_run_metadata(tmp_path / 'x.mcap')['status'] == 'failed'


def test_exception_inside_with_block_leaves_readable_failed_file(tmp_path):
    path = tmp_path / 'crash.mcap'
    with pytest.raises(RuntimeError):
        with McapRecorder(path) as rec:
            rec.add_topic('/slave/force', 'geometry_msgs/msg/WrenchStamped')
            rec.write('/slave/force', serialize_message(_wrench(0.1)), 5)
            raise RuntimeError('node died')
    meta = read_run_metadata(path)
    assert meta['status'] == 'failed' and 'node died' in meta['reason']


@settings(max_examples=25, deadline=None)
@given(st.lists(st.tuples(st.sampled_from(['/a', '/b', '/c']),
                          st.integers(0, 10**12),
                          st.floats(-1e6, 1e6, allow_nan=False)), max_size=60))
def test_every_written_message_comes_back_in_time_order(tmp_path_factory, items):
    path = tmp_path_factory.mktemp('h') / 'p.mcap'
    rec = McapRecorder(path, chunk_size=512)
    for t in ('/a', '/b', '/c'):
        rec.add_topic(t, 'geometry_msgs/msg/WrenchStamped')
    for topic, t, f in items:
        rec.write(topic, serialize_message(_wrench(f)), t)
    rec.close()
    from mcap_ros2.reader import read_ros2_messages
    back = [(m.channel.topic, m.log_time_ns, m.ros_msg.wrench.force.x)
            for m in read_ros2_messages(str(path))]
    assert sorted(back, key=lambda x: x[1]) == back
    assert sorted(back) == sorted(items)


def test_recorder_cuts_estimated_size_padding_and_refuses_short_payloads(tmp_path):
    """rclpy's serialize_message pads some messages (the rmw's size estimate); the file holds
    each message's exact bytes, which the strict rosbags reader accepts."""
    from sensor_msgs.msg import JointState
    from catheter_bringup.cdr import cdr_end
    msg = JointState(name=['m', 'c', 'k', 'offset', 'valid'], position=[0.0, 1.5, 2.0, 0.1, 1.0])
    data = serialize_message(msg)
    assert len(data) > cdr_end(data, JointState)
    path = tmp_path / 'exact.mcap'
    rec = McapRecorder(path)
    rec.add_topic('/slave/impedance', 'sensor_msgs/msg/JointState')
    rec.write('/slave/impedance', data, 1)
    with pytest.raises(ValueError, match='data'):
        rec.write('/slave/impedance', data[:cdr_end(data, JointState) - 1], 2)
    with pytest.raises(ValueError, match='data'):
        rec.write('/slave/impedance', b'not cdr at all', 3)
    rec.close()
    assert rec.counts['/slave/impedance'] == 1
    from rosbags.highlevel import AnyReader
    with AnyReader([pathlib.Path(path)]) as reader:
        (conn,) = reader.connections
        ((_, t, raw),) = list(reader.messages())
        assert len(raw) == cdr_end(data, JointState)
        back = reader.deserialize(raw, conn.msgtype)
    assert list(back.name) == list(msg.name) and list(back.position) == list(msg.position)


def test_chunks_are_zstd_at_the_recorders_level(tmp_path):
    """mcap's writer compresses through the module global the recorder sets
    (`recorder.ZSTD_LEVEL`): a chunk's frame says its level's window, and its content comes
    back whole (zstd frames of every level decompress alike)."""
    import zstandard
    from mcap.records import Chunk
    from mcap.stream_reader import StreamReader
    import catheter_bringup.recorder as R
    assert R.ZSTD_LEVEL == 1 and R.mcap.writer.zstandard.level == R.ZSTD_LEVEL
    path = tmp_path / 'z.mcap'
    rec = McapRecorder(path, chunk_size=1 << 16)
    rec.add_topic('/slave/force', 'geometry_msgs/msg/WrenchStamped')
    rng = np.random.default_rng(1)
    for i in range(2000):
        rec.write('/slave/force', serialize_message(_wrench(rng.normal(), sec=i)), i)
    rec.close('complete')
    with open(path, 'rb') as f:
        chunks = [r for r in StreamReader(f, skip_magic=False, emit_chunks=True).records
                  if isinstance(r, Chunk)]
    assert chunks and all(c.compression == 'zstd' for c in chunks)
    for c in chunks:
        raw = zstandard.ZstdDecompressor().decompress(c.data, max_output_size=c.uncompressed_size)
        assert len(raw) == c.uncompressed_size
        # the same bytes at level 1 (deterministic): what the recorder wrote
        assert zstandard.ZstdCompressor(level=1).compress(raw) == c.data
    from mcap_ros2.reader import read_ros2_messages
    assert len(list(read_ros2_messages(str(path)))) == 2000


def _record(path, items, fast: bool, chunk_size: int) -> bytes:
    rec = McapRecorder(path, chunk_size=chunk_size)
    if not fast:
        rec._add = None                   # mcap's own Writer.add_message
    for t in ('/a', '/b', '/c'):
        rec.add_topic(t, 'geometry_msgs/msg/WrenchStamped')
    for topic, t, f in items:
        rec.write(topic, serialize_message(_wrench(f, sec=t % 1000)), t,
                  publish_time_ns=None if f > 0 else t + 7)
    rec.close('complete', extra={'n': len(items)})
    return pathlib.Path(path).read_bytes()


@settings(max_examples=25, deadline=None)
@given(st.lists(st.tuples(st.sampled_from(['/a', '/b', '/c']),
                          st.integers(0, 10**12),
                          st.floats(-1e6, 1e6, allow_nan=False)), max_size=80),
       st.sampled_from([200, 1 << 12, 1 << 20]))
def test_fast_message_path_writes_the_same_file_as_mcaps_add_message(tmp_path_factory,
                                                                      items, chunk_size):
    """`fast_message_writer` relies on mcap's Writer internals: the file must be byte for
    byte the one Writer.add_message writes (statistics, chunk time ranges, message indexes,
    records; chunks finished at the same sizes), with log times in any order."""
    d = tmp_path_factory.mktemp('fast')
    assert McapRecorder(d / 'probe.mcap')._add is not None     # the fast path is in use
    fast = _record(d / 'fast.mcap', items, True, chunk_size)
    slow = _record(d / 'slow.mcap', items, False, chunk_size)
    assert fast == slow


def test_fast_message_path_pinned_example(tmp_path):
    """A pinned case: several chunks, three channels, times out of order, a publish time
    other than the log time."""
    items = [('/a', 5, 1.0), ('/b', 3, -2.0), ('/a', 1, 3.0), ('/c', 10**12, 4.0),
             ('/b', 0, -5.0)] * 30
    assert _record(tmp_path / 'f.mcap', items, True, 300) == \
        _record(tmp_path / 's.mcap', items, False, 300)

"""The split layout's per-worker part files and their merge into the run's bag
(`catheter_bringup.local_recording`), read back by rosbags and mcap_ros2."""
import pathlib

import pytest
from rclpy.serialization import serialize_message

from catheter_bringup.local_recording import (PartRecorder, merge_parts, part_path,
                                              read_part, wanted)
from catheter_bringup.recorder import McapRecorder, read_run_metadata

WRENCH = 'geometry_msgs/msg/WrenchStamped'
JOINTS = 'sensor_msgs/msg/JointState'


def _wrench(fx):
    from geometry_msgs.msg import WrenchStamped
    m = WrenchStamped()
    m.wrench.force.x = float(fx)
    return m


def _joints(x):
    from sensor_msgs.msg import JointState
    m = JointState()
    m.name = ['a', 'b']
    m.position = [float(x), 2.0]     # a sequence: serialize_message pads the bytes
    return m


def _part(path, topics, times, proc='w'):
    """A part with one message per (topic, time); values = index."""
    rec = PartRecorder(path, proc, chunk_size=512)
    for topic, type_name in topics.items():
        rec.add_topic(topic, type_name, [{'reliability': 'best_effort', 'depth': 10}])
    clock = iter(times)
    rec._clock = lambda: next(clock)
    for i, _t in enumerate(times):
        topic = sorted(topics)[i % len(topics)]
        msg = _wrench(i) if topics[topic] == WRENCH else _joints(i)
        rec.record(topic, serialize_message(msg))
    rec.record('/not/added', b'\x00\x01\x00\x00')      # topics not added are ignored
    return rec


def test_part_path_and_wanted():
    assert part_path('/b/run.mcap', 'master') == '/b/run.master.part.mcap'
    with pytest.raises(ValueError, match='process'):
        part_path('/b/run.mcap', '')
    assert wanted('/a', ['/clock'], None) and not wanted('/clock', ['/clock'], None)
    assert not wanted('/a', [], ['/b']) and wanted('/b', [], ['/b'])


def test_merge_keeps_every_message_in_log_time_order(tmp_path):
    from mcap_ros2.reader import read_ros2_messages
    from rosbags.highlevel import AnyReader
    a, b = str(tmp_path / 'r.master.part.mcap'), str(tmp_path / 'r.slave.part.mcap')
    ra = _part(a, {'/m/force': WRENCH}, [10, 30, 50, 50, 70])
    rb = _part(b, {'/s/joints': JOINTS, '/s/force': WRENCH}, [20, 30, 40, 60, 80, 90])
    ra.close('complete')
    rb.close('interrupted', 'SIGINT')
    assert ra.counts == {'/m/force': 5} and rb.counts == {'/s/force': 3, '/s/joints': 3}
    bag = tmp_path / 'r.mcap'
    out = McapRecorder(bag)
    info = merge_parts(out, {'master': a, 'slave': b})
    out.close('complete')
    assert info['master'] == {'messages': 5, 'complete': True, 'stopped_at': '',
                              'status': 'complete', 'reason': ''}
    assert info['slave']['messages'] == 6 and info['slave']['complete']
    assert not pathlib.Path(a).exists() and not pathlib.Path(b).exists()   # merged: removed
    assert read_run_metadata(bag)['counts'] == \
        '{"/m/force": 5, "/s/force": 3, "/s/joints": 3}'
    times, got = [], []
    with AnyReader([bag]) as reader:        # strict CDR lengths: the padding was cut
        for conn, t, raw in reader.messages():
            reader.deserialize(raw, conn.msgtype)
            times.append(t)
            got.append(conn.topic)
    assert times == sorted(times) == [10, 20, 30, 30, 40, 50, 50, 60, 70, 80, 90]
    assert sorted(got) == ['/m/force'] * 5 + ['/s/force'] * 3 + ['/s/joints'] * 3
    # in the file (not re-sorted by a reader): log-time order, ties master's part first
    from mcap.reader import make_reader
    with open(bag, 'rb') as f:
        r = make_reader(f)
        topic = {c.id: c.topic for c in r.get_summary().channels.values()}
        stored = [(m.log_time, topic[m.channel_id])
                  for _s, _c, m in r.iter_messages(log_time_order=False)]
    assert [t for t, _ in stored] == times
    assert stored[2:4] == [(30, '/m/force'), (30, '/s/joints')]
    n = 0
    for m in read_ros2_messages(str(bag)):
        n += 1
        if m.channel.topic == '/s/joints':
            assert list(m.ros_msg.position)[1] == 2.0
    assert n == 11
    # the QoS of the parts reached the bag
    with open(bag, 'rb') as f:
        chans = make_reader(f).get_summary().channels.values()
        assert all('best_effort' in c.metadata['offered_qos_profiles'] for c in chans)


def test_a_killed_workers_part_gives_its_complete_chunks(tmp_path):
    """SIGKILL: the part has no summary and its last chunk may be cut; the merge keeps the
    messages of its complete chunks, in order, and says the part was not complete."""
    path = str(tmp_path / 'k.vision.part.mcap')
    rec = _part(path, {'/v/force': WRENCH}, list(range(100, 300)))
    rec.close('complete')
    whole = pathlib.Path(path).read_bytes()
    _ch, all_msgs, _ = read_part(path)
    assert len(all_msgs) == 200
    cut = pathlib.Path(path)
    cut.write_bytes(whole[:len(whole) // 2])          # killed halfway through the file
    _ch, msgs, info = read_part(path)
    assert not info['complete'] and info['stopped_at']
    assert 0 < len(msgs) < 200
    assert [m[0] for m in msgs] == list(range(100, 100 + len(msgs)))   # a prefix
    bag = tmp_path / 'k.mcap'
    out = McapRecorder(bag)
    res = merge_parts(out, {'vision': path, 'gone': str(tmp_path / 'missing.mcap')})
    out.close('complete')
    assert res['vision']['messages'] == len(msgs) and not res['vision']['complete']
    assert res['gone']['messages'] == 0 and 'error' in res['gone']
    assert out.counts == {'/v/force': len(msgs)}


def test_read_part_refuses_a_file_that_is_not_mcap(tmp_path):
    p = tmp_path / 'x.part.mcap'
    p.write_bytes(b'not an mcap file at all')
    with pytest.raises(ValueError, match='path'):
        read_part(p)


def test_a_part_whose_clock_stepped_back_is_merged_in_log_time_order(tmp_path):
    """The wall clock can step back (NTP); the bag is still in log-time order."""
    a, b = str(tmp_path / 'c.a.part.mcap'), str(tmp_path / 'c.b.part.mcap')
    _part(a, {'/a': WRENCH}, [50, 10, 40]).close('complete')
    _part(b, {'/b': WRENCH}, [30, 20]).close('complete')
    out = McapRecorder(tmp_path / 'c.mcap')
    merge_parts(out, {'a': a, 'b': b})
    out.close('complete')
    from mcap.reader import make_reader
    with open(tmp_path / 'c.mcap', 'rb') as f:
        times = [m.log_time for _s, _c, m in make_reader(f).iter_messages(
            log_time_order=False)]
    assert times == [10, 20, 30, 40, 50]


def test_a_part_counts_refused_payloads_keeps_given_log_times_and_ignores_other_topics(
        tmp_path):
    """A publish with a given log time is recorded at that time; one the recorder refuses
    (a negative log time) is counted in part_errors, not fatal; a topic not added (excluded
    by the run) is neither recorded nor counted as an error."""
    path = tmp_path / 'e.master.part.mcap'
    rec = PartRecorder(path, 'master', chunk_size=512)
    rec.add_topic('/m/force', WRENCH, None)
    rec._clock = lambda: 5_000
    data = serialize_message(_wrench(1.0))
    rec.record('/m/force', data, log_time_ns=123)
    rec.record('/m/force', data)
    rec.record('/m/force', data, log_time_ns=-1)            # refused by the recorder
    rec.record('/excluded', data)
    assert rec.errors == 1 and rec.counts == {'/m/force': 2}
    rec.close('complete')
    assert read_run_metadata(path)['part_errors'] == '1'
    _ch, msgs, _info = read_part(path)
    assert [(t, topic) for t, _seq, topic, _d in msgs] == [(123, '/m/force'), (5_000, '/m/force')]


def test_a_process_name_must_not_leave_the_bags_folder():
    for bad in ('a/b', '../x', '/abs'):
        with pytest.raises(ValueError, match='process'):
            part_path('/b/run.mcap', bad)

"""What the analysis reads back from a recording (catheter_bringup.recording): log times, and
JointState values decoded straight from the CDR bytes, against mcap_ros2's generic decoder of
the same file (an independent reader)."""
import math

import pytest
from rclpy.serialization import serialize_message

from catheter_bringup.recorder import McapRecorder
from catheter_bringup.recording import Recording, load

# names of 1..5 characters and frame ids of 0..4 characters: every CDR alignment of the
# float64 arrays behind them (4 or 8 byte boundary) and of each name string occurs
NAMES = [['a'], ['ab', 'c'], ['insertion', 'rotation'], ['abc', 'de', 'fghij'],
         ['abcd', 'x', 'yz', 'w']]


def _joint_state(k, names):
    from sensor_msgs.msg import JointState
    m = JointState()
    m.header.stamp.sec, m.header.stamp.nanosec = 1, k
    m.header.frame_id = 'f' * (k % 5)
    m.name = names
    m.position = [0.5 * k + i for i in range(len(names))]
    m.velocity = [-0.25 * k - i for i in range(len(names) - k % 2)]   # sometimes shorter
    m.effort = [1e-3 * k] * (k % 3 == 0) * len(names)                   # sometimes empty
    return m


@pytest.fixture(scope='module')
def bag(tmp_path_factory):
    path = tmp_path_factory.mktemp('js') / 'js.mcap'
    rec = McapRecorder(path)
    rec.add_topic('/slave/joint_states', 'sensor_msgs/msg/JointState')
    k = 0
    for names in NAMES:
        for _ in range(5):
            rec.write('/slave/joint_states', serialize_message(_joint_state(k, names)),
                      2_000_000_000 + k * 1_000_000, publish_time_ns=k * 3_000_000 + 11)
            k += 1
    rec.close('complete')
    return path


def test_joint_state_values_match_the_generic_decoder(bag):
    from mcap_ros2.reader import read_ros2_messages
    ref = [m.ros_msg for m in read_ros2_messages(str(bag))]
    got = Recording(bag).values['/slave/joint_states']
    assert len(got) == len(ref) == 5 * len(NAMES)
    for msg, vals in zip(ref, got, strict=True):
        assert list(vals) == list(msg.name)
        for i, name in enumerate(msg.name):
            for arr, v in zip((msg.position, msg.velocity, msg.effort), vals[name], strict=True):
                if i < len(arr):
                    assert v == arr[i], (name, msg.name)
                else:
                    assert math.isnan(v)


def test_times_are_log_times_not_publish_times(bag):
    from mcap.reader import make_reader
    with open(bag, 'rb') as f:
        log = [m.log_time * 1e-9 for _, _, m in make_reader(f).iter_messages()]
    rec = load(bag)
    assert rec.t('/slave/joint_states').tolist() == log
    assert rec.t('/slave/joint_states')[3] == pytest.approx(2.003, abs=1e-12)
    # the header stamp is read from the bytes: 1 s + k ns
    assert rec.stamps('/slave/joint_states')[3] == pytest.approx(1.0 + 3e-9, abs=1e-12)


def test_a_tip_force_estimate_reads_as_its_force_and_stamps_come_from_the_bytes(tmp_path):
    from catheter_interfaces.msg import TipForceEstimate
    from catheter_bringup.recording import _leading_header, raw_stamp
    path = tmp_path / 'tfe.mcap'
    rec = McapRecorder(path)
    rec.add_topic('/force_estimator/estimate', 'catheter_interfaces/msg/TipForceEstimate')
    for k in range(3):
        m = TipForceEstimate()
        m.header.stamp.sec, m.header.stamp.nanosec = 7, 250_000_000 * k
        m.force.x, m.force.y, m.force.z = 0.1 * k, -0.02 * k, 0.0
        m.method = 'svr'
        rec.write('/force_estimator/estimate', serialize_message(m), 1_000_000 * (k + 1))
    rec.close('complete')
    r = Recording(path)
    vals = r.values['/force_estimator/estimate']
    assert [tuple(v) for v in vals] == [(0.1 * k, -0.02 * k, 0.0) for k in range(3)]
    assert r.stamp['/force_estimator/estimate'] == [7.0, 7.25, 7.5]
    assert raw_stamp(b'\x00\x01\x00\x00\x07\x00\x00') is None        # too short for a stamp
    # the header check skips comments, blank lines and constants before the first field
    assert _leading_header('# doc\n\nuint8 OK=0  # a constant\nstd_msgs/Header header\n')
    assert not _leading_header('uint8 A=1\nfloat64 x\nstd_msgs/Header header\n')
    assert not _leading_header('# only comments\n')

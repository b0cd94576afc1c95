"""The true CDR length of a message (catheter_bringup.cdr) against two independent references:
rosbags' serializer (typestore serialize_cdr, its own field definitions) and the bytes a DDS
raw subscription delivers; every message type of the graph, sequences of many lengths."""
import time

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from rclpy.serialization import serialize_message

from catheter_bringup.cdr import cdr_end, exact_cdr, message_class, walker
from catheter_bringup.ros_recording import exact_bytes

from msg_tools import (GRAPH_TYPES, assert_same, message_strategy, sample_message, to_rosbags,
                       typestore_with)

TS = typestore_with(*GRAPH_TYPES)


def _check_against_rosbags(msg, type_name):
    data = serialize_message(msg)
    exact = exact_cdr(data, type(msg))
    reference = bytes(TS.serialize_cdr(to_rosbags(TS, msg, type_name), type_name))
    assert len(exact) == len(reference), (type_name, len(data), len(exact), len(reference))
    assert len(exact) <= len(data)
    back = TS.deserialize_cdr(exact, type_name)      # strict: rejects > 3 trailing bytes
    assert_same(back, msg, type_name)
    # the same bytes up to the alignment padding (rclpy leaves padding uninitialised)
    assert bytes(TS.serialize_cdr(back, type_name)) == reference


@pytest.mark.parametrize('type_name', GRAPH_TYPES)
def test_exact_length_equals_rosbags_serializer(type_name):
    cls = message_class(type_name)

    @settings(max_examples=60, deadline=None)
    @given(message_strategy(cls))
    def check(msg):
        _check_against_rosbags(msg, type_name)
    check()


@settings(max_examples=80, deadline=None)
@given(st.lists(st.text(max_size=9), max_size=30), st.integers(0, 40), st.integers(0, 40),
       st.integers(0, 40))
def test_joint_state_any_sequence_lengths(names, n_pos, n_vel, n_eff):
    from sensor_msgs.msg import JointState
    msg = JointState(name=names, position=[0.5] * n_pos, velocity=[-1.0] * n_vel,
                     effort=[2.0] * n_eff)
    _check_against_rosbags(msg, 'sensor_msgs/msg/JointState')


def test_serialize_message_has_trailing_garbage_that_rosbags_rejects():
    """Why the recorder cuts payloads: the defect of issue 13, pinned."""
    from rosbags.serde import SerdeError
    from sensor_msgs.msg import JointState
    # /slave/impedance before the typed message: names and values in position only
    msg = JointState(name=['m', 'c', 'k', 'offset', 'valid'], position=[0.0, 1.5, 2.0, 0.1, 1.0])
    data = serialize_message(msg)
    assert len(data) > cdr_end(data, JointState) + 3
    with pytest.raises(SerdeError, match='size mismatch'):
        TS.deserialize_cdr(data, 'sensor_msgs/msg/JointState')
    TS.deserialize_cdr(exact_bytes(msg), 'sensor_msgs/msg/JointState')


def test_truncated_or_foreign_bytes_are_refused():
    from sensor_msgs.msg import JointState
    from geometry_msgs.msg import WrenchStamped
    for msg in (JointState(name=['a', 'b'], position=[1.0, 2.0]), WrenchStamped()):
        whole = exact_bytes(msg)          # WrenchStamped ends in doubles: no length to read
        for n in range(len(whole)):
            with pytest.raises(ValueError, match='data'):
                cdr_end(whole[:n], type(msg))
    data = exact_bytes(JointState(name=['a', 'b'], position=[1.0, 2.0]))
    with pytest.raises(ValueError, match='data'):
        cdr_end(b'\x01\x02\x03\x04' + data[4:], JointState)
    with pytest.raises(ValueError, match='data must be bytes'):
        cdr_end('text', JointState)
    with pytest.raises(ValueError, match='cls'):
        walker(dict)
    with pytest.raises(ValueError, match='type_name'):
        message_class('no_such_pkg/msg/Nothing')
    # a huge string length inside the payload is a truncation, not a crash or a hang
    bad = bytearray(data)
    bad[12:16] = (2 ** 31).to_bytes(4, "little")      # frame_id length
    with pytest.raises(ValueError, match='truncated'):
        cdr_end(bytes(bad), JointState)


def test_big_endian_payload_is_walked_too():
    from std_msgs.msg import String
    data = b'\x00\x00\x00\x00' + (4).to_bytes(4, 'big') + b'abc\x00' + b'\xee' * 8
    assert cdr_end(data, String) == 12


@pytest.mark.ros
def test_exact_length_equals_what_dds_delivers(ros):
    """Each graph type published over DDS: the raw subscription's bytes are exactly the
    walked length of rclpy's serialisation of the same message."""
    import random
    from rclpy.qos import QoSProfile, ReliabilityPolicy, HistoryPolicy
    qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE,
                     history=HistoryPolicy.KEEP_ALL)
    node = ros.node('cdr_probe')
    cases = []
    for i, type_name in enumerate(GRAPH_TYPES):
        cls = message_class(type_name)
        rng = random.Random(i)
        msgs = [cls()] + [sample_message(cls, rng) for _ in range(4)]
        got = []
        topic = f'/cdr_probe/t{i}'
        node.create_subscription(cls, topic, got.append, qos, raw=True)
        pub = node.create_publisher(cls, topic, qos)
        cases.append((type_name, cls, msgs, got, pub))
    ros.spin_until(lambda: all(p.get_subscription_count() > 0 for *_, p in cases), 5.0)
    time.sleep(0.2)
    for _, _, msgs, _, pub in cases:
        for m in msgs:
            pub.publish(m)
    assert ros.spin_until(lambda: all(len(g) == len(m) for _, _, m, g, _ in cases), 10.0)
    for type_name, cls, msgs, got, _ in cases:
        for m, raw in zip(msgs, got, strict=True):
            assert len(exact_bytes(m)) == len(raw), type_name
            assert cdr_end(raw, cls) == len(raw), type_name


@pytest.mark.parametrize('type_name', GRAPH_TYPES + ('visualization_msgs/msg/Marker',))
def test_the_generated_end_finds_what_the_walker_finds(type_name):
    """`cdr._generated_end` (what cdr_end tries first): the walker's end on rclpy's bytes
    (estimated-size padding after the message) and on the exact bytes; bytes cut inside the
    message give None (cdr_end then lets the walker say what is wrong), never another
    end."""
    from catheter_bringup.cdr import HEADER, _generated_end
    cls = message_class(type_name)
    end = _generated_end(cls)
    assert end is not None
    w = walker(cls)

    @settings(max_examples=30, deadline=None)
    @given(message_strategy(cls, max_len=5), st.data())
    def check(msg, data):
        raw = serialize_message(msg)
        true = w(raw, 0, True)
        assert end(raw) == true
        assert end(raw[:HEADER + true]) == true
        cut = data.draw(st.integers(HEADER, HEADER + true - 1)) if true else None
        if cut is not None:
            assert end(raw[:cut]) is None
            with pytest.raises(ValueError, match='truncated'):
                cdr_end(raw[:cut], cls)
    check()

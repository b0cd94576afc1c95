"""`cdr_decode.decoder`: the bus's deserialisation of bytes without rclpy. The reference is
rclpy's own ``deserialize_message``: for any message of every type of the graph (hypothesis)
the decoded message equals it field for field and in each value's Python type (array
typecodes, lists, ints, bools), from rclpy's bytes (estimated-size padding after the
message) and from the exact bytes; bytes it cannot read give None (the caller then asks
rclpy), never a wrong message."""
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from catheter_bringup import rclpy_adapter as A
from catheter_bringup.cdr import cdr_end, message_class
from catheter_bringup.cdr_decode import decoder
from msg_tools import GRAPH_TYPES, message_strategy
from test_message_copy import _leaves, _typed


def _same(got, ref):
    assert type(got) is type(ref)
    assert _typed(got) == _typed(ref)
    assert got == ref or 'nan' in _leaves(ref)


@pytest.mark.parametrize('type_name', GRAPH_TYPES)
def test_decoded_equals_rclpys_deserialisation(type_name):
    cls = message_class(type_name)
    dec = decoder(cls)
    ser, de = A.serializer()

    @settings(max_examples=40, deadline=None)
    @given(message_strategy(cls, max_len=5))
    def check(msg):
        data = ser(msg)
        ref = de(data, cls)
        if dec is None:
            return
        _same(dec(data), ref)
        _same(dec(data[:cdr_end(data, cls)]), ref)
    check()


def test_which_types_are_decoded():
    for name in ('geometry_msgs/msg/WrenchStamped', 'sensor_msgs/msg/JointState',
                 'catheter_interfaces/msg/MasterCommand',
                 'catheter_interfaces/msg/ImpedanceModel', 'geometry_msgs/msg/PoseArray',
                 'nav_msgs/msg/Path', 'rosgraph_msgs/msg/Clock'):
        assert decoder(message_class(name)) is not None, name
    # byte sequences, float32, fixed arrays, octet: left to rclpy
    for name in ('sensor_msgs/msg/Image', 'std_msgs/msg/ColorRGBA',
                 'diagnostic_msgs/msg/DiagnosticArray',
                 'visualization_msgs/msg/Marker', 'catheter_interfaces/msg/TipForceEstimate'):
        assert decoder(message_class(name)) is None, name
    with pytest.raises(ValueError, match='cls must be a generated ROS message class'):
        decoder(dict)


@settings(max_examples=60, deadline=None)
@given(st.data())
def test_bytes_it_cannot_read_give_none(data):
    """Cut anywhere inside the message, a corrupted string length, big endian or no CDR
    header: None, never a message (rclpy decides what such bytes are)."""
    from sensor_msgs.msg import JointState
    ser, _de = A.serializer()
    msg = data.draw(message_strategy(JointState, max_len=4))
    raw = ser(msg)
    end = cdr_end(raw, JointState)
    dec = decoder(JointState)
    cut = data.draw(st.integers(0, end - 1))
    assert dec(raw[:cut]) is None
    assert dec(b'\x00\x00' + raw[2:]) is None          # big endian: not read here
    assert dec(b'\x01\x01' + raw[2:]) is None          # not a CDR header
    bad = bytearray(raw)
    bad[12:16] = (len(raw) + 100).to_bytes(4, 'little')   # the frame_id's length
    assert dec(bytes(bad)) is None


def test_pinned_joint_state():
    from sensor_msgs.msg import JointState
    ser, de = A.serializer()
    msg = JointState(name=['m', 'c', 'k', 'offset', 'valid'],
                     position=[0.0, 1.5, 2.0, 0.1, 1.0], velocity=[], effort=[3.5])
    msg.header.frame_id = 'catheter_base'
    msg.header.stamp.sec, msg.header.stamp.nanosec = 12, 345
    _same(decoder(JointState)(ser(msg)), de(ser(msg), JointState))

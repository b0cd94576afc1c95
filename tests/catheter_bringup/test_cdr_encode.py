"""cdr_encode: the generated encoders give CDR that rclpy decodes to the same message, as
long as rclpy's own bytes (cut to the message's true length), equal to them except in
padding (zero here, uninitialised in rclpy's), and is refused (None) for types it does not
cover."""
import pytest
from hypothesis import given, settings
from msg_tools import GRAPH_TYPES, message_strategy
from rclpy.serialization import deserialize_message, serialize_message

from catheter_bringup.cdr import exact_cdr, message_class
from catheter_bringup.cdr_encode import encoder

ENCODED = ('geometry_msgs/msg/WrenchStamped', 'sensor_msgs/msg/JointState',
           'catheter_interfaces/msg/ImpedanceModel', 'catheter_interfaces/msg/MasterCommand',
           'geometry_msgs/msg/PoseArray', 'nav_msgs/msg/Path', 'rosgraph_msgs/msg/Clock',
           'diagnostic_msgs/msg/DiagnosticArray')
#: float32, byte sequences, fixed arrays
NOT_ENCODED = ('sensor_msgs/msg/Image', 'catheter_interfaces/msg/TipForceEstimate',
               'visualization_msgs/msg/Marker', 'geometry_msgs/msg/Point32')


def same_but_padding(ours: bytes, theirs: bytes) -> bool:
    """Equal length; where they differ, ours is a zero padding byte (rclpy's padding bytes
    are uninitialised: the only bytes allowed to differ)."""
    return len(ours) == len(theirs) and all(
        a == b or a == 0 for a, b in zip(ours, theirs, strict=True))


def test_which_types_are_encoded():
    assert set(ENCODED) | set(NOT_ENCODED) >= set(GRAPH_TYPES)
    for name in ENCODED:
        assert encoder(message_class(name)) is not None, name
    for name in NOT_ENCODED:
        assert encoder(message_class(name)) is None, name


@pytest.mark.parametrize('name', ENCODED)
def test_the_bytes_are_rclpys(name):
    cls = message_class(name)
    enc = encoder(cls)

    @settings(max_examples=60, deadline=None)
    @given(message_strategy(cls, max_len=5))
    def check(msg):
        ours = enc(msg)
        theirs = exact_cdr(serialize_message(msg), cls)
        assert same_but_padding(ours, theirs)
        assert exact_cdr(ours, cls) == ours                  # exactly the message's length
        assert repr(deserialize_message(ours, cls)) == repr(deserialize_message(theirs, cls))
    check()


def test_padding_and_alignment_after_strings_and_empty_sequences():
    """Hand-checked bytes: the doubles after a string of each length mod 8 and after an
    empty sequence start at an 8-aligned offset (from the end of the 4-byte header)."""
    from sensor_msgs.msg import JointState
    enc = encoder(JointState)
    for n in range(9):
        js = JointState(name=['x' * n], position=[], velocity=[1.5])
        b = enc(js)
        assert b[:4] == b'\x00\x01\x00\x00'
        # stamp 8 bytes, frame_id '' (4 + 1 bytes), pad to 4, name count, its length + text
        off = 8 + 5 + 3 + 4 + 4 + n + 1
        off += (-off) % 4                       # position: count 0 (no elements, no padding)
        off += 4
        off += (-off) % 4                       # velocity count
        off += 4
        off += (-off) % 8                       # its first double
        import struct
        assert struct.unpack_from('<d', b, 4 + off)[0] == 1.5, n
        assert len(b) == 4 + off + 8 + 4        # effort: an empty sequence's count
        assert repr(deserialize_message(b, JointState)) == repr(js)


def test_values_not_of_their_fields_exact_type_are_left_to_rclpy():
    """An int in a double field (field checks off), an int in a bool field, a numpy float, a
    list where the setter keeps an array: the encoder says None (rclpy's serialiser decides
    what they become, as it always did); the same message with canonical values encodes."""
    import array
    import numpy as np
    from geometry_msgs.msg import WrenchStamped
    from catheter_interfaces.msg import ImpedanceModel
    enc = encoder(WrenchStamped)
    w = WrenchStamped(check_fields=False)
    assert enc(w) is not None
    for bad in (3, np.float64(0.5), True):
        w._wrench._force._y = bad
        assert enc(w) is None, bad
    w._wrench._force._y = 0.5
    w._header._stamp._sec = np.int32(2)
    assert enc(w) is None
    im = ImpedanceModel(check_fields=False)
    enc_im = encoder(ImpedanceModel)
    assert enc_im(im) is not None
    im._valid = 1
    assert enc_im(im) is None
    im._valid = True
    im._s_table = [1.0]
    assert enc_im(im) is None
    im._s_table = array.array('d', [1.0])
    assert enc_im(im) is not None


def test_bad_input_names_the_argument():
    with pytest.raises(ValueError, match='cls'):
        encoder('geometry_msgs/msg/WrenchStamped')

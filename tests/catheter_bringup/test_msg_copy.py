"""msg_copy: the bus's snapshot of a message equals what serialising and deserialising it
gives (field values and their Python types), shares nothing mutable with the original, and
is refused (None) for the types it does not cover."""
import array

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from msg_tools import GRAPH_TYPES, message_strategy
from rclpy.serialization import deserialize_message, serialize_message

from catheter_bringup.cdr import message_class
from catheter_bringup.msg_copy import copier

COPIED = ('geometry_msgs/msg/WrenchStamped', 'sensor_msgs/msg/JointState',
          'catheter_interfaces/msg/ImpedanceModel', 'catheter_interfaces/msg/MasterCommand',
          'geometry_msgs/msg/PoseArray', 'nav_msgs/msg/Path', 'rosgraph_msgs/msg/Clock')
#: float32 (rounded by the serialisation), bytes (octet), byte sequences, fixed arrays (numpy)
NOT_COPIED = ('sensor_msgs/msg/Image', 'catheter_interfaces/msg/TipForceEstimate',
              'diagnostic_msgs/msg/DiagnosticArray',
              'visualization_msgs/msg/Marker', 'geometry_msgs/msg/Point32')


def shape(x):
    """A message as nested (type name, value) pairs: equal shapes = equal values of equal
    Python types (an int where the round trip gives a float is a difference)."""
    if hasattr(x, 'get_fields_and_field_types'):
        return (type(x).__name__, tuple((f, shape(getattr(x, f)))
                                        for f in x.get_fields_and_field_types()))
    if isinstance(x, array.array):
        return ('array', x.typecode, x.tolist())
    if isinstance(x, list):
        return ('list', tuple(shape(v) for v in x))
    if isinstance(x, float) and x != x:
        return ('float', 'nan')
    return (type(x).__name__, x)


def round_trip(msg):
    return deserialize_message(serialize_message(msg), type(msg))


def test_which_types_are_copied():
    assert set(COPIED) | set(NOT_COPIED) >= set(GRAPH_TYPES)
    for name in COPIED:
        assert copier(message_class(name)) is not None, name
    for name in NOT_COPIED:
        assert copier(message_class(name)) is None, name


@pytest.mark.parametrize('name', COPIED)
def test_the_copy_is_the_round_trip(name):
    cls = message_class(name)
    cp = copier(cls)

    @settings(max_examples=40, deadline=None)
    @given(message_strategy(cls, max_len=4))
    def check(msg):
        assert shape(cp(msg)) == shape(round_trip(msg))
    check()


def test_values_are_converted_as_the_serialisation_converts_them():
    """What the serialisation accepts besides the canonical types (the bus serialises
    before it copies: anything it refuses never reaches the copy)."""
    from catheter_interfaces.msg import ImpedanceModel
    from sensor_msgs.msg import JointState
    m = ImpedanceModel()
    # without field checks (the default) a node may leave numpy scalars and lists in fields
    m._m, m._s_table = np.float64(2.5), [1.0, np.float64(2.5)]
    m.header.stamp._sec = np.int32(3)
    got = copier(ImpedanceModel)(m)
    assert shape(got) == shape(round_trip(m))
    assert type(got.m) is float and type(got.header.stamp.sec) is int
    assert got.s_table == array.array('d', [1.0, 2.5])
    js = JointState(name=['insertion'], position=[0.1])
    js._effort = [np.float64(0.5)]
    assert shape(copier(JointState)(js)) == shape(round_trip(js))


@given(st.floats(allow_nan=False), st.lists(st.floats(allow_nan=False), max_size=3))
def test_the_copy_shares_nothing_the_publisher_changes_later(x, xs):
    from sensor_msgs.msg import JointState
    js = JointState(name=['a'], position=list(xs))
    js.header.stamp.sec = 5
    cp = copier(JointState)(js)
    before = shape(cp)
    js.position.append(x)          # the publisher fills its reused object in place
    js.name.append('b')
    js.header.stamp.sec = 6
    js.header.frame_id = 'moved'
    assert shape(cp) == before
    assert cp.header is not js.header and cp.position is not js.position


def test_bad_input_names_the_argument():
    with pytest.raises(ValueError, match='cls'):
        copier(42)
    with pytest.raises(ValueError, match='cls'):
        copier(dict)

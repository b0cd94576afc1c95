"""catheter_common.outgoing: a reused message, filled in place, serialises to the same bytes
as one built fresh for each publish (the reference: the message classes and
rclpy.time.Time.to_msg), however many times it is reused; bad input is refused by name and
leaves the message as it was."""
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from rclpy.serialization import serialize_message
from rclpy.time import Time

from catheter_common import messages as M
from catheter_common.outgoing import CommandOut, WrenchOut, set_stamp
from catheter_interfaces.msg import MasterCommand
from geometry_msgs.msg import WrenchStamped

FIN = st.floats(-1e6, 1e6, allow_nan=False)
NS = st.integers(0, 2 ** 62)


def _fresh_wrench(ns, fx, frame):
    w = WrenchStamped()
    w.header.stamp = Time(nanoseconds=ns).to_msg()
    w.header.frame_id = frame
    w.wrench.force.x = fx
    return w


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(NS, FIN), min_size=1, max_size=5))
def test_reused_wrench_serialises_like_a_fresh_one(seq):
    out = WrenchOut('catheter_base')
    for ns, fx in seq:
        assert serialize_message(out.fill(ns, fx)) == serialize_message(
            _fresh_wrench(ns, fx, 'catheter_base'))
    assert out.fill(*seq[0]) is out.msg            # one object, reused


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(NS, FIN, FIN, FIN, FIN), min_size=1, max_size=5))
def test_reused_command_serialises_like_master_command_msg(seq):
    out = CommandOut('catheter_base')
    for ns, x, v, a, r in seq:
        ref = M.master_command_msg(x, v, a, r, Time(nanoseconds=ns).to_msg(), 'catheter_base')
        assert serialize_message(out.fill(ns, x, v, a, r)) == serialize_message(ref)


@pytest.mark.parametrize('ns', [0, 1, 999_999_999, 1_000_000_000, 5_000_000_001, 2 ** 62])
def test_set_stamp_splits_like_rclpy(ns):
    from builtin_interfaces.msg import Time as TimeMsg
    s = TimeMsg()
    set_stamp(s, ns)
    ref = Time(nanoseconds=ns).to_msg()
    assert (s.sec, s.nanosec) == (ref.sec, ref.nanosec)


@pytest.mark.parametrize('ns', [-1, 1.5, True, None, np.int64(5), '5'])
def test_set_stamp_refuses_what_is_not_integer_nanoseconds(ns):
    from builtin_interfaces.msg import Time as TimeMsg
    with pytest.raises(ValueError, match='ns'):
        set_stamp(TimeMsg(), ns)


@pytest.mark.parametrize('field', ['position', 'velocity', 'acceleration', 'rotation'])
@pytest.mark.parametrize('bad', [math.nan, math.inf, -math.inf, 'x', None])
def test_command_refuses_a_bad_value_by_name_and_keeps_the_message(field, bad):
    out = CommandOut('catheter_base')
    before = serialize_message(out.fill(7, 0.1, 0.2, 0.3, 0.4))
    vals = dict(position=0.5, velocity=0.6, acceleration=0.7, rotation=0.8)
    vals[field] = bad
    with pytest.raises(ValueError, match=field):
        out.fill(8, **vals)
    assert serialize_message(out.msg) == before


def test_frame_id_must_be_a_string():
    for cls in (WrenchOut, CommandOut):
        with pytest.raises(ValueError, match='frame_id'):
            cls(3)


@pytest.mark.parametrize('field', ['position', 'velocity', 'acceleration', 'rotation'])
@pytest.mark.parametrize('bad', [math.nan, math.inf, -math.inf])
def test_master_command_values_names_every_non_finite_field(field, bad):
    """The fast path for float fields still refuses each field that is not finite."""
    msg = MasterCommand(position=0.1, velocity=0.2, acceleration=0.3, rotation=0.4)
    setattr(msg, field, bad)
    with pytest.raises(ValueError, match=f'msg.{field}'):
        M.master_command_values(msg)


def test_master_command_values_gives_plain_floats():
    msg = MasterCommand(position=0.1, velocity=-0.2, acceleration=0.0, rotation=3.0)
    got = M.master_command_values(msg)
    assert got == (0.1, -0.2, 0.0, 3.0) and all(type(v) is float for v in got)

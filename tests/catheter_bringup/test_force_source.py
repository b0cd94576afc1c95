"""`force_source_node`: the identifier's joint state with the insertion effort replaced by
the latest image-based tip force (component, sign, age limit); bad inputs are dropped."""
import math

import pytest
from geometry_msgs.msg import WrenchStamped
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState

from catheter_bringup.force_source_node import ForceSourceNode


@pytest.fixture
def make():
    from catheter_common.ros_testing import RosHarness
    h = RosHarness()
    made = []

    def build(**params):
        node = h.add(ForceSourceNode(context=h.context, parameter_overrides=[
            Parameter(k, value=v) for k, v in params.items()]))
        node.sent = []
        node.pub.publish = node.sent.append            # what it publishes, in order
        made.append(node)
        return node
    yield build
    h.close()


def _wrench(fx, fy, sec, nanosec=0):
    m = WrenchStamped()
    m.wrench.force.x, m.wrench.force.y = fx, fy
    m.header.stamp.sec, m.header.stamp.nanosec = sec, nanosec
    return m


def _state(effort, sec, nanosec=0):
    m = JointState()
    m.name = ['insertion', 'rotation']
    m.position, m.velocity, m.effort = [0.03, 0.1], [0.0, 0.0], [effort, 0.7]
    m.header.stamp.sec, m.header.stamp.nanosec = sec, nanosec
    return m


@pytest.mark.parametrize('component,sign,want', [
    ('magnitude', 1.0, 0.5), ('x', 1.0, 0.3), ('y', 1.0, -0.4), ('x', -1.0, -0.3)])
def test_the_insertion_effort_is_the_chosen_component_with_its_sign(make, component, sign,
                                                                   want):
    node = make(component=component, sign=sign)
    node._on_wrench(_wrench(0.3, -0.4, 10))
    node._on_state(_state(9.0, 10, 100_000_000))
    out = node.sent[-1]
    assert out.effort[0] == pytest.approx(want) and out.effort[1] == 0.7
    assert list(out.position) == [0.03, 0.1] and out.name == ['insertion', 'rotation']


def test_an_estimate_older_than_max_age_is_not_used(make):
    node = make(max_age=0.2)
    node._on_wrench(_wrench(0.3, 0.4, 10, 900_000_000))      # t = 10.9 s
    node._on_state(_state(9.0, 11, 50_000_000))               # 0.15 s later: used
    node._on_state(_state(9.0, 11, 150_000_000))              # 0.25 s later: load cell
    assert [m.effort[0] for m in node.sent] == [pytest.approx(0.5), 9.0]
    node._on_state(_state(8.0, 100))                          # much later: load cell
    assert node.sent[-1].effort[0] == 8.0


def test_a_joint_state_with_a_nan_is_dropped(make):
    node = make()
    node._on_wrench(_wrench(0.3, 0.4, 10))
    for bad in ('position', 'velocity', 'effort'):
        m = _state(1.0, 10)
        getattr(m, bad)[0] = math.nan
        setattr(m, bad, list(getattr(m, bad)))
        node._on_state(m)
    assert node.sent == []
    node._on_wrench(_wrench(math.nan, 0.0, 11))               # a NaN estimate is not taken
    node._on_state(_state(1.0, 10))
    assert node.sent[-1].effort[0] == pytest.approx(0.5)

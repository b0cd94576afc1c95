"""ima_master_node's promises the renderer tests cannot see (module doc): the published force
is finite and within +-limit whatever the renderer returns (both signs); ima_thesis renders
only the linear part of a model and switches at once; a model re-sent unchanged keeps the
renderer fresh; the settings of mode ima are refused in the other modes."""
import math

import pytest
from geometry_msgs.msg import WrenchStamped
from rclpy.parameter import Parameter

from catheter_bringup.rclpy_adapter import intercept_publish
from catheter_common.messages import impedance_msg, master_command_msg
from catheter_common.qos import QOS_FAST
from catheter_common.topics import MASTER_RENDERED_FORCE
from impedance_master.ima_master_node import ImaMasterNode
from impedance_master.impedance import Impedance

pytestmark = pytest.mark.ros


def node_and_output(ros, probe, **params):
    node = ros.add(ImaMasterNode(context=ros.context, parameter_overrides=[
        Parameter(k, value=v) for k, v in params.items()]))
    ros.node(probe).create_subscription(WrenchStamped, MASTER_RENDERED_FORCE, lambda m: None,
                                        QOS_FAST)
    assert ros.spin_until(lambda: node.pub.get_subscription_count() > 0, 10.0)
    out = []
    intercept_publish(node.pub, lambda m: out.append(m.wrench.force.x))
    return node, out


class Returns:
    """A renderer stand-in that returns a fixed force."""

    def __init__(self, f):
        self.f = f

    def desired_force(self, *state):
        return self.f


def test_the_output_is_finite_and_within_the_limit_of_either_sign(ros):
    node, out = node_and_output(ros, 'probe_safe', mode='dfr', limit=0.5)
    for f, want in ((-3.0, -0.5), (3.0, 0.5), (-0.25, -0.25), (math.nan, 0.0),
                    (-math.inf, 0.0)):
        node.renderer = Returns(f)
        node._render()
        assert out[-1] == want, f
    assert node.diag.get('clamped_outputs') == 2 and node.diag.get('nonfinite_outputs') == 2


def table_model():
    """0.1 x'' + 2 x' + 5 x + 0.01 N plus a static table force S of 0.3 N everywhere."""
    n = 5
    return Impedance(0.1, 2.0, 5.0, 0.01, x0=0.0, dx=0.02, S=[0.3] * n, F=[0.0] * n,
                     B=[0.0] * n, C=[0.0] * n)


def test_ima_thesis_renders_the_linear_part_of_a_table_model_at_once(ros):
    node, out = node_and_output(ros, 'probe_thesis', mode='ima_thesis')
    node._on_command(master_command_msg(0.03, 0.0, 0.0))
    first = Impedance(0.0, 0.0, 10.0, 0.0)                    # 0.3 N at 30 mm
    node._on_impedance(impedance_msg(first))
    node._render()
    assert out[-1] == pytest.approx(0.3)
    imp = table_model()
    assert imp.force(0.03, 0.0, 0.0) != pytest.approx(0.16, abs=0.01)   # the table counts
    node._on_impedance(impedance_msg(imp))
    node._render()                                # the first tick after: no blending
    assert out[-1] == pytest.approx(5.0 * 0.03 + 0.01)         # k x + offset = 0.16 N


def test_a_model_re_sent_unchanged_keeps_the_renderer_fresh(ros):
    """stale_after 0.1 s at 1 kHz: 300 ticks with the same model re-sent every tick stay
    'ok'; 300 ticks without it are 'held' (a link outage)."""
    node, out = node_and_output(ros, 'probe_fresh', mode='ima', rate=1000.0,
                                stale_after=0.1)
    node._on_command(master_command_msg(0.03, 0.0, 0.0))
    msg = impedance_msg(Impedance(0.0, 0.0, 10.0, 0.0))
    for _ in range(300):
        node._on_impedance(msg)
        node._render()
    assert node.diag.get('models_unchanged') == 299
    assert node.renderer.status().state == 'ok'
    for _ in range(300):
        node._render()
    assert node.renderer.status().state == 'held'


@pytest.mark.parametrize('mode', ['dfr', 'ima_thesis'])
def test_settings_of_mode_ima_are_refused_in_the_other_modes(ros, mode):
    node, _ = node_and_output(ros, 'probe_modes_' + mode, mode=mode)
    for name, value in (('blend_time', 0.2), ('max_rate', 5.0), ('passivity', False),
                        ('fallback_time', 1.0)):
        before = node.get_parameter(name).value
        res = node.set_parameters([Parameter(name, value=value)])[0]
        assert not res.successful and 'mode ima' in res.reason, (name, res.reason)
        assert node.get_parameter(name).value == before

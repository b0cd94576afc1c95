"""The whole teleoperation graph in one process: sim_slave_node -> impedance_identifier_node
-> sim_haptic_node (link) -> ima_master_node -> sim_haptic_node, at a reduced rate (200 Hz)
so the test stays light on shared cores."""
import numpy as np
import pytest
from geometry_msgs.msg import WrenchStamped
from rclpy.parameter import Parameter

from catheter_common.topics import SLAVE_FORCE
from catheter_common.qos import QOS_FAST
from impedance_master.ima_master_node import ImaMasterNode
from impedance_master.impedance_identifier_node import ImpedanceIdentifierNode
from impedance_master.sim_haptic_node import MASTER_HAND_FORCE, SimHapticNode

sim_slave_node = pytest.importorskip('sim_slave.sim_slave_node')

pytestmark = pytest.mark.ros
RATE = 200.0


def params(**kw):
    return [Parameter(k, value=v) for k, v in kw.items()]


@pytest.mark.parametrize('mode', ['ima', 'dfr'])
def test_closed_loop_renders_the_slave_force_at_the_hand(ros, mode):
    link = {'link.delay': 0.05, 'link.outages': [0.0, 0.0]}
    slave = sim_slave_node.NODE_CLASS(context=ros.context,
                                      parameter_overrides=params(rate=RATE, **link))
    ident = ImpedanceIdentifierNode(context=ros.context, parameter_overrides=params(
        rate=RATE, window=0.5, publish_rate=50.0))
    haptic = SimHapticNode(context=ros.context, parameter_overrides=params(rate=RATE, **link))
    master = ImaMasterNode(context=ros.context, parameter_overrides=params(mode=mode, rate=RATE))
    ros.add(slave, ident, haptic, master)
    probe = ros.node('probe_graph_' + mode)
    hand, slave_f = [], []
    probe.create_subscription(WrenchStamped, MASTER_HAND_FORCE,
                              lambda m: hand.append(m.wrench.force.x), QOS_FAST)
    probe.create_subscription(WrenchStamped, SLAVE_FORCE,
                              lambda m: slave_f.append(m.wrench.force.x), QOS_FAST)
    # the script inserts to 56 mm in the first 2.3 s (about 0.35 N at the slave); under load
    # the slave's timer lags the master's script (0.175 N at the slave when the script passed
    # 2.3 s, once, at load 8), so spin until the forces rose or the script is well past it
    def risen():
        return max(slave_f, default=0.0) > 0.2 and max(hand, default=0.0) > 0.15

    assert ros.spin_until(lambda: haptic.run.t_last is not None and haptic.run.t_last > 2.3, 60.0)
    ros.spin_until(lambda: risen() or haptic.run.t_last > 4.0, 60.0)
    assert max(slave_f) > 0.2, f'slave force never rose: largest {max(slave_f):.3f} N'
    assert max(hand) > 0.15, f'hand force never rose: largest {max(hand):.3f} N, last {hand[-5:]}'
    if mode == 'ima':
        assert master.renderer.model is not None and master.renderer.model.kind == 1
        assert ident.diag.get('published') > 0
    assert np.all(np.abs(hand) <= 2.5)

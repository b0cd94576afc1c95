"""The link topics between master and slave keep every sample through a stalled receiver
(QOS_LINK, keep last 1000): the split layout's master process once stalled 11.7 ms and its
keep-last-10 subscription to /slave/force lost one sample, DDS reporting none lost, and with
keep last 100 a 117 ms stall of the machine lost two (catheter_common.qos). Here a receiver
that is not spun while 300 samples (300 ms at 1 kHz) are published takes all 300
afterwards; a QOS_FAST subscription beside it, the control, keeps at most its 10 newest (so
this test can tell the two apart)."""
import pytest
from geometry_msgs.msg import WrenchStamped
from rclpy.qos import QoSHistoryPolicy, QoSReliabilityPolicy

from catheter_common import qos as Q

pytestmark = pytest.mark.ros

BURST = 300


def test_link_profile_is_a_deeper_fast_profile():
    assert Q.QOS_LINK.history == QoSHistoryPolicy.KEEP_LAST and Q.QOS_LINK.depth >= 1000
    assert Q.QOS_LINK.reliability == Q.QOS_FAST.reliability == QoSReliabilityPolicy.BEST_EFFORT
    assert Q.QOS_LINK.durability == Q.QOS_FAST.durability


def test_a_stalled_link_receiver_takes_every_sample_sent(ros):
    pub_node = ros.node('link_sender')
    sub_node = ros.node('link_receiver')
    pub = pub_node.create_publisher(WrenchStamped, '/test/link_burst', Q.QOS_FAST)
    got_link, got_fast = [], []
    sub_node.create_subscription(WrenchStamped, '/test/link_burst',
                                 lambda m: got_link.append(m.wrench.force.x), Q.QOS_LINK)
    sub_node.create_subscription(WrenchStamped, '/test/link_burst',
                                 lambda m: got_fast.append(m.wrench.force.x), Q.QOS_FAST)
    assert ros.spin_until(lambda: pub.get_subscription_count() >= 2, timeout=10.0)
    ros.spin_for(0.2)                      # discovery settled both ways
    msg = WrenchStamped()
    for i in range(BURST):                 # the receiver is not spun: a stalled process
        msg.wrench.force.x = float(i)
        pub.publish(msg)
    ros.spin_until(lambda: len(got_link) >= BURST, timeout=5.0)
    ros.spin_for(0.2)
    assert got_link == [float(i) for i in range(BURST)]
    assert 1 <= len(got_fast) <= Q.QOS_FAST.depth
    assert got_fast[-1] == float(BURST - 1)     # the newest kept, the oldest dropped


def test_the_link_subscriptions_use_the_link_profile(ros):
    from impedance_master.sim_haptic_node import SimHapticNode
    from sim_slave.sim_slave_node import SimSlaveNode
    haptic = ros.add(SimHapticNode(context=ros.context))
    slave = ros.add(SimSlaveNode(context=ros.context))
    for sub in (haptic.sub_impedance, haptic.sub_slave_force, slave.sub):
        assert sub.qos_profile.depth == Q.QOS_LINK.depth, sub.topic_name
        assert sub.qos_profile.reliability == QoSReliabilityPolicy.BEST_EFFORT

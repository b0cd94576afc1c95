"""The camera's input in a busy process (the split layout's vision process, or any deployment
over DDS): it takes the robot's newest joint state, keep-last 1 (no backlog of stale samples
to take and deserialise). (shape_node keeps its keep-last-5 frames and drops stale ones
itself, counted: a keep-last-1 subscription would drop them in DDS uncounted, and the
publisher's sequence numbers in the message info, which could count them, crash rclpy 7.1's
EventsExecutor: 'SystemError: null argument to internal routine', seen in
tests/nodes/test_processes.py.)"""
import pytest
from rclpy.qos import QoSHistoryPolicy, QoSReliabilityPolicy

from catheter_common import qos as Q

pytestmark = pytest.mark.ros


def test_latest_profile_is_keep_last_one_best_effort():
    assert Q.QOS_LATEST.history == QoSHistoryPolicy.KEEP_LAST and Q.QOS_LATEST.depth == 1
    assert Q.QOS_LATEST.reliability == QoSReliabilityPolicy.BEST_EFFORT
    # a QOS_FAST (1 kHz) publisher and QOS_SENSOR frames are compatible with it
    assert Q.QOS_FAST.reliability == Q.QOS_LATEST.reliability == Q.QOS_SENSOR.reliability


def test_camera_node_takes_the_newest_joint_state_only(ros):
    pytest.importorskip('sim_slave.camera_node')
    from sim_slave.camera_node import CameraNode
    node = ros.add(CameraNode(context=ros.context))
    assert node.sub.qos_profile.depth == 1
    assert node.sub.qos_profile.reliability == QoSReliabilityPolicy.BEST_EFFORT

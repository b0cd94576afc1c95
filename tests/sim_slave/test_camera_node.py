"""camera_node in-process with a /clock source: frames and the truth follow the joint state."""
import math

import numpy as np
import pytest
from geometry_msgs.msg import WrenchStamped
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Image, JointState

pytest.importorskip('fam_solver')
pytest.importorskip('catheter_shape')

from catheter_common.topics import (CAMERA_IMAGE, CLOCK, FRAME_CAMERA,
                                    SLAVE_JOINT_STATE_DECIMATED)
from catheter_common.qos import QOS_DEFAULT, QOS_FAST, QOS_SENSOR
from sim_slave import VesselParams  # noqa: E402
from sim_slave.camera_node import (CAMERA_TIP_FORCE_TRUTH, MAX_EXTRAPOLATION_S,  # noqa: E402
                                   CameraNode)

pytestmark = pytest.mark.ros


def test_frames_and_truth_follow_the_joint_state(ros, tmp_path):
    bg = tmp_path / 'bg.png'
    node = ros.add(CameraNode(context=ros.context, parameter_overrides=[
        Parameter('use_sim_time', value=True), Parameter('background_file', value=str(bg))]))
    assert bg.exists()
    peer = ros.node('camera_test_peer')
    clock = peer.create_publisher(Clock, CLOCK, QOS_DEFAULT)
    js = peer.create_publisher(JointState, SLAVE_JOINT_STATE_DECIMATED, QOS_FAST)
    images, truth = [], []
    peer.create_subscription(Image, CAMERA_IMAGE, images.append, QOS_SENSOR)
    peer.create_subscription(WrenchStamped, CAMERA_TIP_FORCE_TRUTH, truth.append, QOS_SENSOR)
    assert ros.spin_until(lambda: node.pub_image.get_subscription_count() > 0
                          and node.sub.get_publisher_count() > 0
                          and clock.get_subscription_count() > 0, 10.0)
    p = VesselParams()
    x = p.wall_depth + 0.011
    ms = 0
    for k in range(12):
        m = JointState()
        m.position = [x if k >= 3 else 0.01, 0.0]
        m.velocity = [0.0, 0.0]
        js.publish(m)
        ros.spin_until(lambda m=m: node.x == m.position[0], 3.0)
        if k == 6:
            bad = JointState()
            bad.position = [math.nan]
            js.publish(bad)
            ros.spin_until(lambda: node.diag.get('bad_joint_states') == 1, 3.0)
        ms += 34                                     # one 30 Hz period per step
        c = Clock()
        c.clock.sec, c.clock.nanosec = divmod(ms * 1_000_000, 1_000_000_000)
        n = len(images)
        clock.publish(c)
        ros.spin_until(lambda n=n: len(images) > n, 3.0)
    assert len(images) >= 8 and len(truth) >= 8
    img = images[-1]
    assert (img.encoding, img.width, img.height, img.step) == ('mono8', 800, 800, 800)
    assert img.header.frame_id == FRAME_CAMERA
    f = truth[-1].wrench.force
    assert math.hypot(f.x, f.y) == pytest.approx(p.wall_stiffness * 0.011 ** 1.5, rel=1e-9)
    assert truth[0].wrench.force.x == 0.0 and truth[0].wrench.force.y == 0.0
    a = np.frombuffer(bytes(img.data), np.uint8).reshape(800, 800)
    assert a.min() < 100 < a.max()                   # a dark catheter on a bright background
    assert node.diag.get('bad_joint_states') == 1
    # a moving state stamped 7 ms before the next frame: drawn where it is at the frame
    m = _state(x, 0.02, (ms + 34 - 7) * 1_000_000)
    js.publish(m)
    ros.spin_until(lambda: node.xd == 0.02, 3.0)
    ms += 34
    c = Clock()
    c.clock.sec, c.clock.nanosec = divmod(ms * 1_000_000, 1_000_000_000)
    n = len(truth)
    clock.publish(c)
    ros.spin_until(lambda: len(truth) > n, 3.0)
    f = truth[-1].wrench.force
    assert math.hypot(f.x, f.y) == pytest.approx(
        p.wall_stiffness * (0.011 + 0.02 * 0.007) ** 1.5 * (1 + p.wall_damping * 0.02), rel=1e-9)


def _state(x, xd, ns):
    m = JointState()
    m.position, m.velocity = [x, 0.0], [xd, 0.0]
    m.header.stamp.sec, m.header.stamp.nanosec = divmod(ns, 1_000_000_000)
    return m


def test_the_state_is_carried_to_the_frame_stamp_at_its_velocity(ros):
    node = ros.add(CameraNode(context=ros.context, parameter_overrides=[
        Parameter('use_sim_time', value=True)]))
    assert node.state_at(5_000_000_000) == (0.0, 0.0)         # nothing received yet
    node._on_state(_state(0.05, 0.04, 5_000_000_000))
    x, xd = node.state_at(5_007_000_000)                      # 7 ms later: 0.28 mm further
    assert x == pytest.approx(0.05 + 0.04 * 0.007, abs=1e-15) and xd == 0.04
    assert node.state_at(5_000_000_000) == (0.05, 0.04)       # at its own stamp: itself
    assert node.state_at(4_990_000_000) == (0.05, 0.04)       # a frame before it: not back
    # a stale state is carried MAX_EXTRAPOLATION_S, no farther
    x, _ = node.state_at(6_000_000_000)
    assert x == pytest.approx(0.05 + 0.04 * MAX_EXTRAPOLATION_S, abs=1e-15)

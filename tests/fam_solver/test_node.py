"""fam_solver_node in-process: load in, Path and Marker out; lazy; robust to bad input."""
import math
import os

import numpy as np
import pytest
from geometry_msgs.msg import WrenchStamped
from nav_msgs.msg import Path
from visualization_msgs.msg import Marker

from catheter_common.topics import FAM_SHAPE, FAM_SHAPE_MARKER, TIP_LOAD, resolve
from catheter_common.qos import QOS_DEFAULT
from fam_solver import Catheter, Loads, solve_fam
from fam_solver.fam_solver_node import FamSolverNode
from node_msgs import wrench as _wrench

pytestmark = pytest.mark.ros


# The node runs in a per-process namespace (its topic names are relative): other test
# processes on this machine may share the ROS domain and subscribe to the shape topic, which
# would make "no subscriber" untrue.
NS = f'/fam_test_{os.getpid()}'
LOAD_T, SHAPE_T, MARKER_T = (resolve(t, NS) for t in (TIP_LOAD, FAM_SHAPE, FAM_SHAPE_MARKER))


def _setup(ros, **params):
    from rclpy.parameter import Parameter
    overrides = [Parameter(k, value=v) for k, v in params.items()]
    node = ros.add(FamSolverNode(context=ros.context, parameter_overrides=overrides,
                                 namespace=NS))
    client = ros.node('fam_test_client')
    pub = client.create_publisher(WrenchStamped, LOAD_T, QOS_DEFAULT)
    return node, client, pub


def test_publishes_path_and_marker(ros):
    node, client, pub = _setup(ros, path_points=21)
    paths, markers = [], []
    client.create_subscription(Path, SHAPE_T, paths.append, QOS_DEFAULT)
    client.create_subscription(Marker, MARKER_T, markers.append, QOS_DEFAULT)
    assert ros.spin_until(lambda: pub.get_subscription_count() > 0 and node._listeners() >= 2, 10)
    pub.publish(_wrench(0.05, 0.2, 1e-4))
    assert ros.spin_until(lambda: paths and markers, 10)
    p = paths[-1]
    assert p.header.frame_id == 'catheter_base' and p.header.stamp.sec == 7
    assert len(p.poses) == 21 and len(markers[-1].points) == 21
    assert markers[-1].type == Marker.LINE_STRIP
    ref = solve_fam(Catheter(0.065, 6e-5), Loads(tip_force=(0.05, 0.2), tip_moment=1e-4), n_arcs=12)
    tip = p.poses[-1].pose
    assert abs(tip.position.x - ref.tip[0]) < 1e-12 and abs(tip.position.y - ref.tip[1]) < 1e-12
    ang = 2 * math.atan2(tip.orientation.z, tip.orientation.w)
    assert abs(ang - ref.tip_angle) < 1e-9
    # unchanged load: no new solve
    n = node.diag.get('solves')
    pub.publish(_wrench(0.05, 0.2, 1e-4))
    ros.spin_until(lambda: node.diag.get('unchanged_loads') > 0, 5)
    assert node.diag.get('solves') == n


def test_spacing_parameter_graded(ros):
    node, client, pub = _setup(ros, path_points=5, spacing='graded')
    paths = []
    client.create_subscription(Path, SHAPE_T, paths.append, QOS_DEFAULT)
    assert ros.spin_until(lambda: pub.get_subscription_count() > 0 and node._listeners() >= 1, 10)
    pub.publish(_wrench(0.0, 0.3, 0.0))
    assert ros.spin_until(lambda: paths, 10)
    ld = Loads(tip_force=(0.0, 0.3))
    uni = solve_fam(Catheter(0.065, 6e-5), ld, spacing='uniform')
    gra = solve_fam(Catheter(0.065, 6e-5), ld, spacing='graded')
    tip = paths[-1].poses[-1].pose.position
    assert abs(tip.x - gra.tip[0]) < 1e-12 and abs(tip.y - gra.tip[1]) < 1e-12
    assert np.max(np.abs(uni.tip - gra.tip)) > 1e-7          # the two spacings differ (7.5e-7 m)


def test_no_solve_without_subscribers_then_solves_when_one_appears(ros):
    node, client, pub = _setup(ros)
    assert ros.spin_until(lambda: pub.get_subscription_count() > 0, 10)
    pub.publish(_wrench(0.0, 0.1))
    assert ros.spin_until(lambda: node.diag.get('loads_received') > 0, 10)
    ros.spin_for(0.3)
    assert node.diag.get('solves') == 0
    paths = []
    client.create_subscription(Path, SHAPE_T, paths.append, QOS_DEFAULT)
    assert ros.spin_until(lambda: paths, 10)
    assert node.diag.get('solves') == 1


def test_bad_wrench_is_counted_and_node_keeps_running(ros):
    node, client, pub = _setup(ros)
    paths = []
    client.create_subscription(Path, SHAPE_T, paths.append, QOS_DEFAULT)
    assert ros.spin_until(lambda: pub.get_subscription_count() > 0 and node._listeners() > 0, 10)
    pub.publish(_wrench(float('nan'), 0.1))
    assert ros.spin_until(lambda: node.diag.get('bad_messages') == 1, 10)
    assert not paths
    pub.publish(_wrench(0.0, 0.1))
    assert ros.spin_until(lambda: paths, 10)
    assert np.isfinite(paths[-1].poses[-1].pose.position.y)

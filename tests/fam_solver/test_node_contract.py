"""fam_solver_node's promises (module doc) beyond the shape itself: loads beyond max_force
(magnitude) or max_moment are refused as bad messages; follower:=true turns the force with
the tip, also when changed at run time; a parameter change re-solves the last load; a load
without a stamp gets the node clock's; line_width reaches the marker."""
import os

import pytest
from nav_msgs.msg import Path
from rclpy.parameter import Parameter

from catheter_bringup.rclpy_adapter import intercept_publish
from catheter_common.qos import QOS_DEFAULT
from catheter_common.topics import FAM_SHAPE, resolve
from fam_solver import Catheter, Loads, solve_fam
from fam_solver.fam_solver_node import FamSolverNode
from node_msgs import wrench

pytestmark = pytest.mark.ros

NS = f'/fam_contract_{os.getpid()}'


def node_and_paths(ros, probe, **params):
    node = ros.add(FamSolverNode(context=ros.context, namespace=NS, parameter_overrides=[
        Parameter(k, value=v) for k, v in params.items()]))
    ros.node(probe).create_subscription(Path, resolve(FAM_SHAPE, NS), lambda m: None,
                                        QOS_DEFAULT)
    assert ros.spin_until(lambda: node._listeners() > 0, 10.0)
    paths, markers = [], []
    intercept_publish(node.path_pub, paths.append)
    intercept_publish(node.marker_pub, markers.append)
    return node, paths, markers


def tip(path):
    p = path.poses[-1].pose.position
    return p.x, p.y


def ref_tip(fx, fy, follower=False, length=0.065):
    s = solve_fam(Catheter(length, 6e-5), Loads(tip_force=(fx, fy), follower=follower),
                  n_arcs=12)
    return tuple(float(v) for v in s.tip)


def test_loads_beyond_max_force_or_max_moment_are_refused(ros):
    node, paths, _ = node_and_paths(ros, 'probe_max', max_force=0.5, max_moment=0.002)
    for bad in (wrench(0.6, 0.0), wrench(0.4, 0.4), wrench(0.0, 0.1, 0.003),
                wrench(0.0, 0.1, -0.003)):
        node._on_load(bad)                   # |(0.4, 0.4)| = 0.57 N: the magnitude counts
    assert node.diag.get('bad_messages') == 4 and node.diag.get('solves') == 0 and not paths
    node._on_load(wrench(0.3, 0.3, 0.001))
    assert node.diag.get('solves') == 1 and len(paths) == 1


def test_follower_loads_turn_with_the_tip_also_after_a_change(ros):
    node, paths, _ = node_and_paths(ros, 'probe_follower', follower=True)
    fixed, follower = ref_tip(0.0, 0.1), ref_tip(0.0, 0.1, follower=True)
    assert abs(fixed[0] - follower[0]) + abs(fixed[1] - follower[1]) > 1e-3
    node._on_load(wrench(0.0, 0.1))
    assert tip(paths[-1]) == pytest.approx(follower, abs=1e-9)
    assert node.set_parameters([Parameter('follower', value=False)])[0].successful
    node._flush()                            # the last load again, now in catheter_base
    assert len(paths) == 2 and tip(paths[-1]) == pytest.approx(fixed, abs=1e-9)


def test_a_parameter_change_re_solves_the_last_load(ros):
    node, paths, _ = node_and_paths(ros, 'probe_resolve')
    node._on_load(wrench(0.0, 0.05, sec=9))
    assert node.set_parameters([Parameter('length', value=0.05)])[0].successful
    node._flush()
    assert len(paths) == 2 and paths[-1].header.stamp.sec == 9
    assert tip(paths[-1]) == pytest.approx(ref_tip(0.0, 0.05, length=0.05), abs=1e-9)


def test_a_load_without_a_stamp_gets_the_node_clocks(ros):
    node, paths, _ = node_and_paths(ros, 'probe_stamp')
    node._on_load(wrench(0.0, 0.05, sec=0))
    s = paths[-1].header.stamp
    assert s.sec > 0 and paths[-1].poses[-1].header.stamp.sec == s.sec


def test_line_width_reaches_the_marker(ros):
    node, _, markers = node_and_paths(ros, 'probe_width', line_width=0.005)
    node._on_load(wrench(0.0, 0.05))
    assert markers[-1].scale.x == 0.005


def test_a_follower_change_applies_to_a_load_still_waiting_for_a_listener(ros):
    """A load that arrived while nobody listened is the last load: solved (when a listener
    appears) with the follower setting in force then, not the one it arrived under."""
    node = ros.add(FamSolverNode(context=ros.context, namespace=NS + '_wait'))
    paths = []
    intercept_publish(node.path_pub, paths.append)
    node._on_load(wrench(0.0, 0.1))
    assert node.diag.get('solves') == 0 and node._pending is not None
    assert node.set_parameters([Parameter('follower', value=True)])[0].successful
    ros.node('probe_wait').create_subscription(Path, resolve(FAM_SHAPE, NS + '_wait'),
                                               lambda m: None, QOS_DEFAULT)
    assert ros.spin_until(lambda: node._listeners() > 0, 10.0)
    node._flush()
    assert len(paths) == 1
    assert tip(paths[-1]) == pytest.approx(ref_tip(0.0, 0.1, follower=True), abs=1e-9)

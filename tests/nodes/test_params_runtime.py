"""Runtime parameter changes on every node (issue 10 item 3): a change of a parameter the node
applies takes effect within one cycle; anything else is refused with a reason (unknown
choices, files that do not load, read-only parameters); no declared parameter is accepted
and then ignored."""
import math

import numpy as np
import pytest
from geometry_msgs.msg import Point, Pose, PoseArray, WrenchStamped
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState

from catheter_bringup.rclpy_adapter import intercept_publish
from catheter_common import topics as T
from catheter_common.qos import QOS_FAST, QOS_SENSOR

from node_cases import NODE_MODULES, make_node

pytestmark = pytest.mark.ros


def set_param(node, name, value):
    return node.set_parameters([Parameter(name, value=value)])[0]


def capture(pub):
    out = []
    intercept_publish(pub, out.append)
    return out


@pytest.mark.parametrize('name', sorted(NODE_MODULES))
def test_every_declared_parameter_is_applied_or_read_only(ros, name):
    node = make_node(ros, name)
    dynamic = {p.name for p in node.PARAMS if p.dynamic}
    names = node.list_parameters([], 0).names
    assert {p.name for p in node.PARAMS} <= set(names)
    for n in names:
        if n in ('use_sim_time',):
            continue
        ro = node.describe_parameter(n).read_only
        assert ro != (n in dynamic), (name, n, ro)
        if ro:
            cur = node.get_parameter(n).value
            res = set_param(node, n, cur if isinstance(cur, str) else cur)
            # even the same value: rclpy refuses any set of a read-only parameter
            assert not res.successful and 'read-only' in res.reason.lower(), (n, res.reason)


REFUSED = [
    ('ima_master_node', 'mode', 'pid'),
    ('ima_master_node', 'limit', math.nan),
    ('ima_master_node', 'limit', 100.0),
    ('force_estimator_node', 'method', 'bogus'),
    ('force_estimator_node', 'svr_model', '/nonexistent.npz'),
    ('force_estimator_node', 'mlp_model', 'blazer-svr'),          # the other kind of model
    ('fam_solver_node', 'arc_model', 'bogus'),
    ('fam_solver_node', 'length', -1.0),
    ('impedance_identifier_node', 'identifier', 'foo'),
    ('sim_haptic_node', 'experiment', 'III'),
    ('sim_slave_node', 'link.outages', [1.0]),
    ('sim_slave_node', 'link.outages', [1.0, -1.0]),
    ('sim_slave_node', 'rate', 5.0),
    ('shape_node', 'psi', [1.0, 2.0]),
    ('shape_node', 'method', 'bogus'),
    ('shape_node', 'background_file', '/nonexistent/background.png'),
    ('camera_node', 'camera.width', 64),
    ('force_source_node', 'sign', 0.5),
]


@pytest.mark.parametrize('name,param,value', REFUSED,
                         ids=[f'{n}-{p}={v}' for n, p, v in REFUSED])
def test_bad_changes_are_refused_with_a_reason(ros, name, param, value):
    node = make_node(ros, name)
    before = node.get_parameter(param).value
    res = set_param(node, param, value)
    assert not res.successful
    assert res.reason, 'a refusal says why'
    after = node.get_parameter(param).value
    assert after == before


def test_limit_applies_to_the_rendered_force_within_one_tick(ros):
    from impedance_master.impedance import Impedance
    node = make_node(ros, 'ima_master_node', mode='ima', blend_time=0.0, max_rate=1e6,
                     passivity=False)
    probe = ros.node('limit_probe')
    probe.create_subscription(WrenchStamped, T.MASTER_RENDERED_FORCE, lambda m: None, QOS_FAST)
    assert ros.spin_until(lambda: node.pub.get_subscription_count() > 0, 10.0)
    out = capture(node.pub)
    cmd = JointState(position=[0.05], velocity=[0.0], effort=[0.0])
    node._on_command(cmd)
    imp = Impedance(0.0, 0.0, 30.0, 0.0)                # 1.5 N at 50 mm
    msg = JointState()
    d = imp.to_fields()
    msg.name, msg.position = list(d), list(d.values())
    node._on_impedance(msg)
    node._render()
    assert out[-1].wrench.force.x == pytest.approx(1.5)
    res = set_param(node, 'limit', 0.5)
    assert res.successful, res.reason
    node._render()                                      # the next tick
    assert out[-1].wrench.force.x == pytest.approx(0.5)
    assert node.get_parameter('limit').value == 0.5
    assert set_param(node, 'limit', 2.0).successful
    node._render()
    assert out[-1].wrench.force.x == pytest.approx(1.5)


def test_limit_set_through_the_parameter_service(ros):
    from rclpy.parameter_client import AsyncParameterClient
    node = make_node(ros, 'ima_master_node', mode='dfr')
    probe = ros.node('param_client_probe')
    client = AsyncParameterClient(probe, node.get_fully_qualified_name())
    assert client.wait_for_services(timeout_sec=10.0)
    fut = client.set_parameters([Parameter('limit', value=0.5),
                                 Parameter('mode', value='ima')])
    assert ros.spin_until(fut.done, 10.0)
    ok, refused = fut.result().results
    assert ok.successful and not refused.successful and refused.reason
    assert node.limit == 0.5 and node.mode == 'dfr'
    node.renderer.set_force(3.0)
    out = capture(node.pub)
    probe.create_subscription(WrenchStamped, T.MASTER_RENDERED_FORCE, lambda m: None, QOS_FAST)
    assert ros.spin_until(lambda: node.pub.get_subscription_count() > 0, 10.0)
    node._render()
    assert out[-1].wrench.force.x == 0.5


def test_method_switches_the_estimator(ros):
    from force_estimator.models import load_estimator
    node = make_node(ros, 'force_estimator_node')
    assert node.estimator.kind == 'svr'
    probe = ros.node('method_probe')
    probe.create_subscription(WrenchStamped, T.TIP_WRENCH, lambda m: None, QOS_SENSOR)
    assert ros.spin_until(lambda: node.pub.get_subscription_count() > 0, 10.0)
    out = capture(node.pub)
    res = set_param(node, 'method', 'mlp')
    assert res.successful, res.reason
    assert node.estimator.kind == 'mlp' and node.diag.value('method') == 'mlp'
    assert node.diag.status().values  # built without error
    assert any(kv.key == 'method' and kv.value == 'mlp' for kv in node.diag.status().values)
    from catheter_shape import fit_bezier
    from fam_solver import Catheter, Loads, solve_fam
    mlp = load_estimator('blazer-mlp')
    cl = solve_fam(Catheter(length=0.065, ei=6e-5), Loads(tip_force=(0.0, 0.05))).centerline(200)
    cp = fit_bezier(np.c_[cl, np.zeros(len(cl))], degree=3)    # a shape of the training domain
    msg = PoseArray()
    msg.header.frame_id = T.FRAME_CATHETER_BASE
    msg.poses = [Pose(position=Point(x=p[0], y=p[1], z=p[2])) for p in cp]
    node._on_points(msg)
    f, inside = mlp.predict(cp, return_flags=True)
    assert inside
    assert out[-1].wrench.force.x == pytest.approx(float(f[0]), abs=1e-12)
    assert out[-1].wrench.force.y == pytest.approx(float(f[1]), abs=1e-12)
    assert set_param(node, 'method', 'fam').successful and node.estimator.__class__.__name__ \
        == 'FamInverseEstimator'


def test_changes_of_the_other_nodes_take_effect(ros):
    slave = make_node(ros, 'sim_slave_node')
    assert set_param(slave, 'link.delay', 0.5).successful
    assert slave.link.config.delay == 0.5
    assert set_param(slave, 'link.outages', [1, 2]).successful        # ints accepted
    assert slave.link.config.outages == ((1.0, 2.0),)
    haptic = make_node(ros, 'sim_haptic_node')
    assert set_param(haptic, 'link.loss', 0.25).successful
    assert haptic.link_imp.config.loss == 0.25 and haptic.link_force.config.loss == 0.25
    ident = make_node(ros, 'impedance_identifier_node')
    assert set_param(ident, 'publish_rate', 100.0).successful
    assert ident.timer.timer_period_ns == 10_000_000
    cam = make_node(ros, 'camera_node')
    assert set_param(cam, 'rate', 10.0).successful
    assert cam.timer.timer_period_ns == 100_000_000
    shape = make_node(ros, 'shape_node')
    old = shape.sensor
    assert set_param(shape, 'threshold', 100).successful
    assert shape.sensor is not old and shape.sensor.threshold == 100
    src = make_node(ros, 'force_source_node')
    assert set_param(src, 'component', 'x').successful and src.component == 'x'
    fam = make_node(ros, 'fam_solver_node')
    assert set_param(fam, 'n_arcs', 24).successful and fam.n_arcs == 24

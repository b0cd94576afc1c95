"""force_estimator_node in-process: control points in, tip wrench out (stamp, frame, value),
bad messages counted while the node keeps running, diagnostics published."""
import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Point, Pose, PoseArray, WrenchStamped
from rclpy.parameter import Parameter

from catheter_common.topics import CONTROL_POINTS, DIAGNOSTICS, FRAME_CATHETER_BASE, TIP_WRENCH
from catheter_common.qos import QOS_DEFAULT, QOS_SENSOR
from force_estimator.force_estimator_node import NODE_CLASS
from force_estimator.models import load_estimator

pytestmark = pytest.mark.ros


def _msg(cp, sec=0, nsec=0, frame=FRAME_CATHETER_BASE):
    m = PoseArray()
    m.header.frame_id = frame
    m.header.stamp.sec = sec
    m.header.stamp.nanosec = nsec
    for p in cp:
        m.poses.append(Pose(position=Point(x=float(p[0]), y=float(p[1]), z=float(p[2]))))
    return m


def _setup(ros, overrides):
    node = NODE_CLASS(context=ros.context, parameter_overrides=overrides)
    ros.add(node)
    client = ros.node('fe_test_client')
    pub = client.create_publisher(PoseArray, CONTROL_POINTS, QOS_SENSOR)
    got, diags = [], []
    client.create_subscription(WrenchStamped, TIP_WRENCH, got.append, QOS_SENSOR)
    client.create_subscription(DiagnosticArray, DIAGNOSTICS, diags.append, QOS_DEFAULT)
    assert ros.spin_until(lambda: pub.get_subscription_count() > 0
                          and node.pub.get_subscription_count() > 0, 10.0)
    return node, pub, got, diags


def far_seen(node):
    return node.diag.get('status_out_of_domain') + node.diag.get('status_out_of_envelope')


def _send_until(ros, pub, msg, got):
    """Publish (best effort) until a wrench with the message's stamp arrived."""
    sec = msg.header.stamp.sec

    def arrived():
        return any(w.header.stamp.sec == sec for w in got)
    for _ in range(50):
        pub.publish(msg)
        if ros.spin_until(arrived, 0.2):
            return True
    return False


@pytest.mark.parametrize('method', ['svr', 'mlp'])
def test_node_estimates_with_stamp_and_frame(ros, toy_models, toy_model_files, method):
    X = toy_models[0]
    node, pub, got, diags = _setup(ros, [
        Parameter('method', value=method), Parameter('fallback', value=False),
        Parameter(f'{method}_model', value=str(toy_model_files[method]))])
    est = load_estimator(toy_model_files[method])
    cp = X[7].reshape(4, 3)
    assert _send_until(ros, pub, _msg(cp, 12, 345), got)
    w = got[-1]
    assert w.header.frame_id == FRAME_CATHETER_BASE
    assert (w.header.stamp.sec, w.header.stamp.nanosec) == (12, 345)
    np.testing.assert_allclose([w.wrench.force.x, w.wrench.force.y], est.predict(cp),
                               rtol=1e-12, atol=1e-15)
    assert w.wrench.force.z == 0.0 and w.wrench.torque.z == 0.0

    # bad messages: wrong count of poses, NaN, wrong frame -> counted, nothing published
    ros.spin_for(0.2)
    n_before = len(got)
    bad_nan = cp.copy()
    bad_nan[3, 1] = np.nan
    for bad in (_msg(cp[:3]), _msg(bad_nan), _msg(cp, frame='camera_optical_frame')):
        pub.publish(bad)
    assert ros.spin_until(lambda: node.diag.get('bad_messages') >= 3, 5.0)
    ros.spin_for(0.1)
    assert len(got) == n_before
    # a far input is flagged out of envelope and NOT published as a normal estimate ...
    far = cp.copy()
    far[3, 1] += 0.2
    for _ in range(50):
        pub.publish(_msg(far, 13, 0))
        if ros.spin_until(lambda: far_seen(node) >= 1, 0.2):
            break
    assert far_seen(node) >= 1 and node.diag.get('withheld') >= 2       # NaN and far
    assert node.diag.level()[0] == 1
    ros.spin_for(0.1)
    assert all(w.header.stamp.sec != 13 for w in got)
    # ... and the node keeps working
    assert _send_until(ros, pub, _msg(cp, 14, 0), got)
    assert ros.spin_until(lambda: any(
        kv.key == 'bad_messages' for d in diags for s in d.status for kv in s.values), 5.0)
    keys = {kv.key for d in diags for s in d.status for kv in s.values}
    assert {'estimates', 'estimates_rate_hz', 'withheld', 'status_ok', 'method'} <= keys


def test_node_rejects_unknown_method(ros):
    with pytest.raises(ValueError, match='method'):
        NODE_CLASS(context=ros.context, parameter_overrides=[Parameter('method', value='knn')])


def test_node_rejects_model_of_wrong_kind(ros, toy_model_files):
    with pytest.raises(ValueError, match='svr_model'):
        NODE_CLASS(context=ros.context, parameter_overrides=[
            Parameter('method', value='svr'),
            Parameter('svr_model', value=str(toy_model_files['mlp']))])


def test_node_defaults_use_the_shipped_svr(ros):
    node = NODE_CLASS(context=ros.context)
    assert node.method == 'svr' and node.estimator.model.name == 'blazer-svr'
    assert node.estimator.fam is not None           # the FAM inversion as fallback


def test_node_fam_method(ros):
    pytest.importorskip('fam_solver')
    from catheter_shape import fit_bezier
    from fam_solver import Catheter, Loads, solve_fam
    node, pub, got, _ = _setup(ros, [Parameter('method', value='fam'),
                                     Parameter('n_arcs', value=12)])
    cl = solve_fam(Catheter(length=0.065, ei=6e-5), Loads(tip_force=(0.0, 0.08)),
                   n_arcs=12).centerline(200)
    cp = fit_bezier(np.c_[cl, np.zeros(len(cl))], degree=3)
    assert _send_until(ros, pub, _msg(cp, 21, 0), got)
    w = [m for m in got if m.header.stamp.sec == 21][0]
    assert abs(w.wrench.force.y - 0.08) < 0.005 and abs(w.wrench.force.x) < 0.005
    assert node.diag.get('estimates') >= 1


def test_node_idles_without_subscribers(ros, toy_models, toy_model_files):
    node = NODE_CLASS(context=ros.context, parameter_overrides=[
        Parameter('svr_model', value=str(toy_model_files['svr']))])
    ros.add(node)
    client = ros.node('fe_idle_client')
    pub = client.create_publisher(PoseArray, CONTROL_POINTS, QOS_SENSOR)
    assert ros.spin_until(lambda: pub.get_subscription_count() > 0, 10.0)
    msg = _msg(toy_models[0][0].reshape(4, 3), 5, 0)
    for _ in range(20):
        pub.publish(msg)
        if ros.spin_until(lambda: node.diag.get('skipped_no_subscriber') > 0, 0.2):
            break
    assert node.diag.get('skipped_no_subscriber') > 0 and node.diag.get('estimates') == 0


def _direct(ros, **params):
    """The node with both outputs captured (callbacks called directly: no DDS)."""
    from catheter_bringup.rclpy_adapter import intercept_publish
    from catheter_interfaces.msg import TipForceEstimate
    from catheter_common.topics import TIP_FORCE
    node = NODE_CLASS(context=ros.context, parameter_overrides=[
        Parameter(k, value=v) for k, v in params.items()])
    ros.add(node)
    client = ros.node('fe_direct_client')
    client.create_subscription(WrenchStamped, TIP_WRENCH, lambda m: None, QOS_SENSOR)
    client.create_subscription(TipForceEstimate, TIP_FORCE, lambda m: None, QOS_SENSOR)
    assert ros.spin_until(lambda: node.pub.get_subscription_count() > 0
                          and node.pub_est.get_subscription_count() > 0, 10.0)
    wrench, typed = [], []
    intercept_publish(node.pub, wrench.append)
    intercept_publish(node.pub_est, typed.append)
    return node, wrench, typed


def test_every_message_gets_a_typed_estimate_and_only_normal_ones_a_wrench(
        ros, toy_models, toy_model_files):
    """Issue 11 / 10 item 4: TipForceEstimate for EVERY input (status, covariance, method,
    domain distance); tip_wrench only for normal estimates, equal to the estimate."""
    from catheter_common.messages import TIP_FORCE_STATUS, tip_force_values
    X = toy_models[0]
    node, wrench, typed = _direct(ros, svr_model=str(toy_model_files['svr']), fallback=False)
    cp = X[7].reshape(4, 3)
    nan = cp.copy()
    nan[2, 0] = np.nan
    far = cp.copy()
    far[3, 1] += 0.2
    cases = [(_msg(cp, 1), 'ok'), (_msg(nan, 2), 'non_finite_input'),
             (_msg(cp[:3], 3), 'out_of_domain'),
             (_msg(cp, 4, frame='camera_optical_frame'), 'out_of_domain'),
             (_msg(far, 5), 'out_of_domain')]
    for msg, _ in cases:
        node._on_points(msg)
    assert len(typed) == len(cases)
    for t, (msg, status) in zip(typed, cases, strict=True):
        v = tip_force_values(t)
        assert t.header.stamp.sec == msg.header.stamp.sec
        assert v['status_name'] == status, (msg.header.stamp.sec, v)
        assert v['covariance'] is not None and v['method'] == 'svr'
        assert np.all(np.isfinite(v['force'])) and v['domain_distance'] >= 0.0
    assert typed[0].status == TIP_FORCE_STATUS['ok'] and typed[0].domain_distance == 0.0
    assert all(t.domain_distance > 0.0 for t in typed[1:])
    assert [w.header.stamp.sec for w in wrench] == [1]          # only the normal one
    assert (wrench[0].wrench.force.x, wrench[0].wrench.force.y) == (typed[0].force.x,
                                                                   typed[0].force.y)
    d = node.diag
    assert d.get('messages') == 5 and d.get('estimates') == 1 and d.get('withheld') == 2
    assert d.get('bad_messages') == 3                     # NaN, 3 poses, wrong frame
    assert d.get('status_ok') == 1 and d.get('status_non_finite_input') == 1


def test_the_fam_fallback_answers_what_the_learned_model_does_not_cover(
        ros, toy_model_files):
    """svr + fallback (the default): a real Blazer shape far outside the toy model's domain
    is answered by the FAM inversion, published with method fam_fallback."""
    from catheter_shape import fit_bezier
    from catheter_common.messages import tip_force_values
    from fam_solver import Catheter, Loads, solve_fam
    node, wrench, typed = _direct(ros, svr_model=str(toy_model_files['svr']), n_arcs=12)
    cl = solve_fam(Catheter(length=0.065, ei=6e-5), Loads(tip_force=(0.0, 0.12)),
                   n_arcs=12).centerline(200)
    node._on_points(_msg(fit_bezier(np.c_[cl, np.zeros(len(cl))], degree=3), 31))
    v = tip_force_values(typed[-1])
    assert node.last.method == 'fam_fallback' and v['method'] == 'fam_fallback'
    assert v['status_name'] in ('ok', 'unobservable_axial')
    assert abs(v['force'][1] - 0.12) < 0.01 and abs(v['force'][0]) < 0.01
    assert wrench and wrench[-1].wrench.force.y == v['force'][1]
    # fallback off at run time: the same input is the toy model's, withheld
    assert node.set_parameters([Parameter('fallback', value=False)])[0].successful
    node._on_points(_msg(fit_bezier(np.c_[cl, np.zeros(len(cl))], degree=3), 32))
    assert node.last.method == 'svr' and not node.last.normal
    assert wrench[-1].header.stamp.sec == 31


def test_an_estimator_that_breaks_its_promises_is_counted_and_the_node_keeps_running(
        ros, toy_models, toy_model_files):
    """The node's last lines: an estimator that raises is a refused message (a typed estimate
    that says so, force 0, no wrench); an estimate that is not a valid message (a NaN force:
    the core promises never to give one) is counted as invalid and published nowhere; the
    next good message is estimated as usual."""
    import copy
    X = toy_models[0]
    node, wrench, typed = _direct(ros, svr_model=str(toy_model_files['svr']), fallback=False)
    real = node.estimator
    good = real.estimate(X[7].reshape(4, 3))

    class Broken:
        def __init__(self):
            self.calls = 0

        def estimate(self, cp):
            self.calls += 1
            if self.calls == 1:
                raise ValueError('control_points must have shape (4, 3)')
            bad = copy.copy(good)
            bad.force = np.array([np.nan, 0.1])
            return bad

    node.estimator = Broken()
    node._on_points(_msg(X[7].reshape(4, 3), 1))
    node._on_points(_msg(X[7].reshape(4, 3), 2))
    assert [t.header.stamp.sec for t in typed] == [1] and wrench == []
    assert (typed[0].force.x, typed[0].force.y) == (0.0, 0.0) and typed[0].status != 0
    d = node.diag
    assert d.get('bad_messages') == 1 and d.get('invalid_estimates') == 1
    node.estimator = real
    node._on_points(_msg(X[7].reshape(4, 3), 3))
    assert [t.header.stamp.sec for t in typed] == [1, 3]
    assert [w.header.stamp.sec for w in wrench] == [3]

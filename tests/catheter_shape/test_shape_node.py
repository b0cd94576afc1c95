"""shape_node in-process: a rendered frame in, 4 control-point poses out (close to the
truth), Path and debug image while subscribed, bad messages counted without stopping."""
import numpy as np
import pytest
from rclpy.parameter import Parameter
from geometry_msgs.msg import PoseArray
from nav_msgs.msg import Path
from sensor_msgs.msg import Image
from diagnostic_msgs.msg import DiagnosticArray

from catheter_common import topics as T

from catheter_common import qos as Q
from catheter_shape import SyntheticCamera, fit_bezier
from catheter_shape.shape_node import (ShapeNode, array_to_image, control_points_to_pose_array,
                                       image_to_array, pose_array_to_control_points,
                                       PathOut, points_to_path)

pytestmark = pytest.mark.ros


def _image(arr, stamp_sec=12, frame='camera_optical_frame'):
    from builtin_interfaces.msg import Time
    return array_to_image(arr, Time(sec=stamp_sec, nanosec=345), frame)


def test_image_conversion_round_trip():
    rng = np.random.default_rng(0)
    g = rng.integers(0, 256, (7, 9), dtype=np.uint8)
    np.testing.assert_array_equal(image_to_array(_image(g)), g)
    bgr = rng.integers(0, 256, (7, 9, 3), dtype=np.uint8)
    msg = _image(bgr)
    assert msg.encoding == 'bgr8'
    np.testing.assert_array_equal(image_to_array(msg), bgr)
    msg.encoding = 'rgb8'
    np.testing.assert_array_equal(image_to_array(msg), bgr[:, :, ::-1])
    # rows padded to a larger step
    m = Image(height=2, width=3, encoding='mono8', step=4, data=bytes([1, 2, 3, 0, 4, 5, 6, 0]))
    np.testing.assert_array_equal(image_to_array(m), [[1, 2, 3], [4, 5, 6]])
    for bad in (Image(height=2, width=3, encoding='16UC1', step=6, data=bytes(12)),
                Image(height=2, width=3, encoding='mono8', step=3, data=bytes(5)),
                Image(height=0, width=3, encoding='mono8', step=3, data=b''),
                Image(height=2, width=3, encoding='mono8', step=2, data=bytes(6))):
        with pytest.raises(ValueError):
            image_to_array(bad)


def test_pose_array_round_trip():
    from builtin_interfaces.msg import Time
    c = np.array([[0, 0, 0], [0.02, 0.001, 0], [0.04, 0.01, 0], [0.055, 0.03, 0.0]])
    msg = control_points_to_pose_array(c, Time(sec=1), 'catheter_base')
    assert msg.header.frame_id == 'catheter_base' and len(msg.poses) == 4
    np.testing.assert_allclose(pose_array_to_control_points(msg), c)
    for i, (a, b) in ((0, (0, 1)), (3, (2, 3))):    # tangents at the ends: the control legs
        q = msg.poses[i].orientation
        t = c[b] - c[a]
        assert q.x == 0 and q.y == 0
        assert 2 * np.arctan2(q.z, q.w) == pytest.approx(np.arctan2(t[1], t[0]))
    with pytest.raises(ValueError):
        control_points_to_pose_array(np.full((4, 3), np.nan), Time(), 'x')
    p = points_to_path(np.zeros((500, 3)), Time(), max_poses=50)
    assert len(p.poses) == 50 and p.header.frame_id == 'catheter_base'


def test_the_reused_path_is_the_built_one_frame_after_frame():
    """PathOut refills one message: after each fill it equals points_to_path's fresh one
    (fewer points than before, more, subsampled), and what was serialised at an earlier
    publish is not changed by a later fill."""
    from builtin_interfaces.msg import Time
    from nav_msgs.msg import Path
    from rclpy.serialization import deserialize_message, serialize_message
    out = PathOut()
    rng = np.random.default_rng(4)
    sent = []
    for k, n in enumerate((450, 3, 100, 101, 40, 450, 1)):
        pts = rng.normal(size=(n, 3))
        st = Time(sec=k, nanosec=7 * k)
        m = out.fill(pts, st, 100)
        assert m == points_to_path(pts, st, max_poses=100)
        sent.append((serialize_message(m), points_to_path(pts, st, max_poses=100)))
    assert all(deserialize_message(b, Path) == ref for b, ref in sent)


def test_node_publishes_control_points_close_to_the_truth(ros, shape_helpers):
    cam = SyntheticCamera(noise=4, seed=2)
    truth = shape_helpers.arc(0.5)
    frame = cam.render(truth)
    node = ros.add(ShapeNode(context=ros.context, parameter_overrides=[
        Parameter('psi', value=[float(x) for x in cam.psi.reshape(-1)]),
        Parameter('base_px', value=[int(round(cam.base_px[0])), int(round(cam.base_px[1]))]),
        Parameter('threshold', value=132)]))
    probe = ros.node('shape_probe')
    got, paths, dbg, diags = [], [], [], []
    probe.create_subscription(PoseArray, T.CONTROL_POINTS, got.append, Q.QOS_SENSOR)
    probe.create_subscription(Path, T.SHAPE, paths.append, Q.QOS_DEFAULT)
    probe.create_subscription(Image, T.SHAPE_DEBUG_IMAGE, dbg.append, Q.QOS_SENSOR)
    probe.create_subscription(DiagnosticArray, T.DIAGNOSTICS, diags.append, Q.QOS_DEFAULT)
    pub = probe.create_publisher(Image, T.CAMERA_IMAGE, Q.QOS_SENSOR)
    assert ros.spin_until(lambda: pub.get_subscription_count() > 0, 10.0)
    assert ros.spin_until(lambda: node.pub_debug.get_subscription_count() > 0, 10.0)

    # a bad encoding first: counted, logged, the node keeps going
    bad = _image(frame.image)
    bad.encoding = '32FC1'
    pub.publish(bad)
    assert ros.spin_until(lambda: node.diag.get('bad_messages') >= 1, 10.0)

    msg = _image(frame.image, stamp_sec=77)

    def publish_until_received():
        pub.publish(msg)
        return len(got) > 0 and len(paths) > 0 and len(dbg) > 0
    ok = False
    for _ in range(50):
        if ros.spin_until(publish_until_received, 0.2):
            ok = True
            break
    assert ok, (len(got), len(paths), len(dbg))
    pa = got[-1]
    assert pa.header.stamp.sec == 77 and pa.header.stamp.nanosec == 345
    assert pa.header.frame_id == T.FRAME_CATHETER_BASE
    assert len(pa.poses) == 4
    cp = pose_array_to_control_points(pa)
    best = fit_bezier(truth)
    np.testing.assert_allclose(cp[:, :2], best, atol=1.5e-3)
    np.testing.assert_allclose(cp[[0, 3], :2], best[[0, 3]], atol=0.5e-3)
    assert paths[-1].header.frame_id == T.FRAME_CATHETER_BASE
    assert 2 <= len(paths[-1].poses) <= 100
    assert dbg[-1].encoding == 'bgr8' and dbg[-1].height == 480
    # a frame with no catheter: counted as a failure, no control points published
    n = len(got)
    pub.publish(_image(cam.background, stamp_sec=90))
    assert ros.spin_until(lambda: node.diag.get('fail_too_short') + node.diag.get(
        'fail_no_catheter') >= 1, 10.0)
    ros.spin_for(0.1)
    assert all(p.header.stamp.sec != 90 for p in got[n:])
    assert node.diag.get('processed') >= 3
    assert ros.spin_until(lambda: len(diags) > 0, 5.0)
    keys = {kv.key for kv in diags[-1].status[0].values}
    assert {'frames', 'processed', 'dropped', 'bad_messages', 'latency_ms'} <= keys


def test_node_drops_frames_instead_of_queueing(ros, shape_helpers):
    cam = SyntheticCamera(noise=0)
    node = ros.add(ShapeNode(context=ros.context, parameter_overrides=[
        Parameter('psi', value=[float(x) for x in cam.psi.reshape(-1)])]))
    img = _image(cam.render(shape_helpers.arc(0.2)).image)
    # nobody listens: frames are not processed
    node._on_image(img)
    node._process()
    assert node.diag.get('idle') == 1 and node.diag.get('processed') == 0
    probe = ros.node('cp_listener')
    probe.create_subscription(PoseArray, T.CONTROL_POINTS, lambda m: None, Q.QOS_SENSOR)
    assert ros.spin_until(lambda: node.pub_cp.get_subscription_count() > 0, 10.0)
    # callbacks without the timer in between: only the newest frame is kept
    for _ in range(5):
        node._on_image(img)
    assert node.diag.get('frames') == 6 and node.diag.get('dropped') == 4
    node._process()
    assert node.diag.get('processed') == 1
    node._process()                                   # nothing pending: nothing done
    assert node.diag.get('processed') == 1


@pytest.mark.parametrize('base', [[51, 240], [51.2, 240.0]])
def test_base_px_accepts_ints_and_doubles(ros, base):
    node = ros.add(ShapeNode(context=ros.context, parameter_overrides=[
        Parameter('base_px', value=base)]))
    np.testing.assert_allclose(node.sensor.base_px, base)


def test_base_constraint_parameter(ros, shape_helpers):
    cam = SyntheticCamera(noise=2)
    node = ros.add(ShapeNode(context=ros.context, parameter_overrides=[
        Parameter('psi', value=[float(x) for x in cam.psi.reshape(-1)]),
        Parameter('base_px', value=list(cam.base_px)),
        Parameter('base_constraint', value='point')]))
    probe = ros.node('cp_listener2')
    probe.create_subscription(PoseArray, T.CONTROL_POINTS, lambda m: None, Q.QOS_SENSOR)
    assert ros.spin_until(lambda: node.pub_cp.get_subscription_count() > 0, 10.0)
    node._on_image(_image(cam.render(shape_helpers.arc(0.4)).image))
    node._process()
    assert node._last_obs.ok
    np.testing.assert_allclose(node._last_obs.control_points[0], 0.0, atol=1e-12)


def test_bad_parameters_are_refused(ros):
    with pytest.raises(ValueError):
        ShapeNode(context=ros.context, parameter_overrides=[Parameter('psi', value=[1.0, 2.0])])


def test_debug_overlay_draws_whatever_the_calibration_gives(shape_helpers):
    """Found by the node fuzz benchmark: a wild calibration or base_px put pixel positions
    of 1e300 (or NaN) into cv2.circle, which raised and stopped the node's timer."""
    import types
    from catheter_shape.shape_node import debug_overlay
    frame = np.full((40, 60), 200, np.uint8)
    obs = types.SimpleNamespace(
        ok=True, mask=None, roi=None, pixels=np.array([[1.0, 2.0], [np.inf, 3.0]]),
        control_points=np.array([[0.0, 0.0, 0.0], [0.02, 0.0, 0.0], [0.04, 0.0, 0.0],
                                 [0.06, 0.0, 0.0]]),
        base_px=(1e300, np.nan), tip_px=(-1e300, 5.0), residual=1e-5,
        timings={'total': 0.001}, status='ok', message='')
    psi = np.array([[1e-150, 0.0, 0.0, 0.0], [0.0, 1e-150, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0]])
    img = debug_overlay(frame, obs, psi)
    assert img.shape == (40, 60, 3) and img.dtype == np.uint8


def test_node_defaults_for_foreign_images_and_plausibility_statuses_counted(ros, shape_helpers):
    """Issue 11: the node's defaults are the flat-field segmentation and the Blazer's length
    (the plausibility check); a frame refused by a check (here a 90 mm curve for a 65 mm
    catheter: length_mismatch) is counted under its status and never published, and
    length := 0 turns the check off."""
    from catheter_bringup.rclpy_adapter import intercept_publish
    from catheter_shape.sensor import CHECK_STATUSES
    cam = SyntheticCamera(noise=2, seed=4)
    node = ros.add(ShapeNode(context=ros.context, parameter_overrides=[
        Parameter('psi', value=[float(x) for x in cam.psi.reshape(-1)]),
        Parameter('base_px', value=[float(cam.base_px[0]), float(cam.base_px[1])])]))
    assert node.sensor.method == 'flatfield' and node.params['length'] == 0.065
    for s in CHECK_STATUSES:
        assert node.diag.get('fail_' + s) == 0          # declared: shown from the start
    probe = ros.node('shape_defaults_probe')
    probe.create_subscription(PoseArray, T.CONTROL_POINTS, lambda m: None, Q.QOS_SENSOR)
    assert ros.spin_until(lambda: node.pub_cp.get_subscription_count() > 0, 10.0)
    out = []
    intercept_publish(node.pub_cp, out.append)

    def process(truth, sec):
        node._on_image(_image(cam.render(truth).image, stamp_sec=sec))
        node._process()
    process(shape_helpers.arc(0.5), 1)
    assert [m.header.stamp.sec for m in out] == [1], node._last_obs.status
    process(shape_helpers.arc(0.5, length=0.09), 2)
    assert node._last_obs.status == 'length_mismatch'
    assert node.diag.get('fail_length_mismatch') == 1
    assert [m.header.stamp.sec for m in out] == [1]
    assert node.set_parameters([Parameter('length', value=0.0)])[0].successful
    process(shape_helpers.arc(0.5, length=0.09), 3)
    assert [m.header.stamp.sec for m in out] == [1, 3], node._last_obs.status


def _stamped(arr, ns):
    from builtin_interfaces.msg import Time
    return array_to_image(arr, Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000),
                          'camera_optical_frame')


def test_process_on_arrival_processes_fresh_frames_in_the_callback(ros, shape_helpers):
    cam = SyntheticCamera(noise=0)
    img = cam.render(shape_helpers.arc(0.2)).image
    node = ros.add(ShapeNode(context=ros.context, parameter_overrides=[
        Parameter('psi', value=[float(x) for x in cam.psi.reshape(-1)]),
        Parameter('base_px', value=list(cam.base_px)),
        Parameter('process_on_arrival', value=True)]))
    probe = ros.node('cp_listener_arrival')
    probe.create_subscription(PoseArray, T.CONTROL_POINTS, lambda m: None, Q.QOS_SENSOR)
    assert ros.spin_until(lambda: node.pub_cp.get_subscription_count() > 0, 10.0)
    now = node.get_clock().now().nanoseconds
    # stamped after the node became idle: processed in the callback, nothing left pending
    node._on_image(_stamped(img, now + 1_000_000))
    assert node.diag.get('processed') == 1 and node._pending is None
    assert node._last_obs.ok
    idle = node._idle_since_ns
    assert idle >= now
    # a frame stamped while the node was busy (before its last processing ended) may have
    # newer frames queued behind it: kept for the timer, which takes the newest
    node._on_image(_stamped(img, idle - 1))
    node._on_image(_stamped(img, idle - 1))
    assert node.diag.get('processed') == 1 and node.diag.get('dropped') == 1
    assert node._pending is not None
    node._process()
    assert node.diag.get('processed') == 2 and node._pending is None
    # a processing that failed still marks the end of the busy time
    before = node._idle_since_ns
    node._on_image(_stamped(np.zeros((4, 4), np.uint8), node._idle_since_ns + 1))
    assert node.diag.get('processed') == 3 and not node._last_obs.ok
    assert node._idle_since_ns >= before
    # off (the default): the callback only keeps the frame
    node.set_parameters([Parameter('process_on_arrival', value=False)])
    node._on_image(_stamped(img, node._idle_since_ns + 10**9))
    assert node._pending is not None and node.diag.get('processed') == 3


def test_process_on_arrival_is_off_by_default(ros):
    node = ros.add(ShapeNode(context=ros.context))
    assert node.params['process_on_arrival'] is False

"""shape_node: camera frames -> catheter control points (PoseArray), centreline (Path) and a
debug overlay. Thin: decodes messages, owns parameters/timers/diagnostics and calls
catheter_shape.ShapeSensor.

Subscribes  camera/image_raw          sensor_msgs/Image (mono8, bgr8, rgb8, bgra8, rgba8)
Publishes   catheter/control_points   geometry_msgs/PoseArray, 4 poses base -> tip, catheter_base,
                                      stamped with the image's stamp
            catheter/shape            nav_msgs/Path (the centreline MEASURED in the image; the
                                      FAM model's is catheter/fam/shape), only while subscribed
            catheter/debug_image      sensor_msgs/Image bgr8 overlay, only while subscribed
            /diagnostics              WARN after frames without a catheter shape and bad images;
                                      fail_<status> counts every refused frame by its status
                                      (catheter_shape.STATUSES, the plausibility checks
                                      outside_frame, tip_out_of_view, bad_tip, base_mismatch,
                                      ambiguous_base, length_mismatch, folded, poor_fit
                                      included): only ok frames are published

Frames are never queued: the callback keeps only the newest frame and a timer on the node
clock (period `period`) processes it; a frame replaced before it was processed counts as
dropped. With `process_on_arrival` the callback processes the frame at once (no wait for
the timer tick) when it was stamped after the previous frame's processing ended: nothing can
be queued behind it then; a frame stamped while the node was busy (a backlog of frames
delivered one after another) is kept for the timer, which takes the newest (the stamp is
compared with this node's clock: a camera whose clock ran ahead of it by more than a frame's
processing time would let a backlog through frame by frame). While nobody
subscribes to any output, frames are not processed (counted 'idle').
Every parameter applies at run time (from the next frame; a background_file that cannot be
read is refused). Topic names are relative (the node's namespace applies).
"""
from __future__ import annotations

import math
from typing import Optional

import cv2
import numpy as np
from geometry_msgs.msg import Pose, PoseArray, PoseStamped
from nav_msgs.msg import Path
from rclpy.node import Node
from rclpy.qos import QoSProfile
from sensor_msgs.msg import Image

from catheter_common import qos as Q
from catheter_common import topics as T
from catheter_common.diagnostics import WARN, Diagnostics
from catheter_common.images import array_to_image, image_to_array  # noqa: F401  (re-exported)
from catheter_common.params import NodeParams, Param, table
from catheter_common.ros_node import node_main, wall_time
from catheter_shape.bezier import bezier_derivative, bezier_eval
from catheter_shape.camera import SYSTEM_CAMERA, system_psi
from catheter_shape import stage_trace
from catheter_shape.segmentation import METHODS
from catheter_shape.sensor import STATUSES, ShapeSensor

#: default calibration: the system camera (catheter_shape.camera.SYSTEM_CAMERA, the one
#: definition sim_slave's camera_node draws with: 800x800, 0.15 mm/px, clamp at (260, 400))
DEFAULT_PSI = [float(x) for x in system_psi().reshape(-1)]
DEFAULT_BASE_PX = [float(b) for b in SYSTEM_CAMERA['base_px']]

PARAMS = table(
    Param('psi', DEFAULT_PSI, 'camera calibration matrix PSI (Eq. 1), 12 numbers row-major '
          '3x4: (x, y, z) [m, catheter_base] = PSI (u, v, 0, 1) [pixels]', numbers=True,
          length=12, dynamic=True),
    Param('threshold', 132, 'grey threshold (8 bit): the catheter is darker than this after '
          'background removal (thesis: 132)', 1, 255, dynamic=True),
    Param('base_px', DEFAULT_BASE_PX, 'pixel (u, v) of the clamp / catheter base (ints or '
          'doubles; default: the system camera\'s, with the default psi); [-1, -1] = unknown '
          '(the base is the centreline end nearest the image border)', numbers=True, length=2,
          dynamic=True),
    Param('background_file', '', 'optional PNG of the scene without the catheter (background '
          'removal)', dynamic=True),
    Param('method', 'flatfield', 'segmentation: flatfield (divisive flat-field, independent of '
          'the illumination; the default), fixed (the thesis: subtractive flat-field and '
          '`threshold`), otsu, adaptive', choices=tuple(METHODS), dynamic=True),
    Param('length', 0.065, 'catheter length from the clamp for the plausibility check, m (a '
          'centreline longer than length * (1 + length_tolerance) is refused as '
          'length_mismatch); 0 = not checked', 0.0, 2.0, dynamic=True),
    Param('length_tolerance', 0.025, 'relative tolerance of the length check', 0.0, 1.0,
          dynamic=True),
    Param('period', 0.005, 'processing timer period, s (node clock): the newest frame is '
          'processed, older unprocessed ones are dropped', 0.001, 1.0, dynamic=True),
    Param('process_on_arrival', False, 'process a frame in its callback, without waiting for '
          'the timer, when it was stamped after the previous frame\'s processing ended (the '
          'real-time workers turn it on; off: the timer processes every frame, as lockstep '
          'needs for its message order)', dynamic=True),
    Param('path_poses', 100, 'largest number of poses in catheter/shape', 2, 10000,
          dynamic=True),
    Param('degree', 3, 'Bezier degree (3: the 4 control points of the thesis; force_estimator '
          'expects 3)', 1, 8, dynamic=True),
    Param('base_constraint', 'none', 'Bezier base constraint (needs base_px): none (thesis), '
          'point (p0 at the clamp), tangent (p0 at the clamp, p1 along +x)',
          choices=('none', 'point', 'tangent'), dynamic=True),
)
_SENSOR_KEYS = {'psi', 'threshold', 'base_px', 'background_file', 'method', 'degree',
                'base_constraint', 'length', 'length_tolerance'}


def _yaw_quaternion(yaw: float):
    return 0.0, 0.0, math.sin(0.5 * yaw), math.cos(0.5 * yaw)


def control_points_to_pose_array(control_points, stamp, frame_id: str = T.FRAME_CATHETER_BASE
                                 ) -> PoseArray:
    """Control points (n+1, 3) m (or (n+1, 2)) -> PoseArray, poses base -> tip.

    Orientation of pose i: rotation about z to the curve's tangent at s = i / n (in the
    catheter_base x-y plane); identity where the tangent vanishes."""
    c = np.asarray(control_points, dtype=float)
    if c.ndim != 2 or c.shape[1] not in (2, 3) or c.shape[0] < 2:
        raise ValueError(f'control_points must be (n+1, 2|3), got {c.shape}')
    if not np.all(np.isfinite(c)):
        raise ValueError('control_points contain non-finite values')
    if c.shape[1] == 2:
        c = np.hstack([c, np.zeros((c.shape[0], 1))])
    n = c.shape[0] - 1
    tang = bezier_eval(bezier_derivative(c, 1), np.linspace(0.0, 1.0, n + 1)) if n >= 2 else \
        np.repeat(bezier_derivative(c, 1), n + 1, axis=0)
    msg = PoseArray()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    for p, t in zip(c, tang, strict=True):
        pose = Pose()
        pose.position.x, pose.position.y, pose.position.z = (float(v) for v in p)
        yaw = math.atan2(t[1], t[0]) if (t[0] ** 2 + t[1] ** 2) > 0 else 0.0
        q = _yaw_quaternion(yaw)
        pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w = q
        msg.poses.append(pose)
    return msg


def pose_array_to_control_points(msg: PoseArray) -> np.ndarray:
    """PoseArray -> control points (len(poses), 3) m, in the message's order (base -> tip)."""
    return np.array([[p.position.x, p.position.y, p.position.z] for p in msg.poses],
                    dtype=float).reshape(-1, 3)


def points_to_path(points, stamp, frame_id: str = T.FRAME_CATHETER_BASE,
                   max_poses: int = 100) -> Path:
    """Points (N, 3) m -> nav_msgs/Path of at most max_poses evenly subsampled poses."""
    p = np.asarray(points, dtype=float).reshape(-1, 3)
    if p.shape[0] > max_poses:
        p = p[np.unique(np.linspace(0, p.shape[0] - 1, max_poses).round().astype(int))]
    msg = Path()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    for q in p:
        ps = PoseStamped()
        ps.header = msg.header
        ps.pose.position.x, ps.pose.position.y, ps.pose.position.z = (float(v) for v in q)
        ps.pose.orientation.w = 1.0
        msg.poses.append(ps)
    return msg


class PathOut:
    """One reused nav_msgs/Path for catheter/shape: the same message as `points_to_path`
    (equal field for field), its PoseStamped objects kept and refilled in place (building
    100 of them per frame cost ~0.65 ms, on the way to the estimator: its control points
    are delivered after shape_node's callback returns; refilled: ~0.05 ms). Safe for the
    reason of `catheter_common.outgoing`: every publish path serialises (or copies) the
    message inside publish(), so nothing holds it afterwards; never hand it to anything
    that keeps it."""

    def __init__(self, frame_id: str = T.FRAME_CATHETER_BASE):
        self.msg = Path()
        self.msg.header.frame_id = frame_id
        self._pool = []

    def fill(self, points, stamp, max_poses: int = 100) -> Path:
        """The message for points (N, 3) m (at most max_poses evenly subsampled poses)."""
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        if p.shape[0] > max_poses:
            p = p[np.unique(np.linspace(0, p.shape[0] - 1, max_poses).round().astype(int))]
        msg = self.msg
        msg.header.stamp = stamp
        header = msg.header                 # every pose's header is the path's (as before)
        pool = self._pool
        while len(pool) < p.shape[0]:
            ps = PoseStamped()
            ps.header = header
            ps.pose.orientation.w = 1.0
            pool.append(ps)
        for ps, (x, y, z) in zip(pool, p.tolist(), strict=False):
            pos = ps.pose.position
            pos.x, pos.y, pos.z = x, y, z
        msg.poses = pool[:p.shape[0]]
        return msg


#: px, drawing coordinates are kept within +-this (OpenCV takes int32 pixel positions; a wild
#: calibration or base_px gives positions far outside the image, or not finite)
_DRAW_LIMIT = 1e6


def _draw_points(pts, shift: int = 0) -> np.ndarray:
    """Pixel positions (n, 2) as the int32 (n, 1, 2) OpenCV draws, scaled by 2**shift, with
    non-finite and far-away positions pulled to the drawing limit."""
    a = np.nan_to_num(np.asarray(pts, dtype=float) * (1 << shift), nan=-_DRAW_LIMIT,
                      posinf=_DRAW_LIMIT, neginf=-_DRAW_LIMIT)
    return np.rint(np.clip(a, -_DRAW_LIMIT, _DRAW_LIMIT)).astype(np.int32).reshape(-1, 1, 2)


def debug_overlay(frame: np.ndarray, obs, psi: np.ndarray) -> np.ndarray:
    """BGR overlay: the catheter mask tinted, the ordered centreline (green), the fitted
    curve (red), control points (yellow), base (blue) and tip (magenta) ends."""
    img = cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR) if frame.ndim == 2 else \
        np.ascontiguousarray(frame[:, :, :3]).copy()
    if obs.mask is not None and obs.roi is not None:
        u0, v0, w, h = obs.roi
        sub = img[v0:v0 + h, u0:u0 + w]
        sub[obs.mask > 0] = (0.5 * sub[obs.mask > 0] + np.array([0, 60, 120])).astype(np.uint8)
    if obs.ok:
        from catheter_shape.camera import psi_to_pixels
        cv2.polylines(img, [_draw_points(obs.pixels, 2)], False, (0, 200, 0), 1, cv2.LINE_AA, 2)
        curve = bezier_eval(obs.control_points, np.linspace(0, 1, 100))
        cv2.polylines(img, [_draw_points(psi_to_pixels(psi, curve), 2)], False, (0, 0, 255), 1,
                      cv2.LINE_AA, 2)
        for q in _draw_points(psi_to_pixels(psi, obs.control_points)).reshape(-1, 2):
            cv2.circle(img, (int(q[0]), int(q[1])), 4, (0, 220, 220), 1, cv2.LINE_AA)
        for p, colour in ((obs.base_px, (255, 0, 0)), (obs.tip_px, (255, 0, 255))):
            q = _draw_points([p]).reshape(2)
            cv2.circle(img, (int(q[0]), int(q[1])), 5, colour, 2)
        txt = (f'ok  residual {obs.residual * 1e3:.3f} mm  '
               f'{obs.timings.get("total", 0) * 1e3:.1f} ms')
    else:
        txt = f'{obs.status}: {obs.message}'[:80]
    cv2.putText(img, txt, (8, 18), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 255, 255), 1, cv2.LINE_AA)
    return img


class ShapeNode(Node):
    """Image -> control points (see the module docstring)."""

    PARAMS = PARAMS

    def __init__(self, **kwargs):
        super().__init__('shape_node', **kwargs)
        self.params = p = NodeParams(self, PARAMS, apply=self._apply_params)
        self._path_max = p['path_poses']
        self._path_out = PathOut()
        self.sensor, self._psi = self._build_sensor(p.values, strict=False)
        self.diag = Diagnostics(self)
        for k in ('frames', 'processed', 'dropped', 'idle', 'published', 'bad_messages') + \
                tuple('fail_' + s for s in STATUSES if s != 'ok'):
            self.diag.count(k, 0)
        qos_in = QoSProfile(history=Q.QOS_SENSOR.history, depth=Q.QOS_SENSOR.depth,
                            reliability=Q.QOS_SENSOR.reliability,
                            durability=Q.QOS_SENSOR.durability)
        self.sub = self.create_subscription(Image, T.relative(T.CAMERA_IMAGE), self._on_image,
                                            qos_in)
        self.pub_cp = self.create_publisher(PoseArray, T.relative(T.CONTROL_POINTS),
                                            Q.QOS_SENSOR)
        self.pub_path = self.create_publisher(Path, T.relative(T.SHAPE), Q.QOS_DEFAULT)
        self.pub_debug = self.create_publisher(Image, T.relative(T.SHAPE_DEBUG_IMAGE),
                                               Q.QOS_SENSOR)
        self._pending: Optional[Image] = None
        self._on_arrival = p['process_on_arrival']
        #: node clock (ns) when the last processing ended: a frame stamped before it may
        #: have newer ones queued behind it
        self._idle_since_ns = 0
        self._timer = self.create_timer(p['period'], self._process)
        self._last_obs = None
        self.get_logger().info(
            f'shape_node: {self.sub.topic_name} -> {self.pub_cp.topic_name}, '
            f'{self.pub_path.topic_name}; {p["method"]} segmentation, length '
            f'{p["length"] or "not checked"}, base_px '
            f'{self.sensor.base_px}, background '
            f'{"yes" if self.sensor.background is not None else "no"}, '
            f'{self.sensor._m_per_px * 1e3:.4f} mm/px')

    def _build_sensor(self, values, strict: bool):
        """(ShapeSensor, psi 3x4) for the parameter values. A background_file that cannot be
        read: ValueError when `strict` (a runtime change), else logged and left out (at start
        the camera may not have written it yet)."""
        base_px = values['base_px']
        base = (base_px[0], base_px[1]) if base_px[0] >= 0 and base_px[1] >= 0 else None
        background = None
        bg_file = values['background_file']
        if bg_file:
            background = cv2.imread(bg_file, cv2.IMREAD_GRAYSCALE)
            if background is None:
                if strict:
                    raise ValueError(f'cannot read background_file {bg_file!r}')
                self.get_logger().error(f'cannot read background_file {bg_file!r}: running '
                                        'without background removal')
        constraint = values['base_constraint']
        if base is None and constraint != 'none':
            if strict:
                raise ValueError(f'base_constraint {constraint} needs base_px')
            self.get_logger().warning('base_constraint needs base_px: using none')
            constraint = 'none'
        psi = np.asarray(values['psi'], dtype=float).reshape(3, 4)
        sensor = ShapeSensor(psi, threshold=values['threshold'], background=background,
                             base_px=base, method=values['method'], degree=values['degree'],
                             base_constraint=constraint, length=values['length'] or None,
                             length_tolerance=values['length_tolerance'])
        return sensor, psi

    def _apply_params(self, changes, values) -> None:
        if _SENSOR_KEYS & set(changes):
            self.sensor, self._psi = self._build_sensor(values, strict=True)
        if 'period' in changes:
            self._timer.timer_period_ns = int(round(values['period'] * 1e9))
            self._timer.reset()          # the new period counts from now
        if 'path_poses' in changes:
            self._path_max = values['path_poses']
        if 'process_on_arrival' in changes:
            self._on_arrival = values['process_on_arrival']

    def _on_image(self, msg: Image) -> None:
        if stage_trace.enabled():
            now = stage_trace.time.time_ns()
            stage_trace.note('arrive', stage_trace.stamp_ns(msg.header.stamp), now, now)
        self.diag.count('frames')
        if self._pending is not None:
            self.diag.count('dropped')
        self._pending = msg
        if self._on_arrival:
            st = msg.header.stamp
            if st.sec * 1_000_000_000 + st.nanosec >= self._idle_since_ns:
                self._process()

    def _process(self) -> None:
        msg, self._pending = self._pending, None
        if msg is None:
            return
        try:
            self._process_frame(msg)
        finally:
            self._idle_since_ns = self.get_clock().now().nanoseconds

    def _process_frame(self, msg: Image) -> None:
        stage = stage_trace.Stage.begin()
        t0 = wall_time()
        try:
            frame = image_to_array(msg)
        except ValueError as exc:
            self.diag.bad_input('image', str(exc))
            return
        want_debug = self.pub_debug.get_subscription_count() > 0
        if not want_debug and self.pub_cp.get_subscription_count() == 0 and \
                self.pub_path.get_subscription_count() == 0:
            self.diag.count('idle')         # nobody listens: skip the heavy work
            return
        self.sensor.keep_mask = want_debug
        try:
            obs = self.sensor.process(frame)
        except (ValueError, cv2.error) as exc:    # the sensor should say 'bad_input' itself
            self.diag.count('sensor_errors')
            self.diag.bad_input('image', f'the shape sensor failed on it: {exc!r}'[:300])
            return
        self._last_obs = obs
        self.diag.count('processed')
        stamp = msg.header.stamp
        if stage is not None:
            stage.end('shape', stage_trace.stamp_ns(stamp), obs.status)
        if obs.ok:
            self.pub_cp.publish(control_points_to_pose_array(obs.control_points, stamp))
            self.diag.count('published')
            if self.pub_path.get_subscription_count() > 0:
                self.pub_path.publish(self._path_out.fill(obs.points, stamp, self._path_max))
            self.diag.set('residual_mm', obs.residual * 1e3)
        else:
            self.diag.count('fail_' + obs.status)
            self.diag.event('no_shape', WARN, f'no catheter shape: {obs.status} '
                            f'({obs.message})')
            self.diag.log_limited('no_shape', f'no catheter shape: {obs.status} '
                                  f'({obs.message})')
        if want_debug:
            self.pub_debug.publish(array_to_image(debug_overlay(frame, obs, self._psi), stamp,
                                                  T.FRAME_CAMERA))
        now = self.get_clock().now()
        lat = (now.nanoseconds - (stamp.sec * 1_000_000_000 + stamp.nanosec)) * 1e-9
        self.diag.set('latency_ms', lat * 1e3)
        self.diag.set('process_ms', (wall_time() - t0) * 1e3)
        self.diag.set('pipeline_ms', obs.timings.get('total', float('nan')) * 1e3)


NODE_CLASS = ShapeNode


main = node_main(NODE_CLASS)


if __name__ == '__main__':
    raise SystemExit(main())

"""ROS 2 node `camera_node`: the slave's camera, 30 Hz frames of the catheter's distal end bent
by the tip's wall-contact force.

Subscribes  slave/joint_state_decimated  sensor_msgs/JointState (position[0] insertion m,
                                     velocity[0] m/s), QOS_LATEST (keep last 1): the newest
                                     one is used, its insertion carried forward to the
                                     frame's stamp at its velocity (at most
                                     MAX_EXTRAPOLATION_S): sim_slave_node publishes it at
                                     100 Hz (its 1 kHz slave/joint_state cost the camera's
                                     process about 10 % of a core through DDS)
Publishes   camera/image_raw         sensor_msgs/Image mono8, frame camera_optical_frame,
                                     sensor-data QoS (only while subscribed)
            camera/tip_force_truth   geometry_msgs/WrenchStamped, frame catheter_base: the tip
                                     force the frame was drawn with (the truth for image-based
                                     force estimation), same stamp as the image
            /diagnostics             frames, FAM not converged, bad joint states (WARN events)
Timer on the node clock (use_sim_time works); `rate` applies at run time, the other
parameters are fixed at start (they define the camera and the scene). Topic names are
relative (the node's namespace applies). The shape node needs this camera's calibration:
psi, base_px and the background (written to `background_file` if given) are logged at start.

Thin: the physics (tip force, FAM, drawing) is in sim_slave.camera.TipCamera.
"""
from __future__ import annotations

import math

from geometry_msgs.msg import WrenchStamped
from rclpy.node import Node
from sensor_msgs.msg import Image, JointState

from catheter_common import topics as T
from catheter_common.checks import first
from catheter_common.diagnostics import ERROR, WARN, Diagnostics
from catheter_common.images import array_to_image
from catheter_common.params import NodeParams, Param, table
from catheter_common.qos import QOS_LATEST, QOS_SENSOR
from catheter_common.ros_node import node_main
from catheter_shape import stage_trace
from sim_slave.camera import BLAZER_EI, BLAZER_LENGTH, DEFAULT_CAMERA, TipCamera
from sim_slave.node_params import DEFAULT_VESSEL, VESSEL_CHOICES, vessel_from_params
from sim_slave.vessel import VesselParams

#: the tip force each frame was drawn with (re-exported for the tests that import it here)
CAMERA_TIP_FORCE_TRUTH = T.CAMERA_TIP_FORCE_TRUTH
#: the longest time (s) the newest joint state's insertion is carried forward to a frame's
#: stamp at its velocity: two periods of the 100 Hz decimated state (a staler state is
#: carried this far, no farther: the slave has stopped publishing)
MAX_EXTRAPOLATION_S = 0.02
_WALL_FIELDS = ('wall_depth', 'wall_stiffness', 'wall_exponent', 'wall_damping')

PARAMS = table(
    Param('rate', 30.0, 'frame rate, Hz', 0.1, 1000.0, dynamic=True),
    Param('seed', 0, 'random seed (background texture, image noise)', 0, 2 ** 31 - 1),
    Param('tip_force_angle', 2.0 * math.pi / 3.0, 'direction of the wall force on the tip in '
          'catheter_base, rad', -2.0 * math.pi, 2.0 * math.pi),
    Param('catheter.length', BLAZER_LENGTH, 'catheter length from clamp to tip, m', 0.005, 1.0),
    Param('catheter.ei', BLAZER_EI, 'bending stiffness EI, N m^2', 1e-7, 1.0),
    Param('n_arcs', 12, 'FAM arcs', 1, 500),
    Param('camera.width', DEFAULT_CAMERA['width'], 'image width, px', 16, 8192),
    Param('camera.height', DEFAULT_CAMERA['height'], 'image height, px', 16, 8192),
    Param('camera.mm_per_px', DEFAULT_CAMERA['mm_per_px'], 'scale, mm per pixel', 0.001, 10.0),
    Param('camera.base_px', [float(b) for b in DEFAULT_CAMERA['base_px']],
          'pixel (u, v) of the clamp (catheter_base origin)', numbers=True, length=2),
    Param('camera.noise', 4.0, 'image noise std, grey levels', 0.0, 100.0),
    Param('vessel', DEFAULT_VESSEL, 'the simulated vessel (sim_slave.vessels, as '
          'sim_slave_node): its wall gives the tip force', choices=VESSEL_CHOICES),
    Param('background_file', '', 'if set, the background frame (no catheter) is written here '
          'as PNG at start, for the shape node\'s background removal'),
    *(Param('vessel.' + f, float(getattr(VesselParams(), f)),
            f'vessel {f} (as sim_slave_node), SI', 0.0, 1e5) for f in _WALL_FIELDS),
)


class CameraNode(Node):
    """Renders the simulated catheter at a fixed rate from the newest slave joint state."""

    PARAMS = PARAMS

    def __init__(self, **kwargs):
        super().__init__('camera_node', **kwargs)
        self.params = p = NodeParams(self, PARAMS, apply=self._apply_params)
        rate = p['rate']
        width, height = p['camera.width'], p['camera.height']
        base_px = p['camera.base_px']
        bg_file = p['background_file']
        # the wall of the same vessel as sim_slave_node's (its vessel.wall_* overridable)
        vp = vessel_from_params(p.values).params
        self.camera = TipCamera(vp, force_angle=p['tip_force_angle'], length=p['catheter.length'],
                                ei=p['catheter.ei'], n_arcs=p['n_arcs'],
                                camera=dict(width=width, height=height,
                                            mm_per_px=p['camera.mm_per_px'],
                                            base_px=tuple(base_px), noise=p['camera.noise']),
                                seed=p['seed'])
        if bg_file:
            import cv2
            if not cv2.imwrite(bg_file, self.camera.camera.background):
                raise ValueError(f'background_file {bg_file!r} cannot be written')
        self.x, self.xd = 0.0, 0.0
        self._state_ns = None           # the newest joint state's stamp, ns
        self.diag = Diagnostics(self)
        self.diag.count('bad_messages', 0)
        self.pub_image = self.create_publisher(Image, T.relative(T.CAMERA_IMAGE), QOS_SENSOR)
        self.pub_truth = self.create_publisher(WrenchStamped,
                                               T.relative(T.CAMERA_TIP_FORCE_TRUTH), QOS_SENSOR)
        self.sub = self.create_subscription(JointState,
                                            T.relative(T.SLAVE_JOINT_STATE_DECIMATED),
                                            self._on_state, QOS_LATEST)
        self.timer = self.create_timer(1.0 / rate, self._tick)
        psi = ', '.join(f'{v:.9g}' for v in self.camera.psi.reshape(-1))
        self.get_logger().info(
            f'camera {width}x{height} at {rate:g} Hz: {self.sub.topic_name} -> wall force on '
            f'the tip ({p["tip_force_angle"]:.3f} rad) -> FAM -> {self.pub_image.topic_name}, '
            f'{self.pub_truth.topic_name}; shape_node needs psi=[{psi}] base_px={list(base_px)}'
            + (f' background_file={bg_file}' if bg_file else ''))

    def _apply_params(self, changes, values) -> None:
        if 'rate' in changes:
            self.timer.timer_period_ns = int(round(1e9 / values['rate']))
            self.timer.reset()          # the new period counts from now

    def _on_state(self, msg: JointState) -> None:
        try:
            x = first('position', msg.position)
            xd = first('velocity', msg.velocity, 0.0)
        except ValueError as exc:
            self.diag.count('bad_joint_states')
            self.diag.bad_input('joint_state', str(exc))
            return
        self.x, self.xd = x, xd
        st = msg.header.stamp
        self._state_ns = st.sec * 1_000_000_000 + st.nanosec
        self.diag.count('joint_states')

    def state_at(self, stamp_ns: int):
        """(insertion m, velocity m/s) at stamp_ns: the newest joint state's insertion carried
        forward at its velocity over the time from its stamp (clamped to [0,
        MAX_EXTRAPOLATION_S]; none without a stamp)."""
        if self._state_ns is None:
            return self.x, self.xd
        dt = min(max((stamp_ns - self._state_ns) * 1e-9, 0.0), MAX_EXTRAPOLATION_S)
        return self.x + self.xd * dt, self.xd

    def _tick(self) -> None:
        want_image = self.pub_image.get_subscription_count() > 0
        want_truth = self.pub_truth.get_subscription_count() > 0
        if not (want_image or want_truth):
            return
        stage = stage_trace.Stage.begin()
        now = self.get_clock().now()
        stamp = now.to_msg()
        x, xd = self.state_at(now.nanoseconds)
        try:
            frame = self.camera.frame(x, xd) if want_image else None
            force = frame.tip_force if want_image else self.camera.tip_force(x, xd)
        except (ArithmeticError, ValueError) as exc:     # a state the camera cannot draw
            self.diag.count('frame_errors')
            self.diag.event('frame_error', ERROR, f'no frame for x={x!r} m: {exc!r}')
            return
        if want_image:
            if not frame.converged:
                self.diag.count('fam_not_converged')
                self.diag.event('fam_not_converged', WARN, 'FAM did not converge: the frame '
                                'shows its best iterate')
            if stage is not None:
                stage.end('camera', stage_trace.stamp_ns(stamp))
            self.pub_image.publish(array_to_image(frame.image, stamp, T.FRAME_CAMERA))
            self.diag.count('frames')
        w = WrenchStamped()
        w.header.stamp = stamp
        w.header.frame_id = T.FRAME_CATHETER_BASE
        w.wrench.force.x, w.wrench.force.y = float(force[0]), float(force[1])
        self.pub_truth.publish(w)


NODE_CLASS = CameraNode


main = node_main(NODE_CLASS)


if __name__ == '__main__':
    raise SystemExit(main())

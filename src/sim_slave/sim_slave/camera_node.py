"""ROS 2 node `camera_node`: the slave's camera, 30 Hz frames of the catheter's distal end bent
by the tip's wall-contact force.

Subscribes  /slave/joint_state        sensor_msgs/JointState (position[0] insertion m,
                                      velocity[0] m/s), QOS_FAST: the newest one is used
Publishes   /camera/image_raw         sensor_msgs/Image mono8, frame camera_optical_frame,
                                      sensor-data QoS (only while subscribed)
            /camera/tip_force_truth   geometry_msgs/WrenchStamped, frame catheter_base: the tip
                                      force the frame was drawn with (the truth for image-based
                                      force estimation), same stamp as the image
            /diagnostics              frames, FAM not converged, bad joint states
Timer on the node clock (use_sim_time works). The shape node needs this camera's calibration:
psi, base_px and the background (written to `background_file` if given) are logged at start.

Thin: the physics (tip force, FAM, drawing) is in sim_slave.camera.TipCamera.
"""
from __future__ import annotations

import math
from dataclasses import fields

import numpy as np
from geometry_msgs.msg import WrenchStamped
from rclpy.node import Node
from sensor_msgs.msg import Image, JointState

from catheter_common.ros_node import Diagnostics, declare, run_node
from catheter_common.topics import (CAMERA_IMAGE, FRAME_CAMERA, FRAME_CATHETER_BASE,
                                    SLAVE_JOINT_STATE)
from catheter_common.qos import QOS_FAST, QOS_SENSOR
from sim_slave.camera import BLAZER_EI, BLAZER_LENGTH, DEFAULT_CAMERA, TipCamera
from sim_slave.vessel import VesselParams

#: the tip force each frame was drawn with (ground truth of image-based estimation)
from catheter_common.topics import CAMERA_TIP_FORCE_TRUTH  # noqa: E402  (re-exported)
_WALL_FIELDS = ('wall_depth', 'wall_stiffness', 'wall_exponent', 'wall_damping')


class CameraNode(Node):
    """Renders the simulated catheter at a fixed rate from the newest slave joint state."""

    def __init__(self, **kwargs):
        super().__init__('camera_node', **kwargs)
        rate = declare(self, 'rate', 30.0, 'frame rate, Hz', 0.1, 1000.0)
        seed = declare(self, 'seed', 0, 'random seed (background texture, image noise)',
                       0, 2 ** 31 - 1)
        angle = declare(self, 'tip_force_angle', 2.0 * math.pi / 3.0,
                        'direction of the wall force on the tip in catheter_base, rad',
                        -2.0 * math.pi, 2.0 * math.pi)
        length = declare(self, 'catheter.length', BLAZER_LENGTH,
                         'catheter length from clamp to tip, m', 0.005, 1.0)
        ei = declare(self, 'catheter.ei', BLAZER_EI, 'bending stiffness EI, N m^2', 1e-7, 1.0)
        n_arcs = declare(self, 'n_arcs', 12, 'FAM arcs', 1, 500)
        width = declare(self, 'camera.width', DEFAULT_CAMERA['width'], 'image width, px',
                        16, 8192)
        height = declare(self, 'camera.height', DEFAULT_CAMERA['height'], 'image height, px',
                         16, 8192)
        mm_per_px = declare(self, 'camera.mm_per_px', DEFAULT_CAMERA['mm_per_px'],
                            'scale, mm per pixel', 0.001, 10.0)
        base_px = declare(self, 'camera.base_px', [float(b) for b in DEFAULT_CAMERA['base_px']],
                          'pixel (u, v) of the clamp (catheter_base origin)')
        noise = declare(self, 'camera.noise', 4.0, 'image noise std, grey levels', 0.0, 100.0)
        bg_file = declare(self, 'background_file', '',
                          'if set, the background frame (no catheter) is written here as PNG '
                          'at start, for the shape node\'s background removal')
        defaults = VesselParams()
        wall = {f: declare(self, 'vessel.' + f, float(getattr(defaults, f)),
                           f'vessel {f} (as sim_slave_node), SI', 0.0, 1e5)
                for f in _WALL_FIELDS}
        if len(base_px) != 2:
            raise ValueError(f'camera.base_px needs 2 values, got {list(base_px)}')
        vp = VesselParams(**{f.name: wall.get(f.name, getattr(defaults, f.name))
                             for f in fields(VesselParams)})
        self.camera = TipCamera(vp, force_angle=angle, length=length, ei=ei, n_arcs=n_arcs,
                                camera=dict(width=width, height=height, mm_per_px=mm_per_px,
                                            base_px=tuple(base_px), noise=noise),
                                seed=seed)
        if bg_file:
            import cv2
            if not cv2.imwrite(bg_file, self.camera.camera.background):
                raise ValueError(f'background_file {bg_file!r} cannot be written')
        self.x, self.xd = 0.0, 0.0
        self.diag = Diagnostics(self)
        self.pub_image = self.create_publisher(Image, CAMERA_IMAGE, QOS_SENSOR)
        self.pub_truth = self.create_publisher(WrenchStamped, CAMERA_TIP_FORCE_TRUTH, QOS_SENSOR)
        self.sub = self.create_subscription(JointState, SLAVE_JOINT_STATE, self._on_state,
                                            QOS_FAST)
        self.timer = self.create_timer(1.0 / rate, self._tick)
        psi = ', '.join(f'{v:.9g}' for v in self.camera.psi.reshape(-1))
        self.get_logger().info(
            f'camera {width}x{height} at {rate:g} Hz: {SLAVE_JOINT_STATE} -> wall force on the tip '
            f'({angle:.3f} rad) -> FAM -> {CAMERA_IMAGE}, {CAMERA_TIP_FORCE_TRUTH}; shape_node '
            f'needs psi=[{psi}] base_px={list(base_px)}'
            + (f' background_file={bg_file}' if bg_file else ''))

    def _on_state(self, msg: JointState) -> None:
        if len(msg.position) < 1 or not math.isfinite(msg.position[0]) or (
                len(msg.velocity) >= 1 and not math.isfinite(msg.velocity[0])):
            self.diag.count('bad_joint_states')
            self.diag.error('joint state without a finite insertion position/velocity')
            self.get_logger().warning('bad joint state ignored', throttle_duration_sec=2.0)
            return
        self.x = float(msg.position[0])
        self.xd = float(msg.velocity[0]) if len(msg.velocity) >= 1 else 0.0

    def _tick(self) -> None:
        want_image = self.pub_image.get_subscription_count() > 0
        want_truth = self.pub_truth.get_subscription_count() > 0
        if not (want_image or want_truth):
            return
        stamp = self.get_clock().now().to_msg()
        if want_image:
            frame = self.camera.frame(self.x, self.xd)
            force = frame.tip_force
            if not frame.converged:
                self.diag.count('fam_not_converged')
            img = Image()
            img.header.stamp = stamp
            img.header.frame_id = FRAME_CAMERA
            img.height, img.width = int(frame.image.shape[0]), int(frame.image.shape[1])
            img.encoding = 'mono8'
            img.is_bigendian = 0
            img.step = img.width
            img.data = np.ascontiguousarray(frame.image, dtype=np.uint8).tobytes()
            self.pub_image.publish(img)
            self.diag.count('frames')
        else:
            force = self.camera.tip_force(self.x, self.xd)
        w = WrenchStamped()
        w.header.stamp = stamp
        w.header.frame_id = FRAME_CATHETER_BASE
        w.wrench.force.x, w.wrench.force.y = float(force[0]), float(force[1])
        self.pub_truth.publish(w)


NODE_CLASS = CameraNode


def main(args=None):
    return run_node(NODE_CLASS, args)


if __name__ == '__main__':
    raise SystemExit(main())

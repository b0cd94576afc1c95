"""ROS 2 node `force_estimator_node`: Bezier control points in, estimated tip wrench out.

Subscribes  /catheter/control_points  geometry_msgs/PoseArray (4 poses p0..p3 base -> tip,
                                      positions in m, frame catheter_base), sensor-data QoS
Publishes   /catheter/tip_wrench      geometry_msgs/WrenchStamped (force x, y in N,
                                      catheter_base, the input's stamp), sensor-data QoS
            /diagnostics              estimates, rate, latency, out-of-envelope, bad messages

Parameters (read at start): method (svr | mlp | fam; only the chosen estimator is loaded),
svr_model / mlp_model (shipped name or .npz path), length (m), ei (N m^2), n_arcs, f_max (N)
for fam. Thin: conversion and bookkeeping only; the estimators live in the core modules.
"""
from __future__ import annotations

import numpy as np
from geometry_msgs.msg import PoseArray, WrenchStamped
from rclpy.node import Node

from catheter_common.ros_node import Diagnostics, declare, run_node, wall_time
from catheter_common.topics import CONTROL_POINTS, FRAME_CATHETER_BASE, TIP_WRENCH
from catheter_common.qos import QOS_SENSOR

METHODS = ('svr', 'mlp', 'fam')


class ForceEstimatorNode(Node):
    """Estimates the catheter tip force from each control-point message."""

    def __init__(self, **kwargs):
        super().__init__('force_estimator_node', **kwargs)
        self.method = declare(self, 'method', 'svr',
                              'estimator: svr / mlp (learned, shipped models) or fam '
                              '(FAM inversion)', choices=METHODS)
        svr_model = declare(self, 'svr_model', 'blazer-svr',
                            'SVR model: shipped name or path to a .npz model file')
        mlp_model = declare(self, 'mlp_model', 'blazer-mlp',
                            'MLP model: shipped name or path to a .npz model file')
        length = declare(self, 'length', 0.065, 'catheter length for fam, m', 0.005, 2.0)
        ei = declare(self, 'ei', 6.0e-5, 'bending stiffness EI for fam, N m^2', 1e-7, 1.0)
        n_arcs = declare(self, 'n_arcs', 24, 'FAM arcs for fam (more: more accurate, slower)', 1, 200)
        f_max = declare(self, 'f_max', 0.45, 'largest plausible tip force for fam, N', 0.01, 10.0)
        if self.method == 'fam':
            from fam_solver import Catheter

            from force_estimator.fam_inverse import FamInverseEstimator
            self.estimator = FamInverseEstimator(Catheter(length=length, ei=ei),
                                                 n_arcs=n_arcs, f_max=f_max)
            source = f'FAM inversion (L={length} m, EI={ei} N m^2, {n_arcs} arcs)'
        else:
            from force_estimator.models import load_estimator
            source = svr_model if self.method == 'svr' else mlp_model
            self.estimator = load_estimator(source)
            if self.estimator.kind != self.method:
                raise ValueError(f'{self.method}_model {source!r} holds a '
                                 f'{self.estimator.kind} model')
        self.diag = Diagnostics(self)
        self.diag.set('method', self.method)
        self.diag.set('model', str(source))
        self._lat_sum = 0.0
        self._lat_n = 0
        self._lat_max = 0.0
        self.pub = self.create_publisher(WrenchStamped, TIP_WRENCH, QOS_SENSOR)
        self.sub = self.create_subscription(PoseArray, CONTROL_POINTS, self._on_points,
                                            QOS_SENSOR)
        self._diag_timer = self.create_timer(1.0, self._latency_to_diag)
        self.get_logger().info(f'estimating tip force with {self.method} ({source}): '
                               f'{CONTROL_POINTS} -> {TIP_WRENCH}')

    def _bad(self, why: str) -> None:
        self.diag.count('bad_messages')
        self.diag.error(why, key='errors')
        self.get_logger().warning(f'bad control-point message: {why}',
                                  throttle_duration_sec=2.0)

    def _on_points(self, msg: PoseArray) -> None:
        self.diag.count('messages')
        if msg.header.frame_id not in ('', FRAME_CATHETER_BASE):
            self._bad(f'frame_id {msg.header.frame_id!r}, expected {FRAME_CATHETER_BASE!r}')
            return
        if len(msg.poses) != 4:
            self._bad(f'{len(msg.poses)} poses, expected 4 (p0..p3)')
            return
        if self.pub.get_subscription_count() == 0:
            self.diag.count('skipped_no_subscriber')
            return
        cp = np.array([[p.position.x, p.position.y, p.position.z] for p in msg.poses])
        t0 = wall_time()
        try:
            force, inside = self.estimator.predict(cp, return_flags=True)
        except ValueError as exc:
            self._bad(str(exc))
            return
        lat = wall_time() - t0
        self._lat_sum += lat
        self._lat_n += 1
        self._lat_max = max(self._lat_max, lat)
        if not inside:
            self.diag.count('out_of_envelope')
        out = WrenchStamped()
        out.header.stamp = msg.header.stamp
        out.header.frame_id = FRAME_CATHETER_BASE
        out.wrench.force.x = float(force[0])
        out.wrench.force.y = float(force[1])
        self.pub.publish(out)
        self.diag.count('estimates')

    def _latency_to_diag(self) -> None:
        if self._lat_n:
            self.diag.set('latency_mean_ms', 1e3 * self._lat_sum / self._lat_n)
            self.diag.set('latency_max_ms', 1e3 * self._lat_max)
            self._lat_sum, self._lat_n, self._lat_max = 0.0, 0, 0.0


NODE_CLASS = ForceEstimatorNode


def main(args=None):
    return run_node(NODE_CLASS, args)


if __name__ == '__main__':
    raise SystemExit(main())

"""ROS 2 node `force_estimator_node`: Bezier control points in, estimated tip wrench out.

Subscribes  catheter/control_points  geometry_msgs/PoseArray (4 poses p0..p3 base -> tip,
                                     positions in m, frame catheter_base), sensor-data QoS
Publishes   catheter/tip_wrench      geometry_msgs/WrenchStamped (force x, y in N,
                                     catheter_base, the input's stamp), sensor-data QoS: only
                                     estimates inside the estimator's envelope; an estimate
                                     out of it or not finite is not published (counted,
                                     reported on /diagnostics as WARN / ERROR)
            /diagnostics             estimates, rate, latency, out-of-envelope, bad messages

Parameters (all apply at run time, from the next message): method (svr | mlp | fam; only
the chosen estimator is loaded), svr_model / mlp_model (shipped name or .npz path; a file
that does not load or holds the other kind of model is refused), length (m), ei (N m^2),
n_arcs, f_max (N) for fam. Topic names are relative (the node's namespace applies).
Thin: conversion and bookkeeping only; the estimators live in the core modules.
"""
from __future__ import annotations

import math

import numpy as np
from geometry_msgs.msg import PoseArray, WrenchStamped
from rclpy.node import Node

from catheter_common import topics as T
from catheter_common.diagnostics import ERROR, WARN, Diagnostics
from catheter_common.params import NodeParams, Param, table
from catheter_common.qos import QOS_SENSOR
from catheter_common.ros_node import run_node, wall_time

METHODS = ('svr', 'mlp', 'fam')

PARAMS = table(
    Param('method', 'svr', 'estimator: svr / mlp (learned, shipped models) or fam (FAM '
          'inversion)', choices=METHODS, dynamic=True),
    Param('svr_model', 'blazer-svr', 'SVR model: shipped name or path to a .npz model file',
          dynamic=True),
    Param('mlp_model', 'blazer-mlp', 'MLP model: shipped name or path to a .npz model file',
          dynamic=True),
    Param('length', 0.065, 'catheter length for fam, m', 0.005, 2.0, dynamic=True),
    Param('ei', 6.0e-5, 'bending stiffness EI for fam, N m^2', 1e-7, 1.0, dynamic=True),
    Param('n_arcs', 24, 'FAM arcs for fam (more: more accurate, slower)', 1, 200, dynamic=True),
    Param('f_max', 0.45, 'largest plausible tip force for fam, N', 0.01, 10.0, dynamic=True),
)


def load_model(method: str, source: str):
    """The learned model `source` (shipped name or path); ValueError if it does not load or
    holds another kind of model than `method`."""
    from force_estimator.models import load_estimator
    est = load_estimator(source)
    if est.kind != method:
        raise ValueError(f'{method}_model {source!r} holds a {est.kind} model')
    return est


def build_estimator(values):
    """(estimator, description) for the parameter values (ValueError when it cannot be built)."""
    method = values['method']
    if method == 'fam':
        from fam_solver import Catheter
        from force_estimator.fam_inverse import FamInverseEstimator
        est = FamInverseEstimator(Catheter(length=values['length'], ei=values['ei']),
                                  n_arcs=values['n_arcs'], f_max=values['f_max'])
        return est, (f'FAM inversion (L={values["length"]} m, EI={values["ei"]} N m^2, '
                     f'{values["n_arcs"]} arcs)')
    source = values[f'{method}_model']
    return load_model(method, source), source


class ForceEstimatorNode(Node):
    """Estimates the catheter tip force from each control-point message."""

    PARAMS = PARAMS

    def __init__(self, **kwargs):
        super().__init__('force_estimator_node', **kwargs)
        self.params = p = NodeParams(self, PARAMS, apply=self._apply_params)
        self.method = p['method']
        self.estimator, source = build_estimator(p.values)
        self.diag = Diagnostics(self)
        for k in ('messages', 'estimates', 'bad_messages', 'out_of_envelope', 'nonfinite'):
            self.diag.count(k, 0)
        self.diag.set('method', self.method)
        self.diag.set('model', str(source))
        self._lat_sum = 0.0
        self._lat_n = 0
        self._lat_max = 0.0
        self.pub = self.create_publisher(WrenchStamped, T.relative(T.TIP_WRENCH), QOS_SENSOR)
        self.sub = self.create_subscription(PoseArray, T.relative(T.CONTROL_POINTS),
                                            self._on_points, QOS_SENSOR)
        self.diag.add_updater(self._latency_to_diag)
        self.get_logger().info(f'estimating tip force with {self.method} ({source}): '
                               f'{self.sub.topic_name} -> {self.pub.topic_name}')

    def _apply_params(self, changes, values) -> None:
        for method in ('svr', 'mlp'):             # a model file is checked even when unused
            key = f'{method}_model'
            if key in changes and values['method'] != method:
                load_model(method, changes[key])
        fam_keys = {'length', 'ei', 'n_arcs', 'f_max'}
        if 'method' in changes or f'{values["method"]}_model' in changes or \
                (values['method'] == 'fam' and fam_keys & set(changes)):
            est, source = build_estimator(values)
            self.estimator, self.method = est, values['method']
            self.diag.set('method', self.method)
            self.diag.set('model', str(source))

    def _on_points(self, msg: PoseArray) -> None:
        self.diag.count('messages')
        if msg.header.frame_id not in ('', T.FRAME_CATHETER_BASE):
            self.diag.bad_input('control_points', f'frame_id {msg.header.frame_id!r}, '
                                f'expected {T.FRAME_CATHETER_BASE!r}')
            return
        if len(msg.poses) != 4:
            self.diag.bad_input('control_points', f'{len(msg.poses)} poses, expected 4 '
                                '(p0..p3)')
            return
        if self.pub.get_subscription_count() == 0:
            self.diag.count('skipped_no_subscriber')
            return
        cp = np.array([[p.position.x, p.position.y, p.position.z] for p in msg.poses])
        t0 = wall_time()
        try:
            force, inside = self.estimator.predict(cp, return_flags=True)
        except ValueError as exc:
            self.diag.bad_input('control_points', str(exc))
            return
        lat = wall_time() - t0
        self._lat_sum += lat
        self._lat_n += 1
        self._lat_max = max(self._lat_max, lat)
        fx, fy = float(force[0]), float(force[1])
        if not (math.isfinite(fx) and math.isfinite(fy)):
            self.diag.count('nonfinite')
            self.diag.event('nonfinite', ERROR, f'{self.method} estimate not finite: not '
                            'published')
            return
        if not inside:
            self.diag.count('out_of_envelope')
            self.diag.event('out_of_envelope', WARN, f'control points outside the {self.method}'
                            ' estimator\'s envelope: estimate not published')
            return
        out = WrenchStamped()
        out.header.stamp = msg.header.stamp
        out.header.frame_id = T.FRAME_CATHETER_BASE
        out.wrench.force.x = fx
        out.wrench.force.y = fy
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

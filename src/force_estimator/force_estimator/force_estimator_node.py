"""ROS 2 node `force_estimator_node`: Bezier control points in, estimated tip force out.

Subscribes  catheter/control_points  geometry_msgs/PoseArray (4 poses p0..p3 base -> tip,
                                     positions in m, frame catheter_base), sensor-data QoS
Publishes   catheter/tip_force       catheter_interfaces/TipForceEstimate for EVERY message:
                                     force (N, catheter_base), covariance (N^2, row-major
                                     over fx, fy), status (ok, unobservable_axial,
                                     out_of_domain, non_finite_input), method (svr, mlp, fam,
                                     fam_fallback), domain_distance; the input's stamp.
                                     A refused message (wrong frame, not 4 poses) gets status
                                     out_of_domain, force 0 and the covariance of "anything
                                     up to f_max". Sensor-data QoS.
            catheter/tip_wrench      geometry_msgs/WrenchStamped (force x, y in N,
                                     catheter_base, the input's stamp), sensor-data QoS: ONLY
                                     normal estimates (ForceEstimate.normal: status ok or
                                     axial_unobservable); the others are withheld (counted,
                                     WARN on /diagnostics)
            /diagnostics             messages, estimates (published on tip_wrench), withheld,
                                     status_<status> per ForceEstimate status, bad messages,
                                     latency, method, model

Parameters (all apply at run time, from the next message): method (svr | mlp | fam; only
the chosen estimator is loaded), svr_model / mlp_model (shipped name or .npz path; a file
that does not load or holds the other kind of model is refused), fallback (svr / mlp: the
FAM inversion answers the inputs the learned model does not cover, method fam_fallback),
length (m), ei (N m^2), n_arcs, f_max (N) for the FAM inversion (method fam or the
fallback). Nothing is estimated while nobody subscribes to either output. Topic names are
relative (the node's namespace applies). Thin: conversion and bookkeeping only; the
estimate is force_estimator.make_estimator(...).estimate(cp), a ForceEstimate.
"""
from __future__ import annotations

import numpy as np
from catheter_interfaces.msg import TipForceEstimate
from geometry_msgs.msg import PoseArray, WrenchStamped
from rclpy.node import Node

from catheter_common import topics as T
from catheter_common.diagnostics import ERROR, WARN, Diagnostics
from catheter_common.messages import tip_force_msg
from catheter_common.params import NodeParams, Param, table
from catheter_common.qos import QOS_SENSOR
from catheter_common.ros_node import node_main, wall_time
from catheter_shape import stage_trace

METHODS = ('svr', 'mlp', 'fam')
#: the parameters of the FAM inversion (method fam, or the learned models' fallback)
FAM_KEYS = frozenset({'length', 'ei', 'n_arcs', 'f_max'})

PARAMS = table(
    Param('method', 'svr', 'estimator: svr / mlp (learned, shipped models) or fam (FAM '
          'inversion)', choices=METHODS, dynamic=True),
    Param('svr_model', 'blazer-svr', 'SVR model: shipped name or path to a .npz model file',
          dynamic=True),
    Param('mlp_model', 'blazer-mlp', 'MLP model: shipped name or path to a .npz model file',
          dynamic=True),
    Param('fallback', True, 'svr / mlp: the FAM inversion answers inputs the learned model '
          'does not cover (method fam_fallback)', dynamic=True),
    Param('length', 0.065, 'catheter length for the FAM inversion, m', 0.005, 2.0,
          dynamic=True),
    Param('ei', 6.0e-5, 'bending stiffness EI for the FAM inversion, N m^2', 1e-7, 1.0,
          dynamic=True),
    Param('n_arcs', 24, 'FAM arcs of the inversion (more: more accurate, slower)', 1, 200,
          dynamic=True),
    Param('f_max', 0.45, 'largest plausible tip force for the FAM inversion, N', 0.01, 10.0,
          dynamic=True),
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
    """(estimator with estimate(cp) -> ForceEstimate, description) for the parameter values
    (ValueError when it cannot be built)."""
    from fam_solver import Catheter
    from force_estimator.hybrid import make_estimator
    method = values['method']
    cat = Catheter(length=values['length'], ei=values['ei'])
    fam = (f'FAM inversion (L={values["length"]} m, EI={values["ei"]} N m^2, '
           f'{values["n_arcs"]} arcs)')
    if method == 'fam':
        return make_estimator('fam', cat=cat, n_arcs=values['n_arcs'],
                              f_max=values['f_max']), fam
    source = values[f'{method}_model']
    est = make_estimator(method, load_model(method, source), cat=cat, n_arcs=values['n_arcs'],
                         f_max=values['f_max'], fallback=values['fallback'])
    return est, str(source) + (f' + {fam} as fallback' if values['fallback'] else '')


class ForceEstimatorNode(Node):
    """Estimates the catheter tip force from each control-point message."""

    PARAMS = PARAMS

    def __init__(self, **kwargs):
        super().__init__('force_estimator_node', **kwargs)
        self.params = p = NodeParams(self, PARAMS, apply=self._apply_params)
        self.method = p['method']
        self.estimator, source = build_estimator(p.values)
        self.diag = Diagnostics(self)
        for k in ('messages', 'estimates', 'withheld', 'bad_messages'):
            self.diag.count(k, 0)
        self.diag.set('method', self.method)
        self.diag.set('model', source)
        self._lat_sum = 0.0
        self._lat_n = 0
        self._lat_max = 0.0
        #: the last ForceEstimate (None before the first message or after a refused one)
        self.last = None
        self.pub = self.create_publisher(WrenchStamped, T.relative(T.TIP_WRENCH), QOS_SENSOR)
        self.pub_est = self.create_publisher(TipForceEstimate, T.relative(T.TIP_FORCE),
                                             QOS_SENSOR)
        self.sub = self.create_subscription(PoseArray, T.relative(T.CONTROL_POINTS),
                                            self._on_points, QOS_SENSOR)
        self.diag.add_updater(self._latency_to_diag)
        self.get_logger().info(f'estimating tip force with {self.method} ({source}): '
                               f'{self.sub.topic_name} -> {self.pub_est.topic_name} (every '
                               f'estimate), {self.pub.topic_name} (normal estimates)')

    def _apply_params(self, changes, values) -> None:
        for method in ('svr', 'mlp'):             # a model file is checked even when unused
            key = f'{method}_model'
            if key in changes and values['method'] != method:
                load_model(method, changes[key])
        uses_fam = values['method'] == 'fam' or values['fallback']
        if 'method' in changes or 'fallback' in changes or \
                f'{values["method"]}_model' in changes or (uses_fam and FAM_KEYS & set(changes)):
            est, source = build_estimator(values)
            self.estimator, self.method = est, values['method']
            self.diag.set('method', self.method)
            self.diag.set('model', source)

    def _f_max(self) -> float:
        return self.params['f_max']

    def _refused(self, msg: PoseArray, why: str) -> None:
        """A message that cannot be estimated from: counted, and published on the typed topic
        as an estimate that says so (force 0, anything up to f_max)."""
        from force_estimator.estimate import failed_estimate
        self.diag.bad_input('control_points', why)
        self.last = None
        self._publish_estimate(msg, failed_estimate('bad_input', self.method, why,
                                                    self._f_max()))

    def _on_points(self, msg: PoseArray) -> None:
        self.diag.count('messages')
        if self.pub.get_subscription_count() == 0 and self.pub_est.get_subscription_count() == 0:
            self.diag.count('skipped_no_subscriber')
            return
        if msg.header.frame_id not in ('', T.FRAME_CATHETER_BASE):
            self._refused(msg, f'frame_id {msg.header.frame_id!r}, expected '
                          f'{T.FRAME_CATHETER_BASE!r}')
            return
        if len(msg.poses) != 4:
            self._refused(msg, f'{len(msg.poses)} poses, expected 4 (p0..p3)')
            return
        cp = np.array([[p.position.x, p.position.y, p.position.z] for p in msg.poses])
        stage = stage_trace.Stage.begin()
        t0 = wall_time()
        try:
            est = self.estimator.estimate(cp)
        except ValueError as exc:                   # only for a wrong shape: not expected here
            self._refused(msg, str(exc))
            return
        lat = wall_time() - t0
        if stage is not None:
            stage.end('estimate', stage_trace.stamp_ns(msg.header.stamp),
                      [est.method, est.status, getattr(est, 'solves', 0)])
        self._lat_sum += lat
        self._lat_n += 1
        self._lat_max = max(self._lat_max, lat)
        self.last = est
        self.diag.count('status_' + est.status)
        if est.status == 'non_finite_input':
            self.diag.bad_input('control_points', est.message or 'non-finite control points')
        if not self._publish_estimate(msg, est):
            return
        if not est.normal:
            self.diag.count('withheld')
            self.diag.event('withheld', WARN, f'{est.method} estimate {est.status} (not '
                            f'published on {self.pub.topic_name}): {est.message}')
            return
        out = WrenchStamped()
        out.header.stamp = msg.header.stamp
        out.header.frame_id = T.FRAME_CATHETER_BASE
        out.wrench.force.x = float(est.force[0])
        out.wrench.force.y = float(est.force[1])
        self.pub.publish(out)
        self.diag.count('estimates')

    def _publish_estimate(self, msg: PoseArray, est) -> bool:
        """Publish `est` on the typed topic; False (an ERROR) if it is not a valid message
        (the core guarantees finite, bounded estimates: this is the last line)."""
        try:
            typed = tip_force_msg(est.force, est.covariance, est.message_status, est.method,
                                  est.domain_distance, stamp=msg.header.stamp)
        except ValueError as exc:
            self.diag.count('invalid_estimates')
            self.diag.event('invalid_estimate', ERROR, f'estimate not published: {exc}')
            return False
        self.pub_est.publish(typed)
        return True

    def _latency_to_diag(self) -> None:
        if self._lat_n:
            self.diag.set('latency_mean_ms', 1e3 * self._lat_sum / self._lat_n)
            self.diag.set('latency_max_ms', 1e3 * self._lat_max)
            self._lat_sum, self._lat_n, self._lat_max = 0.0, 0, 0.0


NODE_CLASS = ForceEstimatorNode


main = node_main(NODE_CLASS)


if __name__ == '__main__':
    raise SystemExit(main())

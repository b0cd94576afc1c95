"""ROS 2 node ``fam_solver_node``: tip load in, FAM centreline out.

Subscribes ``catheter/tip_load`` (geometry_msgs/WrenchStamped; force x, y [N] and torque z
[N m] in ``catheter_base``; with ``follower:=true`` the force is in the tip frame).
Publishes ``catheter/fam/shape`` (nav_msgs/Path in ``catheter_base``, the input's stamp,
``path_points`` poses base -> tip, orientation = tangent: the MODELLED centreline; the one
measured in the image is shape_node's ``catheter/shape``) and ``catheter/fam/shape_marker``
(visualization_msgs/Marker LINE_STRIP). Solves only when the load changed and someone
subscribes to an output (a load that arrives while nobody listens is solved when a
subscriber appears). Bad (non-finite) wrenches are logged, counted and dropped. Topic names
are relative (the node's namespace applies).

Parameters (all apply at run time: the last load is solved again with them within 0.1 s):
length [m], ei [N m^2], n_arcs, arc_model, spacing (graded|uniform arc lengths), follower,
path_points, line_width [m], max_force [N], max_moment [N m] (bigger loads are refused as bad
messages: they are no catheter's and take the solver long). Diagnostics: solves,
non_converged, unstable, bad_messages, solve_errors, last solve time; WARN after a solve
that did not converge or is unstable, and after bad messages; ERROR after a solver failure.
The physics lives in ``fam_solver.fam``; this module only converts.
"""
from __future__ import annotations

import math

from geometry_msgs.msg import Point, PoseStamped, WrenchStamped
from nav_msgs.msg import Path
from rclpy.node import Node
from visualization_msgs.msg import Marker

from catheter_common import topics as T
from catheter_common.diagnostics import ERROR, WARN, Diagnostics
from catheter_common.params import NodeParams, Param, table
from catheter_common.qos import QOS_DEFAULT
from catheter_common.ros_node import node_main, wall_time
from fam_solver import ARC_MODELS, DEFAULT_ARC_MODEL, Catheter, Loads, solve_fam
from fam_solver.fam import DEFAULT_SPACING, SPACINGS

PARAMS = table(
    Param('length', 0.065, 'catheter length [m] (Blazer II-XP: 0.065)', 1e-4, 10.0,
          dynamic=True),
    Param('ei', 6.0e-5, 'flexural rigidity EI [N m^2] (Blazer II-XP: 6e-5)', 1e-9, 1e3,
          dynamic=True),
    Param('n_arcs', 12, 'number of FAM arcs', 1, 5000, dynamic=True),
    Param('arc_model', DEFAULT_ARC_MODEL, 'arc model: clothoid (linearly changing curvature '
          'per arc, fourth order), exact (circular arcs) or bezier (thesis)',
          choices=tuple(ARC_MODELS), dynamic=True),
    Param('spacing', DEFAULT_SPACING, 'arc lengths: uniform (equal arcs) or graded (shorter '
          'arcs where the curvature changes fastest; ~2x more accurate for circular arcs, '
          '~1.7x slower)', choices=tuple(SPACINGS), dynamic=True),
    Param('follower', False, 'true: the tip force turns with the tip (tendon pull, tip frame)',
          dynamic=True),
    Param('path_points', 50, 'poses in the published Path', 2, 10000, dynamic=True),
    Param('line_width', 0.0023, 'marker line width [m] (7 Fr)', 1e-5, 0.1, dynamic=True),
    Param('max_force', 1.0, 'largest tip force accepted, N (a bigger load is refused as a bad '
          'message; the thesis range is 0-0.3 N)', 1e-6, 1e4, dynamic=True),
    Param('max_moment', 0.01, 'largest tip moment accepted, N m (0.003 N m bends the Blazer '
          'into a half circle)', 1e-9, 100.0, dynamic=True),
)


class FamSolverNode(Node):
    PARAMS = PARAMS

    def __init__(self, **kwargs):
        super().__init__('fam_solver_node', **kwargs)
        self.params = p = NodeParams(self, PARAMS, apply=self._apply_params)
        self._set_values(p.values)
        self.path_pub = self.create_publisher(Path, T.relative(T.FAM_SHAPE), QOS_DEFAULT)
        self.marker_pub = self.create_publisher(Marker, T.relative(T.FAM_SHAPE_MARKER),
                                                QOS_DEFAULT)
        self.sub = self.create_subscription(WrenchStamped, T.relative(T.TIP_LOAD), self._on_load,
                                            QOS_DEFAULT)
        self.diag = Diagnostics(self)
        self.diag.count('bad_messages', 0)
        self._pending = None        # (stamp, loads) not yet solved
        self._last_loads = None     # loads of the last published shape
        self._last_stamp = None
        self._last_shape = None     # warm start for the next solve
        self._poll = self.create_timer(0.1, self._flush)
        self.get_logger().info(
            f'FAM solver: L={self.cat.length} m, EI={self.cat.ei} N m^2, N={self.n_arcs}, '
            f'model={self.arc_model}, spacing={self.spacing}, follower={self.follower}; '
            f'{self.sub.topic_name} -> {self.path_pub.topic_name}, {self.marker_pub.topic_name}')

    def _set_values(self, v) -> None:
        cat = Catheter(length=v['length'], ei=v['ei'])       # ValueError refuses the change
        self.cat = cat
        self.n_arcs = v['n_arcs']
        self.arc_model = v['arc_model']
        self.spacing = v['spacing']
        self.follower = v['follower']
        self.path_points = v['path_points']
        self.line_width = v['line_width']
        self.max_force = v['max_force']
        self.max_moment = v['max_moment']

    def _apply_params(self, changes, values) -> None:
        self._set_values(values)
        self._last_shape = None               # no warm start across a model change
        if self._last_loads is not None:      # the shape of the last load, with the new values
            self._pending = (self._last_stamp, self._last_loads)
            self._last_loads = None
        # the follower flag is part of the load: also a load still waiting for a listener
        if 'follower' in changes and self._pending is not None:
            stamp, loads = self._pending
            self._pending = (stamp, Loads(tip_force=loads.tip_force, tip_moment=loads.tip_moment,
                                          follower=self.follower))

    def _listeners(self) -> int:
        return self.path_pub.get_subscription_count() + self.marker_pub.get_subscription_count()

    def _on_load(self, msg: WrenchStamped) -> None:
        self.diag.count('loads_received')
        f, t = msg.wrench.force, msg.wrench.torque
        try:
            loads = Loads(tip_force=(f.x, f.y), tip_moment=t.z, follower=self.follower)
        except ValueError as exc:
            self.diag.bad_input('tip_load', str(exc))
            return
        if math.hypot(f.x, f.y) > self.max_force or abs(t.z) > self.max_moment:
            self.diag.bad_input('tip_load', f'force ({f.x:.3g}, {f.y:.3g}) N / moment {t.z:.3g} '
                                f'N m beyond max_force {self.max_force:g} N / max_moment '
                                f'{self.max_moment:g} N m')
            return
        if msg.header.frame_id and msg.header.frame_id != T.FRAME_CATHETER_BASE:
            self.diag.log_limited('frame', f'tip load in frame {msg.header.frame_id!r}, '
                                  f'treated as {T.FRAME_CATHETER_BASE!r}')
        if loads == self._last_loads:
            self.diag.count('unchanged_loads')
            return
        self._pending = (msg.header.stamp, loads)
        self._flush()

    def _flush(self) -> None:
        if self._pending is None or self._listeners() == 0:
            return
        stamp, loads = self._pending
        self._pending = None
        t0 = wall_time()
        try:
            shape = solve_fam(self.cat, loads, n_arcs=self.n_arcs, arc_model=self.arc_model,
                              initial=self._last_shape if self.arc_model != 'bezier' else None,
                              spacing=self.spacing)
        except ValueError as exc:       # the solver refused (or failed on) this load
            self.diag.count('solve_errors')
            self.diag.event('solve_error', ERROR, f'FAM failed on {loads}: {exc!r}')
            self.diag.log_limited('solve_error', f'FAM failed on {loads}: {exc!r}', ERROR)
            return
        dt = wall_time() - t0
        self.diag.count('solves')
        self.diag.set('last_solve_ms', dt * 1e3)
        self.diag.set('last_iterations', shape.iterations)
        if not shape.converged:
            self.diag.count('non_converged')
            self.diag.event('non_converged', WARN, f'FAM did not converge: {shape.warning}')
            self.diag.log_limited('non_converged', f'FAM did not converge: {shape.warning}')
        if not shape.stable:
            self.diag.count('unstable')
            self.diag.event('unstable', WARN, f'unstable equilibrium: {shape.warning}')
            self.diag.log_limited('unstable', str(shape.warning))
        self._last_loads = loads
        self._last_stamp = stamp
        self._last_shape = shape if shape.converged and shape.stable else None
        if stamp.sec == 0 and stamp.nanosec == 0:
            stamp = self.get_clock().now().to_msg()
        self._publish(stamp, shape)

    def _publish(self, stamp, shape) -> None:
        import numpy as np
        s = np.linspace(0.0, 1.0, self.path_points)
        pts = shape.points_at(s)
        ang = shape.angles_at(s)
        path = Path()
        path.header.stamp = stamp
        path.header.frame_id = T.FRAME_CATHETER_BASE
        for (x, y), a in zip(pts.tolist(), ang.tolist(), strict=True):
            ps = PoseStamped()
            ps.header = path.header
            ps.pose.position.x, ps.pose.position.y = x, y
            ps.pose.orientation.z = math.sin(0.5 * a)
            ps.pose.orientation.w = math.cos(0.5 * a)
            path.poses.append(ps)
        self.path_pub.publish(path)
        mk = Marker()
        mk.header = path.header
        mk.ns = 'fam_solver'
        mk.id = 0
        mk.type = Marker.LINE_STRIP
        mk.action = Marker.ADD
        mk.pose.orientation.w = 1.0
        mk.scale.x = self.line_width
        mk.color.r, mk.color.g, mk.color.b, mk.color.a = 0.1, 0.6, 1.0, 1.0
        mk.points = [Point(x=x, y=y, z=0.0) for x, y in pts.tolist()]
        self.marker_pub.publish(mk)


NODE_CLASS = FamSolverNode


main = node_main(NODE_CLASS)


if __name__ == '__main__':
    raise SystemExit(main())

"""After a fuzz run: the node's parameters go back to their defaults (every runtime change
must be accepted) and plausible input must give a plausible output again ("still spinning
and publishing")."""
import math

import numpy as np
from geometry_msgs.msg import Point, Pose, PoseArray, WrenchStamped
from rclpy.parameter import Parameter
from catheter_interfaces.msg import ImpedanceModel, MasterCommand
from sensor_msgs.msg import JointState

from catheter_common import topics as T


def reset_params(rig) -> None:
    node = rig.node
    spec = rig.spec
    changes = [Parameter(p.name, value=spec.params.get(p.name, p.default))
               for p in node.PARAMS if p.dynamic]
    for c in changes:
        res = node.set_parameters([c])[0]
        assert res.successful, (c.name, res.reason)


def _outputs(rig, topic):
    return rig.outputs.get(T.resolve(topic, rig.node.get_namespace()), [])


def _count(rig, topic=None):
    if topic is None:
        return rig.tally.outputs
    return rig.counts.get(T.resolve(topic, rig.node.get_namespace()), 0)


def _good_linear_model(valid=True):
    return ImpedanceModel(m=0.0, c=2.0, k=5.0, offset=0.01, valid=bool(valid),
                          kind=ImpedanceModel.KIND_LINEAR)


def _cmd(x, xd, xdd=0.0):
    return MasterCommand(position=x, velocity=xd, acceleration=xdd)


def _wrench(fx, fy=0.0):
    w = WrenchStamped()
    w.header.frame_id = T.FRAME_CATHETER_BASE
    w.wrench.force.x, w.wrench.force.y = fx, fy
    return w


def _js(x, xd, f=0.0, sec=0):
    m = JointState()
    m.header.stamp.sec = sec
    m.position, m.velocity, m.effort = [x, 0.0], [xd, 0.0], [f, 0.0]
    return m


def _fam_control_points(fy=0.05):
    from catheter_shape import fit_bezier
    from fam_solver import Catheter, Loads, solve_fam
    cl = solve_fam(Catheter(length=0.065, ei=6e-5), Loads(tip_force=(0.0, fy))).centerline(200)
    return fit_bezier(np.c_[cl, np.zeros(len(cl))], degree=3)


def _finite_last(rig, topic):
    out = _outputs(rig, topic)
    assert out, f'nothing on {topic}'
    f = out[-1].wrench.force
    assert math.isfinite(f.x) and math.isfinite(f.y)
    return out[-1]


def ima(rig):
    reset_params(rig)
    n = _count(rig)
    rig.feed(T.MASTER_COMMAND, _cmd(0.03, 0.01))
    rig.feed(T.MASTER_LINK_IMPEDANCE, _good_linear_model())
    rig.tick(5)
    assert _count(rig) > n
    assert abs(_finite_last(rig, T.MASTER_RENDERED_FORCE).wrench.force.x) <= 2.0


def dfr(rig):
    reset_params(rig)
    rig.feed(T.MASTER_LINK_FORCE, _wrench(0.3))
    rig.tick(2)
    assert _finite_last(rig, T.MASTER_RENDERED_FORCE).wrench.force.x == 0.3


def feed_clean_samples(rig, n=400):
    for k in range(n):
        t = k * 1e-3
        x = 0.03 + 0.01 * math.sin(3 * t)
        xd = 0.03 * math.cos(3 * t)
        rig.feed(T.SLAVE_JOINT_STATE, _js(x, xd, 2.0 * xd + 30.0 * x))
        rig.tick(1)


def identifier(rig):
    """The node keeps taking samples and says how it is (whether the identifier itself
    recovers is the core's: test_fuzz_core_dependent.py)."""
    reset_params(rig)
    n = rig.node.diag.get('samples') + rig.node.diag.get('update_errors')
    feed_clean_samples(rig)
    assert rig.node.diag.get('samples') + rig.node.diag.get('update_errors') == n + 400
    assert rig.node.diag.status().message


def haptic(rig):
    reset_params(rig)
    n = _count(rig, T.MASTER_COMMAND)
    rig.feed(T.MASTER_RENDERED_FORCE, _wrench(0.1))
    rig.tick(5)
    assert _count(rig, T.MASTER_COMMAND) >= n + 5


def slave(rig):
    reset_params(rig)
    n = _count(rig, T.SLAVE_JOINT_STATE)
    rig.feed(T.MASTER_COMMAND, _cmd(0.02, 0.0))
    rig.tick(5)
    assert _count(rig, T.SLAVE_JOINT_STATE) >= n + 5


def camera(rig):
    reset_params(rig)
    n = _count(rig, T.CAMERA_IMAGE)
    rig.feed(T.SLAVE_JOINT_STATE_DECIMATED, _js(0.05, 0.0))
    rig.tick(2)
    assert _count(rig, T.CAMERA_IMAGE) > n


def estimator(rig):
    reset_params(rig)
    cp = _fam_control_points()
    msg = PoseArray()
    msg.header.frame_id = T.FRAME_CATHETER_BASE
    msg.header.stamp.sec = 4242
    msg.poses = [Pose(position=Point(x=p[0], y=p[1], z=p[2])) for p in cp]
    rig.feed(T.CONTROL_POINTS, msg)
    out = _finite_last(rig, T.TIP_WRENCH)
    assert out.header.stamp.sec == 4242 and abs(out.wrench.force.y - 0.05) < 0.02


def shape(rig):
    from catheter_common.images import array_to_image
    from catheter_shape.camera import SYSTEM_CAMERA, SyntheticCamera
    reset_params(rig)
    s = np.linspace(0, 1, 300)
    th = 0.6
    arc = np.c_[0.065 * np.sin(s * th) / th, 0.065 * (1 - np.cos(s * th)) / th]
    frame = SyntheticCamera(**SYSTEM_CAMERA, noise=2.0, seed=1).render(arc).image
    from builtin_interfaces.msg import Time
    rig.feed(T.CAMERA_IMAGE, array_to_image(frame, Time(sec=77), T.FRAME_CAMERA))
    rig.tick(2)
    out = _outputs(rig, T.CONTROL_POINTS)
    obs = rig.node._last_obs
    assert out, (obs.status, obs.message) if obs is not None else 'not processed'
    assert out[-1].header.stamp.sec == 77 and len(out[-1].poses) == 4


def fam(rig):
    reset_params(rig)
    w = _wrench(0.01, 0.123)
    w.header.stamp.sec = 99
    rig.feed(T.TIP_LOAD, w)
    rig.tick(1)
    out = _outputs(rig, T.FAM_SHAPE)
    assert out and out[-1].header.stamp.sec == 99 and len(out[-1].poses) == 50


def source(rig):
    reset_params(rig)
    w = _wrench(0.0, 0.2)
    w.header.stamp.sec = 500
    rig.feed(T.TIP_WRENCH, w)
    rig.feed(T.SLAVE_JOINT_STATE, _js(0.03, 0.0, 0.5, sec=500))
    out = _outputs(rig, T.SLAVE_JOINT_STATE_IMAGE)
    assert out and out[-1].effort[0] == 0.2


HEALTHY = {
    'ima_master_node': ima, 'dfr_master_node': dfr, 'impedance_identifier_node': identifier,
    'sim_haptic_node': haptic, 'sim_slave_node': slave, 'camera_node': camera,
    'force_estimator_node': estimator, 'fam_estimator_node': estimator,
    'hybrid_estimator_node': estimator, 'shape_node': shape,
    'fam_solver_node': fam,
    'force_source_node': source,
}

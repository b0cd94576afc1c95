"""Node-level tests of issue 10 that need the CORE fixes other branches are making; on a
branch without them these fail, for the reason each docstring gives. Nothing here is
skipped or marked xfail: a failure says the core still lets the defect through.

- the renderer must never produce a non-finite force and must recover by itself after an
  absurd model (item 1; the node replaces a NaN by 0 N, but that is the last line only);
- one outlier sample must not poison the identifier (item 2), and a tampered, finite state
  file must not give an absurd model (item 5);
- the force estimator must not publish absurd forces: FAM inversion of a straight catheter,
  learned models with tampered weights (item 4);
- the cores must answer a finite input with a result or a ValueError of their own, not an
  exception from numpy / OpenCV (the fuzz found LinAlgError in the identifier, OpenCV's
  adaptiveThreshold assertion in the shape sensor).

Marked `core_dependent`: `pytest -m "not core_dependent"` runs everything else.
"""
import json
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from rclpy.parameter import Parameter

from catheter_common import topics as T
from harness import Rig, events
from healthy import _good_linear_model, _js, feed_clean_samples

pytestmark = [pytest.mark.ros, pytest.mark.core_dependent]


def _fuzz(rig, key, examples=60, params=False):
    @settings(max_examples=examples, deadline=None, database=None,
              suppress_health_check=list(HealthCheck))
    @given(events(key, params=params))
    def run(evs):
        rig.run(evs)
    run()


def _last_force(rig, topic=T.MASTER_RENDERED_FORCE):
    return rig.outputs[T.resolve(topic, rig.node.get_namespace())][-1].wrench.force.x


def _model_msg(m, c, k, offset=0.0):
    msg = _good_linear_model()
    msg.position = [m, c, k, offset, 1.0, 0.0]
    return msg


def test_renderer_never_returns_a_non_finite_force_under_fuzz(ros):
    """Core: ImaRenderer's output is finite for any finite model and state (issue 10 item 1:
    the clamp min(max(f, -limit), limit) lets NaN through)."""
    rig = Rig(ros, 'ima_master_node')
    _fuzz(rig, 'ima_master_node')
    assert rig.node.diag.get('nonfinite_outputs') == 0, \
        f'{rig.node.diag.get("nonfinite_outputs")} non-finite renderer outputs replaced by 0 N'


@pytest.mark.parametrize('poison', ['nan', 'k1e300'])
def test_renderer_recovers_after_an_absurd_model(ros, poison):
    """Core: after an absurd model the renderer drops it and renders the next good model
    (issue 10 item 1: NaN stuck for 8 s; after k = 1e300, +2.0 N for 2 s instead of 0.1 N)."""
    rig = Rig(ros, 'ima_master_node')
    if poison == 'nan':
        rig.feed(T.MASTER_LINK_IMPEDANCE, _model_msg(1e308, -1e308, 2.0))
        rig.feed(T.MASTER_COMMAND, _command(0.03, 2.0, 2.0))
    else:
        rig.feed(T.MASTER_COMMAND, _js(0.03, 0.0))
        rig.feed(T.MASTER_LINK_IMPEDANCE, _model_msg(0.0, 0.0, 1e300))
    rig.tick(50)
    good = _model_msg(0.0, 2.0, 3.0, 0.0)          # 0.09 N at x = 30 mm, at rest
    rig.feed(T.MASTER_LINK_IMPEDANCE, good)
    rig.feed(T.MASTER_COMMAND, _js(0.03, 0.0))
    rig.tick(1000)                                  # 1 s of good data
    f = _last_force(rig)
    assert math.isfinite(f) and abs(f - 0.09) < 0.01, f'rendered {f} N, the model says 0.09 N'
    energy = rig.node.renderer.energy
    assert math.isfinite(energy), f'passivity energy {energy}'


def _command(x, xd, xdd):
    m = _js(x, xd)
    m.effort = [xdd, 0.0]        # /master/command carries the acceleration in effort
    return m


def _identifier_force(node, x=0.03, xd=0.02):
    return node.model.force(x, xd, 0.0, None) if node.model.kind == 0 else \
        node.model.force(x, xd, 0.0, node.model.make_state().steady(xd))


@pytest.mark.parametrize('outlier', ['effort', 'position', 'velocity'])
def test_one_outlier_sample_does_not_poison_the_identifier(ros, outlier):
    """Core: one sample of 1e6 N (or a position / velocity of 1e300) moves the published
    model by little and the identifier returns to the clean one (issue 10 item 2: 0.19 N
    became 105 N at 0.02 m/s, still 48 N after 12 s; a 1e300 position left it
    ill_conditioned for ever)."""
    clean = Rig(ros, 'impedance_identifier_node', namespace='/clean')
    dirty = Rig(ros, 'impedance_identifier_node', namespace='/dirty')
    for rig in (clean, dirty):
        feed_clean_samples(rig, 2000)
    bad = {'effort': _js(0.03, 0.02, 1e6), 'position': _js(1e300, 0.02, 0.5),
           'velocity': _js(0.03, 1e300, 0.5)}[outlier]
    dirty.feed(T.SLAVE_JOINT_STATE, bad)
    for rig in (clean, dirty):
        feed_clean_samples(rig, 3000)
    assert dirty.node.ident.status == 'ok', dirty.node.ident.status
    fc, fd = _identifier_force(clean.node), _identifier_force(dirty.node)
    assert abs(fd - fc) <= 0.1 * abs(fc) + 0.01, f'clean {fc} N, after one outlier {fd} N'


def test_a_tampered_state_file_gives_no_absurd_model(ros, tmp_path):
    """Core: a finite but tampered state (b x 1e6) is validated against the model envelope
    (issue 10 item 5: it loaded silently and published a valid +-72 334 N model)."""
    from impedance_master.identification import make_identifier
    ident = make_identifier(window=1.0)
    for k in range(3000):
        t = k * 1e-3
        x = 0.03 + 0.01 * math.sin(3.0 * t)
        xd = 0.03 * math.cos(3.0 * t)
        ident.update(x, xd, 0.0, 0.1 * math.copysign(1, xd) + 2.0 * x)
    state = ident.get_state()
    state['b'] = [v * 1e6 for v in state['b']]
    path = tmp_path / 'tampered.json'
    path.write_text(json.dumps(state))
    from node_cases import make_node
    node = make_node(ros, 'impedance_identifier_node', state_file=str(path))
    if node.model is not None and node.model.valid:
        f = _identifier_force(node)
        assert abs(f) < 10.0, f'a loaded state gives {f} N at 30 mm, 0.02 m/s'


def _straight_cp():
    from geometry_msgs.msg import Point, Pose, PoseArray
    msg = PoseArray()
    msg.header.frame_id = T.FRAME_CATHETER_BASE
    msg.poses = [Pose(position=Point(x=0.065 * i / 3, y=0.0, z=0.0)) for i in range(4)]
    return msg


def test_fam_inversion_of_a_straight_catheter_is_no_force(ros):
    """Core: straight 65 mm control points are no tip force (issue 10 item 4: 0.675 N)."""
    rig = Rig(ros, 'force_estimator_node')
    assert rig.node.set_parameters([Parameter('method', value='fam')])[0].successful
    rig.feed(T.CONTROL_POINTS, _straight_cp())
    out = rig.outputs.get(T.TIP_WRENCH, [])
    assert out, rig.node.diag.level()
    f = out[-1].wrench.force
    assert math.hypot(f.x, f.y) < 0.02, f'straight catheter -> {f.x}, {f.y} N'


@pytest.mark.parametrize('method', ['svr', 'mlp'])
def test_a_model_file_with_absurd_weights_is_refused(ros, tmp_path, method):
    """Core: model files are validated on load (issue 10 item 4: weights x 1e200 loaded and
    published 1.4e200 N). The node's model parameter must refuse such a file."""
    from force_estimator.models import shipped_model_path
    with np.load(shipped_model_path(f'blazer-{method}'), allow_pickle=False) as data:
        arrays = {k: np.array(data[k]) for k in data.files}
    for k, a in arrays.items():
        if k != 'header' and a.dtype.kind == 'f':
            arrays[k] = a * 1e200
    path = tmp_path / f'tampered-{method}.npz'
    np.savez(path, **arrays)
    rig = Rig(ros, 'force_estimator_node')
    res = rig.node.set_parameters([Parameter(f'{method}_model', value=str(path))])[0]
    assert not res.successful, 'a model file with weights x 1e200 was accepted'


@pytest.mark.parametrize('method', ['svr', 'mlp'])
def test_learned_estimates_stay_in_the_force_range_under_fuzz(ros, method):
    """Core: no published estimate above 1.5 x the 0.3 N training range (issue 10 item 4:
    the MLP extrapolated to kilonewtons)."""
    rig = Rig(ros, 'force_estimator_node')
    assert rig.node.set_parameters([Parameter('method', value=method)])[0].successful
    worst = [0.0]
    orig = rig.checks[T.TIP_WRENCH]

    def check(msg):
        orig(msg)
        worst[0] = max(worst[0], math.hypot(msg.wrench.force.x, msg.wrench.force.y))
    rig.checks[T.TIP_WRENCH] = check
    _fuzz(rig, 'force_estimator_node', examples=60)
    assert worst[0] <= 0.45, f'published {worst[0]} N'


@pytest.mark.parametrize('key,counter,params', [
    ('impedance_identifier_node', 'update_errors', False),
    ('fam_solver_node', 'solve_errors', False)])      # (FAM with bezier arcs: ~1 s a load)
def test_cores_answer_finite_input_without_foreign_exceptions(ros, key, counter, params):
    """Core: a finite input gives a result or the core's own ValueError, never an exception
    from inside numpy or OpenCV (the node catches them and counts `counter`)."""
    rig = Rig(ros, key)
    _fuzz(rig, key, examples=40, params=params)
    assert rig.node.diag.get(counter) == 0, rig.node.diag.level()


def test_the_shape_sensor_answers_a_coarse_calibration_with_a_status(ros):
    """Core: with method adaptive and a calibration of 0.5 m per pixel the shape sensor raised
    OpenCV's `blockSize % 2 == 1 && blockSize > 1` assertion (found by the fuzz, 476 frames of
    the benchmark) instead of returning a status such as bad_input."""
    from builtin_interfaces.msg import Time
    from catheter_common.images import array_to_image
    psi = [0.5, 0.0, 0.0, 0.0, 0.0, 0.5, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
    from node_cases import make_node
    node = make_node(ros, 'shape_node', psi=psi, method='adaptive')
    frame = np.full((12, 35), 220, np.uint8)
    frame[4:6, :] = 20
    from geometry_msgs.msg import PoseArray
    probe = ros.node('coarse_probe')
    from catheter_common.qos import QOS_SENSOR
    probe.create_subscription(PoseArray, T.CONTROL_POINTS, lambda m: None, QOS_SENSOR)
    assert ros.spin_until(lambda: node.pub_cp.get_subscription_count() > 0, 10.0)
    node._on_image(array_to_image(frame, Time(), T.FRAME_CAMERA))
    node._process()
    assert node.diag.get('processed') + node.diag.get('sensor_errors') == 1
    assert node.diag.get('sensor_errors') == 0, node.diag.level()

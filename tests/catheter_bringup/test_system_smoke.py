"""The real node graph (whatever of it exists) in the smoke scenario: it runs, loses nothing,
two runs with one seed record the same streams, reprocess reproduces every node, and the
main command writes its files. Skipped while the teleoperation nodes are not importable."""
import json
import math

import pytest
from mcap_ros2.reader import read_ros2_messages

from catheter_bringup.runner import ScenarioRunner
from catheter_bringup.scenario import load_scenario

pytest.importorskip('impedance_master.ima_master_node')
pytest.importorskip('sim_slave.sim_slave_node')


def _decoded(path):
    return [(m.channel.topic, m.log_time_ns, repr(m.ros_msg)) for m in read_ros2_messages(str(path))
            if m.channel.topic != '/diagnostics']


@pytest.fixture(scope='module')
def smoke_runs(tmp_path_factory):
    d = tmp_path_factory.mktemp('smoke')
    out = []
    for k in range(2):
        sc = load_scenario('smoke')
        sc['duration'] = 1.0
        res = ScenarioRunner(sc, bag=str(d / f'{k}.mcap'), progress=False,
                             log=lambda *_: None).run()
        out.append(res)
    return out


def test_smoke_runs_complete_without_loss(smoke_runs):
    res = smoke_runs[0]
    assert res.status == 'complete', res.reason
    assert {'sim_slave_node', 'sim_haptic_node', 'ima_master_node'} <= set(res.nodes)
    assert res.lost == {}
    assert res.published['/slave/force'] == 1000
    assert res.recorded['/master/rendered_force'] == 1000


def test_two_runs_with_one_seed_are_identical(smoke_runs):
    a, b = (_decoded(r.bag) for r in smoke_runs)
    assert len(a) > 5000 and a == b


def test_reprocess_reproduces_every_node(smoke_runs):
    from catheter_bringup.reprocess import format_results, reprocess
    res = reprocess(smoke_runs[0].bag, log=lambda *_: None)
    assert {'sim_slave_node', 'ima_master_node'} <= set(res)
    assert all(c['ok'] for c in res.values()), format_results(res)


def test_main_command_writes_metrics_and_plots(tmp_path, capsys):
    from catheter_bringup.main import main
    code = main(['smoke', '--duration', '1.0', '--out', str(tmp_path),
                 '--bag', str(tmp_path / 'smoke.mcap'), '--no-fam'])
    assert code == 0
    text = capsys.readouterr().out
    assert 'Force tracking at the master' in text and 'thesis MAE' in text
    m = json.loads((tmp_path / 'smoke_metrics.json').read_text())
    assert m['status'] == 'complete' and 'ima' in m['force_tracking']
    assert (tmp_path / 'smoke_tracking.png').stat().st_size > 10_000
    assert (tmp_path / 'smoke_errors.png').exists()


def _in_file_order(path):
    """Every message as written: (topic, log time, decoded); /diagnostics in its place,
    without its timing values."""
    return [(m.channel.topic, m.log_time_ns,
             '' if m.channel.topic == '/diagnostics' else repr(m.ros_msg))
            for m in read_ros2_messages(str(path), log_time_order=False)]


def test_full_default_graph_with_image_pipeline_is_deterministic(tmp_path):
    """The lockstep regression check of the default scenario: the run with the vision chain
    in a process of its own (the default, `lockstep_peer`) records what the one-process
    run records: the same messages, log times and order (1.05 s: the first /diagnostics
    of every node, at 1 s, included)."""
    pytest.importorskip('sim_slave.camera_node')
    pytest.importorskip('catheter_shape.shape_node')
    pytest.importorskip('force_estimator.force_estimator_node')
    runs = []
    for processes in (1, 2):
        sc = load_scenario('experiment_ii')
        sc['duration'] = 1.05
        sc['lockstep_processes'] = processes
        res = ScenarioRunner(sc, bag=str(tmp_path / f'{processes}.mcap'), progress=False,
                             log=lambda *_: None).run()
        assert res.status == 'complete', res.reason
        assert {'camera_node', 'shape_node', 'force_estimator_node'} <= set(res.nodes)
        assert ('vision' in res.processes) == (processes == 2)
        assert res.lost == {}
        runs.append(_in_file_order(res.bag))
    assert sum(1 for t, _, _ in runs[0] if t == '/catheter/tip_wrench') >= 25
    assert sum(1 for t, _, _ in runs[0] if t == '/diagnostics') == 8
    assert runs[0] == runs[1]


def test_image_force_source_scenario_feeds_the_identifier(tmp_path):
    """force_source: image (never run in tests before): force_source_node puts the image-based
    tip force into the identifier's joint state and the identifier takes it."""
    pytest.importorskip('catheter_shape.shape_node')
    pytest.importorskip('force_estimator.force_estimator_node')
    sc = load_scenario('experiment_ii_image_source')
    sc['duration'] = 0.5
    sc['record']['only'] = ['/slave/joint_state_image', '/catheter/tip_wrench']
    res = ScenarioRunner(sc, bag=str(tmp_path / 'img.mcap'), progress=False,
                         log=lambda *_: None).run()
    assert res.status == 'complete', res.reason
    assert 'force_source_node' in res.nodes and 'impedance_identifier_node' in res.nodes
    assert res.published['/slave/joint_state_image'] == 500
    assert res.published['/catheter/tip_wrench'] >= 10
    msgs = [m.ros_msg for m in read_ros2_messages(str(res.bag),
                                                  topics=['/slave/joint_state_image'])]
    wrenches = [m.ros_msg for m in read_ros2_messages(str(res.bag),
                                                      topics=['/catheter/tip_wrench'])]
    estimates = {round(math.hypot(w.wrench.force.x, w.wrench.force.y), 12) for w in wrenches}
    # after the first estimate, the insertion effort is an image estimate, not the load cell's
    replaced = [m for m in msgs[-100:] if round(m.effort[0], 12) in estimates]
    assert len(replaced) == 100

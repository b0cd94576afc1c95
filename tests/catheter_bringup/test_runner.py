"""The launchless runner on the tests' own small nodes: node selection, lockstep timing,
determinism, recording counts, failure and interruption handling."""
import json

import pytest
from mcap_ros2.reader import read_ros2_messages

from catheter_bringup.recorder import read_run_metadata
from catheter_bringup.runner import ScenarioRunner
from catheter_bringup.scenario import resolve_nodes


def _decoded(path):
    """(topic, log time, decoded message as text): CDR alignment padding bytes written by
    rclpy's serializer are not initialised, so streams are compared decoded."""
    return [(m.channel.topic, m.log_time_ns, repr(m.ros_msg))
            for m in read_ros2_messages(str(path))]


def _raw(path):
    from mcap.reader import make_reader
    with open(path, 'rb') as f:
        r = make_reader(f)
        return [(c.topic, m.log_time, m.data) for _, c, m in r.iter_messages(log_time_order=True)]


def test_resolution_starts_only_needed_nodes(make_scenario, test_registry):
    sc = make_scenario(outputs=['/test/relayed'])
    order, missing = resolve_nodes(sc, None, test_registry)
    assert [i.name for i in order] == ['relay', 'talker']
    assert missing == []
    sc = make_scenario(outputs=['/test/relayed', '/test/missing'])
    order, missing = resolve_nodes(sc, {'relay', 'talker'}, test_registry)
    assert missing == ['/test/missing']


def test_lockstep_run_records_every_message(tmp_path, make_scenario, test_registry):
    bag = tmp_path / 'run.mcap'
    res = ScenarioRunner(make_scenario(), bag=str(bag), registry=test_registry,
                         progress=False).run()
    assert res.status == 'complete', res.reason
    assert res.nodes == ['fake_camera', 'relay', 'talker']   # not 'unused', not 'failing'
    assert res.steps == 300
    # 1 kHz timer on a 1 ms lockstep clock: one message per step (t = 1..300 ms)
    assert res.published['/test/force'] == 300
    assert res.published['/test/relayed'] == 300
    assert res.published['/test/image'] == 9                 # 30 Hz over 0.3 s
    assert res.lost == {}
    meta = read_run_metadata(bag)
    assert meta['status'] == 'complete'
    assert json.loads(meta['counts'])['/test/force'] == 300
    msgs = _raw(bag)
    force_times = [t for topic, t, _ in msgs if topic == '/test/force']
    assert force_times == [k * 1_000_000 for k in range(1, 301)]


def test_lockstep_delivers_to_callbacks_that_take_message_info(tmp_path, make_scenario,
                                                               test_registry):
    import sys
    import types

    import nodes_for_tests as n
    from catheter_bringup.scenario import NodeSpec
    mod = types.ModuleType('bringup_test_nodes_InfoRelayNode')
    mod.NODE_CLASS = n.InfoRelayNode
    sys.modules[mod.__name__] = mod
    registry = dict(test_registry, info_relay=NodeSpec(
        'info_relay', mod.__name__, ('/test/force',), ('/test/info_relayed',)))
    res = ScenarioRunner(make_scenario(outputs=['/test/info_relayed', '/test/relayed']),
                         bag=str(tmp_path / 'info.mcap'), registry=registry,
                         progress=False).run()
    assert res.status == 'complete', res.reason
    assert res.published['/test/info_relayed'] == res.published['/test/relayed'] == 300


def test_two_runs_with_one_seed_record_identical_streams(tmp_path, make_scenario,
                                                          test_registry):
    a, b, c = (tmp_path / f'{n}.mcap' for n in 'abc')
    ScenarioRunner(make_scenario(), bag=str(a), registry=test_registry, progress=False).run()
    ScenarioRunner(make_scenario(), bag=str(b), registry=test_registry, progress=False).run()
    da = _decoded(a)
    assert len(da) > 600
    assert da == _decoded(b)
    sc = make_scenario(global_params={'seed': 5})
    ScenarioRunner(sc, bag=str(c), registry=test_registry, progress=False).run()
    assert da != _decoded(c)


def test_failing_node_stops_run_and_closes_recording(tmp_path, make_scenario, test_registry):
    bag = tmp_path / 'fail.mcap'
    sc = make_scenario(duration=2.0, outputs=['/test/failing', '/test/relayed'],
                       nodes={'failing': {'params': {'fail_at': 0.25}}})
    res = ScenarioRunner(sc, bag=str(bag), registry=test_registry, progress=False).run()
    assert res.status == 'failed'
    assert 'simulated node failure' in res.reason
    assert 0.2 <= res.sim_time <= 0.3
    meta = read_run_metadata(bag)
    assert meta['status'] == 'failed' and 'simulated node failure' in meta['reason']
    assert 0.2 <= float(meta['sim_time_reached_s']) <= 0.3
    assert len(_raw(bag)) > 0


def test_a_node_whose_close_fails_costs_nothing_else(tmp_path, make_scenario, test_registry):
    """The teardown logs the failed close and goes on: the other nodes are closed, the run
    ends complete and its recording is closed with every message."""
    import nodes_for_tests
    bag = tmp_path / 'badclose.mcap'
    lines = []
    talkers = []
    real_init = nodes_for_tests.TalkerNode.__init__

    def keep(self, **kw):
        real_init(self, **kw)
        talkers.append(self)

    nodes_for_tests.TalkerNode.__init__ = keep
    try:
        res = ScenarioRunner(make_scenario(outputs=['/test/relayed', '/test/bad_close']),
                             bag=str(bag), registry=test_registry, progress=False,
                             log=lines.append).run()
    finally:
        nodes_for_tests.TalkerNode.__init__ = real_init
    assert res.status == 'complete', res.reason
    assert "[run] error closing bad_close: OSError('disk full while saving')" in lines
    assert talkers and all(t.closed for t in talkers)
    meta = read_run_metadata(bag)
    assert meta['status'] == 'complete'
    assert json.loads(meta['counts'])['/test/bad_close'] == res.published['/test/bad_close'] > 0


def test_interrupt_closes_recording(tmp_path, make_scenario, test_registry):
    bag = tmp_path / 'int.mcap'
    r = ScenarioRunner(make_scenario(duration=2.0), bag=str(bag), registry=test_registry,
                       progress=False)

    def stop(t):
        if t >= 0.1:
            raise KeyboardInterrupt
    r.on_step = stop
    res = r.run()
    assert res.status == 'interrupted'
    meta = read_run_metadata(bag)
    assert meta['status'] == 'interrupted'
    assert abs(float(meta['sim_time_reached_s']) - 0.1) < 0.0015
    assert int(meta['last_log_time_ns']) <= 100_000_000
    assert len([m for m in _raw(bag) if m[0] == '/test/force']) == 100


def test_realtime_run(tmp_path, make_scenario, test_registry):
    bag = tmp_path / 'rt.mcap'
    sc = make_scenario(mode='realtime', duration=0.5, outputs=['/test/relayed'])
    res = ScenarioRunner(sc, bag=str(bag), registry=test_registry, progress=False).run()
    assert res.status == 'complete', res.reason
    assert res.published['/test/force'] > 50      # a 1 kHz timer on 2 shared, loaded cores
    assert res.lost == {}
    assert read_run_metadata(bag)['mode'] == 'realtime'


def test_bad_scenario_values_are_refused(make_scenario):
    with pytest.raises(ValueError, match='duration'):
        make_scenario(duration=float('nan'))
    with pytest.raises(ValueError, match='mode'):
        make_scenario(mode='fast')
    with pytest.raises(ValueError, match='force_source'):
        make_scenario(force_source='magic')
    with pytest.raises(ValueError, match='outages'):
        make_scenario(link={'outages': [[1.0]]})


def test_realtime_split_runs_image_nodes_in_a_worker_process(tmp_path, make_scenario,
                                                            test_registry, monkeypatch):
    import os
    import pathlib
    here = str(pathlib.Path(__file__).resolve().parent)
    monkeypatch.setenv('PYTHONPATH', here + os.pathsep + os.environ.get('PYTHONPATH', ''))
    bag = tmp_path / 'split.mcap'
    sc = make_scenario(mode='realtime', duration=1.5, outputs=['/test/relayed', '/test/image'],
                       nodes={'fake_camera': {'module': 'worker_camera_node', 'kind': 'vision',
                                              'produces': ['/test/image']}})
    logs = []
    r = ScenarioRunner(sc, bag=str(bag), registry=test_registry, progress=False,
                       log=logs.append)
    res = r.run()
    assert res.status == 'complete', res.reason
    assert any('worker process' in m for m in logs), logs
    assert 'fake_camera' in res.nodes and 'fake_camera' not in res.skipped
    assert res.lost == {}
    # the worker's frames reached the main process's recorder through DDS
    assert res.recorded.get('/test/image', 0) >= 15
    assert res.recorded['/test/relayed'] > 150


def test_setup_writes_the_run_start_record_before_the_first_step(tmp_path, make_scenario,
                                                                 test_registry):
    """Whoever drives the runner (run_scenario, scripts/run, a test), the file says what the
    run is as soon as it exists: a run killed before its first step still carries its
    scenario (read here from the unfinished file, as recover_bag does)."""
    import yaml
    from mcap.records import Metadata
    from mcap.stream_reader import StreamReader
    from catheter_bringup.recorder import RUN_START_METADATA
    bag = tmp_path / 'started.mcap'
    runner = ScenarioRunner(make_scenario(), bag=str(bag), registry=test_registry,
                            progress=False)
    runner.setup()
    started = sorted(runner.nodes)
    meta = []
    try:
        with open(bag, 'rb') as f:
            for r in StreamReader(f, skip_magic=False).records:
                if isinstance(r, Metadata):
                    meta.append(r)
    except Exception:  # noqa: BLE001 - an unfinished file ends in the middle of a record
        pass
    finally:
        runner.close()
    assert meta and meta[0].name == RUN_START_METADATA
    info = meta[0].metadata
    assert info['status'] == 'running' and info['scenario'] == runner.scenario['name']
    assert yaml.safe_load(info['scenario_yaml'])['name'] == runner.scenario['name']
    assert json.loads(info['nodes']) == started != []

"""Lockstep with the vision chain in a process of its own (`lockstep_peer`,
`lockstep_follower`): the recording is the one-process run's, message for message, log time
for log time, in the same order; a failing vision node, a cascade across the processes, an
interrupted run and a killed main process end cleanly and say what happened."""
import json
import os
import pathlib
import signal
import subprocess
import sys
import time

import pytest
from mcap_ros2.reader import read_ros2_messages

from catheter_bringup.lockstep_peer import vision_plan
from catheter_bringup.runner import ScenarioRunner
from catheter_bringup.scenario import load_scenario, resolve_nodes

HERE = pathlib.Path(__file__).resolve().parent


def decoded(path):
    """Every message in file order: (topic, log time, decoded message); /diagnostics without
    its content (timing values differ between any two runs) but with its place."""
    return [(m.channel.topic, m.log_time_ns,
             '' if m.channel.topic == '/diagnostics' else repr(m.ros_msg))
            for m in read_ros2_messages(str(path), log_time_order=False)]


@pytest.fixture
def importable(monkeypatch):
    """The test node modules importable by the vision process."""
    monkeypatch.setenv('PYTHONPATH', str(HERE) + os.pathsep + os.environ.get('PYTHONPATH', ''))


def sampler_scenario(make_scenario, **a_params):
    """talker (1 kHz) and relay in the main process; in the vision process a_sampler (before
    talker in start order: it sees the previous step's force), z_sampler (after it: this
    step's), which also takes a_sampler's output and echoes it (a cascade inside the vision
    process), and a 3 ms sampler whose topic a main-process sampler publishes too, after it
    in start order (in one step: the vision process's message first)."""
    node = {'module': 'lockstep_nodes', 'executable': 'sampler', 'kind': 'vision'}
    return make_scenario(duration=0.4, outputs=['/test/relayed', '/test/a', '/test/z',
                                                '/test/z_echo', '/test/m'], nodes={
        'n_sampler': dict(node, kind='node', consumes=['/test/force'], produces=['/test/m'],
                          params={'output': '/test/m', 'tag': 1.0}, always=True),
        'a_sampler': dict(node, consumes=['/test/force'], produces=['/test/a'],
                          params={'output': '/test/a', **a_params}),
        'm_sampler': dict(node, consumes=['/test/force'], produces=['/test/m'],
                          params={'output': '/test/m', 'period': 0.003, 'tag': 2.0}),
        'z_sampler': dict(node, consumes=['/test/a', '/test/force'],
                          produces=['/test/z', '/test/z_echo'],
                          params={'output': '/test/z', 'inputs': ['/test/a', '/test/force'],
                                  'echo': '/test/z_echo'})})


def run(sc, bag, registry, processes, **kw):
    sc = dict(sc)
    sc['lockstep_processes'] = processes
    logs = []
    res = ScenarioRunner(sc, bag=str(bag), registry=registry, progress=False,
                         log=logs.append, **kw).run()
    return res, logs


def vision_pid(logs):
    line = next(m for m in logs if 'vision process (pid' in m)
    return int(line.split('pid ')[1].split(')')[0])


def gone(pid, timeout=10.0):
    """True once `pid` is no longer a running process (exited and reaped, or a zombie)."""
    t_end = time.monotonic() + timeout
    while time.monotonic() < t_end:
        try:
            with open(f'/proc/{pid}/stat') as f:
                if f.read().rsplit(') ', 1)[1].split()[0] == 'Z':
                    return True
        except (OSError, IndexError):
            return True
        time.sleep(0.05)
    return False


def test_split_run_records_what_the_one_process_run_records(tmp_path, make_scenario,
                                                            test_registry, importable):
    sc = sampler_scenario(make_scenario)
    one, _ = run(sc, tmp_path / 'one.mcap', test_registry, 1)
    two, logs = run(sc, tmp_path / 'two.mcap', test_registry, 2)
    assert one.status == two.status == 'complete', (one.reason, two.reason)
    assert 'vision' not in one.processes and two.processes['vision']['status'] == 'complete'
    assert set(two.processes['vision']['nodes']) == {'a_sampler', 'm_sampler', 'z_sampler'}
    assert one.nodes == two.nodes and one.published == two.published
    assert two.lost == {} and two.recorded == one.recorded
    a, b = decoded(one.bag), decoded(two.bag)
    assert len(a) > 2000 and a == b
    # the order inside a step is the point: a_sampler runs before talker (the previous
    # step's force), z_sampler after it (this step's)
    from mcap_ros2.reader import read_ros2_messages as rd
    force = [m.ros_msg.wrench.force.x for m in rd(str(two.bag), topics=['/test/force'])]
    sa = [m.ros_msg.wrench.force.x for m in rd(str(two.bag), topics=['/test/a'])]
    sz = [m.ros_msg.wrench.force.y for m in rd(str(two.bag), topics=['/test/z'])]
    assert sa[1:200] == force[0:199] and sz[0:200] == force[0:200]
    assert gone(vision_pid(logs))


def test_a_publisher_that_works_only_while_subscribed_counts_the_vision_process(
        tmp_path, make_scenario, test_registry, importable, monkeypatch):
    """b_sampler (main process) publishes only while /test/b has a subscriber, and only
    y_sampler (vision process) takes it; /test/b is not recorded. In one process y_sampler's
    subscription counts from the start; so it must in two, whenever (here: never, no
    discovery between processes) DDS matches it across the processes."""
    monkeypatch.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'OFF')
    sc = sampler_scenario(make_scenario)
    node = {'module': 'lockstep_nodes', 'executable': 'sampler'}
    sc['nodes']['b_sampler'] = dict(node, kind='node', consumes=['/test/force'],
                                    produces=['/test/b'],
                                    params={'output': '/test/b', 'only_subscribed': True})
    sc['nodes']['y_sampler'] = dict(node, kind='vision', consumes=['/test/b'],
                                    produces=['/test/y'],
                                    params={'output': '/test/y', 'inputs': ['/test/b']})
    sc['outputs'] = list(sc['outputs']) + ['/test/y']
    sc['record']['exclude'] = list(sc['record']['exclude']) + ['/test/b']
    sc['duration'] = 0.2
    one, _ = run(sc, tmp_path / 'one.mcap', test_registry, 1)
    two, _ = run(sc, tmp_path / 'two.mcap', test_registry, 2)
    assert one.status == two.status == 'complete', (one.reason, two.reason)
    assert 'y_sampler' in two.processes['vision']['nodes']
    assert one.published['/test/b'] == two.published['/test/b'] == 200
    assert decoded(one.bag) == decoded(two.bag)


def test_a_failing_vision_node_fails_the_run_and_closes_everything(
        tmp_path, make_scenario, test_registry, importable):
    sc = sampler_scenario(make_scenario, fail_at=0.2)
    res, logs = run(sc, tmp_path / 'fail.mcap', test_registry, 2)
    assert res.status == 'failed'
    assert 'vision process' in res.reason and 'sampler failure at t=0.200' in res.reason
    assert res.processes['vision']['status'] == 'failed'
    # what both processes published was recorded (the main process ran ahead: all of it)
    assert res.lost == {}
    assert res.recorded['/test/a'] == 199          # 0.001 .. 0.199 s
    assert gone(vision_pid(logs))
    assert decoded(res.bag)                        # closed and readable


def test_a_cascade_across_the_processes_is_refused(tmp_path, make_scenario, test_registry,
                                                   importable):
    sc = sampler_scenario(make_scenario, echo='/test/a_echo')
    res, logs = run(sc, tmp_path / 'cross.mcap', test_registry, 2)
    assert res.status == 'failed'
    assert 'crosses the processes' in res.reason and 'lockstep_processes: 1' in res.reason
    assert gone(vision_pid(logs))
    ok, _ = run(sc, tmp_path / 'cross1.mcap', test_registry, 1)
    assert ok.status == 'complete' and ok.recorded['/test/a_echo'] == 400


def test_an_interrupted_split_run_records_every_step_it_ran(tmp_path, make_scenario,
                                                            test_registry, importable):
    sc = sampler_scenario(make_scenario)
    runner = ScenarioRunner(dict(sc), bag=str(tmp_path / 'int.mcap'), registry=test_registry,
                            progress=False, log=lambda *_: None)

    def stop_at(t):
        if t >= 0.15:
            runner.stop_requested = True
    runner.on_step = stop_at
    res = runner.run()
    assert res.status == 'interrupted' and res.reason == 'stop requested'
    assert res.lost == {} and res.recorded['/test/a'] == res.recorded['/test/force'] == 150
    assert res.processes['vision']['status'] == 'complete'


def start_long_run(tmp_path, make_scenario):
    """`run_scenario` on the sampler scenario for up to 600 s, in a session of its own (as a
    terminal's foreground job); returns (process, bag, vision pid) once the vision process
    has started and the run has gone on for a while."""
    import yaml
    sc = sampler_scenario(make_scenario)
    sc['duration'] = 600.0
    # the main process's nodes from the registry, as scenario entries (a separate process)
    sc['nodes']['talker'] = {'module': 'nodes_for_tests_talker', 'produces': ['/test/force']}
    (tmp_path / 'nodes_for_tests_talker.py').write_text(
        'from nodes_for_tests import TalkerNode as NODE_CLASS  # noqa: F401\n')
    path = tmp_path / 'long.yaml'
    path.write_text(yaml.safe_dump({k: v for k, v in sc.items() if k != 'source'}))
    env = dict(os.environ, PYTHONUNBUFFERED='1', PYTHONPATH=os.pathsep.join(
        [str(tmp_path), str(HERE), os.environ.get('PYTHONPATH', '')]))
    bag = tmp_path / 'long.mcap'
    proc = subprocess.Popen([sys.executable, '-m', 'catheter_bringup.run_scenario', str(path),
                             '--quiet', '--bag', str(bag)], stdout=subprocess.PIPE,
                            stderr=subprocess.DEVNULL, text=True, env=env,
                            start_new_session=True)
    pid = None
    for line in proc.stdout:
        if 'vision process (pid' in line:
            pid = int(line.split('pid ')[1].split(')')[0])
            break
    assert pid is not None
    t_end = time.monotonic() + 60
    while time.monotonic() < t_end and not (bag.exists() and bag.stat().st_size > 50_000):
        assert proc.poll() is None
        time.sleep(0.2)
    assert not gone(pid, timeout=0.1)
    return proc, bag, pid


def test_ctrl_c_stops_both_processes_and_records_everything(tmp_path, make_scenario,
                                                            importable):
    """SIGINT to the process group, as a terminal's Ctrl-C: the vision process ignores it and
    ends after the steps the main process completed; nothing published is missing."""
    from catheter_bringup.recorder import read_run_metadata
    proc, bag, pid = start_long_run(tmp_path, make_scenario)
    try:
        os.killpg(proc.pid, signal.SIGINT)
        code = proc.wait(timeout=120)
        out = proc.stdout.read()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert code == 0 and 'interrupted (SIGINT (Ctrl-C))' in out, out
    assert gone(pid, timeout=15.0)
    meta = read_run_metadata(bag)
    assert meta['status'] == 'interrupted' and meta['reason'] == 'SIGINT (Ctrl-C)'
    published = json.loads(meta['published'])
    counts = json.loads(meta['counts'])
    for topic in ('/test/force', '/test/a', '/test/z', '/test/z_echo', '/test/m'):
        assert counts[topic] == published[topic] > 0, topic
    assert counts['/test/a'] == counts['/test/force']   # both processes up to the last step


def test_the_vision_process_ends_when_the_main_process_is_killed(tmp_path, make_scenario,
                                                                 importable):
    proc, _bag, pid = start_long_run(tmp_path, make_scenario)
    try:
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
        assert gone(pid, timeout=15.0)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def test_the_plan_keeps_one_process_when_it_must():
    sc = load_scenario('experiment_ii')
    chosen, _ = resolve_nodes(sc)
    assert {i.name for i in vision_plan(sc, chosen)} == {'camera_node', 'shape_node',
                                                         'force_estimator_node'}
    assert vision_plan(sc, chosen, inject=lambda *_: []) == []     # reprocess
    for key, value in (('lockstep_processes', 1), ('mode', 'realtime'),
                       ('lockstep_transport', 'dds')):
        assert vision_plan(dict(sc, **{key: value}), chosen) == []
    # the identifier fits the image-based force: the 1 kHz loop consumes the vision chain
    img = load_scenario('experiment_ii_image_source')
    assert vision_plan(img, resolve_nodes(img)[0]) == []
    one = load_scenario('experiment_i')                           # no vision chain at all
    assert vision_plan(one, resolve_nodes(one)[0]) == []
    with pytest.raises(ValueError, match='lockstep_processes'):
        from catheter_bringup.scenario import validate_scenario
        validate_scenario(dict(sc, lockstep_processes=3))


def test_a_vision_process_that_cannot_start_is_reported(tmp_path):
    """The process dies before its start report (here: not even Python): a VisionError that
    says so, nothing left running."""
    from catheter_bringup.lockstep_peer import VisionError, VisionPeer
    plan = {'scenario': load_scenario('smoke'), 'registry': None, 'order': [], 'nodes': [],
            'record': False}
    peer = VisionPeer(plan, log=lambda *_: None, python='/bin/false')
    with pytest.raises(VisionError, match='ended before it started'):
        peer.wait_ready(timeout=30.0)
    assert not peer.running


def test_the_vision_processs_inputs_and_steps_are_counted_as_in_one_process(
        tmp_path, make_scenario, test_registry, importable):
    """A vision node subscribed to a topic nobody publishes: the split run's published counts
    are still the one-process run's (the vision process's inputs are not its own
    publishes); the vision process ran every step of the main process and step 0."""
    node = {'module': 'lockstep_nodes', 'executable': 'sampler', 'kind': 'vision'}
    sc = make_scenario(duration=0.1, outputs=['/test/relayed', '/test/a'], nodes={
        'a_sampler': dict(node, consumes=['/test/force'], produces=['/test/a'],
                          params={'output': '/test/a',
                                  'inputs': ['/test/force', '/test/nobody']})})
    one, _ = run(sc, tmp_path / 'one.mcap', test_registry, 1)
    two, _ = run(sc, tmp_path / 'two.mcap', test_registry, 2)
    assert one.status == two.status == 'complete', (one.reason, two.reason)
    assert 'a_sampler' in two.processes['vision']['nodes']
    assert '/test/nobody' not in one.published
    assert two.published == one.published
    assert one.steps == two.steps == 100
    assert two.processes['vision']['steps'] == two.steps + 1       # steps 0 .. 100


def test_a_vision_node_the_vision_process_cannot_start_is_listed_as_skipped(
        tmp_path, make_scenario, test_registry, importable):
    """A vision node whose module only the main process has (the tests' in-memory node
    modules): the vision process leaves it out and the run lists it as skipped."""
    sc = make_scenario(duration=0.05, outputs=['/test/relayed', '/test/image'], nodes={
        'fake_camera': {'kind': 'vision'}})
    cam = test_registry['fake_camera']
    import dataclasses
    registry = dict(test_registry, fake_camera=dataclasses.replace(cam, kind='vision'))
    two, _ = run(sc, tmp_path / 'two.mcap', registry, 2)
    assert two.status == 'complete', two.reason
    assert 'vision' in two.processes
    assert 'fake_camera' not in two.nodes and 'fake_camera' in two.skipped

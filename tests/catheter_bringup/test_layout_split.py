"""The deployment layout with real processes: `layout: split` starts a master process (haptic
device + renderers) and a slave process (robot, vessel, sensor, identifier); each records
what its nodes publish and the runner merges the parts into the bag; master and slave
exchange only the link topics, over DDS. A few seconds
of the smoke scenario: the link topics flow both ways, every node ran in the process the
layout says, and the recording holds every message the workers published (each records its
own nodes' messages; the runner merges them) and is readable by rosbags and mcap_ros2."""
import json
import pathlib

import pytest

from catheter_bringup.overrides import apply_overrides
from catheter_bringup.runner import ScenarioRunner
from catheter_bringup.scenario import LINK_TOPICS, load_scenario

pytestmark = pytest.mark.ros


@pytest.fixture(scope='module')
def split_run(tmp_path_factory):
    bag = tmp_path_factory.mktemp('split') / 'split.mcap'
    sc = apply_overrides(load_scenario('smoke'), ['mode=realtime', 'layout=split',
                                                  'duration=3.0'])
    logs = []
    res = ScenarioRunner(sc, bag=str(bag), progress=False, log=logs.append).run()
    return res, bag, logs


def test_split_layout_runs_each_group_in_its_own_process(split_run):
    res, _bag, logs = split_run
    assert res.status == 'complete', res.reason
    procs = {k: v for k, v in res.processes.items() if k != 'link'}
    assert set(procs) == {'master', 'slave'}, logs
    assert set(procs['master']['nodes']) == {'sim_haptic_node', 'ima_master_node',
                                            'dfr_master_node'}
    assert set(procs['slave']['nodes']) == {'sim_slave_node', 'impedance_identifier_node'}
    pids = [line for line in logs if 'process (pid' in line]
    assert len(pids) == 2, logs
    for rep in procs.values():
        # each worker ran until the runner stopped it (SIGINT), not failed
        assert rep['status'] == 'interrupted' and 'SIGINT' in rep['reason'], rep
        assert rep['realtime']['process'] in ('master', 'slave')


def test_link_topics_flow_between_the_processes(split_run):
    res, _bag, _logs = split_run
    link = res.processes['link']
    assert set(link) == {f'{LINK_TOPICS[0]} -> slave', f'{LINK_TOPICS[1]} -> master',
                         f'{LINK_TOPICS[2]} -> master'}
    for name, c in link.items():
        # a second of 1 kHz at least, and most of it arrived (best effort; 2 loaded cores)
        assert c['sent'] > 1000 and c['taken'] > 0.9 * c['sent'], (name, c)
        # the receiving subscription was watched for what DDS itself reports lost
        assert isinstance(c['dds_reported'], int) and c['dds_reported'] >= 0, (name, c)
    master = res.processes['master']
    # the master took the slave's force and impedance only from DDS, and the renderers
    # got the device's command through the process's own bus (not DDS)
    assert master['received'].get('/slave/force', 0) > 1000
    assert '/master/command' not in master['received']
    assert res.processes['slave']['received'].get('/master/command', 0) > 1000
    # each worker put on DDS only what the other process consumes (and /diagnostics):
    # the renderers' output, the hand force and the master's link copies stay in the process
    assert master['realtime']['dds_topics'] == ['/diagnostics', '/master/command']
    assert res.processes['slave']['realtime']['dds_topics'] == [
        '/diagnostics', '/slave/force', '/slave/impedance']
    streams = master['realtime']['streams']
    assert streams['/master/rendered_force']['n'] > 1000


def test_split_recording_is_complete_and_readable(split_run):
    res, bag, _logs = split_run
    from rosbags.highlevel import AnyReader
    from catheter_bringup.recorder import read_run_metadata
    meta = read_run_metadata(bag)
    assert meta['status'] == 'complete' and meta['mode'] == 'realtime'
    counts = {}
    with AnyReader([pathlib.Path(bag)]) as reader:
        for conn, _t, raw in reader.messages():
            reader.deserialize(raw, conn.msgtype)
            counts[conn.topic] = counts.get(conn.topic, 0) + 1
    # every stream, also those their nodes publish only while subscribed (nobody but the
    # recorder takes /master/hand_force and /master/dfr/rendered_force)
    for topic in ('/master/command', '/slave/force', '/master/rendered_force',
                  '/master/hand_force', '/master/dfr/rendered_force', '/slave/joint_state'):
        assert counts.get(topic, 0) > 100, counts
    # every worker recorded every message its nodes published (its part file), and the
    # bag holds all of them: nothing lost, per topic
    excluded = set(load_scenario('smoke')['record']['exclude'])
    expected = {}
    for name, rep in res.processes.items():
        if name == 'link':
            continue
        rec = {t: n for t, n in rep['published'].items() if t not in excluded}
        assert rep['recorded'] == rec, name
        for t, n in rec.items():
            expected[t] = expected.get(t, 0) + n
    assert res.recorded == expected
    # the run's published counts hold the workers' (this process runs no node)
    published = {}
    for name, rep in res.processes.items():
        for t, n in (rep['published'].items() if name != 'link' else ()):
            published[t] = published.get(t, 0) + n
    assert {t: n for t, n in res.published.items() if n} == \
        {t: n for t, n in published.items() if n}
    assert counts == {t: n for t, n in expected.items() if n}    # a reader sees no empty topic
    assert res.lost == {}
    # mcap_ros2 (another reader) decodes every message too; log times never go back
    from mcap_ros2.reader import read_ros2_messages
    times = [m.log_time_ns for m in read_ros2_messages(str(bag))]
    assert len(times) == sum(expected.values())
    assert times == sorted(times)
    parts = json.loads(meta['parts'])
    assert set(parts) == {'master', 'slave'} and all(p['complete'] for p in parts.values())
    assert not list(bag.parent.glob('*.part.mcap'))       # merged, then removed


def test_a_sigkilled_workers_messages_reach_the_bag(tmp_path):
    """SIGKILL to the master process mid-run: its part's writer process (`part_pipe`) takes
    every frame that reached the pipe and closes the part as interrupted, saying the worker
    ended without closing it; the runner waits for the writer, merges the part and says so."""
    import os
    import signal
    import threading
    import time
    from rosbags.highlevel import AnyReader
    from catheter_bringup.recorder import read_run_metadata
    bag = tmp_path / 'killed.mcap'
    sc = apply_overrides(load_scenario('smoke'), ['mode=realtime', 'layout=split',
                                                  'duration=3'])
    runner = ScenarioRunner(sc, bag=str(bag), progress=False, log=lambda *_: None)
    runner.setup()
    master = next(w for w in runner.children.workers if w.name == 'master')

    def kill():
        time.sleep(2.0)
        os.kill(master.proc.pid, signal.SIGKILL)

    threading.Thread(target=kill, daemon=True).start()
    res = runner.run()
    parts = json.loads(read_run_metadata(bag)['parts'])
    assert parts['master']['status'] == 'interrupted' and parts['master']['messages'] > 0
    assert 'without closing' in parts['master']['reason'], parts
    assert parts['slave']['complete'] and 'SIGINT' in parts['slave']['reason'], parts
    counts = {}
    with AnyReader([bag]) as reader:
        for conn, _t, raw in reader.messages():
            reader.deserialize(raw, conn.msgtype)
            counts[conn.topic] = counts.get(conn.topic, 0) + 1
    assert counts.get('/master/command', 0) > 0 and counts.get('/slave/force', 0) > 0
    assert sum(counts.values()) == sum(res.recorded.values()) == \
        parts['master']['messages'] + parts['slave']['messages']
    assert not list(tmp_path.glob('*.part.mcap'))

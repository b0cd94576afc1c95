"""A main-command-like run (Experiment II's graph with the image pipeline, every topic the main
command records, 1.5 s) read back by two independent readers: EVERY message of EVERY topic
deserialises in rosbags (AnyReader: the ROS2_JAZZY typestore plus the definitions the MCAP
carries) and in mcap_ros2, and a sample of messages equals, field by field, what the nodes
published."""
import copy
import pathlib

import pytest

from catheter_bringup.runner import ScenarioRunner
from catheter_bringup.scenario import load_scenario

from msg_tools import assert_same

pytest.importorskip('impedance_master.ima_master_node')
pytest.importorskip('sim_slave.camera_node')



def main_topics():
    """Every topic `scripts/run` (experiment_ii) records: what its nodes produce (the runner's
    registry, names from catheter_common.topics) and /diagnostics, less the excluded."""
    from catheter_bringup.scenario import resolve_nodes
    from catheter_common import topics as T
    sc = load_scenario('experiment_ii')
    nodes, _ = resolve_nodes(sc)
    produced = {t for inst in nodes for t in inst.spec.produces} | {T.DIAGNOSTICS}
    return produced - set(sc['record']['exclude'])


SAMPLE_EVERY = 97


def _capture_published(runner, store):
    """Keep a deep copy of every SAMPLE_EVERY-th message published on each topic, keyed by
    its index in the topic (= its index in the topic's recording: publish order; several
    publishers of one topic, like /diagnostics, share the count)."""
    counts = {}
    for node in runner.nodes.values():
        for pub in node.publishers:
            topic = pub.topic_name
            counts.setdefault(topic, 0)
            inner = pub.publish

            def publish(msg, _inner=inner, _topic=topic):
                k = counts[_topic]
                if k % SAMPLE_EVERY == 0 and not isinstance(msg, bytes):
                    store.setdefault(_topic, {})[k] = copy.deepcopy(msg)
                counts[_topic] = k + 1
                return _inner(msg)
            pub.publish = publish


@pytest.fixture(scope='module')
def main_like_run(tmp_path_factory):
    sc = load_scenario('experiment_ii')
    sc['duration'] = 2.2          # the first impedance model comes at ~1.6 s
    # every node in this process, where its publishes are captured (the run with the vision
    # chain in a process of its own records the same: test_lockstep_vision, test_system_smoke)
    sc['lockstep_processes'] = 1
    bag = tmp_path_factory.mktemp('main') / 'experiment_ii.mcap'
    runner = ScenarioRunner(sc, bag=str(bag), progress=False, log=lambda *_: None)
    runner.setup()
    published = {}
    _capture_published(runner, published)
    res = runner.run()
    assert res.status == 'complete', res.reason
    return res, pathlib.Path(bag), published


def test_every_message_reads_in_rosbags_and_matches_what_was_published(main_like_run):
    from rosbags.highlevel import AnyReader
    res, bag, published = main_like_run
    index = {}
    failures = []
    n = 0
    with AnyReader([bag]) as reader:
        topics = {c.topic for c in reader.connections}
        want = main_topics()
        assert len(want) >= 15 and want <= topics, want - topics
        for conn, _t, raw in reader.messages():
            k = index.get(conn.topic, 0)
            index[conn.topic] = k + 1
            n += 1
            try:
                msg = reader.deserialize(raw, conn.msgtype)
            except Exception as exc:  # noqa: BLE001 - count every failure
                failures.append((conn.topic, k, repr(exc)))
                continue
            sent = published.get(conn.topic, {}).get(k)
            if sent is not None:
                assert_same(msg, sent, f'{conn.topic}[{k}]')
    assert failures == []
    assert index == {t: c for t, c in res.recorded.items() if c}
    assert n == sum(res.recorded.values())
    compared = sum(len(v) for t, v in published.items() if t in index)
    assert compared >= 100
    assert {t for t in published if t in index} >= want


def test_every_message_reads_in_mcap_ros2(main_like_run):
    from mcap_ros2.reader import read_ros2_messages
    res, bag, published = main_like_run
    counts = {}
    for m in read_ros2_messages(str(bag)):
        counts[m.channel.topic] = counts.get(m.channel.topic, 0) + 1
        assert m.ros_msg is not None
    assert counts == {t: c for t, c in res.recorded.items() if c}
    # a field-by-field sample from this reader too (the 1 kHz force the hand feels)
    topic = '/master/hand_force'
    got = [m.ros_msg for m in read_ros2_messages(str(bag), [topic])]
    for k, sent in published[topic].items():
        assert got[k].wrench.force.x == sent.wrench.force.x
        assert got[k].header.stamp.nanosec == sent.header.stamp.nanosec


@pytest.mark.slow
def test_a_real_time_recording_reads_in_rosbags_too(tmp_path):
    """The real-time path (system clock, the same bus, 64 kB chunks): every message strict."""
    from rosbags.highlevel import AnyReader
    sc = load_scenario('smoke')
    sc['duration'] = 1.0
    res = ScenarioRunner(sc, bag=str(tmp_path / 'rt.mcap'), mode='realtime', progress=False,
                         log=lambda *_: None).run()
    assert res.status == 'complete', res.reason
    n = 0
    with AnyReader([pathlib.Path(res.bag)]) as reader:
        for conn, _t, raw in reader.messages():
            reader.deserialize(raw, conn.msgtype)
            n += 1
    assert n == sum(res.recorded.values()) > 500       # ~1 kHz x 7 topics on a quiet machine

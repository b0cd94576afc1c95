"""`recorder_node` in-process: by default it records every topic of the graph into
bags/recording_<date>.mcap under the workspace; with ``scenario`` its end record carries the
scenario's run information with ``mode: realtime`` (a launched graph runs on the system
clock), which analyze reads."""
import json

import pytest
from rclpy.parameter import Parameter

from catheter_bringup.recorder import read_run_metadata
from catheter_bringup.recorder_node import RecorderNode


@pytest.fixture
def harness():
    from catheter_common.ros_testing import RosHarness
    h = RosHarness()
    yield h
    h.close()


def test_the_default_records_every_topic_into_the_workspace_bags(harness, tmp_path,
                                                                    monkeypatch):
    from std_msgs.msg import String
    monkeypatch.setenv('CATHETER_WS_ROOT', str(tmp_path))
    rec = harness.add(RecorderNode(context=harness.context,
                                   parameter_overrides=[Parameter('discovery_period', value=0.05)]))
    assert rec.recorder.path.parent == tmp_path / 'bags'
    assert rec.recorder.path.name.startswith('recording_')
    talker = harness.node('rec_talker')
    pub = talker.create_publisher(String, '/rec_test/chatter', 10)

    def got():
        pub.publish(String(data='x'))
        return rec.recorder.counts.get('/rec_test/chatter', 0) > 0
    assert harness.spin_until(got, 8.0), rec.recorder.counts
    path = rec.recorder.path
    rec.close()
    meta = read_run_metadata(path)
    assert meta['status'] == 'complete'
    assert json.loads(meta['counts'])['/rec_test/chatter'] >= 1


def test_the_scenario_goes_into_the_end_record_as_a_realtime_run(harness, tmp_path):
    path = tmp_path / 'launched.mcap'
    rec = harness.add(RecorderNode(context=harness.context, parameter_overrides=[
        Parameter('path', value=str(path)), Parameter('scenario', value='smoke')]))
    rec.close()
    meta = read_run_metadata(path)
    assert meta['status'] == 'complete' and meta['scenario'] == 'smoke'
    assert meta['mode'] == 'realtime'
    assert 'mode: realtime' in meta['scenario_yaml']

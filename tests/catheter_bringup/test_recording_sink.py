"""RecordingSink's promises when something goes wrong (no data lost that can be kept): a
write that fails is counted and logged and the other topics keep recording; a buffered
step is written ordered by topic, stable within a topic, and one failed write does not stop
the flush; the lockstep clock sets the log time; a discovered topic whose type cannot be
imported is excluded with a warning, not a crash; our own lone publisher is skipped. The
subscriptions' callbacks are called directly with raw bytes (no DDS traffic needed)."""
from types import SimpleNamespace

import pytest
import rclpy
from rclpy.qos import QoSProfile

from catheter_bringup.ros_recording import RecordingSink
from catheter_common.ros_testing import CapturedLog, RosHarness, isolate_ros_env

pytestmark = pytest.mark.ros

WRENCH = 'geometry_msgs/msg/WrenchStamped'


class FakeRecorder:
    def __init__(self, failing=()):
        self.failing = set(failing)
        self.topics = {}
        self.written = []

    def add_topic(self, topic, type_name, qos=None):
        self.topics[topic] = (type_name, qos)

    def write(self, topic, data, t):
        if topic in self.failing:
            raise OSError(f'disk full writing {topic}')
        self.written.append((topic, t, data))


@pytest.fixture
def node():
    isolate_ros_env()
    h = RosHarness()
    n = rclpy.create_node('sink_test', context=h.context)
    h.add(n)
    yield n
    h.close()


def _deliver(sink, topic, data):
    sink.subs[topic].callback(data)


def test_a_failed_write_is_counted_and_the_other_topics_keep_recording(node):
    rec = FakeRecorder(failing={'/bad'})
    sink = RecordingSink(node, rec)
    sink.now_ns = iter(range(100, 200)).__next__
    assert sink.add('/good', WRENCH, [QoSProfile(depth=5)]) and sink.add('/bad', WRENCH)
    assert rec.topics['/good'][1][0]['depth'] == 5 and rec.topics['/bad'][1] is None
    for i in range(3):
        _deliver(sink, '/good', b'g%d' % i)
        _deliver(sink, '/bad', b'b%d' % i)
    assert sink.errors == 3 and sink.received == {'/good': 3, '/bad': 3}
    assert rec.written == [('/good', 100, b'g0'), ('/good', 102, b'g1'), ('/good', 104, b'g2')]
    assert not sink.add('/good', WRENCH)                       # already subscribed
    sink.destroy()
    assert sink.subs == {}


def test_a_buffered_step_is_written_by_topic_and_a_failed_write_does_not_stop_it(node):
    rec = FakeRecorder(failing={'/b'})
    sink = RecordingSink(node, rec)
    sink.buffered = True
    sink.now_ns = lambda: 7
    for t in ('/c', '/b', '/a'):
        sink.add(t, WRENCH)
    for topic, data in (('/c', b'c0'), ('/a', b'a0'), ('/b', b'b0'), ('/c', b'c1'),
                        ('/a', b'a1')):
        _deliver(sink, topic, data)
    assert rec.written == [] and sink.errors == 0
    sink.flush()
    assert [(t, d) for t, _, d in rec.written] == [('/a', b'a0'), ('/a', b'a1'),
                                                  ('/c', b'c0'), ('/c', b'c1')]
    assert sink.errors == 1 and sink._buffer == []
    sink.flush()                                               # nothing buffered: no-op
    assert len(rec.written) == 4


def test_only_and_exclude_choose_the_topics(node):
    sink = RecordingSink(node, FakeRecorder(), exclude=('/x',), only=('/x', '/y'))
    assert not sink.wants('/x') and sink.wants('/y') and not sink.wants('/z')
    assert not sink.add('/z', WRENCH) and sink.subs == {}


def test_discover_excludes_a_type_it_cannot_import_and_skips_our_own_publisher(node,
                                                                               monkeypatch):
    sink = RecordingSink(node, FakeRecorder())
    graph = [('/weird', ['no_such_pkg/msg/Nope']), ('/ours', [WRENCH]), ('/theirs', [WRENCH]),
             ('/silent', [WRENCH]), ('/untyped', [])]
    pubs = {'/weird': [('other', QoSProfile(depth=1))],
            '/ours': [('sink_test', QoSProfile(depth=1))],
            '/theirs': [('other', QoSProfile(depth=3)), ('sink_test', QoSProfile(depth=1))],
            '/silent': []}
    monkeypatch.setattr(node, 'get_topic_names_and_types', lambda: graph)
    monkeypatch.setattr(node, 'get_publishers_info_by_topic', lambda t: [
        SimpleNamespace(node_name=n, qos_profile=q) for n, q in pubs[t]])
    log = CapturedLog(node)
    assert sink.discover() == ['/theirs']
    assert '/weird' in sink.exclude and len(log) == 1 and '/weird' in log.texts('warning')[0]
    assert set(sink.subs) == {'/theirs'}
    assert sink.discover() == []                                # nothing new, no new warning
    assert len(log) == 1

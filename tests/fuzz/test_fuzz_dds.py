"""One real-DDS smoke test per node: the fuzz builders' messages (nasty values included) go
out on DDS from a probe node and come back to it from the node under test, serialised and
deserialised as in a deployment (the in-process fuzz feeds the callbacks directly). The
executor re-raises what a callback raises, so a crash fails the test; every message that
arrives is accounted for by the node's counters; outputs received over DDS hold only
finite floats."""
import math
import random

import pytest

from catheter_common import topics as T
from harness import FUZZ_NODES, float_values
from strategies import NASTY, Pick
from node_cases import make_node

pytestmark = pytest.mark.ros
PER_TOPIC = 40


@pytest.mark.parametrize('key', sorted(FUZZ_NODES))
def test_fuzz_messages_over_dds(ros, key):
    spec = FUZZ_NODES[key]
    node = make_node(ros, spec.name, **spec.params)
    probe = ros.node(f'dds_fuzz_probe_{key}')
    outputs, bad = [], []

    def seen(msg, topic):
        outputs.append(topic)
        bad.extend(f'{topic}.{p}={v}' for p, v in float_values(msg) if not math.isfinite(v))
    for pub in node.publishers:
        if pub.topic_name not in ('/parameter_events', '/rosout'):
            probe.create_subscription(pub.msg_type, pub.topic_name,
                                      lambda m, t=pub.topic_name: seen(m, t), pub.qos_profile)
    subs = {s.topic_name: s for s in node.subscriptions}
    pubs = {t: probe.create_publisher(subs[t].msg_type, t, subs[t].qos_profile)
            for t in spec.inputs}
    assert ros.spin_until(lambda: all(p.get_subscription_count() > 0 for p in pubs.values()),
                          10.0)
    pick = Pick([0.1, -0.3, 0.02, 0.5, -0.05] + NASTY, 7)
    rng = random.Random(3)
    for topic, inp in sorted(spec.inputs.items()):
        keys = inp.accounted
        for _ in range(PER_TOPIC):
            before = sum(node.diag.get(k) for k in keys)
            pubs[topic].publish(inp.build(pick))
            # best effort, depth 1: one message at a time, until the node took it
            def taken(keys=keys, before=before):
                return sum(node.diag.get(k) for k in keys) > before
            assert ros.spin_until(taken, 5.0), f'{topic}: message not taken'
            assert sum(node.diag.get(k) for k in keys) == before + 1
            if rng.random() < 0.3:
                ros.spin_for(0.01)              # let timers run (renderers, sim nodes, camera)
    if spec.name == 'force_estimator_node':          # a plausible shape: an estimate
        from geometry_msgs.msg import Point, Pose, PoseArray
        from healthy import _fam_control_points
        msg = PoseArray()
        msg.header.frame_id = T.FRAME_CATHETER_BASE
        msg.poses = [Pose(position=Point(x=p[0], y=p[1], z=p[2])) for p in _fam_control_points()]
        assert ros.spin_until(lambda: (pubs[T.CONTROL_POINTS].publish(msg), outputs)[1], 10.0)
    ros.spin_for(0.2)
    assert node.diag.get('bad_messages') > 0
    assert not bad, bad[:5]
    if key not in ('impedance_identifier_node',):    # (needs a window of good samples)
        assert outputs, f'{key} published nothing'

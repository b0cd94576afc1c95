"""The runner's DDS transport pieces (`run_scenario --dds`), in process over real DDS:
`PublishCounter` counts what each wrapped publisher sent, `DeliveryTracker` counts what each
wrapped subscription took and says how many published messages are still pending (the
lockstep drain waits for 0); a node wrapped twice is counted once."""
import pytest
from std_msgs.msg import Float64

from catheter_bringup.bus import DeliveryTracker, PublishCounter

pytestmark = pytest.mark.ros


def test_publish_counter_and_delivery_tracker_over_dds(ros):
    pub_node = ros.node('bus_pub')
    sub_node = ros.node('bus_sub')
    pub = pub_node.create_publisher(Float64, '/bus_test/x', 10)
    got = []
    sub_node.create_subscription(Float64, '/bus_test/x', lambda m: got.append(m.data), 10)
    counter = PublishCounter()
    assert pub in counter.wrap_node(pub_node)        # (besides /parameter_events, /rosout)
    assert counter.wrap_node(pub_node) == []                  # already wrapped
    tracker = DeliveryTracker(counter.counts)
    tracker.wrap_node(sub_node)
    tracker.wrap_node(sub_node)
    assert len(tracker.subs) == 1
    assert ros.spin_until(lambda: pub.get_subscription_count() == 1, 10.0)
    for i in range(5):
        pub.publish(Float64(data=float(i)))
    assert counter.counts['/bus_test/x'] == 5
    assert tracker.pending() == 5 - len(got)
    assert ros.spin_until(lambda: tracker.pending() == 0, 10.0)
    assert got == [0.0, 1.0, 2.0, 3.0, 4.0]
    assert tracker.subs[0][3] == 5                             # taken by the wrapped callback

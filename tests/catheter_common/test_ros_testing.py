"""catheter_common.ros_testing.isolate_ros_env: the domain id it sets keeps every port Fast
DDS may bind out of the kernel's ephemeral range (where another socket may already hold it),
differs between neighbouring processes, and discovery stays on localhost."""
import os
import pathlib

import pytest

from catheter_common import ros_testing
from catheter_common.ros_testing import (EPHEMERAL_PORTS, ISOLATED_DOMAINS, domain_ports,
                                         isolate_ros_env)


@pytest.fixture
def keep_env():
    old = {k: os.environ.get(k) for k in ('ROS_DOMAIN_ID', 'ROS_AUTOMATIC_DISCOVERY_RANGE')}
    yield
    for k, v in old.items():
        if v is None:
            os.environ.pop(k, None)
        else:
            os.environ[k] = v


def test_the_port_rule_by_hand():
    # RTPS well-known ports (DDSI-RTPS 9.6.1.1): domain 0 multicast discovery 7400, user
    # multicast 7401, unicast discovery 7410 + 2 p, user unicast 7411 + 2 p
    assert domain_ports(0, participants=1) == range(7400, 7414)
    assert domain_ports(101)[-1] == 7400 + 250 * 101 + 11 + 2 * 50 == 32761
    assert domain_ports(232)[-1] < 65536 <= domain_ports(233)[-1]


def test_every_isolated_domain_keeps_its_ports_out_of_the_ephemeral_range():
    lo, hi = EPHEMERAL_PORTS
    assert len(ISOLATED_DOMAINS) == len(set(ISOLATED_DOMAINS)) >= 90
    for d in ISOLATED_DOMAINS:
        ports = domain_ports(d)
        assert ports[-1] < lo or ports[0] > hi, d
        assert 0 <= d <= 232 and ports[-1] < 65536, d
    # the domains left out are exactly those whose ports touch the range (within 20-232)
    touching = [d for d in range(20, 233)
                if not (domain_ports(d)[-1] < lo or domain_ports(d)[0] > hi)]
    assert sorted(set(range(20, 233)) - set(touching)) == list(ISOLATED_DOMAINS)


def test_the_range_matches_this_kernel_where_it_can_be_read():
    f = pathlib.Path('/proc/sys/net/ipv4/ip_local_port_range')
    if not f.exists():
        pytest.skip('no /proc/sys/net/ipv4/ip_local_port_range on this system')
    lo, hi = (int(v) for v in f.read_text().split())
    for d in ISOLATED_DOMAINS:
        assert domain_ports(d)[-1] < lo or domain_ports(d)[0] > hi, (d, lo, hi)


def test_isolate_sets_an_isolated_domain_and_localhost_discovery(keep_env):
    seen = set()
    for seed in list(range(0, 400, 7)) + [os.getpid(), 10**9 + 3]:
        d = isolate_ros_env(seed)
        assert d in ISOLATED_DOMAINS
        assert os.environ['ROS_DOMAIN_ID'] == str(d)
        assert os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] == 'LOCALHOST'
        seen.add(d)
    assert len(seen) > 40                                   # spread, not one domain
    # neighbouring process ids get different domains
    assert len({isolate_ros_env(s) for s in range(5000, 5000 + len(ISOLATED_DOMAINS))}) \
        == len(ISOLATED_DOMAINS)
    assert isolate_ros_env() == ros_testing.ISOLATED_DOMAINS[os.getpid() % len(ISOLATED_DOMAINS)]
    assert ros_testing.isolated_domain(5000 + 7) == isolate_ros_env(5007)


def test_manual_clock_sets_the_nodes_time_and_runs_its_timer_callback():
    from types import SimpleNamespace
    from catheter_common.ros_testing import ManualClock
    seen = []
    node = SimpleNamespace()
    node._tick = lambda: seen.append(node._clock_ns())
    clock = ManualClock(node, 1.5)
    assert node._clock_ns() == 1_500_000_000
    clock.tick(2.0, 2.001)
    assert seen == [2_000_000_000, 2_001_000_000]
    clock.set(0.25)
    assert node._clock_ns() == 250_000_000 and len(seen) == 2


def test_captured_log_keeps_each_line_with_its_level_and_ignores_rclpys_keywords():
    from types import SimpleNamespace
    from catheter_common.ros_testing import CapturedLog
    node = SimpleNamespace()
    log = CapturedLog(node)
    node.get_logger().warning('w1', throttle_duration_sec=1.0)
    node.get_logger().error('e1')
    node.get_logger().warning('w2', once=True)
    assert log == [('warning', 'w1'), ('error', 'e1'), ('warning', 'w2')]
    assert log.texts('warning') == ['w1', 'w2'] and log.texts('info') == []

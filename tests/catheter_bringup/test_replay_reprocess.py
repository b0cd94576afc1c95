"""replay republishes a recording with /clock; reprocess re-runs nodes on recorded inputs and
finds a changed node."""
import pathlib
import sys

import pytest

from catheter_bringup.replay import replay
from catheter_bringup.reprocess import reprocess
from catheter_bringup.runner import ScenarioRunner


def _scenario(make_scenario, modules):
    return make_scenario(duration=0.25, outputs=['/test/relayed'], nodes={
        'talker': {'module': modules['talker'], 'produces': ['/test/force']},
        'relay': {'module': modules['relay'], 'consumes': ['/test/force'],
                  'produces': ['/test/relayed']}})


@pytest.fixture
def modules(test_registry):
    return {k: v.module for k, v in test_registry.items()}


@pytest.fixture
def recorded(tmp_path, make_scenario, modules):
    bag = tmp_path / 'run.mcap'
    res = ScenarioRunner(_scenario(make_scenario, modules), bag=str(bag), registry={},
                         progress=False).run()
    assert res.status == 'complete' and res.nodes == ['relay', 'talker']
    return bag


def test_reprocess_reproduces_and_detects_a_change(recorded, modules):
    res = reprocess(recorded, log=lambda *_: None)
    assert set(res) == {'relay'}                     # the talker consumes nothing
    c = res['relay']['/test/relayed']
    assert res['relay']['ok'] and c['recorded'] == c['now'] == c['matched'] == 250
    assert c['max_diff'] == 0.0

    import nodes_for_tests as n

    class ChangedRelay(n.RelayNode):
        def cb(self, msg):
            msg.wrench.force.x += 1e-3
            super().cb(msg)
    mod = sys.modules[modules['relay']]
    old = mod.NODE_CLASS
    mod.NODE_CLASS = ChangedRelay
    try:
        res = reprocess(recorded, log=lambda *_: None)
    finally:
        mod.NODE_CLASS = old
    assert not res['relay']['ok']
    assert res['relay']['/test/relayed']['max_diff'] == pytest.approx(1e-3, rel=1e-6)


def test_replay_republishes_every_message_with_clock(recorded, ros):
    from geometry_msgs.msg import WrenchStamped
    from rosgraph_msgs.msg import Clock
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    listener = ros.node('replay_listener')
    got, clocks = [], []
    qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.BEST_EFFORT)
    listener.create_subscription(WrenchStamped, '/test/force', got.append, qos)
    listener.create_subscription(Clock, '/clock', clocks.append, QoSProfile(depth=1000))
    pub_node = ros.node('replay')
    ros.spin_until(lambda: pub_node.count_subscribers('/clock') > 0, 5.0)
    res = replay(recorded, rate=0.5, topics=['/test/force'], node=pub_node)
    assert res['published'] == {'/test/force': 250}
    assert res['wall_time'] >= 0.45                 # 0.25 s recording at half speed
    ros.spin_until(lambda: got and got[-1].header.stamp.nanosec == 250_000_000
                   and clocks and clocks[-1].clock.nanosec == 250_000_000, 5.0)
    assert len(got) >= 240                           # best effort; the first may precede matching
    assert got[-1].header.stamp.nanosec == 250_000_000
    assert clocks and clocks[-1].clock.nanosec == 250_000_000
    with pytest.raises(ValueError, match='rate'):
        replay(recorded, rate=0.0, node=pub_node)


REF = pathlib.Path(__file__).resolve().parents[2] / 'bags' / 'reference'


@pytest.mark.parametrize('bag', sorted(REF.glob('*.mcap')), ids=lambda p: p.stem)
def test_reprocess_reports_the_shipped_reference_bags_unchanged(bag, capsys):
    """The documented regression check on the shipped bags: every node it can check
    reproduces its outputs exactly; nodes whose inputs the bag does not hold (the renderers:
    the reference runs record the force streams only) are listed as not checked, never as
    CHANGED (they were: fed part of their inputs they computed something else)."""
    from catheter_bringup.reprocess import main
    code = main([str(bag)])
    out = capsys.readouterr().out
    assert code == 0, out
    assert 'CHANGED' not in out
    assert 'sim_slave_node' in out and ' same' in out
    for node in ('dfr_master_node', 'ima_master_node'):
        line = next(line for line in out.splitlines() if line.startswith(node))
        assert 'not checked (inputs not recorded: /master/link/force' in line


def test_a_node_whose_inputs_were_not_recorded_is_not_checked(tmp_path, make_scenario, modules,
                                                              capsys):
    bag = tmp_path / 'outputs_only.mcap'
    sc = _scenario(make_scenario, modules)
    sc['record']['only'] = ['/test/relayed']
    ScenarioRunner(sc, bag=str(bag), registry={}, progress=False).run()
    res = reprocess(bag, log=lambda *_: None)
    assert res == {'relay': {'ok': None, 'skipped': 'inputs not recorded: /test/force'}}
    from catheter_bringup.reprocess import main
    assert main([str(bag)]) == 2
    assert 'nothing checked' in capsys.readouterr().out


def test_flatten_compares_every_field():
    from sensor_msgs.msg import Image, JointState
    from catheter_bringup.reprocess import flatten_message
    a = flatten_message(JointState(name=['x'], position=[1.0, 2.0], effort=[3.0]))
    assert a[0].tolist() == [0.0, 0.0, 1.0, 2.0, 3.0] and a[1] == ('', 'x')
    img = Image(height=20, width=20, encoding='mono8', step=20, data=bytes(400))
    other = Image(height=20, width=20, encoding='mono8', step=20, data=bytes(399) + b'\x01')
    assert flatten_message(img)[1] != flatten_message(other)[1]

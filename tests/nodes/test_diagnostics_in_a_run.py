"""Diagnostics of the real graph in a lockstep run with a link outage (issue 10 item 8: all 96
statuses of a default run were OK, outages included): the sim nodes report WARN while their
link is out and OK again after it, the renderers report stale feedback during the outage,
and every status says which conditions are active."""
import pytest
from mcap_ros2.reader import read_ros2_messages

from catheter_bringup.runner import ScenarioRunner
from catheter_bringup.scenario import load_scenario

pytestmark = pytest.mark.ros
pytest.importorskip('sim_slave.sim_slave_node')


@pytest.fixture(scope='module')
def statuses(tmp_path_factory):
    sc = load_scenario('smoke')
    sc['duration'] = 5.5
    sc['link']['outages'] = [[3.5, 1.0]]          # (the identifier has a model by then)
    bag = tmp_path_factory.mktemp('diag') / 'diag.mcap'
    res = ScenarioRunner(sc, bag=str(bag), progress=False, log=lambda *_: None).run()
    assert res.status == 'complete', res.reason
    out = {}
    for m in read_ros2_messages(str(bag), topics=['/diagnostics']):
        for st in m.ros_msg.status:
            conds = {kv.key[len('condition.'):]: kv.value for kv in st.values
                     if kv.key.startswith('condition.')}
            out.setdefault(st.name.lstrip('/'), []).append(
                (round(m.log_time_ns * 1e-9, 3), st.level[0] if isinstance(st.level, bytes)
                 else int(st.level), st.message, conds))
    return out


def _at(rows, t):
    return next(r for r in rows if abs(r[0] - t) < 1e-6)


@pytest.mark.parametrize('node', ['sim_slave_node', 'sim_haptic_node'])
def test_sim_nodes_warn_during_their_link_outage_and_recover(statuses, node):
    rows = statuses[node]
    assert [r[0] for r in rows] == [1.0, 2.0, 3.0, 4.0, 5.0]
    before, during, after = rows[2], rows[3], rows[4]
    assert before[1] == 0 and before[2] == 'ok'
    assert during[1] == 1 and 'link outage' in during[2] and 'link_outage' in during[3]
    assert after[1] == 0 and 'link_outage' not in after[3]


@pytest.mark.parametrize('node', ['ima_master_node', 'dfr_master_node'])
def test_renderers_report_a_held_model_during_the_outage(statuses, node):
    rows = statuses[node]
    during, after = _at(rows, 4.0), _at(rows, 5.0)
    assert during[1] >= 1 and 'held' in during[3].get('renderer', ''), during
    assert 'renderer' not in after[3], after


def test_every_level_matches_its_conditions(statuses):
    for node, rows in statuses.items():
        for t, level, message, conds in rows:
            worst = max([{'WARN': 1, 'ERROR': 2}[v.split(':')[0]] for v in conds.values()],
                        default=0)
            assert level == worst, (node, t, level, conds)
            assert (message == 'ok') == (not conds), (node, t, message)

"""--set overrides typed by the scenario, runs named after what they are (a changed or copied
scenario never overwrites the default run's outputs), and analyze reading the link from the
run's metadata (warning when it must assume it)."""
import json
import math
import pathlib

import pytest
import yaml
from rclpy.serialization import serialize_message

from catheter_bringup.analyze import analyze, main as analyze_main
from catheter_bringup.overrides import apply_overrides, parse_set, run_name
from catheter_bringup.recorder import McapRecorder
from catheter_bringup.scenario import config_dir, load_scenario


@pytest.fixture
def exp():
    return load_scenario('experiment_ii')


def test_values_are_typed_by_the_scenario(exp):
    sc = apply_overrides(exp, ['link.delay=1', 'seed=9', 'dds=true', 'duration=3',
                               'link.outages=[[2, 0.5]]', 'mode=realtime',
                               'nodes.ima_master_node.params.mode=ima_thesis',
                               'nodes.sim_slave_node.params.robot.x0=0.01',
                               'operator.trajectory=experiment_i'])
    assert sc['link']['delay'] == 1.0 and isinstance(sc['link']['delay'], float)
    assert sc['seed'] == 9 and isinstance(sc['seed'], int)
    assert sc['dds'] is True and sc['duration'] == 3.0 and sc['mode'] == 'realtime'
    assert sc['link']['outages'] == [[2.0, 0.5]]
    assert sc['nodes']['ima_master_node']['params']['mode'] == 'ima_thesis'
    assert sc['nodes']['sim_slave_node']['params']['robot.x0'] == 0.01   # one dotted name
    assert sc['operator']['trajectory'] == 'experiment_i'
    assert exp['link']['delay'] == 0.2                                   # a copy: not changed
    # a parameter the YAML does not set goes to a registry node's params
    sc = apply_overrides(exp, ['nodes.camera_node.params.fps=15'])
    assert sc['nodes']['camera_node'] == {'params': {'fps': 15}}


@pytest.mark.parametrize('item,match', [
    ('link.delay=abc', 'link.delay: expected a number'),
    ('link.delay=-1', r'link.delay=-1.0 outside'),
    ('link.bogus=1', "no field 'link.bogus'"),
    ('bogus=1', "no field 'bogus'"),
    ('seed=1.5', 'seed: expected an integer'),
    ('dds=3', 'dds: expected true or false'),
    ('mode=fast', 'scenario.mode must be one of'),
    ('link.outages=4', 'link.outages: expected a list'),
    ('nodes.nobody.params.x=1', "no node instance 'nobody'"),
    ('duration', 'expects key=value'),
    ('=1', 'dotted name'),
    ('link.delay=[', 'not a YAML value'),
])
def test_bad_overrides_are_refused_naming_the_key(exp, item, match):
    with pytest.raises(ValueError, match=match):
        apply_overrides(exp, [item])


def test_runs_are_named_after_what_they_are(exp, tmp_path):
    assert run_name(exp) == ('experiment_ii', 'the scenario')
    name, why = run_name(exp, ['link.delay=0.5', 'link.outages=[[4,1]]'])
    assert name == 'experiment_ii__link.delay-0.5__link.outages-4_1' and '--set' in why
    assert run_name(exp, ['link.delay=0.5'], name='experiment_ii')[0] == 'experiment_ii'
    with pytest.raises(ValueError, match='name'):
        run_name(exp, name='a b')
    # a copied YAML that keeps name: experiment_ii is named after its file ...
    copy = tmp_path / 'my_delay.yaml'
    copy.write_text((config_dir() / 'experiment_ii.yaml').read_text())
    sc = load_scenario(str(copy))
    assert sc['name'] == 'experiment_ii'
    assert run_name(sc)[0] == 'my_delay'
    # ... or, when the file has a shipped scenario's name too, after its path
    same = tmp_path / 'experiment_ii.yaml'
    same.write_text(copy.read_text())
    got = run_name(load_scenario(str(same)))[0]
    assert got.startswith('experiment_ii-') and len(got) == len('experiment_ii-') + 6
    long = run_name(exp, [f'link.outages={[[i, 0.1] for i in range(30)]}'])[0]
    assert len(long) < 110
    assert parse_set('a.b= [1, 2]') == ('a.b', [1, 2])


@pytest.mark.ros
@pytest.mark.slow
def test_main_command_with_set_writes_outputs_named_after_the_run(tmp_path, monkeypatch,
                                                                   capsys):
    from catheter_bringup.main import main
    monkeypatch.setenv('CATHETER_WS_ROOT', str(tmp_path))
    out = tmp_path / 'out'
    default = out / 'smoke_metrics.json'
    out.mkdir()
    default.write_text('{"untouched": true}')
    code = main(['smoke', '--duration', '1.0', '--set', 'link.delay=0.1', '--out', str(out),
                 '--no-fam'])
    assert code == 0
    text = capsys.readouterr().out
    name = 'smoke__link.delay-0.1'
    assert f'== {name}' in text and '[the scenario with --set link.delay=0.1]' in text
    bag = tmp_path / 'bags' / f'{name}.mcap'
    assert bag.exists()
    m = json.loads((out / f'{name}_metrics.json').read_text())
    assert m['delay_s'] == 0.1 and 'warnings' not in m
    for suffix in ('tracking', 'errors'):      # no model yet in 1 s: no impedance figure
        assert (out / f'{name}_{suffix}.png').exists()
    assert json.loads(default.read_text()) == {'untouched': True}
    assert not (tmp_path / 'bags' / 'smoke.mcap').exists()
    assert '[analysis] done in' in text and '[analysis] plot: IMA vs DFR errors' in text


def _bag_without_scenario(path):
    def wrench(fx, t):
        from geometry_msgs.msg import WrenchStamped
        msg = WrenchStamped()
        msg.header.stamp.sec, msg.header.stamp.nanosec = int(t), int(round((t % 1) * 1e9))
        msg.wrench.force.x = fx
        return msg
    rec = McapRecorder(path)
    rec.add_topic('/slave/force', 'geometry_msgs/msg/WrenchStamped')
    rec.add_topic('/master/rendered_force', 'geometry_msgs/msg/WrenchStamped')
    for k in range(2001):
        t = k * 1e-3
        rec.write('/slave/force', serialize_message(wrench(math.sin(t), t)), k * 1_000_000)
        rec.write('/master/rendered_force', serialize_message(wrench(math.sin(t + 0.3), t)),
                  k * 1_000_000)
    rec.close('complete', 'recorder_node shut down')      # no scenario: a recorder_node bag
    return path


def test_analyze_warns_when_it_must_assume_the_link(tmp_path, capsys):
    bag = _bag_without_scenario(tmp_path / 'plain.mcap')
    res = analyze(bag, skip=0.0)
    assert res['delay_s'] == 0.0 and res['outages'] == []
    assert len(res['warnings']) == 2 and 'assuming 0 ms' in res['warnings'][0]
    assert analyze_main([str(bag), '--quiet']) == 0
    assert capsys.readouterr().err.count('analyze: warning:') == 2
    # given on the command line: used, no warning, and the error is the known one (0 N)
    assert analyze_main([str(bag), '--delay', '0.3', '--outages', '1,0.2', '--skip', '0',
                         '--json', str(tmp_path / 'm.json')]) == 0
    assert 'WARNING' not in capsys.readouterr().out
    m = json.loads((tmp_path / 'm.json').read_text())
    assert m['delay_s'] == 0.3 and m['outages'] == [[1.0, 0.2]] and 'warnings' not in m
    assert m['force_tracking']['ima']['normal']['max'] < 1e-9


def test_a_recorded_scenario_gives_delay_and_outages(tmp_path):
    sc = yaml.safe_dump({'name': 'x', 'link': {'delay': 0.25, 'outages': [[1.0, 0.5]]}})
    path = tmp_path / 'with.mcap'
    rec = McapRecorder(path)
    rec.add_topic('/slave/force', 'geometry_msgs/msg/WrenchStamped')
    rec.close('complete', extra={'scenario_yaml': sc})
    res = analyze(path)
    assert res['delay_s'] == 0.25 and res['outages'] == [[1.0, 0.5]] and 'warnings' not in res
    assert pathlib.Path(path).exists()


def test_long_override_lists_that_differ_late_get_different_names(exp):
    """A name cut to its first 60 characters would make two different runs write the same
    outputs: the cut name carries a hash of the whole list."""
    base = [f'link.outages={[[i, 0.1] for i in range(30)]}']
    a = run_name(exp, base + ['link.delay=0.3'])[0]
    b = run_name(exp, base + ['link.delay=0.4'])[0]
    assert a[:60] == b[:60] and a != b
    assert run_name(exp, base + ['link.delay=0.3'])[0] == a        # and it is reproducible

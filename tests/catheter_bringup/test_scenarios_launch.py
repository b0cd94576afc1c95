"""Every scenario of catheter_bringup's config/ loads; launch/scenario.launch.py starts exactly
the runner's node instances (run against stand-ins for `launch`/`launch_ros`, not on PyPI);
both are found through the ament index (installed to share/catheter_bringup)."""
import pathlib
import runpy
import sys
import types

import pytest
import yaml

from catheter_bringup.make_launch import launch_entries
from catheter_bringup.scenario import config_dir, load_scenario, resolve_nodes

ROOT = pathlib.Path(__file__).resolve().parents[2]
PKG = ROOT / 'src' / 'catheter_bringup'
NAMES = sorted(p.stem for p in (PKG / 'config').glob('*.yaml'))


def test_the_expected_scenarios_exist_and_are_installed():
    from ament_index_python.packages import get_package_share_directory
    share = pathlib.Path(get_package_share_directory('catheter_bringup'))
    assert config_dir() == share / 'config'
    assert sorted(p.stem for p in config_dir().glob('*.yaml')) == NAMES
    assert (share / 'launch' / 'scenario.launch.py').exists()
    assert {'experiment_ii', 'experiment_i', 'experiment_ii_dfr', 'smoke'} <= set(NAMES)


def test_config_dir_falls_back_to_the_source_tree_when_not_installed(monkeypatch):
    from catheter_bringup import scenario
    monkeypatch.setattr(scenario, 'share_dir', lambda: None)
    assert scenario.config_dir() == PKG / 'config'
    assert load_scenario('smoke')['source'] == str(PKG / 'config' / 'smoke.yaml')


class _Recorder:
    """Stand-in for a launch action: keeps its constructor arguments."""

    def __init__(self, *args, **kwargs):
        self.args, self.kwargs = args, kwargs


def _fake_launch_modules(scenario_name, layout=''):
    class LaunchConfiguration(_Recorder):
        def perform(self, context):
            assert self.args in (('scenario',), ('layout',))
            return scenario_name if self.args == ('scenario',) else layout
    mods = {n: types.ModuleType(n) for n in
            ('launch', 'launch.actions', 'launch.substitutions', 'launch_ros',
             'launch_ros.actions')}
    mods['launch'].LaunchDescription = _Recorder
    mods['launch.actions'].DeclareLaunchArgument = _Recorder
    mods['launch.actions'].OpaqueFunction = _Recorder
    mods['launch.substitutions'].LaunchConfiguration = LaunchConfiguration
    mods['launch_ros.actions'].Node = _Recorder
    return mods


@pytest.mark.parametrize('name', NAMES)
def test_scenario_loads_and_the_launch_file_starts_its_nodes(name, monkeypatch):
    sc = load_scenario(name)
    assert sc['name'] == name
    nodes, _ = resolve_nodes(sc)
    for mod_name, mod in _fake_launch_modules(name).items():
        monkeypatch.setitem(sys.modules, mod_name, mod)
    ns = runpy.run_path(str(PKG / 'launch' / 'scenario.launch.py'))
    desc = ns['generate_launch_description']()
    declare, declare_layout, opaque = desc.args[0]
    assert declare.args[0] == 'scenario' and declare_layout.args[0] == 'layout'
    launched = opaque.kwargs['function'](context=None)
    started = {n.kwargs['name']: n.kwargs for n in launched}
    assert set(started) == {i.name for i in nodes} | {'recorder_node'}
    for inst in nodes:
        kw = started[inst.name]
        assert kw['executable'] == inst.spec.executable
        assert kw['parameters'][0]['use_sim_time'] is False
        for key, value in inst.params.items():
            assert kw['parameters'][0][key] == value
        assert dict(kw.get('remappings', [])) == dict(inst.remap)
    assert started['recorder_node']['parameters'][0]['path'] == f'bags/{name}.mcap'
    assert started['recorder_node']['parameters'][0]['scenario'] == sc['source']
    assert launch_entries(sc) == [{k: v for k, v in n.kwargs.items() if k != 'output'}
                                  for n in launched]


def test_launch_with_layout_split_starts_master_slave_vision_processes(monkeypatch):
    """layout:=split: one run_scenario process per process of the layout, each running only
    its nodes in real time; the force loop's nodes (device, renderers) in one; every node
    of the scenario in exactly one process; and the recorder."""
    sc = load_scenario('experiment_ii')
    nodes = {i.name for i in resolve_nodes(sc)[0]}
    for mod_name, mod in _fake_launch_modules('experiment_ii', 'split').items():
        monkeypatch.setitem(sys.modules, mod_name, mod)
    ns = runpy.run_path(str(PKG / 'launch' / 'scenario.launch.py'))
    opaque = ns['generate_launch_description']().args[0][2]
    launched = [n.kwargs for n in opaque.kwargs['function'](context=None)]
    procs = {}
    for kw in launched[:-1]:
        assert kw['executable'] == 'run_scenario' and 'name' not in kw   # names stay the nodes'
        a = kw['arguments']
        assert a[a.index('--mode') + 1] == 'realtime' and 'layout=split' in a
        procs[a[a.index('--process') + 1]] = a[a.index('--only') + 1].split(',')
    assert launched[-1]['executable'] == 'recorder_node'
    assert set(procs) == {'master', 'slave', 'vision'}
    assert {'sim_haptic_node', 'ima_master_node', 'dfr_master_node'} == set(procs['master'])
    assert {'sim_slave_node', 'impedance_identifier_node'} == set(procs['slave'])
    assert {'camera_node', 'shape_node', 'force_estimator_node'} == set(procs['vision'])
    every = [n for names in procs.values() for n in names]
    assert sorted(every) == sorted(nodes)


def test_launched_split_workers_get_the_worker_params_and_the_cpu_placement():
    """The launch file's split processes are set up as the launchless runner's workers:
    shape_node processes frames on arrival, and with a realtime_priority the master keeps
    the first CPU, vision the last (`realtime.worker_cpus`), the slave runs anywhere."""
    from catheter_bringup.make_launch import split_entries
    from catheter_bringup.run_scenario import build_parser
    sc = load_scenario('experiment_ii')
    nodes = resolve_nodes(sc)[0]

    def by_process(entries):
        out = {}
        for e in entries:
            a = e['arguments']
            out[a[a.index('--process') + 1]] = a
        return out
    procs = by_process(split_entries(sc, nodes, cpus={0, 1}))
    for a in procs.values():
        i = a.index('global_params.process_on_arrival=true')
        assert a[i - 1] == '--set'
        assert build_parser().parse_args(a).overrides[-1] == 'global_params.process_on_arrival=true'
    assert procs['master'][procs['master'].index('--cpus') + 1] == '0'
    assert procs['vision'][procs['vision'].index('--cpus') + 1] == '1'
    assert '--cpus' not in procs['slave']
    assert not any('--cpus' in a for a in by_process(split_entries(sc, nodes, cpus={0})).values())
    quiet = dict(sc, realtime_priority=0, global_params={'process_on_arrival': False})
    for a in by_process(split_entries(quiet, nodes, cpus={0, 1})).values():
        assert '--cpus' not in a                       # no SCHED_FIFO loops: no placement
        assert not any('process_on_arrival' in x for x in a)   # the scenario's value stands


def test_run_scenario_pins_itself_and_refuses_bad_cpus(monkeypatch):
    from catheter_bringup import realtime, runner
    from catheter_bringup.run_scenario import main, parse_cpus
    assert parse_cpus('1,0') == frozenset({0, 1}) and parse_cpus(None) is None
    for bad in ('a', '', '-1', '0,,1'):
        with pytest.raises(ValueError, match='--cpus'):
            parse_cpus(bad)
    assert main(['smoke', '--cpus', 'x', '--no-record']) == 2
    calls = []
    monkeypatch.setattr(realtime, 'pin_process',
                        lambda pid, cpus, log, main_only=False: calls.append((cpus, main_only)))

    def setup(self):
        calls.append('setup')
        raise ValueError('stop here')
    monkeypatch.setattr(runner.ScenarioRunner, 'setup', setup)
    assert main(['smoke', '--cpus', '0', '--no-record', '--quiet']) == 2
    assert calls == [(frozenset({0}), False), 'setup']      # every thread, before any exists
    # a 1 kHz process: its loop thread only, once setup made the other threads
    calls.clear()

    class Done(Exception):
        pass

    def run(self):
        raise Done
    monkeypatch.setattr(runner.ScenarioRunner, 'setup', lambda self: calls.append('setup'))
    monkeypatch.setattr(runner.ScenarioRunner, 'run', run)
    with pytest.raises(Done):
        main(['smoke', '--cpus', '1', '--process', 'master', '--no-record', '--quiet'])
    assert calls == ['setup', (frozenset({1}), True)]


def test_a_worker_reports_the_cpus_it_kept_itself_on(tmp_path):
    import json
    from types import SimpleNamespace
    from catheter_bringup.run_scenario import write_report
    res = SimpleNamespace(status='complete', reason='', nodes=[], published={}, recorded={},
                          received={}, cost={}, realtime={}, wall_time=0.0)
    for cpus, want in ((frozenset({1, 0}), [0, 1]), (None, None)):
        write_report(str(tmp_path / 'r.json'), 'vision', res, cpus)
        assert json.loads((tmp_path / 'r.json').read_text())['cpus'] == want


def test_layout_is_validated_and_split_needs_real_time():
    from catheter_bringup.overrides import apply_overrides
    sc = load_scenario('smoke')
    assert sc['layout'] == 'one'
    with pytest.raises(ValueError, match='layout'):
        apply_overrides(sc, ['layout=three'])
    with pytest.raises(ValueError, match='layout split .*realtime'):
        apply_overrides(sc, ['layout=split'])           # smoke is lockstep
    assert apply_overrides(sc, ['layout=split', 'mode=realtime'])['layout'] == 'split'
    with pytest.raises(ValueError, match='realtime_priority'):
        apply_overrides(sc, ['realtime_priority=120'])


def test_default_scenario_is_experiment_ii_as_in_the_thesis():
    sc = load_scenario('experiment_ii')
    assert sc['duration'] == 12.0 and sc['link']['delay'] == 0.2
    assert sc['link']['outages'] == [[4.0, 1.0], [8.0, 1.0]]
    names = {i.name for i in resolve_nodes(sc)[0]}
    # image-based force estimation alongside, and both renderers
    assert {'shape_node', 'force_estimator_node', 'ima_master_node', 'dfr_master_node',
            'sim_slave_node', 'sim_haptic_node', 'impedance_identifier_node'} <= names
    # experiment I needs no camera pipeline: it is not started
    names_i = {i.name for i in resolve_nodes(load_scenario('experiment_i'))[0]}
    assert not names_i & {'shape_node', 'force_estimator_node', 'camera_node'}


@pytest.mark.ros
def test_recorder_node_records_the_scenario_it_is_given(ros, tmp_path):
    """A launched run's recorder writes the scenario (real time) into the run metadata, so
    analyze knows the link delay and outages without assuming them."""
    from rclpy.parameter import Parameter
    from geometry_msgs.msg import WrenchStamped
    from catheter_bringup.analyze import analyze
    from catheter_bringup.recorder import RUN_START_METADATA, read_run_metadata
    from catheter_bringup.recorder_node import RecorderNode
    bag = tmp_path / 'launched.mcap'
    node = RecorderNode(context=ros.context, parameter_overrides=[
        Parameter('path', value=str(bag)), Parameter('scenario', value='experiment_ii'),
        Parameter('topics', value=['/slave/force']), Parameter('discovery_period', value=0.1)])
    ros.add(node)
    pub = ros.node('talker').create_publisher(WrenchStamped, '/slave/force', 10)
    assert ros.spin_until(lambda: '/slave/force' in node.sink.subs, 10.0)
    for _ in range(5):
        pub.publish(WrenchStamped())
    assert ros.spin_until(lambda: node.recorder.total >= 5, 10.0)
    node.close()
    meta = read_run_metadata(bag)
    assert meta['scenario'] == 'experiment_ii' and meta['mode'] == 'realtime'
    sc = yaml.safe_load(meta['scenario_yaml'])
    assert sc['link']['delay'] == 0.2 and sc['mode'] == 'realtime'
    res = analyze(bag)
    assert 'warnings' not in res and res['delay_s'] == 0.2
    from mcap.reader import make_reader
    with open(bag, 'rb') as f:
        names = [m.name for m in make_reader(f).iter_metadata()]
    assert names == [RUN_START_METADATA, 'catheter_run']

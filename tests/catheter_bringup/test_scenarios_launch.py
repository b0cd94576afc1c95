"""Every scenario in ros_ws/config loads; the launch files in ros_ws/launch are the ones the
YAML generates today and are valid Python naming the scenario's nodes."""
import ast
import pathlib

import pytest

from catheter_bringup.make_launch import launch_text
from catheter_bringup.scenario import config_dir, load_scenario, resolve_nodes

ROOT = pathlib.Path(__file__).resolve().parents[2]
NAMES = sorted(p.stem for p in (ROOT / 'ros_ws' / 'config').glob('*.yaml'))


def test_the_expected_scenarios_exist():
    assert config_dir() == ROOT / 'ros_ws' / 'config'
    assert {'experiment_ii', 'experiment_i', 'experiment_ii_dfr', 'smoke'} <= set(NAMES)


@pytest.mark.parametrize('name', NAMES)
def test_scenario_loads_and_its_launch_file_is_current(name):
    sc = load_scenario(name)
    assert sc['name'] == name
    nodes, _ = resolve_nodes(sc)
    text = launch_text(sc)
    ast.parse(text)
    for inst in nodes:
        assert f"name={inst.name!r}" in text
    committed = (ROOT / 'ros_ws' / 'launch' / f'{name}.launch.py').read_text()
    assert committed == text, f'regenerate: python -m catheter_bringup.make_launch {name}'


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

"""Vessel and operator selection in the simulator (issue 12 context): the sim nodes take the
vessel family by name (validated, choices in --help), scenarios carry `vessel` and
`operator.family` (`--set vessel=stiff_wall` works), and a non-default vessel changes the
force the slave records; the offline analysis builds its twin from the same vessel."""
import numpy as np
import pytest
from rclpy.parameter import Parameter

from catheter_common.params import format_help
from sim_slave.node_params import VESSEL_CHOICES, vessel_from_params
from sim_slave.vessels import VESSELS, vessel_spec


def test_vessel_from_params_names_the_vessel_and_overrides_only_what_differs():
    assert vessel_from_params({}).name == 'phantom'
    phantom = vessel_spec('phantom')
    ref = vessel_spec('stiff_wall')
    spec = vessel_from_params({
        'vessel': 'stiff_wall', 'vessel.friction_per_length': 2.0,        # differs: taken
        'vessel.wall_stiffness': phantom.params.wall_stiffness,          # the default: not
        'sensor.noise_std': phantom.noise_std})                          # the default: not
    assert spec.name == 'stiff_wall' and spec.params.friction_per_length == 2.0
    assert spec.params.wall_stiffness == ref.params.wall_stiffness != \
        phantom.params.wall_stiffness
    assert spec.noise_std == ref.noise_std != phantom.noise_std
    assert vessel_from_params({'vessel': 'soft', 'sensor.noise_std': 0.05}).noise_std == 0.05
    with pytest.raises(ValueError, match='vessel'):
        vessel_from_params({'vessel': 'bogus'})
    assert set(VESSELS) <= set(VESSEL_CHOICES)


@pytest.mark.parametrize('module, name', [('sim_slave.sim_slave_node', 'vessel'),
                                          ('sim_slave.camera_node', 'vessel'),
                                          ('impedance_master.sim_haptic_node',
                                           'operator.family')])
def test_the_choices_are_in_help_and_unknown_names_are_refused(ros, module, name):
    import importlib
    mod = importlib.import_module(module)
    text = format_help(module.rsplit('.', 1)[1], mod.PARAMS)
    choices = {'vessel': VESSELS, 'operator.family': ('minjerk', 'sines', 'human')}[name]
    line = next(ln for ln in text.splitlines() if ln.strip().startswith(name + ' ')
                or ln.strip().startswith(name + ':') or f' {name} ' in ln)
    assert all(c in text for c in choices), line
    with pytest.raises(ValueError, match=name.replace('.', r'\.')):
        mod.NODE_CLASS(context=ros.context, parameter_overrides=[Parameter(name, value='bogus')])


def test_sim_slave_node_simulates_the_named_vessel(ros):
    from sim_slave.sim_slave_node import SimSlaveNode
    node = SimSlaveNode(context=ros.context, parameter_overrides=[
        Parameter('vessel', value='stenosis')])
    try:
        assert node.vessel_name == 'stenosis'
        assert node.sim.vessel.extras == vessel_spec('stenosis').extras
        assert node.sim.sensor.noise_std == vessel_spec('stenosis').noise_std
    finally:
        node.destroy_node()


def test_sim_haptic_node_runs_the_named_operator(ros):
    from impedance_master.operator import HumanTrajectory
    from impedance_master.sim_haptic_node import SimHapticNode
    node = SimHapticNode(context=ros.context, parameter_overrides=[
        Parameter('operator.family', value='human')])
    try:
        assert isinstance(node.traj, HumanTrajectory)
    finally:
        node.destroy_node()


def test_scenario_fields_and_set_overrides():
    from catheter_bringup.analyze import twin_vessel
    from catheter_bringup.overrides import apply_overrides
    from catheter_bringup.scenario import instances, load_scenario
    sc = load_scenario('smoke')
    assert sc['vessel'] == 'phantom' and sc['operator']['family'] == 'minjerk'
    sc2 = apply_overrides(sc, ['vessel=stiff_wall', 'operator.family=sines'])
    inst = instances(sc2)
    assert inst['sim_slave_node'].params['vessel'] == 'stiff_wall'
    assert inst['sim_haptic_node'].params['operator.family'] == 'sines'
    assert twin_vessel(sc2)[0].name == 'stiff_wall'
    for bad in (['vessel=bogus'], ['operator.family=robot']):
        with pytest.raises(ValueError, match=bad[0].split('=')[0].split('.')[-1]):
            apply_overrides(sc, bad)


@pytest.mark.slow
def test_a_non_default_vessel_changes_the_recorded_slave_force(tmp_path):
    """run_scenario smoke --set vessel=stiff_wall: the recorded slave force is another one
    (same seed, same motion), and the run's recorded scenario says which vessel."""
    from mcap_ros2.reader import read_ros2_messages
    from catheter_bringup.overrides import apply_overrides
    from catheter_bringup.recorder import read_run_metadata
    from catheter_bringup.runner import ScenarioRunner
    from catheter_bringup.scenario import load_scenario
    import yaml
    forces = {}
    for vessel in ('phantom', 'stiff_wall'):
        sc = apply_overrides(load_scenario('smoke'), [f'vessel={vessel}'])
        sc['record']['only'] = ['/slave/force', '/slave/joint_state']
        bag = tmp_path / f'{vessel}.mcap'
        res = ScenarioRunner(sc, bag=str(bag), progress=False, log=lambda *_: None).run()
        assert res.status == 'complete', res.reason
        assert yaml.safe_load(read_run_metadata(bag)['scenario_yaml'])['vessel'] == vessel
        forces[vessel] = np.array([m.ros_msg.wrench.force.x
                                   for m in read_ros2_messages(str(bag), ['/slave/force'])])
    a, b = forces['phantom'], forces['stiff_wall']
    assert a.size == b.size > 1000
    assert np.max(np.abs(a - b)) > 0.02            # N: another vessel, another force

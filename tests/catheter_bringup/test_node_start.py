"""Starting a scenario's node instances (`catheter_bringup.node_start`): the parameters a node
gets (use_sim_time in lockstep, mixed int / float lists as doubles), its name and remaps on
the command line, and the second try with the scenario's fallback_params."""
import pytest
from rclpy.parameter import Parameter

from catheter_bringup.node_start import cli_args, params_for, start_node
from catheter_bringup.scenario import NodeInstance, NodeSpec

SPEC = NodeSpec('camera_node', 'catheter_sim.camera_node', (), ('/camera/image',))


def _inst(name='camera_node', params=None, remap=None):
    return NodeInstance(name, SPEC, dict(params or {}), dict(remap or {}))


def _values(params):
    return {p.name: p.value for p in params}


def test_use_sim_time_follows_the_mode_and_lists_become_doubles():
    inst = _inst(params={'base_px': [20, 80.5], 'rate': 30, 'ids': [1, 2]})
    assert _values(params_for(inst, True))['use_sim_time'] is True
    assert _values(params_for(inst, False))['use_sim_time'] is False
    by_name = {p.name: p for p in params_for(inst, True)}
    # [20, 80.5] is a double array (rclpy refuses a list of mixed int and float)
    assert by_name['base_px'].value == [20.0, 80.5]
    assert by_name['base_px'].type_ == Parameter.Type.DOUBLE_ARRAY
    assert by_name['ids'].type_ == Parameter.Type.INTEGER_ARRAY
    assert by_name['rate'].value == 30


def test_a_second_instance_is_renamed_and_remaps_go_from_old_to_new():
    assert cli_args(_inst()) == []
    assert cli_args(_inst('camera_2', remap={'/camera/image': '/camera2/image'})) == [
        '--ros-args', '-r', '__node:=camera_2', '-r', '/camera/image:=/camera2/image']


class _Picky:
    """A node class that fails unless its parameter 'mode' is 'safe'."""
    made = []

    def __init__(self, **kwargs):
        values = _values(kwargs['parameter_overrides'])
        if values.get('mode') != 'safe':
            raise RuntimeError(f"mode {values.get('mode')!r} unsupported")
        _Picky.made.append(kwargs)


def test_a_failing_start_is_retried_once_with_the_fallback_params():
    logged = []
    inst = _inst(params={'mode': 'fast', 'rate': 5})
    node, used = start_node(_Picky, inst, 'ctx', True, fallback_params={'mode': 'safe'},
                            log=logged.append)
    assert used and isinstance(node, _Picky) and len(logged) == 1
    values = _values(_Picky.made[-1]['parameter_overrides'])
    assert values == {'use_sim_time': True, 'mode': 'safe', 'rate': 5}
    assert _Picky.made[-1]['context'] == 'ctx'
    with pytest.raises(RuntimeError, match='unsupported'):
        start_node(_Picky, inst, 'ctx', True, fallback_params=None, log=logged.append)
    node, used = start_node(_Picky, _inst(params={'mode': 'safe'}), 'ctx', False)
    assert not used

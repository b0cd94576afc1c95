"""What a ROS 2 launch of a scenario starts (`catheter_bringup.make_launch.launch_entries`):
the launched recorder gets the scenario's record section (exclude, only), as the launchless
runner applies it."""
from catheter_bringup.make_launch import launch_entries
from catheter_bringup.overrides import apply_overrides
from catheter_bringup.scenario import load_scenario


def _recorder(sc):
    rec = [e for e in launch_entries(sc) if e['executable'] == 'recorder_node']
    assert len(rec) == 1
    return rec[0]['parameters'][0]


def test_the_launched_recorder_takes_the_scenarios_record_section():
    sc = apply_overrides(load_scenario('smoke'), [
        'record.exclude=["/clock", "/diagnostics"]', 'record.only=["/slave/force"]'])
    p = _recorder(sc)
    assert p['exclude'] == ['/clock', '/diagnostics'] and p['topics'] == ['/slave/force']
    sc = apply_overrides(load_scenario('smoke'), ['record.exclude=[]'])
    p = _recorder(sc)
    assert p['exclude'] == [''] and p['topics'] == ['']      # nothing excluded, every topic

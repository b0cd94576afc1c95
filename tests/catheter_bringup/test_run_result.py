"""RunResult.lost: per recorded topic, how many published messages the recording misses."""
from catheter_bringup.result import RunResult


def _result(published, recorded):
    return RunResult(scenario='s', status='complete', reason='', bag=None, sim_time=1.0,
                     wall_time=2.0, steps=1000, nodes=[], skipped=[], missing_outputs=[],
                     published=published, recorded=recorded)


def test_lost_counts_what_the_recording_misses():
    r = _result({'/a': 100, '/b': 50, '/c': 7}, {'/a': 97, '/b': 50, '/d': 3})
    # /a: 3 missing; /b: complete (not listed); /c published but not recorded (not a
    # recorded topic); /d recorded but published by another process (unknown here)
    assert r.lost == {'/a': 3}

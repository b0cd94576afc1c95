"""The runner's loops and end (`catheter_bringup.stepping`, `catheter_bringup.run_teardown`)
on the tests' small nodes: a stop request ends a lockstep run, /clock carries the whole
simulated time, the time reached never exceeds the duration, the nodes are closed at the
end, a runner closed before its run finished leaves a closed recording, and the end record
names the skipped nodes."""
import json
import types

import pytest
from rosgraph_msgs.msg import Clock

from catheter_bringup.recorder import read_run_metadata
from catheter_bringup.runner import ScenarioRunner
from catheter_bringup.stepping import Stepping


def test_a_stop_request_ends_a_lockstep_run_at_that_step(tmp_path, make_scenario,
                                                          test_registry):
    bag = tmp_path / 'stop.mcap'
    r = ScenarioRunner(make_scenario(duration=2.0), bag=str(bag), registry=test_registry,
                       progress=False)

    def on_step(t):
        if t >= 0.1:
            r.stop_requested = True       # what Ctrl-C / SIGTERM's handler does
    r.on_step = on_step
    res = r.run()
    assert res.status == 'interrupted'
    assert res.sim_time == pytest.approx(0.1, abs=1e-9)
    meta = read_run_metadata(bag)
    assert meta['status'] == 'interrupted'
    # the steps it ran (each published one /test/force), not 0: also for a run that stopped
    assert res.steps == res.published['/test/force'] == int(meta['steps']) == 100


def test_clock_carries_seconds_and_nanoseconds():
    sent = []
    fake = types.SimpleNamespace(time_sources=[], clock_pub=types.SimpleNamespace(
        get_subscription_count=lambda: 1, publish=lambda m: sent.append(
            (m.clock.sec, m.clock.nanosec))))
    Stepping._publish_clock(fake, 2_345_000_000, Clock())
    assert fake._now_ns == 2_345_000_000 and sent == [(2, 345_000_000)]


def test_the_time_reached_of_a_real_time_run_stops_at_its_duration():
    now = {'ns': 0}
    fake = types.SimpleNamespace(scenario={'duration': 1.0}, _rescan=lambda: None, sink=None)
    clock = types.SimpleNamespace(now=lambda: types.SimpleNamespace(nanoseconds=now['ns']))
    now['ns'] = 400_000_000
    Stepping._upkeep(fake, clock, now['ns'], 0, 10 ** 18, None, 0.0)
    assert fake._sim_reached == pytest.approx(0.4)
    now['ns'] = 1_003_000_000        # the clock passed the end during the iteration
    Stepping._upkeep(fake, clock, 999_000_000, 0, 10 ** 18, None, 0.0)
    assert fake._sim_reached == 1.0


def test_the_nodes_are_closed_and_the_skipped_ones_recorded(tmp_path, make_scenario,
                                                            test_registry):
    bag = tmp_path / 'end.mcap'
    sc = make_scenario(duration=0.05, outputs=['/test/relayed', '/test/missing'])
    r = ScenarioRunner(sc, bag=str(bag), registry=test_registry, progress=False)
    r.setup()
    talker = r.nodes['talker']
    assert not talker.closed
    res = r.run()
    assert res.status == 'complete' and talker.closed
    meta = read_run_metadata(bag)
    assert json.loads(meta['skipped_nodes']) == res.skipped == ['not_installed']


def test_a_runner_closed_before_its_run_leaves_an_interrupted_recording(tmp_path,
                                                                       make_scenario,
                                                                       test_registry):
    bag = tmp_path / 'early.mcap'
    r = ScenarioRunner(make_scenario(), bag=str(bag), registry=test_registry, progress=False)
    r.setup()
    r.close()
    meta = read_run_metadata(bag)
    assert meta['status'] == 'interrupted' and 'before the run finished' in meta['reason']


def test_a_duration_not_exactly_a_multiple_in_floats_runs_every_step(tmp_path, make_scenario,
                                                                   test_registry):
    """0.35 / 0.001 is 349.99999999999994 in floats: the run still has 350 steps."""
    assert 0.35 / 0.001 < 350
    res = ScenarioRunner(make_scenario(duration=0.35), bag=None, registry=test_registry,
                         progress=False, record=False).run()
    assert res.status == 'complete', res.reason
    assert res.steps == 350 and res.published['/test/force'] == 350
    assert res.sim_time == pytest.approx(0.35)

"""The ROS graph (lockstep, the default scenario's nodes and parameters) gives the same force
feedback errors as the pure closed-loop experiment (impedance_master.experiment) for the same
seed and configuration, measured by the same metric (impedance_master.metrics via analyze).

Tolerance: 5 % of the experiment's value + 1 mN on MAE (normal and outage intervals) and 5 mN
on the max. The seeds are matched (vessel phase, haptic device, hand script; the slave's
sensor noise via ExperimentConfig.sensor_seed = seed + 1 as sim_slave_node draws it; the link
seeds do not matter without loss or jitter), so what remains is the graph's ordering within
a 1 ms step (the renderer node uses the command of the previous step) and float rounding:
measured 0.2 % apart. The tolerance is far below what the integration bugs it guards against
cost: an identifier fitted with x'' = 0 (no acceleration in /slave/joint_state) gave 0.065 N
in outages against the experiment's 0.027 N, a robot starting at 0 instead of the hand's 8 mm
raised the normal-interval MAE from 0.028 to 0.036 N (both measured).
"""
import pytest

from catheter_bringup.analyze import analyze
from catheter_bringup.runner import ScenarioRunner
from catheter_bringup.scenario import load_scenario

pytest.importorskip('sim_slave.sim_slave_node')
from impedance_master.experiment import ExperimentConfig, run_experiment  # noqa: E402

DURATION = 6.0     # s: the first outage (4-5 s) and its catch-up are inside


def test_lockstep_graph_matches_the_pure_experiment(tmp_path):
    sc = load_scenario('experiment_ii')
    # only the teleoperation loop (no camera pipeline): the force streams and the command
    sc['outputs'] = ['/master/rendered_force', '/master/hand_force', '/master/command',
                     '/slave/force']
    sc['nodes'].pop('dfr_master_node', None)
    res = ScenarioRunner(sc, bag=str(tmp_path / 'g.mcap'), duration=DURATION, progress=False,
                         log=lambda *_: None).run()
    assert res.status == 'complete', res.reason
    got = analyze(res.bag)
    assert got['reference'] == 'twin'
    seed = sc['seed']
    exp = run_experiment(ExperimentConfig(
        experiment='II', mode='ima', seed=seed, sensor_seed=seed + 1, duration=DURATION,
        delay=sc['link']['delay'], outages=tuple(tuple(o) for o in sc['link']['outages']),
        passivity=True))
    graph = got['force_tracking']['hand_ima']
    for iv in ('normal', 'outage'):
        g, e = graph[iv], exp.metrics[iv]
        assert g['n'] == e['n'], iv
        assert abs(g['mae'] - e['mae']) <= 0.05 * e['mae'] + 1e-3, (iv, g, e)
        assert abs(g['max'] - e['max']) <= 5e-3, (iv, g, e)
    # and the default IMA's outage error is what the experiment gets, not several times it
    assert graph['outage']['mae'] < 0.04

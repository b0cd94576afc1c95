"""analyze and metrics against exact answers: recordings written with known signals."""
import json
import math

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from rclpy.serialization import serialize_message

from catheter_bringup import metrics as M
from catheter_bringup.analyze import analyze, format_report, main as analyze_main
from catheter_bringup.recorder import McapRecorder


def _wrench(fx, t):
    from geometry_msgs.msg import WrenchStamped
    m = WrenchStamped()
    m.header.stamp.sec, m.header.stamp.nanosec = int(t // 1), int(round((t % 1) * 1e9))
    m.header.frame_id = 'catheter_base'
    m.wrench.force.x = float(fx)
    return m


def _write(path, delay=0.2, outages=((1.0, 0.5),), err_normal=0.01, err_outage=0.05,
           duration=2.0, with_estimate=False):
    """Slave force f(t) = 0.3 sin(t); rendered f(t + delay) + a known error: err_normal outside
    the outage windows, err_outage inside (alternating sign, so MAE = |err|, RMSE = |err|).
    Outage window of a link outage (start, length): [start + delay, start + length + 2 delay),
    impedance_master.metrics' convention."""
    sc = {'name': 'synthetic', 'link': {'delay': delay, 'outages': [list(o) for o in outages]},
          'nodes': {'ima_master_node': {'params': {'mode': 'ima'}},
                    'dfr_master_node': {'executable': 'ima_master_node', 'params': {'mode': 'dfr'},
                                        'remap': {'/master/rendered_force':
                                                  '/master/dfr/rendered_force'}}},
          'metrics': {'truth_topic': '/truth'}}
    rec = McapRecorder(path)
    for t in ('/slave/force', '/master/rendered_force', '/master/dfr/rendered_force'):
        rec.add_topic(t, 'geometry_msgs/msg/WrenchStamped')
    if with_estimate:
        rec.add_topic('/catheter/tip_wrench', 'geometry_msgs/msg/WrenchStamped')
        rec.add_topic('/truth', 'geometry_msgs/msg/WrenchStamped')
    n = int(duration * 1000)
    for k in range(n + 1):
        t = k * 1e-3
        ns = k * 1_000_000
        rec.write('/slave/force', serialize_message(_wrench(0.3 * math.sin(t), t)), ns)
        inside = any(a + delay <= t < a + b + 2 * delay for a, b in outages)
        e = (err_outage if inside else err_normal) * (1 if k % 2 else -1)
        rec.write('/master/rendered_force',
                  serialize_message(_wrench(0.3 * math.sin(t + delay) + e, t)), ns)
        rec.write('/master/dfr/rendered_force',
                  serialize_message(_wrench(0.3 * math.sin(t + delay) + 2 * e, t)), ns)
        if with_estimate and k % 33 == 0:
            rec.write('/truth', serialize_message(_wrench(0.1, t)), ns)
            rec.write('/catheter/tip_wrench', serialize_message(_wrench(0.1 + 0.02, t)),
                      ns + 5_000_000)
    rec.close('complete', extra={'scenario_yaml': yaml.safe_dump(sc), 'mode': 'lockstep',
                                 'sim_time_reached_s': duration})
    return path


def test_force_tracking_recovers_known_errors(tmp_path):
    res = analyze(_write(tmp_path / 's.mcap'), skip=0.0)
    ft = res['force_tracking']
    assert set(ft) == {'ima', 'dfr'}
    # the last 200 ms have no slave force at t + delay: left out (n counts the rest)
    assert ft['ima']['normal']['mae'] == pytest.approx(0.01, abs=1e-9)
    assert ft['ima']['outage']['mae'] == pytest.approx(0.05, abs=1e-9)
    assert ft['ima']['outage']['rmse'] == pytest.approx(0.05, abs=1e-9)
    assert ft['dfr']['outage']['max'] == pytest.approx(0.10, abs=1e-9)
    # window [1.2, 1.9) s, cut at 1.8 s (slave force only up to 2.0 s): 601 samples
    assert ft['ima']['outage']['n'] == 601
    assert ft['ima']['all']['n'] == 2001 - 200
    report = format_report(res)
    assert 'ima' in report and '0.0500' in report and '0.0520' in report   # thesis beside


def test_estimation_error_and_latency(tmp_path):
    res = analyze(_write(tmp_path / 'e.mcap', with_estimate=True), skip=0.0)
    est = res['estimation']
    assert est['reference'] == '/truth' and est['reference_is_truth']
    assert est['x']['mae'] == pytest.approx(0.02, abs=1e-9)
    s = res['streams']['/catheter/tip_wrench']
    assert s['latency_p50'] == pytest.approx(0.005, abs=1e-9)
    assert s['rate_hz'] == pytest.approx(1000 / 33, rel=1e-6)


def test_analyze_cli_writes_json(tmp_path, capsys):
    bag = _write(tmp_path / 'c.mcap')
    out = tmp_path / 'm.json'
    assert analyze_main([str(bag), '--json', str(out), '--skip', '0']) == 0
    data = json.loads(out.read_text())
    assert data['force_tracking']['ima']['outage']['mae'] == pytest.approx(0.05, abs=1e-9)
    assert 'Force tracking' in capsys.readouterr().out


def test_metrics_refuse_bad_input():
    with pytest.raises(ValueError, match='delay'):
        M.force_tracking([0, 1], [0, 0], [0, 1], [0, 0], delay=-1)
    with pytest.raises(ValueError, match='t_master'):
        M.force_tracking([[0, 1]], [0, 0], [0, 1], [0, 0], delay=0)
    with pytest.raises(ValueError, match='sig'):
        M.align([0, 1], [0, 1], [0, float('nan')])


@settings(max_examples=40, deadline=None)
@given(st.floats(0.0, 1.0), st.floats(-0.5, 0.5), st.floats(0.01, 2.0))
def test_align_of_a_line_is_exact_and_nan_outside(shift, offset, slope):
    t = np.linspace(0.0, 2.0, 201)
    sig = offset + slope * t
    q = np.linspace(0.0, 2.0, 57)
    got = M.align(q, t, sig, shift=shift)
    inside = q + shift <= 2.0
    np.testing.assert_allclose(got[inside], offset + slope * (q[inside] + shift), atol=1e-12)
    assert np.all(np.isnan(got[~inside]))


def test_the_error_statistics_are_impedance_master_s():
    """One definition of the error metric (tested in tests/impedance_master/test_metrics.py)."""
    import impedance_master.metrics as IM
    assert M.error_stats is IM.error_stats and M.outage_mask is IM.outage_mask


def test_force_error_uses_the_twin_reference_of_the_master_motion(tmp_path):
    """With /master/command recorded, the reference is impedance_master.metrics' twin vessel
    (sim_slave_node's seed and vessel parameters from the scenario) along the master's motion
    at t + delay, and the outage intervals are [start + d, start + length + 2 d)."""
    from catheter_common.messages import master_command_msg
    from impedance_master.metrics import twin_reference
    from sim_slave.vessel import VesselParams
    delay, seed = 0.2, 5
    sc = {'name': 'twin', 'seed': seed, 'link': {'delay': delay, 'outages': [[1.0, 0.5]]},
          'nodes': {'ima_master_node': {'params': {'mode': 'ima'}},
                    'sim_slave_node': {'params': {'vessel.friction_per_length': 4.0}}},
          'metrics': {'skip': 0.0}}
    n = 3000
    t = np.arange(n) * 1e-3
    x = 0.03 + 0.01 * np.sin(2.0 * t)
    xd = 0.02 * np.cos(2.0 * t)
    ref = twin_reference(t, x, xd, delay, VesselParams(friction_per_length=4.0), seed)
    outage = (t >= 1.2) & (t < 1.9)
    err = np.where(outage, 0.05, 0.01) * np.where(np.arange(n) % 2, 1.0, -1.0)
    rec = McapRecorder(tmp_path / 't.mcap')
    rec.add_topic('/slave/force', 'geometry_msgs/msg/WrenchStamped')
    rec.add_topic('/master/rendered_force', 'geometry_msgs/msg/WrenchStamped')
    rec.add_topic('/master/command', 'catheter_interfaces/msg/MasterCommand')
    t0 = 100.0            # the experiment clock starts at the slave's first message
    for k in range(n):
        ns = int(round((t0 + t[k]) * 1e9))
        cmd = master_command_msg(x[k], xd[k], 0.0, stamp=ns)
        rec.write('/master/command', serialize_message(cmd), ns)
        rec.write('/slave/force', serialize_message(_wrench(0.0, t0 + t[k])), ns)
        rec.write('/master/rendered_force',
                  serialize_message(_wrench(ref[k] + err[k], t0 + t[k])), ns)
    rec.close('complete', extra={'scenario_yaml': yaml.safe_dump(sc), 'mode': 'lockstep',
                                 'sim_time_reached_s': 3.0})
    res = analyze(tmp_path / 't.mcap')
    assert res['reference'] == 'twin'
    ft = res['force_tracking']['ima']
    assert ft['outage']['n'] == 700 and ft['normal']['n'] == n - 700
    assert ft['outage']['mae'] == pytest.approx(0.05, abs=1e-9)
    assert ft['normal']['mae'] == pytest.approx(0.01, abs=1e-9)
    assert ft['all']['max'] == pytest.approx(0.05, abs=1e-9)
    # the default vessel (wrong parameters) would not reproduce the reference
    wrong = twin_reference(t, x, xd, delay, VesselParams(), seed)
    assert np.max(np.abs(wrong - ref)) > 0.01
    assert 'vs slave' in format_report(res)


def test_an_odd_outages_list_is_a_usage_error(tmp_path, capsys):
    """--outages 4,1,8 (a start without its length): argparse's usage error (exit 2) naming
    the option, not an IndexError."""
    bag = _write(tmp_path / 'o.mcap', duration=0.1)
    with pytest.raises(SystemExit) as exc:
        analyze_main([str(bag), '--outages', '4,1,8'])
    assert exc.value.code == 2
    assert 'start,length pairs' in capsys.readouterr().err


def test_the_json_file_is_strict_json_with_null_for_undefined_metrics(tmp_path):
    """No outages: the outage interval has no samples, its MAE is undefined; the file must
    say null there (NaN is not JSON: jq, JavaScript and strict parsers reject it)."""
    bag = _write(tmp_path / 'n.mcap', outages=(), duration=0.5)
    out = tmp_path / 'n.json'
    assert analyze_main([str(bag), '--quiet', '--skip', '0', '--json', str(out)]) == 0

    def refuse(name):
        raise ValueError(f'non-JSON constant {name} in the file')
    data = json.loads(out.read_text(), parse_constant=refuse)
    outage = data['force_tracking']['ima']['outage']
    assert outage['n'] == 0 and outage['mae'] is None
    assert data['force_tracking']['ima']['normal']['mae'] == pytest.approx(0.01, abs=1e-9)

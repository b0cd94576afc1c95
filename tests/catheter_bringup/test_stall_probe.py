"""The machine stall probe (catheter_bringup.stall_probe) and the gaps of realtime.stream_stats
that it is compared with: a stall made on purpose is seen, overlap is decided right."""
import json
import os
import signal
import struct
import subprocess
import sys
import time

import numpy as np
import pytest

from catheter_bringup import realtime as R
from catheter_bringup import stall_probe as P


def test_coinciding_hand_checked():
    stalls = [[10.000, 3.0], [20.000, 1.5]]        # [10.000, 10.003], [20.000, 20.0015]
    gaps = [[9.998, 2.5],      # [9.998, 10.0005]: its end overlaps the first stall
            [10.0025, 2.2],    # starts inside the first stall
            [10.010, 4.0],     # [10.010, 10.014]: 7 ms after it, beyond the slack
            [19.990, 20.0],    # [19.990, 20.010]: holds the second stall whole
            [20.0025, 2.0]]    # starts 1 ms after its end: beyond the 0.5 ms slack
    assert P.coinciding(gaps, stalls) == [True, True, False, True, False]
    # a wider slack takes the last one in; none takes the third
    assert P.coinciding(gaps, stalls, slack_s=1.5e-3) == [True, True, False, True, True]
    assert P.coinciding(gaps, []) == [False] * 5
    assert P.coinciding([], stalls) == []
    with pytest.raises(ValueError, match='slack_s'):
        P.coinciding(gaps, stalls, slack_s=-1e-3)


def test_stream_stats_lists_its_gaps():
    t = np.arange(0.0, 0.1, 0.001)
    t = np.r_[t[:40], t[40:] + 0.0015, ]             # one 2.5 ms period after sample 39
    t = np.r_[t[:70], t[70:] + 0.005]                 # one 6 ms period after sample 69
    s = R.stream_stats(t, skip_fraction=0.0)
    assert [round(g[1], 6) for g in s['gaps']] == [2.5, 6.0]
    assert s['gaps'][0][0] == pytest.approx(t[39]) and s['gaps'][1][0] == pytest.approx(t[69])
    # a 2 ms period is not a gap (GAP_S is a strict bound); regular streams have none
    assert R.stream_stats([0.0, 0.001, 0.003, 0.004], 0.0)['gaps'] == []
    assert R.stream_stats([0.0, 1.0], 0.0)['gaps'] == []


def test_stream_stats_keeps_the_longest_gaps_in_time_order(monkeypatch):
    monkeypatch.setattr(R, 'MAX_GAPS', 2)
    d = np.r_[np.full(5, 0.001), 0.004, 0.001, 0.009, 0.001, 0.003, 0.001, 0.007, 0.001]
    t = np.r_[0.0, np.cumsum(d)]
    gaps = R.stream_stats(t, 0.0)['gaps']
    assert [round(g[1], 6) for g in gaps] == [9.0, 7.0]
    assert gaps[0][0] < gaps[1][0]


def test_probe_loop_refuses_bad_settings():
    for kw, name in [({'period_s': 0.0}, 'period_s'), ({'threshold_s': -1e-3}, 'threshold_s'),
                     ({'seconds': float('nan')}, 'seconds'), ({'period_s': True}, 'period_s')]:
        with pytest.raises(ValueError, match=name):
            P.probe_loop(**kw)
    with pytest.raises(ValueError, match='threshold_s'):
        P.StallProbe(threshold_s=0)


def test_probe_loop_reports_late_wake_ups_only():
    # 30 ms asleep in one go: with a threshold of 20 ms nothing; the loop's own periods are
    # far shorter than that
    calls = []

    def stop():
        calls.append(1)
        if len(calls) == 3:
            time.sleep(0.03)           # inside the loop: the next wake-up is 30 ms late
        return len(calls) >= 6
    out = P.probe_loop(period_s=1e-3, threshold_s=20e-3, stop=stop)
    assert len(out) == 1 and out[0][1] >= 25.0
    assert P.probe_loop(period_s=1e-3, threshold_s=20e-3, seconds=0.02) == []


def _env():
    return {**os.environ, 'PYTHONPATH': os.pathsep.join(p for p in sys.path if p)}


def test_probe_process_sees_a_stall_made_on_purpose():
    """The probe stopped (SIGSTOP) for 80 ms: the one report it prints on SIGTERM holds a
    stall of at least 70 ms, due within the time it was stopped."""
    proc = subprocess.Popen([sys.executable, '-m', 'catheter_bringup.stall_probe', '--json',
                             '--threshold', '0.02'], stdout=subprocess.PIPE, text=True,
                            env=_env())
    try:
        time.sleep(1.0)                       # imported and looping
        t_stop = time.monotonic()
        proc.send_signal(signal.SIGSTOP)
        time.sleep(0.08)
        proc.send_signal(signal.SIGCONT)
        t_cont = time.monotonic()
        time.sleep(0.1)
        proc.send_signal(signal.SIGTERM)
        out, _ = proc.communicate(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
    rep = json.loads(out)
    assert proc.returncode == 0
    big = [s for s in rep['stalls'] if s[1] >= 70.0]
    assert big, rep['stalls']
    assert any(t_stop - 0.01 <= s[0] <= t_cont for s in big), (t_stop, t_cont, big)


def test_stall_probe_context_reports_every_cpu():
    with P.StallProbe(threshold_s=0.5) as probe:   # 500 ms: nothing here stalls that long
        time.sleep(0.3)
    cpus = sorted(os.sched_getaffinity(0))
    assert probe.errors == {}
    assert sorted(probe.stalls) == cpus and sorted(probe.scheduling) == cpus
    assert all(v == [] for v in probe.stalls.values())
    sm = probe.summary()
    assert sm['span_s'] == pytest.approx(0.3, abs=0.25)
    assert all(sm[f'cpu{c}_n'] == 0 for c in cpus)


def test_stall_probe_summary_and_selection_hand_checked():
    probe = P.StallProbe(cpus=[0, 1])
    probe.t_start, probe.t_end = 0.0, 10.0
    probe.stalls = {0: [[1.0, 3.0], [5.0, 2.0]], 1: [[1.0005, 4.0], [7.0, 9.0]]}
    sm = probe.summary()
    assert sm['cpu0_n'] == 2 and sm['cpu0_max_ms'] == 3.0 and sm['cpu1_max_ms'] == 9.0
    assert sm['together'] == 1                 # only the stall at 1 s is on both CPUs
    assert probe.stalls_on([1]) == [[1.0005, 4.0], [7.0, 9.0]]
    assert probe.stalls_on(None) == [[1.0, 3.0], [1.0005, 4.0], [5.0, 2.0], [7.0, 9.0]]


def test_hold_cpu_latency_writes_the_request_and_keeps_it_open(tmp_path):
    path = tmp_path / 'cpu_dma_latency'
    path.write_bytes(b'')
    req = R.hold_cpu_latency(7, log=lambda m: None, path=str(path))
    assert req is not None and req.held and repr(req) == 'CPU latency 7 us'
    assert path.read_bytes() == struct.pack('=i', 7)      # one s32, native byte order
    fd = req._fd
    os.fstat(fd)                                            # still open: the request holds
    req.close()
    assert not req.held and 'withdrawn' in repr(req)
    with pytest.raises(OSError):
        os.fstat(fd)
    req.close()                                             # twice is harmless


def test_hold_cpu_latency_refuses_bad_values_and_says_when_it_cannot(tmp_path):
    for bad in (-1, 1.5, True, None):
        with pytest.raises(ValueError, match='us must be'):
            R.hold_cpu_latency(bad, log=lambda m: None, path=str(tmp_path / 'x'))
    said = []
    assert R.hold_cpu_latency(0, log=said.append, path=str(tmp_path / 'missing' / 'x')) is None
    assert len(said) == 1 and 'CPU latency request not made' in said[0]


def test_hold_cpu_latency_on_this_machine():
    """The real device: while held, the kernel's aggregate request (what reading the device
    returns) is 0; without the permission nothing is held and one line says why."""
    path = R.CPU_DMA_LATENCY
    said = []
    req = R.hold_cpu_latency(0, log=said.append)
    if not (os.path.exists(path) and os.access(path, os.R_OK | os.W_OK)):
        assert req is None and len(said) == 1
        return
    try:
        assert req is not None and said == []
        with open(path, 'rb') as f:
            assert struct.unpack('=i', f.read(4))[0] == 0
    finally:
        req.close()


def test_scenario_cpu_latency_field():
    from catheter_bringup.overrides import apply_overrides
    from catheter_bringup.scenario import load_scenario
    sc = load_scenario('experiment_ii')
    assert sc['realtime_cpu_latency_us'] == -1           # off unless asked for
    assert apply_overrides(sc, ['realtime_cpu_latency_us=0'])['realtime_cpu_latency_us'] == 0
    with pytest.raises(ValueError, match='realtime_cpu_latency_us'):
        apply_overrides(sc, ['realtime_cpu_latency_us=-2'])


def test_latency_stats_lists_the_slow_ones_with_their_start():
    lat = [0.5, 0.5, 0.020, 0.040, 0.010, 0.0331]        # the first two: start-up, left out
    t = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]
    s = R.latency_stats(lat, times_s=t)
    assert s['n'] == 4
    assert [[round(a, 6), round(b, 6)] for a, b in s['slow']] == [[3.96, 40.0], [5.9669, 33.1]]
    assert 'slow' not in R.latency_stats(lat)
    with pytest.raises(ValueError, match='times_s'):
        R.latency_stats(lat, times_s=t[:-1])
    assert R.latency_stats([0.1], times_s=[1.0])['slow'] == []      # all start-up

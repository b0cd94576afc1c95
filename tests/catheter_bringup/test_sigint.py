"""Ctrl-C or SIGTERM on a running `run_scenario` process: it exits 0, the recording is closed,
readable, says it was interrupted, by which signal (SIGTERM was recorded as "KeyboardInterrupt
(Ctrl-C)") and how far it got."""
import os
import signal
import subprocess
import sys
import time

import pytest

from catheter_bringup.recorder import read_run_metadata


@pytest.mark.parametrize('sig,reason', [(signal.SIGINT, 'SIGINT (Ctrl-C)'),
                                        (signal.SIGTERM, 'SIGTERM')], ids=['SIGINT', 'SIGTERM'])
def test_signal_closes_the_recording_and_names_the_signal(tmp_path, sig, reason):
    bag = tmp_path / 'int.mcap'
    env = dict(os.environ)
    proc = subprocess.Popen([sys.executable, '-m', 'catheter_bringup.run_scenario', 'smoke',
                             '--duration', '60', '--bag', str(bag), '--quiet'],
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        t_end = time.monotonic() + 60
        # the recording exists from the start; wait until the run has gone on for a while
        while time.monotonic() < t_end and not (bag.exists() and bag.stat().st_size > 20_000):
            assert proc.poll() is None, proc.stdout.read()
            time.sleep(0.2)
        proc.send_signal(sig)
        code = proc.wait(timeout=30)
        out = proc.stdout.read()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert code == 0, out
    assert 'Traceback' not in out and 'FATAL' not in out, out
    assert f'interrupted ({reason})' in out, out
    meta = read_run_metadata(bag)
    assert meta['status'] == 'interrupted', meta
    assert meta['reason'] == reason, meta
    reached = float(meta['sim_time_reached_s'])
    assert 0.0 < reached < 60.0
    assert int(meta['last_log_time_ns']) <= reached * 1e9 + 1e6

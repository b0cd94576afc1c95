"""Ctrl-C on a running `run_scenario` process: it exits 0 and the recording is closed, readable,
and says it was interrupted and how far it got."""
import os
import signal
import subprocess
import sys
import time

from catheter_bringup.recorder import read_run_metadata


def test_sigint_closes_the_recording(tmp_path):
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
        proc.send_signal(signal.SIGINT)
        code = proc.wait(timeout=30)
        out = proc.stdout.read()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert code == 0, out
    assert 'Traceback' not in out, out
    meta = read_run_metadata(bag)
    assert meta['status'] == 'interrupted', meta
    reached = float(meta['sim_time_reached_s'])
    assert 0.0 < reached < 60.0
    assert int(meta['last_log_time_ns']) <= reached * 1e9 + 1e6

"""The worker process of a split real-time run: the image pipeline nodes (tens of ms per frame)
run in a second `run_scenario` process so they never hold up the 1 kHz loops; messages
between the two go through DDS."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import tempfile
import time
from typing import Callable, List, Optional

import yaml


class Worker:
    """Starts `run_scenario --only <nodes>` on the scenario and stops it with SIGINT."""

    def __init__(self, scenario: dict, nodes: List[str], log: Callable[[str], None]):
        self.nodes = list(nodes)
        self.log = log
        sc = dict(scenario)
        sc.pop('source', None)
        fd, self._yaml = tempfile.mkstemp(suffix='.yaml', prefix='worker_')
        with os.fdopen(fd, 'w') as f:
            yaml.safe_dump(sc, f)
        cmd = [sys.executable, '-m', 'catheter_bringup.run_scenario', self._yaml, '--mode',
               'realtime', '--no-record', '--quiet', '--only', ','.join(self.nodes),
               '--duration', str(scenario['duration'] + 30.0)]
        self._log_file = tempfile.TemporaryFile(mode='w+')
        self.proc: Optional[subprocess.Popen] = subprocess.Popen(
            cmd, stdout=subprocess.DEVNULL, stderr=self._log_file, text=True)
        self.log(f'[run] image pipeline in a worker process (pid {self.proc.pid}): '
                 f'{", ".join(self.nodes)}')

    def wait_in_graph(self, node_names: Callable[[], List[str]], timeout: float = 60.0) -> bool:
        """Wait until the worker's nodes are in the ROS graph; False (and the worker is
        stopped) if it exited first."""
        t_end = time.monotonic() + timeout
        while time.monotonic() < t_end:
            if set(self.nodes) <= set(node_names()):
                return True
            if self.proc.poll() is not None:
                self._log_file.seek(0)
                err = self._log_file.read()[-2000:]
                self.log(f'[run] worker process exited ({self.proc.returncode}): {err}')
                self.proc = None
                self._cleanup()
                return False
            time.sleep(0.1)
        return True

    def stop(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(timeout=10)
            except Exception:  # noqa: BLE001
                self.proc.kill()
                self.proc.wait()
        self.proc = None
        self._cleanup()

    def _cleanup(self) -> None:
        try:
            os.unlink(self._yaml)
        except OSError:
            pass

"""The worker processes of a multi-process real-time run. Each is a `run_scenario --only
<nodes>` process on the same scenario; messages between the processes go through DDS.

- layout one (``realtime_processes: 2``): the image pipeline nodes (tens of ms per frame) in
  one worker, so they never hold up the 1 kHz loops of the runner's process;
- layout split: one worker per process of `catheter_bringup.scenario.PROCESSES` (master,
  slave, vision), the runner's process only records.

At its end each worker writes a JSON report (what it published and took from DDS per topic,
its callback cost, GC pauses, the scheduling it got; in layout split also what it recorded
into its part file, see `catheter_bringup.local_recording`), which `Workers.reports`
collects."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from typing import Callable, Dict, List, Optional

import yaml

#: node parameters every worker process sets (the scenario's `global_params` may override
#: them): the image pipeline processes a frame as it arrives instead of at its next timer
#: tick (shape_node `process_on_arrival`; lockstep, in one process or two, keeps the timer
#: and so its message order)
WORKER_PARAMS = {'process_on_arrival': True}


class Worker:
    """Starts `run_scenario --only <nodes> --process <name>` on the scenario; stopped with
    SIGINT."""

    def __init__(self, scenario: dict, nodes: List[str], log: Callable[[str], None],
                 name: str = 'vision', part: Optional[str] = None,
                 cpus: Optional[frozenset] = None):
        self.nodes = list(nodes)
        self.name = name
        self.log = log
        sc = dict(scenario)
        sc.pop('source', None)
        sc['global_params'] = {**WORKER_PARAMS, **(sc.get('global_params') or {})}
        fd, self._yaml = tempfile.mkstemp(suffix='.yaml', prefix=f'worker_{name}_')
        with os.fdopen(fd, 'w') as f:
            yaml.safe_dump(sc, f)
        fd, self._report = tempfile.mkstemp(suffix='.json', prefix=f'worker_{name}_')
        os.close(fd)
        #: created by `go()`: the worker starts its loop then (after the recorder subscribed)
        self._go = self._report[:-5] + '.go'
        cmd = [sys.executable, '-m', 'catheter_bringup.run_scenario', self._yaml, '--mode',
               'realtime', '--no-record', '--quiet', '--only', ','.join(self.nodes),
               '--process', name, '--report', self._report, '--go', self._go,
               '--duration', str(scenario['duration'] + 60.0)]
        if part:
            cmd += ['--part-bag', part]    # records its nodes' messages itself
        if cpus:
            # the worker pins itself (`run_scenario --cpus`, as the launch file's workers)
            cmd += ['--cpus', ','.join(str(c) for c in sorted(cpus))]
        self._log_file = tempfile.TemporaryFile(mode='w+')
        self.proc: Optional[subprocess.Popen] = subprocess.Popen(
            cmd, stdout=subprocess.DEVNULL, stderr=self._log_file, text=True)
        self.log(f'[run] {name} worker process (pid {self.proc.pid}): {", ".join(self.nodes)}'
                 + (f', CPUs {sorted(cpus)}' if cpus else ''))

    def exited(self) -> bool:
        """True (and the reason logged) if the process ended on its own."""
        if self.proc is None or self.proc.poll() is None:
            return False
        self.log(f'[run] {self.name} process exited ({self.proc.returncode}): {self.stderr()}')
        return True

    def stderr(self) -> str:
        self._log_file.seek(0)
        return self._log_file.read()[-2000:]

    def go(self) -> None:
        with open(self._go, 'w'):
            pass

    def interrupt(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)

    def running(self) -> bool:
        return self.proc is not None and self.proc.poll() is None

    def kill(self) -> None:
        if self.running():
            self.proc.kill()
            self.proc.wait()

    def report(self) -> Optional[dict]:
        """The worker's report, once it has exited (None if it wrote none)."""
        try:
            with open(self._report) as f:
                text = f.read()
            return json.loads(text) if text.strip() else None
        except (OSError, ValueError):
            return None

    def cleanup(self) -> None:
        for p in (self._yaml, self._report, self._go):
            try:
                os.unlink(p)
            except OSError:
                pass


class Workers:
    """The worker processes of one run: started together, waited for together, stopped
    together (SIGINT to all, then wait), reports collected."""

    def __init__(self, scenario: dict, groups: Dict[str, List[str]],
                 log: Callable[[str], None], parts: Optional[Dict[str, str]] = None):
        from catheter_bringup.realtime import worker_cpus
        self.log = log
        parts = parts or {}
        # CPU placement with the loops under SCHED_FIFO (`realtime.worker_cpus`)
        place = int(scenario.get('realtime_priority', 0)) > 0
        cpus = os.sched_getaffinity(0) if hasattr(os, 'sched_getaffinity') else ()
        self.workers = [Worker(scenario, nodes, log, name, parts.get(name),
                               worker_cpus(name, groups, cpus) if place else None)
                        for name, nodes in groups.items()]
        self.reports: Dict[str, dict] = {}
        #: after `stop`: per link topic and receiving process, sent / taken / lost by DDS
        self.link: Dict[str, dict] = {}

    @property
    def nodes(self) -> List[str]:
        return [n for w in self.workers for n in w.nodes]

    def wait_in_graph(self, node_names: Callable[[], List[str]], timeout: float = 90.0) -> bool:
        """Wait until every worker's nodes are in the ROS graph; False (and all workers
        stopped) if one exited first."""
        t_end = time.monotonic() + timeout
        want = set(self.nodes)
        while time.monotonic() < t_end:
            if want <= set(node_names()):
                return True
            if any(w.exited() for w in self.workers):
                self.stop(lambda: None)
                return False
            time.sleep(0.1)
        self.log(f'[run] workers not in the graph after {timeout:g} s: '
                 f'{sorted(want - set(node_names()))}')
        return True

    def go(self) -> None:
        """Let every worker start its loop."""
        for w in self.workers:
            w.go()

    def interrupt(self) -> None:
        """SIGINT to every worker (they stop their loops, report and exit)."""
        for w in self.workers:
            w.interrupt()

    def stop(self, spin: Callable[[], None], timeout: float = 15.0) -> None:
        """SIGINT to every worker, then `spin()` (the recorder takes what is in flight) until
        all have exited; a worker still running after `timeout` s is killed."""
        for w in self.workers:
            w.interrupt()
        t_end = time.monotonic() + timeout
        while any(w.running() for w in self.workers) and time.monotonic() < t_end:
            spin()
        for w in self.workers:
            if w.running():
                self.log(f'[run] {w.name} process did not stop: killed')
                w.kill()
            rep = w.report()
            if rep is not None:
                rep.setdefault('cpus', None)     # the CPUs it kept itself on (None: any)
                self.reports[w.name] = rep
            w.cleanup()
        self.workers = []
        self.link = self._link_loss()

    def _link_loss(self) -> Dict[str, dict]:
        """Per link topic and receiving process: what DDS lost between the processes
        (`catheter_bringup.realtime.link_loss`) and, `dds_reported`, how many samples DDS
        itself reported lost to the receiver while its loop ran (its reader saw a gap in the
        sequence numbers: transport or sender; None when not watched). A loss that DDS did not
        report was dropped by the receiving subscription's own queue (not taken in time).
        The stamp lists leave the reports."""
        from catheter_bringup.realtime import link_loss
        sent, taken, reported = {}, {}, {}
        for name, rep in self.reports.items():
            rt = rep.get('realtime') or {}
            for t, v in (rt.pop('link_sent', None) or {}).items():
                sent[t] = v
            for t, v in (rt.pop('link_taken', None) or {}).items():
                taken.setdefault(t, {})[name] = v
            for t, n in (rt.pop('link_dds_lost', None) or {}).items():
                reported[t, name] = n
        out = {}
        for t in sorted(sent):
            for proc, v in sorted(taken.get(t, {}).items()):
                out[f'{t} -> {proc}'] = dict(link_loss(sent[t], v),
                                             dds_reported=reported.get((t, proc)))
        return out

    def published(self) -> Dict[str, int]:
        out: Dict[str, int] = {}
        for rep in self.reports.values():
            for t, n in rep.get('published', {}).items():
                out[t] = out.get(t, 0) + int(n)
        return out

    def cost(self) -> Dict[str, dict]:
        return {node: c for rep in self.reports.values()
                for node, c in rep.get('cost', {}).items()}

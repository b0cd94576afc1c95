"""The end of a scenario run (`ScenarioRunner`'s teardown): stop the vision peer and the
worker processes, close the recording with its ``catheter_run`` record (status, reason, what
was published and recorded, the parts of a split run), build the `RunResult`, and release
every node, executor and context. A mixin: it works on the runner's attributes."""
from __future__ import annotations

import signal
import time

from catheter_bringup.local_recording import merge_parts
from catheter_bringup.part_pipe import RecorderPipe
from catheter_bringup.rclpy_adapter import shutdown_context
from catheter_bringup.result import RunResult
from catheter_bringup.scenario import scenario_text


class RunTeardown:
    """`_finish` (the result of a run) and `close` (release everything; safe to call twice)."""

    def _finish(self, status, reason, sim, wall, steps) -> RunResult:
        self.child_reports, self.child_published, self.child_cost = {}, {}, {}
        if self.peer is not None:
            status, reason = self._stop_peer(status, reason)
        if self.children is not None:
            self._stop_children()
        if self.sink is not None:
            self.sink.flush()
        recorded = dict(self.sink.received) if self.sink else {}
        if self.part is not None:
            self.bus.record = None
            self.part.close(status, reason)
            recorded = self.part.counts
        if self.parts and self.recorder is not None:
            self.part_info = merge_parts(self.recorder, self.parts)
            recorded = dict(self.recorder.counts)
        published = dict(self.counter.counts)
        for t, n in self.child_published.items():
            published[t] = published.get(t, 0) + n
        for name, node in self.nodes.items():
            close = getattr(node, 'close', None)
            if callable(close):
                try:
                    close()
                except Exception as exc:  # noqa: BLE001 - keep shutting down
                    self.log(f'[run] error closing {name}: {exc!r}')
        if self.recorder is not None:
            self.recorder.close(status, reason, extra={
                'scenario': self.scenario['name'],
                'mode': self.scenario['mode'],
                'seed': self.scenario['seed'],
                'duration_s': self.scenario['duration'],
                'sim_time_reached_s': round(sim, 6),
                'steps': steps,
                'nodes': sorted(set(self.nodes) | set(self.peer_nodes)),
                'skipped_nodes': self.skipped,
                'start_errors': self.start_errors,
                'fallbacks': self.fallbacks,
                'published': published,
                **({'parts': self.part_info} if self.parts else {}),
                'scenario_yaml': scenario_text(self.scenario),
            })
        if isinstance(self.recorder, RecorderPipe) and self.sink is not None:
            # what the writer process wrote (a writer that died is not hidden: `lost` shows it)
            written = self.recorder.counts
            recorded = {t: written.get(t, 0) for t in recorded}
            if self.recorder.errors:
                self.log(f'[run] the recording writer reported {self.recorder.errors} errors')
        # shares of the time the loop ran (a worker's wall time includes its wait for go)
        loop_s = getattr(self, 'realtime_info', {}).get('loop_s', wall)
        cost = self.bus.cost.summary(loop_s) if self.bus is not None else {}
        cost.update(self.child_cost)
        res_nodes = sorted(set(self.nodes) | set(self.child_nodes) | set(self.peer_nodes))
        res = RunResult(self.scenario['name'], status, reason, self.bag, sim, wall, steps,
                        res_nodes, self.skipped, self.missing, published, recorded, cost,
                        received=dict(self.bus.received) if self.bus is not None else {},
                        processes=self.child_reports,
                        realtime=dict(getattr(self, 'realtime_info', {})))
        self.close()
        return res

    def close(self):
        if self.peer is not None:
            self.peer.kill()
            self.peer = None
        if getattr(self, '_watchdog', None) is not None:
            self._watchdog.cancel()
        if self.children is not None:
            self.children.stop(lambda: time.sleep(0.01))
            self.children = None
        for sig, handler in self._old_handlers.items():
            signal.signal(sig, handler)
        self._old_handlers = {}
        if self.part is not None and not self.part.closed:
            self.part.close('interrupted', 'closed before the run finished')
        if self.recorder is not None and not self.recorder.closed:
            self.recorder.close('interrupted', 'closed before the run finished')
        if self.executor is not None:
            for n in list(self.nodes.values()) + [self.runner_node]:
                try:
                    self.executor.remove_node(n)
                except Exception:  # noqa: BLE001
                    pass
        for n in list(self.nodes.values()) + ([self.runner_node] if self.runner_node else []):
            try:
                n.destroy_node()
            except Exception:  # noqa: BLE001
                pass
        self.nodes = {}
        self.runner_node = None
        if self.executor is not None:
            self.executor.shutdown()
            self.executor = None
        if self.context is not None and self._own_context:
            shutdown_context(self.context)
        self.context = None

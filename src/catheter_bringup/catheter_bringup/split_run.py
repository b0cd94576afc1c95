"""The runner's side of the split layout (real time, one process per group of
`catheter_bringup.scenario.PROCESSES`): which topics a worker puts on DDS, a worker's part
recording, and starting / stopping the worker processes from the runner's process.

`SplitRun` is a mixin of `catheter_bringup.runner.ScenarioRunner` (it uses the runner's
scenario, nodes, bus, sink, log and runner node); kept apart so runner.py holds the run
itself (set-up, the run, its end)."""
from __future__ import annotations

import threading
import time

from catheter_bringup.local_recording import wanted
from catheter_bringup.part_pipe import PartPipe
from catheter_bringup.rclpy_adapter import count_extra_subscriber
from catheter_bringup.ros_recording import type_name_of
from catheter_bringup.worker import Workers
from catheter_common import topics as T


def worker_dds_topics(consumed_elsewhere) -> set:
    """Layout split: what a worker publishes on DDS besides its local bus: the topics a node
    of another process consumes (the link topics between master and slave, the slave's
    joint state for the camera) and /diagnostics (the operator's tools). Nothing else: each
    worker records its own nodes, so a DDS publish of a topic nobody outside takes cost a
    serialisation hand-off to the rmw per message in the 1 kHz loop, and the process's own
    subscriptions of it were handed the copy back by DDS (taken and dropped). The scenario's
    ``dds: true`` puts every topic on DDS again (for outside tools: catheter_topic, rviz)."""
    return set(consumed_elsewhere) | {T.DIAGNOSTICS}


class SplitRun:
    """The split layout's worker processes and part recording (mixin of ScenarioRunner)."""

    def _record_part(self):
        """A worker of the split layout: every publish of its nodes' recorded topics goes,
        as the bytes the bus serialised, into its part file."""
        from catheter_bringup.ros_recording import qos_to_dict
        rec = self.scenario['record']
        # written by a process of its own (`part_pipe`): the loop only hands over bytes
        self.part = PartPipe(self.part_bag, self.process)
        for node in self.nodes.values():
            for pub in list(node.publishers):
                if wanted(pub.topic_name, rec['exclude'], rec.get('only') or None):
                    self.part.add_topic(pub.topic_name, type_name_of(pub.msg_type),
                                        [qos_to_dict(pub.qos_profile)])
                    # the part records it: a subscriber, as the DDS recorder was (nodes that
                    # publish only while someone subscribes keep publishing it)
                    count_extra_subscriber(pub)
        self.bus.record = self.part.record

    def _start_children(self):
        """Start the worker processes (real time) and wait until their nodes are in the
        graph."""
        self.children = Workers(self.scenario, self.child_groups, self.log, parts=self.parts)
        if not self.children.wait_in_graph(self.runner_node.get_node_names):
            self.children = None
            if not self.nodes:
                raise RuntimeError('a worker process failed to start (see the log)')
            return
        if self.sink is not None:
            # the workers' topics, recorded through DDS: subscribed before their loops start
            want = {t for t in self._child_produces if self.sink.wants(t)}
            t_end = time.monotonic() + 10.0
            while time.monotonic() < t_end:
                self.sink.discover()
                if not (want - set(self.sink.subs)):
                    break
                time.sleep(0.1)
            self._track()
            time.sleep(0.5)            # the workers' publishers match the new subscriptions
        self.children.go()
        # the workers stop at the end of the run even when this process cannot keep up
        # (an executor busy with a backlog of recorder messages returns late)
        self._watchdog = threading.Timer(self.scenario['duration'] + 1.0,
                                         self.children.interrupt)
        self._watchdog.daemon = True
        self._watchdog.start()

    def _stop_children(self):
        """Stop the workers (the recorder takes what they still publish meanwhile) and keep
        their reports."""
        if self.children is None:
            return
        if getattr(self, '_watchdog', None) is not None:
            self._watchdog.cancel()
        spin = self._spin_external if self.bus is not None else (
            lambda: self.executor.spin_once(timeout_sec=0.01))
        self.children.stop(spin)
        self.child_reports = dict(self.children.reports)
        if self.children.link:
            self.child_reports['link'] = self.children.link
        self.child_published = self.children.published()
        self.child_cost = self.children.cost()
        t_end = time.perf_counter() + 0.3
        while time.perf_counter() < t_end:
            spin()
        self.children = None

"""The lockstep run with the vision chain in a process of its own, the runner's side: starting
the vision process, taking its start report, ending it and taking its report. A mixin of
`catheter_bringup.runner.ScenarioRunner` (it uses the runner's scenario, registry, bag,
nodes, bus and log); the process and the recording's merge are `lockstep_peer.VisionPeer`,
the vision process itself `lockstep_follower`."""
from __future__ import annotations

from catheter_bringup.lockstep_peer import VisionError, VisionPeer
from catheter_bringup.rclpy_adapter import count_extra_subscriber


class LockstepSplit:
    """The lockstep vision process of ScenarioRunner (see the module docstring)."""

    def _start_peer(self, vision, chosen) -> VisionPeer:
        reg = None
        if self.registry is not None:
            reg = {k: {'executable': v.executable, 'module': v.module,
                       'consumes': list(v.consumes), 'produces': list(v.produces),
                       'kind': v.kind} for k, v in self.registry.items()}
        plan = {'scenario': dict(self.scenario), 'registry': reg,
                'order': [i.name for i in chosen], 'nodes': [i.name for i in vision],
                'record': bool(self.bag)}
        return VisionPeer(plan, self.log)

    def _peer_ready(self) -> None:
        """Take the vision process's start report: its nodes (and those left out), and
        forward its inputs to it from the bus."""
        ready = self.peer.wait_ready()
        self.peer_nodes = list(ready['nodes'])
        self.skipped = sorted(set(self.skipped) | set(ready['skipped']))
        self.start_errors.update(ready['start_errors'])
        self.fallbacks.update(ready['fallbacks'])
        theirs = set(ready['publishes'])
        ours = {s.topic_name for n in self.nodes.values() for s in n.subscriptions}
        if theirs & ours:
            raise VisionError(f'nodes of this process subscribe to {sorted(theirs & ours)}, '
                              'which the lockstep vision process publishes: set '
                              'lockstep_processes: 1')
        self.bus.record = self.peer.forward
        # the vision process subscribes to its inputs, as its nodes did in one process: a
        # publisher that works only while subscribed counts it from the first step (DDS
        # would match it across the processes only some time into the run)
        inputs = set(ready['inputs'])
        for node in self.nodes.values():
            for pub in node.publishers:
                if pub.topic_name in inputs:
                    count_extra_subscriber(pub)

    def _stop_peer(self, status: str, reason: str):
        """The end of the lockstep vision process: it runs the steps this process completed,
        the rest of both recordings is merged; its report becomes the process 'vision' of
        the result. A vision process that failed fails the run."""
        peer, self.peer = self.peer, None
        rep = peer.finish(self._step_done, status) or {}
        self.child_published = dict(rep.get('published', {}))
        self.child_cost = dict(rep.get('cost', {}))
        self.child_reports['vision'] = {
            'process': 'vision', 'mode': 'lockstep', 'status': rep.get('status', 'failed'),
            'reason': peer.error or rep.get('reason', ''), 'nodes': peer.nodes,
            'published': self.child_published, 'steps': rep.get('steps'),
            'cpu_s': rep.get('cpu_s'), 'cpu_total_s': rep.get('cpu_total_s'),
            'wall_s': rep.get('wall_s'),
            'wait_at_end_s': round(peer.wait_s, 3)}
        if peer.error is not None and status != 'failed':
            status, reason = 'failed', f'vision process: {peer.error}'
        return status, reason

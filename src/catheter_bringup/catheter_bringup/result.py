"""What a run of `catheter_bringup.runner.ScenarioRunner` did (`RunResult`)."""
from __future__ import annotations

import dataclasses
from typing import Dict, List, Optional


@dataclasses.dataclass
class RunResult:
    """What a run did. Times in seconds; counts per topic."""
    scenario: str
    status: str                  # complete | interrupted | failed
    reason: str
    bag: Optional[str]
    sim_time: float              # simulated (lockstep) or elapsed (real time) seconds reached
    wall_time: float
    steps: int
    nodes: List[str]
    skipped: List[str]           # node instances that could not be imported
    missing_outputs: List[str]   # wanted topics nobody produces
    published: Dict[str, int]
    recorded: Dict[str, int]
    cost: Dict[str, dict] = dataclasses.field(default_factory=dict)   # per node callback time
    #: per topic: what DDS delivered to this process's subscriptions outside the bus
    received: Dict[str, int] = dataclasses.field(default_factory=dict)
    #: multi-process runs: each worker process's report (published, received, cost, gc, ...)
    processes: Dict[str, dict] = dataclasses.field(default_factory=dict)
    #: this process's real-time settings and GC pauses (real time only)
    realtime: Dict[str, object] = dataclasses.field(default_factory=dict)

    @property
    def lost(self) -> Dict[str, int]:
        """Per recorded topic: published in this process but not in the recording."""
        return {t: self.published[t] - self.recorded.get(t, 0)
                for t in self.recorded
                if t in self.published and self.published[t] != self.recorded.get(t, 0)}

    @property
    def realtime_factor(self) -> float:
        return self.sim_time / self.wall_time if self.wall_time > 0 else float('inf')

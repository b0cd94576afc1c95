"""The node fuzz suite (issue 10): every node that takes input is driven in-process with
hypothesis-generated messages on each input topic, clock ticks and runtime parameter
changes, a few thousand messages per input topic. Invariants, checked at every output:

- no crash: no callback or timer raises, and afterwards the node still publishes;
- every message is accounted for: exactly one of its topic's diagnostics counters moves
  (bad messages are counted as such, and reported as a WARN);
- no non-finite float in any published message;
- no rendered force above the renderer's current limit; no tip force estimate published
  for control points outside the estimator's envelope.

Invariants that need the core fixes of other branches are in test_fuzz_core_dependent.py.
The benchmark tests/bench/bench_fuzz.py runs the same with >= 100 000 messages per topic.
"""
import os

import pytest
from hypothesis import HealthCheck, given, settings

from harness import FUZZ_NODES, Rig, events
from healthy import HEALTHY

pytestmark = pytest.mark.ros
#: examples per node (divided by the node's cost); each example holds 40-120 events
EXAMPLES = int(os.environ.get('FUZZ_EXAMPLES', '120'))


@pytest.mark.parametrize('key', sorted(FUZZ_NODES))
def test_fuzz_node(ros, key):
    rig = Rig(ros, key)

    @settings(max_examples=max(1, int(EXAMPLES / FUZZ_NODES[key].cost)), deadline=None,
              database=None,
              suppress_health_check=list(HealthCheck))
    @given(events(key))
    def run(evs):
        t = rig.tally
        before = (t.crashes, t.nonfinite, t.over_limit, t.unaccounted)
        rig.run(evs)
        assert (t.crashes, t.nonfinite, t.over_limit, t.unaccounted) == before, t.examples

    run()
    t = rig.tally
    print(f'{key}: sent {t.sent}, refused {t.refused} (+{t.refused_in_timer} in timers), '
          f'{t.outputs} outputs, {t.params_set} parameter changes applied, '
          f'{t.params_refused} refused')
    if EXAMPLES >= 120:
        assert min(t.sent.values()) >= FUZZ_NODES[key].min_sent, t.sent
    assert t.outputs > 0
    refused = sum(t.refused.values()) + t.refused_in_timer
    assert refused > 0, 'the strategies send bad messages: some were refused'
    assert rig.node.diag.get('bad_messages') == refused
    assert t.params_set > 0 and t.params_refused > 0
    HEALTHY[key](rig)          # still working after all that

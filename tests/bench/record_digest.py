"""A recorded lockstep run as a digest of its decoded messages, to check that a change keeps
every recorded message (the round-4/6/9 check; /diagnostics aside: its timing values differ
between any two runs).

    python tests/bench/record_digest.py experiment_ii 12 out.txt   # in each checkout
    cmp this.txt other.txt

Records `scenario` for `duration` s in lockstep (the scenario's own process layout) and
writes one line per recorded message in file order: topic, log time (ns), sha1 of the repr
of the message decoded by mcap_ros2 (every field and its value). Prints the count.
"""
from __future__ import annotations

import hashlib
import sys
import tempfile


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 3:
        print(__doc__.strip().splitlines()[3].strip(), file=sys.stderr)
        return 2
    name, duration, out = argv[0], float(argv[1]), argv[2]
    from catheter_common.ros_testing import isolate_ros_env
    isolate_ros_env()
    from mcap_ros2.reader import read_ros2_messages
    from catheter_bringup.runner import ScenarioRunner
    from catheter_bringup.scenario import load_scenario
    sc = load_scenario(name)
    sc['duration'] = duration
    with tempfile.TemporaryDirectory() as tmp:
        res = ScenarioRunner(sc, bag=f'{tmp}/x.mcap', progress=False,
                             log=lambda *a: None).run()
        if res.status != 'complete':
            print(f'run {res.status}: {res.reason}', file=sys.stderr)
            return 1
        n = 0
        with open(out, 'w') as f:
            for m in read_ros2_messages(f'{tmp}/x.mcap'):
                if m.channel.topic == '/diagnostics':
                    continue
                digest = hashlib.sha1(repr(m.ros_msg).encode()).hexdigest()
                f.write(f'{m.channel.topic} {m.log_time_ns} {digest}\n')
                n += 1
    print(f'{name} {duration:g} s: {n} messages (/diagnostics aside), processes '
          f'{sorted(res.processes) or ["main"]}, real-time factor {res.realtime_factor:.2f}x')
    return 0


if __name__ == '__main__':
    sys.exit(main())

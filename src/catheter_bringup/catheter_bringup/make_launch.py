"""What a ROS 2 launch of a scenario starts, computed from the scenario YAML, so launched and
launchless runs use the same nodes, parameters and remappings.

The package's `launch/scenario.launch.py` (installed to share/catheter_bringup/launch; for a
ROS 2 install with `launch` and `launch_ros`) calls `launch_entries` at launch time:

    ros2 launch catheter_bringup scenario.launch.py scenario:=experiment_ii

It starts the scenario's node instances (the nodes it needs, as the runner resolves them) as
separate processes in real time, with their parameters and remaps, plus ``recorder_node``
writing bags/<scenario>.mcap. Lockstep (simulated clock) runs need the launchless runner
(``run_scenario``): separate processes cannot be stepped deterministically.

    python -m catheter_bringup.make_launch SCENARIO     # prints what the launch would start
"""
from __future__ import annotations

import argparse
import pprint
import sys
from typing import Dict, List

from catheter_bringup.scenario import load_scenario, resolve_nodes


def launch_entries(scenario: dict) -> List[Dict]:
    """Keyword arguments of one `launch_ros.actions.Node` per process the scenario starts:
    package, executable, name, parameters ([dict]) and remappings (list of pairs)."""
    nodes, _missing = resolve_nodes(scenario)
    out = []
    for inst in nodes:
        params = dict(inst.params)
        params['use_sim_time'] = False
        entry = {'package': inst.spec.module.split('.')[0], 'executable': inst.spec.executable,
                 'name': inst.name, 'parameters': [params]}
        if inst.remap:
            entry['remappings'] = sorted(inst.remap.items())
        out.append(entry)
    rec = scenario['record']
    out.append({'package': 'catheter_bringup', 'executable': 'recorder_node',
                'name': 'recorder_node',
                'parameters': [{'path': f"bags/{scenario['name']}.mcap",
                                'scenario': scenario.get('source') or scenario['name'],
                                'exclude': list(rec['exclude']) or [''],
                                'topics': list(rec.get('only') or []) or ['']}]})
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(prog='make_launch', description=__doc__.split('\n\n')[0])
    ap.add_argument('scenario', help="a scenario name of catheter_bringup's config/ or a YAML path")
    a = ap.parse_args(argv)
    pprint.pprint(launch_entries(load_scenario(a.scenario)), width=100, sort_dicts=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())

"""What a ROS 2 launch of a scenario starts, computed from the scenario YAML, so launched and
launchless runs use the same nodes, parameters and remappings.

The package's `launch/scenario.launch.py` (installed to share/catheter_bringup/launch; for a
ROS 2 install with `launch` and `launch_ros`) calls `launch_entries` at launch time:

    ros2 launch catheter_bringup scenario.launch.py scenario:=experiment_ii

It starts the scenario's node instances (the nodes it needs, as the runner resolves them) as
separate processes in real time, with their parameters and remaps, plus ``recorder_node``
writing bags/<scenario>.mcap. With ``layout: split`` (in the YAML) it starts the deployment
layout instead: a master process (haptic device and renderers: the force loop never
crosses a process), a slave process (robot, vessel, sensor, identifier) and a vision process
(camera, shape, force estimator), each a ``run_scenario --only ...`` in real time, plus the
recorder; master and slave talk only through the link topics over DDS. Lockstep (simulated
clock) runs need the launchless runner (``run_scenario``): separate processes cannot be
stepped deterministically.

    python -m catheter_bringup.make_launch SCENARIO     # prints what the launch would start
"""
from __future__ import annotations

import argparse
import json
import os
import pprint
import sys
from typing import Dict, Iterable, List, Optional, Sequence

from catheter_bringup.scenario import NodeInstance, load_scenario, resolve_nodes


def launch_entries(scenario: dict) -> List[Dict]:
    """Keyword arguments of one `launch_ros.actions.Node` per process the scenario starts:
    package, executable, name, parameters ([dict]) and remappings (list of pairs); with
    ``layout: split`` one `run_scenario --only ...` process per process of the layout (master,
    slave, vision: package, executable, arguments) instead of one per node. Plus the
    recorder."""
    nodes, _missing = resolve_nodes(scenario)
    out = split_entries(scenario, nodes) if scenario.get('layout') == 'split' else []
    for inst in (nodes if not out else []):
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


def split_entries(scenario: dict, nodes: Sequence[NodeInstance],
                  cpus: Optional[Iterable[int]] = None) -> List[Dict]:
    """Layout split: one process per group of `split_processes` (the force loop's nodes
    together), each a `run_scenario` in real time running only its nodes, with the loop
    processes' SCHED_FIFO priority and their EventsExecutor; they talk over DDS. As the
    launchless runner's workers (`catheter_bringup.worker`): the worker parameters
    (`WORKER_PARAMS`, unless the scenario's global_params set them) and, with a
    realtime_priority, the CPU placement of `realtime.worker_cpus` over `cpus` (default:
    the CPUs this process may use, i.e. the machine the launch runs on)."""
    from catheter_bringup.realtime import worker_cpus
    from catheter_bringup.scenario import split_processes
    from catheter_bringup.worker import WORKER_PARAMS
    source = scenario.get('source') or scenario['name']
    if cpus is None:
        cpus = os.sched_getaffinity(0) if hasattr(os, 'sched_getaffinity') else ()
    groups = split_processes(nodes, scenario)
    place = int(scenario.get('realtime_priority', 0)) > 0
    given = scenario.get('global_params') or {}
    params = [a for k, v in WORKER_PARAMS.items() if k not in given
              for a in ('--set', f'global_params.{k}={json.dumps(v)}')]
    out = []
    for group, insts in groups.items():
        args = [str(source), '--mode', 'realtime', '--no-record', '--quiet',
                '--set', 'layout=split', *params, '--process', group, '--duration', '86400',
                '--only', ','.join(i.name for i in insts)]
        mine = worker_cpus(group, groups, cpus) if place else None
        if mine:
            args += ['--cpus', ','.join(str(c) for c in sorted(mine))]
        out.append({'package': 'catheter_bringup', 'executable': 'run_scenario',
                    'arguments': args})
    return out


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(prog='make_launch', description=__doc__.split('\n\n')[0])
    ap.add_argument('scenario', help="a scenario name of catheter_bringup's config/ or a YAML path")
    a = ap.parse_args(argv)
    pprint.pprint(launch_entries(load_scenario(a.scenario)), width=100, sort_dicts=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())

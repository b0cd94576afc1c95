"""Scenarios (no nodes, no executor; topic names from catheter_common.topics): the YAML files in
the package's config/ (installed to share/catheter_bringup/config), the node registry and the
resolution of which nodes a scene needs.

A scenario file::

    name: experiment_ii
    duration: 12.0            # simulated seconds
    step: 0.001               # lockstep clock step, s
    mode: lockstep            # lockstep | realtime
    seed: 7
    force_source: load_cell   # load_cell | image  (force the identifier fits)
    link: {delay: 0.2, jitter: 0.0, loss: 0.0, outages: [[4.0, 1.0], [8.0, 1.0]]}
    operator: {trajectory: experiment_ii, family: minjerk}   # family: minjerk | sines | human
    vessel: phantom           # sim_slave.vessels: phantom, smooth_coulomb, stribeck_kv,
                              # stenosis, soft, stiff_wall (sim nodes and analyze's twin)
    outputs: [/master/rendered_force, /slave/force]   # what the scene consumes
    lockstep_transport: local # local: in-process bus (fast, deterministic) | dds: via DDS
    realtime_transport: local # the same choice for real-time runs
    dds: false                # local bus: also publish every message on DDS (outside viewers;
                              # run_scenario --dds)
    strict: false             # a node that fails to start fails the run (else it is left out)
    realtime_processes: 2     # real time: 2 = the image pipeline in a worker process, 1 = none
    lockstep_processes: 2     # lockstep: 2 = the vision chain in a process of its own when
                              # nothing of the rest consumes it (same recording, in
                              # parallel; `lockstep_peer`), 1 = everything in one process
    layout: one               # one | split (real time only: master, slave, vision processes
                              # talking over DDS, each records its own nodes' messages and
                              # the runner merges them into the bag; see PROCESSES)
    realtime_priority: 30     # SCHED_FIFO priority of the real-time processes that run 1 kHz
                              # loops (0: normal scheduling; falls back with a log line)
    realtime_cpu_latency_us: -1  # >= 0: those processes hold a PM QoS CPU latency request
                              # of this many us while their loops run (/dev/cpu_dma_latency,
                              # 0: idle CPUs poll instead of halting between ticks; needs
                              # root, else one log line; only with realtime_priority > 0);
                              # -1: none (the default: on the benchmark VM polling drew the
                              # host's 100 ms holds of the whole machine)
    record: {exclude: [/clock]}   # and/or only: [topics] (everything else is not recorded)
    nodes:                    # parameters per node instance (and optional registry fields)
      ima_master_node: {params: {mode: ima}}
      dfr_shadow: {executable: ima_master_node, remap: {/master/rendered_force:
      /master/dfr/rendered_force},
                   params: {mode: dfr}, optional: true}

Only nodes whose outputs the scene consumes are started: the wanted ``outputs`` pull in their
producers, whose inputs pull in theirs, and so on (`resolve_nodes`). Entries listed under
``nodes`` with ``always: true`` are started regardless.
"""
from __future__ import annotations

import copy
import dataclasses
import math
import pathlib
from typing import Dict, List, Mapping, Optional, Tuple

import yaml

from catheter_common import topics as T


@dataclasses.dataclass
class NodeSpec:
    """What the runner needs to start a node and to know its place in the graph."""
    executable: str                 # console_script / node name
    module: str                     # python module defining NODE_CLASS
    consumes: Tuple[str, ...] = ()  # topics it subscribes to (the scene's data flow)
    produces: Tuple[str, ...] = ()  # topics it publishes
    kind: str = 'node'

    def remapped(self, remap: Mapping[str, str]) -> 'NodeSpec':
        return dataclasses.replace(
            self, consumes=tuple(remap.get(t, t) for t in self.consumes),
            produces=tuple(remap.get(t, t) for t in self.produces))


#: The project's nodes. consumes/produces follow DESIGN section 4 and catheter_common.topics;
#: a scenario may override any field (e.g. for nodes of its own).
REGISTRY: Dict[str, NodeSpec] = {s.executable: s for s in [
    NodeSpec('sim_haptic_node', 'impedance_master.sim_haptic_node',
             consumes=(T.MASTER_RENDERED_FORCE, T.SLAVE_IMPEDANCE, T.SLAVE_FORCE),
             produces=(T.MASTER_COMMAND, T.MASTER_LINK_IMPEDANCE, T.MASTER_LINK_FORCE,
                       T.MASTER_HAND_FORCE)),
    NodeSpec('ima_master_node', 'impedance_master.ima_master_node',
             consumes=(T.MASTER_LINK_IMPEDANCE, T.MASTER_LINK_FORCE, T.MASTER_COMMAND),
             produces=(T.MASTER_RENDERED_FORCE,)),
    NodeSpec('impedance_identifier_node', 'impedance_master.impedance_identifier_node',
             consumes=(T.SLAVE_JOINT_STATE,),
             produces=(T.SLAVE_IMPEDANCE,)),
    NodeSpec('sim_slave_node', 'sim_slave.sim_slave_node',
             consumes=(T.MASTER_COMMAND,),
             produces=(T.SLAVE_JOINT_STATE, T.SLAVE_JOINT_STATE_DECIMATED, T.SLAVE_FORCE)),
    NodeSpec('camera_node', 'sim_slave.camera_node',
             consumes=(T.SLAVE_JOINT_STATE_DECIMATED,),
             produces=(T.CAMERA_IMAGE, T.CAMERA_TIP_FORCE_TRUTH), kind='vision'),
    NodeSpec('shape_node', 'catheter_shape.shape_node',
             consumes=(T.CAMERA_IMAGE,),
             produces=(T.CONTROL_POINTS, T.SHAPE), kind='vision'),
    NodeSpec('force_estimator_node', 'force_estimator.force_estimator_node',
             consumes=(T.CONTROL_POINTS,),
             produces=(T.TIP_WRENCH, T.TIP_FORCE), kind='vision'),
    NodeSpec('fam_solver_node', 'fam_solver.fam_solver_node',
             consumes=(T.TIP_LOAD,),
             produces=(T.SHAPE, T.SHAPE_MARKER), kind='vision'),
]}

MODES = ('lockstep', 'realtime')
LAYOUTS = ('one', 'split')
#: layout split: the process each executable runs in. The force loop (haptic device +
#: renderers) stays in one process; master and slave talk only through the link topics
#: (/master/command, /slave/force, /slave/impedance) over DDS, as across two machines.
PROCESSES: Dict[str, str] = {
    'sim_haptic_node': 'master', 'ima_master_node': 'master',
    'sim_slave_node': 'slave', 'impedance_identifier_node': 'slave', 'force_source_node': 'slave',
    'camera_node': 'vision', 'shape_node': 'vision', 'force_estimator_node': 'vision',
    'fam_solver_node': 'vision',
}
#: the link between master and slave: what crosses between their processes (layout split)
LINK_TOPICS = (T.MASTER_COMMAND, T.SLAVE_FORCE, T.SLAVE_IMPEDANCE)
#: processes whose loops run at 1 kHz (they get the scenario's realtime_priority)
LOOP_PROCESSES = ('master', 'slave')
#: nice value of the vision process when the loops run under SCHED_FIFO: more CPU share than
#: the machine's other work (30 frames/s must keep up), never ahead of the 1 kHz loops
VISION_NICE = -10
FORCE_SOURCES = ('load_cell', 'image')


@dataclasses.dataclass
class NodeInstance:
    """One node to start: its spec (after remapping), instance name, parameters, remaps."""
    name: str
    spec: NodeSpec
    params: Dict[str, object]
    remap: Dict[str, str]
    optional: bool = False
    always: bool = False


PACKAGE = 'catheter_bringup'


def share_dir() -> Optional[pathlib.Path]:
    """share/catheter_bringup of the installed package (ament index), or None when the package
    is not installed (run from the source tree)."""
    try:
        from ament_index_python.packages import (PackageNotFoundError,
                                                 get_package_share_directory)
    except ImportError:                 # pragma: no cover - ament_index_python is a dependency
        return None
    try:
        return pathlib.Path(get_package_share_directory(PACKAGE))
    except (PackageNotFoundError, ValueError):
        return None


def config_dir() -> pathlib.Path:
    """The scenario folder: share/catheter_bringup/config of the installed package (found
    through ament_index_python, so a plain `colcon build` works), or config/ of the source
    tree when the package is not installed."""
    share = share_dir()
    if share is not None and (share / 'config').is_dir():
        return share / 'config'
    return pathlib.Path(__file__).resolve().parents[1] / 'config'


def _num(d: Mapping, key: str, default, lo=None, hi=None, where='scenario'):
    v = d.get(key, default)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise ValueError(f'{where}.{key} must be a finite number, got {v!r}')
    if lo is not None and v < lo or hi is not None and v > hi:
        raise ValueError(f'{where}.{key}={v} outside [{lo}, {hi}]')
    return float(v) if isinstance(default, float) else int(v)


def load_scenario(name_or_path) -> dict:
    """Load and validate a scenario: a path to a YAML file or a name in `config_dir()`.

    Returns a plain dict with defaults filled in (see the module docstring for the fields).
    """
    p = pathlib.Path(str(name_or_path))
    if not p.suffix:
        p = config_dir() / f'{name_or_path}.yaml'
    if not p.exists():
        avail = sorted(x.stem for x in config_dir().glob('*.yaml'))
        raise ValueError(f'scenario {name_or_path!r} not found (available: {avail})')
    with open(p) as f:
        data = yaml.safe_load(f) or {}
    data.setdefault('name', p.stem)
    data['source'] = str(p)
    return validate_scenario(data)


def validate_scenario(data: Mapping) -> dict:
    """Fill defaults and refuse bad values with ValueError naming the field."""
    if not isinstance(data, Mapping):
        raise ValueError(f'scenario must be a mapping, got {type(data).__name__}')
    s = copy.deepcopy(dict(data))
    s.setdefault('name', 'scenario')
    s['duration'] = _num(s, 'duration', 1.0, 0.0, 3600.0)
    s['step'] = _num(s, 'step', 0.001, 1e-5, 1.0)
    s['seed'] = _num(s, 'seed', 0, 0, 2**31 - 1)
    s.setdefault('mode', 'lockstep')
    if s['mode'] not in MODES:
        raise ValueError(f'scenario.mode must be one of {MODES}, got {s["mode"]!r}')
    s.setdefault('force_source', 'load_cell')
    if s['force_source'] not in FORCE_SOURCES:
        raise ValueError(f'scenario.force_source must be one of {FORCE_SOURCES}, '
                         f'got {s["force_source"]!r}')
    link = dict(s.get('link') or {})
    link['delay'] = _num(link, 'delay', 0.2, 0.0, 10.0, 'link')
    link['jitter'] = _num(link, 'jitter', 0.0, 0.0, 10.0, 'link')
    link['loss'] = _num(link, 'loss', 0.0, 0.0, 1.0, 'link')
    outages = link.get('outages') or []
    if not isinstance(outages, (list, tuple)):
        raise ValueError(f'link.outages must be a list of [start, duration], got {outages!r}')
    clean = []
    for o in outages:
        if not isinstance(o, (list, tuple)) or len(o) != 2:
            raise ValueError(f'link.outages entries must be [start, duration], got {o!r}')
        try:
            a, b = float(o[0]), float(o[1])
        except (TypeError, ValueError):
            raise ValueError(f'link.outages entry must be two numbers [start, duration], '
                             f'got {o!r}') from None
        if not (math.isfinite(a) and math.isfinite(b)) or a < 0 or b < 0:
            raise ValueError(f'link.outages entry must be finite and >= 0, got {o!r}')
        clean.append([a, b])
    link['outages'] = clean
    s['link'] = link
    s['operator'] = dict(s.get('operator') or {})
    from impedance_master.operator import OPERATORS
    s['operator'].setdefault('family', 'minjerk')
    if s['operator']['family'] not in OPERATORS:
        raise ValueError(f'scenario.operator.family must be one of {tuple(OPERATORS)}, got '
                         f'{s["operator"]["family"]!r}')
    from sim_slave.node_params import DEFAULT_VESSEL, VESSEL_CHOICES
    s.setdefault('vessel', DEFAULT_VESSEL)
    if s['vessel'] not in VESSEL_CHOICES:
        raise ValueError(f'scenario.vessel must be one of {VESSEL_CHOICES}, got '
                         f'{s["vessel"]!r}')
    outs = s.get('outputs') or []
    if not isinstance(outs, (list, tuple)) or not all(isinstance(t, str) for t in outs):
        raise ValueError(f'scenario.outputs must be a list of topic names, got {outs!r}')
    s['outputs'] = list(outs)
    rec = dict(s.get('record') or {})
    rec.setdefault('enabled', True)
    rec.setdefault('exclude', ['/clock', '/rosout', '/parameter_events'])
    only = rec.get('only') or []
    if not isinstance(only, (list, tuple)) or not all(isinstance(t, str) for t in only):
        raise ValueError(f'record.only must be a list of topic names, got {only!r}')
    rec['only'] = list(only)
    s['record'] = rec
    nodes = s.get('nodes') or {}
    if not isinstance(nodes, Mapping):
        raise ValueError('scenario.nodes must be a mapping of instance name -> settings')
    s['nodes'] = {str(k): dict(v or {}) for k, v in nodes.items()}
    s.setdefault('lockstep_transport', 'local')
    if s['lockstep_transport'] not in ('local', 'dds'):
        raise ValueError("scenario.lockstep_transport must be 'local' or 'dds', "
                         f"got {s['lockstep_transport']!r}")
    s.setdefault('realtime_transport', 'local')
    if s['realtime_transport'] not in ('local', 'dds'):
        raise ValueError("scenario.realtime_transport must be 'local' or 'dds', "
                         f"got {s['realtime_transport']!r}")
    for key in ('dds', 'strict'):
        s.setdefault(key, False)
        if not isinstance(s[key], bool):
            raise ValueError(f'scenario.{key} must be true or false, got {s[key]!r}')
    s['realtime_processes'] = _num(s, 'realtime_processes', 2, 1, 2)
    s['lockstep_processes'] = _num(s, 'lockstep_processes', 2, 1, 2)
    s.setdefault('layout', 'one')
    if s['layout'] not in LAYOUTS:
        raise ValueError(f'scenario.layout must be one of {LAYOUTS}, got {s["layout"]!r}')
    s['realtime_priority'] = _num(s, 'realtime_priority', 30, 0, 99)
    s['realtime_cpu_latency_us'] = _num(s, 'realtime_cpu_latency_us', -1, -1, 1_000_000)
    if s['layout'] == 'split' and s['mode'] != 'realtime':
        raise ValueError('scenario.layout split runs the graph as separate processes in real '
                         'time: it needs mode realtime (--mode realtime); lockstep runs in '
                         'one process')
    s.setdefault('description', '')
    s.setdefault('global_params', {})
    s.setdefault('metrics', {})
    return s


def scenario_text(scenario: Mapping) -> str:
    """The scenario as YAML (what recordings store as ``scenario_yaml``; ``source`` left out)."""
    return yaml.safe_dump({k: v for k, v in scenario.items() if k != 'source'}, sort_keys=True)


def run_start_info(scenario: Mapping, nodes) -> Dict[str, object]:
    """What a recording says about its run when the run starts (`McapRecorder.start`): enough
    for analyze and recover_bag when the run is killed before it can close the file."""
    return {'scenario': scenario['name'], 'mode': scenario['mode'], 'seed': scenario['seed'],
            'duration_s': scenario['duration'], 'nodes': sorted(nodes),
            'scenario_yaml': scenario_text(scenario)}


def common_params(scenario: Mapping) -> Dict[str, object]:
    """Parameters every node gets (a node ignores those it does not declare): the seed, the
    link (``link.delay``, ``link.jitter``, ``link.loss``, ``link.outages`` as a flat list
    start, length, ...), the operator (``operator.<key>``: ``operator.family`` is
    sim_haptic_node's), the vessel (``vessel``: the sim nodes'), the identification force
    source, then the scenario's ``global_params``."""
    link = scenario['link']
    flat = [float(x) for o in link['outages'] for x in o] or [0.0, 0.0]
    p = {'seed': int(scenario['seed']), 'link.delay': float(link['delay']),
         'link.jitter': float(link['jitter']), 'link.loss': float(link['loss']),
         'link.outages': flat, 'force_source': scenario['force_source'],
         'vessel': scenario['vessel']}
    for k, v in scenario['operator'].items():
        p[f'operator.{k}'] = v
    p.update(scenario['global_params'])
    return p


def instances(scenario: Mapping, registry: Optional[Mapping[str, NodeSpec]] = None
              ) -> Dict[str, NodeInstance]:
    """Every node instance the scenario could start: the registry's nodes (with the scenario's
    parameters) plus the scenario's own entries (shadow instances, nodes of tests)."""
    reg = dict(REGISTRY if registry is None else registry)
    image_source = registry is None and scenario['force_source'] == 'image'
    if image_source:
        reg['force_source_node'] = NodeSpec(
            'force_source_node', 'catheter_bringup.force_source_node',
            consumes=(T.SLAVE_JOINT_STATE, T.TIP_WRENCH), produces=(T.SLAVE_JOINT_STATE_IMAGE,))
    common = common_params(scenario)
    out: Dict[str, NodeInstance] = {}
    for name, spec in reg.items():
        if name not in scenario['nodes']:
            out[name] = NodeInstance(name, spec, dict(common), {})
    for name, cfg in scenario['nodes'].items():
        exe = cfg.get('executable', name)
        base = reg.get(exe)
        if base is None and 'module' not in cfg:
            raise ValueError(f'nodes.{name}: unknown executable {exe!r} and no module given')
        spec = NodeSpec(
            executable=exe,
            module=cfg.get('module', base.module if base else ''),
            consumes=tuple(cfg.get('consumes', base.consumes if base else ())),
            produces=tuple(cfg.get('produces', base.produces if base else ())),
            kind=cfg.get('kind', base.kind if base else 'node'))
        remap = {str(k): str(v) for k, v in (cfg.get('remap') or {}).items()}
        params = dict(common)
        params.update(cfg.get('params') or {})
        if cfg.get('enabled', True) is False:
            continue
        out[name] = NodeInstance(name, spec.remapped(remap), params, remap,
                                 optional=bool(cfg.get('optional', False)),
                                 always=bool(cfg.get('always', False)))
    if image_source and 'impedance_identifier_node' in out:
        # the identifier fits the image-based force: its joint state comes through the adapter
        ident = out['impedance_identifier_node']
        remap = dict(ident.remap)
        remap[T.SLAVE_JOINT_STATE] = T.SLAVE_JOINT_STATE_IMAGE
        base = reg['impedance_identifier_node'] if ident.name in reg else ident.spec
        out[ident.name] = dataclasses.replace(ident, spec=base.remapped(remap), remap=remap)
    return out


def resolve_nodes(scenario: Mapping, available: Optional[set] = None,
                  registry: Optional[Mapping[str, NodeSpec]] = None
                  ) -> Tuple[List[NodeInstance], List[str]]:
    """The node instances a scene needs, in start order (producers first), and the wanted
    topics nobody available can produce.

    ``available``: instance names that can be started (importable); None = all.
    """
    cands = instances(scenario, registry)
    if available is not None:
        cands = {k: v for k, v in cands.items() if k in available}
    chosen: Dict[str, NodeInstance] = {}
    missing: List[str] = []
    wanted = list(scenario['outputs'])
    for inst in cands.values():
        if inst.always:
            chosen[inst.name] = inst
            wanted += list(inst.spec.consumes)
    seen_topics = set()
    while wanted:
        topic = wanted.pop(0)
        if topic in seen_topics:
            continue
        seen_topics.add(topic)
        producers = [i for i in cands.values() if topic in i.spec.produces]
        if not producers:
            if topic in scenario['outputs']:
                missing.append(topic)
            continue
        for inst in producers:
            if inst.name not in chosen:
                chosen[inst.name] = inst
                wanted += list(inst.spec.consumes)
    # a node none of whose inputs anybody can produce would idle: leave it out (repeat, since
    # leaving one out can starve the next)
    while True:
        produced = {t for i in chosen.values() for t in i.spec.produces}
        idle = [n for n, i in chosen.items()
                if i.spec.consumes and not i.always
                and not any(t in produced for t in i.spec.consumes)]
        if not idle:
            break
        for n in idle:
            del chosen[n]
    produced = {t for i in chosen.values() for t in i.spec.produces}
    missing = [t for t in scenario['outputs'] if t not in produced]
    order = sorted(chosen.values(), key=lambda i: i.name)
    return order, missing


def process_of(inst: NodeInstance, scenario: Mapping) -> str:
    """The process (layout split) a node instance runs in: the scenario's ``nodes.<name>.process``
    if given, else `PROCESSES` by executable, else 'vision' for vision nodes and 'slave' for
    the rest."""
    cfg = scenario['nodes'].get(inst.name) or {}
    if cfg.get('process'):
        return str(cfg['process'])
    return PROCESSES.get(inst.spec.executable, 'vision' if inst.spec.kind == 'vision' else 'slave')


def split_processes(chosen: List[NodeInstance], scenario: Mapping) -> Dict[str, List[NodeInstance]]:
    """Layout split: process name -> its node instances (start order kept), loop processes
    first."""
    out: Dict[str, List[NodeInstance]] = {}
    for inst in chosen:
        out.setdefault(process_of(inst, scenario), []).append(inst)
    return dict(sorted(out.items(), key=lambda kv: (kv[0] not in LOOP_PROCESSES, kv[0])))

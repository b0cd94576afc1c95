"""Starting a scenario's node instances in the runner's process: their classes (imported from
``<pkg>.<executable>.NODE_CLASS``), parameters (``use_sim_time`` in lockstep plus the
instance's), remaps and a second try with the scenario's ``fallback_params``."""
from __future__ import annotations

import dataclasses
import importlib
from typing import Callable, Dict, List, Optional, Tuple

from rclpy.parameter import Parameter

from catheter_bringup.scenario import NodeInstance


def _to_param_value(v):
    if isinstance(v, tuple):
        v = list(v)
    if isinstance(v, list) and v and all(isinstance(x, (int, float)) and not isinstance(x, bool)
                                         for x in v) and any(isinstance(x, float) for x in v):
        v = [float(x) for x in v]
    return v


def load_node_class(module: str):
    mod = importlib.import_module(module)
    cls = getattr(mod, 'NODE_CLASS', None)
    if cls is None:
        raise ImportError(f'{module} defines no NODE_CLASS')
    return cls


def available_instances(candidates: List[NodeInstance]) -> Dict[str, object]:
    """name -> node class for every instance whose module imports."""
    out = {}
    for inst in candidates:
        try:
            out[inst.name] = load_node_class(inst.spec.module)
        except ImportError:
            continue
    return out


def params_for(inst: NodeInstance, lockstep: bool) -> List[Parameter]:
    """The parameter overrides of a node instance."""
    params = {'use_sim_time': lockstep}
    params.update({k: _to_param_value(v) for k, v in inst.params.items()})
    return [Parameter(k, value=v) for k, v in params.items()]


def cli_args(inst: NodeInstance) -> List[str]:
    """--ros-args of an instance: its name (a second instance of an executable) and remaps."""
    cli = []
    if inst.name != inst.spec.executable:
        cli += ['-r', f'__node:={inst.name}']
    for a, b in inst.remap.items():
        cli += ['-r', f'{a}:={b}']
    return ['--ros-args'] + cli if cli else []


def start_node(cls, inst: NodeInstance, context, lockstep: bool,
               fallback_params: Optional[dict] = None,
               log: Callable[[str], None] = print) -> Tuple[object, bool]:
    """Build the node of `inst`; if that raises and `fallback_params` are given, try once more
    with them. Returns (node, whether the fallback was used); raises what the last try raised."""
    kwargs = dict(context=context, parameter_overrides=params_for(inst, lockstep))
    cli = cli_args(inst)
    if cli:
        kwargs['cli_args'] = cli
    try:
        return cls(**kwargs), False
    except Exception as first:  # noqa: BLE001
        if not fallback_params:
            raise
        log(f'[run] {inst.name} failed to start ({type(first).__name__}: {first}); retrying '
            f'with {fallback_params}')
    params = dict(inst.params)
    params.update(fallback_params)
    kwargs['parameter_overrides'] = params_for(dataclasses.replace(inst, params=params), lockstep)
    return cls(**kwargs), True

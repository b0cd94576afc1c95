"""Steering a run from the command line (no rclpy): ``--set key=value`` overrides of any
scenario field, typed by the scenario, and the run's name that every output is named after.

    run_scenario experiment_ii --set link.delay=0.5 --set link.outages=[[4,1]]
    scripts/run experiment_ii --set nodes.ima_master_node.params.mode=ima_thesis

Keys are dotted paths into the scenario (`catheter_bringup.scenario` documents the fields):
``duration``, ``seed``, ``mode``, ``dds``, ``link.delay``, ``link.outages``,
``operator.trajectory``, ``metrics.skip``, ``nodes.<instance>.params.<parameter>``,
``global_params.<parameter>`` ... The value is YAML (``0.5``, ``true``, ``[[4, 1]]``, ``ima``)
converted to the type the field has (a float field takes ``1`` as 1.0; a string field takes
``7`` as '7'); a value of another kind, or a key the scenario does not have outside the
open mappings (node parameters, global_params, operator, metrics), is refused with a
ValueError naming the key. The scenario is validated again afterwards (ranges).

The run is named after what it is, so a changed run never overwrites the default run's
outputs (bags/<name>.mcap, out/<name>_*.png, out/<name>_metrics.json):

- the shipped scenario, unchanged: its name (``experiment_ii``);
- with overrides: ``<name>__<key>-<value>...`` (``experiment_ii__link.delay-0.5``);
- a YAML file outside the shipped config that keeps a shipped scenario's name (a copy):
  ``<name>-<6 hex digits of the file's path>``, the file's own stem if that is free;
- ``--name NAME`` names the run explicitly (the way to overwrite on purpose).
"""
from __future__ import annotations

import copy
import hashlib
import pathlib
import re
from typing import Iterable, Mapping, Optional, Tuple

import yaml

#: mappings whose keys are free (parameters): --set may add keys there
OPEN_MAPPINGS = ('params', 'global_params', 'operator', 'metrics', 'remap', 'fallback_params')


def parse_set(item: str) -> Tuple[str, object]:
    """'link.delay=0.5' -> ('link.delay', 0.5) (the value parsed as YAML)."""
    if not isinstance(item, str) or '=' not in item:
        raise ValueError(f'--set expects key=value, got {item!r}')
    key, text = item.split('=', 1)
    key = key.strip()
    if not key or any(not part for part in key.split('.')):
        raise ValueError(f'--set key must be a dotted name like link.delay, got {key!r}')
    try:
        value = yaml.safe_load(text) if text.strip() else ''
    except yaml.YAMLError as exc:
        raise ValueError(f'--set {key}: not a YAML value: {text!r} ({exc.problem})') from None
    return key, value


def _typed(key: str, old, new):
    """``new`` converted to the kind of ``old`` (the field's current value)."""
    if old is None:
        return new
    if isinstance(old, bool):
        if not isinstance(new, bool):
            raise ValueError(f'--set {key}: expected true or false, got {new!r}')
        return new
    if isinstance(old, (int, float)):
        if isinstance(new, bool) or not isinstance(new, (int, float)):
            raise ValueError(f'--set {key}: expected a number, got {new!r}')
        if isinstance(old, float):
            return float(new)
        if not float(new).is_integer():
            raise ValueError(f'--set {key}: expected an integer, got {new!r}')
        return int(new)
    if isinstance(old, str):
        if isinstance(new, (dict, list)):
            raise ValueError(f'--set {key}: expected a string, got {new!r}')
        return str(new).lower() if isinstance(new, bool) else str(new)
    if isinstance(old, list):
        if not isinstance(new, list):
            raise ValueError(f'--set {key}: expected a list, got {new!r}')
        return new
    if isinstance(old, dict):
        if not isinstance(new, dict):
            raise ValueError(f'--set {key}: expected a mapping, got {new!r}')
        return new
    return new


def apply_overrides(scenario: Mapping, items: Iterable[str]) -> dict:
    """A validated copy of ``scenario`` with the ``key=value`` overrides applied."""
    from catheter_bringup.scenario import REGISTRY, validate_scenario
    sc = copy.deepcopy(dict(scenario))
    for item in items or ():
        key, value = parse_set(item)
        parts = key.split('.')
        # inside an open mapping the rest of the key is ONE name (ROS parameter names have
        # dots: nodes.sim_slave_node.params.robot.x0 sets the parameter 'robot.x0')
        for i, part in enumerate(parts[:-1]):
            if part in OPEN_MAPPINGS:
                parts = parts[:i + 1] + ['.'.join(parts[i + 1:])]
                break
        node = sc
        for i, part in enumerate(parts[:-1]):
            if not isinstance(node, dict):
                raise ValueError(f'--set {key}: {".".join(parts[:i])} is not a mapping')
            if part not in node or node[part] is None:
                if i > 0 and parts[i - 1] == 'nodes':
                    if part not in REGISTRY:
                        raise ValueError(f'--set {key}: no node instance {part!r} in the '
                                         f'scenario or the registry')
                    node[part] = {}
                elif part in OPEN_MAPPINGS:
                    node[part] = {}
                else:
                    raise ValueError(f'--set {key}: the scenario has no field '
                                     f'{".".join(parts[:i + 1])!r}')
            node = node[part]
        last = parts[-1]
        if not isinstance(node, dict):
            raise ValueError(f'--set {key}: {".".join(parts[:-1])} is not a mapping')
        parent = parts[-2] if len(parts) >= 2 else ''
        if last not in node and parent not in OPEN_MAPPINGS:
            known = ', '.join(sorted(str(k) for k in node))
            raise ValueError(f'--set {key}: the scenario has no field {key!r} '
                             f'(known here: {known})')
        node[last] = _typed(key, node.get(last), value)
    return validate_scenario(sc)


def _slug(items: Iterable[str]) -> str:
    parts = []
    for item in items:
        key, value = parse_set(item)
        text = yaml.safe_dump(value, default_flow_style=True).strip().rstrip('.').strip()
        text = re.sub(r'[^A-Za-z0-9._-]+', '', text.replace(', ', '_').replace(',', '_'))
        parts.append(f'{key}-{text}' if text else key)
    slug = '__'.join(parts)
    if len(slug) > 80:
        slug = slug[:60] + '-' + hashlib.sha1(slug.encode()).hexdigest()[:8]
    return slug


def run_name(scenario: Mapping, overrides: Iterable[str] = (), name: Optional[str] = None,
             shipped: Optional[Iterable[str]] = None) -> Tuple[str, str]:
    """(the run's name, why): see the module docstring. ``shipped``: the shipped scenario
    names (default: the YAML files of `scenario.config_dir()`)."""
    from catheter_bringup.scenario import config_dir
    if name is not None:
        if not re.fullmatch(r'[A-Za-z0-9._-]+', name):
            raise ValueError(f'name must be letters, digits, ".", "_" or "-", got {name!r}')
        return name, 'given with --name'
    cfg = config_dir()
    shipped = set(shipped) if shipped is not None else {p.stem for p in cfg.glob('*.yaml')}
    base = str(scenario['name'])
    why = 'the scenario'
    source = scenario.get('source')
    if source and base in shipped:
        src = pathlib.Path(source).resolve()
        if src != (cfg / f'{base}.yaml').resolve():
            stem = src.stem
            if stem not in shipped and re.fullmatch(r'[A-Za-z0-9._-]+', stem):
                base, why = stem, f'a copy of {scenario["name"]} (named after its file)'
            else:
                base = f'{base}-{hashlib.sha1(str(src).encode()).hexdigest()[:6]}'
                why = f'a copy of {scenario["name"]} ({src})'
    items = list(overrides or ())
    if items:
        base = f'{base}__{_slug(items)}'
        why = f'{why} with --set {" ".join(items)}'
    return base, why

"""`reprocess`: feed a recording's inputs through today's nodes and compare with its outputs.

    python -m catheter_bringup.reprocess bags/reference/smoke.mcap [--nodes
    impedance_identifier_node ...]
                                         [--tol 1e-9]

For each node instance of the recorded scenario that ran, consumes something and has an output
in the recording, the node is started alone in lockstep on the recorded clock with the recorded
scenario's parameters; the recorded messages of the topics it consumes are delivered at their
recorded times; what it publishes now is compared, message by message (matched by header
stamp), with what it published then. A node is checked only when EVERY topic it consumes was
recorded (a channel in the file): fed part of its inputs it computes something else, and the
comparison would report a change that is not one (the shipped reference bags record the force
streams only, so the renderers, whose link inputs are missing there, are listed as not checked).

Exit code: 0 every checked node reproduced its outputs; 1 a node's output changed by more than
``tol`` or a message is missing or extra; 2 nothing could be checked or the file is unreadable.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import math
import os
import sys
import tempfile
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np

from catheter_bringup.bagfile import BagError, check_bag, cli_errors, read_messages
from catheter_bringup.recorder import read_run_metadata


#: byte sequences longer than this are compared by digest (equal or not), not element-wise
DIGEST_OVER = 256


def flatten_message(msg: Any) -> Tuple[np.ndarray, tuple]:
    """Every field of a decoded message (mcap_ros2 or rclpy) in field order: the numbers as one
    float
    array, the strings and digests of long byte sequences (images) as a tuple."""
    nums: List[float] = []
    other: list = []

    def walk(x):
        if type(x).__name__ == 'array' and x.typecode == 'B':   # rclpy uint8[]
            x = bytes(x)
        if isinstance(x, (bytes, bytearray, memoryview)):
            b = bytes(x)
            if len(b) > DIGEST_OVER:
                other.append(hashlib.sha1(b).hexdigest())
            else:
                nums.extend(b)
        elif isinstance(x, str):
            other.append(x)
        elif isinstance(x, (bool, int, float, np.number)):
            nums.append(float(x))
        elif isinstance(x, (list, tuple, np.ndarray)) or type(x).__name__ == 'array':
            for v in x:
                walk(v)
        elif hasattr(x, 'get_fields_and_field_types'):       # rclpy message
            for name in x.get_fields_and_field_types():
                walk(getattr(x, name))
        elif hasattr(x, '__slots__'):                          # mcap_ros2 decoded message
            for name in x.__slots__:
                walk(getattr(x, name))
        else:
            raise ValueError(f'cannot compare a field of type {type(x).__name__}')
    walk(msg)
    return np.asarray(nums, dtype=float), tuple(other)


def _stamped(path, topic) -> List[tuple]:
    """(header stamp ns or None, flattened message) of every message of ``topic``."""
    out = []
    for _, _, _, msg in read_messages(path, [topic], decode=True):
        h = getattr(msg, 'header', None)
        stamp = None if h is None else h.stamp.sec * 1_000_000_000 + h.stamp.nanosec
        out.append((stamp, flatten_message(msg)))
    return out


def recorded_channels(path: str | os.PathLike) -> set:
    """Every topic with a channel in the recording (recorded, whether or not it had messages)."""
    from mcap.reader import make_reader
    with open(path, 'rb') as f:
        summary = make_reader(f).get_summary()
    return {c.topic for c in summary.channels.values()} if summary else set()


def compare_streams(old_path: str | os.PathLike, new_path: str | os.PathLike,
                    topic: str) -> dict:
    """Messages of ``topic`` in two recordings matched by header stamp (in order when there is
    none), every field compared: counts, matched, max |difference| of the numbers (inf when
    the shapes, strings or image data differ)."""
    old, new = _stamped(old_path, topic), _stamped(new_path, topic)
    idx_new: Dict[object, list] = {}
    for i, (s, _) in enumerate(new):
        idx_new.setdefault(s, []).append(i)
    matched, max_diff = 0, 0.0
    for _k, (s, (a, sa)) in enumerate(old):
        js = idx_new.get(s)
        if not js:
            continue
        b, sb = new[js.pop(0)][1]
        matched += 1
        if a.shape != b.shape or sa != sb:
            max_diff = math.inf
            continue
        if a.size:
            d = np.abs(a - b)
            d = np.where(np.isnan(a) & np.isnan(b), 0.0, d)    # NaN in both: equal
            d = np.where(np.isnan(d), math.inf, d)
            max_diff = max(max_diff, float(d.max()))
    return {'recorded': len(old), 'now': len(new), 'matched': matched, 'max_diff': max_diff}


def reprocess(path: str | os.PathLike, nodes: Optional[List[str]] = None, tol: float = 1e-9,
              log: Callable[[str], None] = print) -> Dict[str, dict]:
    """Re-run node instances on a recording's inputs; returns {instance: {topic: comparison,
    'ok': bool}}. Both recordings are read with the chunks' CRCs checked (BagError)."""

    from catheter_bringup.runner import ScenarioRunner
    from catheter_bringup.scenario import REGISTRY, instances, validate_scenario

    import yaml
    check_bag(path)
    meta = read_run_metadata(path)
    scenario = yaml.safe_load(meta['scenario_yaml']) if meta.get('scenario_yaml') else None
    if not scenario:
        raise BagError(f'{path}: no recorded scenario (catheter_run metadata): not a run of '
                       'this project\'s runner')
    sc = validate_scenario(scenario)
    cands = instances(sc)
    channels = recorded_channels(path)
    recorded = channels
    ran = set(json.loads(meta.get('nodes', '[]')))
    if nodes is None:
        nodes = [n for n, i in sorted(cands.items())
                 if n in ran and i.spec.consumes and set(i.spec.produces) & recorded]
    unknown = [n for n in nodes if n not in cands]
    if unknown:
        raise ValueError(f'nodes {unknown} are not in the recorded scenario')
    results = {}
    for name in list(nodes):
        missing = sorted(set(cands[name].spec.consumes) - channels)
        if missing:
            results[name] = {'ok': None,
                             'skipped': f'inputs not recorded: {", ".join(missing)}'}
    nodes = [n for n in nodes if n not in results]
    # every recorded message, once, in log-time order
    msgs = [(m.log_time, c.topic, bytes(m.data)) for _, c, m in read_messages(path)]
    end = max(t for t, _, _ in msgs) if msgs else 0
    for name in nodes:
        inst = cands[name]
        inputs = set(inst.spec.consumes)
        # an input produced by a node that ran before this one in a step (start order: by
        # name) arrived before this node's timers, else after them: replay that order
        producer = {t: p for p, i in cands.items() if p in ran for t in i.spec.produces}
        feeds = {'pre': [], 'post': []}
        for t, topic, d in msgs:
            if topic in inputs:
                phase = 'pre' if producer.get(topic, '') < name else 'post'
                feeds[phase].append((t, topic, d))
        pos = {'pre': 0, 'post': 0}

        def inject(t_ns, phase, feeds=feeds, pos=pos):
            out = []
            feed = feeds[phase]
            while pos[phase] < len(feed) and feed[pos[phase]][0] <= t_ns:
                out.append((feed[pos[phase]][1], feed[pos[phase]][2]))
                pos[phase] += 1
            return out
        sub = dict(sc)
        sub['name'] = f"{sc['name']}_reprocess_{name}"
        sub['duration'] = round(end * 1e-9, 9)
        sub['outputs'] = list(inst.spec.produces)
        node_cfg = dict(sc['nodes'].get(name, {}))
        node_cfg['always'] = True
        sub['nodes'] = {name: node_cfg}
        sub['record'] = dict(sc['record'])
        # the executable's own (unremapped) spec: a remapped instance (the DFR shadow) gets its
        # remaps from its entry in sub['nodes']
        exe = inst.spec.executable
        reg = {exe: REGISTRY.get(exe, inst.spec) if name != exe else inst.spec}
        with tempfile.TemporaryDirectory() as tmp:
            bag = f'{tmp}/re.mcap'
            runner = ScenarioRunner(validate_scenario(sub), bag=bag, progress=False,
                                    registry=reg, log=log)
            runner.inject = inject
            runner.inject_topics = set(inputs)
            res = runner.run()
            if res.status != 'complete':
                results[name] = {'ok': False, 'error': res.reason or 'not started'}
                continue
            if name not in res.nodes:
                results[name] = {'ok': False, 'error': 'node could not be started'}
                continue
            comp = {}
            ok = True
            for topic in inst.spec.produces:
                if topic not in recorded:
                    continue
                c = compare_streams(path, bag, topic)
                c['ok'] = (c['recorded'] == c['now'] == c['matched'] and c['max_diff'] <= tol)
                ok &= c['ok']
                comp[topic] = c
            comp['ok'] = ok
            results[name] = comp
    return results


def format_results(results: Dict[str, dict]) -> str:
    lines = [f"{'node':<26} {'topic':<30} {'recorded':>8} {'now':>8} {'matched':>8} "
             f"{'max |diff|':>11}  result"]
    for name, comp in sorted(results.items()):
        if 'skipped' in comp:
            lines.append(f'{name:<26} {"-":<30} {"":>8} {"":>8} {"":>8} {"":>11}  '
                         f'not checked ({comp["skipped"]})')
            continue
        if 'error' in comp:
            lines.append(f'{name:<26} {"-":<30} {"":>8} {"":>8} {"":>8} {"":>11}  '
                         f'NOT RUN ({comp["error"]})')
            continue
        for topic, c in sorted((k, v) for k, v in comp.items() if k != 'ok'):
            lines.append(f"{name:<26} {topic:<30} {c['recorded']:>8} {c['now']:>8} "
                         f"{c['matched']:>8} {c['max_diff']:>11.3g}  "
                         f"{'same' if c['ok'] else 'CHANGED'}")
    return '\n'.join(lines)


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(prog='reprocess', description=__doc__.split('\n\n')[0])
    ap.add_argument('bag')
    ap.add_argument('--nodes', nargs='*', default=None)
    ap.add_argument('--tol', type=float, default=1e-9)
    a = ap.parse_args(argv)

    def body():
        res = reprocess(a.bag, a.nodes, a.tol)
        if res:
            print(format_results(res))
        checked = {n: c for n, c in res.items() if c.get('ok') is not None}
        if not checked:
            print('nothing checked: no node of the recorded scenario has all its inputs and an '
                  'output in this recording (record them)')
            return 2
        return 0 if all(c['ok'] for c in checked.values()) else 1
    return cli_errors('reprocess', body)


if __name__ == '__main__':
    sys.exit(main())

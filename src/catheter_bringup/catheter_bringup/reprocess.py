"""`reprocess`: feed a recording's inputs through today's nodes and compare with its outputs.

    python -m catheter_bringup.reprocess bags/reference/smoke.mcap [--nodes impedance_identifier_node ...]
                                         [--tol 1e-9]

For each node instance of the recorded scenario (default: every node whose inputs and outputs are
all in the recording), the node is started alone in lockstep on the recorded clock with the
recorded scenario's parameters; the recorded messages of the topics it consumes are delivered at
their recorded times; what it publishes now is compared, message by message (matched by header
stamp), with what it published then. A regression check: exit code 1 when a node's output
changed by more than ``tol`` or a message is missing or extra.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
from typing import Dict, List, Optional

import numpy as np

from catheter_bringup.analyze import Recording


def _flat(v) -> List[float]:
    if v is None:
        return []
    if isinstance(v, dict):
        out = []
        for k in sorted(v):
            out += list(v[k])
        return out
    return list(v)


def compare_streams(old: Recording, new: Recording, topic: str) -> dict:
    """Messages of ``topic`` matched by header stamp: counts, matched, max |difference|."""
    so, sn = old.stamps(topic), new.stamps(topic)
    vo, vn = old.values.get(topic, []), new.values.get(topic, [])
    idx_new: Dict[float, list] = {}
    for i, s in enumerate(sn):
        idx_new.setdefault(round(float(s), 9), []).append(i)
    matched, max_diff = 0, 0.0
    for i, s in enumerate(so):
        js = idx_new.get(round(float(s), 9))
        if not js:
            continue
        j = js.pop(0)
        a, b = _flat(vo[i]), _flat(vn[j])
        matched += 1
        if len(a) != len(b):
            max_diff = math.inf
            continue
        if a:
            d = np.abs(np.asarray(a, float) - np.asarray(b, float))
            d = np.where(np.isnan(d), 0.0, d)  # NaN in both: equal
            max_diff = max(max_diff, float(d.max()))
    return {'recorded': len(so), 'now': len(sn), 'matched': matched, 'max_diff': max_diff}


def reprocess(path, nodes: Optional[List[str]] = None, tol: float = 1e-9,
              log=print) -> Dict[str, dict]:
    """Re-run node instances on a recording's inputs; returns {instance: {topic: comparison,
    'ok': bool}}."""
    from mcap.reader import make_reader

    from catheter_bringup.runner import ScenarioRunner
    from catheter_bringup.scenario import instances, validate_scenario

    old = Recording(path)
    if not old.scenario:
        raise ValueError(f'path {path!r} has no recorded scenario (catheter_run metadata)')
    sc = validate_scenario(old.scenario)
    cands = instances(sc)
    recorded = set(old.topics)
    ran = set(json.loads(old.meta.get('nodes', '[]')))
    if nodes is None:
        nodes = [n for n, i in sorted(cands.items())
                 if n in ran and i.spec.consumes and set(i.spec.produces) & recorded
                 and set(i.spec.consumes) & recorded]
    unknown = [n for n in nodes if n not in cands]
    if unknown:
        raise ValueError(f'nodes {unknown} are not in the recorded scenario')
    # every recorded message, once, in log-time order
    with open(path, 'rb') as f:
        msgs = [(m.log_time, c.topic, bytes(m.data))
                for _, c, m in make_reader(f).iter_messages(log_time_order=True)]
    end = max(t for t, _, _ in msgs) if msgs else 0
    results = {}
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
        reg = {inst.spec.executable: inst.spec} if name == inst.spec.executable else {}
        with tempfile.TemporaryDirectory() as tmp:
            bag = f'{tmp}/re.mcap'
            runner = ScenarioRunner(validate_scenario(sub), bag=bag, progress=False,
                                    registry=reg or {inst.spec.executable: inst.spec}, log=log)
            runner.inject = inject
            runner.inject_topics = set(inputs)
            res = runner.run()
            if res.status != 'complete':
                results[name] = {'ok': False, 'error': res.reason or 'not started'}
                continue
            if name not in res.nodes:
                results[name] = {'ok': False, 'error': 'node could not be started'}
                continue
            new = Recording(bag)
        comp = {}
        ok = True
        for topic in inst.spec.produces:
            if topic not in recorded:
                continue
            c = compare_streams(old, new, topic)
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
        if 'error' in comp:
            lines.append(f'{name:<26} {"-":<30} {"":>8} {"":>8} {"":>8} {"":>11}  '
                         f'NOT RUN ({comp["error"]})')
            continue
        for topic, c in sorted((k, v) for k, v in comp.items() if k != 'ok'):
            lines.append(f"{name:<26} {topic:<30} {c['recorded']:>8} {c['now']:>8} "
                         f"{c['matched']:>8} {c['max_diff']:>11.3g}  "
                         f"{'same' if c['ok'] else 'CHANGED'}")
    return '\n'.join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(prog='reprocess', description=__doc__.split('\n\n')[0])
    ap.add_argument('bag')
    ap.add_argument('--nodes', nargs='*', default=None)
    ap.add_argument('--tol', type=float, default=1e-9)
    a = ap.parse_args(argv)
    res = reprocess(a.bag, a.nodes, a.tol)
    if not res:
        print('no node of the recorded scenario has its inputs and outputs in this recording '
              '(record them, or name nodes with --nodes)')
        return 0
    print(format_results(res))
    return 0 if all(c.get('ok') for c in res.values()) else 1


if __name__ == '__main__':
    sys.exit(main())

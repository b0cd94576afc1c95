"""`analyze`: recompute a run's metrics from its MCAP recording, without ROS running.

    python -m catheter_bringup.analyze bags/experiment_ii.mcap [--json out.json] [--quiet]

Reads the recording with ``mcap_ros2`` (messages decoded from the schemas stored in the file), and
the scenario stored in its ``catheter_run`` metadata (link delay, outages), and reports:

- force tracking: each rendered force stream (``/master/rendered_force`` = the scenario's renderer,
  ``/master/dfr/rendered_force`` = a DFR shadow renderer if recorded) against ``/slave/force``
  time-aligned by the link delay, in normal and outage intervals (MAE, RMSE, max; N);
- image force estimation: ``/catheter/tip_wrench`` against the true tip force topic (scenario
  ``metrics.truth_topic``) if recorded, or against the slave's load cell otherwise (flagged);
- per topic: message count, rate, period p50/p99/max and latency (log time - header stamp) p50/p99.
"""
from __future__ import annotations

import argparse
import json
import math
import pathlib
import sys
from typing import Dict, Iterable, List, Optional

import numpy as np
import yaml

from catheter_bringup import metrics as M
from catheter_bringup.recorder import read_run_metadata

RENDERED = '/master/rendered_force'
HAND_FORCE = '/master/hand_force'         # catheter_common.topics.MASTER_HAND_FORCE
SLAVE_FORCE = '/slave/force'
TIP_WRENCH = '/catheter/tip_wrench'
IMPEDANCE = '/master/link/impedance'
SLAVE_IMPEDANCE = '/slave/impedance'


def _stamp(msg) -> Optional[float]:
    h = getattr(msg, 'header', None)
    if h is None:
        return None
    return h.stamp.sec + h.stamp.nanosec * 1e-9


def _values(msg):
    """A few numbers per message for the analysis (None when the type has none of interest)."""
    if hasattr(msg, 'wrench'):
        f = msg.wrench.force
        return (f.x, f.y, f.z)
    if hasattr(msg, 'position') and hasattr(msg, 'name') and hasattr(msg, 'effort'):
        vals = {}
        for i, n in enumerate(msg.name):
            vals[n] = (msg.position[i] if i < len(msg.position) else math.nan,
                       msg.velocity[i] if i < len(msg.velocity) else math.nan,
                       msg.effort[i] if i < len(msg.effort) else math.nan)
        return vals
    return None


class Recording:
    """A recording loaded into arrays: per topic log times, header stamps (s), values."""

    def __init__(self, path, topics: Optional[Iterable[str]] = None, decode: bool = True):
        from mcap.reader import make_reader
        from mcap_ros2.decoder import DecoderFactory
        self.path = str(path)
        self.meta = read_run_metadata(path)
        sc = self.meta.get('scenario_yaml')
        self.scenario = yaml.safe_load(sc) if sc else {}
        self.log: Dict[str, List[float]] = {}
        self.stamp: Dict[str, List[float]] = {}
        self.values: Dict[str, list] = {}
        self.types: Dict[str, str] = {}
        want = set(topics) if topics else None
        with open(self.path, 'rb') as f:
            reader = make_reader(f, decoder_factories=[DecoderFactory()])
            for schema, channel, message, msg in reader.iter_decoded_messages(
                    topics=list(want) if want else None, log_time_order=True):
                topic = channel.topic
                self.types.setdefault(topic, schema.name)
                self.log.setdefault(topic, []).append(message.log_time * 1e-9)
                s = _stamp(msg)
                self.stamp.setdefault(topic, []).append(math.nan if s is None else s)
                if decode:
                    self.values.setdefault(topic, []).append(_values(msg))

    @property
    def topics(self) -> List[str]:
        return sorted(self.log)

    def t(self, topic) -> np.ndarray:
        return np.asarray(self.log.get(topic, []), dtype=float)

    def stamps(self, topic) -> np.ndarray:
        return np.asarray(self.stamp.get(topic, []), dtype=float)

    def force(self, topic, axis: int = 0) -> np.ndarray:
        return np.asarray([v[axis] for v in self.values.get(topic, [])], dtype=float)

    def named(self, topic, name, field: int = 0) -> np.ndarray:
        return np.asarray([v.get(name, (math.nan,) * 3)[field] if isinstance(v, dict)
                           else math.nan for v in self.values.get(topic, [])], dtype=float)


def renderer_streams(scenario: dict, topics) -> Dict[str, str]:
    """label -> topic of every rendered force stream in a recording: the renderer the device
    plays (label = its mode), shadow renderers (remapped /master/rendered_force, label = their
    mode) and the force at the hand ('hand_<mode>')."""
    nodes = scenario.get('nodes') or {}
    active = ((nodes.get('ima_master_node') or {}).get('params') or {}).get('mode', 'ima')
    out = {}
    if RENDERED in topics:
        out[active] = RENDERED
    for name, cfg in nodes.items():
        cfg = cfg or {}
        target = (cfg.get('remap') or {}).get(RENDERED)
        if target and target in topics:
            label = (cfg.get('params') or {}).get('mode', name)
            out[label if label not in out else name] = target
    if HAND_FORCE in topics:
        out[f'hand_{active}'] = HAND_FORCE
    return out


def topic_owners(scenario: dict, ran) -> Dict[str, str]:
    """topic -> the node instance of the run that publishes it (from the scenario registry)."""
    if not scenario:
        return {}
    try:
        from catheter_bringup.scenario import instances, validate_scenario
        cands = instances(validate_scenario(scenario))
    except (ValueError, KeyError):
        return {}
    out = {}
    for name in sorted(ran):
        inst = cands.get(name)
        if inst is not None:
            for t in inst.spec.produces:
                out.setdefault(t, name)
    return out


def _t0(rec: Recording) -> float:
    """Start of the experiment clock: the first message of the slave (its timer's first tick),
    else the first message of the run."""
    for topic in (SLAVE_FORCE, '/slave/joint_state'):
        if rec.log.get(topic):
            return rec.log[topic][0]
    allt = [v[0] for v in rec.log.values() if v]
    return min(allt) if allt else 0.0


def analyze(path, skip: Optional[float] = None) -> dict:
    """All metrics of one recording as a JSON-able dict (see the module docstring).

    ``skip``: start-up seconds left out of the force metrics (default: the scenario's
    ``metrics.skip``, else 0.5)."""
    rec = Recording(path)
    sc = rec.scenario or {}
    if skip is None:
        skip = float((sc.get('metrics') or {}).get('skip', 0.5))
    link = sc.get('link') or {}
    delay = float(link.get('delay', 0.0))
    outages = [tuple(o) for o in link.get('outages', [])]
    t0 = _t0(rec)
    out = {'bag': pathlib.Path(path).name, 'skip_s': skip, 'scenario': sc.get('name', rec.meta.get('scenario', '')),
           'status': rec.meta.get('status', 'unknown'), 'reason': rec.meta.get('reason', ''),
           'mode': rec.meta.get('mode', ''), 'seed': sc.get('seed'),
           'delay_s': delay, 'outages': [list(o) for o in outages],
           'sim_time_reached_s': float(rec.meta.get('sim_time_reached_s', 'nan')),
           'force_tracking': {}, 'estimation': {}, 'streams': {}}
    if rec.log.get(SLAVE_FORCE):
        ts, fs = rec.t(SLAVE_FORCE), rec.force(SLAVE_FORCE)
        for label, topic in renderer_streams(sc, rec.topics).items():
            out['force_tracking'][label] = M.force_tracking(
                rec.t(topic), rec.force(topic), ts, fs, delay, outages, t0=t0, skip=skip)
            out['force_tracking'][label]['topic'] = topic
        out['slave_force_max'] = float(np.max(np.abs(fs))) if fs.size else float('nan')
    if rec.log.get(TIP_WRENCH):
        truth = (sc.get('metrics') or {}).get('truth_topic')
        ref_topic = truth if truth and rec.log.get(truth) else SLAVE_FORCE
        if rec.log.get(ref_topic):
            te, fe = rec.stamps(TIP_WRENCH), rec.values[TIP_WRENCH]
            fe = np.asarray(fe, dtype=float)
            tr = rec.stamps(ref_topic)
            fr = np.asarray(rec.values[ref_topic], dtype=float)
            order = np.argsort(tr)
            est = {}
            for i, ax in enumerate('xy'):
                ref = M.align(te, tr[order], fr[order, i])
                est[ax] = M.error_stats(fe[:, i] - ref)
            mag_e = np.hypot(fe[:, 0], fe[:, 1])
            mag_r = M.align(te, tr[order], np.hypot(fr[order, 0], fr[order, 1]))
            est['magnitude'] = M.error_stats(mag_e - mag_r)
            est['reference'] = ref_topic
            est['reference_is_truth'] = ref_topic != SLAVE_FORCE
            out['estimation'] = est
    owner = topic_owners(sc, json.loads(rec.meta.get('nodes', '[]') or '[]'))
    for topic in rec.topics:
        st = rec.stamps(topic)
        out['streams'][topic] = M.stream_stats(rec.t(topic),
                                               None if np.all(np.isnan(st)) else st)
        out['streams'][topic]['type'] = rec.types.get(topic, '')
        out['streams'][topic]['node'] = owner.get(topic, '')
    return out


def _f(x, fmt='{:.4f}'):
    return '-' if x is None or (isinstance(x, float) and not math.isfinite(x)) else fmt.format(x)


def format_report(res: dict) -> str:
    """The metrics as text tables, beside the thesis's numbers."""
    th = M.THESIS
    lines = [f"run {res['scenario']} ({res['mode']}, {res['status']}"
             f"{': ' + res['reason'] if res.get('reason') else ''}), link delay "
             f"{res['delay_s'] * 1e3:.0f} ms, outages {res['outages']}, "
             f"simulated {res['sim_time_reached_s']:.2f} s", '']
    ft = res.get('force_tracking') or {}
    if ft:
        lines += ['Force tracking at the master (rendered force vs slave force t + delay), N',
                  f"{'renderer':<14} {'interval':<8} {'MAE':>8} {'RMSE':>8} {'max':>8} "
                  f"{'thesis MAE':>11} {'thesis max':>11} {'n':>7}"]
        ref = {('ima', 'normal'): (th['ima_mae_normal'], th['ima_max']),
               ('ima', 'outage'): (th['ima_mae_outage'], th['ima_max']),
               ('ima', 'all'): (th['ima_mae'], th['ima_max']),
               ('ima_thesis', 'normal'): (th['ima_mae_normal'], th['ima_max']),
               ('ima_thesis', 'outage'): (th['ima_mae_outage'], th['ima_max']),
               ('ima_thesis', 'all'): (th['ima_mae'], th['ima_max']),
               ('dfr', 'normal'): (th['dfr_mae_normal'], th['dfr_max']),
               ('dfr', 'outage'): (th['dfr_mae_outage'], th['dfr_max']),
               ('dfr', 'all'): (None, th['dfr_max'])}
        for label in sorted(ft):
            for iv in ('normal', 'outage', 'all'):
                s = ft[label][iv]
                tm, tx = ref.get((label.replace('hand_', ''), iv), (None, None))
                lines.append(f"{label:<14} {iv:<8} {_f(s['mae']):>8} {_f(s['rmse']):>8} "
                             f"{_f(s['max']):>8} {_f(tm):>11} {_f(tx):>11} {s['n']:>7}")
        lines.append('')
    est = res.get('estimation') or {}
    if est:
        what = 'true tip force' if est.get('reference_is_truth') else \
            'slave load cell (no true tip force recorded)'
        lines += [f'Image-based tip force estimate (/catheter/tip_wrench) vs {what}, N',
                  f"{'component':<10} {'MAE':>8} {'RMSE':>8} {'max':>8} {'n':>6}   thesis "
                  f"ex-vivo MAE: SVR {th['svr_mae']}, MLP {th['mlp_mae']}"]
        for ax in ('x', 'y', 'magnitude'):
            s = est[ax]
            lines.append(f"{ax:<10} {_f(s['mae']):>8} {_f(s['rmse']):>8} {_f(s['max']):>8} "
                         f"{s['n']:>6}")
        lines.append('')
    lines += ['Streams per node (on the run\'s clock: simulated in lockstep runs; rate from log '
              'times; latency = log time - header stamp)',
              f"{'node':<26} {'topic':<28} {'count':>7} {'rate Hz':>8} {'period p50 ms':>14} "
              f"{'p99 ms':>8} {'lat p50 ms':>11} {'lat p99 ms':>11}"]
    for topic, s in sorted(res.get('streams', {}).items(),
                           key=lambda kv: (kv[1].get('node') or '~', kv[0])):
        lines.append(f"{s.get('node') or '-':<26} {topic:<28} {s['count']:>7} "
                     f"{_f(s['rate_hz'], '{:.1f}'):>8} "
                     f"{_f(s['period_p50'] * 1e3, '{:.3f}'):>14} "
                     f"{_f(s['period_p99'] * 1e3, '{:.3f}'):>8} "
                     f"{_f(s.get('latency_p50', math.nan) * 1e3, '{:.3f}'):>11} "
                     f"{_f(s.get('latency_p99', math.nan) * 1e3, '{:.3f}'):>11}")
    return '\n'.join(lines)


def _jsonable(x):
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, dict):
        return {k: _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    return x


def main(argv=None):
    p = argparse.ArgumentParser(prog='analyze', description=__doc__.split('\n\n')[0])
    p.add_argument('bag', help='an .mcap recording')
    p.add_argument('--json', default=None, help='write the metrics to this JSON file')
    p.add_argument('--skip', type=float, default=None,
                   help="start-up seconds left out (default: the scenario's metrics.skip or 0.5)")
    p.add_argument('--quiet', action='store_true')
    a = p.parse_args(argv)
    res = analyze(a.bag, skip=a.skip)
    if not a.quiet:
        print(format_report(res))
    if a.json:
        with open(a.json, 'w') as f:
            json.dump(_jsonable(res), f, indent=1, sort_keys=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())

"""`analyze`: recompute a run's metrics from its MCAP recording, without ROS running.

    python -m catheter_bringup.analyze bags/experiment_ii.mcap [--json out.json] [--quiet]

Reads the recording with ``mcap_ros2`` (messages decoded from the schemas stored in the file), and
the scenario stored in its ``catheter_run`` metadata (link delay, outages), and reports:

- force tracking: each rendered force stream (``/master/rendered_force`` = the scenario's renderer,
  ``/master/dfr/rendered_force`` = a DFR shadow renderer if recorded, ``/master/hand_force`` = the
  force at the hand) against the reference of `impedance_master.metrics` (the ONE definition the
  pure experiment uses too): the true, noise-free vessel force for the MASTER's own motion (a twin
  VesselModel with sim_slave_node's vessel parameters and seed, driven by the recorded
  ``/master/command`` at t + delay), in normal and outage intervals ([start + delay, start +
  length + 2 delay)), evaluated from 1.5 s + 2 delay (or the scenario's ``metrics.skip``);
  MAE, RMSE, max in N. Secondary (``vs_slave``): against ``/slave/force`` at t + delay, which is
  not the force for the master's motion during an outage and the catch-up after it. Recordings
  without ``/master/command`` fall back to the slave-force comparison (``reference`` says which);
- image force estimation: ``/catheter/tip_wrench`` against the true tip force topic (scenario
  ``metrics.truth_topic``) if recorded, or against the slave's load cell otherwise (flagged);
- per topic: message count, rate, period p50/p99/max and latency (log time - header stamp) p50/p99.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import pathlib
import sys
from typing import Callable, Dict, Iterable, List, Optional, Sequence, TYPE_CHECKING, Tuple

import numpy as np

from catheter_bringup import metrics as M
from catheter_bringup.bagfile import check_bag, cli_errors
from catheter_bringup.recording import Recording, load  # noqa: F401 (Recording re-exported)
from catheter_common import topics as T

if TYPE_CHECKING:
    from sim_slave.vessels import VesselSpec

RENDERED = T.MASTER_RENDERED_FORCE
HAND_FORCE = T.MASTER_HAND_FORCE
SLAVE_FORCE = T.SLAVE_FORCE
TIP_WRENCH = T.TIP_WRENCH
MASTER_COMMAND = T.MASTER_COMMAND


def renderer_streams(scenario: dict, topics: Iterable[str]) -> Dict[str, str]:
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


def topic_owners(scenario: dict, ran: Iterable[str]) -> Dict[str, str]:
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
    for topic in (SLAVE_FORCE, T.SLAVE_JOINT_STATE):
        if rec.log.get(topic):
            return rec.log[topic][0]
    allt = [v[0] for v in rec.log.values() if v]
    return min(allt) if allt else 0.0


def twin_vessel(scenario: dict) -> Tuple[VesselSpec, int]:
    """(VesselSpec, seed) of the run's sim_slave_node (its vessel, parameters over the
    defaults; `sim_slave.node_params.vessel_from_params`, as the node builds it): what the
    twin reference of `impedance_master.metrics` is built with."""
    from sim_slave.node_params import vessel_from_params
    params = {}
    try:
        from catheter_bringup.scenario import instances, validate_scenario
        inst = instances(validate_scenario(scenario)).get('sim_slave_node')
        if inst is not None:
            params = inst.params
    except (ValueError, KeyError):
        params = {}
    return vessel_from_params(params), int(params.get('seed', scenario.get('seed', 0)) or 0)


def _master_reference(rec: Recording, sc: dict, t0: float, delay: float):
    """(t rel. to t0, reference N) along the recorded master motion, or None (computed once
    per recording, delay and start: the twin vessel is a Python loop over the samples)."""
    key = (t0, delay)
    cache = rec.__dict__.setdefault('_twin_cache', {})
    if key not in cache:
        cache[key] = _compute_master_reference(rec, sc, t0, delay)
    return cache[key]


def _compute_master_reference(rec: Recording, sc: dict, t0: float, delay: float):
    from impedance_master.metrics import twin_reference
    vals = rec.values.get(MASTER_COMMAND) or []
    if not vals:
        return None
    tc = rec.t(MASTER_COMMAND) - t0
    x = np.asarray([v.get('insertion', (math.nan,) * 3)[0] if isinstance(v, dict) else math.nan
                    for v in vals], dtype=float)
    xd = np.asarray([v.get('insertion', (math.nan,) * 3)[1] if isinstance(v, dict) else math.nan
                     for v in vals], dtype=float)
    ok = np.isfinite(x) & np.isfinite(xd)
    if not ok.any():
        return None
    params, seed = twin_vessel(sc)
    tc, x, xd = tc[ok], x[ok], xd[ok]
    return tc, twin_reference(tc, x, xd, delay, params, seed)


def run_link(scenario: dict, delay: Optional[float] = None,
             outages: Optional[Iterable[Sequence[float]]] = None
             ) -> Tuple[float, List[Tuple[float, ...]], List[str]]:
    """(delay s, outages [(start, length)], warnings) of a run: given values first, else the
    recorded scenario's ``link``, else assumed (0 s, none) with a warning saying so."""
    warnings = []
    link = (scenario or {}).get('link')
    if delay is None:
        if isinstance(link, dict) and 'delay' in link:
            delay = float(link['delay'])
        else:
            delay = 0.0
            warnings.append('no link delay in the recording\'s metadata (no recorded scenario): '
                            'assuming 0 ms; give --delay')
    if outages is None:
        if isinstance(link, dict) and 'outages' in link:
            outages = link['outages'] or []
        else:
            outages = []
            warnings.append('no link outages in the recording\'s metadata (no recorded '
                            'scenario): assuming none; give --outages')
    return float(delay), [tuple(float(v) for v in o) for o in outages], warnings


def analyze(path: str | os.PathLike, skip: Optional[float] = None,
            delay: Optional[float] = None, outages: Optional[Iterable[Sequence[float]]] = None,
            progress: Optional[Callable[[str], None]] = None,
            rec: Optional[Recording] = None) -> dict:
    """All metrics of one recording as a JSON-able dict (see the module docstring).

    ``skip``: start-up seconds left out of the force metrics (default: the scenario's
    ``metrics.skip``, else the experiment's 1.5 s + 2 delay). ``delay`` (s) and ``outages``
    ([(start, length)] s) override the recorded scenario's link; when neither is given nor
    recorded they are assumed (0, none) and ``warnings`` in the result says so.
    ``progress``: a callable(str) told what is being done (the analysis of a 12 s run takes
    seconds); ``rec``: the recording already loaded (`Recording(path)`), e.g. to plot it too."""
    from impedance_master.metrics import default_eval_start, tracking_metrics
    say = progress or (lambda _msg: None)
    if rec is None:
        say('reading the recording')
        rec = load(path)
    sc = rec.scenario or {}
    delay, outages, warnings = run_link(sc, delay, outages)
    if skip is None:
        given = (sc.get('metrics') or {}).get('skip')
        skip = float(given) if given is not None else default_eval_start(delay)
    t0 = _t0(rec)
    out = {'bag': pathlib.Path(path).name, 'skip_s': skip,
           'scenario': sc.get('name', rec.meta.get('scenario', '')),
           'status': rec.meta.get('status', 'unknown'), 'reason': rec.meta.get('reason', ''),
           'mode': rec.meta.get('mode', ''), 'seed': sc.get('seed'),
           'delay_s': delay, 'outages': [list(o) for o in outages],
           'sim_time_reached_s': float(rec.meta.get('sim_time_reached_s', 'nan')),
           'force_tracking': {}, 'estimation': {}, 'streams': {}}
    if warnings:
        out['warnings'] = warnings
    say('the reference force (twin vessel along the master\'s motion)')
    twin = _master_reference(rec, sc, t0, delay)
    out['reference'] = 'twin' if twin is not None else 'slave_force'
    if twin is not None:
        out['reference_max'] = float(np.max(np.abs(twin[1]))) if twin[1].size else float('nan')
    streams = renderer_streams(sc, rec.topics)
    if rec.log.get(SLAVE_FORCE) or twin is not None:
        ts, fs = rec.t(SLAVE_FORCE), rec.force(SLAVE_FORCE)
        for label, topic in streams.items():
            tf, ff = rec.t(topic), rec.force(topic)
            # secondary: the slave's force at t + delay, in the same intervals
            vs_slave = (M.force_tracking(tf, ff, ts, fs, delay, outages, t0=t0, skip=skip)
                        if ts.size else None)
            if twin is not None:
                tc, ref = twin
                f = M.align(tc, tf - t0, ff) if tf.size else np.full(tc.shape, np.nan)
                res = tracking_metrics(tc, f, ref, outages, delay, t_eval0=skip)
                if vs_slave is not None:
                    res['vs_slave'] = vs_slave
            else:
                res = vs_slave
            res['topic'] = topic
            out['force_tracking'][label] = res
        if fs.size:
            out['slave_force_max'] = float(np.max(np.abs(fs)))
    if rec.log.get(TIP_WRENCH):
        say('the image-based force estimate')
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
            est['reference_max'] = float(np.max(np.hypot(fr[:, 0], fr[:, 1]))) if len(fr) \
                else float('nan')
            est['reference'] = ref_topic
            est['reference_is_truth'] = ref_topic != SLAVE_FORCE
            out['estimation'] = est
    say('rates and latencies per stream')
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
             f"simulated {res['sim_time_reached_s']:.2f} s"]
    lines += [f'WARNING: {w}' for w in res.get('warnings', [])] + ['']
    ft = res.get('force_tracking') or {}
    if ft:
        twin = res.get('reference') == 'twin'
        if twin:
            lines += ['Force tracking at the master, N: rendered force - true vessel force for '
                      "the master's own motion",
                      f"(twin vessel driven by /master/command at t + delay; outage = [start + d, "
                      f"start + length + 2 d); from t = {res['skip_s']:.2f} s; "
                      "'vs slave' = MAE against /slave/force at t + delay)"]
        else:
            lines += ['Force tracking at the master (rendered force vs slave force t + delay; '
                      '/master/command not recorded), N']
        lines.append(f"{'renderer':<14} {'interval':<8} {'MAE':>8} {'RMSE':>8} {'max':>8} "
                     f"{'thesis MAE':>11} {'thesis max':>11} {'n':>7}"
                     + (f" {'vs slave':>9}" if twin else ''))
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
                vs = ((ft[label].get('vs_slave') or {}).get(iv) or {}).get('mae')
                lines.append(f"{label:<14} {iv:<8} {_f(s['mae']):>8} {_f(s['rmse']):>8} "
                             f"{_f(s['max']):>8} {_f(tm):>11} {_f(tx):>11} {s['n']:>7}"
                             + (f" {_f(vs):>9}" if twin else ''))
        ima = next((k for k in ('ima', 'ima_thesis') if k in ft), None)
        if ima and 'dfr' in ft:
            parts = []
            for iv in ('normal', 'outage'):
                a, b = ft[ima][iv]['mae'], ft['dfr'][iv]['mae']
                ok = a is not None and b is not None and math.isfinite(a) and math.isfinite(b) \
                    and b > 0
                parts.append(f"{iv} {_f(a)} vs {_f(b)} N" + (f" ({a / b:.2f}x)" if ok else ''))
            lines.append(f'{ima} vs dfr MAE: ' + ', '.join(parts) + '   (thesis: IMA 0.052 / '
                         '0.041 N, DFR 0.061 / 0.171 N)')
        lines.append('')
    est = res.get('estimation') or {}
    if est:
        what = 'true tip force' if est.get('reference_is_truth') else \
            'slave load cell (no true tip force recorded)'
        lines += [f'Image-based tip force estimate (/catheter/tip_wrench) vs {what}, N '
                  f"(reference up to {_f(est.get('reference_max'))} N)",
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


def _outages_arg(text: str):
    """'4,1,8,1' -> [(4.0, 1.0), (8.0, 1.0)] (start, length pairs, s); '' -> []."""
    vals = [float(v) for v in text.split(',') if v.strip()]
    if len(vals) % 2:
        raise argparse.ArgumentTypeError('outages: start,length pairs, e.g. 4,1,8,1')
    return [(vals[i], vals[i + 1]) for i in range(0, len(vals), 2)]


def main(argv: Optional[Sequence[str]] = None) -> int:
    p = argparse.ArgumentParser(prog='analyze', description=__doc__.split('\n\n')[0])
    p.add_argument('bag', help='an .mcap recording')
    p.add_argument('--json', default=None, help='write the metrics to this JSON file')
    p.add_argument('--skip', type=float, default=None,
                   help="start-up seconds left out (default: the scenario's metrics.skip, "
                        'else 1.5 s + 2 delay)')
    p.add_argument('--delay', type=float, default=None,
                   help="link delay, s (default: the recorded scenario's)")
    p.add_argument('--outages', type=_outages_arg, default=None,
                   help="link outages as start,length pairs in s, e.g. 4,1,8,1 (default: "
                        "the recorded scenario's)")
    p.add_argument('--quiet', action='store_true')
    a = p.parse_args(argv)

    def body():
        check_bag(a.bag)
        res = analyze(a.bag, skip=a.skip, delay=a.delay, outages=a.outages,
                      progress=None if a.quiet else _progress)
        for w in res.get('warnings', []):
            print(f'analyze: warning: {w}', file=sys.stderr)
        if not a.quiet:
            print(format_report(res))
        if a.json:
            with open(a.json, 'w') as f:
                json.dump(_jsonable(res), f, indent=1, sort_keys=True)
        return 0
    return cli_errors('analyze', body)


def _progress(msg: str) -> None:
    print(f'[analyze] {msg}', file=sys.stderr, flush=True)


if __name__ == '__main__':
    sys.exit(main())

"""PNG figures of a run (like the thesis's Figs. 24-25), drawn from its recording.

    python -m catheter_bringup.plots bags/experiment_ii.mcap [--out out/] [--fam]

Every time axis is the experiment clock (s since the slave's first tick), and every panel
carries the same shaded key: the evaluation's outage windows (for a link outage (start,
length): [start + d, start + length + 2 d), d = link delay: the feedback at the master is
missing or stale; `impedance_master.metrics.intervals`), the link's own down time (a dark band
at the top), and the start-up before the evaluation starts (hatched, not evaluated). The
numbers in the legends are the ones `analyze` prints.

- ``<name>_tracking.png`` (Figs. 24/25 a-b): (a) insertion and velocity at the slave, the
  master's insertion; then per rendered stream the rendered force, the reference (the true
  vessel force for the master's motion at t + delay) and the slave's force at t + delay, with
  the stream's MAE per interval in its legend.
- ``<name>_errors.png`` (Figs. 24 c, 25 d): IMA against DFR: the error of each renderer over
  time (rendered force - reference), per-interval MAE in the legend, and the distribution of
  the evaluated errors.
- ``<name>_impedance.png`` (Fig. 25 c, and more): m, c, k and offset delivered at the master
  over time, and the last valid model's tables over insertion: static force S(x), friction
  F(x), breakaway B(x), drag C(x) (and c + C(x)).
- ``fam_accuracy.png``: see `catheter_bringup.fam_plot` (only with ``--fam`` here; the main
  command draws it when missing or stale).
"""
from __future__ import annotations

import argparse
import math
import os
import pathlib
import sys
from typing import Callable, Dict, List, Optional, Sequence, TYPE_CHECKING

import numpy as np

from catheter_bringup import metrics as M
from catheter_bringup.bagfile import cli_errors
from catheter_common import topics as T

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure
    from catheter_bringup.recording import Recording

#: one colour per renderer everywhere
COLORS = {'ima': 'tab:blue', 'ima_thesis': 'tab:purple', 'dfr': 'tab:red',
          'hand_ima': 'tab:cyan', 'hand_dfr': 'tab:orange', 'hand_ima_thesis': 'tab:pink'}
OUTAGE_STYLE = dict(color='tab:orange', alpha=0.18, lw=0)
LINK_DOWN_STYLE = dict(color='tab:orange', alpha=0.9, lw=0, ymin=0.96, ymax=1.0)
SKIP_STYLE = dict(facecolor='none', edgecolor='0.6', hatch='///', lw=0)
LEGEND = dict(fontsize=7, loc='upper left', bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)


def _plt():
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    return plt


class Windows:
    """The shaded intervals of a run (s on the experiment clock) and their key."""

    def __init__(self, outages, delay: float, eval_start: float):
        from impedance_master.metrics import intervals
        self.link_down = [(a, a + b) for a, b in outages]
        self.outage = intervals(outages, delay)
        self.eval_start = eval_start

    def shade(self, ax: Axes) -> None:
        if self.eval_start > 0:
            ax.axvspan(0.0, self.eval_start, zorder=0, **SKIP_STYLE)
        for a, b in self.outage:
            ax.axvspan(a, b, zorder=0, **OUTAGE_STYLE)
        for a, b in self.link_down:
            ax.axvspan(a, b, zorder=0, **LINK_DOWN_STYLE)

    def key(self, fig: Figure, y: float = 1.0) -> None:
        from matplotlib.patches import Patch
        handles = [Patch(**SKIP_STYLE,
                         label=f'start-up, not evaluated (< {self.eval_start:.2f} s)')]
        if self.outage:
            handles += [Patch(color='tab:orange', alpha=0.18,
                              label='outage window: feedback missing or stale '
                                    '[start + d, start + length + 2 d)'),
                        Patch(color='tab:orange', alpha=0.9, label='link down (top band)')]
        fig.legend(handles=handles, loc='upper center', ncol=len(handles), fontsize=7,
                   bbox_to_anchor=(0.5, y), frameon=False)


def _mae_label(stats: Optional[dict]) -> str:
    if not stats:
        return ''

    def f(iv):
        v = (stats.get(iv) or {}).get('mae')
        return '-' if v is None or not math.isfinite(v) else f'{v:.4f}'
    return f"MAE normal {f('normal')} N, outage {f('outage')} N"


def _save(fig, path) -> str:
    fig.savefig(path, dpi=110)
    _plt().close(fig)
    return str(path)


def run_plots(path: str | os.PathLike, out_dir: str | os.PathLike = 'out',
              name: Optional[str] = None, rec: Optional[Recording] = None,
              metrics: Optional[dict] = None,
              progress: Optional[Callable[[str], None]] = None) -> List[str]:
    """Write the run's PNGs into ``out_dir``; returns their paths. ``rec``: the loaded
    recording and ``metrics``: its `analyze` result (computed here when not given)."""
    from catheter_bringup.analyze import (SLAVE_FORCE, _master_reference, _t0, analyze,
                                          renderer_streams)
    from catheter_bringup.recording import load
    say = progress or (lambda _msg: None)
    rec = rec if rec is not None else load(path)
    metrics = metrics if metrics is not None else analyze(path, rec=rec)
    sc = rec.scenario or {}
    name = name or sc.get('name') or pathlib.Path(path).stem
    out = pathlib.Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    delay = float(metrics.get('delay_s', 0.0))
    win = Windows([tuple(o) for o in metrics.get('outages', [])], delay,
                  float(metrics.get('skip_s', 0.0)))
    t0 = _t0(rec)
    streams = renderer_streams(sc, rec.topics)
    if not rec.log.get(SLAVE_FORCE):
        return []
    ts, fs = rec.t(SLAVE_FORCE) - t0, rec.force(SLAVE_FORCE)
    twin = _master_reference(rec, sc, t0, delay)
    if twin is None:
        what = f'slave force (t + {delay * 1e3:.0f} ms)'
    else:
        what = "true force for the master's motion"

    def reference(tm):
        if twin is None:
            return M.align(tm, ts, fs, shift=delay)
        return M.align(tm, twin[0], twin[1])

    files = []
    say('plot: tracking')
    files.append(_tracking(rec, t0, streams, metrics, win, reference, what, ts, fs, delay,
                           out / f'{name}_tracking.png', name))
    say('plot: IMA vs DFR errors')
    files.append(_errors(rec, t0, streams, metrics, win, reference, what,
                         out / f'{name}_errors.png', name))
    say('plot: impedance')
    p = _impedance(rec, t0, win, out / f'{name}_impedance.png', name)
    if p:
        files.append(p)
    return files


def _tracking(rec, t0, streams, metrics, win, reference, what, ts, fs, delay, path, name):
    plt = _plt()
    n = 1 + len(streams)
    fig, axes = plt.subplots(n, 1, figsize=(11, 2.3 * n + 0.6), sharex=True)
    axes = np.atleast_1d(axes)
    ax = axes[0]
    js = T.SLAVE_JOINT_STATE
    handles = []
    if rec.log.get(js):
        tj = rec.t(js) - t0
        handles += ax.plot(tj, rec.named(js, 'insertion', 0) * 1e3, 'k', lw=1,
                           label='slave insertion, mm')
        if rec.log.get(T.MASTER_COMMAND):
            handles += ax.plot(rec.t(T.MASTER_COMMAND) - t0,
                               rec.named(T.MASTER_COMMAND, 'insertion', 0) * 1e3,
                               color='tab:green', lw=0.8, ls='--', label='master insertion, mm')
        ax2 = ax.twinx()
        handles += ax2.plot(tj, rec.named(js, 'insertion', 1) * 1e3, 'tab:blue', lw=0.6,
                            alpha=0.8, label='slave velocity, mm/s (right axis)')
        ax2.set_ylabel('velocity, mm/s', color='tab:blue', fontsize=8)
        ax2.tick_params(labelsize=7)
    ax.set_ylabel('insertion, mm', fontsize=8)
    ax.set_title(f'{name}: (a) insertion at the slave and the master', fontsize=9)
    if handles:
        ax.legend(handles=handles, **dict(LEGEND, bbox_to_anchor=(1.09, 1.0)))
    win.shade(ax)
    ft = metrics.get('force_tracking') or {}
    for k, (ax, (label, topic)) in enumerate(zip(axes[1:], sorted(streams.items()), strict=True)):
        tm = rec.t(topic) - t0
        win.shade(ax)
        ax.plot(tm, M.align(tm, ts, fs, shift=delay), color='0.6', lw=0.6,
                label=f'slave force (t + {delay * 1e3:.0f} ms)')
        ax.plot(tm, reference(tm), 'k', lw=1, label=what)
        ax.plot(tm, rec.force(topic), color=COLORS.get(label, 'tab:red'), lw=0.8,
                label=f'{label} ({topic})\n{_mae_label(ft.get(label))}')
        ax.set_ylabel('force, N', fontsize=8)
        ax.legend(**dict(LEGEND, bbox_to_anchor=(1.09, 1.0)))
        ax.set_title(f'({chr(ord("b") + k)}) {label}: rendered force against the {what}',
                     fontsize=9)
    for ax in axes:
        ax.set_xlabel('time, s', fontsize=8)
        ax.tick_params(labelsize=7, labelbottom=True)
    win.key(fig)
    fig.tight_layout(rect=(0, 0, 1, 0.97))
    return _save(fig, path)


def _errors(rec, t0, streams, metrics, win, reference, what, path, name):
    plt = _plt()
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 4.2),
                                   gridspec_kw={'width_ratios': [2.3, 1]})
    win.shade(ax1)
    ft = metrics.get('force_tracking') or {}
    shown = [(label, topic) for label, topic in sorted(streams.items())
             if not label.startswith('hand_')]
    for label, topic in shown:
        tm = rec.t(topic) - t0
        err = rec.force(topic) - reference(tm)
        color = COLORS.get(label)
        ax1.plot(tm, err, lw=0.7, color=color, label=f'{label}: {_mae_label(ft.get(label))}')
        e = err[np.isfinite(err) & (tm >= win.eval_start)]
        if e.size:
            ax2.hist(e, bins=80, alpha=0.5, density=True, color=color, label=label)
    ax1.axhline(0.0, color='k', lw=0.5)
    ax1.set_xlabel('time, s', fontsize=8)
    ax1.set_ylabel('rendered - reference force, N', fontsize=8)
    ax1.legend(fontsize=7, loc='upper center', bbox_to_anchor=(0.5, -0.16), ncol=2)
    title = ' vs '.join(label.upper() for label, _ in shown)
    ax1.set_title(f'{name}: {title} force error against the {what}', fontsize=9)
    ax2.set_xlabel('error, N (evaluated samples)', fontsize=8)
    ax2.set_ylabel('probability density, 1/N', fontsize=8)
    ax2.set_title('error distribution', fontsize=9)
    ax2.legend(fontsize=7, loc='upper center', bbox_to_anchor=(0.5, -0.16), ncol=2)
    for ax in (ax1, ax2):
        ax.tick_params(labelsize=7)
    win.key(fig)
    fig.tight_layout(rect=(0, 0, 1, 0.95))
    return _save(fig, path)


def _table_model(rec, topic) -> Optional[Dict[str, np.ndarray]]:
    """The last valid tabulated model of ``topic``: grid x (m) and S, F, B, C node values."""
    for v in reversed(rec.values.get(topic, [])):
        if not isinstance(v, dict) or v.get('valid', (0.0,))[0] < 0.5:
            continue
        if v.get('kind', (0.0,))[0] < 0.5 or 'n' not in v:
            return None
        n = int(round(v['n'][0]))
        grid = v['x0'][0] + v['dx'][0] * np.arange(n)
        try:
            tables = {k: np.asarray([v[f'{k}{i}'][0] for i in range(n)]) for k in 'SFBC'}
        except KeyError:
            return None
        return dict(x=grid, c=v['c'][0], **tables)
    return None


def _impedance(rec, t0, win, path, name) -> Optional[str]:
    topic = T.MASTER_LINK_IMPEDANCE if rec.log.get(T.MASTER_LINK_IMPEDANCE) \
        else T.SLAVE_IMPEDANCE
    if not rec.log.get(topic):
        return None
    plt = _plt()
    ti = rec.t(topic) - t0
    fig = plt.figure(figsize=(13.5, 7))
    gs = fig.add_gridspec(4, 2, width_ratios=[1.6, 1])
    valid = rec.named(topic, 'valid', 0)
    for row, (key, unit) in enumerate((('m', 'kg'), ('c', 'N s/m'), ('k', 'N/m'),
                                       ('offset', 'N'))):
        ax = fig.add_subplot(gs[row, 0])
        win.shade(ax)
        y = rec.named(topic, key, 0)
        ax.plot(ti, y, lw=1, color='k')
        bad = valid < 0.5
        if bad.any():
            ax.plot(ti[bad], y[bad], '.', ms=1, color='tab:red')
        ax.set_ylabel(f'{key}, {unit}', fontsize=8)
        ax.set_xlabel('time, s', fontsize=8)
        ax.tick_params(labelsize=7)
        if row == 0:
            ax.set_title(f'{name}: model delivered at the master ({topic}; red dots: '
                         'not valid)', fontsize=9)
    model = _table_model(rec, topic)
    ax = fig.add_subplot(gs[0:2, 1])
    ax2 = fig.add_subplot(gs[2:4, 1])
    if model is not None:
        x = model['x'] * 1e3
        for key, label in (('S', 'S(x) static force'), ('F', 'F(x) friction level'),
                           ('B', 'B(x) breakaway extra')):
            ax.plot(x, model[key], 'o-', ms=2, lw=1, label=label)
        ax.set_ylabel('force, N', fontsize=8)
        ax2.plot(x, model['C'], 'o-', ms=2, lw=1, label='C(x) drag table')
        ax2.plot(x, model['c'] + model['C'], 'k--', lw=1, label='c + C(x) total drag')
        ax2.set_ylabel('drag, N s/m', fontsize=8)
        ax.set_title('the last valid model\'s tables', fontsize=9)
        for a in (ax, ax2):
            a.legend(fontsize=7, loc='upper left', bbox_to_anchor=(1.01, 1.0),
                     borderaxespad=0.0)
    else:
        for a in (ax, ax2):
            a.text(0.5, 0.5, 'no valid tabulated model\n(linear models only)',
                   ha='center', va='center', transform=a.transAxes, fontsize=8)
        ax.set_ylabel('force, N', fontsize=8)
        ax2.set_ylabel('drag, N s/m', fontsize=8)
    for a in (ax, ax2):
        a.set_xlabel('insertion x, mm', fontsize=8)
        a.tick_params(labelsize=7)
    win.key(fig)
    fig.tight_layout(rect=(0, 0, 1, 0.96))
    return _save(fig, path)


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(prog='plots', description=__doc__.split('\n\n')[0])
    ap.add_argument('bag', nargs='?', help='an .mcap recording')
    ap.add_argument('--out', default='out')
    ap.add_argument('--fam', action='store_true',
                    help='also measure and draw the FAM accuracy plot')
    a = ap.parse_args(argv)

    def body():
        files = run_plots(a.bag, a.out) if a.bag else []
        if a.fam:
            from catheter_bringup.fam_plot import fam_accuracy_plot
            p = fam_accuracy_plot(a.out)
            if p:
                files.append(p)
        for f in files:
            print(f)
        return 0
    return cli_errors('plots', body)


if __name__ == '__main__':
    sys.exit(main())

"""PNG plots of a run, like the thesis's Figs. 24-25, and the FAM accuracy-against-time plot.

    python -m catheter_bringup.plots bags/experiment_ii.mcap [--out out/]

- ``<name>_tracking.png`` (Fig. 24/25 a-b): insertion length and velocity at the slave (and the
  master's insertion); each renderer's force against the reference of analyze /
  impedance_master.metrics (true vessel force for the master's motion at t + delay; the slave
  force at t + delay in grey); the outage intervals [start + d, start + length + 2 d) shaded.
- ``<name>_impedance.png`` (Fig. 25 c): the impedance coefficients m, c, k delivered at the master.
- ``<name>_errors.png`` (Fig. 24 c, 25 d): tracking error over time and its distribution per
  renderer, normal and outage intervals.
- ``fam_accuracy.png``: FAM tip error against solve time for growing arc counts, measured now
  (fam_solver against solve_elastica), or read from out/bench/bench_fam.txt when asked.
"""
from __future__ import annotations

import argparse
import pathlib
import sys
import time
from typing import Dict, List, Optional

import numpy as np

from catheter_bringup import metrics as M


def _plt():
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    return plt


def _shade(ax, outages, t0=0.0):
    for a, length in outages:
        ax.axvspan(t0 + a, t0 + a + length, color='0.85', zorder=0, lw=0)


def _reference(rec, sc, t0, delay, tm, ts, fs):
    """The metric's reference at the times tm (rel. to t0): the twin-vessel force along the
    master's motion if /master/command is recorded, else the slave force at t + delay."""
    from catheter_bringup.analyze import _master_reference
    twin = _master_reference(rec, sc, t0, delay)
    if twin is None:
        return M.align(tm, ts, fs, shift=delay), f'slave force (t + {delay * 1e3:.0f} ms)'
    return M.align(tm, twin[0], twin[1]), "true force for the master's motion"


def run_plots(path, out_dir='out', name: Optional[str] = None) -> List[str]:
    """Write the run's PNGs into ``out_dir``; returns their paths."""
    from catheter_bringup.analyze import SLAVE_FORCE, Recording, _t0, renderer_streams
    plt = _plt()
    rec = Recording(path)
    sc = rec.scenario or {}
    name = name or sc.get('name') or pathlib.Path(path).stem
    out = pathlib.Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    delay = float((sc.get('link') or {}).get('delay', 0.0))
    outages = [tuple(o) for o in (sc.get('link') or {}).get('outages', [])]
    t0 = _t0(rec)
    # the outage intervals of the metric: feedback missing or stale
    shaded = [(a + delay, b + delay) for a, b in outages]
    files = []
    streams = renderer_streams(sc, rec.topics)
    if not rec.log.get(SLAVE_FORCE):
        return files
    ts, fs = rec.t(SLAVE_FORCE) - t0, rec.force(SLAVE_FORCE)

    # tracking (Figs. 24a-b, 25a-b)
    n = 1 + len(streams)
    fig, axes = plt.subplots(n, 1, figsize=(9, 2.4 * n), sharex=True)
    axes = np.atleast_1d(axes)
    js = '/slave/joint_state'
    if rec.log.get(js):
        tj = rec.t(js) - t0
        ax = axes[0]
        ax.plot(tj, rec.named(js, 'insertion', 0) * 1e3, 'k', lw=1, label='insertion (mm)')
        ax2 = ax.twinx()
        ax2.plot(tj, rec.named(js, 'insertion', 1) * 1e3, 'tab:blue', lw=0.8,
                 label='velocity (mm/s)')
        ax.set_ylabel('insertion, mm')
        ax2.set_ylabel('velocity, mm/s', color='tab:blue')
        if rec.log.get('/master/command'):
            ax.plot(rec.t('/master/command') - t0, rec.named('/master/command', 'insertion', 0)
                    * 1e3, color='tab:green', lw=0.8, ls='--', label='master insertion (mm)')
        ax.legend(loc='lower center', fontsize=7)
        ax.set_title(f'{name}: slave insertion (a), link outages shaded')
        _shade(ax, outages)
    for ax, (label, topic) in zip(axes[1:], sorted(streams.items())):
        tm = rec.t(topic) - t0
        fm = rec.force(topic)
        ref, what = _reference(rec, sc, t0, delay, tm, ts, fs)
        _shade(ax, shaded)
        ax.plot(tm, M.align(tm, ts, fs, shift=delay), color='0.6', lw=0.6,
                label=f'slave force (t + {delay * 1e3:.0f} ms)')
        ax.plot(tm, ref, 'k', lw=1, label=what)
        ax.plot(tm, fm, 'tab:red', lw=0.8, label=f'{label} ({topic})')
        ax.set_ylabel('force, N')
        ax.legend(loc='upper left', fontsize=7)
        ax.set_title(f'{label}: rendered force vs {what} (outage intervals shaded)', fontsize=9)
    axes[-1].set_xlabel('time, s')
    fig.tight_layout()
    p = out / f'{name}_tracking.png'
    fig.savefig(p, dpi=110)
    plt.close(fig)
    files.append(str(p))

    # impedance over time (Fig. 25c)
    imp = '/master/link/impedance' if rec.log.get('/master/link/impedance') else '/slave/impedance'
    if rec.log.get(imp):
        ti = rec.t(imp) - t0
        fig, axes = plt.subplots(3, 1, figsize=(9, 5.5), sharex=True)
        for ax, (key, unit) in zip(axes, (('m', 'kg'), ('c', 'N s/m'), ('k', 'N/m'))):
            _shade(ax, outages)
            ax.plot(ti, rec.named(imp, key, 0), lw=1)
            ax.set_ylabel(f'{key}, {unit}')
        axes[0].set_title(f'{name}: impedance delivered at the master ({imp})')
        axes[-1].set_xlabel('time, s')
        fig.tight_layout()
        p = out / f'{name}_impedance.png'
        fig.savefig(p, dpi=110)
        plt.close(fig)
        files.append(str(p))

    # errors over time and distribution (Figs. 24c, 25d)
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 3.6), gridspec_kw={'width_ratios': [2, 1]})
    _shade(ax1, shaded)
    what = ''
    for label, topic in sorted(streams.items()):
        if label.startswith('hand_'):
            continue
        tm = rec.t(topic) - t0
        ref, what = _reference(rec, sc, t0, delay, tm, ts, fs)
        err = rec.force(topic) - ref
        ax1.plot(tm, err, lw=0.8, label=label)
        e = err[np.isfinite(err)]
        if e.size:
            ax2.hist(e, bins=60, alpha=0.5, density=True, label=label)
    ax1.set_xlabel('time, s')
    ax1.set_ylabel('tracking error, N')
    ax1.legend(fontsize=8)
    ax1.set_title(f'{name}: rendered force - {what} (outage intervals shaded)', fontsize=9)
    ax2.set_xlabel('error, N')
    ax2.set_title('error distribution', fontsize=9)
    ax2.legend(fontsize=8)
    fig.tight_layout()
    p = out / f'{name}_errors.png'
    fig.savefig(p, dpi=110)
    plt.close(fig)
    files.append(str(p))
    return files


def fam_accuracy_data(n_arcs=(1, 2, 4, 8, 12, 24, 48, 96, 200), alphas=(1.0, 5.0, 10.0),
                      repeats: int = 3, arc_model: str = 'clothoid') -> Optional[Dict[str, list]]:
    """FAM tip error (fraction of L, worst over ``alphas`` = F L^2 / EI, perpendicular dead tip
    load) against the median solve time, for each arc count (equal arcs of ``arc_model``);
    None if fam_solver is missing."""
    try:
        from fam_solver import Catheter, Loads, solve_elastica, solve_fam
    except ImportError:
        return None
    cat = Catheter(length=0.065, ei=6.0e-5)
    refs = {}
    for a in alphas:
        loads = Loads(tip_force=(0.0, a * cat.ei / cat.length ** 2))
        refs[a] = (loads, np.asarray(solve_elastica(cat, loads).tip))
    rows = {'n_arcs': [], 'error_frac_l': [], 'time_s': []}
    for n in n_arcs:
        errs, times = [], []
        for a, (loads, tip_ref) in refs.items():
            best = float('inf')
            for _ in range(repeats):
                t = time.perf_counter()
                shape = solve_fam(cat, loads, n_arcs=n, arc_model=arc_model, spacing='uniform')
                best = min(best, time.perf_counter() - t)
            times.append(best)
            errs.append(float(np.linalg.norm(np.asarray(shape.tip) - tip_ref)) / cat.length)
        rows['n_arcs'].append(int(n))
        rows['error_frac_l'].append(max(errs))
        rows['time_s'].append(float(np.median(times)))
    return rows


def fam_accuracy_plot(out_dir='out', data=None) -> Optional[str]:
    """The FAM accuracy plot; ``data``: {arc model: fam_accuracy_data(...)} (None: measured
    now for the clothoid and circular arcs)."""
    if data is None:
        data = {m: fam_accuracy_data(arc_model=m) for m in ('clothoid', 'exact')}
    if not data or not all(data.values()):
        return None
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6, 4))
    for model, d in data.items():
        ax.loglog(np.asarray(d['time_s']) * 1e3, np.asarray(d['error_frac_l']) * 100, 'o-',
                  label=f'{model} arcs')
        for n, t, e in zip(d['n_arcs'], d['time_s'], d['error_frac_l']):
            ax.annotate(f'N={n}', (t * 1e3, e * 100), fontsize=7, textcoords='offset points',
                        xytext=(4, 2))
    ax.axhline(0.6, color='tab:red', ls='--', lw=0.8, label='thesis N=12 vs Abaqus (0.6 % L)')
    ax.axhline(0.1, color='tab:green', ls=':', lw=0.8, label='project target (0.1 % L)')
    ax.set_xlabel('solve time, ms (this machine, one core, shared)')
    ax.set_ylabel('tip error, % of L (worst of F L^2/EI = 1, 5, 10)')
    ax.set_title('FAM accuracy against time (vs solve_elastica)')
    ax.legend(fontsize=7)
    fig.tight_layout()
    p = pathlib.Path(out_dir) / 'fam_accuracy.png'
    p.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(p, dpi=110)
    plt.close(fig)
    return str(p)


def main(argv=None):
    ap = argparse.ArgumentParser(prog='plots', description=__doc__.split('\n\n')[0])
    ap.add_argument('bag', nargs='?', help='an .mcap recording')
    ap.add_argument('--out', default='out')
    ap.add_argument('--no-fam', action='store_true', help='skip the FAM accuracy plot')
    a = ap.parse_args(argv)
    files = run_plots(a.bag, a.out) if a.bag else []
    if not a.no_fam:
        p = fam_accuracy_plot(a.out)
        if p:
            files.append(p)
    for f in files:
        print(f)
    return 0


if __name__ == '__main__':
    sys.exit(main())

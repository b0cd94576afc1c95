"""The FAM accuracy-against-time figure (``fam_accuracy.png``): the tip error of fam_solver
against solve_elastica for growing arc counts, with solve times measured on this machine
(about a second). The times differ from run to run, so the main command draws it only when
the file is missing or older than the fam_solver sources (`is_current`), not on every run.
"""
from __future__ import annotations

import importlib.util
import os
import pathlib
import time
from typing import Dict, Optional, Sequence

import numpy as np

FILE = 'fam_accuracy.png'


def fam_sources_mtime() -> Optional[float]:
    """Newest modification time of fam_solver's modules (None if fam_solver is missing)."""
    spec = importlib.util.find_spec('fam_solver')
    if spec is None or not spec.submodule_search_locations:
        return None
    files = [p for d in spec.submodule_search_locations for p in pathlib.Path(d).glob('*.py')]
    return max((p.stat().st_mtime for p in files), default=None)


def is_current(out_dir: str | os.PathLike) -> bool:
    """True when out_dir/fam_accuracy.png exists and is newer than every fam_solver module."""
    png = pathlib.Path(out_dir) / FILE
    src = fam_sources_mtime()
    return png.exists() and src is not None and png.stat().st_mtime >= src


def fam_accuracy_data(n_arcs: Sequence[int] = (1, 2, 4, 8, 12, 24, 48, 96, 200),
                      alphas: Sequence[float] = (1.0, 5.0, 10.0),
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
        for _a, (loads, tip_ref) in refs.items():
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


def fam_accuracy_plot(out_dir: str | os.PathLike = 'out',
                      data: Optional[Dict[str, dict]] = None) -> Optional[str]:
    """Draw fam_accuracy.png; ``data``: {arc model: fam_accuracy_data(...)} (None: measured
    now for the clothoid and circular arcs). None when fam_solver is missing."""
    from catheter_bringup.plots import _plt
    if data is None:
        data = {m: fam_accuracy_data(arc_model=m) for m in ('clothoid', 'exact')}
    if not data or not all(data.values()):
        return None
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7.5, 4.2))
    for model, d in data.items():
        ax.loglog(np.asarray(d['time_s']) * 1e3, np.asarray(d['error_frac_l']) * 100, 'o-',
                  label=f'{model} arcs')
        for n, t, e in zip(d['n_arcs'], d['time_s'], d['error_frac_l'], strict=True):
            ax.annotate(f'N={n}', (t * 1e3, e * 100), fontsize=7, textcoords='offset points',
                        xytext=(4, 2))
    ax.axhline(0.6, color='tab:red', ls='--', lw=0.8, label='thesis N=12 vs Abaqus (0.6 % L)')
    ax.axhline(0.1, color='tab:green', ls=':', lw=0.8, label='project target (0.1 % L)')
    ax.set_xlabel('solve time, ms (this machine, one core, shared)')
    ax.set_ylabel('tip error, % of L\n(worst of F L^2/EI = 1, 5, 10)')
    ax.set_title('FAM accuracy against time (vs solve_elastica)')
    ax.legend(fontsize=7, loc='upper left', bbox_to_anchor=(1.01, 1.0))
    fig.tight_layout()
    p = pathlib.Path(out_dir) / FILE
    p.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(p, dpi=110)
    plt.close(fig)
    return str(p)

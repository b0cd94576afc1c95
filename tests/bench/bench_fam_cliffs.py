"""Performance cliffs of the FAM solver (issue 15), robust to a shared machine.

    scripts/bench fam            # runs bench_fam.py and this; or:
    python tests/bench/bench_fam_cliffs.py [--quick]

For each case set (bench_fam's thesis and Blazer sets; tip forces with tip moments), arc
model and spacing: per N the median over the cases of each case's CPU time, and the slowest
case over that median (target <= 3); whether the median is non-decreasing in N, and by how
much it drops where it is not, against the noise left in the measurement. Times are CPU times
of single solves from ``interleaved_cpu`` (rounds over all (N, case), the order rotated each
round, the minimum over the rounds), with a reference solve interleaved in the same rounds
(its time and the ratios to it are printed: compare runs by those, not by absolute times).
"""
from __future__ import annotations

import math
import os
import pathlib
import sys
import time

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))

from bench_fam import BLAZER, MODELS, QUICK, THESIS, blazer_cases, thesis_cases  # noqa: E402
from fam_solver import Loads, solve_fam  # noqa: E402

#: the slowest case at most this many times the median at the same N
CLIFF_RATIO = 3.0


def interleaved_cpu(jobs, rounds):
    """CPU time [ms] of single calls of each job, robust to the other jobs on a shared machine.
    Every round runs every job once, the order rotated and reversed from round to round (so a
    burst of load hits different jobs each time); each job's figure is its MINIMUM over the
    rounds (the least disturbed call: a statement about the code, not the machine). Also
    returns the minima over the even and the odd rounds separately: their ratio is the noise
    left in the figure. One warm-up call per job first (caches of arc constants)."""
    keys = list(jobs)
    for k in keys:
        jobs[k]()
    t = {k: [] for k in keys}
    for r in range(rounds):
        off = (r * len(keys)) // max(rounds, 1)
        order = keys[off:] + keys[:off]
        if r % 2:
            order = order[::-1]
        for k in order:
            fn = jobs[k]
            c0 = time.process_time()
            fn()
            t[k].append(time.process_time() - c0)
    best = {k: min(v) * 1e3 for k, v in t.items()}
    even = {k: min(v[0::2]) * 1e3 for k, v in t.items()}
    odd = {k: min(v[1::2]) * 1e3 if len(v) > 1 else min(v) * 1e3 for k, v in t.items()}
    return best, even, odd


#: cliff checks: N (both sides of the fast path's dense/banded switch at 80 and of the general
#: path's at 64), and the interleaved rounds per group of N
CLIFF_NS = [1, 2, 4, 8, 12, 16, 24, 32, 48, 64, 65, 80, 81, 100, 200, 500, 1000]
CLIFF_ROUNDS = (9, 3)      # rounds for N <= 100, for N > 100


def cliff_times(solve, cases, ns, ref):
    """Per-case CPU ms {n: (cases,)} of ``solve(case, n)``, measured by ``interleaved_cpu``
    (every (N, case) once per round, min over the rounds) with the reference job ``ref``
    interleaved in the same rounds; also {n: noise}: the median over the cases from the even
    rounds against that from the odd rounds (|ratio - 1|), and the reference's ms."""
    times, noise, refs = {}, {}, []
    for group, rounds in ((n_ for n_ in ns if n_ <= 100), CLIFF_ROUNDS[0]), \
            ((n_ for n_ in ns if n_ > 100), CLIFF_ROUNDS[1]):
        group = list(group)
        if QUICK:
            rounds = max(3, rounds // 3)
        jobs = {('ref',): ref}
        for n in group:
            for i, ld in enumerate(cases):
                jobs[(n, i)] = (lambda ld=ld, n=n: solve(ld, n))
        best, even, odd = interleaved_cpu(jobs, rounds)
        refs.append(best[('ref',)])
        for n in group:
            times[n] = np.array([best[(n, i)] for i in range(len(cases))])
            me = np.median([even[(n, i)] for i in range(len(cases))])
            mo = np.median([odd[(n, i)] for i in range(len(cases))])
            noise[n] = abs(me / mo - 1.0)
    return times, noise, min(refs)


def cliff_report(title, times, noise, ns, labels, ref_ms):
    """One row of the cliff checks: times[n] = per-case CPU ms, noise[n] (fraction)."""
    meds = [float(np.median(times[n])) for n in ns]
    ratios = [float(np.max(times[n]) / np.median(times[n])) for n in ns]
    worst = [labels[int(np.argmax(times[n]))] for n in ns]
    # the largest drop of the median from any smaller N (0 when non-decreasing), and whether
    # it is larger than the noise of the two medians (even vs odd rounds)
    drop, where, nz = 0.0, '', 0.0
    for j in range(1, len(ns)):
        k = int(np.argmax(meds[:j]))
        d = 1.0 - meds[j] / meds[k]
        if d > drop:
            drop, where, nz = d, f' (N = {ns[k]} -> {ns[j]})', noise[ns[k]] + noise[ns[j]]
    cells = ' | '.join(f'{m:.3f} / {r:.2f}' for m, r in zip(meds, ratios, strict=True))
    ok_ratio = max(ratios) <= CLIFF_RATIO
    smooth = (f'{meds[ns.index(100)] / meds[ns.index(48)]:.2f}'
              if 48 in ns and 100 in ns else '')
    verdict = 'yes' if drop == 0.0 else ('within noise' if drop <= nz else 'NO')
    print(f'| {title} | {cells} | {max(ratios):.2f} at N = {ns[int(np.argmax(ratios))]} '
          f'({worst[int(np.argmax(ratios))]}) {"ok" if ok_ratio else "OVER " + str(CLIFF_RATIO)} | '
          f'{smooth} | {meds[ns.index(12)] / ref_ms if 12 in ns else float("nan"):.2f} | '
          f'{verdict}; largest drop {drop * 100:.1f} %{where}, noise {nz * 100:.1f} % |')
    return ok_ratio, drop, verdict


def cliff_header(ns):
    print('| case set, model, spacing | ' + ' | '.join(f'N = {n}' for n in ns) +
          ' | max slowest/median | N = 100 / N = 48 | N = 12 / reference | median '
          'non-decreasing in N (largest drop, noise of the two medians) |')
    print('|---|' + '---|' * (len(ns) + 4))


def table_cliffs():
    ref_ld = Loads(tip_force=(0.0, 0.2))
    ref = lambda: solve_fam(BLAZER, ref_ld, n_arcs=12)   # noqa: E731
    ns = [n for n in CLIFF_NS if not (QUICK and n > 100)]
    print(f'### Performance cliffs (issue 15): per N, median CPU ms over the cases / slowest case '
          f'over that median (target <= {CLIFF_RATIO:g}); is the median non-decreasing in N')
    print(f'CPU times: every (N, case) once per round, rounds interleaved ({CLIFF_ROUNDS[0]} '
          f'rounds for N <= 100, {CLIFF_ROUNDS[1]} beyond), the minimum over the rounds; noise: '
          f'medians from the even against the odd rounds; reference: clothoid N = 12, Blazer '
          f'0.2 N lateral, '
          f'interleaved in the same rounds. load average {os.getloadavg()[0]:.1f} on '
          f'{os.cpu_count()} cores')
    cliff_header(ns)
    sets = [('thesis 40 mm', THESIS, thesis_cases()), ('Blazer 65 mm', BLAZER, blazer_cases())]
    rows = []
    for name, cat, cases in sets:
        labels = [f'case {i}' for i in range(len(cases))]
        for model in MODELS:
            for spacing in ('uniform', 'graded'):
                times, noise, ref_ms = cliff_times(
                    lambda ld, n, cat=cat, model=model, spacing=spacing: solve_fam(
                        cat, ld, n_arcs=n, arc_model=model, spacing=spacing),
                    cases, ns, ref)
                rows.append(cliff_report(f'{name}, {model}, {spacing}', times, noise, ns, labels,
                                         ref_ms))
    print(f'reference (clothoid N = 12, Blazer 0.2 N lateral): {ref_ms:.3f} ms CPU in this run')
    cliff_summary(rows)
    # tip forces with tip moments (the case that used to leave the fast path)
    cat = BLAZER
    cases, labels = [], []
    for F in (0.1, 0.2, 0.3):
        for b in (math.pi / 4, math.pi / 2, 3 * math.pi / 4):
            for sgn in (-1, 1):
                m = sgn * 0.25 * F * cat.length
                cases.append(Loads(tip_force=(F * math.cos(b), F * math.sin(b)), tip_moment=m))
                labels.append(f'{F} N at {math.degrees(b):.0f} deg, {m * 1e3:+.2f} mN m')
    print('### Tip force with tip moment (Blazer 0.1-0.3 N at 45/90/135 deg, moments +-F L/4)')
    ns2 = [12, 24, 48, 64, 80, 81, 100]
    cliff_header(ns2)
    rows = []
    for model in ('clothoid', 'exact'):
        for spacing in ('uniform', 'graded'):
            times, noise, ref_ms = cliff_times(
                lambda ld, n, model=model, spacing=spacing: solve_fam(
                    cat, ld, n_arcs=n, arc_model=model, spacing=spacing),
                cases, ns2, ref)
            rows.append(cliff_report(f'Blazer force + moment, {model}, {spacing}', times, noise,
                                     ns2, labels, ref_ms))
    cliff_summary(rows)
    st = [solve_fam(cat, ld, n_arcs=12).status.name for ld in cases]
    print('status of the 18 cases (clothoid, N = 12): ' +
          ', '.join(f'{k} {st.count(k)}' for k in sorted(set(st))))
    print()


def cliff_summary(rows):
    worst = max(rows, key=lambda r: r[1])
    print(f'all within {CLIFF_RATIO:g}x of the median: '
          f'{"yes" if all(ok for ok, _, _ in rows) else "NO"}; medians non-decreasing: '
          f'{sum(v == "yes" for _, _, v in rows)} rows yes, '
          f'{sum(v == "within noise" for _, _, v in rows)} within noise, '
          f'{sum(v == "NO" for _, _, v in rows)} no; largest drop {worst[1] * 100:.1f} %')
    print()


if __name__ == '__main__':
    t = time.perf_counter()
    table_cliffs()
    print(f'bench_fam_cliffs finished in {time.perf_counter() - t:.0f} s')

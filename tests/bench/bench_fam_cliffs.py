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

A drop larger than that coarse noise figure is measured again (``follow_up``): only the two N
concerned, in FOLLOW_ROUNDS paired rounds (every case at both N back to back, the order
alternating), a ratio per round (the cases' paired ratios, ``paired_ratios``), their median and
its sign-test interval. The drop is confirmed ("NO") when the interval lies below 1, cleared
when it lies at or above 1 ("yes") or holds 1 and excludes the coarse drop ("within noise");
an interval that cannot exclude the coarse drop leaves it "NO" (``follow_verdict``).
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


#: cliff checks: N, and the interleaved rounds per group of N. N = 64/65 straddle the
#: dense/banded switches (the fast path's FAST_DENSE_MAX_N and the general path's DENSE_MAX_N,
#: both 64); N = 80/81 straddled the fast path's first switch (80 until commit f3866b8): both
#: take the banded path now, with the same LAPACK calls and steps (package README, round 8)
CLIFF_NS = [1, 2, 4, 8, 12, 16, 24, 32, 48, 64, 65, 80, 81, 100, 200, 500, 1000]
CLIFF_ROUNDS = (9, 3)      # rounds for N <= 100, for N > 100
#: the follow-up of a drop larger than the coarse noise figure: paired rounds of the two N
#: (``paired_ratios``; --quick: a third) and the confidence of the sign-test interval
FOLLOW_ROUNDS = 121
FOLLOW_CONF = 0.95


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


def paired_times(job_a, job_b, n_jobs, rounds, clock=time.process_time):
    """CPU times ta, tb (rounds, n_jobs) of ``job_a(i)`` and ``job_b(i)``, i < n_jobs (the
    cases of a row at two N). Every round runs every i at both, back to back (a burst of load
    hits both sides of a pair alike), a first when r + i is even (``a_first``), else b: in
    every round about half the cases run in each order; the i rotated from round to round. One
    warm-up call of each job first."""
    if n_jobs < 2 or rounds < 1:
        raise ValueError(f'paired_times: n_jobs ({n_jobs}) must be >= 2 (both orders in every '
                         f'round) and rounds ({rounds}) >= 1')
    for i in range(n_jobs):
        job_a(i)
        job_b(i)
    first_a = a_first(rounds, n_jobs)
    ta, tb = np.empty((rounds, n_jobs)), np.empty((rounds, n_jobs))
    for r in range(rounds):
        for s in range(n_jobs):
            i = (s + r) % n_jobs
            af = first_a[r, i]
            first, second = (job_a, job_b) if af else (job_b, job_a)
            c0 = clock()
            first(i)
            c1 = clock()
            second(i)
            c2 = clock()
            ta[r, i], tb[r, i] = (c1 - c0, c2 - c1) if af else (c2 - c1, c1 - c0)
    return ta, tb


def a_first(rounds, n_jobs):
    """(rounds, n_jobs) bool: job a runs first in round r for case i (r + i even)."""
    return (np.arange(rounds)[:, None] + np.arange(n_jobs)[None, :]) % 2 == 0


def paired_ratios(ta, tb):
    """Per-round ratios (rounds,) of ``paired_times``: sqrt(m1 m2), m1 and m2 the medians of
    the cases' ratios tb / ta over the cases where a ran first and where b ran first. The
    second call of a pair runs on caches the first warmed (measured: ~2.5 % cheaper, more than
    the drops in question); a factor on the second call moves m1 and m2 by inverse factors,
    so it cancels in their geometric mean."""
    q = tb / ta
    af = a_first(*q.shape)
    return np.array([math.sqrt(np.median(qr[m]) * np.median(qr[~m]))
                     for qr, m in zip(q, af, strict=True)])


def sign_interval(x, conf=FOLLOW_CONF):
    """Distribution-free confidence interval of the median of the independent samples x: the
    sign test's order statistics x_(l) and x_(n+1-l) (1-based), l the largest with
    P(Binomial(n, 1/2) <= l - 1) <= (1 - conf) / 2. Returns (lo, hi, coverage), coverage =
    1 - 2 P(Binomial(n, 1/2) <= l - 1) >= conf; (-inf, inf, 1.0) when n is too small."""
    if not 0.0 < conf < 1.0:
        raise ValueError(f'sign_interval: conf must be in (0, 1), got {conf}')
    x = np.sort(np.asarray(x, dtype=float).ravel())
    n = x.size
    if n == 0 or not np.all(np.isfinite(x)):
        raise ValueError(f'sign_interval: x must be non-empty and finite, got {n} values')
    alpha = 0.5 * (1.0 - conf)
    cdf, l_ = 0.0, 0
    while l_ < n:
        p = math.comb(n, l_) / 2.0 ** n
        if cdf + p > alpha:
            break
        cdf += p
        l_ += 1
    if l_ == 0:
        return -math.inf, math.inf, 1.0
    return float(x[l_ - 1]), float(x[n - l_]), 1.0 - 2.0 * cdf


def follow_verdict(lo, hi, drop):
    """The verdict on a coarse drop (fraction) from the interval [lo, hi] of the paired ratio
    (larger N over smaller N): ('NO', 'confirmed') when hi < 1; ('yes', 'no drop') when
    lo >= 1; ('within noise', ...) when the interval holds 1 and excludes the coarse drop
    (lo > 1 - drop); else ('NO', 'inconclusive'): the follow-up cannot rule out the drop the
    coarse rounds saw, so it does not clear it."""
    if hi < 1.0:
        return 'NO', 'confirmed'
    if lo >= 1.0:
        return 'yes', 'no drop'
    if lo > 1.0 - drop:
        return 'within noise', 'within noise'
    return 'NO', 'inconclusive'


def median_drops(meds, noise, ns):
    """Every drop of the median in N: for each N_j whose median is below the largest median
    at a smaller N (at N_k), (k, j, 1 - med_j / med_k, noise of the two medians)."""
    out = []
    for j in range(1, len(ns)):
        k = int(np.argmax(meds[:j]))
        d = 1.0 - meds[j] / meds[k]
        if d > 0.0:
            out.append((k, j, d, noise[ns[k]] + noise[ns[j]]))
    return out


def follow_up(title, na, nb, drop, follow):
    """Re-measure the pair (na, nb) of a row (``follow(na, nb)``: the per-round ratios nb / na,
    ``paired_ratios``); returns the verdict and the line printed after the table."""
    ratios = follow(na, nb)
    lo, hi, cov = sign_interval(ratios)
    verdict, what = follow_verdict(lo, hi, drop)
    line = (f'follow-up, {title}, N = {na} -> {nb} (coarse drop {drop * 100:.1f} %): '
            f'{ratios.size} paired rounds, median ratio N = {nb} / N = {na} '
            f'{np.median(ratios):.4f}, {cov * 100:.1f} % sign-test interval {lo:.4f}-{hi:.4f} '
            f'({int(np.sum(ratios < 1.0))} of {ratios.size} rounds below 1): {what} -> {verdict}')
    return verdict, what, line


def cliff_report(title, times, noise, ns, labels, ref_ms, follow=None):
    """One row of the cliff checks: times[n] = per-case CPU ms, noise[n] (fraction).
    follow(na, nb): the paired follow-up of a drop beyond the coarse noise (None: none).
    Returns (every case within CLIFF_RATIO, largest drop, verdict, coarse verdict, follow-up
    lines)."""
    meds = [float(np.median(times[n])) for n in ns]
    ratios = [float(np.max(times[n]) / np.median(times[n])) for n in ns]
    worst = [labels[int(np.argmax(times[n]))] for n in ns]
    # every drop of the median from a smaller N; the row is "NO" when any drop is larger than
    # the noise of its two medians (even vs odd rounds) and its follow-up does not clear it
    drops = median_drops(meds, noise, ns)
    drop, where, nz = 0.0, '', 0.0
    if drops:
        k, j, drop, nz = max(drops, key=lambda t: t[2])
        where = f' (N = {ns[k]} -> {ns[j]})'
    coarse = [('NO' if d > z else 'within noise') for _, _, d, z in drops]
    final, lines, notes = list(coarse), [], []
    if follow is not None:
        for q, (k, j, d, _) in enumerate(drops):
            if coarse[q] == 'NO':
                final[q], what, line = follow_up(title, ns[k], ns[j], d, follow)
                lines.append(line)
                notes.append(f'N = {ns[k]} -> {ns[j]} {d * 100:.1f} % {what}')
    rank = {'yes': 0, 'within noise': 1, 'NO': 2}
    verdict = max(final, key=rank.get, default='yes')
    coarse_v = max(coarse, key=rank.get, default='yes')
    cells = ' | '.join(f'{m:.3f} / {r:.2f}' for m, r in zip(meds, ratios, strict=True))
    ok_ratio = max(ratios) <= CLIFF_RATIO
    smooth = (f'{meds[ns.index(100)] / meds[ns.index(48)]:.2f}'
              if 48 in ns and 100 in ns else '')
    fu = f' (coarse {coarse_v}; follow-up: {", ".join(notes)})' if notes else ''
    print(f'| {title} | {cells} | {max(ratios):.2f} at N = {ns[int(np.argmax(ratios))]} '
          f'({worst[int(np.argmax(ratios))]}) {"ok" if ok_ratio else "OVER " + str(CLIFF_RATIO)} | '
          f'{smooth} | {meds[ns.index(12)] / ref_ms if 12 in ns else float("nan"):.2f} | '
          f'{verdict}{fu}; largest drop {drop * 100:.1f} %{where}, noise {nz * 100:.1f} % |')
    return ok_ratio, drop, verdict, coarse_v, lines


def cliff_header(ns):
    print('| case set, model, spacing | ' + ' | '.join(f'N = {n}' for n in ns) +
          ' | max slowest/median | N = 100 / N = 48 | N = 12 / reference | median '
          'non-decreasing in N (largest drop, noise of the two medians) |')
    print('|---|' + '---|' * (len(ns) + 4))


def follower_of(solve, cases):
    """The follow-up of a row: per-round ratios N = nb / N = na over the row's cases."""
    rounds = max(21, FOLLOW_ROUNDS // 3) if QUICK else FOLLOW_ROUNDS
    return lambda na, nb: paired_ratios(*paired_times(lambda i: solve(cases[i], na),
                                                      lambda i: solve(cases[i], nb),
                                                      len(cases), rounds))


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
          f'interleaved in the same rounds; a drop beyond the noise is followed up (paired '
          f'rounds of its two N, {FOLLOW_CONF * 100:g} % sign-test interval: lines below the '
          f'table). load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores')
    cliff_header(ns)
    sets = [('thesis 40 mm', THESIS, thesis_cases()), ('Blazer 65 mm', BLAZER, blazer_cases())]
    rows = []
    for name, cat, cases in sets:
        labels = [f'case {i}' for i in range(len(cases))]
        for model in MODELS:
            for spacing in ('uniform', 'graded'):
                def solve(ld, n, cat=cat, model=model, spacing=spacing):
                    return solve_fam(cat, ld, n_arcs=n, arc_model=model, spacing=spacing)
                times, noise, ref_ms = cliff_times(solve, cases, ns, ref)
                rows.append(cliff_report(f'{name}, {model}, {spacing}', times, noise, ns, labels,
                                         ref_ms, follower_of(solve, cases)))
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
            def solve(ld, n, model=model, spacing=spacing):
                return solve_fam(cat, ld, n_arcs=n, arc_model=model, spacing=spacing)
            times, noise, ref_ms = cliff_times(solve, cases, ns2, ref)
            rows.append(cliff_report(f'Blazer force + moment, {model}, {spacing}', times, noise,
                                     ns2, labels, ref_ms, follower_of(solve, cases)))
            if (model, spacing) == ('clothoid', 'uniform'):
                follow_control = follower_of(solve, cases)
    cliff_summary(rows)
    # the follow-up's control: N = 80 against itself (identical jobs), every run
    ratios = follow_control(80, 80)
    lo, hi, cov = sign_interval(ratios)
    print(f'control of the follow-up (Blazer force + moment, clothoid, uniform, N = 80 against '
          f'itself: identical jobs, the interval should hold 1 in >= {FOLLOW_CONF * 100:g} % of '
          f'runs): {ratios.size} paired rounds, median ratio {np.median(ratios):.4f}, '
          f'{cov * 100:.1f} % sign-test interval {lo:.4f}-{hi:.4f}: '
          f'{"holds 1" if lo <= 1.0 <= hi else "MISSES 1"}')
    st = [solve_fam(cat, ld, n_arcs=12).status.name for ld in cases]
    print('status of the 18 cases (clothoid, N = 12): ' +
          ', '.join(f'{k} {st.count(k)}' for k in sorted(set(st))))
    print()


def cliff_summary(rows):
    for row in rows:
        for line in row[4]:
            print(line)
    worst = max(rows, key=lambda r: r[1])
    coarse_no = sum(r[3] == 'NO' for r in rows)
    print(f'all within {CLIFF_RATIO:g}x of the median: '
          f'{"yes" if all(r[0] for r in rows) else "NO"}; medians non-decreasing: '
          f'{sum(r[2] == "yes" for r in rows)} rows yes, '
          f'{sum(r[2] == "within noise" for r in rows)} within noise, '
          f'{sum(r[2] == "NO" for r in rows)} no; largest drop {worst[1] * 100:.1f} %; '
          f'coarse "NO" {coarse_no} rows, followed up: '
          f'{sum(r[3] == "NO" and r[2] == "NO" for r in rows)} stay "NO"')
    print()


if __name__ == '__main__':
    t = time.perf_counter()
    table_cliffs()
    print(f'bench_fam_cliffs finished in {time.perf_counter() - t:.0f} s')

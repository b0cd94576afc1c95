"""Benchmark of the FAM solver (fam_solver): run time against error, stress sweep, batch.

    scripts/bench fam            # or: python tests/bench/bench_fam.py [--quick]

Prints three tables:
 1. run time vs error: N in {1..5000}, the three arc models ('clothoid', the default:
    linearly changing curvature per arc; 'exact': circular arcs; 'bezier': the thesis) and
    both arc spacings ('uniform': equal arcs, the default; 'graded': per-case arc lengths
    from the curvature change), tip error (% L) against
    solve_elastica (rtol 1e-12) and median solve time; the reference solver at looser
    tolerances; scipy.integrate.solve_bvp; cases: the thesis flexure (40 mm, EI 7.5e-4 N m^2,
    tip forces and moments) and the Blazer II-XP (65 mm, EI 6e-5 N m^2, 0-0.3 N at 0..pi);
    (the performance-cliff checks of issue 15 are ``bench_fam_cliffs.py``, which
    ``scripts/bench fam`` runs too);
 2. stress: a seeded random sweep of 10 000 load cases (near zero, huge, compressive,
    follower, point forces): non-converged / NaN counts, worst error on a subsample;
 3. batch throughput against a loop of single solves (both models, both spacings).
Times are wall-clock medians (perf_counter) AND process CPU time: the machine is shared,
so wall times are noisy; the load average is printed.
"""
from __future__ import annotations

import math
import os
import pathlib
import sys
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / 'src' / 'fam_solver'))

from scipy.integrate import solve_bvp  # noqa: E402

from fam_solver import Catheter, Loads, Status, solve_elastica, solve_fam, solve_fam_batch  # noqa: E402
from fam_solver.fam import DEFAULT_ARC_MODEL, DEFAULT_SPACING  # noqa: E402

QUICK = '--quick' in sys.argv
THESIS = Catheter(length=0.040, ei=7.5e-4)
BLAZER = Catheter(length=0.065, ei=6.0e-5)
NS = [1, 2, 4, 8, 12, 24, 48, 100, 500, 1000, 5000]
TARGET_ERR = 0.1      # % L at N = 12, F L^2/EI <= 21
TARGET_MS = 0.2       # ms, N = 12 single solve median
THESIS_MS = 3.0       # thesis C++ FAM, N = 12
TARGET_BATCH = 20000  # solves/s
MODELS = ('clothoid', 'exact', 'bezier')
#: % L: below this the comparison measures the reference, not the FAM (solve_elastica at
#: rtol 1e-12 is accurate to ~1e-12 L; clothoid arcs get there by N ~ 1000)
FLOOR = 2e-10
#: the stress table: solves over this many times the median are counted
CLIFF_RATIO = 3.0


def thesis_cases():
    """Tip forces [N] at angles and tip moments [N m] on the 40 mm flexure (alpha <= 21)."""
    out = []
    for F, deg, m in [(1.0, 90, 0.0), (4.0, 60, 0.0), (9.8, 90, 0.0), (5.0, 135, 0.01),
                      (0.0, 0, 0.03), (2.0, -90, 0.02), (6.0, 30, -0.015), (3.0, 170, 0.0)]:
        b = math.radians(deg)
        out.append(Loads(tip_force=(F * math.cos(b), F * math.sin(b)), tip_moment=m))
    return out


def blazer_cases():
    out = []
    for F in (0.1, 0.2, 0.3):
        for b in np.linspace(0.0, np.pi, 5)[1:-1]:   # pi/4, pi/2, 3pi/4 (0 and pi: straight)
            out.append(Loads(tip_force=(F * math.cos(b), F * math.sin(b))))
    return out


def timed(fn, repeat):
    """Median wall and CPU time [s] over `repeat` calls, and the last result. The cliff
    checks use the CPU time (the machine is shared: a wall time includes the other jobs)."""
    walls, cpus = [], []
    res = None
    for _ in range(repeat):
        c0, w0 = time.process_time(), time.perf_counter()
        res = fn()
        walls.append(time.perf_counter() - w0)
        cpus.append(time.process_time() - c0)
    return float(np.median(walls)), float(np.median(cpus)), res


def bvp_solve(cat, loads, tol, guess=None):
    """scipy solve_bvp on the same rod ODE (dead tip load); initial guess: the small-deflection
    beam, or ``guess`` (a Shape: its angles and moments on 21 nodes)."""
    EI, L = cat.ei, cat.length
    fx, fy = loads.tip_force
    m = loads.tip_moment

    def f(s, y):
        th, x, yy, M = y
        return np.vstack([M / EI, np.cos(th), np.sin(th), -(np.cos(th) * fy - np.sin(th) * fx)])

    def bc(ya, yb):
        return np.array([ya[0], ya[1], ya[2], yb[3] - m])

    s = np.linspace(0, L, 21)
    M0 = m + fy * (L - s)
    th0 = np.cumsum(M0 / EI) * (s[1] - s[0])
    y0 = np.vstack([th0, s, np.zeros_like(s), M0])
    if guess is not None:
        sf = s / L
        pts = guess.points_at(sf)
        th = guess.angles_at(sf)
        M = m + fy * (guess.tip[0] - pts[:, 0]) - fx * (guess.tip[1] - pts[:, 1])
        y0 = np.vstack([th, pts[:, 0], pts[:, 1], M])
    sol = solve_bvp(f, bc, s, y0, tol=tol, max_nodes=100000)
    return np.array([sol.y[1, -1], sol.y[2, -1]]), sol.success


def table1():
    print('## 1. Run time against error (tip error in % of L vs solve_elastica rtol=1e-12)')
    print(f'load average: {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores (shared machine: wall '
          'times noisy)')
    sets = [('thesis 40 mm', THESIS, thesis_cases()), ('Blazer 65 mm', BLAZER, blazer_cases())]
    refs = {}
    t_ref = {}
    for name, cat, cases in sets:
        rs, ts = [], []
        for ld in cases:
            w, c, r = timed(lambda cat=cat, ld=ld: solve_elastica(cat, ld), 1)
            assert r.converged, ld
            rs.append(r)
            ts.append(w)
        refs[name] = rs
        t_ref[name] = float(np.median(ts))
        alphas = [ld.load_parameter(cat) for ld in cases]
        print(f'{name}: {len(cases)} cases, load parameter (|F| L^2 + |M| L)/EI up to '
              f'{max(alphas):.1f}; '
              f'reference median {t_ref[name] * 1e3:.1f} ms')
    print()
    hdr = ('| case set | model | spacing | N | max err %L | mean err %L | order | median wall ms '
           '| median cpu ms | vs target 0.2 ms | vs thesis C++ 3 ms | converged |')
    print(hdr)
    print('|' + '---|' * 12)
    summary = {}
    for name, cat, cases in sets:
        for model in MODELS:
            for spacing in ('uniform', 'graded'):
                errs_by_n, ns = [], []
                for n in NS:
                    if QUICK and n > 500:
                        continue
                    rep = 9 if n <= 48 else (3 if n <= 1000 else 1)
                    errs, walls, cpus, conv = [], [], [], 0
                    for ld, ref in zip(cases, refs[name], strict=True):
                        w, c, sh = timed(lambda cat=cat, ld=ld, n=n, model=model,
                                         spacing=spacing: solve_fam(cat, ld, n_arcs=n,
                                                                    arc_model=model,
                                                           spacing=spacing), rep)
                        errs.append(np.max(np.abs(sh.tip - ref.tip)) / cat.length * 100)
                        walls.append(w)
                        cpus.append(c)
                        conv += sh.converged
                    mw, mc = float(np.median(walls)) * 1e3, float(np.median(cpus)) * 1e3
                    # observed order between this N and the previous one (2 = second order)
                    order = (math.log(errs_by_n[-1] / max(errs)) / math.log(n / ns[-1])
                             if errs_by_n else float('nan'))
                    errs_by_n.append(max(errs))
                    ns.append(n)
                    summary[(name, model, spacing, n)] = (max(errs), mw, mc)
                    print(f'| {name} | {model} | {spacing} | {n} | {max(errs):.2e} | '
                          f'{np.mean(errs):.2e} | '
                          f'{order:.2f} | {mw:.3f} | {mc:.3f} | {mw / TARGET_MS:.2f}x | '
                          f'{mw / THESIS_MS:.3f}x | '
                          f'{conv}/{len(cases)} |')
                mono = all(a > b or max(a, b) < FLOOR
                           for a, b in zip(errs_by_n[:-1], errs_by_n[1:], strict=True))
                floor = [n for n, e in zip(ns, errs_by_n, strict=True) if e < FLOOR]
                note = (f' (from N = {floor[0]} below {FLOOR:g} % L: the reference\'s own accuracy)'
                        if floor else '')
                print(f'| {name} | {model} | {spacing} | error falls monotonically with N up to '
                      f'{ns[-1]}: {"yes" if mono else "NO"}{note} |')
    print()
    print('### reference solver (shooting, DOP853) at looser tolerances, and scipy solve_bvp')
    print('| case set | solver | tolerance | max err %L | median wall ms | converged |')
    print('|---|---|---|---|---|---|')
    for name, cat, cases in sets:
        for rtol in (1e-4, 1e-6, 1e-8, 1e-10):
            errs, walls, conv = [], [], 0
            for ld, ref in zip(cases, refs[name], strict=True):
                w, c, r = timed(lambda cat=cat, ld=ld,
                                rtol=rtol: solve_elastica(cat, ld, rtol=rtol), 1)
                errs.append(np.max(np.abs(r.tip - ref.tip)) / cat.length * 100)
                walls.append(w)
                conv += r.converged
            print(f'| {name} | solve_elastica | rtol {rtol:.0e} | {max(errs):.2e} | '
                  f'{np.median(walls) * 1e3:.2f} | {conv}/{len(cases)} |')
        for tol in (1e-3, 1e-6, 1e-8):
            errs, walls, conv = [], [], 0
            for ld, ref in zip(cases, refs[name], strict=True):
                w, c, (tip, ok) = timed(lambda cat=cat, ld=ld, tol=tol: bvp_solve(cat, ld, tol), 1)
                errs.append(np.max(np.abs(tip - ref.tip)) / cat.length * 100)
                walls.append(w)
                conv += ok
            print(f'| {name} | scipy solve_bvp (small-deflection guess) | tol {tol:.0e} | '
                  f'{max(errs):.2e} | {np.median(walls) * 1e3:.2f} | {conv}/{len(cases)} |')
        for tol in (1e-3, 1e-6, 1e-8):
            errs, walls, conv = [], [], 0
            for ld, ref in zip(cases, refs[name], strict=True):
                g = solve_fam(cat, ld, n_arcs=12)
                w, c, (tip, ok) = timed(lambda cat=cat, ld=ld, tol=tol,
                                        g=g: bvp_solve(cat, ld, tol, guess=g), 1)
                errs.append(np.max(np.abs(tip - ref.tip)) / cat.length * 100)
                walls.append(w)
                conv += ok
            print(f'| {name} | scipy solve_bvp (FAM N=12 guess, time excl. FAM) | tol {tol:.0e} | '
                  f'{max(errs):.2e} | {np.median(walls) * 1e3:.2f} | {conv}/{len(cases)} |')
    print()
    print(f'### N = 12 against the targets (defaults: arc_model {DEFAULT_ARC_MODEL}, spacing '
          f'{DEFAULT_SPACING})')
    print('| what | this project | target / reference | ratio |')
    print('|---|---|---|---|')
    for name, cat, cases in sets:
        for model in MODELS:
            for spacing in ('uniform', 'graded'):
                e, w, c = summary[(name, model, spacing, 12)]
                k = f'{name} {model} {spacing}'
                print(f'| {k}: max tip error | {e:.3f} % L | {TARGET_ERR} % L | '
                      f'{e / TARGET_ERR:.2f} |')
                print(f'| {k}: median solve (wall) | {w:.3f} ms | {TARGET_MS} ms | '
                      f'{w / TARGET_MS:.2f} |')
                print(f'| {k}: median solve (cpu) | {c:.3f} ms | {TARGET_MS} ms | '
                      f'{c / TARGET_MS:.2f} |')
                print(f'| {k}: vs reference in this run | {w:.3f} ms | solve_elastica '
                      f'{t_ref[name] * 1e3:.1f} ms | {w / (t_ref[name] * 1e3):.4f} |')
        for spacing in ('uniform', 'graded'):
            for n in (16, 20):
                e = max(np.max(np.abs(solve_fam(cat, ld, n_arcs=n, spacing=spacing,
                                                arc_model='exact').tip - r.tip)) / cat.length * 100
                        for ld, r in zip(cases, refs[name], strict=True))
                print(f'| {name} exact {spacing}: max tip error at N = {n} | {e:.3f} % L | '
                      f'{TARGET_ERR} % L | '
                      f'{e / TARGET_ERR:.2f} |')
    print()
    print('### N = 12 per case, tip error % L: circular arcs uniform -> graded, clothoid arcs '
          'uniform')
    print('| case set | tip force N | tip moment N m | F L^2/EI | exact uniform | exact graded | '
          'graded / uniform | clothoid uniform | clothoid / exact graded |')
    print('|---|---|---|---|---|---|---|---|---|')
    for name, cat, cases in sets:
        for ld, ref in zip(cases, refs[name], strict=True):
            eu, eg, ec = (np.max(np.abs(solve_fam(cat, ld, n_arcs=12, spacing=sp, arc_model=md).tip
                                        - ref.tip)) / cat.length * 100
                          for md, sp in (('exact', 'uniform'), ('exact', 'graded'),
                                         ('clothoid', 'uniform')))
            fx, fy = ld.tip_force
            nan = float('nan')
            print(f'| {name} | ({fx:.3f}, {fy:.3f}) | {ld.tip_moment:g} | '
                  f'{ld.load_parameter(cat):.1f} | '
                  f'{eu:.4f} | {eg:.4f} | {eg / eu if eu > 0 else nan:.2f} | {ec:.2e} | '
                  f'{ec / eg if eg > 0 else nan:.3f} |')
    print()


def table1b():
    print('### thesis Study II: 504 mm catheter, three point forces (0.463 N at s=0.165, '
          '-0.065 N at 0.577, 0.007 N at 0.968)')
    area_moment = math.pi / 64 * (2.14 ** 4 - 1.56 ** 4) * 1e-12   # OD 2.14 mm, wall 0.29 mm
    cat = Catheter(0.504, 1592.3e6 * area_moment)
    ld = Loads(point_forces=((0.165, 0.0, 0.463), (0.577, 0.0, -0.065), (0.968, 0.0, 0.007)))
    w, c, ref = timed(lambda: solve_elastica(cat, ld), 1)
    print(f'EI = {cat.ei:.4g} N m^2; reference tip ({ref.tip[0] * 1e3:.2f}, '
          f'{ref.tip[1] * 1e3:.2f}) mm '
          f'in {w * 1e3:.0f} ms')
    print('| model | spacing | N | tip error mm | tip error %L | median wall ms | median cpu ms | '
          'thesis (C++, vs experiment) |')
    print('|---|---|---|---|---|---|---|---|')
    for model in ('clothoid', 'exact'):
        for spacing in ('uniform', 'graded'):
            for n in (12, 24, 48, 100, 500):
                w, c, sh = timed(lambda n=n, spacing=spacing,
                                 model=model: solve_fam(cat, ld, n_arcs=n, spacing=spacing,
                                                   arc_model=model), 5)
                e = float(np.max(np.abs(sh.tip - ref.tip)))
                print(f'| {model} | {spacing} | {n} | {e * 1e3:.4f} | {e / cat.length * 100:.5f} | '
                      f'{w * 1e3:.2f} | {c * 1e3:.2f} | 7 ms, 1.41 +- 1.47 mm |')
    print()


def random_cases(rng, count):
    """Seeded stress cases on a unit catheter (L = 1, EI = 1: loads are alpha directly)."""
    kinds = ['near_zero', 'huge', 'compressive', 'follower', 'point_forces', 'moment_mix']
    out = []
    for i in range(count):
        k = kinds[i % len(kinds)]
        ang = rng.uniform(-np.pi, np.pi)
        if k == 'near_zero':
            a = 10 ** rng.uniform(-14, -4)
            ld = Loads(tip_force=(a * np.cos(ang), a * np.sin(ang)), tip_moment=a * rng.normal())
        elif k == 'huge':
            a = rng.uniform(21, 50)
            ld = Loads(tip_force=(a * np.cos(ang), a * np.sin(ang)))
        elif k == 'compressive':
            a = rng.uniform(0, 50)
            b = np.pi + rng.normal(0, 0.3)
            ld = Loads(tip_force=(a * np.cos(b), a * np.sin(b)),
                       tip_moment=rng.choice([0.0, rng.normal(0, 0.5)]))
        elif k == 'follower':
            a = rng.uniform(0, 8)
            ld = Loads(tip_force=(a * np.cos(ang), a * np.sin(ang)), follower=True,
                       tip_moment=rng.normal(0, 1))
        elif k == 'point_forces':
            f = rng.normal(0, 5, (3, 2))
            ld = Loads(tip_force=tuple(rng.normal(0, 2, 2)),
                       point_forces=((0.165, *f[0]), (0.577, *f[1]), (0.968, *f[2])))
        else:
            a = rng.uniform(0, 21)
            ld = Loads(tip_force=(a * np.cos(ang), a * np.sin(ang)), tip_moment=rng.uniform(-5, 5))
        out.append((k, ld))
    return out


def table2():
    rng = np.random.default_rng(20261125)
    count = 2000 if QUICK else 10000
    cases = random_cases(rng, count)
    sub = rng.choice(count, 60 if QUICK else 240, replace=False)
    cat = Catheter(1.0, 1.0)
    refs = {}
    for i in sub:
        ref = solve_elastica(cat, cases[i][1])
        refs[i] = ref if ref.converged else None
    for model, spacing in (('clothoid', 'uniform'), ('exact', 'uniform'), ('exact', 'graded')):
        stress_table(cases, sub, refs, spacing, model)


def stress_table(cases, sub, refs, spacing, model):
    print(f'## 2. Stress: seeded random sweep (N = 12, {model} model, {spacing} arcs, unit '
          'catheter '
          f'L = 1, EI = 1)')
    count = len(cases)
    cat = Catheter(1.0, 1.0)
    stats = {}
    t0 = time.perf_counter()
    shapes = []
    for k, ld in cases:
        c0 = time.process_time()
        sh = solve_fam(cat, ld, n_arcs=12, spacing=spacing, arc_model=model)
        cpu = time.process_time() - c0
        shapes.append(sh)
        s = stats.setdefault(k, dict(n=0, nonconv=0, nan=0, unstable=0, snap=0, maxit=0, t=[]))
        s['t'].append(cpu * 1e3)
        s['n'] += 1
        s['nonconv'] += not sh.converged
        s['nan'] += not (np.all(np.isfinite(sh.arc_angles)) and np.all(np.isfinite(sh.tip)))
        s['unstable'] += not sh.stable
        s['snap'] += sh.status == Status.SNAP_THROUGH
        s['maxit'] = max(s['maxit'], sh.iterations)
    wall = time.perf_counter() - t0
    # reference comparison on a subsample of stable, converged cases
    worst, errs = {}, {}
    for i in sub:
        k, ld = cases[i]
        sh = shapes[i]
        ref = refs[i]
        if not (sh.converged and sh.stable) or ref is None:
            continue
        e = float(np.max(np.abs(sh.tip - ref.tip))) * 100
        errs.setdefault(k, []).append(e)
        if e > worst.get(k, (-1, None))[0]:
            worst[k] = (e, ld.load_parameter(cat))
    print(f'{count} cases in {wall:.1f} s wall ({wall / count * 1e3:.2f} ms per solve incl. '
          'continuation fallbacks)')
    med_all = float(np.median(np.concatenate([s['t'] for s in stats.values()])))
    print(f'CPU time per solve: median {med_all:.3f} ms over all kinds; per kind the median, and '
          'how many '
          f'solves took over {CLIFF_RATIO:g}x the overall median')
    print('| kind | cases | non-converged | NaN | flagged unstable | snap-through | max iterations '
          '| worst tip error %L (subsample) | at load parameter | mean tip error %L (subsample) | '
          'median cpu ms | over 3x median |')
    print('|---|---|---|---|---|---|---|---|---|---|---|---|')
    tot = dict(n=0, nonconv=0, nan=0, unstable=0, snap=0)
    for k, s in stats.items():
        e, a = worst.get(k, (float('nan'), float('nan')))
        me = float(np.mean(errs[k])) if errs.get(k) else float('nan')
        t = np.array(s['t'])
        print(f'| {k} | {s["n"]} | {s["nonconv"]} | {s["nan"]} | {s["unstable"]} | {s["snap"]} | '
              f'{s["maxit"]} | '
              f'{e:.3f} | {a:.1f} | {me:.4f} | {np.median(t):.3f} | '
              f'{int(np.sum(t > CLIFF_RATIO * med_all))} |')
        for key in tot:
            tot[key] += s[key]
    print(f'| total | {tot["n"]} | {tot["nonconv"]} (target 0) | {tot["nan"]} (target 0) | '
          f'{tot["unstable"]} | {tot["snap"]} | | | | |')
    print('(errors at N = 12 are discretisation errors; they grow with the load parameter, up to '
          '50 here)')
    print()


def table3():
    print('## 3. Batch throughput (Blazer, N = 12; tip forces 0-0.3 N at 0..pi)')
    rng = np.random.default_rng(7)
    B = 4000 if QUICK else 20000
    mag = rng.uniform(0, 0.3, B)
    ang = rng.uniform(0, np.pi, B)
    F = np.stack([mag * np.cos(ang), mag * np.sin(ang)], axis=1)
    print('| model | spacing | what | this project | reference in this run | target | ratio to '
          'target |')
    print('|---|---|---|---|---|---|---|')
    for model in ('clothoid', 'exact'):
        for spacing in ('uniform', 'graded'):
            w, c, bt = timed(lambda spacing=spacing,
                             model=model: solve_fam_batch(BLAZER, F, n_arcs=12, spacing=spacing,
                                                     arc_model=model), 1)
            nloop = 1000 if QUICK else 3000
            w0, c0 = time.perf_counter(), time.process_time()
            tips = np.array([solve_fam(BLAZER, Loads(tip_force=F[i]), n_arcs=12, spacing=spacing,
                                       arc_model=model).tip for i in range(nloop)])
            wl, cl = time.perf_counter() - w0, time.process_time() - c0
            diff = np.max(np.abs(tips - bt.tips[:nloop]))
            k = f'{model} | {spacing}'
            print(f'| {k} | batch solves/s (wall) | {B / w:,.0f} | single-solve loop '
                  f'{nloop / wl:,.0f}/s | '
                  f'{TARGET_BATCH:,} | {B / w / TARGET_BATCH:.2f} |')
            print(f'| {k} | batch solves/s (cpu) | {B / c:,.0f} | single-solve loop '
                  f'{nloop / cl:,.0f}/s | '
                  f'{TARGET_BATCH:,} | {B / c / TARGET_BATCH:.2f} |')
            print(f'| {k} | batch converged | {int(bt.converged.sum())}/{B} | max |batch - single| '
                  'tip '
                  f'{diff:.1e} m | all | |')
    print()


if __name__ == '__main__':
    t = time.perf_counter()
    table1()
    table1b()
    table2()
    table3()
    print(f'bench_fam finished in {time.perf_counter() - t:.0f} s')

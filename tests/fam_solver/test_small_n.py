"""Issue 15, round 6: few arcs (N <= 4) cost no more than more arcs. The Newton step's Jacobian
built in Python floats for N <= SMALL_N equals the array form (which the kernel tests check
against central differences and the general path), and the graded second pass's curvature
start reaches the same equilibrium as the remapped start, in fewer Newton iterations (counted:
the timing is ``tests/bench/bench_fam_cliffs.py``)."""
import math

import numpy as np
import pytest

from fam_solver import Catheter, Loads, fast, fast_bezier, fast_newton, mesh
from fam_solver import solve_fam, solve_fam_batch

BLAZER = Catheter(length=0.065, ei=6e-5)
THESIS = Catheter(length=0.040, ei=7.5e-4)
#: the cliff bench's load sets (tests/bench/bench_fam.py), tip forces with and without moments
BENCH = [(THESIS, Loads(tip_force=(F * math.cos(math.radians(d)), F * math.sin(math.radians(d))),
                        tip_moment=m))
         for F, d, m in [(1.0, 90, 0.0), (4.0, 60, 0.0), (9.8, 90, 0.0), (5.0, 135, 0.01),
                         (2.0, -90, 0.02), (6.0, 30, -0.015), (3.0, 170, 0.0)]] + \
        [(BLAZER, Loads(tip_force=(F * math.cos(b), F * math.sin(b))))
         for F in (0.1, 0.2, 0.3) for b in (math.pi / 4, math.pi / 2, 3 * math.pi / 4)]


def _case(rng, n, force=3.0):
    l = rng.uniform(0.2, 1.0, n)
    w = l / rng.uniform(0.5, 2.0)
    return l, w, complex(*rng.normal(0, force, 2)), float(rng.normal(0, 1))


@pytest.mark.parametrize('n', [1, 2, 3, 4])
@pytest.mark.parametrize('follower', [False, True])
@pytest.mark.parametrize('clothoid', [False, True])
def test_small_jacobian_equals_the_array_form(n, follower, clothoid, monkeypatch):
    """The residual, tip and rates, the Jacobian (far from and near a solution: clothoid arcs
    with and without the rates' terms) and the Newton iterates equal those of the array form
    to rounding."""
    K = fast_newton.SMALL_N
    assert K >= 4
    # both Jacobians compared, with and without the rates' terms: the shipped setting adds the
    # terms at every step on N <= SMALL_N (_QUASI_MIN_N), so only a lower switch reaches the
    # circular-arc factors of the Python-float form
    monkeypatch.setattr(fast_newton, '_QUASI_MIN_N', 3)
    rng = np.random.default_rng(10 * n + 2 * follower + clothoid)
    terms_seen = set()
    for trial in range(6):
        l, w, F, m = _case(rng, n)
        sol = fast_newton.fast_tip_newton(n, l, w, F, m, follower, np.zeros(n), 40,
                                          clothoid=clothoid)
        far = trial < 3 or not sol[1]
        phi = rng.normal(0, 0.8, n) if far else sol[0] + rng.normal(0, 1e-4, n)
        out = {}
        for small in (K, 0):
            monkeypatch.setattr(fast_newton, 'SMALL_N', small)
            J = fast_newton.jacobian_at(phi, l, w, F, m, follower, clothoid)
            it = fast_newton.fast_tip_newton(n, l, w, F, m, follower, phi, 3, rtol=0.0,
                                             clothoid=clothoid)
            out[small] = (J, it[0])
            out[small] += fast_newton.fast_tip_newton(n, l, w, F, m, follower, phi, 0,
                                                      clothoid=clothoid)[3:]
        (J1, p1, r1, tip1, _, rho1), (J0, p0, r0, tip0, _, rho0) = out[K], out[0]
        assert np.max(np.abs(J1 - J0)) <= 1e-14 * max(1.0, np.max(np.abs(J0)))
        assert np.max(np.abs(p1 - p0)) <= 1e-12 * max(1.0, np.max(np.abs(p0)))
        # the residual, the tip and the clothoid rates at phi
        assert abs(r1 - r0) <= 1e-15 * max(1.0, r0) and abs(tip1 - tip0) <= 1e-15
        assert (rho0 is None) == (rho1 is None) == (not clothoid)
        assert clothoid is False or np.max(np.abs(rho1 - rho0)) <= 1e-15
        terms_seen.add(clothoid and (r0 < fast_newton.QUASI_ABOVE or n < fast_newton._QUASI_MIN_N))
    if clothoid and n >= 3:
        assert terms_seen == {False, True}


@pytest.mark.parametrize('n', [1, 2, 3, 4])
@pytest.mark.parametrize('follower', [False, True])
def test_small_bezier_step_equals_the_array_form(n, follower, monkeypatch):
    """The Bezier kernel's dense Jacobian and iterates (the scaled residual's step, and the
    plain one where the scale s is small: long arcs) equal those of the array form."""
    K = fast_bezier.SMALL_N
    assert K >= 4
    rng = np.random.default_rng(20 * n + follower)
    scaled = []
    orig = fast_bezier._small_step

    def spy(*a, **k):
        out = orig(*a, **k)
        scaled.append(None if out is None else out[4])
        return out
    for trial in range(12):
        l, w, F, m = _case(rng, n, 10.0)       # large forces: the scale s is small on some
        phi = rng.normal(0, 0.8, n) if trial < 6 else rng.uniform(2.5, 4.8, n)
        out = {}
        for small in (K, 0):
            monkeypatch.setattr(fast_bezier, 'SMALL_N', small)
            monkeypatch.setattr(fast_bezier, '_small_step', spy)
            a = fast_bezier.bezier_tip_newton(n, l, w, F, m, follower, phi, 1, math.inf, -1.0)
            b = fast_bezier.bezier_tip_newton(n, l, w, F, m, follower, phi, 3, math.inf, 0.0)
            out[small] = a[5], b[0]
        (J1, p1), (J0, p0) = out[K], out[0]
        assert J0 is not None and J1 is not None
        assert np.max(np.abs(J1 - J0)) <= 1e-13 * max(1.0, np.max(np.abs(J0)))
        assert np.max(np.abs(p1 - p0)) <= 1e-11 * max(1.0, np.max(np.abs(p0)))
    assert True in scaled and False in scaled


def test_curvature_start_is_exact_for_a_linear_curvature():
    """Equal-arc angles of a curvature linear in s (the small-deflection FAM under a tip
    load): the start on any arcs is each arc's length times the curvature at its midpoint."""
    rng = np.random.default_rng(5)
    for n in (2, 3, 7, 40):
        a, b = rng.normal(size=2)
        phi = (a + b * (np.arange(n) + 0.5) / n) / n
        f = rng.uniform(0.2, 1.0, n)
        f /= f.sum()
        ends = np.concatenate([[0.0], np.cumsum(f)])
        ends[-1] = 1.0
        s = mesh.curvature_start(phi, ends, f)
        ref = f * (a + b * 0.5 * (ends[1:] + ends[:-1]))
        assert np.max(np.abs(s - ref)) < 1e-14
        # remap (the tangent angle linear in each equal arc) is off by O(1/n) relative
        r = mesh.remap(phi[None], f[None])[0]
        assert np.max(np.abs(r - ref)) > 1e-3 * np.max(np.abs(ref)) or n > 7


def _local_cubic_reference(phi, x):
    """Theta at x (fractions of L) by numpy's polyfit through the four equal-arc ends nearest
    each x's arc (one-sided at the first and last arc; N = 2: the parabola through all
    three): an independent reference for mesh.cubic_start."""
    n = phi.size
    Th = np.concatenate([[0.0], np.cumsum(phi)])
    nodes = np.arange(n + 1) / n
    out = np.empty(x.size)
    for i, xi in enumerate(x):
        k = min(int(xi * n), n - 1)
        lo = min(max(k - 1, 0), max(n - 3, 0))
        sel = slice(lo, min(lo + 4, n + 1))
        out[i] = np.polyfit((nodes[sel] - xi) * n, Th[sel], sel.stop - sel.start - 1)[-1]
    return out


def test_cubic_start_matches_local_cubic_interpolation_and_is_exact_for_a_cubic_theta():
    """mesh.cubic_start: each new arc's angle is the difference of the tangent angle at its
    ends, interpolated by the cubic through the four nearest equal-arc ends (polyfit
    reference); a cubic tangent angle (a parabola for N = 2) is reproduced exactly; for a
    smooth tangent angle the error falls ~16x per halving of the arcs (fourth order), remap's
    ~4x (second order)."""
    rng = np.random.default_rng(11)
    for n in (2, 3, 4, 7, 40):
        phi = rng.normal(size=n) / n
        f = rng.uniform(0.2, 1.0, n)
        f /= f.sum()
        ends = np.concatenate([[0.0], np.cumsum(f)])
        ends[-1] = 1.0
        s = mesh.cubic_start(phi, np.cumsum(phi), ends)
        assert np.max(np.abs(s - np.diff(_local_cubic_reference(phi, ends)))) < 1e-13, n
        c = rng.normal(size=4) if n > 2 else np.r_[0.0, rng.normal(size=3)]
        Th = np.polyval(c, np.arange(n + 1) / n) - np.polyval(c, 0.0)
        s = mesh.cubic_start(np.diff(Th), Th[1:], ends)
        ref = np.diff(np.polyval(c, ends))
        assert np.max(np.abs(s - ref)) < 1e-13, n
    err = {'cubic': [], 'remap': []}
    for n in (8, 16, 32):
        nodes = np.arange(n + 1) / n
        Th = np.sin(2.0 * nodes) + 0.3 * nodes ** 2
        f = np.diff(np.linspace(0.0, 1.0, n + 1) ** 1.5)
        ends = np.concatenate([[0.0], np.cumsum(f)])
        ends[-1] = 1.0
        ref = np.diff(np.sin(2.0 * ends) + 0.3 * ends ** 2)
        err['cubic'].append(np.max(np.abs(mesh.cubic_start(np.diff(Th), Th[1:], ends) - ref)))
        err['remap'].append(np.max(np.abs(mesh.remap(np.diff(Th)[None], f[None])[0] - ref)))
    for a, b in zip(err['cubic'][:-1], err['cubic'][1:], strict=True):
        assert 10.0 < a / b < 40.0, err
    for a, b in zip(err['remap'][:-1], err['remap'][1:], strict=True):
        assert 2.5 < a / b < 6.0, err


def test_fast_grade_rejects_an_unknown_start():
    with pytest.raises(ValueError, match='start'):
        mesh.fast_grade(np.array([0.1, 0.2]), 0.5j, False, 'quadratic')


@pytest.mark.parametrize('model', ['exact', 'bezier', 'clothoid'])
def test_graded_pass_from_the_cubic_start_same_equilibrium_fewer_iterations(model):
    """On the cliff bench's loads, N = 2 to 64: the second pass from the cubic start (the
    shipped one), from the curvature start (round 6's, circular and Bezier arcs up to N = 16)
    and from the remapped start (round 6's otherwise) end at the same equilibrium; from the
    cubic start it takes fewer Newton iterations in all than from remap at every N, and than
    from the curvature start summed over the N (measured in round 7: e.g. exact arcs
    N = 8: 33 / 39 / 45, clothoid N = 64: 16 / 32 / 33; Bezier N = 3: 46 / 45 / 50)."""
    bz, cl = model == 'bezier', model == 'clothoid'
    total = {'cubic': 0, 'curvature': 0, 'remap': 0}
    for n in (2, 3, 4, 8, 16, 32, 64):
        its = {k: 0 for k in total}
        for cat, ld in BENCH:
            F = complex(*ld.tip_force)
            eq = solve_fam(cat, ld, n_arcs=n, arc_model=model)
            sols = {}
            for st in its:
                f, start = mesh.fast_grade(eq.arc_angles, F, False, st)
                lg = cat.length * f
                p, conv, it = fast_newton.fast_tip_newton(n, lg, lg / cat.ei, F, ld.tip_moment,
                                                          False, start, 12, bezier=bz,
                                                          clothoid=cl)[:3]
                assert conv
                sols[st] = p
                its[st] += it
            for st in ('cubic', 'curvature'):
                assert np.max(np.abs(sols[st] - sols['remap'])) < 1e-11, (n, ld, st)
        assert its['cubic'] < its['remap'], (n, its)
        for k in total:
            total[k] += its[k]
    assert total['cubic'] < total['curvature'], total


@pytest.mark.parametrize('model', ['exact', 'bezier', 'clothoid'])
@pytest.mark.parametrize('n', [2, 3, 4, 8])
def test_few_graded_arcs_single_equals_batch(model, n):
    """The fast path (curvature start, Python-float Jacobian) and the batch's general path
    (remapped start, array Jacobian) give the same graded arcs and shape. To ~1e-10 L, not
    1e-12 as at N = 12: the first pass stops at 1e-9 (it only places the arcs), and with few
    arcs the graded solution moves more with the arcs (measured before this round on these
    loads: arc lengths up to 8.9e-11 L apart at N = 3, tips 6.5e-12 L; unchanged by it)."""
    cases = [ld for cat, ld in BENCH if cat is BLAZER]
    F = np.array([ld.tip_force for ld in cases])
    M = np.array([ld.tip_moment for ld in cases])
    bt = solve_fam_batch(BLAZER, F, M, n_arcs=n, arc_model=model, spacing='graded')
    assert bt.converged.all()
    for b, ld in enumerate(cases):
        sh = solve_fam(BLAZER, ld, n_arcs=n, arc_model=model, spacing='graded')
        assert sh.converged and np.ptp(sh.arc_lengths) > 0.1 * BLAZER.length / n
        assert np.max(np.abs(sh.arc_lengths - bt.arc_lengths[b])) < 2e-10 * BLAZER.length
        assert np.max(np.abs(sh.tip - bt.tips[b])) < 2e-11 * BLAZER.length


def test_the_small_paths_are_taken_up_to_small_n_only():
    """N <= SMALL_N uses the Python-float Jacobian, N = SMALL_N + 1 the array form (the
    switch both kernels document)."""
    calls = []
    orig = fast_newton._small_jacobian
    orig_b = fast_bezier._small_step

    def spy(*a, **k):
        calls.append(len(a[3]))
        return orig(*a, **k)

    def spy_b(*a, **k):
        calls.append(len(a[8]))
        return orig_b(*a, **k)
    fast_newton._small_jacobian, fast_bezier._small_step = spy, spy_b
    try:
        for model in ('exact', 'clothoid', 'bezier'):
            for n in (fast_newton.SMALL_N, fast_newton.SMALL_N + 1):
                calls.clear()
                sh = solve_fam(BLAZER, Loads(tip_force=(0.1, 0.2)), n_arcs=n, arc_model=model)
                assert sh.converged
                assert bool(calls) == (n <= fast_newton.SMALL_N), (model, n)
    finally:
        fast_newton._small_jacobian, fast_bezier._small_step = orig, orig_b
    assert fast.FAST_DENSE_MAX_N >= fast_newton.SMALL_N == fast_bezier.SMALL_N


def test_graded_solves_take_the_cubic_start_between_its_bounds(monkeypatch):
    """solve_fam's second pass starts from the cubic start on fast._CUBIC_MIN_N (clothoid arcs:
    3) to fast._CUBIC_MAX_N arcs, from the curvature start on fewer (on 2 the same parabola)
    and from remap on more (package README, round 7)."""
    seen = []
    orig = fast.fast_grade

    def spy(phi, F, follower, start='remap'):
        seen.append(start)
        return orig(phi, F, follower, start)
    monkeypatch.setattr(fast, 'fast_grade', spy)
    lo, top = fast._CUBIC_MIN_N, fast._CUBIC_MAX_N
    assert 3 < lo < top
    for model in ('exact', 'bezier', 'clothoid'):
        cl = model == 'clothoid'
        for n, want in ((2, 'curvature'), (3, 'cubic' if cl else 'curvature'),
                        (lo - 1, 'cubic' if cl else 'curvature'), (lo, 'cubic'), (top, 'cubic'),
                        (top + 1, 'remap'), (100, 'remap')):
            seen.clear()
            sh = solve_fam(BLAZER, Loads(tip_force=(0.1, 0.2)), n_arcs=n, arc_model=model,
                           spacing='graded')
            assert sh.converged and seen == [want], (model, n, seen)


# -- round 10 (issue 15): the graded N = 4 -> 8 drop. At N <= 8 a graded solve costs about its
# residual evaluations and Newton steps, each about as dear at N = 4 as at 8; N = 4's second pass
# starts ~10x farther from its solution (the 4-arc graded mesh differs more from the equal one)
# and took more steps: on clothoid arcs a first step without the rates' terms (max|r| above
# QUASI_ABOVE) that converged only linearly; and its grading's ~30 numpy calls cost about a step.

@pytest.mark.parametrize('spacing', ['graded', 'uniform'])
def test_rates_terms_from_the_first_step_on_few_arcs_save_iterations(spacing, monkeypatch):
    """Clothoid arcs, N = 3-4 (_QUASI_MIN_N = 5): the rates' terms at every step reach the
    same solutions as the switch at N = 3 did (the circular-arc factors far from a solution),
    in fewer iterations on the cliff bench's loads (measured, round 10: graded 46 -> 40 and
    62 -> 53 at N = 3, 43 -> 41 and 58 -> 53 at N = 4, thesis / Blazer; uniform fewer at N = 3
    only), never more per set and N."""
    shipped = fast_newton._QUASI_MIN_N
    assert shipped == fast_newton.SMALL_N + 1
    total = {shipped: 0, 3: 0}
    for n in (3, 4):
        its = {}
        tips = {}
        for q in (shipped, 3):
            monkeypatch.setattr(fast_newton, '_QUASI_MIN_N', q)
            its[q] = {id(THESIS): 0, id(BLAZER): 0}
            tips[q] = []
            for cat, ld in BENCH:
                sh = solve_fam(cat, ld, n_arcs=n, arc_model='clothoid', spacing=spacing)
                assert sh.converged
                its[q][id(cat)] += sh.iterations
                tips[q].append(sh.tip / cat.length)
        q5, q3 = its[shipped], its[3]
        assert all(q5[k] <= q3[k] for k in q5), (n, its)
        assert spacing == 'uniform' or sum(q5.values()) < sum(q3.values()), (n, its)
        assert np.max(np.abs(np.array(tips[shipped]) - np.array(tips[3]))) < 1e-11
        total[shipped] += sum(q5.values())
        total[3] += sum(q3.values())
    assert total[shipped] < total[3], total


def test_graded_second_pass_on_four_clothoid_arcs_converges_quadratically():
    """The graded second pass at N = 4 on the Blazer loads: from its start (max|r| above
    QUASI_ABOVE on 6 of the 9) Newton with the rates' terms takes at most 3 iterations per load
    (before round 10: 4 on three loads, a first step without the terms reducing max|r| by
    only 3-6x), and 25 in all (27 before)."""
    total = 0
    for cat, ld in BENCH:
        if cat is not BLAZER:
            continue
        F = complex(*ld.tip_force)
        l, w, _ = fast._equal_arcs(4, cat.length, cat.ei)
        eq = fast.fast_solve(4, cat.length, cat.ei, F, 0.0, False, clothoid=True, rtol=1e-9)
        f, start = mesh.fast_grade(eq[0], F, False, fast._graded_start(4, True))
        lg = cat.length * f
        p, conv, it = fast_newton.fast_tip_newton(4, lg, lg / cat.ei, F, 0.0, False, start, 12,
                                                  clothoid=True)[:3]
        assert conv and it <= 3, (ld, it)
        total += it
    assert total <= 25


@pytest.mark.parametrize('n', [1, 2, 3, 4])
def test_small_grade_equals_the_array_form(n):
    """fast_grade in Python floats (N <= SMALL_GRADE_N) gives the array form's fractions and
    starts (every start, dead and follower forces, tiny to large angles) to rounding."""
    rng = np.random.default_rng(40 + n)
    for trial in range(150):
        phi = rng.normal(0, [1e-9, 0.05, 0.5, 2.0][trial % 4], n)
        F = complex(*rng.normal(0, 1, 2)) * 10.0 ** rng.integers(-3, 3)
        follower = bool(trial % 3 == 0)
        for st in ('remap', 'curvature', 'cubic'):
            f1, s1 = mesh._small_grade(phi, F, follower, st)
            f2, s2 = mesh._array_grade(phi, F, follower, st)
            assert f1.shape == s1.shape == (n,)
            assert np.max(np.abs(f1 - f2)) < 2e-15, (n, st, f1, f2)
            assert np.max(np.abs(s1 - s2)) < 4e-15 * max(1e-300, np.max(np.abs(phi))), (n, st)
    # no curvature change (no force: a pure moment): equal arcs from the equal solution itself;
    # a straight catheter under a lateral force: equal arcs (a uniform monitor), straight start
    phi = np.full(n, 0.3)
    f, s = mesh._small_grade(phi, 0j, False, 'cubic')
    assert np.all(f == 1.0 / n) and s is phi
    f, s = mesh._small_grade(np.zeros(n), 0.5 + 0.2j, False, 'cubic')
    assert np.allclose(f, 1.0 / n, rtol=0, atol=1e-15) and not np.any(s)


def test_fast_grade_takes_the_python_float_form_up_to_small_grade_n(monkeypatch):
    """fast_grade: Python floats up to SMALL_GRADE_N (= the Newton kernel's SMALL_N) arcs, the
    array form beyond; a graded solve at N = 4 grades through the Python-float form."""
    assert mesh.SMALL_GRADE_N == fast_newton.SMALL_N
    seen = []
    orig_s, orig_a = mesh._small_grade, mesh._array_grade
    monkeypatch.setattr(mesh, '_small_grade', lambda *a: seen.append('small') or orig_s(*a))
    monkeypatch.setattr(mesh, '_array_grade', lambda *a: seen.append('array') or orig_a(*a))
    K = mesh.SMALL_GRADE_N
    for n, want in ((1, 'small'), (K, 'small'), (K + 1, 'array'), (12, 'array')):
        seen.clear()
        mesh.fast_grade(np.linspace(0.1, 0.3, n), 0.2j, False, 'cubic')
        assert seen == [want], (n, seen)
    seen.clear()
    sh = solve_fam(BLAZER, Loads(tip_force=(0.1, 0.2)), n_arcs=K, spacing='graded')
    assert sh.converged and seen == ['small']

"""Issue 15, no performance cliffs in FAM: the cheaper strategies give the same equilibria,
as accurate against the independent references, in fewer Newton iterations (counted, not
timed: the timing is ``scripts/bench fam``)."""
import numpy as np
import pytest

from fam_solver import Catheter, Loads, fast, solve_elastica, solve_fam, solve_fam_batch
from fam_solver.fast_newton import FAST_DENSE_MAX_N
from fam_solver.globalise import solve_cases
from fam_solver.problem import build_problem

UNIT = Catheter(1.0, 1.0)
BLAZER = Catheter(length=0.065, ei=6e-5)
THESIS = Catheter(length=0.040, ei=7.5e-4)
#: tip force with axial tension and a tip moment against it: the plain small-deflection start
#: led Newton to a looped equilibrium (N = 24: 12-15 iterations with the 12-arc restart)
TENSION_MOMENT = [Loads(tip_force=(F * np.cos(np.pi / 4), F * np.sin(np.pi / 4)),
                        tip_moment=-0.25 * F * BLAZER.length) for F in (0.2, 0.3)]
THESIS_LOADS = [Loads(tip_force=(F * np.cos(np.radians(d)), F * np.sin(np.radians(d))),
                      tip_moment=m)
                for F, d, m in [(1.0, 90, 0.0), (4.0, 60, 0.0), (9.8, 90, 0.0), (5.0, 135, 0.01),
                                (0.0, 0, 0.03), (2.0, -90, 0.02), (6.0, 30, -0.015)]]


@pytest.mark.parametrize('n', [24, 48, 64, 100])
@pytest.mark.parametrize('model', ['clothoid', 'exact'])
def test_tension_with_opposing_moment_is_solved_directly(n, model):
    """The stiffened start reaches the natural equilibrium directly (no restart), the same one
    the general path (batch) finds, and as close to the rod reference as any load."""
    for ld in TENSION_MOMENT:
        sh = solve_fam(BLAZER, ld, n_arcs=n, arc_model=model)
        assert sh.converged and sh.stable
        assert sh.iterations <= (5 if n <= FAST_DENSE_MAX_N else 7), (n, sh.iterations)
        bt = solve_fam_batch(BLAZER, np.array([ld.tip_force]), np.array([ld.tip_moment]),
                             n_arcs=n, arc_model=model)
        assert np.max(np.abs(sh.tip - bt.tips[0])) < 1e-12 * BLAZER.length * 1e3
        ref = solve_elastica(BLAZER, ld)
        err = np.max(np.abs(sh.tip - ref.tip)) / BLAZER.length
        # second order (exact) / fourth order (clothoid) in N: the bench's error table
        bound = 0.6 / n ** 2 if model == 'exact' else 20.0 / n ** 4
        assert err < bound, (n, model, err)


def test_stiffened_start_points_where_the_solution_turns():
    """For the tension + opposing moment loads the small-deflection tip angle has the wrong
    sign; the stiffened one (one Newton step from straight) has the solution's sign."""
    n = 24
    for ld in TENSION_MOMENT:
        l, w, lever = fast._equal_arcs(n, BLAZER.length, BLAZER.ei)
        F = complex(*ld.tip_force)
        lin = w * (ld.tip_moment + F.imag * lever)
        stiff = fast._stiffened_linear(l, w, F, ld.tip_moment, False, True, lin)
        th = solve_fam(BLAZER, ld, n_arcs=n).tip_angle
        assert np.sign(lin.sum()) != np.sign(th)
        assert np.sign(stiff.sum()) == np.sign(th)


@pytest.mark.parametrize('n', [2, 4, 12, 24, 48])
def test_bezier_from_the_circular_solution_is_the_same_equilibrium(n):
    """The Bezier model started from the circular-arc solution (solve_fam) gives the
    equilibrium the small-deflection start gives, in fewer Bezier Newton iterations."""
    for cat, loads in ((THESIS, THESIS_LOADS), (BLAZER, TENSION_MOMENT)):
        fewer = 0
        for ld in loads:
            sh = solve_fam(cat, ld, n_arcs=n, arc_model='bezier')
            prob = build_problem(cat, n, np.array([complex(*ld.tip_force)]), False,
                                 np.array([ld.tip_moment]), [])
            phi, conv, it, _, _ = solve_cases(prob, 1, 'bezier')
            ex = fast.fast_solve(n, cat.length, cat.ei, complex(*ld.tip_force), ld.tip_moment,
                                 False)
            phi2, conv2, it2, _, _ = solve_cases(prob, 1, 'bezier', ex[0][None])
            assert sh.converged and conv[0] and conv2[0]
            assert np.max(np.abs(sh.arc_angles - phi[0])) < 1e-10
            assert np.max(np.abs(phi2[0] - phi[0])) < 1e-10
            assert it2[0] <= it[0]
            fewer += it2[0] < it[0]
        assert fewer >= len(loads) // 2, (n, fewer)


def test_bezier_accuracy_is_that_of_circular_arcs():
    """Bezier and circular arcs agree within 25 % in tip error (both second order) against the
    rod reference, whatever start Newton had."""
    for ld in THESIS_LOADS:
        ref = solve_elastica(THESIS, ld)
        for n in (12, 24):
            eb = np.max(np.abs(solve_fam(THESIS, ld, n_arcs=n, arc_model='bezier').tip - ref.tip))
            ee = np.max(np.abs(solve_fam(THESIS, ld, n_arcs=n, arc_model='exact').tip - ref.tip))
            assert abs(eb - ee) <= 0.25 * ee + 1e-10 * THESIS.length, (ld, n, eb, ee)


def test_coarse_start_is_loose_but_the_answer_is_not():
    """The coarse model that starts N > FAST_DENSE_MAX_N is solved to 1e-7 only (fewer
    iterations than to 1e-12); the fine solution still solves its equations to 1e-12 and
    equals the general path's."""
    ld = Loads(tip_force=(2.0, 6.0), tip_moment=-1.0)
    F = complex(*ld.tip_force)
    loose = fast.fast_solve(32, 1.0, 1.0, F, ld.tip_moment, False, clothoid=True,
                            rtol=fast._START_RTOL)
    full = fast.fast_solve(32, 1.0, 1.0, F, ld.tip_moment, False, clothoid=True)
    assert loose[3] <= 1e-13 + 1e-7 * np.abs(loose[0]).max()
    assert loose[2] < full[2]
    for n in (FAST_DENSE_MAX_N + 1, 200):
        sh = solve_fam(UNIT, ld, n_arcs=n)
        bt = solve_fam_batch(UNIT, np.array([ld.tip_force]), np.array([ld.tip_moment]), n_arcs=n)
        assert sh.converged and np.max(np.abs(sh.tip - bt.tips[0])) < 1e-12


@pytest.mark.parametrize('model', ['clothoid', 'exact'])
def test_dense_and_banded_sides_of_the_switch_agree(model):
    """N = FAST_DENSE_MAX_N (dense, direct start) and + 1 (banded, coarse start): the same
    equilibrium up to the discretisation change, and the same Newton equations solved."""
    n = FAST_DENSE_MAX_N
    for ld in THESIS_LOADS:
        a = solve_fam(THESIS, ld, n_arcs=n, arc_model=model)
        b = solve_fam(THESIS, ld, n_arcs=n + 1, arc_model=model)
        assert a.converged and b.converged and a.stable == b.stable
        assert np.max(np.abs(a.tip - b.tip)) < 1e-5 * THESIS.length
        assert abs(a.tip_angle - b.tip_angle) < 1e-4


def test_bezier_solve_is_handed_the_circular_solution(monkeypatch):
    """When the fast path refuses a Bezier case, solve_fam starts the general path's Bezier
    Newton from the circular-arc solution of the same N (the wiring: the equilibrium itself is
    the same either way, see above)."""
    import fam_solver.fam as fam_mod
    orig_fast = fam_mod.fast_solve
    monkeypatch.setattr(fam_mod, 'fast_solve', lambda *a, **kw: None if kw.get('bezier')
                        else orig_fast(*a, **kw))
    seen = []
    orig = fam_mod.solve_cases

    def spy(prob, B, arc_model='exact', start=None):
        seen.append(start)
        return orig(prob, B, arc_model, start)

    monkeypatch.setattr(fam_mod, 'solve_cases', spy)
    ld = THESIS_LOADS[1]
    sh = solve_fam(THESIS, ld, n_arcs=24, arc_model='bezier')
    ex = solve_fam(THESIS, ld, n_arcs=24, arc_model='exact', spacing='uniform')
    assert seen[0] is not None and np.max(np.abs(seen[0][0] - ex.arc_angles)) < 1e-12
    assert sh.iterations > ex.iterations        # both solves counted


def test_coarse_start_is_asked_for_the_loose_tolerance(monkeypatch):
    """N > FAST_DENSE_MAX_N: the COARSE_N model is solved with rtol = _START_RTOL."""
    calls = []
    orig = fast.fast_solve

    def spy(n, *a, **kw):
        calls.append((n, kw.get('rtol')))
        return orig(n, *a, **kw)

    monkeypatch.setattr(fast, 'fast_solve', spy)
    spy(FAST_DENSE_MAX_N + 1, 1.0, 1.0, 2 + 6j, -1.0, False, clothoid=True)
    assert (fast.COARSE_N, fast._START_RTOL) in calls


@pytest.mark.parametrize('n', [24, 48, 64, 100])
@pytest.mark.parametrize('follower', [False, True])
@pytest.mark.parametrize('graded', [False, True])
def test_single_case_banded_newton_step_is_the_dense_step(n, follower, graded):
    """The general path's Newton step for one case (banded LAPACK solve from BANDED_MIN_N
    arcs) equals the dense solve of the same Jacobian."""
    from fam_solver import equations, linsolve
    from fam_solver.problem import make_problem
    rng = np.random.default_rng(n + 2 * follower + 4 * graded)
    frac = rng.uniform(0.5, 1.5, (1, n)) if graded else None
    if graded:
        frac /= frac.sum()
    prob = make_problem(n, 1.0, 1.0, np.array([2.0 + 6.0j]), follower, np.array([-1.0]), [],
                        fractions=frac)
    phi = rng.normal(0.0, 0.1, (1, n))
    loads, m = prob.loads(1.0)
    r, fac, _ = equations.evaluate(phi, prob.l, prob.w, loads, m, jac=True)
    dx, _ = linsolve.newton_step(prob.w, fac, r)
    J = linsolve.dense_jacobian(prob.w, fac)
    ref = np.linalg.solve(J[0], -r[0])
    assert np.max(np.abs(dx[0] - ref)) <= 1e-10 * max(1.0, np.abs(ref).max())


def test_single_case_branch_check_is_the_eigenvalue_criterion():
    """principal_ok for one case (Cholesky first, ``energy_stable``) says what the
    eigenvalues of the Jacobian say, on stable and on unstable (buckled) equilibria."""
    from fam_solver import equations, linsolve
    from fam_solver.problem import make_problem
    verdicts = []
    for F, th in [(-30.0 + 0.1j, 0.0), (-30.0 + 0.1j, 0.3), (2.0 + 6.0j, 0.0), (-1.0 + 0j, 0.0),
                  (-5.0 + 0j, 0.0), (3.0 - 8.0j, -0.5)]:
        for clothoid in (False, True):
            n = 24
            prob = make_problem(n, 1.0, 1.0, np.array([F]), False, np.array([0.0]), [],
                                clothoid=clothoid)
            phi = np.full((1, n), th / n)
            loads, m = prob.loads(1.0)
            _, fac, _ = equations.evaluate(phi, prob.l, prob.w, loads, m, jac=True,
                                           clothoid=clothoid)
            eig = np.min(np.linalg.eigvals(linsolve.dense_jacobian(prob.w, fac)[0]).real) > 1e-9
            got = bool(linsolve.principal_ok(prob.w, fac)[0])
            assert got == eig, (F, th, clothoid)
            verdicts.append(got)
    assert any(verdicts) and not all(verdicts)


@pytest.mark.parametrize('n', [12, 48, 100])
def test_tip_point_force_with_follower_flag_and_no_tip_force_takes_the_fast_path(n, monkeypatch):
    """follower=True turns only the tip force; without one, a base-fixed point force at s = 1
    and a tip moment are a dead tip load: the fast path, the same shape as tip_force= gives
    (before: always the general path, ~10x the time)."""
    import fam_solver.fam as fam_mod
    calls = []
    orig = fam_mod.solve_cases

    def spy(*a, **k):
        calls.append(1)
        return orig(*a, **k)

    monkeypatch.setattr(fam_mod, 'solve_cases', spy)
    for F, d, m in [(0.2, 60, 0.003), (0.3, 135, -0.004), (0.1, -90, 0.0)]:
        f = (F * np.cos(np.radians(d)), F * np.sin(np.radians(d)))
        a = solve_fam(BLAZER, Loads(point_forces=((1.0, *f),), tip_moment=m, follower=True),
                      n_arcs=n)
        b = solve_fam(BLAZER, Loads(tip_force=f, tip_moment=m), n_arcs=n)
        assert a.converged and a.stable
        assert np.array_equal(a.arc_angles, b.arc_angles)
        g = solve_fam(BLAZER, Loads(point_forces=((1.0, *f),), tip_moment=m, follower=True),
                      n_arcs=n, spacing='graded')
        assert np.ptp(g.arc_lengths) > 0      # graded: no follower force keeps arcs equal
    assert not calls
    # a follower tip force keeps its flag: the point force at the tip stays base-fixed
    ld = Loads(tip_force=(0.0, 0.1), follower=True, point_forces=((1.0, 0.1, 0.0),))
    sh = solve_fam(BLAZER, ld, n_arcs=n)
    ref = solve_elastica(BLAZER, ld)
    assert sh.converged and np.max(np.abs(sh.tip - ref.tip)) < 0.1 / n ** 4 * BLAZER.length


def test_snap_through_is_reported_beyond_64_arcs_too():
    """Regression: beyond 64 arcs the general path starts from the 32-arc solution; a fold on
    that model's loading path was not passed on (SNAP_THROUGH at N = 24, CONVERGED at 100)."""
    b = np.radians(94.0)
    ld = Loads(tip_force=(7.6 * np.cos(b), 7.6 * np.sin(b)), tip_moment=-4.74)
    st = [solve_fam(UNIT, ld, n_arcs=n) for n in (24, 100)]
    assert [s.status.name for s in st] == ['SNAP_THROUGH', 'SNAP_THROUGH']
    assert abs(st[0].tip_angle - st[1].tip_angle) < 1e-3


def _random_tip_loads(seed, k):
    rng = np.random.default_rng(seed)
    f, b = rng.uniform(0.0, 25.0, k), rng.uniform(-np.pi, np.pi, k)
    m = rng.uniform(-5.0, 5.0, k) * (rng.uniform(size=k) < 0.5)
    fol = rng.uniform(size=k) < 0.2
    return [Loads(tip_force=(f[i] * np.cos(b[i]), f[i] * np.sin(b[i])), tip_moment=m[i],
                  follower=bool(fol[i])) for i in range(k)]


@pytest.mark.parametrize('model', ['exact', 'clothoid'])
def test_few_arcs_are_damped_like_four(monkeypatch, model):
    """Round 5: a damped Newton step may turn the tip by STEP_TURN whatever N (the per-arc
    limit alone let one arc turn the tip by 0.3 rad per step, 16 arcs by 4.8). N = 1-3: the same
    equilibria and status as with the per-arc limit alone, in fewer iterations; N >= 4
    unchanged, step for step."""
    from fam_solver import fast_newton
    loads = _random_tip_loads(11, 40)
    its = {}
    for name, turn in (('new', fast_newton.STEP_TURN), ('old', 0.0)):
        monkeypatch.setattr(fast_newton, 'STEP_TURN', turn)
        for n in (1, 2, 3, 4, 8):
            for i, ld in enumerate(loads):
                sh = solve_fam(UNIT, ld, n_arcs=n, arc_model=model)
                its[(name, n, i)] = (sh.iterations, sh.tip_angle, int(sh.status))
    monkeypatch.undo()
    new, old = 'new', 'old'
    for n in (1, 2, 3, 4, 8):
        a = [its[(new, n, i)] for i in range(len(loads))]
        b = [its[(old, n, i)] for i in range(len(loads))]
        for x, y in zip(a, b, strict=True):
            assert abs(x[1] - y[1]) < 1e-9 and x[2] == y[2], (n, x, y)
        if n < 4:
            assert sum(x[0] for x in a) < 0.95 * sum(y[0] for y in b), n
        else:
            assert [x[0] for x in a] == [y[0] for y in b], n


def test_one_bezier_arc_keeps_the_per_arc_damping():
    """Few long Bezier arcs have extra equilibria near the start (design record); with the
    larger steps of STEP_TURN one Bezier arc under this load (found in a random sweep, seed
    101) reached tip angle -0.32 rad. With the per-arc limit it stays on the branch of the
    elastica (4.80 rad), circular arcs (N = 1: 5.04) and Bezier N = 2 (4.72)."""
    ld = Loads(tip_force=(11.63 * np.cos(-2.64), 11.63 * np.sin(-2.64)), tip_moment=4.88)
    sh = solve_fam(UNIT, ld, n_arcs=1, arc_model='bezier')
    assert sh.converged and sh.status == 0
    assert 4.0 < sh.tip_angle < 5.5, sh.tip_angle
    assert abs(solve_fam(UNIT, ld, n_arcs=2, arc_model='bezier').tip_angle - sh.tip_angle) < 0.5

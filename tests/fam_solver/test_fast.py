"""The single-case fast path: same equations as the general path, a true Newton Jacobian, the
branch and stability decisions of the general path, and no loads that fall off it."""
import numpy as np
import pytest

from fam_solver import Catheter, Loads, arcs, equations, fast, fast_newton, problem, solve_fam
from fam_solver import solve_elastica, solve_fam_batch

UNIT = Catheter(1.0, 1.0)
BLAZER = Catheter(length=0.065, ei=6e-5)


def _general_residual(sh, ld, cat):
    n = sh.arc_angles.size
    prob = problem.make_problem(n, cat.length, cat.ei, np.array([complex(*ld.tip_force)]),
                                ld.follower, np.array([ld.tip_moment]), [],
                                fractions=None if sh.spacing == 'uniform'
                                else sh.arc_lengths / cat.length,
                                clothoid=sh.arc_model == 'clothoid')
    loads, m = prob.loads(1.0)
    r, _, _ = equations.evaluate(sh.arc_angles[None], prob.l, prob.w, loads, m, jac=False,
                                 clothoid=sh.arc_model == 'clothoid')
    return float(np.max(np.abs(r)))


@pytest.mark.parametrize('n', [1, 2, 3, 12, 48, 100, 500])
@pytest.mark.parametrize('model', ['exact', 'clothoid'])
@pytest.mark.parametrize('spacing', ['uniform', 'graded'])
def test_fast_solution_solves_the_general_equations(n, model, spacing):
    """Whatever the N (dense, banded, started from a coarser model), the fast path's answer is
    an equilibrium of ``equations.evaluate`` to the solver's tolerance."""
    for ld in (Loads(tip_force=(1.0, 4.0), tip_moment=-0.5), Loads(tip_force=(-2.0, 1.5)),
               Loads(tip_force=(0.5, 3.0), tip_moment=1.0, follower=True)):
        sh = solve_fam(UNIT, ld, n_arcs=n, arc_model=model, spacing=spacing)
        assert sh.converged and sh.status == 0
        assert _general_residual(sh, ld, UNIT) <= 1e-11 * max(1.0, np.abs(sh.arc_angles).max())


@pytest.mark.parametrize('follower', [False, True])
@pytest.mark.parametrize('clothoid', [False, True])
@pytest.mark.parametrize('n', [1, 2, 9])
def test_kernel_jacobian_is_the_derivative_of_its_residual(follower, clothoid, n):
    """Central differences of the kernel's residual (quadratic Newton needs the true Jacobian;
    near a solution the clothoid rates' terms are in it)."""
    rng = np.random.default_rng(n)
    l = np.full(n, 1.0 / n)
    w = l.copy()
    F, m = 2.0 - 1.5j, 0.4

    prob = problem.make_problem(n, 1.0, 1.0, np.array([F]), follower, np.array([m]), [],
                                clothoid=clothoid)
    loads, mm = prob.loads(1.0)

    def residual(phi):      # the general residual (the same equations, tested above)
        return equations.evaluate(phi[None], prob.l, prob.w, loads, mm, jac=False,
                                  clothoid=clothoid)[0][0]

    sol = fast_newton.fast_tip_newton(n, l, w, F, m, follower, np.zeros(n) + 0.1 / n, 30,
                                      clothoid=clothoid)[0]
    checked = 0
    for trial in range(4):      # far from and near the solution
        phi = rng.normal(0, 0.4 / n, n) if trial < 2 else sol + rng.normal(0, 1e-4, n)
        J = fast_newton.jacobian_at(phi, l, w, F, m, follower, clothoid)
        r0 = residual(phi)
        h = 1e-6
        Jn = np.empty((n, n))
        for j in range(n):
            e = np.zeros(n)
            e[j] = h
            Jn[:, j] = (residual(phi + e) - residual(phi - e)) / (2 * h)
        # the clothoid rates' terms are in J only near a solution (max|r| < QUASI_ABOVE) or for
        # N < _QUASI_MIN_N; far from it J is the circular-arc one (a quasi-Newton step)
        exact = not clothoid or n < fast_newton._QUASI_MIN_N or \
            np.max(np.abs(r0)) < fast_newton.QUASI_ABOVE
        if exact:
            assert np.abs(J - Jn).max() < 1e-6 * max(1.0, np.abs(Jn).max())
            checked += 1
    assert checked >= 2


def test_arc_values_equal_the_arc_functions_at_every_angle():
    rng = np.random.default_rng(0)
    for lo, hi in ((0, 1e-3), (0, 0.1), (0, 1), (1, 2.9), (2.9, 3.1), (3, 9)):
        for coef, f in ((fast_newton._COEF4, arcs.arc_funcs),
                        (fast_newton._COEF8, arcs.clothoid_funcs)):
            for n in (3, 300):        # few arcs, and the blocked product of many
                phi = rng.uniform(lo, hi, n) * rng.choice([-1, 1], n)
                V = np.empty((n, fast_newton._K_FAST))
                V[:, 0] = 1.0
                R = fast_newton._arc_values(phi, np.max(np.abs(phi)), V, coef)
                ref = np.stack(f(phi), axis=1)
                assert np.abs(R - ref).max() <= 2e-15 + 1e-13 * np.abs(ref).max(), (lo, hi, n)


@pytest.mark.parametrize('n', [1, 2, 3])
def test_pure_moment_turning_many_radians_is_exact_with_few_arcs(n):
    """Arcs of 2-7 rad: beyond the series' reach, the closed forms."""
    th = 7.0
    sh = solve_fam(UNIT, Loads(tip_moment=th), n_arcs=n, arc_model='exact')
    assert abs(sh.tip_angle - th) < 1e-12
    assert np.max(np.abs(sh.tip - [np.sin(th) / th, (1 - np.cos(th)) / th])) < 1e-12


@pytest.mark.parametrize('n', [1, 2, 12])
def test_clothoid_newton_is_quadratic_for_few_arcs_too(n):
    """With the rates' Jacobian terms from the first step for N < 3 the clothoid model needs
    no more Newton iterations than circular arcs (+1)."""
    for F in (0.1, 0.3):
        for beta in (0.5, 1.5, 2.8):
            ld = Loads(tip_force=(F * np.cos(beta), F * np.sin(beta)))
            c = solve_fam(BLAZER, ld, n_arcs=n, arc_model='clothoid')
            e = solve_fam(BLAZER, ld, n_arcs=n, arc_model='exact')
            assert c.converged and c.iterations <= e.iterations + 1, (n, F, beta)


def _compressive_loads(count, seed):
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(count):
        a = rng.uniform(0.5, 30.0)
        b = np.pi + rng.normal(0, 0.4)
        out.append(Loads(tip_force=(a * np.cos(b), a * np.sin(b)), tip_moment=rng.normal(0, 0.5)))
    return out


def test_many_arcs_judge_stability_like_fewer_arcs():
    """The issue-14 mutant: beyond 64 arcs the stability check runs on a 32-arc model with the
    same curvature; without scaling the angles to the coarse arcs, compressed equilibria flip
    to 'unstable'. N = 100 must agree with N = 48 on every random compressive load that is not
    near a critical point (both converge, to the same shape to O(1/N^2))."""
    for ld in _compressive_loads(30, 5):
        a = solve_fam(UNIT, ld, n_arcs=48)
        b = solve_fam(UNIT, ld, n_arcs=100)
        assert a.converged and b.converged
        if np.max(np.abs(a.tip - b.tip)) < 1e-3:          # same equilibrium
            assert a.stable == b.stable, ld


def test_many_arcs_with_point_forces_judge_stability_like_fewer_arcs():
    """The same on the general path (point forces are not on the fast path)."""
    for ld in _compressive_loads(12, 6):
        ld = Loads(tip_force=ld.tip_force, tip_moment=ld.tip_moment,
                   point_forces=((0.5, 0.0, 0.2),))
        a = solve_fam(UNIT, ld, n_arcs=48)
        b = solve_fam(UNIT, ld, n_arcs=100)
        assert a.converged and b.converged
        if np.max(np.abs(a.tip - b.tip)) < 1e-3:
            assert a.stable == b.stable, ld


def test_many_arcs_agree_with_the_general_path():
    """A compressed, bent catheter on 100 and 500 arcs: the fast path (coarse start, banded
    Newton, coarse stability model) gives the general path's equilibrium, in no more Newton
    iterations (each of them far cheaper)."""
    for ld in _compressive_loads(10, 7):
        for n in (100, 500):
            sh = solve_fam(UNIT, ld, n_arcs=n)
            bt = solve_fam_batch(UNIT, np.array([ld.tip_force]), np.array([ld.tip_moment]),
                                 n_arcs=n)
            assert sh.converged and sh.stable and bt.converged[0] and bt.stable[0]
            assert np.max(np.abs(sh.tip - bt.tips[0])) < 1e-12
            assert sh.iterations <= bt.iterations[0], (n, ld)


FORCE_MOMENT = [Loads(tip_force=(F * np.cos(b), F * np.sin(b)), tip_moment=s * F * BLAZER.length)
                for F in (0.1, 0.2, 0.3) for b in (np.pi / 4, np.pi / 2, 3 * np.pi / 4)
                for s in (-0.25, 0.25)]


@pytest.mark.parametrize('n', [12, 24, 48, 64, 65, 100])
def test_force_with_moment_stays_cheap(n):
    """Issue 15: a tip force with a tip moment left the fast path (20x a normal solve), then
    took 3-4x the median at N = 24 (restart from 12 arcs). Counted in Newton iterations
    (deterministic): at most 3x the median case's, the issue's bound."""
    its = np.array([solve_fam(BLAZER, ld, n_arcs=n).iterations for ld in FORCE_MOMENT])
    assert its.max() <= 3 * np.median(its), its


def test_force_with_moment_matches_the_general_path():
    """The fast path (direct, restart from 12 arcs, continuation) finds the equilibrium the
    vectorised general path (batch) finds."""
    F = np.array([ld.tip_force for ld in FORCE_MOMENT])
    M = np.array([ld.tip_moment for ld in FORCE_MOMENT])
    for n in (12, 24, 48, 64):
        bt = solve_fam_batch(BLAZER, F, M, n_arcs=n)
        for k, ld in enumerate(FORCE_MOMENT):
            sh = solve_fam(BLAZER, ld, n_arcs=n)
            assert np.max(np.abs(sh.tip - bt.tips[k])) < 1e-11, (n, k)


def test_continuation_on_the_fast_path_reaches_the_natural_branch():
    """Loads whose direct Newton lands on another equilibrium (looped the other way): the
    fast path's continuation gives what the general path's continuation gives."""
    cases = [Loads(tip_force=(5.8 * np.cos(-3.10), 5.8 * np.sin(-3.10)), tip_moment=1.46),
             Loads(tip_force=(13.6 * np.cos(2.81), 13.6 * np.sin(2.81)), tip_moment=-1.51),
             Loads(tip_force=(15.0 * np.cos(2.92), 15.0 * np.sin(2.92)), tip_moment=2.63)]
    for ld in cases:
        sh = solve_fam(UNIT, ld, n_arcs=12)
        bt = solve_fam_batch(UNIT, np.array([ld.tip_force]), np.array([ld.tip_moment]), n_arcs=12)
        assert sh.converged and sh.stable
        assert np.max(np.abs(sh.tip - bt.tips[0])) < 1e-11
        # counted in Newton iterations (deterministic): the fast continuation needs 41-47 on
        # these, the general path's (smaller first steps, full tolerance on every step) 58-75
        assert sh.iterations <= 50, sh.iterations


def test_fast_continuation_gives_up_at_a_fold():
    """A snap-through: the fast continuation stops (None) and the general path reports it."""
    ld = Loads(tip_force=(5.2968, -4.2802), tip_moment=4.9337)
    l, w, lever = fast._equal_arcs(12, 1.0, 1.0)
    F = complex(*ld.tip_force)
    lin = w * (ld.tip_moment + F.imag * lever)
    assert fast._continuation(12, l, w, F, ld.tip_moment, False, True, lin, 12) is None
    assert solve_fam(UNIT, ld, n_arcs=12).status.name == 'SNAP_THROUGH'


def test_warm_start_from_another_equilibrium_is_not_taken():
    """A warm start from the natural shape turned by -2 pi: Newton from it converges to a
    looped equilibrium (tip angle -3.36 rad); the branch check rejects it and the cold start
    gives the natural one."""
    ld = Loads(tip_force=(0.0, 21.0))
    nat = solve_fam(UNIT, ld, n_arcs=12)
    l, w, _ = fast._equal_arcs(12, 1.0, 1.0)
    looped = nat.arc_angles - 2 * np.pi / 12
    other = fast_newton.fast_tip_newton(12, l, w, 21j, 0.0, False, looped, 12, clothoid=True)
    assert other[1] and abs(other[0].sum() - nat.tip_angle) > 4.0     # another equilibrium
    warm = solve_fam(UNIT, ld, n_arcs=12, initial=looped)
    assert np.max(np.abs(warm.tip - nat.tip)) < 1e-12


@pytest.mark.parametrize('model', ['exact', 'clothoid'])
def test_point_force_just_off_an_arc_end_moves_the_shape_like_the_reference(model):
    """A point force 4e-5 L before an arc end (s = 0.3, N = 20: 0.9992 of the arc) is carried
    inside the arc, not snapped onto its end: the tip moves as the reference rod's does."""
    base = Loads(tip_force=(0.5, 1.0), point_forces=((0.3, 0.0, 3.0),))
    off = Loads(tip_force=(0.5, 1.0), point_forces=((0.29996, 0.0, 3.0),))
    d = solve_fam(UNIT, off, n_arcs=20, arc_model=model).tip - \
        solve_fam(UNIT, base, n_arcs=20, arc_model=model).tip
    d_ref = solve_elastica(UNIT, off).tip - solve_elastica(UNIT, base).tip
    assert np.max(np.abs(d - d_ref)) < 0.05 * np.max(np.abs(d_ref)), (d, d_ref)   # snapped: d = 0

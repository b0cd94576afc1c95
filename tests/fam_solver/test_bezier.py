"""The Bezier arc model's exact Jacobian (issue 15): checked against central differences of the
residual, the general path's quadratic convergence from the circular-arc start (iterations
counted, not timed), and the graded Bezier arcs (fast path and general path). The fast path's
series kernel: test_fast_bezier.py."""
import numpy as np
import pytest

from fam_solver import Catheter, Loads, fast, solve_elastica, solve_fam
from fam_solver.bezier import BezierResidual
from fam_solver.globalise import solve_cases
from fam_solver.linsolve import banded_solve, dense_jacobian
from fam_solver.problem import build_problem, make_problem

THESIS = Catheter(length=0.040, ei=7.5e-4)
BLAZER = Catheter(length=0.065, ei=6e-5)
LOADS = [Loads(tip_force=(F * np.cos(np.radians(d)), F * np.sin(np.radians(d))), tip_moment=m)
         for F, d, m in [(1.0, 90, 0.0), (4.0, 60, 0.0), (9.8, 90, 0.0), (5.0, 135, 0.01),
                         (2.0, -90, 0.02), (6.0, 30, -0.015), (3.0, 170, 0.0)]]


def _fd_jacobian(bz, phi, loads, m, h=1e-6):
    B, N = phi.shape
    J = np.zeros((B, N, N))
    for j in range(N):
        p1, p2 = phi.copy(), phi.copy()
        p1[:, j] += h
        p2[:, j] -= h
        J[:, :, j] = (bz.residual(p1, loads, m) - bz.residual(p2, loads, m)) / (2 * h)
    return J


@pytest.mark.parametrize('follower', [False, True])
@pytest.mark.parametrize('n', [1, 3, 7])
@pytest.mark.parametrize('graded', [False, True])
def test_exact_jacobian_matches_central_differences(follower, n, graded):
    """Dead and follower tip forces, tip moments, a base-fixed force at an arc end, equal and
    per-case graded arcs; two cases at once with different loads."""
    rng = np.random.default_rng(n + 10 * follower + 100 * graded)
    frac = None
    if graded:
        f = rng.uniform(0.5, 2.0, size=(1, n))
        frac = f / f.sum()
    ends = np.cumsum(frac[0] if graded else np.full(n, 1.0 / n))
    pfs = [] if follower or n == 1 else [(float(ends[n // 2 - 1]) if n > 1 else 1.0,
                                          np.array([1.0 - 2.0j]))]
    prob = make_problem(n, 0.04, 7.5e-4, np.array([3.0 + 4.0j]), follower, np.array([0.01]),
                        pfs, frac)
    assert all(t >= 1.0 for _, t, _ in prob.point_forces)
    bz = BezierResidual(prob)
    loads, m = prob.loads(1.0)
    phi = rng.normal(size=(1, n)) * 0.5
    r, state = bz.residual_state(phi, loads, m)
    assert np.array_equal(r, bz.residual(phi, loads, m))
    w, fac = bz.factors(state)
    J = dense_jacobian(w, fac)
    Jfd = _fd_jacobian(bz, phi, loads, m)
    assert np.max(np.abs(J - Jfd)) < 1e-7 * max(1.0, np.max(np.abs(Jfd))), (J, Jfd)
    # the O(N) banded solve of the same factors gives the dense solution
    rhs = rng.normal(size=n)
    x = banded_solve(w[0], tuple(f[0] for f in fac), rhs)
    assert np.max(np.abs(J[0] @ x - rhs)) < 1e-10


def test_point_force_inside_an_arc_has_no_exact_jacobian():
    """Inside an arc the force kinks the moment: the Bezier model keeps its finite-difference /
    quasi-Newton Jacobian there (residual_state says so with None)."""
    prob = make_problem(4, 1.0, 1.0, np.array([1.0j]), False, np.array([0.0]),
                        [(0.3, np.array([1.0 + 0.0j]))])
    loads, m = prob.loads(1.0)
    assert BezierResidual(prob).residual_state(np.zeros((1, 4)), loads, m) is None


@pytest.mark.parametrize('n', [2, 8, 24, 48, 100])
def test_newton_from_the_circular_solution_converges_quadratically(n):
    """The general path (the fast path's fallback) from the circular-arc solution (residual
    ~ N^-4): the exact Jacobian converges in at most 3 Bezier steps for long arcs, 2 from N = 8
    on, 1 at N = 100 (measured: the quasi-Newton iteration took 4-6 at N = 16-32)."""
    cap = 3 if n < 8 else (2 if n < 100 else 1)
    for cat in (THESIS, BLAZER):
        for ld in LOADS:
            if cat is BLAZER:
                ld = Loads(tip_force=tuple(0.03 * np.array(ld.tip_force)),
                           tip_moment=0.03 * ld.tip_moment)
            F = complex(*ld.tip_force)
            ex = fast.fast_solve(n, cat.length, cat.ei, F, ld.tip_moment, False)
            prob = build_problem(cat, n, np.array([F]), False, np.array([ld.tip_moment]), [])
            phi, conv, it, _, _ = solve_cases(prob, 1, 'bezier', ex[0][None])
            assert conv[0], (n, ld)
            assert it[0] <= cap, (n, ld, it[0])


def test_bezier_is_second_order_against_the_rod_reference():
    """The exact Jacobian does not change the equilibrium: errors against solve_elastica fall
    4x per doubling of N, as for circular arcs."""
    for ld in LOADS[:4]:
        ref = solve_elastica(THESIS, ld)
        e = [np.max(np.abs(solve_fam(THESIS, ld, n_arcs=n, arc_model='bezier').tip - ref.tip))
             for n in (8, 16, 32)]
        assert 3.5 < e[0] / e[1] < 4.5 and 3.5 < e[1] / e[2] < 4.5, (ld, e)


def _no_bezier_fast_path(monkeypatch):
    """solve_fam with the Bezier model's fast path refused (its general-path fallback)."""
    import fam_solver.fam as fam_mod
    orig = fam_mod.fast_solve

    def no_bezier(*a, **kw):
        return None if kw.get('bezier') else orig(*a, **kw)
    monkeypatch.setattr(fam_mod, 'fast_solve', no_bezier)
    return fam_mod


@pytest.mark.parametrize('n', [12, 80])
def test_graded_bezier_arcs(n):
    """Graded Bezier arcs (fast path): placed from the Bezier equal-arc solution, so within
    O(phi^2) of the circular graded arcs, as accurate as those, the same stability verdict as
    equal arcs (also beyond 64 arcs, where it is judged on the 32-arc model), and the
    quadrature model's residual solved to 1e-12 on them."""
    for ld in LOADS:
        ref = solve_elastica(THESIS, ld)
        gb = solve_fam(THESIS, ld, n_arcs=n, arc_model='bezier', spacing='graded')
        ge = solve_fam(THESIS, ld, n_arcs=n, arc_model='exact', spacing='graded')
        ub = solve_fam(THESIS, ld, n_arcs=n, arc_model='bezier')
        assert gb.converged and gb.stable == ub.stable and gb.spacing == 'graded'
        assert np.ptp(gb.arc_lengths) > 0
        assert np.allclose(gb.arc_lengths, ge.arc_lengths, rtol=1e-3, atol=0)
        eb = np.max(np.abs(gb.tip - ref.tip))
        ee = np.max(np.abs(ge.tip - ref.tip))
        assert abs(eb - ee) <= 0.25 * ee + 1e-10 * THESIS.length, (ld, eb, ee)
        prob = build_problem(THESIS, n, np.array([complex(*ld.tip_force)]), False,
                             np.array([ld.tip_moment]), [],
                             fractions=(gb.arc_lengths / THESIS.length)[None])
        loads, m = prob.loads(1.0)
        r = BezierResidual(prob).residual(gb.arc_angles[None], loads, m)
        assert np.max(np.abs(r)) <= 1e-13 + 1e-12 * np.max(np.abs(gb.arc_angles))


def test_general_path_graded_bezier_on_the_circular_graded_arcs(monkeypatch):
    """The fallback (fast path refused): the Bezier model solved once on the arcs of the
    circular graded solution, as accurate as the fast path's graded arcs."""
    fast_tips = [solve_fam(THESIS, ld, n_arcs=12, arc_model='bezier', spacing='graded').tip
                 for ld in LOADS[:4]]
    _no_bezier_fast_path(monkeypatch)
    for ld, tip in zip(LOADS[:4], fast_tips, strict=True):
        gb = solve_fam(THESIS, ld, n_arcs=12, arc_model='bezier', spacing='graded')
        ge = solve_fam(THESIS, ld, n_arcs=12, arc_model='exact', spacing='graded')
        assert gb.converged and np.allclose(gb.arc_lengths, ge.arc_lengths, rtol=0, atol=1e-15)
        assert np.max(np.abs(gb.tip - tip)) < 1e-5 * THESIS.length


def test_graded_bezier_falls_back_to_equal_arcs_regraded(monkeypatch):
    """Wiring of the general path: when the Bezier solve on the circular graded arcs does not
    converge, the equal arcs are solved and regraded, and the result says so."""
    fam_mod = _no_bezier_fast_path(monkeypatch)
    orig = fam_mod.solve_cases
    calls = []

    def failing_first(prob, B, arc_model='exact', start=None):
        phi, conv, it, res, sn = orig(prob, B, arc_model, start)
        calls.append(np.ndim(prob.l))
        if len(calls) == 1:
            conv = np.zeros_like(conv)
        return phi, conv, it, res, sn

    monkeypatch.setattr(fam_mod, 'solve_cases', failing_first)
    ld = LOADS[1]
    sh = solve_fam(THESIS, ld, n_arcs=12, arc_model='bezier', spacing='graded')
    assert calls[:2] == [2, 1]          # graded arcs (per case), then equal arcs
    assert sh.converged and np.ptp(sh.arc_lengths) > 0
    monkeypatch.setattr(fam_mod, 'solve_cases', orig)
    ref = solve_fam(THESIS, ld, n_arcs=12, arc_model='bezier', spacing='graded')
    assert np.max(np.abs(sh.tip - ref.tip)) < 1e-4 * THESIS.length   # both graded, 2nd order

"""Clothoid arcs (arc_model='clothoid', the default): N arcs whose curvature changes linearly
along each, to first order in the change. Closed forms, fourth-order convergence to the
exact elastica, consistency of the fast and general paths, the Shape geometry, properties."""
import numpy as np
import pytest
from hypothesis import assume, given, settings, strategies as st
from scipy.integrate import quad

from fam_solver import Catheter, Loads, solve_elastica, solve_fam, solve_fam_batch
from fam_solver import equations, linsolve, problem
from fam_solver.arcs import rate_funcs, rate_offset

BLAZER = Catheter(length=0.065, ei=6e-5)
UNIT = Catheter(1.0, 1.0)


def _quad(f, a, b):
    return quad(lambda v: f(v).real, a, b, epsabs=1e-15)[0] + \
        1j * quad(lambda v: f(v).imag, a, b, epsabs=1e-15)[0]


@pytest.mark.parametrize('phi', [0.0, 1e-6, 0.3, 0.999999, 1.0, 1.7, -3.0, 6.2])
def test_rate_functions_equal_their_integrals(phi):
    k, km = rate_funcs(np.array([phi]))
    ek = _quad(lambda v: (v * v - v) / 2 * np.exp(1j * phi * v), 0, 1)
    ekm = _quad(lambda v: (1 - v) * (v * v - v) / 2 * np.exp(1j * phi * v), 0, 1)
    assert abs(k[0] - ek) < 1e-15 and abs(km[0] - ekm) < 1e-15
    for tau in (0.0, 0.25, 0.8, 1.0):
        K = rate_offset(np.array([phi]), np.array([tau]))
        assert abs(K[0] - _quad(lambda v: (v * v - v) / 2 * np.exp(1j * phi * v), 0, tau)) < 1e-15


def test_rate_functions_at_zero_are_the_classic_chord_offsets():
    k, km = rate_funcs(np.zeros(1))
    assert k[0] == pytest.approx(-1 / 12, abs=1e-16) and km[0] == pytest.approx(-1 / 24, abs=1e-16)


def test_fourth_order_convergence_to_the_closed_form(closed_form):
    for alpha in (1.0, 10.0, 21.125):
        exact, _ = closed_form(alpha)
        F = alpha * BLAZER.ei / BLAZER.length ** 2
        errs = [np.max(np.abs(solve_fam(BLAZER, Loads(tip_force=(0.0, F)), n_arcs=n).tip
                              / BLAZER.length - exact)) for n in (8, 16, 32, 64)]
        # N = 8 is pre-asymptotic at alpha >= 10 (measured 9e-6 .. 5e-5 L); from N = 16 on the
        # error falls towards 16x per doubling (measured 11.6 then 15.0 at alpha = 21)
        ratios = np.array(errs[1:-1]) / np.array(errs[2:])
        assert np.all((ratios > 10.0) & (ratios < 20.0)) and ratios[-1] > 14.0, (alpha, errs,
                                                                                 ratios)
        assert errs[0] < 2e-4          # N = 8 already below 0.02 % L


def test_n12_meets_0p1_percent_on_the_thesis_set_including_the_post_buckled_case():
    cat = Catheter(length=0.040, ei=7.5e-4)
    # the worst case for circular arcs (0.12 % L graded, 0.15 % L uniform)
    b = np.radians(170.0)
    for F, beta in ((3.0, b), (9.8, np.pi / 2), (4.0, np.radians(60))):
        ld = Loads(tip_force=(F * np.cos(beta), F * np.sin(beta)))
        ref = solve_elastica(cat, ld)
        sh = solve_fam(cat, ld, n_arcs=12)
        assert sh.arc_model == 'clothoid' and sh.converged and sh.stable
        assert np.max(np.abs(sh.tip - ref.tip)) / cat.length < 1e-4     # 0.01 % L


def test_fast_path_solution_solves_the_general_residual():
    """The single-case fast path and _evaluate implement the same clothoid equations."""
    for ld in (Loads(tip_force=(0.1, 0.25), tip_moment=2e-4), Loads(tip_force=(-0.2, 0.05)),
               Loads(tip_force=(0.05, 0.3), follower=True)):
        sh = solve_fam(BLAZER, ld, n_arcs=12)
        prob = problem.build_problem(BLAZER, 12, np.array([complex(*ld.tip_force)]), ld.follower,
                                   np.array([ld.tip_moment]), [], clothoid=True)
        loads, m = prob.loads(1.0)
        r, _, _ = equations.evaluate(sh.arc_angles[None], prob.l, prob.w, loads, m, jac=False,
                                 clothoid=True)
        assert np.max(np.abs(r)) < 1e-12
        rho = problem.problem_rates(prob, sh.arc_angles[None])[0]
        np.testing.assert_allclose(rho, sh.arc_rates, atol=1e-14)


def test_fast_path_newton_converges_quadratically():
    # the Jacobian includes the rates' derivatives: as many iterations as circular arcs (+1)
    for F in (0.05, 0.2, 0.3):
        for beta in (0.5, 1.5, 2.8):
            ld = Loads(tip_force=(F * np.cos(beta), F * np.sin(beta)))
            c = solve_fam(BLAZER, ld, n_arcs=12, arc_model='clothoid')
            e = solve_fam(BLAZER, ld, n_arcs=12, arc_model='exact', spacing='uniform')
            assert c.iterations <= e.iterations + 1, (F, beta, c.iterations, e.iterations)


@pytest.mark.parametrize('spacing', ['uniform', 'graded'])
def test_batch_equals_single(spacing):
    rng = np.random.default_rng(3)
    F = rng.uniform(-0.3, 0.3, (20, 2))
    M = rng.uniform(-3e-4, 3e-4, 20)
    bt = solve_fam_batch(BLAZER, F, M, n_arcs=12, spacing=spacing)
    assert bt.arc_model == 'clothoid' and bt.arc_rates.shape == (20, 12)
    cl = bt.centerlines(30)
    for b in range(20):
        sh = solve_fam(BLAZER, Loads(tip_force=F[b], tip_moment=M[b]), n_arcs=12, spacing=spacing)
        if not (sh.converged and bt.converged[b]):
            continue
        assert np.max(np.abs(bt.tips[b] - sh.tip)) < 1e-12
        assert np.max(np.abs(cl[b] - sh.centerline(30))) < 1e-12
        np.testing.assert_allclose(bt.shape(b).tip, sh.tip, atol=1e-13)


def test_shape_geometry_is_consistent():
    sh = solve_fam(BLAZER, Loads(tip_force=(0.1, 0.25)), n_arcs=12)
    assert np.any(sh.arc_rates != 0)
    s = np.linspace(0, 1, 2001)
    p = sh.points_at(s)
    th = sh.angles_at(s)
    np.testing.assert_allclose(p[-1], sh.tip, atol=1e-15)
    assert abs(th[-1] - sh.tip_angle) < 1e-12 and abs(th[0]) < 1e-15
    # positions and headings agree (to first order in rho, as the model is)
    dp = np.diff(p, axis=0) / (np.diff(s)[:, None] * BLAZER.length)
    mid = 0.5 * (th[1:] + th[:-1])
    assert np.max(np.abs(dp - np.c_[np.cos(mid), np.sin(mid)])) < 2e-3
    # the curve is continuous across arc ends
    assert np.max(np.linalg.norm(np.diff(p, axis=0), axis=1)) < 1.01 * BLAZER.length / 2000
    # headings: linear curvature inside each arc, continuous at the arc ends
    ends = np.cumsum(sh.arc_lengths) / BLAZER.length
    a = sh.angles_at(np.clip(ends - 1e-12, 0, 1))
    b = sh.angles_at(np.clip(ends + 1e-12, 0, 1))
    assert np.max(np.abs(a - b)) < 1e-9


def test_closer_to_the_reference_centreline_than_circular_arcs():
    ld = Loads(tip_force=(-0.1, 0.2))
    ref = solve_elastica(BLAZER, ld)
    s = np.linspace(0, 1, 101)
    ec = np.max(np.linalg.norm(solve_fam(BLAZER, ld).points_at(s) - ref.points_at(s), axis=1))
    ee = np.max(np.linalg.norm(solve_fam(BLAZER, ld, arc_model='exact').points_at(s)
                               - ref.points_at(s), axis=1))
    assert ec < ee / 20, (ec, ee)


def test_one_and_two_arcs_under_huge_loads_converge():
    # the first-order clothoid offsets are saturated at |rho| = RHO_MAX: without that, one arc
    # under F L^2/EI = 30 had no equilibrium
    for n in (1, 2):
        for beta in (0.5, np.pi / 2, 2.5):
            sh = solve_fam(UNIT, Loads(tip_force=(30 * np.cos(beta), 30 * np.sin(beta))), n_arcs=n)
            assert sh.converged and np.all(np.abs(sh.arc_rates) <= equations.RHO_MAX)


@given(fx=st.floats(-20, 20), fy=st.floats(-20, 20), m=st.floats(-5, 5))
@settings(max_examples=40, deadline=None)
def test_mirror_symmetry(fx, fy, m):
    a = solve_fam(UNIT, Loads(tip_force=(fx, fy), tip_moment=m), n_arcs=10)
    b = solve_fam(UNIT, Loads(tip_force=(fx, -fy), tip_moment=-m), n_arcs=10)
    assume(a.converged and b.converged and a.stable and b.stable)
    assume(abs(a.tip_angle + b.tip_angle) < 1e-6)          # same branch, mirrored
    assert np.allclose(a.tip * [1, -1], b.tip, atol=1e-10)
    assert np.allclose(a.arc_rates, -b.arc_rates, atol=1e-10)


@given(alpha=st.floats(0.0, 21.0), beta=st.floats(-np.pi, np.pi), k=st.floats(0.01, 100))
@settings(max_examples=30, deadline=None)
def test_scaling_and_accuracy(alpha, beta, k):
    """Same F L^2/EI -> same shape / L; and N = 12 within 0.1 % L of the reference rod."""
    cats = (UNIT, Catheter(k * 0.05, k ** 3 * 2e-4))
    shapes = []
    for cat in cats:
        F = alpha * cat.ei / cat.length ** 2
        shapes.append(solve_fam(cat, Loads(tip_force=(F * np.cos(beta), F * np.sin(beta)))))
    a, b = shapes
    assume(a.converged and b.converged and a.stable and b.stable)
    assert np.allclose(a.tip / cats[0].length, b.tip / cats[1].length, atol=1e-9)
    assume(abs(abs(beta) - np.pi) > 0.05)      # near-axial pushes: several equilibria
    ref = solve_elastica(UNIT, Loads(tip_force=(alpha * np.cos(beta), alpha * np.sin(beta))))
    assume(ref.converged and abs(ref.tip_angle - a.tip_angle) < 0.1)
    assert np.max(np.abs(a.tip - ref.tip)) < 1e-3


@pytest.mark.parametrize('tip,pfs,follower', [
    (2 - 3j, [], False), (2 - 3j, [], True), (2 - 3j, [(0.33, 1 + 2j)], False),
    (0j, [(0.5, 1 + 2j), (0.9, -1 + 0.5j)], False)])
def test_general_jacobian_matches_finite_differences(tip, pfs, follower):
    """The general path's Jacobian factors include the rates' derivatives: they equal
    central differences of the clothoid residual for a tip force; with point forces inside
    arcs the offsets' effect on those forces is left out (0.04 % measured)."""
    n = 7
    prob = problem.make_problem(n, 1.0, 1.0, np.array([tip]), follower, np.array([0.3]),
                              [(s, np.array([F])) for s, F in pfs], clothoid=True)
    loads, m = prob.loads(1.0)
    phi = np.random.default_rng(1).normal(0, 0.3, (1, n))
    _, fac, _ = equations.evaluate(phi, prob.l, prob.w, loads, m, clothoid=True)
    J = linsolve.dense_jacobian(prob.w, fac)[0]
    Jn = np.zeros((n, n))
    h = 1e-7
    for j in range(n):
        p, q = phi.copy(), phi.copy()
        p[0, j] += h
        q[0, j] -= h
        Jn[:, j] = (equations.evaluate(p, prob.l, prob.w, loads, m, jac=False, clothoid=True)[0][0]
                    - equations.evaluate(q, prob.l, prob.w, loads, m, jac=False,
                                         clothoid=True)[0][0]) / (2 * h)
    tol = 1e-3 if pfs else 1e-7
    assert np.abs(J - Jn).max() < tol * np.abs(Jn - np.eye(n)).max()

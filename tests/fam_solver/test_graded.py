"""Graded arcs (spacing='graded'): per-case arc lengths from the curvature change of the
equal-arc solution. Exact references, convergence order, the mesh itself, batch = single."""
import functools

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from fam_solver import Catheter, Loads, solve_elastica
from fam_solver import solve_fam as _solve_fam, solve_fam_batch as _solve_fam_batch
from fam_solver import equations, linsolve, mesh, problem

BLAZER = Catheter(length=0.065, ei=6e-5)
UNIT = Catheter(1.0, 1.0)

# these tests are about circular arcs (the graded mesh was designed for them)
solve_fam = functools.partial(_solve_fam, arc_model='exact')
solve_fam_batch = functools.partial(_solve_fam_batch, arc_model='exact')


def _perp(cat, alpha):
    return Loads(tip_force=(0.0, alpha * cat.ei / cat.length ** 2))


@pytest.mark.parametrize('alpha', [2.0, 10.0, 21.125])
def test_graded_beats_uniform_at_n12_against_the_closed_form(alpha, closed_form):
    exact, t0 = closed_form(alpha)
    ld = _perp(BLAZER, alpha)
    e = {}
    for sp in ('uniform', 'graded'):
        sh = solve_fam(BLAZER, ld, n_arcs=12, spacing=sp)
        assert sh.converged and sh.spacing == sp
        e[sp] = np.max(np.abs(sh.tip / BLAZER.length - exact))
    # measured: alpha 2: 6.5e-4 -> 6.2e-4; 10: 1.1e-3 -> 5.9e-4; 21.125: 1.7e-3 -> 5.3e-4
    assert e['graded'] < 1e-3
    assert e['graded'] < (0.97 if alpha < 5 else 0.6) * e['uniform'], e


@pytest.mark.parametrize('model', ['exact', 'bezier'])
def test_graded_is_second_order(model, closed_form):
    exact, _ = closed_form(10.0)
    errs = [np.max(np.abs(solve_fam(BLAZER, _perp(BLAZER, 10.0), n_arcs=n, arc_model=model,
                                    spacing='graded').tip / BLAZER.length - exact))
            for n in (6, 12, 24, 48)]
    ratios = np.array(errs[:-1]) / np.array(errs[1:])
    assert np.all((ratios > 3.5) & (ratios < 4.5)), (errs, ratios)


def test_graded_error_keeps_falling_for_large_n(closed_form):
    exact, _ = closed_form(5.0)
    errs = [np.max(np.abs(solve_fam(UNIT, Loads(tip_force=(0, 5.0)), n_arcs=n,
                                    spacing='graded').tip - exact))
            for n in (100, 400, 1600)]
    assert errs[0] > errs[1] > errs[2] and errs[1] / errs[2] > 10, errs


def test_graded_follower_and_point_forces_against_reference():
    cases = [Loads(tip_force=(0.0, 5.0), follower=True),
             Loads(tip_force=(0.5, 2.0), tip_moment=-1.0,
                   point_forces=((0.165, 0.0, 3.0), (0.577, 0.0, -0.5), (0.968, 0.0, 0.1)))]
    for ld in cases:
        ref = solve_elastica(UNIT, ld)
        e = [np.max(np.abs(solve_fam(UNIT, ld, n_arcs=n, spacing='graded').tip - ref.tip))
             for n in (12, 24, 48)]
        assert e[0] > e[1] > e[2] and 3.0 < e[1] / e[2] < 5.0, e
        eu = np.max(np.abs(solve_fam(UNIT, ld, n_arcs=24, spacing='uniform').tip - ref.tip))
        assert e[1] < 1.2 * eu, (e, eu)
    # follower tip forces keep equal arcs (see the fam module docstring)
    sh = solve_fam(UNIT, cases[0], spacing="graded")
    assert np.allclose(sh.arc_lengths, 1 / 12, rtol=0, atol=1e-15)


def test_mesh_follows_the_curvature_change():
    # lateral tip force: kappa' = -(t x F)/EI is largest at the base -> shortest arcs there
    sh = solve_fam(BLAZER, _perp(BLAZER, 21.125), spacing='graded')
    frac = sh.arc_lengths / BLAZER.length
    assert abs(frac.sum() - 1.0) < 1e-14 and np.all(frac > 0)
    assert frac[0] == frac.min() and frac[-1] == frac.max() and frac[-1] > 3 * frac[0]
    # post-buckled compression (force at 170 deg): t x F is smallest at the base and largest
    # where the catheter is turned across the force (mid-length)
    F = 6.4 * BLAZER.ei / BLAZER.length ** 2
    b = np.radians(170.0)
    sh = solve_fam(BLAZER, Loads(tip_force=(F * np.cos(b), F * np.sin(b))), spacing='graded')
    frac = sh.arc_lengths / BLAZER.length
    assert frac[0] == frac.max() and frac[0] > 1.5 * frac.min() and 2 <= np.argmin(frac) <= 8
    # bounded grading: the floor keeps every arc within sqrt(1 + f^2)/f of the longest
    assert frac.max() / frac.min() <= np.hypot(1.0,
                                               mesh.GRADE_FLOOR) / mesh.GRADE_FLOOR * (1 + 1e-9)


def test_pure_moment_and_zero_load_keep_equal_arcs():
    th = 2.0
    sh = solve_fam(BLAZER, Loads(tip_moment=th * BLAZER.ei / BLAZER.length), spacing='graded',
                   n_arcs=7)
    assert np.allclose(sh.arc_lengths, BLAZER.length / 7, rtol=0, atol=1e-18)
    L = BLAZER.length
    assert np.max(np.abs(sh.tip - [L * np.sin(th) / th, L * (1 - np.cos(th)) / th])) < 1e-15
    z = solve_fam(BLAZER, Loads(), spacing='graded')
    assert np.all(z.arc_angles == 0.0) and z.tip[0] == L and z.tip[1] == 0.0


def test_graded_shape_geometry_is_consistent():
    sh = solve_fam(BLAZER, Loads(tip_force=(0.1, 0.2)), spacing='graded')
    c = sh.centerline(241)        # equal arc-length spacing, whatever the arcs
    seg = np.linalg.norm(np.diff(c, axis=0), axis=1)
    assert np.allclose(seg, BLAZER.length / 240, rtol=1e-3)
    assert np.allclose(c[-1], sh.tip, atol=1e-15) and np.allclose(c[0], 0.0)
    # arc ends rebuilt from (arc_lengths, arc_angles) match points_at at the arc boundaries
    s_end = np.cumsum(sh.arc_lengths) / BLAZER.length
    th_end = np.cumsum(sh.arc_angles)
    th0 = th_end - sh.arc_angles
    d = sh.arc_lengths * np.exp(1j * th0) * np.where(
        sh.arc_angles == 0, 1.0,
        (np.exp(1j * sh.arc_angles) - 1) / (1j * np.where(sh.arc_angles == 0, 1, sh.arc_angles)))
    P = np.cumsum(d)
    assert np.allclose(sh.points_at(np.minimum(s_end, 1.0)), np.stack([P.real, P.imag], 1),
                       atol=1e-15)
    assert np.allclose(sh.angles_at(s_end[:-1]), th_end[:-1], atol=1e-14)


@pytest.mark.parametrize('follower', [False, True])
def test_graded_batch_equals_single(follower):
    rng = np.random.default_rng(1)
    F = rng.uniform(-0.3, 0.3, (16, 2))
    M = rng.uniform(-2e-3, 2e-3, 16)
    F[0], M[0] = 0.0, 0.0
    bt = solve_fam_batch(BLAZER, F, M, n_arcs=12, follower=follower, spacing='graded')
    assert bt.converged.all() and bt.arc_lengths.shape == (16, 12)
    for b in range(0, 16, 3):
        sh = solve_fam(BLAZER, Loads(tip_force=F[b], tip_moment=M[b], follower=follower),
                       n_arcs=12, spacing='graded')
        assert np.max(np.abs(sh.tip - bt.tips[b])) < 1e-12
        assert np.max(np.abs(sh.arc_lengths - bt.arc_lengths[b])) < 1e-12
        assert np.max(np.abs(sh.centerline(9) - bt.centerlines(9)[b])) < 1e-12
        assert np.max(np.abs(bt.shape(b).tip - sh.tip)) < 1e-12


def test_warm_start_from_a_graded_shape():
    s0 = solve_fam(UNIT, Loads(tip_force=(0.0, 3.0)), spacing='graded')
    warm = solve_fam(UNIT, Loads(tip_force=(0.1, 3.1)), initial=s0, spacing='graded')
    cold = solve_fam(UNIT, Loads(tip_force=(0.1, 3.1)), spacing='graded')
    assert np.max(np.abs(warm.tip - cold.tip)) < 1e-12


def test_fast_path_grading_equals_the_batched_one():
    rng = np.random.default_rng(2)
    for follower in (False, True):
        phi = rng.normal(0, 0.3, 12)
        F = complex(*rng.normal(0, 1, 2))
        f1, s1 = mesh.fast_grade(phi, F, follower)
        f2 = mesh.graded_fractions(phi[None], np.array([F]), follower)
        s2 = mesh.remap(phi[None], f2)
        assert np.allclose(f1, f2[0], atol=1e-15) and np.allclose(s1, s2[0], atol=1e-14)


def test_remap_keeps_the_tangent_angle_curve():
    rng = np.random.default_rng(4)
    phi = rng.normal(0, 0.5, (3, 8))
    new = rng.uniform(0.2, 1.0, (3, 8))
    new /= new.sum(axis=1, keepdims=True)
    p2 = mesh.remap(phi, new)
    assert np.allclose(p2.sum(axis=1), phi.sum(axis=1), atol=1e-14)
    # equal arcs' ends are nodes of p2's curve?
    back = mesh.remap(p2, np.full((3, 8), 1 / 8), new)
    # theta is piecewise linear on the old arcs; sampling it at the new nodes and back at the
    # old nodes reproduces the old nodes exactly only where they coincide: check the ends
    assert np.allclose(back.sum(axis=1), phi.sum(axis=1), atol=1e-14)


def test_jacobian_with_unequal_arcs_per_case():
    rng = np.random.default_rng(3)
    frac = rng.uniform(0.3, 1.0, (2, 7))
    frac /= frac.sum(axis=1, keepdims=True)
    for follower in (False, True):
        prob = problem.make_problem(7, 1.0, 1.0, np.array([2.0 - 3.0j, -1.0 + 1.0j]), follower,
                                  np.array([0.7, -0.2]), [], frac)
        loads, m = prob.loads(1.0)
        phi = rng.normal(0, 0.6, (2, 7))
        r, fac, _ = equations.evaluate(phi, prob.l, prob.w, loads, m)
        J = linsolve.dense_jacobian(prob.w, fac)
        h = 1e-7
        for b in range(2):
            Jn = np.empty((7, 7))
            for j in range(7):
                p = phi.copy()
                p[b, j] += h
                Jn[:,
                   j] = (equations.evaluate(p, prob.l, prob.w, loads, m,
                                            jac=False)[0][b] - r[b]) / h
            assert np.max(np.abs(J[b] - Jn)) < 1e-5
        rhs = rng.normal(size=(2, 7))
        x = linsolve.structured_solve(prob.w, fac, rhs)
        assert np.allclose(np.einsum('bij,bj->bi', J, x), rhs, atol=1e-10)


@given(phi=st.lists(st.floats(-1.5, 1.5), min_size=2, max_size=20),
       fx=st.floats(-10, 10), fy=st.floats(-10, 10), follower=st.booleans(),
       k=st.floats(1e-3, 1e3))
@settings(max_examples=60, deadline=None)
def test_graded_fractions_properties(phi, fx, fy, follower, k):
    phi = np.array([phi])
    F = np.array([complex(fx, fy)])
    f = mesh.graded_fractions(phi, F, follower)
    assert f.shape == phi.shape and np.all(np.isfinite(f)) and np.all(f > 0)
    assert abs(f.sum() - 1.0) < 1e-12
    assert f.max() / f.min() <= np.hypot(1.0, mesh.GRADE_FLOOR) / mesh.GRADE_FLOOR * (1 + 1e-9)
    # scale-free in the force, mirror-symmetric
    assert np.allclose(mesh.graded_fractions(phi, k * F, follower), f, atol=1e-12)
    assert np.allclose(mesh.graded_fractions(-phi, np.conj(F), follower), f, atol=1e-12)


def test_bad_spacing_is_refused():
    with pytest.raises(ValueError, match='spacing'):
        solve_fam(BLAZER, Loads(), spacing='chebyshev')
    with pytest.raises(ValueError, match='spacing'):
        solve_fam_batch(BLAZER, np.zeros((2, 2)), spacing=None)


def test_graded_fractions_tiny_curvature_change_does_not_underflow():
    """Regression (found by hypothesis): kappa'^2 of a 1e-161 bend underflowed, so the mesh
    changed with the force scale; the monitor is normalised by max|kappa'| first."""
    phi = np.array([[0.0, 2.8002983266425355e-161]])
    F = np.array([1.0 + 0.0j])
    a = mesh.graded_fractions(phi, F)
    assert np.allclose(mesh.graded_fractions(phi, 0.5 * F), a, atol=1e-15)
    assert np.allclose(mesh.fast_grade(phi[0], 0.5, False)[0], a[0], atol=1e-15)


def test_graded_fractions_denormal_force_keeps_its_direction():
    """Regression (found by hypothesis): 5e-324j N lost its direction in t x F, so the mesh
    changed with the force scale; the forces are normalised first."""
    phi = np.array([[1.5, 0.0]])
    ref = mesh.graded_fractions(phi, np.array([1j]))
    for F in (1e-323j, 5e-324j, 1e300j):
        np.testing.assert_allclose(mesh.graded_fractions(phi, np.array([F])), ref, atol=1e-15)

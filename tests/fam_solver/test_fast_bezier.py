"""The thesis' Bezier arcs on the fast path (issue 15, round 4): the power series of the Eq. 23
integrals against the quadrature of ``bezier.BezierModel``, the kernel's exact Jacobian
against the general path's (itself checked against central differences in test_bezier.py),
and the fast-path solutions against the general path's and the rod reference. Iterations are
counted, not timed (timing: ``scripts/bench fam``)."""
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import fam_solver.fam as fam_mod
from fam_solver import Catheter, Loads, fast, fast_bezier, solve_elastica, solve_fam
from fam_solver.arcs import arc_funcs
from fam_solver.bezier import BezierModel, BezierResidual
from fam_solver.fast_newton import FAST_DENSE_MAX_N, fast_tip_newton, jacobian_at
from fam_solver.globalise import solve_cases
from fam_solver.linsolve import dense_jacobian
from fam_solver.problem import build_problem, make_problem

THESIS = Catheter(length=0.040, ei=7.5e-4)
BLAZER = Catheter(length=0.065, ei=6e-5)
LOADS = [Loads(tip_force=(F * np.cos(np.radians(d)), F * np.sin(np.radians(d))), tip_moment=m)
         for F, d, m in [(1.0, 90, 0.0), (4.0, 60, 0.0), (9.8, 90, 0.0), (5.0, 135, 0.01),
                         (0.0, 0, 0.03), (2.0, -90, 0.02), (6.0, 30, -0.015), (3.0, 170, 0.0)]]


def _series_local(phi, l, EI, M, Floc):
    """r, dr/dM, K (dr = Im(conj K dFloc)) and dr/dphi at fixed wrench from the series."""
    n = phi.size
    T = fast_bezier.arc_terms(phi, np.max(np.abs(phi)))
    H = np.stack([T[:, :4].real, T[:, :4].imag, T[:, 8:12].real], 2)      # (n, 4, 3)
    Hd = np.stack([T[:, 4:8].real, T[:, 4:8].imag, T[:, 12:16].real], 2)
    w = l / EI
    f = Floc * l * w
    a = np.stack([M * w, f.imag, -f.real, -np.ones(n)], 1)
    b = np.stack([f.imag, -f.real, -np.ones(n)], 1)
    r = np.einsum('np,nq,npq->n', a, b, H)
    gP = np.einsum('np,nq,npq->n', a, b, Hd)
    gM = np.einsum('nq,nq->n', b, H[:, 0]) * w
    dfy = np.einsum('nq,nq->n', b, H[:, 1]) + np.einsum('np,np->n', a, H[:, :, 0])
    dfx = -(np.einsum('nq,nq->n', b, H[:, 2]) + np.einsum('np,np->n', a, H[:, :, 1]))
    return r, gM, (dfy - 1j * dfx) * l * w, gP, T


@pytest.mark.parametrize('lo, hi', [(0.0, 1e-6), (0.0, 0.05), (0.05, 0.5), (0.5, 2.3),
                                    (2.2, 2.4), (2.3, 3.6), (3.6, 4.9)])
def test_series_equal_the_quadrature(lo, hi):
    """Residual, dr/dM, dr/dFloc and dr/dphi of every arc from the series (about 0 and about
    +-3.6) equal the quadrature's (``BezierModel._local`` and ``_second``), for random end
    wrenches, both signs of phi; g and g' equal ``arcs.arc_funcs``."""
    rng = np.random.default_rng(int(hi * 1000))
    n = 50
    prob = build_problem(BLAZER, n, np.array([0.1 + 0.2j]), False, np.array([0.0]), [])
    bm = BezierModel(prob)
    l, EI = prob.l, prob.EI
    phi = rng.uniform(lo, hi, n) * np.sign(rng.normal(size=n))
    M = rng.normal(size=n) * 1e-3
    Fl = (rng.normal(size=n) + 1j * rng.normal(size=n)) * 0.2
    r, gM, K, R, dR = bm._local(phi[None], l, M[None], Fl[None])
    curves = bm._curves(phi[None], l)
    d2c, d2end, d2kap = bm._second(curves)
    d2R = (np.conj(d2end - d2c) * Fl[None, :, None]).imag - EI * d2kap
    gP = bm._quad(dR * dR + R * d2R) * (l / EI) ** 2
    rs, gMs, Ks, gPs, T = _series_local(phi, l, EI, M, Fl)
    scale = 1.0 + np.abs(r[0])
    assert np.max(np.abs(rs - r[0]) / scale) < 1e-13
    assert np.max(np.abs(gMs - gM[0])) < 1e-13 * np.max(np.abs(gM))
    assert np.max(np.abs(Ks - K[0])) < 1e-12 * np.max(np.abs(K))
    assert np.max(np.abs(gPs - gP[0])) < 1e-10 * np.max(np.abs(gP))
    G, _, GP, _ = arc_funcs(phi)
    assert np.max(np.abs(T[:, 16] - G)) < 1e-14
    assert np.max(np.abs(T[:, 17] - GP)) < 1e-13
    assert np.max(np.abs(T[:, 8:16].imag)) == 0.0


def test_arcs_beyond_the_series_are_left_to_the_general_path():
    """An arc turned by more than MAX_PHI: no series (None), the kernel reports no
    convergence, and solve_fam still solves it (general path, the same equilibrium)."""
    assert fast_bezier.arc_terms(np.array([0.1, 5.0]), 5.0) is None
    assert fast_bezier.arc_terms(np.array([0.1, -4.8]), 4.8) is not None
    ld = Loads(tip_moment=5.5 * THESIS.ei / THESIS.length)       # pure moment: 5.5 rad
    l, w, _ = fast._equal_arcs(1, THESIS.length, THESIS.ei)
    out = fast_tip_newton(1, l, w, 0j, ld.tip_moment, False, np.array([5.5]), 12, bezier=True)
    assert not out[1]
    sh = solve_fam(THESIS, ld, n_arcs=1, arc_model='bezier')
    prob = build_problem(THESIS, 1, np.array([0j]), False, np.array([ld.tip_moment]), [])
    phi, conv, _, _, _ = solve_cases(prob, 1, 'bezier')
    assert sh.converged and conv[0]
    assert abs(sh.arc_angles[0] - phi[0, 0]) < 1e-10


@pytest.mark.parametrize('follower', [False, True])
@pytest.mark.parametrize('n', [1, 2, 5, 12])
def test_kernel_jacobian_equals_the_general_paths(follower, n):
    """The kernel's dense Jacobian and residual at random arc angles (graded arcs, a tip
    moment, dead or follower force) equal those of ``BezierResidual`` (exact Jacobian)."""
    rng = np.random.default_rng(n + 7 * follower)
    f = rng.uniform(0.5, 2.0, size=n)
    frac = f / f.sum()
    F, m = 3.0 + 4.0j, 0.01
    prob = make_problem(n, 0.04, 7.5e-4, np.array([F]), follower, np.array([m]), [],
                        frac[None])
    bz = BezierResidual(prob)
    loads, mm = prob.loads(1.0)
    for _ in range(3):
        phi = rng.normal(size=n) * 0.6
        r, state = bz.residual_state(phi[None], loads, mm)
        w, fac = bz.factors(state)
        J = dense_jacobian(w, fac)[0]
        l = 0.04 * frac
        Jk = jacobian_at(phi, l, l / 7.5e-4, F, m, follower, False, bezier=True)
        assert np.max(np.abs(Jk - J)) < 1e-11 * max(1.0, np.max(np.abs(J)))
        res = fast_tip_newton(n, l, l / 7.5e-4, F, m, follower, phi, 0, bezier=True)[3]
        assert abs(res - np.max(np.abs(r))) < 1e-13 * max(1.0, res)


@pytest.mark.parametrize('follower', [False, True])
def test_banded_step_equals_the_dense_step(follower):
    """One Newton step of the kernel with the O(N) banded solve equals the dense one."""
    n = 40
    rng = np.random.default_rng(3)
    l, w, _ = fast._equal_arcs(n, THESIS.length, THESIS.ei)
    phi = rng.normal(size=n) * 0.05
    F, m = 2.0 - 3.0j, 0.005
    args = (n, l, w, F, m, follower, phi, 1)
    kw = dict(step_limit=np.inf, rtol=-1.0)
    a = fast_bezier.bezier_tip_newton(*args, dense=True, **kw)
    b = fast_bezier.bezier_tip_newton(*args, dense=False, **kw)
    assert a[3] < fast_bezier.bezier_tip_newton(*args[:-1], 0, dense=True, **kw)[3]
    assert np.max(np.abs(a[0] - b[0])) < 1e-12


def _general(cat, ld, n, follower=False):
    """The general path's Bezier solution from the circular-arc solution."""
    F = complex(*ld.tip_force)
    ex = fast.fast_solve(n, cat.length, cat.ei, F, ld.tip_moment, follower)
    prob = build_problem(cat, n, np.array([F]), follower, np.array([ld.tip_moment]), [])
    phi, conv, _, _, _ = solve_cases(prob, 1, 'bezier', None if ex is None else ex[0][None])
    return phi[0], conv[0], prob


@pytest.mark.parametrize('n', [1, 2, 3, 8, 24, FAST_DENSE_MAX_N + 1, 100])
def test_fast_path_solution_is_the_general_paths(n, monkeypatch):
    """Tip forces, moments, a post-buckled compression: the fast path (no general-path call)
    gives the general path's Bezier equilibrium, with the quadrature residual solved to
    1e-12, and the same stability verdict."""
    def no_general(*a, **kw):
        raise AssertionError('general path used')
    for ld in LOADS:
        monkeypatch.setattr(fam_mod, 'solve_cases', no_general)
        sh = solve_fam(THESIS, ld, n_arcs=n, arc_model='bezier')
        monkeypatch.undo()
        phi, conv, prob = _general(THESIS, ld, n)
        assert sh.converged and conv
        assert np.max(np.abs(sh.arc_angles - phi)) < 1e-10, (n, ld)
        loads, m = prob.loads(1.0)
        r = BezierResidual(prob).residual(sh.arc_angles[None], loads, m)
        assert np.max(np.abs(r)) <= 1e-13 + 1.5e-12 * np.max(np.abs(sh.arc_angles))
        ref = solve_fam(THESIS, ld, n_arcs=n, arc_model='exact')
        assert sh.stable == ref.stable


@pytest.mark.parametrize('n', [2, 12, 80])
def test_follower_forces_on_the_fast_path(n):
    """Follower (tendon) tip forces: the general path's equilibrium."""
    for F in (1.0 + 2.0j, -2.0 + 5.0j, 4.0j):
        ld = Loads(tip_force=(F.real, F.imag), follower=True)
        sh = solve_fam(THESIS, ld, n_arcs=n, arc_model='bezier')
        phi, conv, _ = _general(THESIS, ld, n, follower=True)
        assert sh.converged and conv
        assert np.max(np.abs(sh.arc_angles - phi)) < 1e-10


def test_long_arcs_with_another_equilibrium_restart_from_the_circular_solution():
    """Thesis 5 N at 135 deg with 10 mN m on ONE arc: Newton from the small-deflection start
    reaches another Bezier equilibrium (tip angle 0.77 rad, rejected); the restart from the
    circular-arc solution (2.71 rad) finds the general path's 2.80 rad in few iterations
    (load continuation took 37)."""
    ld = LOADS[3]
    sh = solve_fam(THESIS, ld, n_arcs=1, arc_model='bezier')
    phi, conv, _ = _general(THESIS, ld, 1)
    assert sh.converged and abs(sh.tip_angle - phi.sum()) < 1e-10
    assert abs(sh.tip_angle - 2.80) < 0.01
    assert sh.iterations <= 16


def test_bezier_iterations_are_those_of_circular_arcs():
    """Started from the small-deflection shape, as circular arcs are: at most two Newton
    iterations more than circular arcs on the bench's loads at N = 2-64, and at most 10 %
    more in all (counted; measured: equal on 116 of 153 (N, load), 591 against 545 in all)."""
    loads = LOADS + [Loads(tip_force=(F * np.cos(b), F * np.sin(b)))
                     for F in (0.1, 0.2, 0.3) for b in (np.pi / 4, np.pi / 2, 3 * np.pi / 4)]
    total = np.zeros(2, dtype=int)
    for n in (2, 4, 8, 16, 32, 64):
        for i, ld in enumerate(loads):
            cat = THESIS if i < len(LOADS) else BLAZER
            b = solve_fam(cat, ld, n_arcs=n, arc_model='bezier').iterations
            e = solve_fam(cat, ld, n_arcs=n, arc_model='exact').iterations
            assert b <= e + 2, (n, ld, b, e)
            total += (b, e)
    assert total[0] <= 1.1 * total[1], total


def test_bezier_fast_path_against_the_rod_reference():
    """Second order against solve_elastica, within 25 % of circular arcs' error, as before."""
    for ld in LOADS[:5]:
        ref = solve_elastica(THESIS, ld)
        for n in (12, 24):
            eb = np.max(np.abs(solve_fam(THESIS, ld, n_arcs=n, arc_model='bezier').tip - ref.tip))
            ee = np.max(np.abs(solve_fam(THESIS, ld, n_arcs=n, arc_model='exact').tip - ref.tip))
            assert abs(eb - ee) <= 0.25 * ee + 1e-10 * THESIS.length, (ld, n, eb, ee)


@pytest.mark.parametrize('follower', [False, True])
@pytest.mark.parametrize('n, dense', [(4, True), (30, True), (30, False)])
def test_newton_step_is_that_of_the_scaled_residual(follower, n, dense):
    """The kernel's Newton step solves for r / s, s = -(dr/dM) EI/l, with its Jacobian: it
    equals the step from central differences of r / s (the general path's residual and
    dr/dM), dense and banded, dead and follower forces."""
    F, m = (2.0 + 5.0j, 0.004) if not follower else (-1.0 + 4.0j, 0.004)
    ld = Loads(tip_force=(F.real, F.imag), tip_moment=m, follower=follower)
    sol = solve_fam(THESIS, ld, n_arcs=n, arc_model='bezier').arc_angles
    rng = np.random.default_rng(n)
    phi = sol + rng.normal(size=n) * 0.02 / np.sqrt(n)
    prob = build_problem(THESIS, n, np.array([F]), follower, np.array([m]), [])
    bz = BezierResidual(prob)
    loads, mm = prob.loads(1.0)

    def scaled(p):
        r, state = bz.residual_state(p[None], loads, mm)
        return r[0] / (-state[7][0] / prob.w)

    h = 1e-6
    Jfd = np.stack([(scaled(phi + h * e) - scaled(phi - h * e)) / (2 * h) for e in np.eye(n)], 1)
    want = phi - np.linalg.solve(Jfd, scaled(phi))
    l, w, _ = fast._equal_arcs(n, THESIS.length, THESIS.ei)
    got = fast_bezier.bezier_tip_newton(n, l, w, F, m, follower, phi, 1, step_limit=np.inf,
                                        rtol=-1.0, dense=dense)[0]
    assert np.max(np.abs(got - want)) < 1e-6 * np.max(np.abs(want - phi))


@given(fx=st.floats(-25, 25), fy=st.floats(-25, 25), m=st.floats(-6, 6),
       follower=st.booleans(), n=st.sampled_from([1, 2, 3, 5, 12, 30, 70]))
@settings(max_examples=40, deadline=None)
def test_fuzz_bezier_finite_and_solved(fx, fy, m, follower, n):
    """Random tip loads (F L^2/EI <= 35, |M| L/EI <= 6, dead or follower): finite numbers;
    a converged Bezier answer solves the quadrature model's equations (an independent check of
    the series kernel); where the general path from the circular-arc solution also finds a
    stable equilibrium on the same branch, it is the same one."""
    cat = Catheter(1.0, 1.0)
    ld = Loads(tip_force=(fx, fy), tip_moment=m, follower=follower)
    sh = solve_fam(cat, ld, n_arcs=n, arc_model='bezier')
    assert np.all(np.isfinite(sh.arc_angles)) and np.all(np.isfinite(sh.tip))
    if not sh.converged:
        assert sh.warning
        return
    fol = follower and complex(fx, fy) != 0      # (without a tip force: ignored)
    prob = build_problem(cat, n, np.array([complex(fx, fy)]), fol, np.array([m]), [])
    loads, mm = prob.loads(1.0)
    r = BezierResidual(prob).residual(sh.arc_angles[None], loads, mm)
    assert np.max(np.abs(r)) <= 1e-12 * max(1.0, np.max(np.abs(sh.arc_angles)))
    phi, conv, _ = _general(cat, ld, n, follower=fol)
    if conv and sh.stable and abs(phi.sum() - sh.tip_angle) < 0.5:
        assert np.max(np.abs(phi - sh.arc_angles)) < 1e-8


def test_warm_start_is_used_for_bezier_arcs():
    """The node warm-starts from the previous shape: for Bezier arcs the fast path takes it
    (fewer iterations, the same equilibrium as a cold solve)."""
    for n in (12, 40):
        s0 = solve_fam(BLAZER, Loads(tip_force=(0.05, 0.2)), n_arcs=n, arc_model='bezier')
        ld = Loads(tip_force=(0.05, 0.21))
        warm = solve_fam(BLAZER, ld, n_arcs=n, arc_model='bezier', initial=s0)
        cold = solve_fam(BLAZER, ld, n_arcs=n, arc_model='bezier')
        assert warm.converged and np.max(np.abs(warm.arc_angles - cold.arc_angles)) < 1e-10
        assert warm.iterations < cold.iterations

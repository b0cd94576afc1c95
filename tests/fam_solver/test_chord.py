"""Chord steps in the fast Newton kernels (issue 15, round 5): near the solution a step may
reuse the last Jacobian's LU factors (``linsolve.chord_pays``). The answer must be the one
pure Newton gives, to the same tolerance, in no more steps, with fewer Jacobians built."""
import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from fam_solver import (Catheter, Loads, equations, fast, fast_bezier, fast_newton, linsolve,
                        problem, solve_fam)
from fam_solver.linsolve import CHORD_GROWTH, CHORD_MAX_RES, chord_pays

BLAZER = Catheter(length=0.065, ei=6e-5)
UNIT = Catheter(1.0, 1.0)
THESIS = Catheter(length=0.040, ei=7.5e-4)
MODELS = ('exact', 'clothoid', 'bezier')


def test_chord_pays_hand_checked():
    """The rule on numbers worked out by hand (tol 1e-13)."""
    tol = 1e-13
    # after a Newton step 1e-4 -> 1e-9 (q = 1e-5): chord ratio 4e-5 -> 4e-14 < tol in one
    # step, as Newton: chord
    assert chord_pays(1e-9, 1e-4, 1e-4, tol, False)
    # the same ratio but 1e-6 left: chord 1e-6 -> 4e-11 -> 1.6e-15 (2 steps), Newton
    # 1e-6 -> 1e-6 * 1e-5 * 1e-6 / 1e-4 = 1e-13 (1 step): Newton
    assert not chord_pays(1e-6, 1e-1, 1e-1, tol, False)
    # a slow step (q = 0.2): never
    assert not chord_pays(2e-3, 1e-2, 1e-2, tol, False)
    # a Jacobian built far from the solution: never
    assert not chord_pays(1e-9, 1e-1, 10 * CHORD_MAX_RES, tol, False)
    # the growth factor of the first chord step after a Newton step: q = 1e-4, 5e-10 left.
    # At the ratio q itself one chord step would do (5e-14); at CHORD_GROWTH q it needs two,
    # Newton one (5e-10 * 1e-4 * 5e-10 / 1e-6 = 2.5e-17): Newton after a Newton step, chord
    # after a chord step (whose ratio is measured, not predicted)
    assert CHORD_GROWTH > 2.0
    assert not chord_pays(5e-10, 5e-6, 1e-6, tol, False)
    assert chord_pays(5e-10, 5e-6, 1e-6, tol, True)
    # not a contraction at all
    assert not chord_pays(1e-9, 1e-9, 1e-9, tol, True)


def _kernel_runs(monkeypatch, cat, ld, n, model, chord):
    """fast_tip_newton from the fast path's start, with or without chord steps; returns
    (phi, converged, iterations, residual, Jacobians factorised)."""
    count = [0]
    real_n, real_b = fast_newton._dgesv, fast_bezier._dgesv

    def counting(real):
        def f(*a, **k):
            count[0] += 1
            return real(*a, **k)
        return f

    monkeypatch.setattr(fast_newton, '_dgesv', counting(real_n))
    monkeypatch.setattr(fast_bezier, '_dgesv', counting(real_b))
    if not chord:
        monkeypatch.setattr(fast_newton, 'chord_pays', lambda *a: False)
        monkeypatch.setattr(fast_bezier, 'chord_pays', lambda *a: False)
    L, EI = cat.length, cat.ei
    F, m = complex(*ld.tip_force), ld.tip_moment
    l, w, lever = fast._equal_arcs(n, L, EI)
    lin = w * (m + F.imag * lever)
    start = fast._linear_start(lin, float(lin.sum()), F, m, ld.follower, L, EI)
    out = fast_newton.fast_tip_newton(n, l, w, F, m, ld.follower, start, 30,
                                      clothoid=model == 'clothoid', bezier=model == 'bezier')
    monkeypatch.undo()
    return out[0], out[1], out[2], out[3], count[0]


def _loads():
    out = []
    for F, deg, m in [(1.0, 90, 0.0), (4.0, 60, 0.0), (9.8, 90, 0.0), (2.0, -90, 0.02),
                      (6.0, 30, -0.015), (3.0, 170, 0.0)]:
        b = math.radians(deg)
        out.append((THESIS, Loads(tip_force=(F * math.cos(b), F * math.sin(b)), tip_moment=m)))
    for F in (0.1, 0.3):
        for b in (math.pi / 4, 3 * math.pi / 4):
            out.append((BLAZER, Loads(tip_force=(F * math.cos(b), F * math.sin(b)))))
    out.append((BLAZER, Loads(tip_force=(0.0, 0.2), follower=True)))
    return out


@pytest.mark.parametrize('model', MODELS)
def test_chord_steps_give_newtons_answer_in_no_more_steps(monkeypatch, model):
    """Over loads and N = 1-64 (dense kernels): the same solution as pure Newton (to the
    tolerance), converged with max|r| <= 1e-13 + 1e-12 max|phi|; per case at most one step
    more than Newton, in all no more steps, and fewer Jacobians factorised."""
    steps = [0, 0]
    jacs = [0, 0]
    worse = 0
    for cat, ld in _loads():
        for n in (1, 2, 4, 8, 12, 24, 64):
            p1, c1, it1, r1, j1 = _kernel_runs(monkeypatch, cat, ld, n, model, True)
            p0, c0, it0, r0, j0 = _kernel_runs(monkeypatch, cat, ld, n, model, False)
            assert c0 and c1, (ld, n)
            pmax = float(np.max(np.abs(p1)))
            assert r1 <= 1e-13 + 1e-12 * pmax
            assert np.max(np.abs(p1 - p0)) <= 1e-11 * max(1.0, pmax), (ld, n)
            assert it1 <= it0 + 1, (ld, n, it1, it0)
            worse += it1 > it0
            steps[0] += it0
            steps[1] += it1
            jacs[0] += j0
            jacs[1] += j1
    assert steps[1] <= steps[0], steps
    assert worse <= 0.1 * len(_loads()) * 7, worse
    assert jacs[1] <= 0.95 * jacs[0], jacs


@settings(max_examples=40, deadline=None)
@given(f=st.floats(0.0, 20.0), beta=st.floats(-math.pi, math.pi), m=st.floats(-4.0, 4.0),
       n=st.sampled_from([1, 2, 3, 5, 12, 24]), model=st.sampled_from(MODELS))
def test_solutions_with_chord_steps_solve_the_equations(f, beta, m, n, model):
    """Random tip loads on the unit catheter (F L^2/EI <= 20, |M| L/EI <= 4): whatever the
    mix of Newton and chord steps, the solution is finite, converged, and meets the
    tolerance (circular and clothoid arcs: the residual re-evaluated by
    ``equations.evaluate``, not the kernel's own bookkeeping)."""
    ld = Loads(tip_force=(f * math.cos(beta), f * math.sin(beta)), tip_moment=m)
    sh = solve_fam(UNIT, ld, n_arcs=n, arc_model=model)
    assert np.all(np.isfinite(sh.arc_angles)) and np.all(np.isfinite(sh.tip))
    assert sh.converged
    tol = 1e-13 + 1e-12 * np.abs(sh.arc_angles).max()
    assert sh.residual <= tol
    if model != 'bezier':
        prob = problem.make_problem(n, 1.0, 1.0, np.array([complex(*ld.tip_force)]), False,
                                    np.array([m]), [], clothoid=model == 'clothoid')
        loads, mm = prob.loads(1.0)
        r = equations.evaluate(sh.arc_angles[None], prob.l, prob.w, loads, mm, jac=False,
                               clothoid=model == 'clothoid')[0]
        assert np.max(np.abs(r)) <= 10 * tol


def test_chord_constants_are_sane():
    """The rule's guards: a chord step only from a Jacobian near the solution and only for a
    real contraction."""
    assert 0.0 < linsolve.CHORD_MAX_RATIO < 1.0
    assert 0.0 < CHORD_MAX_RES <= fast_newton.QUASI_ABOVE

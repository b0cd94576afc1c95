"""fam_solver.sensitivity.shape_sensitivity: the analytic d(points)/d(tip force) of a converged
FAM shape equals central finite differences of solve_fam (exactly on equal arcs, to the size
of the re-grading effect on graded arcs); points and tangents equal the Shape's own."""
import functools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fam_solver import Catheter, Loads
from fam_solver import solve_fam as _solve_fam
from fam_solver.model import arc_shape
from fam_solver.sensitivity import shape_sensitivity

CAT = Catheter(length=0.065, ei=6.0e-5)
S = np.linspace(0.0, 1.0, 24)

# the sensitivity is that of circular arcs (arc_model='exact')
solve_fam = functools.partial(_solve_fam, arc_model='exact')


def _fd(f, m, spacing, n_arcs, h=1e-6):
    """Central differences of solve_fam points, (k, 2, 2)."""
    cols = []
    for c in range(2):
        fp, fm = np.array(f, float), np.array(f, float)
        fp[c] += h
        fm[c] -= h
        pp = solve_fam(CAT, Loads(tip_force=tuple(fp), tip_moment=m), n_arcs=n_arcs,
                       spacing=spacing).points_at(S)
        pm = solve_fam(CAT, Loads(tip_force=tuple(fm), tip_moment=m), n_arcs=n_arcs,
                       spacing=spacing).points_at(S)
        cols.append((pp - pm) / (2 * h))
    return np.stack(cols, axis=-1)


@pytest.mark.parametrize('f, m', [((0.05, 0.1), 0.0), ((-0.1, 0.2), 0.0), ((0.0, 0.3), 0.0),
                                  ((0.2, -0.05), 0.0), ((0.01, 0.02), 1e-3),
                                  ((-0.2, 0.04), 0.0)])
def test_equals_finite_differences_on_equal_arcs(f, m):
    sh = solve_fam(CAT, Loads(tip_force=f, tip_moment=m), n_arcs=24, spacing='uniform')
    p, dp, t = shape_sensitivity(sh, f, S, CAT.ei, tip_moment=m)
    np.testing.assert_allclose(p, sh.points_at(S), atol=1e-15)
    ang = sh.angles_at(S)
    np.testing.assert_allclose(t, np.c_[np.cos(ang), np.sin(ang)], atol=1e-14)
    fd = _fd(f, m, 'uniform', 24)
    assert np.abs(fd).max() > 0.05                       # a real, nonzero sensitivity (m/N)
    assert np.abs(dp - fd).max() < 1e-8 * np.abs(fd).max()
    assert np.abs(dp[0]).max() == 0.0                    # the clamped base does not move


@pytest.mark.parametrize('f', [(0.05, 0.1), (-0.1, 0.2), (0.2, -0.05)])
def test_close_to_finite_differences_on_graded_arcs(f):
    """Graded arcs move with the force; holding them fixed misses only that (measured
    ~1e-4 relative), far below what a Gauss-Newton step needs."""
    sh = solve_fam(CAT, Loads(tip_force=f), n_arcs=24, spacing='graded')
    assert np.ptp(sh.arc_lengths) > 0
    p, dp, _ = shape_sensitivity(sh, f, S, CAT.ei)
    np.testing.assert_allclose(p, sh.points_at(S), atol=1e-15)
    fd = _fd(f, 0.0, 'graded', 24)
    assert np.abs(dp - fd).max() < 1e-3 * np.abs(fd).max()


def test_unloaded_straight_catheter():
    """At zero load the sensitivity is the linear cantilever: dy/dfy = s^2 (3L - s)/(6 EI)
    at s (in the FAM's circular-arc discretisation: to second order in 1/N), dx/dF = 0."""
    sh = solve_fam(CAT, Loads(tip_force=(0.0, 1e-300)), n_arcs=48, spacing='uniform')
    p, dp, _ = shape_sensitivity(sh, (0.0, 0.0), S, CAT.ei)
    x = S * CAT.length
    np.testing.assert_allclose(p[:, 0], x, atol=1e-15)
    exact = x ** 2 * (3 * CAT.length - x) / (6 * CAT.ei)
    np.testing.assert_allclose(dp[:, 1, 1], exact, rtol=3e-3, atol=1e-12)
    assert abs(dp[-1, 1, 1] / exact[-1] - 1) < 3e-4        # tip: L^3 / (3 EI)
    assert np.abs(dp[:, 0, :]).max() < 1e-12 and np.abs(dp[:, 1, 0]).max() < 1e-12


def test_bad_input():
    sh = solve_fam(CAT, Loads(tip_force=(0.0, 0.1)), n_arcs=12)
    with pytest.raises(ValueError, match='tip_force'):
        shape_sensitivity(sh, (np.nan, 0.1), S, CAT.ei)
    with pytest.raises(ValueError, match='tip_force'):
        shape_sensitivity(sh, (0.0, 0.1, 0.0), S, CAT.ei)
    with pytest.raises(ValueError, match='ei'):
        shape_sensitivity(sh, (0.0, 0.1), S, -1.0)
    with pytest.raises(ValueError, match='ei'):
        shape_sensitivity(sh, (0.0, 0.1), S, 0.0)
    with pytest.raises(ValueError, match='s must'):
        shape_sensitivity(sh, (0.0, 0.1), [0.5, 1.5], CAT.ei)
    with pytest.raises(ValueError, match='tip_moment'):
        shape_sensitivity(sh, (0.0, 0.1), S, CAT.ei, tip_moment=np.inf)
    bz = solve_fam(CAT, Loads(tip_force=(0.0, 0.1)), n_arcs=6, arc_model='bezier')
    with pytest.raises(ValueError, match='shape'):
        shape_sensitivity(bz, (0.0, 0.1), S, CAT.ei)


@settings(max_examples=20, deadline=None)
@given(st.floats(0.0, 0.4), st.floats(-np.pi, np.pi), st.floats(1e-7, 1e-4))
def test_property_predicts_a_small_force_change(mag, ang, dmag):
    """First-order prediction: points(f + df) - points(f) - dpoints df = O(|df|^2) on a
    fixed (equal-arc) mesh, for forces in every direction."""
    f = np.array([mag * np.cos(ang), mag * np.sin(ang)])
    sh = solve_fam(CAT, Loads(tip_force=tuple(f)), n_arcs=12, spacing='uniform')
    if not (sh.converged and sh.stable):
        return
    p, dp, _ = shape_sensitivity(sh, f, S, CAT.ei)
    df = dmag * np.array([0.6, -0.8])
    s2 = solve_fam(CAT, Loads(tip_force=tuple(f + df)), n_arcs=12, spacing='uniform',
                   initial=sh)
    if abs(s2.tip_angle - sh.tip_angle) > 0.1:          # another branch (near buckling)
        return
    err = np.abs(s2.points_at(S) - p - dp @ df).max()
    # second order: the curvature of points(f) grows like the sensitivity squared / L near
    # buckling (mag 0.031 N at 172 deg: |dp| 2.8 m/N, err 1.2e-6 m at |df| 6e-5 N)
    g = np.abs(dp).max()
    assert err < 50.0 * dmag ** 2 + 10.0 * (g * dmag) ** 2 / CAT.length + 1e-13


def test_a_shape_that_did_not_converge_is_refused():
    """The sensitivity is the implicit-function theorem at r(phi, F) = 0: a shape whose solve
    did not converge (same arc angles, flagged) gets a ValueError, not a silent derivative."""
    sh = solve_fam(CAT, Loads(tip_force=(0.0, 0.1)), n_arcs=12)
    assert shape_sensitivity(sh, (0.0, 0.1), S, CAT.ei)[1].shape == (S.size, 2, 2)
    bad = arc_shape(CAT.length, sh.arc_angles, converged=False, iterations=50,
                    arc_model='exact', warning='not converged')
    with pytest.raises(ValueError, match='converged'):
        shape_sensitivity(bad, (0.0, 0.1), S, CAT.ei)

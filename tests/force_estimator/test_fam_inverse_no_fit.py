"""The FAM inversion's statuses say when its force must not be used.

- A shape no tip force makes is refused ('no_fit'), not reported as a force: a catheter that
  runs straight from the clamp and then turns a right-angle corner (the curvature of a rod
  under a tip force is continuous; a corner is not). The inversion converges to the
  least-bad force, but the residual stays millimetres.
- A solve stopped before convergence is 'not_converged', even when its residual is small.

The control points are inputs made once with the camera path's `fit_bezier` (corner: 200
points of the polyline below; FAM shape: `solve_fam` of the 65 mm Blazer, tip force
(0, 0.3) N, 48 arcs), written out so these tests do not depend on catheter_shape.
"""
import numpy as np
import pytest

L = 0.065
CORNER = np.array([[-0.000184, 0.001314, 0.0], [0.034083, -0.010084, 0.0],
                   [0.013037, 0.024034, 0.0], [0.020874, 0.046712, 0.0]])
FAM_0_03 = np.array([[0.000667, -0.000272, 0.0], [0.021807, 0.004954, 0.0],
                     [0.018316, 0.039723, 0.0], [0.020150, 0.056194, 0.0]])


def _fam(**kw):
    from fam_solver import Catheter
    from force_estimator import FamInverseEstimator
    return FamInverseEstimator(Catheter(length=L, ei=6e-5), n_arcs=12, table_angles=24,
                               table_magnitudes=8, **kw)


@pytest.fixture(scope='module')
def fam():
    return _fam()


def test_a_cornered_shape_is_no_fit_not_a_force(fam):
    fam.reset()
    e = fam.estimate(CORNER)
    assert e.converged
    assert e.residual > 2 * fam.max_residual          # millimetres from any FAM shape
    assert e.status == 'no_fit' and not e.normal
    assert np.all(np.isfinite(e.force)) and np.hypot(*e.force) <= fam.f_max


def test_a_stopped_solve_is_not_converged_even_with_a_small_residual(fam):
    fam.reset()
    e = fam.estimate(FAM_0_03)                      # enough iterations: the force comes back
    assert e.status == 'ok' and e.converged
    assert np.hypot(*(e.force - (0.0, 0.3))) < 0.005
    one = _fam(max_iter=1)
    e1 = one.estimate(FAM_0_03)
    assert not e1.converged and e1.residual < one.max_residual
    assert e1.status == 'not_converged' and not e1.normal


@pytest.mark.parametrize('solver', ['analytic', 'single', 'batch'])
def test_when_no_fam_solve_converges_the_estimate_is_flagged_bounded_and_honest(solver):
    """Every FAM solve fails (a load past the solver's reach): the inversion still answers,
    'not_converged', not normal, finite, within f_max, with the prior's covariance."""
    from types import SimpleNamespace
    from force_estimator.uncertainty import FORCE_PRIOR
    est = _fam(solver=solver)
    calls = []

    def no_solve(*a, **k):
        calls.append(1)
        return SimpleNamespace(converged=False)

    est._solve_one = no_solve
    est._solve_batch = lambda *a, **k: calls.append(1) or SimpleNamespace(
        converged=np.zeros(3, bool))
    e = est.estimate(FAM_0_03)
    assert calls, 'the patched solver was never called'
    assert e.status == 'not_converged' and not e.normal and not e.converged
    assert np.all(np.isfinite(e.force)) and np.hypot(*e.force) <= est.f_max * (1 + 1e-9)
    np.testing.assert_allclose(e.covariance, np.eye(2) * FORCE_PRIOR ** 2)
    assert 'did not converge' in e.message


def test_a_singular_sensitivity_is_not_converged_not_a_crash():
    est = _fam()

    def singular(*a, **k):
        raise ValueError('singular FAM Jacobian')

    est._sens = singular
    e = est.estimate(FAM_0_03)
    assert e.status == 'not_converged' and not e.normal and np.all(np.isfinite(e.force))


def test_a_failed_warm_start_is_retried_cold():
    """The analytic path warm-starts each solve from the previous shape; when that fails, the
    same load is solved again from the straight rod before giving up."""
    est = _fam()
    assert est.estimate(FAM_0_03).status == 'ok'          # a previous shape to start from
    est._shapes.clear()                                   # but no cached solution
    real = est._solve_one
    starts = []

    def warm_fails(cat, loads, n_arcs, initial=None):
        starts.append(initial is not None)
        if initial is not None:
            from types import SimpleNamespace
            return SimpleNamespace(converged=False)
        return real(cat, loads, n_arcs=n_arcs)

    est._solve_one = warm_fails
    e = est.estimate(FAM_0_03)
    assert e.status == 'ok' and np.hypot(*(e.force - (0.0, 0.3))) < 0.005
    assert True in starts and False in starts
    # each warm failure is followed by a cold solve of the same load
    assert all(not b for a, b in zip(starts, starts[1:], strict=False) if a)

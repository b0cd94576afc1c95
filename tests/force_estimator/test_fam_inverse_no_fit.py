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

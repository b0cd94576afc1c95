"""force_estimator.uncertainty: the marginal force covariance against hand-checked Gaussian
results, the observability table's interpolation (wrap-around, magnitudes beyond the table)
and its validation, and the point Jacobian's nuisance columns against finite differences."""
import numpy as np
import pytest

from fam_solver import Catheter, Loads, solve_fam
from force_estimator.uncertainty import (ALIGN_SIGMA, FORCE_PRIOR, STRETCH_SIGMA,
                                         ObservabilityTable, force_covariance, point_jacobian)


def test_no_information_gives_the_prior():
    """A shape that does not change with the force (J = 0): the covariance is the prior."""
    C = force_covariance(np.zeros((48, 4)))
    np.testing.assert_allclose(C, np.diag([FORCE_PRIOR ** 2] * 2), rtol=1e-15)
    C = force_covariance(np.zeros((48, 4)), force_prior=0.05)
    np.testing.assert_allclose(C, np.diag([0.05 ** 2] * 2), rtol=1e-15)


@pytest.mark.parametrize('a', [1e-3, 1.0 / 300.0, 0.05])
def test_nuisance_parameters_are_marginalised(a):
    """fx moves every point like an offset delta of the curve's start (column a for fx, 1 for
    delta), fy like the stretch eps (column a for fy, b for eps): the n points then observe
    only z = a fx + delta (and a fy + b eps) with noise sigma^2 / n on their mean, and
    Gaussian conditioning on z gives, by hand,

        var fx = s_f^2 - (a s_f^2)^2 / (a^2 s_f^2 + s_d^2 + sigma^2 / n)

    (and the same for fy with b^2 s_e^2): the priors of delta and eps widen the force's
    variance; holding them at their values would give 1 / (n a^2 / sigma^2 + 1 / s_f^2)."""
    n, b, sigma = 10, 0.05, 1e-5
    J = np.zeros((2 * n, 4))
    J[0::2, 0], J[0::2, 2] = a, 1.0          # x coordinates: fx and the offset
    J[1::2, 1], J[1::2, 3] = a, b            # y coordinates: fy and the stretch
    C = force_covariance(J, sigma)
    sf, sd, se = FORCE_PRIOR, ALIGN_SIGMA, STRETCH_SIGMA
    vx = sf ** 2 - (a * sf ** 2) ** 2 / (a ** 2 * sf ** 2 + sd ** 2 + sigma ** 2 / n)
    vy = sf ** 2 - (a * sf ** 2) ** 2 / (a ** 2 * sf ** 2 + (b * se) ** 2 + sigma ** 2 / n)
    np.testing.assert_allclose(np.diag(C), [vx, vy], rtol=1e-8)
    assert abs(C[0, 1]) < 1e-12 * vx and C[0, 1] == C[1, 0]


def _table(values_a, values_m):
    """(A, M) table with cov[i, j] = values_a[i] * values_m[j] * I, angles as in build_table."""
    A = len(values_a)
    step = 2 * np.pi / A
    ang = -np.pi + 0.5 * step + step * np.arange(A)
    cov = (np.asarray(values_a, float)[:, None, None, None]
           * np.asarray(values_m, float)[None, :, None, None] * np.eye(2))
    return ObservabilityTable(ang, np.linspace(0.0, 0.3, len(values_m)), cov)


def test_lookup_on_the_grid_and_between_its_points():
    t = _table([1.0, 2.0, 3.0, 4.0], [1.0, 5.0])
    for i, a in enumerate(t.angles):
        for j, m in enumerate(t.magnitudes[1:], 1):      # (at zero force: no direction)
            f = m * np.array([np.cos(a), np.sin(a)])
            np.testing.assert_allclose(t.lookup(f), t.cov[i, j], rtol=1e-12)
    # halfway between angles 0 and 1 (-3pi/4, -pi/4: at -pi/2) and between the magnitudes
    f = 0.15 * np.array([0.0, -1.0])
    np.testing.assert_allclose(t.lookup(f), 1.5 * 3.0 * np.eye(2), rtol=1e-12)
    np.testing.assert_allclose(t.lookup(np.stack([f, 2 * f])),
                               [4.5 * np.eye(2), 1.5 * 5.0 * np.eye(2)], rtol=1e-12)


def test_lookup_wraps_around_between_the_last_angle_and_the_first():
    """Angles are periodic: a force at angle pi lies halfway between the last grid angle
    (3pi/4) and the first (-3pi/4), so it gets their mean."""
    t = _table([1.0, 2.0, 3.0, 4.0], [1.0, 1.0])
    np.testing.assert_allclose(t.lookup([-0.2, 0.0]), 2.5 * np.eye(2), rtol=1e-12)
    np.testing.assert_allclose(t.lookup([-0.2, 1e-12]), 2.5 * np.eye(2), rtol=1e-9)
    np.testing.assert_allclose(t.lookup([-0.2, -1e-12]), 2.5 * np.eye(2), rtol=1e-9)


def test_lookup_beyond_the_table_uses_its_last_magnitude():
    t = _table([1.0] * 4, [1.0, 2.0, 4.0])                 # magnitudes 0, 0.15, 0.3
    for m in (0.3, 0.31, 0.6, 30.0):
        np.testing.assert_allclose(t.lookup([0.0, m]), 4.0 * np.eye(2), rtol=1e-12)


def test_from_arrays_round_trip_and_refusals():
    t = _table([1.0, 2.0, 3.0, 4.0], [1.0, 2.0])
    u = ObservabilityTable.from_arrays(t.arrays())
    np.testing.assert_array_equal(u.cov, t.cov)
    np.testing.assert_array_equal(u.magnitudes, t.magnitudes)
    bad = [dict(obs_magnitudes=np.array([0.0, 0.0])),           # repeated magnitude: 0/0
           dict(obs_magnitudes=np.array([0.3, 0.0])),
           dict(obs_cov=np.full((4, 2, 2, 2), np.nan)),
           dict(obs_cov=np.zeros((4, 3, 2, 2))),
           dict(obs_angles=np.array([0.0, np.nan, 1.0, 2.0]))]
    for change in bad:
        a = dict(t.arrays(), **change)
        with pytest.raises(ValueError, match='observability table'):
            ObservabilityTable.from_arrays(a)


def test_point_jacobian_nuisance_columns_are_the_derivatives_of_the_points():
    """Columns delta and eps: the points at arc lengths a (1 + eps) + delta move along the
    tangent by d delta and by a d eps; central differences of the shape's own points."""
    cat = Catheter(length=0.065, ei=6e-5)
    f = (0.04, 0.08)
    sh = solve_fam(cat, Loads(tip_force=f), n_arcs=24, arc_model='exact')
    frac = np.linspace(0.05, 0.9, 12)
    J = point_jacobian(sh, f, frac, cat.ei, cat.length)
    h = 1e-7
    d_delta = (sh.points_at(frac + h / cat.length) - sh.points_at(frac - h / cat.length)) / (2 * h)
    d_eps = (sh.points_at(frac * (1 + h)) - sh.points_at(frac * (1 - h))) / (2 * h)
    np.testing.assert_allclose(J[:, 2], d_delta.reshape(-1), atol=1e-7)
    np.testing.assert_allclose(J[:, 3], d_eps.reshape(-1), atol=1e-7 * cat.length)
    assert np.abs(J[:, 3]).max() > 0.01                      # a real, nonzero column (m)

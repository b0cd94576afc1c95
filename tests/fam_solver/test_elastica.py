"""The reference rod solver against closed-form solutions."""
import numpy as np
import pytest

from fam_solver import Catheter, Loads, solve_elastica

TABLE = [  # REFERENCES.md (Bisshopp & Drucker)
    (0.5, 0.984081, 0.162144, 0.244534),
    (1.0, 0.943567, 0.301721, 0.461352),
    (5.0, 0.612372, 0.713792, 1.215368),
    (10.0, 0.445004, 0.810609, 1.430286),
    (21.125, 0.307606, 0.872301, 1.537354),
]


@pytest.mark.parametrize('alpha,x,y,t0', TABLE)
def test_perpendicular_dead_load_matches_elliptic_closed_form(alpha, x, y, t0, closed_form):
    cat = Catheter(length=0.065, ei=6e-5)
    F = alpha * cat.ei / cat.length ** 2
    ref = solve_elastica(cat, Loads(tip_force=(0.0, F)))
    assert ref.converged
    exact, th = closed_form(alpha)
    assert np.allclose(exact, [x, y], atol=2e-6)          # the table itself
    assert np.max(np.abs(ref.tip / cat.length - exact)) < 1e-9
    assert abs(ref.tip_angle - th) < 1e-9


def test_large_load_stays_on_the_natural_branch(closed_form):
    cat = Catheter(1.0, 1.0)
    ref = solve_elastica(cat, Loads(tip_force=(0.0, 50.0)))
    exact, th = closed_form(50.0)
    assert np.max(np.abs(ref.tip - exact)) < 1e-8 and abs(ref.tip_angle - th) < 1e-8


@pytest.mark.parametrize('alpha,x,y,t0', [(1, 0.935646, 0.320642, 0.495885),
                                          (2, 0.767362, 0.573839, 0.968239),
                                          (5, 0.172278, 0.780690, 2.098157)])
def test_follower_force_normal_to_the_tip(alpha, x, y, t0):
    ref = solve_elastica(Catheter(1.0, 1.0), Loads(tip_force=(0.0, alpha), follower=True))
    assert ref.converged
    assert np.max(np.abs(ref.tip - [x, y])) < 2e-6 and abs(ref.tip_angle - t0) < 2e-6


def test_pure_moment_is_a_circular_arc():
    cat = Catheter(0.04, 7.5e-4)
    M = 2.5 * cat.ei / cat.length
    ref = solve_elastica(cat, Loads(tip_moment=M))
    th = M * cat.length / cat.ei
    L = cat.length
    assert abs(ref.tip_angle - th) < 1e-10
    assert np.max(np.abs(ref.tip - [L * np.sin(th) / th, L * (1 - np.cos(th)) / th])) < 1e-12
    s = np.linspace(0, 1, 7)
    pts = ref.points_at(s)
    assert np.allclose(pts[:, 0], L * np.sin(th * s) / th, atol=1e-12)


def test_point_force_small_load_matches_beam_theory():
    # linear cantilever: load P at a: tip deflection P a^2 (3L - a) / (6 EI)
    cat = Catheter(1.0, 1.0)
    P, a = 1e-6, 0.4
    ref = solve_elastica(cat, Loads(point_forces=((a, 0.0, P),)))
    assert abs(ref.tip[1] - P * a * a * (3 - a) / 6) < 1e-12


def test_zero_load_is_straight():
    ref = solve_elastica(Catheter(0.05, 1e-4), Loads())
    assert ref.tip[0] == pytest.approx(0.05, abs=1e-15) and ref.tip[1] == 0.0


@pytest.mark.parametrize('bad,name', [
    # rtol >= 1 first: were it accepted, it would return at once (rtol = 0 would be clamped
    # by solve_ivp to 100 eps and crawl for minutes)
    (dict(rtol=1.5), 'rtol'), (dict(rtol=1.0), 'rtol'), (dict(rtol=0.0), 'rtol'),
    (dict(rtol=-1e-8), 'rtol'), (dict(rtol=1), 'rtol'),
    (dict(cat=(1.0, 1.0)), 'cat'), (dict(loads=(0.0, 1.0)), 'loads'),
])
def test_bad_input_raises_value_error_naming_the_argument(bad, name):
    args = dict(cat=Catheter(1.0, 1.0), loads=Loads(tip_force=(0.0, 1.0)))
    args.update(bad)
    with pytest.raises(ValueError, match=name):
        solve_elastica(**args)


def test_arc_angles_are_tangent_increments_over_100_equal_pieces():
    """Shape's promise for the reference rod: arc_angles are the tangent-angle increments over
    100 equal pieces (arc_lengths L/100 each): on a pure-moment circular arc every piece turns
    by exactly theta/100."""
    cat = Catheter(0.05, 2e-4)
    th = 1.7
    ref = solve_elastica(cat, Loads(tip_moment=th * cat.ei / cat.length))
    assert ref.arc_angles.shape == (100,)
    np.testing.assert_allclose(ref.arc_angles, th / 100, rtol=0, atol=1e-12)
    np.testing.assert_allclose(ref.arc_lengths, cat.length / 100, rtol=1e-15)
    assert abs(ref.arc_lengths.sum() - cat.length) < 1e-15
    # a general load: the increments of angles_at at k/100, summing to the tip angle
    ref = solve_elastica(cat, Loads(tip_force=(-0.01, 0.05)))
    k = np.arange(101) / 100
    np.testing.assert_allclose(ref.arc_angles, np.diff(ref.angles_at(k)), atol=1e-14)
    assert abs(ref.arc_angles.sum() - ref.tip_angle) < 1e-12


@pytest.mark.parametrize('rtol', [1e-6, 1e-8])
def test_loose_tolerance_scales_with_the_catheter(rtol, closed_form):
    """A soft, short catheter (EI/L ~ 1e-3 N m) at a loose rtol: the shooting tolerance is
    relative to EI/L (the docstring's |M(L) - m_tip| <= 10 rtol EI/L), so the tip still
    matches the elliptic-integral solution to about rtol."""
    cat = Catheter(length=0.065, ei=6e-5)
    alpha = 5.0
    ref = solve_elastica(cat, Loads(tip_force=(0.0, alpha * cat.ei / cat.length ** 2)),
                         rtol=rtol)
    exact, th = closed_form(alpha)
    assert ref.converged and ref.residual <= 10 * rtol * cat.ei / cat.length
    assert np.max(np.abs(ref.tip / cat.length - exact)) < 100 * rtol
    assert abs(ref.tip_angle - th) < 100 * rtol

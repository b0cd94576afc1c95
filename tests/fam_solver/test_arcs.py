"""Arc closed forms and the Bezier handle length lambda (derivation checks)."""
import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from fam_solver import arcs, bezier_lambda


def _direct(phi):
    """Reference values by adaptive-free dense quadrature of the definitions."""
    t = np.linspace(0.0, 1.0, 200001)
    p = (np.exp(1j * phi * t) - 1) / (1j * phi) if phi != 0 else t + 0j  # t g(phi t)
    g = p[-1]
    mean = np.trapezoid(p, t)
    return g, g - mean


@given(st.floats(-3.0, 3.0).filter(lambda x: abs(x) > 1e-3))
@settings(max_examples=40, deadline=None)
def test_g_and_q_match_their_definitions(phi):
    g, q, _, _ = arcs.arc_funcs(np.array([phi]))
    gr, qr = _direct(phi)
    assert abs(g[0] - gr) < 1e-9
    assert abs(q[0] - qr) < 1e-9


def test_series_and_closed_forms_agree_at_the_switch():
    """g, q, g', q' and the clothoid k, k - km, k', (k - km)': Taylor series = closed forms."""
    for coef, closed, tol in ((arcs._CCOEF, arcs._closed, 1e-13),
                              (arcs._CCOEF8, arcs._clothoid_closed, 1e-12)):
        for x in (0.999999, 1.000001, -0.999999, 0.5, 0.9):
            s = (np.array([x])[:, None] ** arcs._POW) @ coef
            c = closed(np.array([x]))
            for j, b in enumerate(c):
                assert abs(s[0, j] - b[0]) < tol, (j, x)


def test_derivatives_by_finite_differences():
    for phi in (-2.0, -0.3, 1e-4, 0.7, 1.5, 2.9):
        h = 1e-6
        gp_, qp_ = [(a - b) / (2 * h) for a, b in zip(arcs.arc_funcs(np.array([phi + h]))[:2],
                                                     arcs.arc_funcs(np.array([phi - h]))[:2],
                                                     strict=True)]
        _, _, gp, qp = arcs.arc_funcs(np.array([phi]))
        assert abs(gp[0] - gp_[0]) < 1e-8 and abs(qp[0] - qp_[0]) < 1e-8


def test_no_cancellation_near_zero():
    g, q, gp, qp = arcs.arc_funcs(np.array([0.0, 1e-12, 1e-8, -1e-5]))
    assert np.all(np.isfinite(g)) and np.all(np.isfinite(qp))
    assert g[0] == 1.0 and q[0] == 0.5 and gp[0] == 0.5j
    assert abs(g[1] - (1 + 0.5e-12j)) < 1e-16


def _bezier_points(phi, t):
    lam = bezier_lambda(phi)
    end = (np.exp(1j * phi) - 1) / (1j * phi)     # unit-length arc
    p = [0j, lam + 0j, end - lam * np.exp(1j * phi), end]
    u = 1 - t
    return u ** 3 * p[0] + 3 * t * u ** 2 * p[1] + 3 * t ** 2 * u * p[2] + t ** 3 * p[3]


def test_lambda_is_the_circular_handle_length():
    for phi in (0.1, 0.5, 1.0, np.pi / 2, 2.5):
        r = 1.0 / phi
        h = 4.0 / 3.0 * np.tan(phi / 4) * r
        assert abs(bezier_lambda(phi) - h) < 1e-14   # l = 1


def test_lambda_limit_and_series():
    assert bezier_lambda(0.0) == 1.0 / 3.0
    for x in (0.9999e-3, 1.0001e-3):   # both sides of the series switch
        assert abs(bezier_lambda(x) - (1 / 3 + x * x / 144 + x ** 4 / 5760)) < 1e-15
    assert abs(bezier_lambda(1e-4) - (1 / 3 + 1e-8 / 144)) < 1e-15


def test_bezier_midpoint_on_circle_and_small_radial_error():
    for phi in (0.2, 1.0, np.pi / 2):
        r = 1.0 / phi
        centre = 1j * r
        mid = _bezier_points(phi, np.array([0.5]))[0]
        assert abs(abs(mid - centre) - r) < 1e-12
        t = np.linspace(0, 1, 2001)
        err = np.max(np.abs(np.abs(_bezier_points(phi, t) - centre) - r)) / r
        assert err < (3e-4 if phi > 1.5 else 3e-5)
    # the radial error grows like phi^6 (a cubic matches the arc to 6th order)
    e = []
    for phi in (0.4, 0.8):
        t = np.linspace(0, 1, 2001)
        r = 1 / phi
        e.append(np.max(np.abs(np.abs(_bezier_points(phi, t) - 1j * r) - r)) / r)
    assert 40 < e[1] / e[0] < 90


def _series(phi, terms=40):
    """g, q, g', q' by their Taylor series (module docstring) summed term by term in Python
    complex arithmetic, far past the truncation (|phi| <= 3: terms below 1e-30)."""
    i, f = 1j, math.factorial
    g = sum((i * phi) ** n / f(n + 1) for n in range(terms))
    q = sum((i * phi) ** n * (n + 1) / f(n + 2) for n in range(terms))
    gp = sum(n * i ** n * phi ** (n - 1) / f(n + 1) for n in range(1, terms))
    qp = sum(n * (n + 1) * i ** n * phi ** (n - 1) / f(n + 2) for n in range(1, terms))
    return g, q, gp, qp


PHIS = [-3.0, -2.4, -1.7, -1.0, -0.99, -0.3, -1e-3, 0.0, 2e-4, 0.999, 1.0, 1.3, 2.0, 2.45, 3.0]


def test_arc_funcs_to_round_off_on_both_sides_of_the_series_switch():
    """The docstring's promise: series below |phi| < 1 with truncation below 3e-16, exact
    closed forms above: g, q, g', q' equal the long series to round-off everywhere."""
    got = arcs.arc_funcs(np.array(PHIS))
    for k, phi in enumerate(PHIS):
        for j, ref in enumerate(_series(phi)):
            assert abs(got[j][k] - ref) < 3e-15, (phi, j, abs(got[j][k] - ref))


def test_g_only_equals_the_chord_on_both_sides_of_its_series_switch():
    for phi in (0.0, 1e-9, -3e-5, 2e-4, 0.9999e-3, -0.9999e-3, 1.0001e-3, 0.01, 0.5, 2.5):
        ref = _series(phi)[0]
        assert abs(arcs.g_only(phi) - ref) < 2e-16, phi
    x = np.array(PHIS)
    assert np.max(np.abs(arcs.g_only(x) - arcs.arc_funcs(x)[0])) < 3e-15


@pytest.mark.parametrize('n', [255, 256, 257, 300, 513, 700])
def test_row_product_in_blocks_equals_the_plain_product(n):
    """row_product splits a long product into row blocks (to stay in one BLAS thread): every
    row, including a last partial block, is computed."""
    V = np.random.default_rng(n).standard_normal((n, arcs._K))
    np.testing.assert_allclose(arcs.row_product(V, arcs._CCOEF8), V @ arcs._CCOEF8,
                               rtol=1e-13, atol=1e-13)
    # and the long Vandermonde path of arc_funcs equals the element-wise one
    phi = np.linspace(-0.99, 0.99, n)
    long = arcs.arc_funcs(phi)
    short = [arcs.arc_funcs(phi[k:k + 1]) for k in (0, n // 2, n - 1)]
    for j in range(4):
        assert [long[j][k] for k in (0, n // 2, n - 1)] == pytest.approx(
            [s[j][0] for s in short], abs=1e-15)

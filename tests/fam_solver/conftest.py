"""Shared helpers for the fam_solver tests: closed-form elastica references, and the folder's
helper modules (node_msgs) importable."""
import pathlib
import sys

import numpy as np
import pytest
from scipy.optimize import brentq
from scipy.special import ellipe, ellipeinc, ellipk, ellipkinc

HERE = pathlib.Path(__file__).resolve().parent
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))


def cantilever_closed_form(alpha):
    """Tip (x/L, y/L) and tip angle of a clamped elastica under a dead end load perpendicular
    to the undeformed axis, alpha = F L^2/EI (Bisshopp & Drucker 1945; scipy uses m = k^2)."""
    def parts(t0):
        m = (1.0 + np.sin(t0)) / 2.0
        k = np.sqrt(m)
        p1 = np.arcsin(1.0 / (k * np.sqrt(2.0)))
        return m, p1

    def f(t0):
        m, p1 = parts(t0)
        return ellipk(m) - ellipkinc(p1, m) - np.sqrt(alpha)

    t0 = brentq(f, 1e-12, np.pi / 2 - 1e-14, xtol=1e-15, rtol=1e-15)
    m, p1 = parts(t0)
    x = np.sqrt(2.0 * np.sin(t0) / alpha)
    y = 1.0 - (2.0 / np.sqrt(alpha)) * (ellipe(m) - ellipeinc(p1, m))
    return np.array([x, y]), t0


@pytest.fixture
def closed_form():
    return cantilever_closed_form

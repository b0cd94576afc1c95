"""Outcome codes of a solve, in the style of scipy's ``OptimizeResult.status`` (0 = success).

``Shape.status`` and ``BatchShape.status`` are DERIVED from the result's ``converged``,
``stable`` and ``snap_through`` flags (one place for the rule, so they cannot disagree):
NOT_CONVERGED wins over UNSTABLE, which wins over SNAP_THROUGH. No rclpy here.
"""
from __future__ import annotations

from enum import IntEnum

import numpy as np
from numpy.typing import ArrayLike


class Status(IntEnum):
    """Outcome of a FAM (or reference rod) solve; ``Status(k).message`` explains code k."""
    #: converged to a stable equilibrium on the loading path from zero
    CONVERGED = 0
    #: Newton (and the continuation fallback) did not converge: the best finite iterate
    NOT_CONVERGED = 1
    #: converged to an equilibrium known to be unstable (an axial compression past buckling:
    #: loading from zero keeps the straight shape, which is returned)
    UNSTABLE = 2
    #: converged beyond a fold of the loading path (snap-through): the loading path from
    #: zero ends at a fold; the (preferably stable) equilibrium found beyond it is returned
    SNAP_THROUGH = 3

    @property
    def message(self) -> str:
        return _MESSAGES[self]


_MESSAGES = {
    Status.CONVERGED: 'converged to a stable equilibrium on the loading path',
    Status.NOT_CONVERGED: 'not converged: the best finite iterate is returned',
    Status.UNSTABLE: ('unstable equilibrium (compressed past buckling; loading from zero kept '
                      'this shape)'),
    Status.SNAP_THROUGH: ('snap-through: the loading path from zero has a fold; returned the '
                          'equilibrium found beyond it'),
}


def status_codes(converged: ArrayLike, stable: ArrayLike, snap_through: ArrayLike) -> np.ndarray:
    """Status codes (int array, the shape of the broadcast inputs) from the three flags."""
    conv = np.asarray(converged, dtype=bool)
    out = np.where(conv, int(Status.CONVERGED), int(Status.NOT_CONVERGED))
    out = np.where(conv & np.asarray(snap_through, dtype=bool), int(Status.SNAP_THROUGH), out)
    return np.where(conv & ~np.asarray(stable, dtype=bool), int(Status.UNSTABLE), out)


def status_of(converged: bool, stable: bool, snap_through: bool) -> Status:
    """The Status of one result from its flags."""
    return Status(int(status_codes(converged, stable, snap_through)))


def warning_text(converged: bool, stable: bool, snap_through: bool, residual: float) -> str:
    """'' for a clean result, else the reasons (non-convergence with its residual,
    snap-through, instability), '; '-separated."""
    parts = []
    if not converged:
        parts.append(f'not converged: max residual {residual:.3g} rad')
    elif snap_through:
        parts.append(Status.SNAP_THROUGH.message)
    if not stable:
        parts.append(Status.UNSTABLE.message)
    return '; '.join(parts)

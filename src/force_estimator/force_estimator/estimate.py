"""The result of one tip-force estimate: the force, its uncertainty, a domain status and
the method, for the node to publish (normal estimates on /catheter/tip_wrench, every estimate
with its covariance and status on the typed TipForceEstimate message).

Invariants (tested): `force` is finite and within the envelope of the method that produced
it (|f| <= its `f_max`, whatever the input); `covariance` is a finite, symmetric, positive
semi-definite 2x2 (N^2); `status` is one of `STATUSES`; only the statuses in `NORMAL`
make `normal` True.

Pure numpy; no rclpy.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional, Tuple

import numpy as np

__all__ = ['ForceEstimate', 'STATUSES', 'NORMAL', 'METHODS', 'UNOBSERVABLE_STD',
           'DOMAIN_UNKNOWN', 'MESSAGE_STATUS', 'failed_estimate', 'domain_distance']

#: every status an estimate can carry:
#: ok - in the training domain (learned) / the shape fits (fam), force observable;
#: axial_unobservable - as ok, but the shape barely constrains one direction (an axial
#:     pull or push on a nearly straight catheter): its std exceeds UNOBSERVABLE_STD; the
#:     force is the best estimate (the covariance says which direction is weak);
#: out_of_domain - the control points are far from any training input (learned model,
#:     no fallback configured); the force is bounded but not to be trusted;
#: out_of_envelope - the model's output was beyond the trained force range (clipped);
#: no_fit - no tip force explains the shape (FAM inversion residual too large);
#: not_converged - the FAM inversion did not converge;
#: non_finite_input - NaN or infinite control points (force 0);
#: bad_input - control points of the wrong shape or absurd size (> 1 m) (force 0).
STATUSES = ('ok', 'axial_unobservable', 'out_of_domain', 'out_of_envelope', 'no_fit',
            'not_converged', 'non_finite_input', 'bad_input')
#: the statuses of estimates that may be published as normal estimates
NORMAL = ('ok', 'axial_unobservable')
#: methods: the learned models, the FAM inversion, and the FAM inversion used because the
#: learned model (`primary`) did not cover the input
METHODS = ('svr', 'mlp', 'fam', 'fam_fallback')
#: std (N) of the weakest direction above which an estimate is 'axial_unobservable':
#: 10 % of the 0.3 N full scale (the clinical error limit)
UNOBSERVABLE_STD = 0.03
#: the status of catheter_interfaces/TipForceEstimate (by the lower-case name of its
#: constant) for each status here: the message's codes are coarser, the reason is in
#: `message`
MESSAGE_STATUS = {'ok': 'ok', 'axial_unobservable': 'unobservable_axial',
                  'out_of_domain': 'out_of_domain', 'out_of_envelope': 'out_of_domain',
                  'no_fit': 'out_of_domain', 'not_converged': 'out_of_domain',
                  'non_finite_input': 'non_finite_input', 'bad_input': 'out_of_domain'}
#: the domain distance of an input that cannot be placed at all (non-finite, absurd, of zero
#: length): finite, so that it fits a message field, and far beyond any real distance
DOMAIN_UNKNOWN = 1e6


def domain_distance(ratio: float) -> float:
    """The published domain distance from a method's ratio (input measure over its
    threshold, <= 1 inside): 0 inside the domain, else how far beyond its edge in units of
    the threshold (ratio - 1); DOMAIN_UNKNOWN when the ratio is not finite. The convention of
    catheter_interfaces/TipForceEstimate.domain_distance (>= 0, 0 inside)."""
    r = float(ratio)
    if not np.isfinite(r):
        return DOMAIN_UNKNOWN
    return min(max(0.0, r - 1.0), DOMAIN_UNKNOWN)


@dataclass
class ForceEstimate:
    """One tip-force estimate.

    force: (2,) N, (fx, fy) in catheter_base; always finite and bounded.
    covariance: (2, 2) N^2; finite, symmetric, positive semi-definite.
    status: one of STATUSES; message: why, in words.
    method: 'svr', 'mlp', 'fam' or 'fam_fallback'; primary: the configured method.
    domain_distance: how far the input lies beyond what the method covers, >= 0 and finite
        (`domain_distance()`): 0 inside; beyond, (ratio - 1) with ratio, for the learned
        models, the nearest-neighbour distance to the training inputs over its calibrated
        threshold (or 1 + how far outside the envelope box), for the FAM inversion, the fit
        residual over max_residual; DOMAIN_UNKNOWN (1e6) for bad or non-finite input.
    """
    force: np.ndarray
    covariance: np.ndarray
    status: str
    method: str
    primary: str = ''
    domain_distance: float = 0.0
    message: str = ''
    extra: dict = field(default_factory=dict)

    @property
    def normal(self) -> bool:
        """True when the estimate may be published as a normal estimate."""
        return self.status in NORMAL

    @property
    def message_status(self) -> str:
        """The TipForceEstimate status name for this estimate (see MESSAGE_STATUS)."""
        return MESSAGE_STATUS[self.status]

    @property
    def std(self) -> np.ndarray:
        """(2,) N, the standard deviations of fx and fy."""
        return np.sqrt(np.maximum(np.diag(self.covariance), 0.0))

    @property
    def max_std(self) -> float:
        """N, the standard deviation along the least constrained direction."""
        return float(np.sqrt(max(np.linalg.eigvalsh(self.covariance)[-1], 0.0)))

    @property
    def weak_direction(self) -> np.ndarray:
        """(2,) unit vector of the least constrained direction (for an axial pull: along
        the catheter's tip)."""
        w, v = np.linalg.eigh(self.covariance)
        return v[:, -1]


def failed_estimate(status: str, method: str, message: str, f_max: float,
                    primary: str = '') -> ForceEstimate:
    """An estimate for an input the method cannot use: force 0, the covariance of a force
    known only to lie in the disc |f| <= f_max (uniform: std f_max / 2 per axis)."""
    if status not in STATUSES:
        raise ValueError(f'status must be one of {STATUSES}, got {status!r}')
    var = (0.5 * f_max) ** 2
    return ForceEstimate(force=np.zeros(2), covariance=np.eye(2) * var, status=status,
                         method=method, primary=primary or method,
                         domain_distance=DOMAIN_UNKNOWN, message=message)


def bounded(force: np.ndarray, f_max: float):
    """(force scaled into |f| <= f_max, True if it had to be scaled); non-finite -> 0."""
    f = np.asarray(force, dtype=float)
    if not np.all(np.isfinite(f)):
        return np.zeros(2), True
    n = float(np.hypot(f[0], f[1]))
    if n > f_max:
        return f * (f_max / n), True
    return f.copy(), False


def unobservable_direction(cov: np.ndarray) -> Optional[np.ndarray]:
    """(2,) unit vector of the weakest direction of a force covariance (2, 2) N^2 when its
    std is above UNOBSERVABLE_STD (the shape does not determine the force along it), else
    None. The one rule behind 'axial_unobservable' (`classify`) and the FAM inversion's held
    warm start."""
    w, v = np.linalg.eigh(cov)
    return v[:, -1] if w[-1] > UNOBSERVABLE_STD ** 2 else None


def classify(cov: np.ndarray, status: str = 'ok') -> str:
    """'axial_unobservable' for an otherwise ok estimate whose weakest direction has a
    std above UNOBSERVABLE_STD."""
    if status == 'ok' and unobservable_direction(cov) is not None:
        return 'axial_unobservable'
    return status


def status_of(cov: np.ndarray, *faults) -> Tuple[str, str]:
    """(status, message) of an estimate: those of the first of `faults` -- (failed, status,
    message) triples, in order of precedence -- that failed; else the `classify` status of
    the covariance and no message. A message may be a callable returning it, formatted only
    when its fault is the one reported."""
    for failed, status, message in faults:
        if failed:
            return status, message() if callable(message) else message
    return classify(cov), ''

"""A learned force model with the FAM inversion as its fallback, and the factory the node
uses: one `estimate(control_points)` per sample whatever the method.

The learned model answers inside its training domain (microseconds); for inputs it does not
cover (status 'out_of_domain' or 'out_of_envelope') and for shapes that do not determine the
axial force ('axial_unobservable': its training targets disagree there) the FAM inversion
answers instead
(milliseconds, no training data: it needs only the catheter's length and stiffness), with
method 'fam_fallback' and primary the learned model's kind. Without a fallback the learned
model's bounded, flagged estimate is returned.

Pure numpy (and fam_solver); no rclpy.
"""
from __future__ import annotations

from typing import Optional, Union

import numpy as np

from force_estimator.estimate import ForceEstimate
from force_estimator.fam_inverse import FamInverseEstimator
from force_estimator.inputs import control_points_to_features
from force_estimator.models import ForceModel, load_estimator

__all__ = ['HybridEstimator', 'make_estimator', 'FALLBACK_STATUSES']

#: statuses of a learned estimate that send the input to the fallback: inputs the model does
#: not cover, and inputs whose axial force the shape does not determine (the training
#: targets of nearly identical shapes disagree there, so the model's output is arbitrary;
#: the inversion's weak force prior gives the least-force answer and an honest covariance)
FALLBACK_STATUSES = ('out_of_domain', 'out_of_envelope', 'axial_unobservable')


class HybridEstimator:
    """model: a ForceModel (svr or mlp); fam: a FamInverseEstimator or None (no fallback)."""

    def __init__(self, model: ForceModel, fam: Optional[FamInverseEstimator] = None):
        if not isinstance(model, ForceModel):
            raise ValueError(f'model must be a ForceModel, got {type(model).__name__}')
        if fam is not None and not isinstance(fam, FamInverseEstimator):
            raise ValueError(f'fam must be a FamInverseEstimator or None, got '
                             f'{type(fam).__name__}')
        self.model = model
        self.fam = fam
        self.kind = model.kind

    def estimate(self, control_points) -> ForceEstimate:
        """One estimate (ForceEstimate); see the module docstring."""
        e = self.model.estimate(control_points)
        if self.fam is None or e.status not in FALLBACK_STATUSES:
            return e
        r = self.fam.estimate(control_points)
        r.method = 'fam_fallback'
        r.primary = self.model.kind
        why = f'{self.model.kind} {e.status}: {e.message}'
        r.message = why if not r.message else f'{why}; fam: {r.message}'
        r.extra['learned'] = dict(force=e.force.tolist(), domain_distance=e.domain_distance)
        return r

    def predict(self, control_points, return_flags: bool = False):
        """(4, 3) -> (2,) N; (B, 4, 3) -> (B, 2) (in order). return_flags: also whether each
        estimate is normal. Raises ValueError for wrong shapes or non-finite values."""
        x = control_points_to_features(control_points)
        if x.ndim == 1:
            e = self.estimate(x.reshape(4, 3))
            return (e.force, e.normal) if return_flags else e.force
        es = [self.estimate(xi.reshape(4, 3)) for xi in x]
        F = np.array([e.force for e in es])
        flags = np.array([e.normal for e in es], dtype=bool)
        return (F, flags) if return_flags else F


def make_estimator(method: str = 'svr', model: Union[str, ForceModel, None] = None,
                   cat=None, n_arcs: int = 24, f_max: float = 0.45,
                   fallback: bool = True):
    """The estimator a node runs: method 'svr' or 'mlp' (model: a shipped name, a .npz path
    or a ForceModel; default the shipped blazer-<method>) with the FAM inversion as fallback
    (unless fallback=False), or 'fam' (the FAM inversion alone). cat: fam_solver.Catheter
    (default the Blazer: 65 mm, EI 6e-5 N m^2). Every returned object has
    estimate(cp) -> ForceEstimate and predict(cp)."""
    if method not in ('svr', 'mlp', 'fam'):
        raise ValueError(f"method must be 'svr', 'mlp' or 'fam', got {method!r}")
    fam = None
    if method == 'fam' or fallback:
        from fam_solver import Catheter
        if cat is None:
            from force_estimator.dataset import BLAZER_EI, BLAZER_LENGTH
            cat = Catheter(length=BLAZER_LENGTH, ei=BLAZER_EI)
    if method == 'fam':
        return FamInverseEstimator(cat, n_arcs=n_arcs, f_max=f_max)
    m = model if isinstance(model, ForceModel) else load_estimator(model or f'blazer-{method}')
    if m.kind != method:
        raise ValueError(f'model holds a {m.kind} model, method is {method!r}')
    if fallback:
        # the fallback's envelope is the learned model's: nothing beyond the trained force
        # range is published as a normal estimate
        fam = FamInverseEstimator(cat, n_arcs=n_arcs, f_max=min(f_max, m.f_bound))
    return HybridEstimator(m, fam)

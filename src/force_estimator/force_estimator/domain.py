"""The training domain of a learned force model: how far an input lies from the inputs the
model was trained on.

A model file stores a reference set of training inputs (control-point features, m) and a
calibrated threshold. The domain distance of an input is its nearest-neighbour distance to
the reference set (the RMS over the 4 control points of their 3-D distances, m) divided by
the threshold: <= 1 inside the domain. The threshold is a high quantile of the same distance
for held-out inputs of the training distribution (they are inside by construction), times a
margin: a shape the pipeline can produce for a tip force in range is inside; control points
scaled by 1e6, a tip 1 km away or the fit of a wrong segmentation are far outside.

The reference inputs' training forces are stored too: the forces that made an input's
nearest neighbours say how well such a shape determines its force (the observability table
at those forces), whatever the model's own, possibly wrong, estimate: a straight catheter's
neighbours include axial pulls of every size.

Pure numpy; no rclpy.
"""
from __future__ import annotations

from typing import Optional

import numpy as np

__all__ = ['DomainCheck', 'DOMAIN_QUANTILE', 'DOMAIN_MARGIN', 'MAX_REFERENCE', 'NEIGHBOURS']

#: quantile of the held-out inputs' nearest-neighbour distances that sets the threshold
DOMAIN_QUANTILE = 0.995
#: the threshold is this many times that quantile
DOMAIN_MARGIN = 1.5
#: at most this many training inputs are kept as the reference set
MAX_REFERENCE = 4000
#: neighbours whose training forces measure how well the shape determines the force
NEIGHBOURS = 8


class DomainCheck:
    """reference: (n, 12) training features, m; threshold: m (> 0); targets: optional
    (n, 2) training forces of the reference inputs, N (for `neighbour_spread`)."""

    def __init__(self, reference: np.ndarray, threshold: float, targets=None):
        ref = np.ascontiguousarray(reference, dtype=float)
        if ref.ndim != 2 or ref.shape[1] != 12 or ref.shape[0] < 1:
            raise ValueError(f'reference must have shape (n >= 1, 12), got {ref.shape}')
        if not np.isfinite(ref).all():
            raise ValueError('reference contains non-finite values')
        if not (np.isfinite(threshold) and threshold > 0):
            raise ValueError(f'threshold must be positive and finite, got {threshold!r}')
        if targets is not None:
            targets = np.ascontiguousarray(targets, dtype=float)
            if targets.shape != (ref.shape[0], 2) or not np.isfinite(targets).all():
                raise ValueError(f'reference targets must be finite with shape '
                                 f'({ref.shape[0]}, 2), got {targets.shape}')
        self.reference = ref
        self.targets = targets
        self.threshold = float(threshold)
        self._r2 = np.einsum('ij,ij->i', ref, ref)

    def neighbours(self, x: np.ndarray, k: int = NEIGHBOURS):
        """(distance of the nearest reference input (RMS per control point, m), indices of
        the k nearest) for one feature vector (12,)."""
        d2 = self._r2 - 2.0 * (self.reference @ x) + float(x @ x)
        k = min(k, len(d2))
        idx = np.argpartition(d2, k - 1)[:k]
        return float(np.sqrt(max(d2[idx].min(), 0.0) / 4.0)), idx

    def nearest(self, X: np.ndarray) -> np.ndarray:
        """Nearest-neighbour distance (RMS per control point, m) of features (12,) or
        (B, 12) to the reference set."""
        x = np.atleast_2d(np.asarray(X, dtype=float))
        d2 = (np.einsum('ij,ij->i', x, x)[:, None] - 2.0 * x @ self.reference.T
              + self._r2[None, :])
        d = np.sqrt(np.maximum(d2.min(axis=1), 0.0) / 4.0)
        return d if np.ndim(X) == 2 else d[:1]

    def distance(self, X) -> np.ndarray:
        """Domain distance (dimensionless, <= 1 inside) of features (12,) or (B, 12)."""
        return self.nearest(X) / self.threshold

    @classmethod
    def calibrate(cls, X_train: np.ndarray, X_held_out: np.ndarray, seed: int = 0,
                  max_reference: int = MAX_REFERENCE,
                  quantile: float = DOMAIN_QUANTILE, margin: float = DOMAIN_MARGIN,
                  Y_train=None) -> 'DomainCheck':
        """A reference set (at most max_reference training inputs, a random subset, with
        their forces Y_train when given) and the threshold from held-out inputs of the same
        distribution."""
        X = np.asarray(X_train, dtype=float)
        Y = None if Y_train is None else np.asarray(Y_train, dtype=float)
        if len(X) > max_reference:
            sel = np.random.default_rng(seed).choice(len(X), max_reference, replace=False)
            X = X[sel]
            Y = None if Y is None else Y[sel]
        dc = cls(X, 1.0, Y)
        d = dc.nearest(np.asarray(X_held_out, dtype=float))
        dc.threshold = float(margin * np.quantile(d, quantile))
        return dc

    def arrays(self) -> dict:
        a = dict(domain_X=self.reference.astype(np.float32))
        if self.targets is not None:
            a['domain_Y'] = self.targets.astype(np.float32)
        return a

    def header(self) -> dict:
        return dict(threshold_m=self.threshold, quantile=DOMAIN_QUANTILE, margin=DOMAIN_MARGIN,
                    n_reference=int(len(self.reference)))

    @classmethod
    def from_model(cls, arrays: dict, header: dict) -> Optional['DomainCheck']:
        """The check stored in a model file, or None (files without one)."""
        if 'domain_X' not in arrays:
            return None
        th = header.get('domain', {}).get('threshold_m')
        if th is None:
            raise ValueError('model has a domain reference set but no domain threshold')
        return cls(arrays['domain_X'], float(th), arrays.get('domain_Y'))

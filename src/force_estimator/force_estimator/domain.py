"""The training domain of a learned force model: how far an input lies from the inputs the
model was trained on.

A model file stores a reference set of training inputs (control-point features, m) and a
calibrated threshold. The domain distance of an input is its nearest-neighbour distance to
the reference set (the RMS over the 4 control points of their 3-D distances, m) divided by
the threshold: <= 1 inside the domain. The threshold is a high quantile of the same distance
for held-out inputs of the training distribution (they are inside by construction), times a
margin: a shape the pipeline can produce for a tip force in range is inside; control points
scaled by 1e6, a tip 1 km away or the fit of a wrong segmentation are far outside.

Pure numpy; no rclpy.
"""
from __future__ import annotations

from typing import Optional

import numpy as np

__all__ = ['DomainCheck', 'DOMAIN_QUANTILE', 'DOMAIN_MARGIN', 'MAX_REFERENCE']

#: quantile of the held-out inputs' nearest-neighbour distances that sets the threshold
DOMAIN_QUANTILE = 0.995
#: the threshold is this many times that quantile
DOMAIN_MARGIN = 1.5
#: at most this many training inputs are kept as the reference set
MAX_REFERENCE = 4000


class DomainCheck:
    """reference: (n, 12) training features, m; threshold: m (> 0)."""

    def __init__(self, reference: np.ndarray, threshold: float):
        ref = np.ascontiguousarray(reference, dtype=float)
        if ref.ndim != 2 or ref.shape[1] != 12 or ref.shape[0] < 1:
            raise ValueError(f'reference must have shape (n >= 1, 12), got {ref.shape}')
        if not np.isfinite(ref).all():
            raise ValueError('reference contains non-finite values')
        if not (np.isfinite(threshold) and threshold > 0):
            raise ValueError(f'threshold must be positive and finite, got {threshold!r}')
        self.reference = ref
        self.threshold = float(threshold)
        self._r2 = np.einsum('ij,ij->i', ref, ref)

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
                  ) -> 'DomainCheck':
        """A reference set (at most max_reference training inputs, a random subset) and the
        threshold from held-out inputs of the same distribution."""
        X = np.asarray(X_train, dtype=float)
        if len(X) > max_reference:
            X = X[np.random.default_rng(seed).choice(len(X), max_reference, replace=False)]
        dc = cls(X, 1.0)
        d = dc.nearest(np.asarray(X_held_out, dtype=float))
        dc.threshold = float(margin * np.quantile(d, quantile))
        return dc

    def arrays(self) -> dict:
        return dict(domain_X=self.reference.astype(np.float32))

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
        return cls(arrays['domain_X'], float(th))

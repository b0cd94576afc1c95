"""Priors, bounds and parameter layout of the history model (`HistoryIdentifier`): the
positive definite matrix added to the data's information, and the physical box of every
parameter.

Layout (G = n_nodes grid nodes per table, K = len(sigmas) friction banks):
``S | F_0 B_0 | F_1 B_1 | ... | F_{K-1} B_{K-1} | C | mass``: the static force S (N), per
presliding-length candidate k the Coulomb level F_k on its Dahl state and the breakaway
extra B_k (N), the drag C (in N at the velocity scale V) and the mass (in N at the
acceleration scale A). The model of candidate k uses S, F_k, B_k, C and the mass
(`candidate_index`): the same 4 G + 1 parameters as an `Impedance` table model.
"""
from __future__ import annotations

from typing import Tuple

import numpy as np

from impedance_master.history_params import HistoryParams


def difference_gram(G: int, order: int) -> np.ndarray:
    """D^T D of the order-th finite difference operator on G nodes (G x G)."""
    D = np.eye(G)
    for _ in range(order):
        D = D[1:] - D[:-1]
    return D.T @ D


def n_params(p: HistoryParams) -> int:
    return (2 + 2 * len(p.sigmas)) * p.n_nodes + 1


def candidate_index(p: HistoryParams, k: int) -> np.ndarray:
    """Indices (into the full layout) of candidate k's parameters, in Impedance order
    S, F, B, C, mass."""
    G = p.n_nodes
    K = len(p.sigmas)
    fb = (1 + 2 * k) * G
    c0 = (1 + 2 * K) * G
    return np.concatenate([np.arange(G), np.arange(fb, fb + 2 * G),
                           np.arange(c0, c0 + G), [n_params(p) - 1]])


def build_prior(p: HistoryParams, A_scale: float) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(prior matrix P x P, lower bounds, upper bounds) for the layout above."""
    G = p.n_nodes
    K = len(p.sigmas)
    P = n_params(p)
    d2 = difference_gram(G, 2)
    origin = np.zeros((G, G))
    if p.origin_weight > 0.0 and p.x_min <= 0.0 <= p.x_max:
        # no inserted length, no friction or drag: the tables vanish at x = 0 (if the grid
        # reaches it), which anchors their growth with length
        u = -p.x_min / p.dx
        j = min(int(u), G - 2)
        h = np.zeros(G)
        h[j], h[j + 1] = 1.0 - (u - j), u - j
        origin = p.origin_weight * np.outer(h, h)
    smooth = p.friction_smoothness * d2 + origin
    if p.friction_kink > 0.0:
        smooth = smooth + p.friction_kink * difference_gram(G, 3)
    Pm = np.zeros((P, P))
    lo = np.full(P, -np.inf)
    hi = np.full(P, np.inf)
    s = slice(0, G)
    Pm[s, s] = p.smoothness * (difference_gram(G, 1) if p.static_first_difference else d2) \
        + p.static_ridge * np.eye(G)
    lo[s], hi[s] = p.static_min, p.max_force
    for k in range(K):
        f = slice((1 + 2 * k) * G, (2 + 2 * k) * G)
        b = slice((2 + 2 * k) * G, (3 + 2 * k) * G)
        Pm[f, f] = smooth
        Pm[b, b] = smooth + p.breakaway_ridge * np.eye(G)
        lo[f], hi[f] = 0.0, p.max_force
        lo[b], hi[b] = 0.0, p.max_force
    c = slice((1 + 2 * K) * G, (2 + 2 * K) * G)
    Pm[c, c] = smooth + p.viscous_ridge * np.eye(G)
    lo[c], hi[c] = 0.0, p.max_force
    Pm += 1e-6 * np.eye(P)
    lo[-1], hi[-1] = 0.0, p.max_mass * A_scale
    return Pm, lo, hi

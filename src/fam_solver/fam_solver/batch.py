"""Batch path: B tip-load cases solved at once, the general path's Newton vectorised over
the cases (converged cases drop out of the active set). No rclpy here.
"""
from __future__ import annotations

from typing import Optional

import numpy as np
from numpy.typing import ArrayLike

from .globalise import solve_cases, stability
from .mesh import regrade
from .model import BatchShape, Catheter
from .problem import (DEFAULT_ARC_MODEL, DEFAULT_SPACING, build_problem, check_arguments,
                      problem_rates, subproblem)


def solve_fam_batch(cat: Catheter, tip_forces: ArrayLike,
                    tip_moments: Optional[ArrayLike] = None, n_arcs: int = 12,
                    follower: bool = False, arc_model: str = DEFAULT_ARC_MODEL,
                    chunk: int = 4096, spacing: str = DEFAULT_SPACING) -> BatchShape:
    """Solve B tip-load cases at once (vectorised Newton over the batch).

    tip_forces: (B, 2) N (base frame, or tip frame if ``follower``); tip_moments: (B,) N m
    or None (zeros). arc_model and spacing as in ``solve_fam`` (graded: each case gets its
    own arcs; the results equal solve_fam's to ~1e-13 m). Returns a BatchShape:
    tips (B, 2), tip_angles (B,), arc_angles (B, N), arc_lengths (B, N), converged (B,),
    stable (B,), snap_through (B,), status (B,) (``status.Status`` codes), iterations (B,),
    centerlines(k) -> (B, k, 2).
    """
    check_arguments(cat, n_arcs, arc_model, spacing)
    tf = np.asarray(tip_forces, dtype=float)
    if tf.ndim != 2 or tf.shape[1] != 2:
        raise ValueError(f'tip_forces must have shape (B, 2), got {tf.shape}')
    if not np.all(np.isfinite(tf)):
        raise ValueError('tip_forces must be finite')
    B = tf.shape[0]
    if tip_moments is None:
        tm = np.zeros(B)
    else:
        tm = np.asarray(tip_moments, dtype=float)
        if tm.shape != (B,):
            raise ValueError(f'tip_moments must have shape ({B},), got {tm.shape}')
        if not np.all(np.isfinite(tm)):
            raise ValueError('tip_moments must be finite')
    if not isinstance(follower, (bool, np.bool_)):
        raise ValueError(f'follower must be a bool, got {follower!r}')
    n = int(n_arcs)
    phi = np.zeros((B, n))
    conv = np.zeros(B, dtype=bool)
    iters = np.zeros(B, dtype=int)
    res = np.zeros(B)
    stable = np.ones(B, dtype=bool)
    snap = np.zeros(B, dtype=bool)
    frac = np.full((B, n), 1.0 / n)
    clothoid = arc_model == 'clothoid'
    rates = np.zeros((B, n)) if clothoid else None
    F = tf[:, 0] + 1j * tf[:, 1]
    for lo in range(0, B, chunk):
        hi = min(B, lo + chunk)
        prob = build_problem(cat, n, F[lo:hi], bool(follower), tm[lo:hi], [],
                              clothoid=clothoid)
        p, c, it, r, snap[lo:hi] = solve_cases(prob, hi - lo, arc_model)
        stable[lo:hi] = stability(prob, p)
        if spacing == 'graded' and np.any(c) and n > 1 and not follower:
            idx = np.nonzero(c)[0]
            pg, fg, okg, itg, rg = regrade(subproblem(prob, idx), p[idx], arc_model)
            it[idx] += itg
            take = idx[okg]
            p[take], r[take] = pg[okg], rg[okg]
            frac[lo + take] = fg[okg]
        phi[lo:hi], conv[lo:hi], iters[lo:hi], res[lo:hi] = p, c, it, r
        if clothoid:
            rates[lo:hi] = problem_rates(prob, p, frac[lo:hi] if spacing == 'graded' else None)
    return BatchShape(cat.length, phi, conv, iters, stable, res, arc_model, spacing=spacing,
                      fractions=frac, rates=rates, snap_through=snap)

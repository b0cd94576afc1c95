"""The FAM problem: N arcs, the loads on them (scaled by a continuation factor), and the
argument checks of the public solvers.

A ``Problem`` holds B load cases on N arcs (equal, or per-case graded lengths): the tip force
(complex, base frame or tip frame if follower), the tip moment and base-fixed point forces,
each point force placed at its arc and its fraction inside the arc. ``loads(scale)`` gives
the ``equations.Load`` list at a load scale (continuation). No rclpy here.
"""
from __future__ import annotations

from typing import List, Optional, Tuple

import numpy as np

from .arcs import g_only
from .equations import Load, clothoid_rates
from .model import SPACINGS, Catheter, uniform_fractions

ARC_MODELS = ('exact', 'bezier', 'clothoid')
#: The default arc model: 'clothoid' (fourth order; 'exact' and 'bezier' are second order).
DEFAULT_ARC_MODEL = 'clothoid'
#: The default arc spacing: 'uniform' (equal arcs) or 'graded' (per-case arc lengths, see
#: ``mesh.graded_fractions``).
DEFAULT_SPACING = 'uniform'
MAX_N = 100_000
#: N of the coarse model that starts (and judges the stability of) problems with many arcs
COARSE_N = 32


class Problem:
    """Loads scaled by a continuation factor; builds Load lists for a given scale.

    l: arc lengths (N,) m, or (B, N) per case (graded arcs); w = l / EI, same shape;
    L: catheter length; EI; point_forces: (arc index, fraction inside the arc, complex (B,))
    (a point force needs arcs common to all cases: l (N,) or B = 1); pf_s: their arc-length
    fractions of the whole catheter."""

    def __init__(self, n: int, l: np.ndarray, w: np.ndarray, tip_force: np.ndarray, follower: bool,
                 tip_moment: np.ndarray, point_forces: list, L: float, EI: float, pf_s: list,
                 clothoid: bool = False):
        self.n, self.l, self.w = n, l, w
        self.clothoid = clothoid          # arc model 'clothoid' (else circular arcs)
        self.L, self.EI = L, EI
        self.pf_s = pf_s
        self.tip_force = tip_force      # complex (B,)
        self.follower = follower
        self.tip_moment = tip_moment    # (B,)
        self.point_forces = point_forces  # list of (a, tau, complex (B,))

    def loads(self, scale) -> Tuple[List[Load], np.ndarray]:
        out = []
        for a, tau, F in self.point_forces:
            out.append(Load(a, tau, F * scale, False))
        if np.any(self.tip_force != 0):
            out.append(Load(self.n - 1, 1.0, self.tip_force * scale, self.follower))
        return out, self.tip_moment * scale


def make_problem(n: int, L: float, EI: float, tip_force: np.ndarray, follower: bool,
                 tip_moment: np.ndarray, point_forces: list, fractions: Optional[np.ndarray] = None,
                 clothoid: bool = False) -> Problem:
    """Core problem of n arcs of lengths L * fractions ((N,) or (B, N); None: equal arcs);
    point_forces: list of (s fraction, complex (B,)). A point force inside an arc is carried
    at its fraction tau of that arc (closed form); at an arc end tau = 1."""
    frac = uniform_fractions(n) if fractions is None else fractions
    l = L * frac
    w = l / EI
    fr = frac if frac.ndim == 1 else frac[0]          # point forces: B = 1 when per case
    bounds = np.concatenate([[0.0], np.cumsum(fr)])
    bounds[-1] = 1.0
    frac = fr
    pfs, pf_s = [], []
    for s, F in point_forces:
        a = int(np.searchsorted(bounds, s - 1e-9 / n, side='left')) - 1
        a = min(max(a, 0), n - 1)
        tau = min(max((s - bounds[a]) / frac[a], 0.0), 1.0)
        if tau >= 1.0 - 1e-9:
            tau = 1.0
        pfs.append((a, tau, F))
        pf_s.append(s)
    return Problem(n, l, w, tip_force, follower, tip_moment, pfs, L, EI, pf_s, clothoid)


def build_problem(cat: Catheter, n: int, tip_force: np.ndarray, follower: bool,
                  tip_moment: np.ndarray, point_forces: list,
                  fractions: Optional[np.ndarray] = None,
                  clothoid: bool = False) -> Problem:
    return make_problem(n, cat.length, cat.ei, tip_force, follower, tip_moment, point_forces,
                         fractions, clothoid)


def tolerance(phi: np.ndarray) -> np.ndarray:
    """Newton's convergence tolerance on max |r_i| (rad) per case, (B,)."""
    return 1e-13 + 1e-12 * np.max(np.abs(phi), axis=1)


def load_size(prob: Problem) -> np.ndarray:
    """Dimensionless load size per case: sum |F| L^2/EI + |m| L/EI, (B,)."""
    L = prob.L
    EI = prob.EI
    f = np.abs(prob.tip_force)
    for _, _, F in prob.point_forces:
        f = f + np.abs(F)
    return f * L * L / EI + np.abs(prob.tip_moment) * L / EI


def repeat_problem(prob: Problem, k: int) -> Problem:
    """Each case repeated k times (finite-difference Jacobians)."""
    rep = lambda x: np.repeat(x, k)  # noqa: E731
    rl = (lambda x: np.repeat(x, k,
                              axis=0)) if np.ndim(prob.l) == 2 else (lambda x: x)  # noqa: E731
    return Problem(prob.n, rl(prob.l), rl(prob.w), rep(prob.tip_force), prob.follower,
                    rep(prob.tip_moment), [(a, t, rep(F)) for a, t, F in prob.point_forces],
                    prob.L, prob.EI, prob.pf_s, prob.clothoid)


def subproblem(prob: Problem, idx) -> Problem:
    """The cases ``idx`` (index or mask) of ``prob``."""
    per_case = np.ndim(prob.l) == 2
    return Problem(prob.n, prob.l[idx] if per_case else prob.l, prob.w[idx] if per_case else prob.w,
                    prob.tip_force[idx], prob.follower,
                    prob.tip_moment[idx], [(a, t, F[idx]) for a, t, F in prob.point_forces],
                    prob.L, prob.EI, prob.pf_s, prob.clothoid)


def coarse_problem(prob: Problem) -> Problem:
    """The same loads on COARSE_N equal arcs (start and stability model for N > 64)."""
    return make_problem(COARSE_N, prob.L, prob.EI, prob.tip_force, prob.follower, prob.tip_moment,
                         [(s, F) for s, (_, _, F)
                          in zip(prob.pf_s, prob.point_forces, strict=True)],
                         clothoid=prob.clothoid)


def midpoints(prob: Problem) -> np.ndarray:
    """Arc-length fractions (N,) of the arc midpoints (equal arcs)."""
    c = np.cumsum(prob.l)
    return (c - 0.5 * prob.l) / prob.L


def problem_rates(prob: Problem, phi: np.ndarray, frac: Optional[np.ndarray] = None
                  ) -> Optional[np.ndarray]:
    """Clothoid rates (B, N) of the solution phi (B, N) of ``prob`` (on arcs ``frac`` (B, N)
    of L when given: a graded solution), or None for circular arcs."""
    if not prob.clothoid:
        return None
    if frac is not None:
        prob = make_problem(prob.n, prob.L, prob.EI, prob.tip_force, prob.follower,
                             prob.tip_moment,
                             [(s, F) for s, (_, _, F)
                              in zip(prob.pf_s, prob.point_forces, strict=True)],
                             frac, True)
    loads, _ = prob.loads(1.0)
    th_end = np.cumsum(phi, axis=1)
    lE = prob.l * np.exp(1j * (th_end - phi))
    return clothoid_rates(phi, lE, g_only(phi), th_end, prob.w, loads)


def check_arguments(cat, n_arcs, arc_model, spacing='uniform') -> None:
    """ValueError naming the argument unless cat, n_arcs, arc_model and spacing are valid."""
    if not isinstance(cat, Catheter):
        raise ValueError(f'cat must be a Catheter, got {type(cat).__name__}')
    if isinstance(n_arcs, bool) or not isinstance(n_arcs, (int, np.integer)):
        raise ValueError(f'n_arcs must be an integer, got {n_arcs!r}')
    if not 1 <= int(n_arcs) <= MAX_N:
        raise ValueError(f'n_arcs must be in [1, {MAX_N}], got {n_arcs}')
    if arc_model not in ARC_MODELS:
        raise ValueError(f'arc_model must be one of {ARC_MODELS}, got {arc_model!r}')
    if not (isinstance(spacing, str) and spacing in SPACINGS):
        raise ValueError(f'spacing must be one of {SPACINGS}, got {spacing!r}')

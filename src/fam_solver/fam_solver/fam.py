"""The Finite Arc Method (thesis Chapter 3, Eqs. 7-28): the public solvers.

The catheter (length L, rigidity EI) is cut into N arcs; arc i turns by phi_i. All N arc
angles are solved together by Newton's method with the analytic Jacobian, because loads fixed
in the base frame couple them (the arc orientations are unknown during a tip -> base sweep).
Follower tip forces (tendon pull) are the same system with the force turning with theta_N.

Where each idea lives:

* ``arcs``       closed forms of one arc (circular, clothoid offsets, Bezier handle length);
* ``equations``  the N arc-angle equations (circular / clothoid arcs) and Jacobian factors;
* ``bezier``     the thesis' Bezier arc model as residuals for the same Newton solver;
* ``problem``    load cases on N arcs, continuation scaling, argument checks;
* ``linsolve``   the Newton step (dense for small N, O(N) beyond) and the eigenvalue checks;
* ``globalise``  which equilibrium: direct attempt, load continuation, snap-through, buckling;
* ``mesh``       graded arc lengths (``spacing='graded'``);
* ``fast``       the single-case fast path for tip loads (which equilibrium);
* ``fast_newton`` its Newton kernel (1-D arrays, LAPACK directly);
* ``fast_bezier`` the Bezier arcs' kernel on the fast path (the Eq. 23 integrals as series);
* ``batch``      ``solve_fam_batch``, the general path vectorised over cases;
* ``status``     outcome codes (``Status``) of ``Shape`` and ``BatchShape``.

Arc model and spacing (decision): clothoid arcs on equal arcs by default. Circular arcs (the
thesis's FAM, 'exact') missed the N = 12 target of 0.1 % L on a post-buckled compression
whatever the spacing; clothoid arcs remove the leading error term itself (fourth order) and
meet it by a wide margin on equal arcs, where grading them no longer pays. The measured
figures behind these decisions are in the package README (from ``scripts/bench fam``).

Non-convergence returns the best iterate (finite numbers) with ``converged=False``; every
result carries a ``status`` (``status.Status``). No rclpy here.
"""
from __future__ import annotations

import numpy as np

from .batch import solve_fam_batch
from .fast import fast_solve
from .globalise import solve_cases, stability
from .linsolve import DENSE_MAX_N
from .mesh import graded_fractions, regrade, remap
from .model import SPACINGS, BatchShape, Catheter, Loads, Shape, arc_shape
from .problem import (ARC_MODELS, DEFAULT_ARC_MODEL, DEFAULT_SPACING, MAX_N, build_problem,
                      check_arguments, problem_rates)
from .status import Status, warning_text

__all__ = ['solve_fam', 'solve_fam_batch', 'graded_fractions', 'Catheter', 'Loads', 'Shape',
           'BatchShape', 'Status', 'ARC_MODELS', 'SPACINGS', 'DEFAULT_ARC_MODEL',
           'DEFAULT_SPACING', 'DENSE_MAX_N', 'MAX_N']


def solve_fam(cat: Catheter, loads: Loads, n_arcs: int = 12, arc_model: str = DEFAULT_ARC_MODEL,
              initial=None, spacing: str = DEFAULT_SPACING) -> Shape:
    """Solve the FAM for one load case; returns a Shape (see ``model.Shape``).

    cat: Catheter (m, N m^2). loads: Loads (N, N m; base frame, or tip frame if follower).
    n_arcs: number of arcs N (1..100000). arc_model: 'clothoid' (default: arcs whose
    curvature changes linearly, fourth order), 'exact' (true circular arcs, the FAM of the
    thesis with exact arcs) or 'bezier' (the thesis' Bezier arcs, Eqs. 7-12). spacing:
    'uniform' (default, N equal arcs) or 'graded' (per-case arc lengths from the curvature
    change of the equal-arc solution, see ``mesh``);
    ``shape.arc_lengths`` (N,) m gives the arcs.
    Never returns NaN: a case that does not converge has converged=False and the best
    finite iterate. ``shape.status`` (``Status``) tells converged / not converged /
    unstable / snap-through apart.
    initial: optional warm start (a previous Shape, or arc angles (N,) of EQUAL arcs); used
    (tip loads, N <= 64) when Newton from it converges to an equilibrium whose Jacobian
    eigenvalues all have positive real parts, else ignored (cold start).
    """
    check_arguments(cat, n_arcs, arc_model, spacing)
    if not isinstance(loads, Loads):
        raise ValueError(f'loads must be a Loads, got {type(loads).__name__}')
    n = int(n_arcs)
    tip = complex(*loads.tip_force)
    # without a tip force the follower flag changes nothing (it turns only the tip force);
    # dropping it lets base-fixed forces at the tip join the tip load (the fast path)
    follower = bool(loads.follower) and tip != 0
    pfs = []
    for s, fx, fy in loads.point_forces:
        if s >= 1.0 and not follower:
            tip += complex(fx, fy)
        else:
            pfs.append((s, np.array([complex(fx, fy)])))
    if initial is not None:
        init_frac = getattr(initial, 'arc_lengths', None)
        init_len = getattr(initial, 'length', None)
        initial = np.asarray(getattr(initial, 'arc_angles', initial), dtype=float)
        if initial.shape != (n,) or not np.all(np.isfinite(initial)):
            raise ValueError(f'initial must be finite arc angles of shape ({n},)')
        if init_frac is not None and init_len and np.ptp(init_frac) > 0:
            # a graded Shape: the same tangent-angle curve on equal arcs (the first pass)
            initial = remap(initial[None], np.full((1, n), 1.0 / n),
                            (np.asarray(init_frac) / init_len)[None])[0]
    clothoid = arc_model == 'clothoid'
    bezier = arc_model == 'bezier'
    if not pfs:
        out = fast_solve(n, cat.length, cat.ei, tip, loads.tip_moment, follower, initial,
                         spacing, clothoid, bezier=bezier)
        if out is None and initial is not None:
            out = fast_solve(n, cat.length, cat.ei, tip, loads.tip_moment, follower,
                             spacing=spacing, clothoid=clothoid, bezier=bezier)
        if out is not None:
            phi, conv, it, res, tipc, stable, frac, rho = out
            return arc_shape(cat.length, phi, tip=tipc, tip_angle=float(phi.sum()),
                             converged=True, iterations=it, stable=stable, warning='',
                             residual=res, arc_model=arc_model, spacing=spacing, fractions=frac,
                             rates=rho, _trusted=True)
    prob = build_problem(cat, n, np.array([tip]), follower,
                         np.array([loads.tip_moment]), pfs, clothoid=clothoid)
    start = gfrac = None
    extra = 0
    if arc_model == 'bezier' and not pfs:
        # the Bezier model starts from the circular-arc solution (fast path): the two agree
        # to O(phi^2) per arc, so Newton on the Bezier residual (exact Jacobian) needs 1-3
        # iterations; graded arcs are placed from the circular solution's curvature change
        # (the fast path's graded pass) and the Bezier model is solved once, on them
        ex = fast_solve(n, cat.length, cat.ei, tip, loads.tip_moment, follower,
                        spacing=spacing)
        if ex is not None:
            start, gfrac, extra = ex[0][None], ex[6], ex[2]   # its iterations count too
    sprob = prob if gfrac is None else build_problem(
        cat, n, np.array([tip]), follower, np.array([loads.tip_moment]), [],
        fractions=gfrac[None])
    phi, conv, iters, res, snapped = solve_cases(sprob, 1, arc_model, start)
    if gfrac is not None and not conv[0]:     # not on the graded arcs: equal arcs, regraded
        ex = fast_solve(n, cat.length, cat.ei, tip, loads.tip_moment, follower)
        start, gfrac = ex[0][None] if ex is not None else None, None
        extra += ex[2] if ex is not None else 0
        phi, conv, i2, res, snapped = solve_cases(prob, 1, arc_model, start)
        iters = iters + i2
    iters = iters + extra
    frac = gfrac
    # stability (buckling) on equal arcs: the same tangent-angle curve
    stable = stability(prob, phi if gfrac is None else
                       remap(phi, np.full((1, n), 1.0 / n), gfrac[None]))
    if spacing == 'graded' and gfrac is None and conv[0] and n > 1 and not follower:
        pg, fg, okg, itg, rg = regrade(prob, phi, arc_model)
        iters = iters + itg
        if okg[0]:
            phi, res, frac = pg, rg, fg[0]
    conv0, stable0, snap0 = bool(conv[0]), bool(stable[0]), bool(snapped[0])
    warning = warning_text(conv0, stable0, snap0, float(res[0]))
    rho = problem_rates(prob, phi, None if frac is None else frac[None])
    return arc_shape(cat.length, phi[0], converged=conv0, iterations=int(iters[0]),
                     stable=stable0, snap_through=snap0, warning=warning, residual=float(res[0]),
                     arc_model=arc_model, spacing=spacing, fractions=frac,
                     rates=None if rho is None else rho[0])

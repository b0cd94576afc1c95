"""Mutants of fam_solver for tests/mutation/mutate.py: each breaks one property the package
promises; the fam tests (without the ROS node tests) must kill every one.

    python tests/mutation/mutate.py fam
"""
from mutate import Mutant

TESTS = ['tests/fam_solver', '-k', 'not test_node']

P = 'src/fam_solver/fam_solver/'

MUTANTS = [
    # -- issue 14's survivor: the buckling check beyond 64 arcs runs on a 32-arc model
    Mutant('M01', P + 'globalise.py',
           'phic = np.stack([np.interp(sc, sf, phi[b] / prob.l) for b in range(B)]) * coarse.l',
           'phic = np.stack([np.interp(sc, sf, phi[b]) for b in range(B)])',
           'general path, N > 64: angles not scaled to the coarse arcs (compressed shapes flip to '
           'unstable)'),
    Mutant('M02', P + 'fast.py',
           'return np.interp(sn, sm, phi) * (m / n)',
           'return np.interp(sn, sm, phi)',
           'fast path, N > 64: coarse start and stability model without the arc-length scaling'),
    # -- the O(N) banded Newton step
    Mutant('M03', P + 'linsolve.py',
           'ab[5, 0:-2:2] = C[1:]',
           'ab[5, 0:-2:2] = -C[1:]',
           'banded solve: sign of the z-recurrence coupling flipped'),
    Mutant('M04', P + 'linsolve.py',
           'Y = y[-1] / (1.0 - u[-2, 1])',
           'Y = y[-1]',
           'banded solve: follower force, the tip-sum unknown not solved for'),
    Mutant('M05', P + 'linsolve.py',
           'ab[6, 0:-2:2] = -wB[1:] - w[1:] * A[1:]',
           'ab[6, 0:-2:2] = -wB[:-1] - w[:-1] * A[:-1]',
           'banded solve: off-by-one arc index in the sub-diagonal'),
    # -- the branch / stability check
    Mutant('M06', P + 'linsolve.py',
           'return bool(np.min(wr) > 1e-9)',
           'return False',
           'energy_stable: the eigenvalue fallback dropped (follower and clothoid cases rejected)'),
    Mutant('M07', P + 'fast.py',
           '        return _stable_at(phi, J, w, None, L, EI, F, m, follower, clothoid)',
           '        return True',
           'fast path: branch check dropped (other equilibria accepted)'),
    Mutant('M08', P + 'globalise.py',
           '    if not np.any(compress):\n        return stable',
           '    if True:\n        return stable',
           'general path: buckling never flagged'),
    # -- the fast Newton kernel
    Mutant('M09', P + 'fast_newton.py',
           'r = phi - w * (m - ZF.imag)',
           'r = phi - w * (m + ZF.imag)',
           'kernel residual: sign of the force moment flipped'),
    Mutant('M10', P + 'fast_newton.py',
           'c = irc + Y[:, 0].imag',
           'c = Y[:, 0].imag',
           'kernel Jacobian: the lever-arm term of the distal columns dropped'),
    Mutant('M11', P + 'fast_newton.py',
           'if clothoid and (res < QUASI_ABOVE or n < _QUASI_MIN_N):',
           'if clothoid and res < QUASI_ABOVE:',
           'kernel: clothoid rates\' Jacobian terms not used for N < 3 (linear convergence)'),
    Mutant('M12', P + 'fast_newton.py',
           '    if pmax < _SERIES_LIMIT:',
           '    if pmax < 10.0:',
           'kernel: Taylor series used beyond its range (wrong series switch)'),
    Mutant('M13', P + 'fast_newton.py',
           '            d = d + dg_',
           '            d = d',
           'kernel Jacobian: clothoid rates\' diagonal terms dropped'),
    # -- equations, problem set-up
    Mutant('M14', P + 'equations.py',
           '            k = a + 1',
           '            k = a',
           'equations: a load at an arc end not carried by its own arc (off by one)'),
    Mutant('M15', P + 'equations.py',
           "        S = cs[..., -1:] - cs         # sum over j > i",
           "        S = cs[..., -1:] - cs + u     # sum over j >= i",
           'clothoid Jacobian: distal sum includes the arc itself (off by one)'),
    Mutant('M16', P + 'problem.py',
           '        if tau >= 1.0 - 1e-9:',
           '        if tau >= 1.0 - 1e-3:',
           'point force near an arc end snapped to the end (wrong load position)'),
    # -- globalisation: continuation and snap-through fallbacks
    Mutant('M17', P + 'fast.py',
           '        out = _continuation(n, l, w, F, m, follower, cl, lin, mi)',
           '        out = None',
           'fast path: continuation fallback dropped (loads fall to the slow general path)'),
    Mutant('M18', P + 'globalise.py',
           'starts = [phi[b]] + [phi[b] + k * unit for k in (0.5, 1.0, 2.0, 3.0)]',
           'starts = []',
           'snap-through: no equilibrium searched beyond the fold',
           harmless='the shapes turned to tip angles up to 2 pi (the later starts) find the '
                    'same equilibrium on every snap-through case tested; the starts along the '
                    'path only save iterations (249 vs 310 on the test case)'),
    Mutant('M19', P + 'globalise.py',
           '        take = c2 | ~conv[idx]',
           '        take = c2 & ~c2',
           'general path: continuation result discarded'),
    Mutant('M20', P + 'fast.py',
           '        ok = c and abs(float(p.sum() - phi.sum())) <= 0.5',
           '        ok = c',
           'fast continuation: unbounded steps (may jump to another branch)'),
    Mutant('M21', P + 'fast.py',
           '        if abs(th - th_c) >= 0.5:',
           '        if abs(th - th_c) >= 50.0:',
           'fast path: a fine solution far from the coarse one it started from accepted'),
    Mutant('M22', P + 'globalise.py',
           'lin / safe[:, None] * target[:, None], lin)',
           'lin * (target / safe)[:, None], lin)',
           'general start rescale overflows for denormal loads (NaN)'),
    # -- status and batch
    Mutant('M23', P + 'status.py',
           'return np.where(conv & ~np.asarray(stable, dtype=bool), int(Status.UNSTABLE), out)',
           'return out',
           'status: UNSTABLE never reported'),
    Mutant('M24', P + 'batch.py',
           'p, c, it, r, snap[lo:hi] = solve_cases(prob, hi - lo, arc_model)',
           'p, c, it, r, _ = solve_cases(prob, hi - lo, arc_model)',
           'batch: snap-through flag dropped'),
    # -- mesh grading
    Mutant('M25', P + 'mesh.py',
           '    rho = (kp * kp + GRADE_FLOOR * GRADE_FLOOR) ** (0.5 * GRADE_POWER)\n    rho[flat] '
           '= 1.0',
           '    rho = (kp * kp + GRADE_FLOOR) ** (0.5 * GRADE_POWER)\n    rho[flat] = 1.0',
           'graded mesh: floor not squared (batched grading differs from the fast one)'),
]

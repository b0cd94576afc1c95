"""Mutants of force_estimator (control points -> tip force with covariance and status) for
tests/mutation/mutate.py: each breaks one property the package promises (bounded output,
the training envelope and domain, the FAM fallback, honest statuses and covariances); the
force_estimator tests (without the ROS node, README and training tests) must kill every one.

    python tests/mutation/mutate.py force
"""
from mutate import Mutant

TESTS = ['tests/force_estimator', '-k', 'not test_node and not test_readme and not test_train']

P = 'src/force_estimator/force_estimator/'

MUTANTS = [
    # -- issue 14's survivor: the envelope force check of the single-sample path
    Mutant('E01', P + 'models.py',
           '            ok = bool(y2 <= self._fmax2)',
           '            ok = True',
           'issue 14 survivor: one sample beyond the trained force range is neither scaled back '
           'nor flagged'),
    Mutant('E02', P + 'models.py',
           '        xc = np.clip(x, self._lo, self._hi)          # bounded: no extrapolation',
           '        xc = x',
           'features not clipped into the envelope box (unbounded extrapolation)'),
    Mutant('E03', P + 'models.py',
           '            return y, ok and bool((x == xc).all())',
           '            return y, ok',
           'single-sample path: an input outside the envelope box is flagged in-envelope'),
    Mutant('E04', P + 'models.py',
           '            e -= self._gamma * (z @ z)',
           '            e += self._gamma * (z @ z)',
           'single-sample SVR kernel differs from the batch one (sign of |z|^2)'),
    Mutant('E05', P + 'models.py',
           "            cov, (not ratio <= 1.0, 'out_of_domain',",
           "            cov, (not ratio <= 10.0, 'out_of_domain',",
           "inputs far from the training data are reported 'ok' (no 'out_of_domain')"),
    Mutant('E06', P + 'models.py',
           '            if self._ref_weak[j] > np.linalg.eigvalsh(C)[-1]:',
           '            if False:',
           "the neighbours' weak direction ignored: overconfident covariance"),
    Mutant('E07', P + 'hybrid.py',
           '        if self.fam is None or e.status not in FALLBACK_STATUSES:',
           '        if True:',
           'the FAM fallback never runs for inputs the learned model does not cover'),
    Mutant('E08', P + 'hybrid.py',
           '        fam = FamInverseEstimator(cat, n_arcs=n_arcs, f_max=min(f_max, m.f_bound))',
           '        fam = FamInverseEstimator(cat, n_arcs=n_arcs, f_max=f_max)',
           "the fallback publishes forces beyond the learned model's trained range as normal"),
    Mutant('E09', P + 'estimate.py',
           '    if n > f_max:\n        return f * (f_max / n), True',
           '    if n > 2 * f_max:\n        return f * (f_max / n), True',
           'bounded(): forces up to 2 f_max pass unclipped'),
    Mutant('E10', P + 'estimate.py',
           '    var = (0.5 * f_max) ** 2',
           '    var = (0.05 * f_max) ** 2',
           'a failed estimate (force 0) claims a tight covariance'),
    Mutant('E11', P + 'estimate.py',
           "    if status == 'ok' and np.linalg.eigvalsh(cov)[-1] > UNOBSERVABLE_STD ** 2:",
           "    if status == 'ok' and np.linalg.eigvalsh(cov)[-1] > UNOBSERVABLE_STD:",
           "an axial pull the shape cannot see is reported 'ok' (variance compared with a std)"),
    Mutant('E12', P + 'inputs.py',
           '    if big > MAX_COORD:',
           '    if big > 1e9:',
           "absurd control points (metres away) are estimated instead of refused ('bad_input')"),
    Mutant('E13', P + 'fam_inverse.py',
           "            (not res <= self.max_residual, 'no_fit',",
           "            (False, 'no_fit',",
           "FAM inversion: a shape no tip force explains is reported as a force ('no_fit' lost)"),
    Mutant('E14', P + 'fam_inverse.py',
           "            cov, (not conv, 'not_converged',",
           "            cov, (False, 'not_converged',",
           'FAM inversion: a non-converged solve is reported as an estimate'),
]

"""Force estimates that know their domain (issue 10 item 4, issue 11): absurd inputs give
bounded, flagged estimates, never normal ones; model files are validated on load; the
estimate object's invariants hold for any input (fuzzed)."""
import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from force_estimator import NORMAL, STATUSES, ForceModel, load_estimator
from force_estimator.estimate import (DOMAIN_UNKNOWN, UNOBSERVABLE_STD, failed_estimate,
                                      status_of)
from force_estimator.hybrid import HybridEstimator, make_estimator

L = 0.065


@pytest.fixture(scope='module')
def models(toy_models):
    return toy_models[2]


@pytest.fixture(scope='module')
def fam():
    pytest.importorskip('fam_solver')
    from fam_solver import Catheter
    from force_estimator import FamInverseEstimator
    return FamInverseEstimator(Catheter(length=L, ei=6e-5), n_arcs=12, table_angles=24,
                               table_magnitudes=8)


def _check(e, f_bound):
    """The estimate object's invariants."""
    assert e.status in STATUSES
    assert e.message_status in ('ok', 'unobservable_axial', 'out_of_domain', 'non_finite_input')
    assert (e.message_status in ('ok', 'unobservable_axial')) == e.normal
    assert e.force.shape == (2,) and np.all(np.isfinite(e.force))
    assert np.hypot(*e.force) <= f_bound * (1 + 1e-9)
    C = e.covariance
    assert C.shape == (2, 2) and np.all(np.isfinite(C)) and np.allclose(C, C.T)
    assert np.linalg.eigvalsh(C)[0] >= -1e-15
    assert e.normal == (e.status in NORMAL)
    if e.normal:
        assert e.domain_distance == 0.0
    assert np.isfinite(e.domain_distance) and e.domain_distance >= 0.0


# --- the defects of issue 10, item 4 -----------------------------------------------------------

@pytest.mark.parametrize('kind', ['svr', 'mlp', 'big'])
def test_scaled_and_far_control_points_are_bounded_and_flagged(toy_models, kind):
    """MLP control points scaled 1e6 gave (-2.0e5, -6.0e4) N; p3 at (1e3, -1e3) gave
    27 520 N; an 8000x8000 frame's control points gave (48.9, -85.0) N; +-1e308 gave NaN."""
    X, _, models, _ = toy_models
    m = models[kind]
    cp = X[3].reshape(4, 3)
    far = cp.copy()
    far[3, :2] = (1e3, -1e3)
    big = np.array([[0, 0, 0], [0.4, 0.1, 0], [0.8, -0.3, 0], [1.1, -0.6, 0]])   # 8000 px frame
    huge = np.full((4, 3), 1e308)
    huge[::2] *= -1
    for bad in (cp * 1e6, far, big, huge, cp + 0.05):
        f, inside = m.predict(bad, return_flags=True)
        assert np.all(np.isfinite(f)) and np.hypot(*f) <= m.f_bound * (1 + 1e-12)
        assert not inside
        e = m.estimate(bad)
        _check(e, m.f_bound)
        assert not e.normal and e.status in ('bad_input', 'out_of_domain', 'out_of_envelope')
    assert m.estimate(cp * 1e6).status == 'bad_input'


@pytest.mark.parametrize('kind', ['svr', 'mlp'])
def test_training_inputs_are_normal_estimates(toy_models, kind):
    X, Y, models, _ = toy_models
    m = models[kind]
    es = [m.estimate(x.reshape(4, 3)) for x in X[:130:5]]
    for e in es:
        _check(e, m.f_bound)
    assert sum(e.normal for e in es) >= 0.9 * len(es)
    assert all(e.method == kind and e.primary == kind for e in es)
    assert all(e.domain_distance == 0.0 for e in es if e.normal)


def test_non_finite_and_wrongly_shaped_input(models):
    m = models['mlp']
    x = np.zeros((4, 3))
    x[1, 0] = np.nan
    e = m.estimate(x)
    assert e.status == 'non_finite_input' and not e.normal and np.all(e.force == 0)
    assert e.domain_distance == DOMAIN_UNKNOWN
    with pytest.raises(ValueError, match='control_points'):
        m.estimate(np.zeros((3, 3)))
    with pytest.raises(ValueError, match='control_points'):
        m.estimate(np.zeros((2, 4, 3)))
    with pytest.raises(ValueError, match='status'):
        failed_estimate('weird', 'svr', '', 0.3)


def _tampered(model, tmp_path, edit, name):
    path = model.save(tmp_path / f'{name}.npz')
    with np.load(path, allow_pickle=False) as d:
        arrays = {k: np.array(d[k]) for k in d.files}
    header = json.loads(str(arrays.pop('header')[()]))
    edit(arrays, header)
    out = tmp_path / f'{name}-bad.npz'
    np.savez(out, header=np.array(json.dumps(header)), **arrays)
    return str(out)


@pytest.mark.parametrize('kind', ['svr', 'mlp'])
def test_model_files_are_validated_on_load(models, tmp_path, kind):
    """A file with weights 1e200 loaded and published 1.4e200 N; a tampered finite file
    (b x 1e6) loaded silently."""
    m = models[kind]
    assert load_estimator(m.save(tmp_path / 'good.npz')).kind == kind
    w = 'coef' if kind == 'svr' else 'W1'
    b = 'intercept' if kind == 'svr' else 'b1'

    def huge(a, h):
        a[w] = a[w] * 1e200

    def shifted(a, h):
        a[b] = a[b] * 1e6 + 1.0

    def nan_weight(a, h):
        a[w] = a[w].copy()
        a[w].flat[0] = np.nan

    def absurd_range(a, h):
        h['envelope']['max_force'] = 1e6

    def no_range(a, h):
        del h['envelope']['max_force']

    def bad_cov(a, h):
        h['model_cov'] = [[-1.0, 0.0], [0.0, 1.0]]

    def bad_domain(a, h):
        a['domain_X'] = a['domain_X'][:, :5]

    for edit, match in ((huge, 'implausible weights'), (shifted, 'self-test'),
                        (nan_weight, 'not finite'), (absurd_range, 'max_force'),
                        (no_range, 'max_force'), (bad_cov, 'model_cov'),
                        (bad_domain, 'reference')):
        with pytest.raises(ValueError, match=match):
            load_estimator(_tampered(m, tmp_path, edit, edit.__name__))


def test_garbage_files_are_refused(tmp_path):
    p = tmp_path / 'junk.npz'
    p.write_bytes(b'not a zip file at all')
    with pytest.raises(ValueError, match='readable'):
        load_estimator(str(p))
    np.savez(tmp_path / 'list.npz', header=np.array(json.dumps([1, 2])))
    with pytest.raises(ValueError, match='JSON object'):
        load_estimator(str(tmp_path / 'list.npz'))


def test_straight_catheter_does_not_give_a_large_force_from_fam(fam):
    """Straight 65 mm control points gave 0.675 N from fam: the iteration drifted along the
    axial pull, which the shape does not show. Now ~0 with a large axial uncertainty."""
    cp = np.array([[0, 0, 0], [L / 3, 0, 0], [2 * L / 3, 0, 0], [L, 0, 0]], dtype=float)
    fam.reset()
    e = fam.estimate(cp)
    _check(e, fam.f_max)
    assert np.hypot(*e.force) < 0.02
    assert e.status == 'axial_unobservable' and e.normal
    assert abs(e.weak_direction[0]) > 0.95 and e.max_std > UNOBSERVABLE_STD
    assert e.std[1] < 0.01                               # the lateral component is known


def test_fam_estimates_carry_covariance_and_status(fam):
    from fam_solver import Catheter, Loads, solve_fam
    from catheter_shape import fit_bezier
    cat = Catheter(length=L, ei=6e-5)
    c = solve_fam(cat, Loads(tip_force=(-0.05, 0.15)), n_arcs=24).centerline(200)
    cp = fit_bezier(np.c_[c, np.zeros(len(c))])
    fam.reset()
    e = fam.estimate(cp)
    _check(e, fam.f_max)
    assert e.status == 'ok' and e.method == 'fam' and e.in_envelope
    assert np.hypot(*(e.force - (-0.05, 0.15))) < 0.005
    assert e.max_std < 0.01
    # a shape no tip force makes: an S-curve
    s = np.linspace(0, 1, 200)
    S = np.stack([s * 0.06, 0.006 * np.sin(2 * np.pi * s), np.zeros(200)], 1)
    fam.reset()
    e = fam.estimate(fit_bezier(S))
    _check(e, fam.f_max)
    assert e.status in ('no_fit', 'not_converged') and not e.normal


def test_hybrid_falls_back_to_fam_outside_the_domain(toy_models, fam):
    X, _, models, _ = toy_models
    h = HybridEstimator(models['svr'], fam)
    inside = h.estimate(X[2].reshape(4, 3))
    assert inside.method == 'svr'
    from fam_solver import Catheter, Loads, solve_fam
    from catheter_shape import fit_bezier
    c = solve_fam(Catheter(length=L, ei=6e-5), Loads(tip_force=(0.0, -0.2)),
                  n_arcs=24).centerline(200)
    far = fit_bezier(np.c_[c, np.zeros(len(c))])          # a Blazer shape: not toy data
    e = h.estimate(far)
    assert e.method == 'fam_fallback' and e.primary == 'svr' and 'out_of' in e.message
    assert e.normal and np.hypot(*(e.force - (0.0, -0.2))) < 0.01
    assert HybridEstimator(models['svr']).estimate(far).status in ('out_of_domain',
                                                                   'out_of_envelope')
    with pytest.raises(ValueError, match='model'):
        HybridEstimator('blazer-svr')
    with pytest.raises(ValueError, match='method'):
        make_estimator('knn')


@settings(max_examples=150, deadline=None)
@given(st.lists(st.one_of(st.floats(-0.1, 0.1), st.floats(allow_nan=True, allow_infinity=True),
                          st.sampled_from([1e308, -1e308, 5e-324, 0.0, 1e6])),
                min_size=12, max_size=12),
       st.sampled_from(['svr', 'mlp', 'big']))
def test_fuzz_estimates_keep_their_invariants(toy_models, x, kind):
    """Any 12 numbers: estimate() never raises, never returns a non-finite or unbounded
    force, a bad covariance or an unknown status; predict() of finite input is bounded."""
    m = toy_models[2][kind]
    cp = np.array(x, dtype=float).reshape(4, 3)
    with np.errstate(all='ignore'):
        e = m.estimate(cp)
    _check(e, m.f_bound)
    if np.isfinite(cp).all():
        f = m.predict(cp)
        assert np.all(np.isfinite(f)) and np.hypot(*f) <= m.f_bound * (1 + 1e-12)
    else:
        assert e.status == 'non_finite_input'


def test_force_model_arrays_validation(models):
    a = dict(models['mlp'].arrays)
    a['env_hi'] = a['env_hi'] + 5.0
    with pytest.raises(ValueError, match='env_lo'):
        ForceModel('mlp', a, models['mlp'].header)


def test_neighbours_forces_decide_observability_when_the_estimate_does_not(toy_models):
    """The covariance takes the least determined of the table at the model's estimate and
    at its nearest training inputs' forces: a model whose (wrong) estimate lands where the
    table is confident is still flagged when the inputs around it came from axial pulls."""
    from tests.force_estimator.conftest import toy_table
    from force_estimator.training import calibrate
    X, Y, models, _ = toy_models
    m = ForceModel('mlp', dict(models['mlp'].arrays), dict(models['mlp'].header), name='toy')
    tab = toy_table(0.002)
    tab.cov[4] = np.eye(2) * 0.1 ** 2              # angles around 0 (pulls): unobservable
    pulls = np.tile([0.2, 0.0], (130, 1))         # pretend every training input was a pull
    calibrate(m, X[:130], X[130:], Y[130:], table=tab, Y_train=pulls)
    e = m.estimate(X[7].reshape(4, 3))
    assert abs(np.arctan2(e.force[1], e.force[0])) > 0.5          # the estimate: not a pull
    assert np.linalg.eigvalsh(tab.lookup(e.force))[-1] < 0.03 ** 2
    assert e.status == 'axial_unobservable' and e.max_std > 0.09


def test_the_fallback_stays_in_the_learned_envelope():
    """A force beyond the trained range (0.45 N): the learned model clips or refuses it, the
    FAM fallback shares the learned envelope: nothing beyond it is published as normal."""
    pytest.importorskip('fam_solver')
    from fam_solver import Catheter, Loads, solve_fam
    from catheter_shape import fit_bezier
    h = make_estimator('svr')
    assert h.fam.f_max <= h.model.f_bound
    c = solve_fam(Catheter(length=L, ei=6e-5), Loads(tip_force=(-0.1, 0.44)), n_arcs=24
                  ).centerline(200)
    e = h.estimate(fit_bezier(np.c_[c, np.zeros(len(c))]))
    _check(e, h.model.f_bound)
    assert not e.normal or np.hypot(*e.force) <= h.model.f_bound


def test_status_takes_the_first_failed_check_in_order_else_the_covariance_decides():
    tight, loose = np.eye(2) * 1e-6, np.eye(2) * (2.0 * UNOBSERVABLE_STD) ** 2
    assert status_of(tight) == ('ok', '')
    assert status_of(loose) == ('axial_unobservable', '')
    assert status_of(tight, (False, 'no_fit', 'a'), (False, 'out_of_envelope', 'b')) == \
        ('ok', '')
    assert status_of(loose, (False, 'no_fit', 'a'), (True, 'out_of_envelope', 'b')) == \
        ('out_of_envelope', 'b')
    assert status_of(tight, (True, 'not_converged', 'a'), (True, 'no_fit', 'b')) == \
        ('not_converged', 'a')


def test_status_formats_only_the_message_it_reports():
    calls = []

    def msg(text):
        return lambda: calls.append(text) or text
    tight = np.eye(2) * 1e-6
    assert status_of(tight, (False, 'no_fit', msg('a')), (True, 'out_of_envelope', msg('b'))) \
        == ('out_of_envelope', 'b')
    assert status_of(tight, (False, 'no_fit', msg('c'))) == ('ok', '')
    assert calls == ['b']


def test_hybrid_predict_is_its_estimates_in_order(toy_models, fam):
    """predict: one (4, 3) shape -> (2,), a batch (B, 4, 3) -> (B, 2) in order, each
    row the force estimate() gives for that shape (the fallback's too), the flags its
    `normal`; bad shapes and non-finite values are refused by name."""
    X, _, models, _ = toy_models
    from fam_solver import Catheter, Loads, solve_fam
    from catheter_shape import fit_bezier
    h = HybridEstimator(models['svr'], fam)
    c = solve_fam(Catheter(length=L, ei=6e-5), Loads(tip_force=(0.0, -0.2)),
                  n_arcs=24).centerline(200)
    far = fit_bezier(np.c_[c, np.zeros(len(c))])          # out of the toy domain: fallback
    batch = np.stack([X[2].reshape(4, 3), far, X[5].reshape(4, 3)])
    fam.reset()
    want = []
    for cp in batch:
        fam.reset()
        want.append(h.estimate(cp))
    assert [e.method for e in want] == ['svr', 'fam_fallback', 'svr']
    fam.reset()
    one = h.predict(batch[0])
    assert one.shape == (2,)
    np.testing.assert_allclose(one, want[0].force)
    f, normal = h.predict(batch[0], return_flags=True)
    np.testing.assert_allclose(f, want[0].force)
    assert normal == want[0].normal
    fam.reset()
    F, flags = h.predict(batch, return_flags=True)
    assert F.shape == (3, 2) and flags.dtype == bool and flags.shape == (3,)
    np.testing.assert_allclose(F, [e.force for e in want], atol=1e-6)
    assert flags.tolist() == [e.normal for e in want]
    fam.reset()
    np.testing.assert_allclose(h.predict(batch), F, atol=1e-6)
    # without the fallback the far shape is refused: its flag is False, the others' True
    h0 = HybridEstimator(models['svr'])
    F0, flags0 = h0.predict(batch, return_flags=True)
    assert flags0.tolist() == [h0.estimate(cp).normal for cp in batch] == [True, False, True]
    np.testing.assert_allclose(F0[1], h0.estimate(far).force)
    assert not h0.predict(far, return_flags=True)[1]
    for shape in ((3, 12), (3, 5)):
        with pytest.raises(ValueError, match='control_points must have shape'):
            h.predict(np.zeros(shape))
    bad = batch.copy()
    bad[1, 2, 0] = np.nan
    with pytest.raises(ValueError, match='finite'):
        h.predict(bad)


def test_hybrid_refuses_a_fallback_that_is_not_a_fam_inversion(toy_models):
    _, _, models, _ = toy_models
    with pytest.raises(ValueError, match='fam must be a FamInverseEstimator'):
        HybridEstimator(models['svr'], fam=models['mlp'])


SVR_DAMAGE = {
    'x_scale missing': (lambda a, h: a.pop('x_scale'), "model array 'x_scale' must have shape"),
    'y_mean shape': (lambda a, h: a.update(y_mean=np.zeros(3)), "model array 'y_mean'"),
    'zero scale': (lambda a, h: a.update(x_scale=np.zeros(12)), 'model scales must be positive'),
    'gamma missing': (lambda a, h: a.pop('gamma'), "svr model lacks array 'gamma'"),
    'sv shape': (lambda a, h: a.update(sv=a['sv'][:, :11]), r'svr array "sv" must have shape'),
    'coef rows': (lambda a, h: a.update(coef=a['coef'][1:]), 'do not match "sv"'),
    'gamma sign': (lambda a, h: a.update(gamma=-a['gamma']), 'svr array "gamma" must be positive'),
    'selftest shape': (lambda a, h: h['selftest'].update(features=[[0.0] * 11]),
                       'selftest must hold features'),
}
MLP_DAMAGE = {
    'no layers': (lambda a, h: [a.pop(k) for k in list(a) if k[0] in 'Wb' and k[1:].isdigit()],
                  'mlp model has no layers'),
    'chain': (lambda a, h: a.update(W1=a['W1'][1:]), 'mlp layer shapes do not chain'),
}


@pytest.mark.parametrize('kind, damage', [('svr', d) for d in SVR_DAMAGE] +
                         [('mlp', d) for d in MLP_DAMAGE])
def test_a_damaged_model_is_refused_naming_the_part(models, kind, damage):
    import copy
    edit, match = (SVR_DAMAGE if kind == 'svr' else MLP_DAMAGE)[damage]
    m = models[kind]
    a, h = dict(m.arrays), copy.deepcopy(m.header)
    edit(a, h)
    with pytest.raises(ValueError, match=match):
        ForceModel(kind, a, h)


def test_an_mlp_whose_output_is_not_two_forces_is_refused(models):
    import copy
    m = models['mlp']
    a, h = dict(m.arrays), copy.deepcopy(m.header)
    last = max(int(k[1:]) for k in a if k[0] == 'W' and k[1:].isdigit())
    a[f'W{last}'] = np.zeros((a[f'W{last}'].shape[0], 3))
    a[f'b{last}'] = np.zeros(3)
    with pytest.raises(ValueError, match='mlp output layer must have 2 units'):
        ForceModel('mlp', a, h)


def test_model_files_are_refused_by_path_format_and_version(models, tmp_path):
    from force_estimator.models import FORMAT_VERSION, load_model
    with pytest.raises(ValueError, match='must name a .npz model file'):
        load_model(tmp_path / 'm.txt')
    with pytest.raises(ValueError, match='does not exist'):
        load_model(tmp_path / 'none.npz')
    np.savez(tmp_path / 'bare.npz', x=np.zeros(2))
    with pytest.raises(ValueError, match=r'not a force_estimator model \(no header\)'):
        load_model(tmp_path / 'bare.npz')

    def newer(a, h):
        h['version'] = FORMAT_VERSION + 1

    def other_format(a, h):
        h['format'] = 'sklearn-pickle'

    with pytest.raises(ValueError, match=f'version {FORMAT_VERSION + 1} is newer'):
        load_model(_tampered(models['svr'], tmp_path, newer, 'newer'))
    with pytest.raises(ValueError, match='is not a force_estimator model file'):
        load_model(_tampered(models['svr'], tmp_path, other_format, 'other'))
    with pytest.raises(ValueError, match='name_or_path must be one of'):
        load_estimator('blazer-knn')


def test_predict_features_refuses_bad_shapes_and_values(models):
    m = models['svr']
    for bad in (np.zeros(11), np.zeros((2, 3, 12))):
        with pytest.raises(ValueError, match=r'features must have shape \(12,\) or \(B, 12\)'):
            m.predict_features(bad)
    x = np.zeros(12)
    x[3] = np.inf
    with pytest.raises(ValueError, match='non-finite'):
        m.predict_features(x)
    assert repr(m).startswith("ForceModel(") and 'support vectors' in repr(m)
    assert 'layers ' in repr(models['big']) and '16x16x2' in repr(models['big'])

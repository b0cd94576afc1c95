"""The model envelope (checked against a brute-force reference) and the state-file protocol:
atomic writes, a rejected file is never overwritten, a loaded state is validated."""
import json
import math
import os

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from impedance_master.envelope import DEFAULT_ENVELOPE, ModelEnvelope
from impedance_master.identification import make_identifier
from impedance_master.impedance import Impedance
from impedance_master.operator import OperatorTrajectory
from impedance_master.state_file import StateFile, beside, read_state, write_state

vals = st.floats(-3.0, 3.0)


@settings(max_examples=60, deadline=None)
@given(st.lists(vals, min_size=4, max_size=4), st.integers(2, 12),
       st.lists(vals, min_size=48, max_size=48), st.floats(0.0, 2.0),
       st.floats(-0.05, 0.1), st.floats(0.002, 0.03))
def test_force_bound_is_the_brute_force_maximum(lin, n, tabs, beta, x0, dx):
    """force_bound against a dense search over the workspace (x on a fine grid that holds
    every node, x' and x'' at their limits, the friction states at their extremes)."""
    m, c, k, o = lin[0] * 0.01, lin[1], lin[2] * 10, lin[3]
    S, F, B, C = (tabs[i * 12:i * 12 + n] for i in range(4))
    imp = Impedance(m, c, k, o, x0=x0, dx=dx, beta=beta, S=S, F=F, B=B, C=C)
    env = DEFAULT_ENVELOPE
    xs = np.union1d(np.linspace(env.x_lo, env.x_hi, 2001),
                    [x for x in x0 + dx * np.arange(n) if env.x_lo <= x <= env.x_hi])
    best = 0.0
    for x in xs:
        for v in (-env.max_speed, env.max_speed):
            for a in (-env.max_accel, env.max_accel):
                for z1, dz in ((1, 2 + beta), (1, -(2 + beta)), (-1, 2 + beta),
                               (-1, -(2 + beta))):
                    best = max(best, abs(imp.force(x, v, a, (z1, z1 + dz))))
    assert env.force_bound(imp) == pytest.approx(best, rel=1e-9, abs=1e-12)


@pytest.mark.parametrize('x0,n', [(0.0, 17), (-0.05, 17), (0.15, 12)])
def test_force_bound_overflowing_is_inf_on_both_paths(x0, n):
    """Twentieth round: a grid wholly inside the workspace takes a Python-float path
    (x0 0: the default identifier's grid), one reaching outside the numpy path; a table
    whose bound overflows is inf on both, and refused."""
    big = [1.5e308] * n
    imp = Impedance(0.0, 1.0, 0.0, 0.0, x0=x0, dx=0.005, S=[0.0] * n, F=big, B=big, C=big)
    assert DEFAULT_ENVELOPE.force_bound(imp) == math.inf
    assert DEFAULT_ENVELOPE.check(imp) is not None


def test_envelope_accepts_the_identifiers_models_and_refuses_absurd_ones():
    ident = make_identifier()
    t, x, xd, xdd = OperatorTrajectory(duration=4.0, seed=3).arrays()
    for s in zip(x, xd, xdd, 0.1 * np.sign(xd) + 3.0 * x, strict=True):
        imp = ident.update(*s)
    assert DEFAULT_ENVELOPE.check(imp) is None
    for bad, what in ((Impedance(1e308, -1e308, 0, 0), 'm'), (Impedance(0, 0, 1e300, 0), 'k'),
                      (Impedance(0, 0, 0, 11.0), 'offset'), (Impedance(0, 300.0, 0, 0), 'c'),
                      (Impedance(0, 0, 60.0, 0), 'predicted force'),
                      (imp.copy(S=[20.0] * 17), 'S'), (imp.copy(sigma=1.0), 'sigma'),
                      (imp.copy(anchor=(0.03, 0, 0, 0, 0, 1e4, 0)), 'anchor')):
        assert what in DEFAULT_ENVELOPE.check(bad), what
    assert not DEFAULT_ENVELOPE.accepts('model')
    with pytest.raises(ValueError, match='x_lo'):
        ModelEnvelope(x_lo=1.0, x_hi=0.0)
    with pytest.raises(ValueError, match='max_force'):
        ModelEnvelope(max_force=0.0)


def learned(seconds=4.0):
    ident = make_identifier()
    t, x, xd, xdd = OperatorTrajectory(duration=seconds, seed=5).arrays()
    rng = np.random.default_rng(1)
    for s in zip(x, xd, xdd, 0.1 * np.tanh(xd / 0.002) + 3.0 * x + 0.005 * rng.normal(size=x.size),
                 strict=True):
        ident.update(*s)
    return ident


def test_write_is_atomic_and_strict(tmp_path):
    p = tmp_path / 'a.json'
    write_state(str(p), {'x': 1.0})
    assert read_state(str(p)) == {'x': 1.0}
    with pytest.raises(ValueError, match='finite'):
        write_state(str(p), {'x': math.nan})
    assert read_state(str(p)) == {'x': 1.0}                 # the old file is intact
    assert sorted(os.listdir(tmp_path)) == ['a.json']       # no temporary file left
    (tmp_path / 'l.json').write_text('[1, 2]')
    with pytest.raises(ValueError, match='list'):
        read_state(str(tmp_path / 'l.json'))


@pytest.mark.parametrize('damage', ['truncated', 'version', 'grid', 'nan', 'list', 'tampered',
                                    'asymmetric'])
def test_a_rejected_state_file_is_kept_and_the_new_state_goes_beside(tmp_path, damage):
    good = learned()
    path = tmp_path / 'ident.json'
    good.save_state(str(path))
    state = json.loads(path.read_text())
    if damage == 'truncated':
        text = path.read_text()[:len(path.read_text()) // 2]
    else:
        if damage == 'version':
            state['version'] = 1
        elif damage == 'grid':
            state['grid']['n_nodes'] = 9
        elif damage == 'nan':
            state['b'][3] = float('nan')
        elif damage == 'tampered':
            state['b'] = [v * 1e6 for v in state['b']]
        elif damage == 'asymmetric':
            state['A'][0][1] = -1e9
        text = json.dumps([1, 2]) if damage == 'list' else json.dumps(state)
    path.write_text(text)
    ident = make_identifier()
    sf = StateFile(str(path))
    assert sf.load(ident) is None and not sf.loaded and sf.rejected
    assert sf.save_path == str(tmp_path / 'ident.1.json') and 'kept' in sf.message
    for s in zip(*OperatorTrajectory(duration=1.5, seed=2).arrays()[1:], [0.1] * 1500, strict=True):
        ident.update(*s)
    written = sf.save(ident)
    assert written == str(tmp_path / 'ident.1.json')
    assert path.read_text() == text                          # never overwritten
    make_identifier().load_state(written)                    # the new state loads
    sf2 = StateFile(str(path))                               # next start: still rejected,
    sf2.load(make_identifier())                              # the next free name beside
    assert sf2.save_path == str(tmp_path / 'ident.2.json')


def test_a_good_state_is_continued_and_saved_in_place(tmp_path):
    good = learned()
    path = tmp_path / 'ident.json'
    sf = StateFile(str(path))
    assert sf.load(make_identifier()) is None and 'no state file' in sf.message
    assert sf.save(good) == str(path)
    ident = make_identifier()
    sf = StateFile(str(path))
    model = sf.load(ident)
    assert sf.loaded and model.valid and ident.n_moving == good.n_moving
    for xx, v in ((0.02, 0.01), (0.04, -0.02)):
        assert model.force(xx, v, 0.0) == pytest.approx(good.last.force(xx, v, 0.0), abs=1e-9)
    assert sf.save(ident) == str(path) and beside(str(path)).endswith('ident.1.json')
    with pytest.raises(ValueError, match='path'):
        StateFile('')


def test_envelope_accepts_the_stateless_friction_law():
    """sigma = 0 is the stateless friction law (`Impedance`: the friction follows the
    velocity and vanishes at rest; `HistoryParams.sigmas` names it a candidate): inside
    the envelope, so the identifier that selects it on data of such a law renders it
    (ninth round of issue 12: refused before, the identifier held its last model)."""
    imp = learned().last
    assert DEFAULT_ENVELOPE.check(imp.copy(sigma=0.0)) is None
    assert 'sigma' in DEFAULT_ENVELOPE.check(imp.copy(sigma=0.06))
    ident = make_identifier(sigmas=(3e-4, 0.0))
    t, x, xd, xdd = OperatorTrajectory(duration=6.0, seed=5).arrays()
    rng = np.random.default_rng(1)
    f = 0.1 * np.tanh(xd / 0.002) + 3.0 * x + 0.005 * rng.normal(size=x.size)
    for s in zip(x, xd, xdd, f, strict=True):
        ident.update(*s)
    m = ident.last
    assert (m.sigma, m.valid, ident.status) == (0.0, True, 'ok')
    assert ident.n_out_of_envelope == 0
    # the friction vanishes at rest: the static force alone (3 N/m x 30 mm)
    assert m.force(0.03, 0.0, 0.0) == pytest.approx(0.09, abs=0.01)
    assert m.force(0.03, 0.01, 0.0) == pytest.approx(0.19, abs=0.015)


def test_a_failed_write_leaves_the_old_file_and_no_temporary_file(tmp_path, monkeypatch):
    import impedance_master.state_file as sfm
    p = tmp_path / 'a.json'
    write_state(str(p), {'x': 1.0})

    def full_disk(src, dst):
        raise OSError(28, 'No space left on device')

    monkeypatch.setattr(sfm.os, 'replace', full_disk)
    with pytest.raises(OSError, match='No space'):
        write_state(str(p), {'x': 2.0})
    assert read_state(str(p)) == {'x': 1.0}
    assert sorted(os.listdir(tmp_path)) == ['a.json']


def test_a_state_the_next_start_would_reject_is_written_beside(tmp_path):
    """save() checks the state loads again; one that would not (here: tampered forces) goes
    to the next free name beside, the previous (good) file is kept and the message says so."""
    good = learned()
    path = tmp_path / 'ident.json'
    sf = StateFile(str(path))
    assert sf.save(good) == str(path)
    before = path.read_text()
    bad = learned()
    state = bad.get_state()
    state['b'] = [v * 1e6 for v in state['b']]
    bad.get_state = lambda: state
    written = sf.save(bad)
    assert written == str(tmp_path / 'ident.1.json') and path.read_text() == before
    assert 'would be rejected at the next start' in sf.message and written in sf.message
    with pytest.raises(ValueError):
        make_identifier().load_state(written)
    # with no previous file the rejected state is written in place (nothing to keep)
    other = tmp_path / 'fresh.json'
    assert StateFile(str(other)).save(bad) == str(other)


def test_beside_names_the_first_free_number(tmp_path):
    p = tmp_path / 'ident.json'
    assert beside(str(p)) == str(tmp_path / 'ident.1.json')
    (tmp_path / 'ident.1.json').write_text('{}')
    (tmp_path / 'ident.3.json').write_text('{}')
    assert beside(str(p)) == str(tmp_path / 'ident.2.json')
    assert beside(str(tmp_path / 'noext')) == str(tmp_path / 'noext.1.json')

"""The environment model's constructors and wire format refuse bad values by name (the model
reaches the operator's hand: a bad one must be a clear ValueError at the boundary, never a
silent NaN or an IndexError deep inside), and a good table model round-trips exactly."""
import math

import numpy as np
import pytest

from impedance_master.impedance import (ANCHOR_FIELDS, MAX_NODES, Anchor, Impedance,
                                        check_state)

TAB = dict(S=[0.0, 0.1, 0.2], F=[0.01, 0.02, 0.03], B=[0.0, 0.0, 0.01], C=[1.0, 1.5, 2.0])
ANCHOR = (0.03, 0.01, 0.0, 1e-4, 1e-4, 0.12, 0.002)


def table(**kw):
    args = dict(x0=0.02, dx=0.01, sigma=3e-4, v_s=0.002, beta=0.5, anchor=ANCHOR, **TAB)
    args.update(kw)
    return Impedance(0.1, 0.2, 3.0, 0.05, True, **args)


def test_a_table_model_round_trips_through_its_fields():
    m = table()
    back = Impedance.from_fields(m.to_fields())
    assert back.to_fields() == m.to_fields() and back.anchor == Anchor(*ANCHOR)
    for x, v in ((0.025, 0.01), (0.041, -0.02), (0.0, 0.0)):
        assert back.force(x, v, 0.0) == m.force(x, v, 0.0)
    lin = Impedance(0.1, 0.2, 3.0, 0.05, False)
    assert Impedance.from_fields(lin.to_fields()).to_fields() == lin.to_fields()
    fast = Impedance.from_arrays(0.1, 0.2, 3.0, 0.05, x0=0.02, dx=0.01, sigma=3e-4,
                                 v_s=0.002, beta=0.5, **{k: np.array(v) for k, v in TAB.items()})
    assert fast.tables() == table().tables() and fast.valid


@pytest.mark.parametrize('kw, match', [
    (dict(S=None), 'S, F, B, C must be given together'),
    (dict(S=[0.0]), 'S must have 2..'),
    (dict(S=[0.0] * (MAX_NODES + 1), F=[0.0] * (MAX_NODES + 1), B=[0.0] * (MAX_NODES + 1),
          C=[0.0] * (MAX_NODES + 1)), 'S must have 2..'),
    (dict(C=[1.0, 2.0]), 'C must have 3 nodes like S'),
    (dict(F=[0.0, math.nan, 0.0]), r'F\[1\]'),
    (dict(anchor=(0.0, 0.0)), "anchor must have 7 values"),
    (dict(anchor=(0.0, 0.0, 0.0, 0.0, 0.0, math.inf, 0.0)), "anchor.f"),
    (dict(dx=0.0), 'dx'),
    (dict(v_s=-1.0), 'v_s'),
    (dict(sigma=-1e-4), 'sigma'),
])
def test_the_constructor_names_what_is_wrong(kw, match):
    with pytest.raises(ValueError, match=match):
        table(**kw)


@pytest.mark.parametrize('tabs, match', [
    (dict(S=[0.0]), '1-D of one length'),
    (dict(C=[1.0, 2.0]), '1-D of one length'),
    (dict(B=[[0.0, 0.0, 0.0]]), '1-D of one length'),
    (dict(F=[0.0, math.nan, 0.0]), 'must be finite'),
])
def test_from_arrays_names_what_is_wrong(tabs, match):
    t = dict(TAB)
    t.update(tabs)
    with pytest.raises(ValueError, match=match):
        Impedance.from_arrays(0.1, 0.2, 3.0, 0.05, x0=0.0, dx=0.01, sigma=3e-4, v_s=0.002,
                              beta=0.5, **t)


def _drop(name):
    f = table().to_fields()
    del f[name]
    return f


def _set(**kv):
    f = table().to_fields()
    f.update(kv)
    return f


@pytest.mark.parametrize('fields, match', [
    ([1.0], 'fields must be a dict'),
    (_drop('offset'), "missing 'offset'"),
    (_drop('sigma'), r"missing 'sigma' \(table model\)"),
    (_drop('B2'), r"missing 'B2' \(table model\)"),
    (_set(n=1.0), 'n must be in 2..'),
    (_set(n=float(MAX_NODES + 1)), 'n must be in 2..'),
    (_set(n=math.nan), 'n must be finite, got nan'),
    (_set(kind=2.0), 'kind must be 0 \\(linear\\) or 1 \\(table\\)'),
    (_set(kind=math.inf), 'kind must be finite'),
    (_drop(ANCHOR_FIELDS[3]), rf"missing '{ANCHOR_FIELDS[3]}' \(anchored model\)"),
    (_set(valid=math.nan), 'valid must be finite'),
    (_set(S1=math.nan), r'S\[1\]'),
])
def test_from_fields_names_what_is_wrong(fields, match):
    with pytest.raises(ValueError, match=match):
        Impedance.from_fields(fields)


def test_check_state_and_repr():
    assert check_state(1, 2.0, np.float64(3.0)) == (1.0, 2.0, 3.0)
    for i, name in enumerate(('x', 'xd', 'xdd')):
        bad = [0.0, 0.0, 0.0]
        bad[i] = math.nan
        with pytest.raises(ValueError, match=name):
            check_state(*bad)
    r = repr(table(status='fit'))
    assert r.startswith('Impedance(m=0.1, c=0.2, k=3') and 'table n=3 x0=0.02 dx=0.01' in r
    assert r.endswith("status='fit')")
    assert repr(Impedance()) == 'Impedance(m=0, c=0, k=0, offset=0, valid=True)'

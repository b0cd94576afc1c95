"""Fifteenth round of issue 12: the stateless friction law (sigma 0) is a candidate of the
default identifier, rendered only once the slave has retracted (`select_outward`)."""
import math

import numpy as np
import pytest

from impedance_master.history import HistoryIdentifier
from impedance_master.history_params import HistoryParams
from impedance_master.identification import make_identifier


def _stream(seconds_in: float, seconds_out: float, seed: int = 3):
    """(x, x', x'', f) at 1 kHz of a stateless friction law, f = 0.1 tanh(x' / 2 mm/s) +
    3 N/m x + 5 mN noise: inserting from 10 mm at 5 +- 4.5 mm/s (slowing to 0.5 mm/s once
    a second, never turning), then retracting at 10 mm/s."""
    dt = 1e-3
    t = np.arange(int(seconds_in / dt)) * dt
    v = np.concatenate([0.005 + 0.0045 * np.sin(2 * math.pi * t),
                        np.full(int(seconds_out / dt), -0.01)])
    x = 0.01 + np.concatenate([[0.0], np.cumsum(v[:-1]) * dt])
    a = np.concatenate([[0.0], np.diff(v) / dt])
    f = 0.1 * np.tanh(v / 0.002) + 3.0 * x + 0.005 * np.random.default_rng(seed).normal(size=v.size)
    return list(zip(x, v, a, f, strict=True))


def _selected_over(ident, samples):
    out = []
    for s in samples:
        ident.update(*s)
        out.append(ident.sigmas[ident.selected])
    return out


def test_the_default_offers_the_stateless_law_after_1000_retracting_samples():
    p = HistoryParams()
    assert p.sigmas == (3e-4, 1e-3, 3e-3, 0.0) and p.select_outward == 1000


def test_inserting_only_the_stateless_law_is_not_rendered_however_well_it_fits():
    """Without the rule the stateless law wins on inserting data alone (its friction
    drops as the insertion slows); with it, it is not even solved until 1000 retracting
    samples are learned, then the retraction selects it."""
    data = _stream(4.0, 1.3)
    n_in = 4000
    free = _selected_over(make_identifier(select_outward=0), data[:n_in])
    assert free[-1] == 0.0
    ident = make_identifier()
    held = _selected_over(ident, data)
    assert 0.0 not in held[:n_in]
    assert ident.n_outward == 1000
    assert held[-1] == 0.0
    first = held.index(0.0)
    # selected at the first selection after the 1000th retracting sample, not before
    assert n_in + 1000 <= first <= n_in + 1000 + ident.select_every * ident.solve_every


def test_the_count_travels_with_the_state_and_an_older_state_counts_as_complete():
    data = _stream(2.0, 0.05)
    ident = make_identifier()
    for s in data:
        ident.update(*s)
    assert 0 < ident.n_outward < 1000
    st = ident.get_state()
    assert st['n_outward'] == ident.n_outward
    other = make_identifier()
    other.set_state(st)
    assert other.n_outward == ident.n_outward
    del st['n_outward']         # written before the fifteenth round
    other.set_state(st)
    assert other.n_outward == 1000


@pytest.mark.parametrize('bad', [-1, 1.5, True, '7', None])
def test_a_bad_count_in_a_state_is_named(bad):
    ident = make_identifier()
    for s in _stream(1.5, 0.0):
        ident.update(*s)
    st = ident.get_state()
    st['n_outward'] = bad
    with pytest.raises(ValueError, match='n_outward'):
        ident.set_state(st)


@pytest.mark.parametrize('bad', [-1, 1.5, True, '100'])
def test_a_bad_select_outward_is_named(bad):
    with pytest.raises(ValueError, match='select_outward'):
        HistoryIdentifier(select_outward=bad)


def test_a_stateless_model_crosses_the_wire_and_is_rendered():
    """The identifier's stateless model (sigma 0) through /slave/impedance's message and
    back: the same law, accepted by the master's renderer (its friction follows the
    master's velocity)."""
    from catheter_common.messages import impedance_fields, impedance_msg
    from impedance_master.impedance import Impedance
    from impedance_master.rendering import ImaRenderer
    ident = make_identifier()
    for s in _stream(4.0, 1.3):
        ident.update(*s)
    m = ident.last
    assert m.sigma == 0.0 and m.anchor is not None
    back = Impedance.from_fields(impedance_fields(impedance_msg(m)))
    assert back.sigma == 0.0 and back.anchor == m.anchor
    for v in (-0.01, 0.0, 0.004):
        assert back.force(0.02, v, 0.0) == m.force(0.02, v, 0.0)
    r = ImaRenderer(blend_time=0.0)
    assert r.set_impedance(back)
    r.desired_force(0.02, 0.01, 0.0)
    assert r.model is back

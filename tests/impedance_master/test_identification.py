"""`impedance_master.identification.make_identifier`: the project's default identifier is the
history model with the defaults impedance_identifier_node declares (window 1 s, 1 kHz), and
every HistoryParams field given by name reaches it."""
import pytest

from impedance_master.history import HistoryIdentifier
from impedance_master.history_params import HistoryParams
from impedance_master.identification import make_identifier
from impedance_master.impedance_identifier_node import PARAMS


def test_the_defaults_are_the_identifier_nodes():
    ident = make_identifier()
    declared = {p.name: p.default for p in PARAMS}
    assert isinstance(ident, HistoryIdentifier)
    assert ident.window == declared['window'] == 1.0            # s
    assert ident.rate == declared['rate'] == 1000.0             # Hz, the 1 kHz loop
    assert ident.params == HistoryParams()


def test_history_params_reach_the_identifier_by_name():
    ident = make_identifier(window=0.5, rate=500.0, select_outward=0, sigma=1e-3)
    assert (ident.window, ident.rate) == (0.5, 500.0)
    assert ident.params.select_outward == 0 and ident.params.sigma == 1e-3
    assert ident.params == HistoryParams(select_outward=0, sigma=1e-3)
    given = HistoryParams(n_nodes=9)
    assert make_identifier(params=given).params == given
    with pytest.raises(ValueError, match='unknown HistoryIdentifier parameter'):
        make_identifier(no_such_setting=1)


@pytest.mark.parametrize('kw, match', [
    (dict(x_min=0.05, x_max=0.05), 'x_max must be > x_min'),
    (dict(x_max=float('nan')), 'x_max'),
    (dict(n_nodes=2), 'n_nodes'),
    (dict(n_nodes=129), 'n_nodes'),
    (dict(n_nodes=9.5), 'n_nodes'),
    (dict(solve_every=0), 'solve_every'),
    (dict(burst_samples=-1), 'burst_samples'),
    (dict(sigmas=()), 'sigmas must be a tuple of 1..8 lengths'),
    (dict(sigmas=(3e-4,) * 9), 'sigmas must be a tuple of 1..8 lengths'),
    (dict(sigmas='3e-4'), 'sigmas must be a tuple'),
    (dict(sigmas=(3e-4, -1e-3)), r'sigmas\[1\]'),
    (dict(sigma=2e-3), 'sigma 0.002 must be one of sigmas'),
    (dict(v_s=0.0), 'v_s'),
    (dict(select_margin=-1.0), 'select_margin'),
    (dict(static_first_difference=1), 'static_first_difference must be a bool'),
    (dict(static_min=5.0), r'static_min must be in \[-max_force, max_force\)'),
    (dict(static_min=-5.1), 'static_min must be in'),
    (dict(static_min=float('inf')), 'static_min'),
])
def test_history_params_refuse_bad_values_by_name(kw, match):
    with pytest.raises(ValueError, match=match):
        HistoryParams(**kw)


def test_history_params_take_a_list_of_sigmas_and_give_the_grid_spacing():
    p = HistoryParams(sigmas=[1e-3, 0.0], sigma=0.0, x_min=0.01, x_max=0.09, n_nodes=9)
    assert p.sigmas == (1e-3, 0.0) and p.dx == pytest.approx(0.01)
    assert HistoryParams(static_min=-5.0).static_min == -5.0          # the closed end
    assert set(p.as_dict()) == set(HistoryParams.names()) and p.as_dict()['n_nodes'] == 9

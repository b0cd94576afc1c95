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

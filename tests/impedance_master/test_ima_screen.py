"""Issue 12's screening tool (tests/bench/ima_screen.py): a replay of the recorded slave side
gives exactly the `CaseResult` of `generalisation.run_case`, for the default renderer, the
anchored baseline and DFR, and a renderer argument reaches the replayed renderer."""
import math
import pathlib
import sys

import pytest

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / 'bench'))
try:
    import ima_screen
finally:
    sys.path.pop(0)

from impedance_master.generalisation import run_case  # noqa: E402

# a stiff_wall world of the seen set f1, whose result depends on the renderer's elastic gain
WORLD = [w for w in ima_screen.worlds('f1') if ima_screen.key(w) == 'stiff_wall_minjerk_100'][0]


@pytest.fixture(scope='module')
def recording():
    return ima_screen.record(WORLD)


def test_replay_is_run_case_exactly(recording):
    v, op, s, params = WORLD
    ref = run_case(v, op, s, modes=ima_screen.REPLAY_MODES, vessel_params=params)
    for mode in ima_screen.REPLAY_MODES:
        assert ima_screen.replay(WORLD, recording, mode) == ref[mode], mode


def test_render_params_reach_the_renderer(recording):
    default = ima_screen.replay(WORLD, recording, 'ima')
    other = ima_screen.replay(WORLD, recording, 'ima', {'elastic_gain': 0.7})
    assert other != default
    v, op, s, params = WORLD
    ref = run_case(v, op, s, modes=('ima',), vessel_params=params,
                   render_params={'elastic_gain': 0.7})
    assert other == ref['ima']


def test_bad_mode_and_set_are_refused(recording):
    with pytest.raises(ValueError, match='mode'):
        ima_screen.replay(WORLD, recording, 'ima_thesis')
    with pytest.raises(ValueError, match='unknown set'):
        ima_screen.worlds('f1,f99')


def test_score_counts_against_dfr_and_anchored():
    from impedance_master.generalisation import CaseResult
    dfr = {'a_x_1': CaseResult(0.1, 0.2, 0.15, 0.5), 'b_x_1': CaseResult(0.1, 0.2, 0.15, 0.5)}
    anc = {'a_x_1': CaseResult(0.05, 0.1, 0.06, 0.3), 'b_x_1': CaseResult(0.05, 0.1, 0.06, 0.3)}
    res = {'a_x_1': CaseResult(0.05, 0.09, 0.06, 0.3),     # beats DFR, = anchored
           'b_x_1': CaseResult(0.05, 0.11, 0.07, 0.3)}     # outage not < half DFR's
    line = ima_screen.score(dfr, anc, res)
    assert 'beat 1 <=anchored 1' in line
    assert "misses {'b': 1}" in line


def test_sample_class_by_hand():
    # the slave has been inward to 30 mm and outward at 20 mm
    cls = ima_screen.sample_class
    assert cls(0.0315, 0.01, 0.030, 0.020) == 'deep'
    assert cls(0.0315, -0.01, 0.030, 0.020) == 'deep'          # deeper wins over direction
    assert cls(0.0305, 0.01, 0.030, 0.020) == 'visited'        # within the 1 mm margin
    assert cls(0.025, -0.01, 0.030, 0.020) == 'first_out'
    assert cls(0.025, 0.01, 0.030, 0.020) == 'visited'         # inward where seen inward
    assert cls(0.015, -0.01, 0.030, 0.020) == 'visited'
    assert cls(0.001, 0.0, -math.inf, -math.inf) == 'deep'     # no data yet


def test_oracle_nothing_is_the_plain_replay(recording):
    assert (ima_screen.replay(WORLD, recording, 'ima', oracle=())
            == ima_screen.replay(WORLD, recording, 'ima'))


def test_oracle_bounds_the_outage_error(recording):
    plain = ima_screen.replay(WORLD, recording, 'ima')
    every = ima_screen.replay(WORLD, recording, 'ima', oracle=ima_screen.ORACLE_CLASSES)
    # the reference rendered in every class of the outages: what is left there is the
    # haptic device's lag; the normal intervals are untouched up to that lag at the edges
    assert every.outage < 0.2 * plain.outage
    assert every.normal == pytest.approx(plain.normal, rel=0.05)
    parts = [ima_screen.replay(WORLD, recording, 'ima', oracle=(c,))
             for c in ima_screen.ORACLE_CLASSES]
    assert all(every.outage <= p.outage <= plain.outage + 1e-12 for p in parts)
    assert min(p.outage for p in parts) < plain.outage
    everywhere = ima_screen.replay(WORLD, recording, 'ima', oracle=ima_screen.ORACLE_CLASSES,
                                   oracle_everywhere=True)
    assert everywhere.normal < 0.2 * plain.normal


def test_oracle_refuses_bad_classes_and_modes(recording):
    with pytest.raises(ValueError, match='unknown oracle class'):
        ima_screen.replay(WORLD, recording, 'ima', oracle=('deeper',))
    with pytest.raises(ValueError, match='needs mode ima'):
        ima_screen.replay(WORLD, recording, 'dfr', oracle=('deep',))


def test_slave_reach_from_anchors():
    from impedance_master.impedance import Anchor
    reach = ima_screen.SlaveReach()
    assert reach.of(0.01, 0.01) == 'deep'
    for x, xd in ((0.010, 0.02), (0.030, 0.02), (0.025, 0.0), (0.020, -0.02), (0.012, -0.02)):
        reach.add(Anchor(x, xd, 0.0, 0.0, 0.0, 0.1, 0.0))
    reach.add(None)
    assert (reach.deepest_in, reach.deepest_out) == (0.030, 0.020)
    assert reach.of(0.032, 0.01) == 'deep'
    assert reach.of(0.025, -0.01) == 'first_out'
    assert reach.of(0.015, -0.01) == 'visited'

"""Issue 12's screening tool (tests/bench/ima_screen.py): a replay of the recorded slave side
gives exactly the `CaseResult` of `generalisation.run_case`, for the default renderer, the
anchored baseline and DFR, and a renderer argument reaches the replayed renderer."""
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

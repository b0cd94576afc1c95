"""The main command's refusals and the FAM plot's rules, without a run: a bad scenario or a
bad --set is exit status 2 with one line naming the problem (no run, no bag); the FAM
accuracy plot is drawn only when asked, missing or stale, and its absence is said."""
import pathlib
from types import SimpleNamespace

import pytest

from catheter_bringup import main as M


@pytest.mark.parametrize('args, named', [
    (['no_such_scenario'], 'no_such_scenario'),
    (['smoke', '--set', 'link.delay=-1'], 'link.delay'),
    (['smoke', '--set', 'no_such_key=1'], 'no_such_key'),
])
def test_a_bad_scenario_is_exit_status_2_naming_it(args, named, tmp_path, monkeypatch, capsys):
    monkeypatch.setenv('CATHETER_WS_ROOT', str(tmp_path))
    monkeypatch.setenv('ROS_DOMAIN_ID', '77')            # no isolation side effect needed
    assert M.main(args + ['--out', str(tmp_path / 'out'), '--no-fam']) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith('scripts/run: ') and named in err[0]
    assert not (tmp_path / 'bags').exists() and not (tmp_path / 'out').exists()


def _opts(no_fam=False, fam=False):
    return SimpleNamespace(no_fam=no_fam, fam=fam)


@pytest.fixture
def fam_plot(monkeypatch):
    import catheter_bringup.fam_plot as fp
    state = SimpleNamespace(current=True, drawn=[], importable=True)
    monkeypatch.setattr(fp, 'is_current', lambda out: state.current)

    def draw(out):
        state.drawn.append(out)
        return (pathlib.Path(out) / fp.FILE) if state.importable else None

    monkeypatch.setattr(fp, 'fam_accuracy_plot', draw)
    return state


def test_the_fam_plot_is_drawn_only_when_asked_missing_or_stale(fam_plot, tmp_path, capsys):
    out = tmp_path
    assert M._fam_plot(out, _opts(no_fam=True)) == [] and fam_plot.drawn == []
    assert M._fam_plot(out, _opts()) == [] and fam_plot.drawn == []
    assert 'up to date' in capsys.readouterr().out
    got = M._fam_plot(out, _opts(fam=True))                  # --fam redraws a current plot
    assert got == [out / 'fam_accuracy.png'] and fam_plot.drawn == [out]
    fam_plot.current = False                                 # missing or stale: drawn
    assert M._fam_plot(out, _opts()) == [out / 'fam_accuracy.png'] and len(fam_plot.drawn) == 2
    assert M._fam_plot(out, _opts(no_fam=True)) == [] and len(fam_plot.drawn) == 2
    fam_plot.importable = False
    capsys.readouterr()
    assert M._fam_plot(out, _opts()) == []
    assert 'skipped: fam_solver not importable' in capsys.readouterr().out

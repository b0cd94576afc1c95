"""`run_scenario`'s command line without running anything (the runner is replaced): the exit
codes (0 done, 1 a node failed, 2 an invalid scenario), --mode and --set in the scenario and
its name, the default bag under the workspace's bags/, and the summary's lost count."""
import pathlib

import pytest

from catheter_bringup import run_scenario, runner
from catheter_bringup.result import RunResult


def _result(status, published=None, recorded=None, bag='b.mcap'):
    return RunResult('smoke', status, 'why' if status == 'failed' else '', bag, 0.5, 0.1, 500,
                     ['a'], [], [], dict(published or {}), dict(recorded or {}))


@pytest.fixture
def fake_runner(monkeypatch):
    """ScenarioRunner without a run: what it was built with, and the result it returns."""
    seen = {}

    def init(self, sc, **kw):
        seen.update(scenario=sc, **kw)
        self.stop_requested = False

    def setup(self):
        if seen.get('fail_setup'):
            raise seen['fail_setup']
    monkeypatch.setattr(runner.ScenarioRunner, '__init__', init)
    monkeypatch.setattr(runner.ScenarioRunner, 'setup', setup)
    monkeypatch.setattr(runner.ScenarioRunner, 'close', lambda self: None)
    monkeypatch.setattr(runner.ScenarioRunner, 'run', lambda self: seen['result'])
    monkeypatch.setattr(run_scenario, 'install_stop_handlers', lambda r: {})
    return seen


def test_exit_codes(fake_runner, capsys):
    fake_runner['result'] = _result('complete')
    assert run_scenario.main(['smoke', '--no-record', '--quiet']) == 0
    fake_runner['result'] = _result('interrupted')
    assert run_scenario.main(['smoke', '--no-record', '--quiet']) == 0
    fake_runner['result'] = _result('failed')
    assert run_scenario.main(['smoke', '--no-record', '--quiet']) == 1
    fake_runner['fail_setup'] = RuntimeError('a node failed to start')
    assert run_scenario.main(['smoke', '--no-record', '--quiet']) == 1
    fake_runner['fail_setup'] = ValueError('bad value')
    assert run_scenario.main(['smoke', '--no-record', '--quiet']) == 2
    assert run_scenario.main(['smoke', '--set', 'link.dleay=1', '--no-record']) == 2
    assert 'bad value' in capsys.readouterr().err


def test_mode_and_overrides_reach_the_scenario_and_name_the_run(fake_runner, monkeypatch,
                                                                 tmp_path):
    monkeypatch.setenv('CATHETER_WS_ROOT', str(tmp_path))
    fake_runner['result'] = _result('complete')
    assert run_scenario.main(['smoke', '--mode', 'realtime', '--set', 'link.delay=0.25',
                              '--quiet']) == 0
    sc = fake_runner['scenario']
    assert sc['mode'] == 'realtime' and sc['link']['delay'] == 0.25
    assert sc['name'] == 'smoke__link.delay-0.25'
    bag = pathlib.Path(fake_runner['bag'])
    assert bag.parent == tmp_path / 'bags' and bag.name.startswith('smoke__link.delay-0.25_')
    assert bag.suffix == '.mcap'


def test_the_summary_counts_what_was_lost():
    res = _result('complete', published={'/a': 10, '/b': 5}, recorded={'/a': 7, '/b': 5})
    text = run_scenario.summarize(res)
    assert 'recorded 12 messages on 2 topics -> b.mcap (lost: 3)' in text

"""validate_scenario refuses a bad scenario YAML with a ValueError naming the field (never a
TypeError from inside float(), never a silently accepted value): what `run_scenario` prints
to the user instead of a traceback."""
import pytest

from catheter_bringup.scenario import validate_scenario


@pytest.mark.parametrize('link,match', [
    ({'outages': 5}, r'link\.outages must be a list'),
    ({'outages': [[None, 1.0]]}, r'link\.outages entry must be two numbers'),
    ({'outages': [['soon', 1.0]]}, r'link\.outages entry must be two numbers'),
    ({'outages': [[1.0]]}, r'link\.outages entries must be \[start, duration\]'),
    ({'outages': [[-1.0, 0.5]]}, r'link\.outages entry must be finite and >= 0'),
    ({'outages': [[1.0, -0.5]]}, r'link\.outages entry must be finite and >= 0'),
    ({'loss': 1.5}, r'link\.loss=1\.5 outside \[0\.0, 1\.0\]'),
    ({'delay': -0.1}, r'link\.delay=-0\.1 outside'),
])
def test_bad_link_values_are_refused_naming_the_field(link, match):
    with pytest.raises(ValueError, match=match):
        validate_scenario({'link': link})


@pytest.mark.parametrize('field', ['duration', 'step', 'seed'])
def test_a_boolean_is_not_a_number(field):
    with pytest.raises(ValueError, match=f'scenario.{field} must be a finite number'):
        validate_scenario({field: True})


def test_good_link_values_pass_through_as_numbers():
    s = validate_scenario({'link': {'delay': 0.3, 'loss': 1.0, 'outages': [[2, 0.5], [0, 0]]}})
    assert s['link']['outages'] == [[2.0, 0.5], [0.0, 0.0]]
    assert s['link']['loss'] == 1.0 and s['link']['delay'] == 0.3
    assert isinstance(s['seed'], int) and s['seed'] == 0

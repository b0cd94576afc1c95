"""catheter_common.checks: every check either returns a usable value or raises a ValueError
naming the argument (hypothesis over any value); check_fields applies its groups in the order
given and names the first attribute that fails."""
import math
from dataclasses import dataclass

import pytest
from hypothesis import given
from hypothesis import strategies as st

from catheter_common import checks

ANY = st.one_of(st.none(), st.booleans(), st.integers(), st.floats(allow_nan=True),
                st.text(max_size=4), st.lists(st.floats(), max_size=2))


@pytest.mark.parametrize('check, usable', [
    (checks.number, lambda v: not math.isnan(v)),
    (checks.positive_or_inf, lambda v: v > 0.0),
], ids=['number', 'positive_or_inf'])
@given(value=ANY)
def test_a_check_returns_a_usable_float_or_names_the_argument(check, usable, value):
    try:
        v = check('max_rate', value)
    except ValueError as exc:
        assert 'max_rate' in str(exc)
        return
    assert usable(v) and v == float(value)


@given(value=ANY)
def test_integer_is_an_int_in_range_or_names_the_argument(value):
    try:
        v = checks.integer('n', value, -3, 7)
    except ValueError as exc:
        assert 'n must be an int in -3..7' in str(exc)
        return
    assert type(v) is int and -3 <= v <= 7


def test_limits_and_bounds_take_inf_but_not_nan_or_zero():
    assert checks.positive_or_inf('x', math.inf) == math.inf
    assert checks.positive_or_inf('x', '2.5') == 2.5
    assert checks.number('x', -math.inf) == -math.inf
    for bad in (0.0, -1.0, -math.inf, math.nan, 'a', None):
        with pytest.raises(ValueError, match='x'):
            checks.positive_or_inf('x', bad)
    for bad in (math.nan, 'nan', None, [1.0]):
        with pytest.raises(ValueError, match='x'):
            checks.number('x', bad)


def test_integer_refuses_bools_floats_and_the_ends_outside():
    assert checks.integer('n', 1, 1, 3) == 1 and checks.integer('n', 3, 1, 3) == 3
    for bad in (True, 2.0, 0, 4, '2', None):
        with pytest.raises(ValueError, match='n must be an int in 1..3'):
            checks.integer('n', bad, 1, 3)


@dataclass
class _Fields:
    a: float = 1.0
    b: float = 0.0
    c: float = math.inf


def test_check_fields_passes_valid_attributes_unchanged():
    obj = _Fields(a='1.5')
    checks.check_fields(obj, positive=('a',), nonneg=('b',), positive_or_inf=('c',))
    assert obj.a == '1.5'                       # checked, not converted


@pytest.mark.parametrize('attrs, first', [
    (dict(a=0.0), 'a must be > 0'),
    (dict(b=-1.0), 'b must be >= 0'),
    (dict(c=math.nan), 'c must be > 0'),
    (dict(a=math.nan, b=-1.0), 'a must be finite'),      # the first group is checked first
])
def test_check_fields_names_the_first_attribute_that_fails(attrs, first):
    with pytest.raises(ValueError, match=first):
        checks.check_fields(_Fields(**attrs), positive=('a',), nonneg=('b',),
                            positive_or_inf=('c',))


def test_check_fields_keeps_the_order_of_the_groups():
    obj = _Fields(a=0.0, b=-1.0)
    with pytest.raises(ValueError, match='b must be >= 0'):
        checks.check_fields(obj, nonneg=('b',), positive=('a',))
    with pytest.raises(ValueError, match='a must be > 0'):
        checks.check_fields(obj, positive=('a',), nonneg=('b',))


def test_check_fields_refuses_an_unknown_check_or_a_bare_string():
    with pytest.raises(TypeError, match='unknown check'):
        checks.check_fields(_Fields(), postive=('a',))
    with pytest.raises(TypeError, match='sequence of names'):
        checks.check_fields(_Fields(), positive='a')


@dataclass(frozen=True)
class _Declared:
    rate: float = checks.checked(1.0, 'positive')
    gain: float = checks.checked(0.0, 'nonneg')
    offset: float = checks.checked(0.0)
    free: object = None

    def __post_init__(self):
        checks.check_declared(self)


def test_check_declared_applies_each_fields_own_check_in_declaration_order():
    _Declared(rate=2.0, gain=0.0, offset=-3.0, free=math.nan)       # free: not checked
    with pytest.raises(ValueError, match='rate must be > 0'):
        _Declared(rate=0.0)
    with pytest.raises(ValueError, match='gain must be >= 0'):
        _Declared(gain=-1e-300)
    with pytest.raises(ValueError, match='offset must be finite'):
        _Declared(offset=math.inf)
    with pytest.raises(ValueError, match='rate'):
        _Declared(rate=math.nan, gain=-1.0)                          # the first declared
    assert _Declared().rate == 1.0


def test_checked_refuses_an_unknown_check():
    with pytest.raises(TypeError, match='unknown check'):
        checks.checked(1.0, 'postive')


class _Settable:
    limit = checks.Checked(checks.positive)
    rate = checks.Checked(checks.positive_or_inf)

    def __init__(self):
        self.limit, self.rate = 2.0, math.inf


def test_checked_attribute_stores_the_checked_value_and_refuses_a_bad_one():
    s = _Settable()
    s.limit = '3'
    assert s.limit == 3.0 == s._limit and s.rate == math.inf
    for bad in (0.0, math.nan, 'x'):
        with pytest.raises(ValueError, match='limit'):
            s.limit = bad
    assert s.limit == 3.0                          # a refused value leaves the last one
    with pytest.raises(ValueError, match='rate'):
        s.rate = -math.inf
    assert isinstance(_Settable.limit, checks.Checked)


@given(value=st.one_of(ANY, st.floats(allow_nan=True, allow_infinity=True).map(
    lambda f: __import__('numpy').float64(f))))
def test_finite_returns_a_finite_float_or_names_the_argument(value):
    """finite's fast path (an exact float) and its general path agree: a float of exactly
    type float, equal to float(value); inf, -inf and NaN refused as 'must be finite'."""
    try:
        v = checks.finite('gain', value)
    except ValueError as exc:
        assert str(exc).startswith('gain must be')
        try:
            f = float(value)
        except (TypeError, ValueError):
            return
        assert not math.isfinite(f) and 'must be finite' in str(exc)
        return
    assert type(v) is float and math.isfinite(v) and v == float(value)


@pytest.mark.parametrize('bad', [math.inf, -math.inf, math.nan])
def test_finite_refuses_non_finite_floats(bad):
    with pytest.raises(ValueError, match=r'x must be finite, got'):
        checks.finite('x', bad)

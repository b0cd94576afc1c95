"""catheter_common.params: validation of every kind of parameter (hypothesis: any value is
either accepted as something the node can use or refused with a ValueError naming the
parameter), runtime changes applied or refused, read-only sealing, --help text."""
import math

import pytest
from hypothesis import given
from hypothesis import strategies as st
from rclpy.parameter import Parameter

from catheter_common.params import NodeParams, Param, declare, format_help, seal, table

pytestmark = pytest.mark.ros

ANY = st.one_of(st.none(), st.booleans(), st.integers(), st.floats(allow_nan=True),
                st.text(max_size=8), st.lists(st.floats(allow_nan=True), max_size=5),
                st.lists(st.integers(), max_size=5), st.lists(st.text(max_size=3), max_size=3))

SPECS = [
    Param('f', 1.0, 'a float in range', 0.0, 2.0),
    Param('i', 3, 'an int in range', 1, 10),
    Param('c', 'a', 'a choice', choices=('a', 'b')),
    Param('n', [1.0, 2.0], 'two numbers', numbers=True, length=2, lo=-5.0, hi=5.0),
    Param('s', 1.0, 'a sign', choices=(-1.0, 1.0)),
    Param('b', False, 'a flag'),
]


@pytest.mark.parametrize('spec', SPECS, ids=[s.name for s in SPECS])
@given(value=ANY)
def test_validate_accepts_only_usable_values_or_names_the_parameter(spec, value):
    try:
        v = spec.validate(value)
    except ValueError as exc:
        assert f'parameter {spec.name}' in str(exc)
        return
    if spec.numbers:
        assert len(v) == spec.length and all(math.isfinite(x) and -5 <= x <= 5 for x in v)
    elif spec.choices is not None:
        assert v in spec.choices
    elif isinstance(spec.default, float) and not isinstance(value, bool):
        assert math.isfinite(v) and spec.lo <= v <= spec.hi
    elif isinstance(spec.default, int) and not isinstance(spec.default, bool):
        assert isinstance(v, int) and spec.lo <= v <= spec.hi


def test_table_refuses_duplicates():
    with pytest.raises(ValueError, match='twice'):
        table(Param('a', 1, 'x'), Param('a', 2, 'y'))


def test_check_refusal_names_the_parameter():
    def exists(v):
        raise ValueError('no such file')
    with pytest.raises(ValueError, match=r'parameter model=.*no such file'):
        Param('model', 'x', 'a file', check=exists).validate('x')


class _Node:
    """A node with a table: `applied` records what the hook saw."""

    def __init__(self, ros, refuse=None, **overrides):
        import rclpy
        self.node = rclpy.create_node(
            'params_test', context=ros.context,
            parameter_overrides=[Parameter(k, value=v) for k, v in overrides.items()])
        ros.add(self.node)
        self.applied = []
        self.refuse = refuse
        self.params = NodeParams(self.node, [
            Param('gain', 1.0, 'applied', 0.0, 10.0, dynamic=True),
            Param('mode', 'a', 'applied choice', choices=('a', 'b'), dynamic=True),
            Param('rate', 100.0, 'fixed at start', 1.0, 1000.0),
        ], apply=self._apply)

    def _apply(self, changes, values):
        if self.refuse and self.refuse in changes:
            raise ValueError(f'{self.refuse} cannot be built')
        self.applied.append((dict(changes), dict(values)))


def _set(node, **kw):
    return node.set_parameters_atomically([Parameter(k, value=v) for k, v in kw.items()])


def test_runtime_changes_are_applied_or_refused(ros):
    t = _Node(ros)
    assert t.params['gain'] == 1.0
    r = _set(t.node, gain=2.5, mode='b')
    assert r.successful
    assert t.applied == [({'gain': 2.5, 'mode': 'b'}, {'gain': 2.5, 'mode': 'b', 'rate': 100.0})]
    assert t.params['gain'] == 2.5
    for bad in ({'mode': 'c'}, {'gain': math.nan}, {'gain': 11.0}, {'rate': 50.0}):
        r = _set(t.node, **bad)
        assert not r.successful and r.reason, bad
    assert len(t.applied) == 1 and t.params['mode'] == 'b'
    # the same value again: nothing to apply
    assert _set(t.node, gain=2.5).successful and len(t.applied) == 1


def test_a_refusing_hook_leaves_everything_unchanged(ros):
    t = _Node(ros, refuse='mode')
    r = _set(t.node, gain=3.0, mode='b')
    assert not r.successful and 'mode cannot be built' in r.reason
    assert t.params['gain'] == 1.0 and t.node.get_parameter('gain').value == 1.0


def test_start_values_are_validated(ros):
    with pytest.raises(ValueError, match='mode'):
        _Node(ros, mode='z')


def test_dynamic_table_without_hook_is_a_programming_error(ros):
    import rclpy
    node = ros.add(rclpy.create_node('params_nohook', context=ros.context))
    with pytest.raises(ValueError, match='apply hook'):
        NodeParams(node, [Param('g', 1.0, 'x', dynamic=True)])


def test_seal_makes_parameters_declared_elsewhere_read_only(ros):
    import rclpy
    node = ros.add(rclpy.create_node('params_seal', context=ros.context))
    NodeParams(node, [Param('gain', 1.0, 'applied', dynamic=True)], apply=lambda c, v: None)
    assert declare(node, 'path', '', 'declared outside a table') == ''
    node.declare_parameter('loose', 1)
    assert seal(node) == 1                       # 'loose' (declare() is read-only already)
    assert seal(node) == 0
    for name in ('path', 'loose'):
        assert node.describe_parameter(name).read_only
        assert not node.set_parameters([Parameter(name, value=node.get_parameter(name).value
                                                  )])[0].successful
    assert not node.describe_parameter('gain').read_only
    assert not node.describe_parameter('use_sim_time').read_only


def test_help_lists_every_parameter_with_range_and_mode():
    text = format_help('demo_node', SPECS + [Param('g', 1.0, 'applied at run time', 0.0, 2.0,
                                                   dynamic=True)], 'Demo node: does things.')
    assert text.startswith('usage: demo_node')
    assert 'Demo node: does things.' in text
    for s in SPECS:
        assert f'  {s.name} (' in text and s.description in text
    assert '[0, 2]' in text and '{a | b}' in text and '(2 values)' in text
    assert 'runtime' in text and 'start only' in text


def test_plain_declare_refuses_an_unknown_choice_and_is_read_only(ros):
    import rclpy
    node = ros.add(rclpy.create_node('params_plain', context=ros.context, parameter_overrides=[
        Parameter('mode', value='z')]))
    with pytest.raises(ValueError, match=r"parameter mode='z' is not one of \['a', 'b'\]"):
        declare(node, 'mode', 'a', 'a choice', choices=('a', 'b'))
    assert declare(node, 'level', 3, 'an int', 1, 5) == 3
    assert node.describe_parameter('level').read_only
    assert node.describe_parameter('level').integer_range[0].to_value == 5


def test_range_is_inclusive_and_refuses_just_outside():
    """lo and hi are inclusive (the docstring; rclpy's own ranges are too): the end points
    are accepted, the nearest values outside refused by name (mutant K01 survived)."""
    f, i, n = SPECS[0], SPECS[1], SPECS[3]
    assert f.validate(0.0) == 0.0 and f.validate(2.0) == 2.0
    assert i.validate(1) == 1 and i.validate(10) == 10
    assert n.validate([-5, 5.0]) == [-5.0, 5.0]
    for spec, bad in ((f, math.nextafter(0.0, -1.0)), (f, math.nextafter(2.0, 3.0)),
                      (i, 0), (i, 11), (n, [0.0, math.nextafter(5.0, 6.0)])):
        with pytest.raises(ValueError, match=f'parameter {spec.name}.*outside'):
            spec.validate(bad)


@pytest.mark.parametrize('bad', [[math.nan, 1.0], [1.0, math.nan], [math.inf, 0.0]])
def test_a_list_of_numbers_with_a_non_finite_value_is_refused(bad):
    """NaN compares False with both ends of a range, so only the finiteness check refuses it
    (mutant K02 survived the hypothesis test's examples)."""
    with pytest.raises(ValueError, match='parameter n has non-finite values'):
        SPECS[3].validate(bad)


@pytest.mark.parametrize('flag', [True, False])
def test_an_integer_parameter_refuses_a_bool(flag):
    """The type is the default's: a bool is a ROS PARAMETER_BOOL, not an integer, although
    Python's bool is an int subclass (mutant K05 survived)."""
    with pytest.raises(ValueError, match='parameter i must be an integer'):
        SPECS[1].validate(flag)


def test_help_says_which_parameters_change_at_run_time():
    """Each help line says 'runtime' for a dynamic parameter and 'start only' otherwise
    (mutant K06 swapped them and survived the check that both words occur somewhere)."""
    dyn = Param('g', 1.0, 'applied', 0.0, 2.0, dynamic=True).help_line()
    fixed = Param('r', 1.0, 'fixed', 0.0, 2.0).help_line()
    assert 'runtime' in dyn and 'start only' not in dyn
    assert 'start only' in fixed and 'runtime' not in fixed

"""catheter_common.topics: one meaning per name, relative names for namespaces."""
import pytest

from catheter_common import topics as T


def _names():
    return {k: v for k, v in vars(T).items() if k.isupper() and isinstance(v, str)
            and v.startswith('/') and k != 'SHAPE_MARKER'}


def test_one_name_per_topic():
    names = _names()
    by_value = {}
    for k, v in names.items():
        by_value.setdefault(v, []).append(k)
    assert {v: ks for v, ks in by_value.items() if len(ks) > 1} == {}
    assert T.SHAPE != T.FAM_SHAPE                      # measured vs modelled shape


def test_relative_and_resolve():
    assert T.relative(T.SLAVE_FORCE) == 'slave/force'
    assert T.relative(T.DIAGNOSTICS) == '/diagnostics' and T.relative(T.CLOCK) == '/clock'
    assert T.resolve(T.SLAVE_FORCE, '/robot1') == '/robot1/slave/force'
    assert T.resolve(T.SLAVE_FORCE, '/robot1/') == '/robot1/slave/force'
    assert T.resolve(T.SLAVE_FORCE) == T.SLAVE_FORCE
    assert T.resolve(T.DIAGNOSTICS, '/robot1') == '/diagnostics'
    for bad in ('slave/force', '', '/', None):
        with pytest.raises(ValueError, match='name'):
            T.relative(bad)
    with pytest.raises(ValueError, match='namespace'):
        T.resolve(T.SLAVE_FORCE, 'robot1')


def test_every_topic_resolves_to_itself_in_the_root_namespace():
    for v in _names().values():
        assert T.resolve(v, '/') == v


def test_ros_wide_topics_stay_absolute_in_a_namespace():
    """/tf, /tf_static, /rosout, /parameter_events, /clock and /diagnostics are where ROS
    tools (tf2 listeners, rqt, the clock) look for them, whatever the node's namespace
    (mutant K17 dropped /tf from GLOBAL and survived)."""
    for name in ('/tf', '/tf_static', '/rosout', '/parameter_events', '/clock', '/diagnostics'):
        assert T.relative(name) == name
        assert T.resolve(name, '/robot1') == name

"""Helpers of the catheter_bringup tests: the folder's test nodes importable as modules, and a
scenario factory built on them."""
import pathlib
import sys

import pytest

HERE = pathlib.Path(__file__).resolve().parent
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))


def _mod(cls):
    """A tiny module object exposing NODE_CLASS, registered in sys.modules."""
    import types
    name = f'bringup_test_nodes_{cls.__name__}'
    if name not in sys.modules:
        m = types.ModuleType(name)
        m.NODE_CLASS = cls
        sys.modules[name] = m
    return name


@pytest.fixture
def test_registry():
    import nodes_for_tests as n
    from catheter_bringup.scenario import NodeSpec
    return {
        'talker': NodeSpec('talker', _mod(n.TalkerNode), (), ('/test/force',)),
        'relay': NodeSpec('relay', _mod(n.RelayNode), ('/test/force',), ('/test/relayed',)),
        'fake_camera': NodeSpec('fake_camera', _mod(n.FakeCameraNode), (), ('/test/image',)),
        'unused': NodeSpec('unused', _mod(n.UnusedNode), (), ('/test/unused',)),
        'failing': NodeSpec('failing', _mod(n.FailingNode), (), ('/test/failing',)),
        'bad_close': NodeSpec('bad_close', _mod(n.BadCloseNode), (), ('/test/bad_close',)),
        'not_installed': NodeSpec('not_installed', 'no_such_package.no_such_node', (),
                                  ('/test/missing',)),
    }


@pytest.fixture
def make_scenario():
    from catheter_bringup.scenario import validate_scenario

    def make(**kw):
        base = dict(name='unit', duration=0.3, step=0.001, seed=3,
                    outputs=['/test/relayed', '/test/image'])
        base.update(kw)
        return validate_scenario(base)
    return make

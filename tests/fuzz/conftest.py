"""tests/fuzz: the strategies and the harness importable by the tests of this folder."""
import pathlib
import sys

HERE = pathlib.Path(__file__).resolve().parent
for p in (HERE, HERE.parent / 'nodes'):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))


def pytest_configure(config):
    config.addinivalue_line('markers', 'core_dependent: a node-level test of issue 10 that needs '
                            'a fix in a core module (see tests/fuzz/test_fuzz_core_dependent.py)')

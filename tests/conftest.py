"""Test set-up shared by all tests: ROS isolation (a domain id of our own, localhost
discovery), package lookup, and the src packages on sys.path."""
import os
import pathlib
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]
for pkg in sorted((ROOT / 'src').iterdir()):
    if (pkg / 'package.xml').exists() and str(pkg) not in sys.path:
        sys.path.insert(0, str(pkg))

os.environ.setdefault('AMENT_PREFIX_PATH', sys.prefix)
if sys.prefix not in os.environ['AMENT_PREFIX_PATH'].split(':'):
    os.environ['AMENT_PREFIX_PATH'] += ':' + sys.prefix

from catheter_common.ros_testing import isolate_ros_env  # noqa: E402

isolate_ros_env()

import pytest  # noqa: E402
from hypothesis import settings  # noqa: E402

# CI (CI=true) replays the same hypothesis examples every run: a property test that fails
# there fails the same way here; locally examples stay random to keep finding new cases.
settings.register_profile('ci', derandomize=True, print_blob=True)
if os.environ.get('CI', '').lower() in ('1', 'true', 'yes'):
    settings.load_profile('ci')


@pytest.fixture
def ros():
    """A private rclpy context and executor; closed (nodes destroyed) after the test."""
    from catheter_common.ros_testing import RosHarness
    h = RosHarness()
    yield h
    h.close()


@pytest.fixture(scope='session')
def repo_root():
    return ROOT

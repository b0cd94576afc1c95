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

# Every run replays the same hypothesis examples (derandomized, no example database), for
# every user and in CI alike: a suite that is green for one person is green for all.
# To explore new random examples, run with HYPOTHESIS_PROFILE=explore; pin what it finds
# as an explicit regression test (@example or a plain test).
settings.register_profile('deterministic', derandomize=True, database=None, print_blob=True)
settings.register_profile('explore', derandomize=False, print_blob=True)
settings.load_profile(os.environ.get('HYPOTHESIS_PROFILE', 'deterministic'))

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

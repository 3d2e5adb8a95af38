"""Shared pytest set-up: an isolated DDS domain per test session, repository paths."""

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = REPO.parent / 'shared' / 'data'
# The colcon install space the node tests run from; VK_INSTALL lets a developer point elsewhere.
INSTALL = Path(os.environ.get('VK_INSTALL', REPO / 'install'))

# Each test session talks DDS on a domain of its own, on this host only, so parallel runs or
# leftover processes never cross-talk. Set before any test imports rclpy.
if 'VK_TEST_DOMAIN_FIXED' not in os.environ:
    os.environ['ROS_DOMAIN_ID'] = str(10 + os.getpid() % 90)
os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
os.environ.setdefault('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp')


@pytest.fixture(scope='session')
def repo() -> Path:
    """Return the repository root."""
    return REPO


@pytest.fixture(scope='session')
def shared_data() -> Path:
    """Return ../shared/data, skipping the test where the shared data is not beside the repo."""
    if not SHARED_DATA.is_dir():
        pytest.skip(f'shared data not found at {SHARED_DATA}')
    return SHARED_DATA

"""The ROS Python package style check: flake8 with ament's configuration."""

from pathlib import Path

from ament_flake8.main import main_with_errors
import pytest

# The package's own sources; colcon's build/ and install/ copies live in the tree and are skipped.
REPO = Path(__file__).resolve().parents[1]
LINTED = [str(REPO / p) for p in ('setup.py', 'vessel_kinematics', 'test', 'bench', 'launch')
          if (REPO / p).exists()]


@pytest.mark.flake8
@pytest.mark.linter
def test_flake8():
    rc, errors = main_with_errors(argv=LINTED)
    assert rc == 0, 'Found %d code style errors / warnings:\n' % len(errors) + '\n'.join(errors)

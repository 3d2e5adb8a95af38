"""The ROS Python package docstring check: pep257 with ament's convention."""

from pathlib import Path

from ament_pep257.main import main
import pytest

# The package's own sources; colcon's build/ and install/ copies live in the tree and are skipped.
REPO = Path(__file__).resolve().parents[1]
LINTED = [str(REPO / p) for p in ('setup.py', 'vessel_kinematics', 'test', 'bench', 'launch')
          if (REPO / p).exists()]


@pytest.mark.linter
@pytest.mark.pep257
def test_pep257():
    rc = main(argv=LINTED)
    assert rc == 0, 'Found code style errors / warnings'

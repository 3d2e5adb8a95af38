"""``python -m vessel_kinematics.tools.replay``: the ``replay`` command (:mod:`.cli`)."""

import sys

from vessel_kinematics.tools.replay.cli import main

__all__ = ['main']

if __name__ == '__main__':
    sys.exit(main())

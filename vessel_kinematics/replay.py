"""``python -m vessel_kinematics.replay``: the replay tool (:mod:`.tools.replay`)."""

from vessel_kinematics.tools.replay.cli import main

__all__ = ['main']

if __name__ == '__main__':
    raise SystemExit(main())

"""
Point the ROS wheels' exported CMake files at this venv's Python and numpy headers.

The PyPI wheels of ROS 2 Jazzy were built under /opt/python/cp311-cp311 and their exported
CMake targets name that prefix's Python include directory and numpy's include directory. To
build the interface packages of .ci/interfaces against them, rewrite those two paths in the
venv's ``share/*/cmake/*.cmake`` (only inside the venv; nothing outside it is touched).
Idempotent: run after every install.
"""

from pathlib import Path
import sys
import sysconfig

import numpy

BAKED = {
    '/opt/python/cp311-cp311/lib/python3.11/site-packages/numpy/_core/include':
        numpy.get_include(),
    '/opt/python/cp311-cp311/include/python3.11': sysconfig.get_paths()['include'],
}


def main() -> int:
    """Rewrite the baked-in paths under ``sys.prefix/share``; print how many files changed."""
    changed = 0
    for path in Path(sys.prefix, 'share').glob('*/cmake/*.cmake'):
        text = path.read_text()
        new = text
        for old, replacement in BAKED.items():
            new = new.replace(old, replacement)
        if new != text:
            path.write_text(new)
            changed += 1
    print(f'venv_cmake_paths: {changed} CMake files now name {sys.prefix}')
    return 0


if __name__ == '__main__':
    sys.exit(main())

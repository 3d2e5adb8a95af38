"""
package.xml declares what the package imports, and setup.py installs what package.xml says.

* package.xml is valid (catkin_pkg, as rosdep and bloom read it), BSD-3-Clause with the
  LICENSE file, and its version is setup.py's and the CHANGELOG's newest release.
* Every module that the package imports outside the standard library (the code, the launch
  file) is an ``exec_depend``, and every one the tests and benchmarks import is a dependency
  too; the few with no rosdep key are named in a package.xml comment with their pip name.
* The installed package (colcon, as a workspace builds it) has package.xml's version and
  licence, its console scripts as ``lib/vessel_kinematics`` executables, and every config and
  launch file in its share directory.
"""

from __future__ import annotations

import ast
from email.parser import Parser
from pathlib import Path
import re
import sys

from catkin_pkg.package import parse_package
import pytest

REPO = Path(__file__).resolve().parents[1]
PACKAGE = parse_package(str(REPO / 'package.xml'))
PACKAGE.validate()
PACKAGE_XML = (REPO / 'package.xml').read_text()

#: Import name -> its dependency key, where the two differ (a ROS package's are the same).
KEYS = {
    'numpy': 'python3-numpy',
    'yaml': 'python3-yaml',
    'rosbags': 'python3-rosbags-pip',
    'matplotlib': 'python3-matplotlib',
    'pynmea2': 'python3-pynmea2',
    'pytest': 'python3-pytest',
    'hypothesis': 'python3-hypothesis',
    'scipy': 'python3-scipy',
    'geographiclib': 'python3-geographiclib',
    'pymap3d': 'python3-pymap3d',
    'pyproj': 'python3-pyproj',
    'colcon_core': 'python3-colcon-common-extensions',
    'catkin_pkg': 'python3-catkin-pkg',
}
#: Import name -> its PyPI name, for the modules that have no rosdep key (optional or test-only;
#: package.xml's comments say how they are installed).
PIP_ONLY = {'wmm': 'wmm-calculator', 'geomaglib': 'wmm-calculator', 'nmea2000': 'nmea2000',
            'dpkt': 'dpkt', 'mpmath': 'mpmath'}


def _imports(paths: list[Path]) -> dict[str, Path]:
    """Return {top-level module: first file importing it} for every import in ``paths``."""
    found: dict[str, Path] = {}
    for path in paths:
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            else:
                continue
            for name in names:
                found.setdefault(name.partition('.')[0], path)
    return found


def _third_party(paths: list[Path], local: set[str]) -> dict[str, Path]:
    return {name: path for name, path in _imports(paths).items()
            if name not in sys.stdlib_module_names and name not in local}


def _sources(*folders: str) -> list[Path]:
    return sorted(p for folder in folders for p in (REPO / folder).rglob('*.py'))


def test_package_xml_is_bsd_3_clause_with_its_licence_file() -> None:
    [licence] = PACKAGE.licenses
    assert str(licence) == 'BSD-3-Clause' and licence.file == 'LICENSE'
    assert (REPO / 'LICENSE').read_text().startswith('BSD 3-Clause License\n')
    assert PACKAGE.urls, 'package.xml has no <url>'


def test_versions_agree() -> None:
    setup_py = (REPO / 'setup.py').read_text()
    assert re.search(r"version='([^']+)'", setup_py).group(1) == PACKAGE.version
    # catkin's CHANGELOG.rst: the newest release heading is "X.Y.Z (YYYY-MM-DD)".
    changelog = (REPO / 'CHANGELOG.rst').read_text()
    newest = re.search(r'^(\d+\.\d+\.\d+) \(\d{4}-\d{2}-\d{2}\)$', changelog, re.MULTILINE)
    assert newest and newest.group(1) == PACKAGE.version


def test_every_runtime_import_is_an_exec_depend() -> None:
    exec_depends = {d.name for d in PACKAGE.exec_depends}
    imported = _third_party(_sources('vessel_kinematics', 'launch'), {'vessel_kinematics'})
    undeclared = {name: str(path.relative_to(REPO)) for name, path in imported.items()
                  if KEYS.get(name, name) not in exec_depends and name not in PIP_ONLY}
    assert undeclared == {}


def test_every_test_import_is_declared() -> None:
    declared = {d.name for d in PACKAGE.exec_depends + PACKAGE.test_depends}
    local = {p.stem for p in _sources('test', 'bench')} | {'vessel_kinematics'}
    imported = _third_party(_sources('test', 'bench'), local)
    undeclared = {name: str(path.relative_to(REPO)) for name, path in imported.items()
                  if KEYS.get(name, name) not in declared and name not in PIP_ONLY}
    assert undeclared == {}


@pytest.mark.parametrize('module', sorted(set(PIP_ONLY.values())))
def test_a_dependency_without_rosdep_key_says_how_to_install_it(module: str) -> None:
    assert f'pip install {module}' in PACKAGE_XML


@pytest.mark.slow
def test_the_installed_package_is_what_package_xml_says(colcon_install: Path) -> None:
    prefix = colcon_install / 'vessel_kinematics'
    [info] = prefix.glob('lib/python3*/site-packages/vessel_kinematics-*.egg-info')
    metadata = Parser().parsestr((info / 'PKG-INFO').read_text())
    assert metadata['Name'].replace('-', '_') == 'vessel_kinematics'
    assert metadata['Version'] == PACKAGE.version
    assert metadata['License'] == 'BSD-3-Clause'
    scripts = re.findall(r'^(\w+) = ', (info / 'entry_points.txt').read_text(), re.MULTILINE)
    executables = sorted(p.name for p in (prefix / 'lib' / 'vessel_kinematics').iterdir())
    assert sorted(scripts) == executables == ['navigator', 'replay', 'simulate']
    share = prefix / 'share' / 'vessel_kinematics'
    for folder, pattern in (('config', '*.yaml'), ('launch', '*.launch.py')):
        assert ({p.name for p in (REPO / folder).glob(pattern)}
                == {p.name for p in (share / folder).iterdir()}), folder
    assert (share / 'package.xml').read_text() == PACKAGE_XML

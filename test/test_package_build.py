"""
The package builds with colcon as ros.ament_python and the navigator runs as ``ros2 run`` runs it.

``ros2 run vessel_kinematics navigator`` looks the package up in the ament index
(``share/ament_index/resource_index/packages/vessel_kinematics`` under a prefix of
AMENT_PREFIX_PATH) and executes ``<prefix>/lib/vessel_kinematics/navigator`` with the rest of
the command line; these tests do exactly that from a fresh colcon build in a temporary
directory (the ``colcon_install`` fixture of conftest.py).
"""

from __future__ import annotations

import math
import os
from pathlib import Path
import signal
import subprocess
import sys

import dds_harness
import pytest
from vessel_kinematics.ros.params import REMOVED
from vessel_kinematics.ros.params_file import flatten
import yaml

REPO = Path(__file__).resolve().parents[1]
pytestmark = pytest.mark.dds


@pytest.fixture(scope='module')
def built_env(colcon_install: Path) -> dict[str, str]:
    """Return the environment after sourcing the temporary build's setup.bash."""
    return dds_harness.sourced_env(colcon_install)


def test_colcon_identifies_an_ament_python_package(colcon_install: Path) -> None:
    # What `colcon build` identifies the source as (colcon-ros reads package.xml).
    from colcon_core.package_identification import (get_package_identification_extensions,
                                                    identify)
    descriptor = identify(get_package_identification_extensions(), str(REPO))
    assert (descriptor.type, descriptor.name) == ('ros.ament_python', 'vessel_kinematics')
    # ...and what it built: the isolated install of one package.
    assert (colcon_install / 'vessel_kinematics' / 'share' / 'colcon-core' / 'packages'
            / 'vessel_kinematics').is_file()


def test_ament_index_resolves_the_navigator(colcon_install: Path,
                                            built_env: dict[str, str]) -> None:
    prefix = colcon_install / 'vessel_kinematics'
    marker = prefix / 'share' / 'ament_index' / 'resource_index' / 'packages' / 'vessel_kinematics'
    assert marker.is_file()
    # ament_index_python (what ros2 run uses) finds the package through the sourced environment.
    found = subprocess.run(
        [sys.executable, '-c', 'from ament_index_python.packages import get_package_prefix;'
         'print(get_package_prefix("vessel_kinematics"))'],
        env=built_env, capture_output=True, text=True, check=True, timeout=60).stdout.strip()
    assert Path(found) == prefix
    executable = dds_harness.resolve_executable(built_env, 'navigator')
    assert executable == prefix / 'lib' / 'vessel_kinematics' / 'navigator'
    assert os.access(executable, os.X_OK)
    assert (prefix / 'share' / 'vessel_kinematics' / 'package.xml').is_file()
    assert (prefix / 'share' / 'vessel_kinematics' / 'config' / 'navigator.yaml').is_file()


def _start(built_env: dict[str, str], tmp_path: Path, args: list[str],
           processes: list) -> dds_harness.NodeProcess:
    executable = dds_harness.resolve_executable(built_env, 'navigator')
    log = tmp_path / f'{len(processes)}.log'
    process = dds_harness.NodeProcess(executable, args, built_env, log)
    processes.append(process)
    return process


@pytest.fixture
def processes():
    """Collect started processes; stop any still running after the test."""
    started: list[dds_harness.NodeProcess] = []
    yield started
    for process in started:
        process.stop(timeout=5.0)


def test_starts_with_the_installed_params_file(built_env, tmp_path, processes, dds) -> None:
    share = dds_harness.share_directory(built_env)
    params_file = share / 'config' / 'navigator.yaml'
    process = _start(built_env, tmp_path, ['--ros-args', '--params-file', str(params_file)],
                     processes)
    dds.wait_for_node('navigator', process)
    document = yaml.safe_load(params_file.read_text())
    section = next(v for k, v in document.items()
                   if k in ('navigator', '/navigator', '/**/navigator', '/**'))
    expected = flatten(section['ros__parameters'])
    expected.pop('use_sim_time', None)
    for removed in REMOVED:        # ignored with one warning (at their neutral values)
        if expected.pop(removed, None) is not None:
            assert f'parameter {removed!r} was removed and is ignored' in process.output()
    values = dds.get_parameters('/navigator', sorted(expected))
    for name, value in expected.items():
        got = values[name]
        if isinstance(value, list):
            assert len(got) == len(value) and all(
                a == b or (isinstance(a, float) and math.isnan(a) and math.isnan(b))
                for a, b in zip(got, value)), name
        else:
            assert got == value, name
    assert process.stop(signal.SIGINT) == 0, process.output()
    assert 'Traceback' not in process.output()


def test_parameters_and_remaps_on_the_command_line(built_env, tmp_path, processes, dds) -> None:
    args = dds_harness.ros_args(
        params={'map_frame': 'world', 'gnss.default_sigma': 4.0, 'sensor_qos': 'reliable'},
        remaps={'fix': 'gps/fix', 'odometry': 'nav/odom', '__node': 'nav'})
    process = _start(built_env, tmp_path, args, processes)
    dds.wait_for_node('nav', process)
    values = dds.get_parameters('/nav', ['map_frame', 'gnss.default_sigma', 'sensor_qos'])
    assert values == {'map_frame': 'world', 'gnss.default_sigma': 4.0, 'sensor_qos': 'reliable'}

    def topics() -> tuple[set[str], set[str]]:
        published = {n for n, _ in dds.node.get_publisher_names_and_types_by_node('nav', '/')}
        subscribed = {n for n, _ in dds.node.get_subscriber_names_and_types_by_node('nav', '/')}
        return published, subscribed
    assert dds.spin_until(lambda: '/nav/odom' in topics()[0], 10.0), topics()
    published, subscribed = topics()
    assert {'/gps/fix', '/imu', '/velocity'} <= subscribed
    assert '/fix' not in subscribed and '/odometry' not in published
    assert {'/odometry/local', '/odometry/ned', '/course_sideslip', '/origin',
            '/diagnostics'} <= published
    # SIGTERM (what a process supervisor sends) ends it cleanly too.
    assert process.stop(signal.SIGTERM) == 0, process.output()
    assert 'Traceback' not in process.output()


@pytest.mark.parametrize(('name', 'value', 'expected'), [
    ('projection', 'mercator', "'projection': must be one of"),
    ('origin', [95.0, 10.0, 0.0], 'latitude must be in [-90, 90]'),
    ('max_gap', 'soon', "'max_gap': must be a finite number, got 'soon'"),
    ('max_gap', 0, "'max_gap': must be in [0.01"),   # an integer is taken as a double
])
def test_invalid_parameter_at_start_up_is_fatal(built_env, tmp_path, processes,
                                                name, value, expected) -> None:
    process = _start(built_env, tmp_path, dds_harness.ros_args({name: value}), processes)
    code = process.wait(30.0)
    output = process.output()
    assert code not in (None, 0), output
    assert expected in output and 'Traceback' not in output, output

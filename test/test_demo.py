"""
The README's first command, end to end: a short simulated voyage through the live navigator.

``python -m vessel_kinematics.tools.demo`` runs in a shell environment that sourced the install
space
(VK_INSTALL, or a fresh colcon build: the ``navigator_env`` fixture of conftest.py), from the
repository root as ``make demo`` runs it, on this session's DDS domain.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
import re
import subprocess
import sys

import pytest
from rosbags.highlevel import AnyReader
from rosbags.interfaces import QosDurability
from rosbags.typesys import get_typestore, Stores
from vessel_kinematics.ros import interface

REPO = Path(__file__).resolve().parents[1]
#: Every output of the interface table (the demo's log is through the water: all of them).
OUTPUT_TOPICS = (*(t.absolute for t in interface.by_role(interface.Role.OUTPUT)), '/diagnostics')
INPUT_TOPICS = ('/fix', '/imu', '/velocity')
TRUTH_TOPICS = ('/truth/odometry', '/truth/course_sideslip', '/truth/current')
ROW = re.compile(r'^\s+(position|heading|course|sideslip|current) \([a-z/]+\)\s+'
                 r'(\S+) / +(\S+)\s+(\S+) / +(\S+)\s*$')


@pytest.fixture(scope='module')
def demo_env(request: pytest.FixtureRequest) -> dict[str, str]:
    """Return the sourced environment; skip only when there is no install and none builds."""
    try:
        return request.getfixturevalue('navigator_env')
    except (RuntimeError, OSError, subprocess.SubprocessError) as error:
        pytest.skip(f'no install space and colcon cannot build one: {error}')


@pytest.fixture(scope='module')
def demo_run(demo_env: dict[str, str], tmp_path_factory: pytest.TempPathFactory) -> dict:
    """Run a 30 s demo once; return its exit status, output and paths."""
    out = tmp_path_factory.mktemp('demo') / 'demo_out'
    done = subprocess.run(
        [sys.executable, '-m', 'vessel_kinematics.tools.demo', '--output', str(out),
         '--duration', '30'],
        cwd=REPO, env=demo_env, capture_output=True, text=True, timeout=300, check=False)
    return {'code': done.returncode, 'stdout': done.stdout, 'stderr': done.stderr, 'out': out}


def _printed_path(stdout: str, label: str) -> Path:
    match = re.search(rf'^\s+{label}:\s+(\S+)\s*$', stdout, re.MULTILINE)
    assert match, f'no "{label}:" line in the output:\n{stdout}'
    return Path(match.group(1))


@pytest.mark.slow
@pytest.mark.dds
def test_demo_runs_and_prints_paths(demo_run: dict) -> None:
    assert demo_run['code'] == 0, demo_run['stdout'] + demo_run['stderr']
    out = demo_run['out']
    assert _printed_path(demo_run['stdout'], 'bag') == out / 'navigator_run'
    assert _printed_path(demo_run['stdout'], 'plot') == out / 'demo_voyage.png'
    assert _printed_path(demo_run['stdout'], 'summary') == out / 'summary.txt'
    for step in ('1/5', '2/5', '3/5', '4/5', '5/5'):
        assert re.search(rf'^\[demo +[0-9.]+ s\] {step} ', demo_run['stdout'], re.MULTILINE)


@pytest.mark.slow
@pytest.mark.dds
def test_demo_bag_holds_outputs_inputs_and_truth(demo_run: dict) -> None:
    assert demo_run['code'] == 0, demo_run['stdout'] + demo_run['stderr']
    bag = demo_run['out'] / 'navigator_run'
    counts: dict[str, int] = {}
    with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        offered = {}
        for connection in reader.connections:
            counts[connection.topic] = connection.msgcount
            offered[connection.topic] = list(connection.ext.offered_qos_profiles)
        odometry = [c for c in reader.connections if c.topic == '/odometry']
        last = None
        for connection, _, raw in reader.messages(connections=odometry):
            last = reader.deserialize(raw, connection.msgtype)
    for topic in OUTPUT_TOPICS + INPUT_TOPICS + TRUTH_TOPICS:
        assert counts.get(topic, 0) > 0, f'{topic} missing from {sorted(counts)}'
    # 30 s of voyage at the demo's publish_rate of 10 Hz (the first output needs the first fix).
    assert counts['/odometry'] >= 250
    assert counts['/imu'] == 3001
    assert last.header.frame_id == 'map' and last.child_frame_id == 'base_link'
    assert all(math.isfinite(v) for v in (last.pose.pose.position.x,
                                          last.pose.pose.position.y))
    # The latched topics offer transient-local (ros2 bag play latches them), the others not.
    latched = [t for t in ('/origin', '/truth/origin', '/tf_static') if t in offered]
    assert {'/origin', '/truth/origin'} <= set(latched)
    for topic in latched:
        (profile,) = offered[topic]
        assert (profile.durability, profile.depth) == (QosDurability.TRANSIENT_LOCAL, 1), topic
    for topic in ('/odometry', '/fix', '/truth/odometry'):
        (profile,) = offered[topic]
        assert profile.durability == QosDurability.VOLATILE, topic


@pytest.mark.slow
@pytest.mark.dds
def test_demo_navigator_used_every_input(demo_run: dict) -> None:
    assert demo_run['code'] == 0, demo_run['stdout'] + demo_run['stderr']
    summary = (demo_run['out'] / 'summary.txt').read_text()
    published = re.search(r'published\s+/fix (\d+), /imu (\d+), /velocity (\d+)', summary)
    accepted = re.search(r'accepted\s+fix (\d+), imu (\d+), velocity (\d+)', summary)
    assert published and accepted, summary
    fixes, imu, velocity = (int(v) for v in published.groups())
    # Every IMU and velocity message reached the node and was used; the fixes but the
    # outage's NO_FIX reports.
    assert int(accepted.group(2)) == imu
    assert int(accepted.group(3)) == velocity
    assert fixes - 5 <= int(accepted.group(1)) < fixes
    assert 'rejected fix/no_fix' in summary


@pytest.mark.slow
@pytest.mark.dds
def test_demo_plot_and_finite_accuracy(demo_run: dict) -> None:
    assert demo_run['code'] == 0, demo_run['stdout'] + demo_run['stderr']
    png = demo_run['out'] / 'demo_voyage.png'
    data = png.read_bytes()
    assert data[:8] == b'\x89PNG\r\n\x1a\n'
    assert 20_000 < len(data) < 400_000
    summary = (demo_run['out'] / 'summary.txt').read_text()
    rows = {m.group(1): [float(v) for v in m.groups()[1:]]
            for m in map(ROW.match, summary.splitlines()) if m}
    assert set(rows) == {'position', 'heading', 'course', 'sideslip', 'current'}, summary
    for name, (rms, peak, dr_rms, dr_peak) in rows.items():
        assert all(math.isfinite(v) for v in (rms, peak, dr_rms, dr_peak)), name
        assert 0.0 <= rms <= peak and 0.0 <= dr_rms <= dr_peak, name
    # GNSS fixes of 1.5 m keep the fused position within a few metres; without them (and
    # without knowing the current) dead reckoning drifts far more.
    assert rows['position'][0] < 3.0
    assert rows['position'][0] < rows['position'][2]
    assert rows['heading'][0] < 2.0


def test_demo_without_install_says_build_first(tmp_path: Path) -> None:
    env = dict(os.environ)
    env['AMENT_PREFIX_PATH'] = str(tmp_path / 'nothing')
    env['PYTHONPATH'] = os.pathsep.join([str(REPO)] + [
        p for p in env.get('PYTHONPATH', '').split(os.pathsep) if p])
    done = subprocess.run(
        [sys.executable, '-m', 'vessel_kinematics.tools.demo', '--output', str(tmp_path / 'out')],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 1
    assert 'make build' in done.stderr
    assert 'Traceback' not in done.stderr

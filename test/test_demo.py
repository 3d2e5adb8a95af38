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
import struct
import subprocess
import sys
from typing import Any

import pytest
from rosbags.highlevel import AnyReader
from rosbags.interfaces import QosDurability
from rosbags.typesys import get_typestore, Stores
from vessel_kinematics.ros import interface
from vessel_kinematics.tools import demo, demo_live

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
    # outage's NO_FIX reports, though each came 0.1-0.5 s after its stamp, after IMU messages
    # stamped later (fused at its stamp: the navigator's history_length).
    assert 'delivery     latency fix 100-500 ms, imu 1-5 ms, velocity 1-5 ms' in summary
    assert int(accepted.group(2)) == imu
    # The log's last message, stamped with the last IMU sample and arriving just before it,
    # may still wait for the IMU to pass its stamp when the voyage ends (a measurement after
    # the newest IMU sample waits for it: estimation/timeline.py); none is refused.
    assert velocity - 1 <= int(accepted.group(3)) <= velocity
    assert fixes - 5 <= int(accepted.group(1)) < fixes
    assert 'rejected fix/no_fix' in summary
    assert not re.search(r'rejected [^\n]*(too_late|future_stamp|stale_stamp)', summary), summary


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


# --- the player, without DDS ----------------------------------------------------------------

def _cdr(topic: str, stamp_ns: int) -> bytes:
    """Return the start of a message's CDR: the encapsulation and its header stamp (and topic)."""
    sec, nanosec = divmod(stamp_ns, 1_000_000_000)
    return b'\x00\x01\x00\x00' + struct.pack('<iI', sec, nanosec) + topic.encode()


def _voyage(seconds: float, fix_latency_ns: int,
            on_receipt: bool = False) -> list[demo_live.Message]:
    """Return an IMU at 100 Hz (3 ms late) and fixes at 5 Hz, as the demo reads them."""
    start = 1_700_000_000 * 10 ** 9
    messages = []
    for k in range(int(seconds * 100) + 1):
        stamp = start + k * 10_000_000
        messages.append(demo_live.Message('/imu', stamp + 3_000_000, _cdr('/imu', stamp)))
        if k % 20 == 0:
            arrival = stamp + fix_latency_ns
            messages.append(demo_live.Message(
                '/fix', arrival, _cdr('/fix', arrival if on_receipt else stamp)))
    return sorted(messages, key=lambda m: m.log_ns)


class _Node:
    """The navigator as the player sees it: its outputs' stamps, its diagnostics' counts."""

    def __init__(self, answers: bool) -> None:
        self.answers = answers
        self.recording = demo_live.Recording()
        self.sim_time_ns = 0
        self.clock: list[int] = []
        self.sent: list[tuple[str, int, int]] = []   # (topic, /clock, stamp) as published

    # Bridge
    @property
    def input_pubs(self) -> dict[str, Any]:
        return {topic: _Publisher(self, topic) for topic in demo_live.INPUT_TOPICS}

    def publish_clock(self, stamp_ns: int) -> None:
        self.sim_time_ns = stamp_ns
        self.clock.append(stamp_ns)

    # NavigatorProcess
    def alive(self) -> bool:
        return True

    def log_tail(self) -> str:
        return ''

    def receive(self, topic: str, data: bytes) -> None:
        stamp = demo_live.header_stamp_ns(data)
        self.sent.append((topic, self.sim_time_ns, stamp))
        if self.answers and topic == '/imu':    # its state: the newest IMU stamp, at once
            self.recording.last_odometry_ns = max(self.recording.last_odometry_ns, stamp)


class _Publisher:
    """One input's publisher: hands the bytes to the node."""

    def __init__(self, node: _Node, topic: str) -> None:
        self.node, self.topic = node, topic

    def publish(self, data: bytes) -> None:
        self.node.receive(self.topic, data)


@pytest.fixture
def quick(monkeypatch: pytest.MonkeyPatch) -> None:
    """Make the player's waits for a node that does not answer short."""
    monkeypatch.setattr(demo_live, 'MAX_WAIT', 0.2)
    monkeypatch.setattr(demo_live, 'END_WAIT', 0.2)
    monkeypatch.setattr(demo_live, 'DIAGNOSTICS_WAIT', 0.0)


@pytest.mark.parametrize('on_receipt', [False, True])
def test_the_player_publishes_each_input_at_its_arrival(quick: None, on_receipt: bool) -> None:
    """By log time, /clock at most one step behind it; late fixes never make it wait."""
    inputs = _voyage(3.0, fix_latency_ns=450_000_000, on_receipt=on_receipt)
    node = _Node(answers=True)
    stats = demo_live.play(node, inputs, 100.0, node, 0.1, demo_live.MAX_LEAD)
    assert [(topic, stamp) for topic, _, stamp in node.sent] == \
        [(m.topic, demo_live.header_stamp_ns(m.data)) for m in inputs]
    assert node.clock[0] == inputs[0].log_ns
    for message, (_, clock, _) in zip(inputs, node.sent):
        assert message.log_ns - demo_live.CLOCK_STEP_NS <= clock <= message.log_ns
    # Its fixes arrive 0.45 s after their measurement, the last after the last IMU message
    # (stamped then, or at their arrival, after it): a node at the newest IMU stamp is not
    # behind.
    assert stats.waits < 0.1 and stats.published == {'/fix': 16, '/imu': 301, '/velocity': 0}


def test_the_player_goes_on_when_the_nodes_output_stands_still(quick: None) -> None:
    """A navigator without output (every fix refused, no origin) delays the demo once."""
    inputs = _voyage(3.0, fix_latency_ns=300_000_000)
    node = _Node(answers=False)
    stats = demo_live.play(node, inputs, 100.0, node, 0.1, demo_live.MAX_LEAD)
    assert len(node.sent) == len(inputs)
    assert 0.2 <= stats.waits < 0.6


@pytest.mark.parametrize(('history', 'latency', 'lead'), [
    (2.0, 0.5, demo_live.MAX_LEAD), (1.0, 0.5, 0.18), (0.7, 0.5, 0.1), (0.7, 0.0, 0.18)])
def test_the_lead_fits_in_the_navigators_history(history: float, latency: float,
                                                 lead: float) -> None:
    assert demo_live.lead_limit(history, latency) == pytest.approx(lead)


def test_latency_beyond_the_history_is_an_error() -> None:
    with pytest.raises(demo_live.DemoError, match='history_length'):
        demo_live.lead_limit(0.5, 0.45)


def test_demo_latency_options() -> None:
    args = demo._parse_args([])
    assert (args.fix_latency, args.stamp_on_receipt) == ([0.1, 0.5], False)
    args = demo._parse_args(['--fix-latency', '0', '0', '--stamp-on-receipt'])
    assert (args.fix_latency, args.stamp_on_receipt) == ([0.0, 0.0], True)

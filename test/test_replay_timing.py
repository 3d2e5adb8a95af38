"""
Real recordings with real timing faults, replayed against the same recording clean.

The motor vessel's bag (``../shared/data/motorboat_wide_turn``) is rewritten as a vessel's
graph would have recorded it with a slower GNSS driver (every fix logged 0.3 s after its
stamp, one 1.5 s) and with glitched stamps (a fix, an IMU sample and a speed-log reading
stamped 1e6 s ahead; an IMU sample stamped 1000 s back). Replayed in log-time order, as the
node would have received them: fewer than 5 % of the outputs lost, the position within 0.5 m
(p95) of the clean replay at the same stamps, no reset, and no output stamped in the future.
"""

from __future__ import annotations

import math
from pathlib import Path
import struct

import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import StoragePlugin, Writer
from test_replay_safety import STORE
from vessel_kinematics.tools import replay

REMAPS = ['fix:=/fix', 'imu:=/imu', 'velocity:=/speed_log']
#: Message indices (per topic) whose stamp is glitched, and by how many seconds.
GLITCHES = {('/fix', 300): 1_000_000, ('/imu', 600): 1_000_000, ('/speed_log', 500): 1_000_000,
            ('/imu', 900): -1000}


def _rewrite(source: Path, target: Path) -> Path:
    """Copy the bag: fixes logged 0.3 s late (the 200th 1.5 s), and the glitched stamps."""
    with AnyReader([source]) as reader, Writer(target, version=9,
                                               storage_plugin=StoragePlugin.MCAP) as writer:
        connections = {c.id: writer.add_connection(c.topic, c.msgtype, typestore=STORE)
                       for c in reader.connections}
        counts: dict[str, int] = {}
        rows = []
        for connection, log_ns, raw in reader.messages():
            index = counts.get(connection.topic, 0)
            counts[connection.topic] = index + 1
            raw = bytes(raw)
            if connection.topic == '/fix':
                log_ns += 1_500_000_000 if index == 200 else 300_000_000
            shift = GLITCHES.get((connection.topic, index))
            if shift is not None:
                (sec,) = struct.unpack_from('<i', raw, 4)
                raw = raw[:4] + struct.pack('<i', sec + shift) + raw[8:]
            rows.append((log_ns, connection.id, raw))
        for log_ns, connection_id, raw in sorted(rows, key=lambda row: row[0]):
            writer.write(connections[connection_id], log_ns, raw)
    return target


def _odometry(bag: Path) -> dict[int, tuple[float, float]]:
    """Return {header stamp ns: (x, y)} of the replay's ``/odometry``."""
    out = {}
    with AnyReader([bag]) as reader:
        connections = [c for c in reader.connections if c.topic == '/odometry']
        for connection, _, raw in reader.messages(connections):
            msg = reader.deserialize(raw, connection.msgtype)
            stamp = msg.header.stamp.sec * 10 ** 9 + msg.header.stamp.nanosec
            out[stamp] = (msg.pose.pose.position.x, msg.pose.pose.position.y)
    return out


@pytest.mark.slow
def test_late_and_glitched_stamps_on_a_real_motor_vessel(shared_data: Path, repo: Path,
                                                         tmp_path: Path) -> None:
    source = shared_data / 'motorboat_wide_turn'
    params = replay.load_params(repo / 'config' / 'motorboat.yaml')
    clean = replay.run(source, tmp_path / 'clean', params, REMAPS, progress=False,
                       copy_inputs=False, accuracy=False)
    faulty_bag = _rewrite(source, tmp_path / 'faulty_in')
    faulty = replay.run(faulty_bag, tmp_path / 'faulty', params, REMAPS, progress=False,
                        copy_inputs=False, accuracy=False)
    assert faulty.resets == 0 and clean.resets == 0
    refused = {k: n for k, n in faulty.rejected.items() if k not in clean.rejected}
    assert refused == {'fix/future_stamp': 1, 'imu/future_stamp': 1,
                       'velocity/future_stamp': 1, 'imu/too_late': 1}, faulty.rejected
    a, b = _odometry(tmp_path / 'clean'), _odometry(tmp_path / 'faulty')
    assert len(b) >= 0.95 * len(a), (len(b), len(a))
    last_stamp = max(a)
    assert max(b) <= last_stamp                         # nothing stamped in the future
    common = sorted(set(a) & set(b))
    errors = [math.hypot(a[t][0] - b[t][0], a[t][1] - b[t][1]) for t in common]
    assert len(common) >= 0.95 * len(a)
    assert np.percentile(errors, 95) < 0.5, np.percentile(errors, [50, 95, 100])


def test_a_logger_pause_on_a_real_sailboat_costs_nothing(shared_data: Path, repo: Path,
                                                         tmp_path: Path) -> None:
    # The IJsselmeer log with 14 s of its lines gone, as one yacht's logger paused now and
    # then: the first messages after the pause had been refused (3 headings here, a fix in
    # the yacht's log: future_stamp), judged against the inputs from before the pause.
    lines = (shared_data / 'sailboat_ijsselmeer_nmea0183.log').read_text().splitlines()
    rmc = [i for i, line in enumerate(lines) if line.startswith('$GPRMC')]
    cut = lines[:rmc[60]] + lines[rmc[74]:]
    path = tmp_path / 'paused.log'
    path.write_text('\n'.join(cut) + '\n')
    params = replay.load_params(repo / 'config' / 'sailboat.yaml')
    summary = replay.run(path, tmp_path / 'out', params, progress=False, copy_inputs=False,
                         accuracy=False)
    assert summary.resets == 0 and dict(summary.rejected) == {}, summary.rejected

"""
Tests of the voyage simulator: determinism, truth self-consistency, sensors, bag contents.

The truth is checked against independent computations (scipy's Rotation for the REP-103
orientation, pymap3d for the geodetic fixes, numpy integration for the headings), not against
the simulator's own helpers.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any

import numpy as np
import pymap3d
import pytest
from rosbags.highlevel import AnyReader
from rosbags.interfaces import QosDurability, QosReliability
from rosbags.typesys import get_typestore, Stores
from scipy.spatial.transform import Rotation
from vessel_kinematics.tools import sim, sim_bag, sim_sensors
import yaml

DURATION = 60.0
START_S = sim.START_NS * 1e-9


def _config(**changes: object) -> sim.VoyageConfig:
    values = {'duration': DURATION, 'seed': 7}
    values.update(changes)
    return sim.VoyageConfig(**values)


@pytest.fixture(scope='module')
def voyage(tmp_path_factory: pytest.TempPathFactory) -> dict:
    """Simulate a 60 s voyage once; return the generate() summary with the bag's messages."""
    path = tmp_path_factory.mktemp('sim') / 'voyage'
    summary = sim.generate(path, _config())
    summary['bag'] = _read(path)
    return summary


def _read(path: Path) -> dict[str, list]:
    """Return {topic: [(log time ns, rosbags message)]} and a '_types' entry."""
    out: dict[str, list] = {}
    with AnyReader([path], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        out['_types'] = [(c.topic, c.msgtype) for c in reader.connections]
        for connection, log_ns, raw in reader.messages():
            out.setdefault(connection.topic, []).append(
                (log_ns, reader.deserialize(raw, connection.msgtype)))
    return out


def _stamp_s(msg: object) -> float:
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9 - START_S


def _yaw_enu(q: object) -> float:
    return Rotation.from_quat([q.x, q.y, q.z, q.w]).as_euler('ZYX')[0]


# --- the bag ---------------------------------------------------------------------------------


def test_topics_types_and_rates(voyage: dict) -> None:
    bag = voyage['bag']
    assert dict(bag['_types']) == sim.TOPICS
    expected_rates = {'/imu': 100.0, '/velocity': 5.0, '/truth/odometry': 20.0,
                      '/truth/course_sideslip': 20.0, '/truth/current': 20.0,
                      '/truth/calibration': 20.0}
    for topic, rate in expected_rates.items():
        stamps = np.array([_stamp_s(m) for _, m in bag[topic]])
        assert len(stamps) == int(DURATION * rate) + 1, topic
        np.testing.assert_allclose(np.diff(stamps), 1.0 / rate, atol=1e-6, err_msg=topic)
    fix_stamps = np.array([_stamp_s(m) for _, m in bag['/fix'] if m.status.status >= 0])
    gaps = np.diff(fix_stamps)
    assert np.median(gaps) == pytest.approx(0.2, abs=1e-6)   # 5 Hz
    assert len(bag['/truth/origin']) == 1


def test_the_latched_origin_offers_transient_local(voyage: dict) -> None:
    """``ros2 bag play`` of a simulated bag latches ``/truth/origin`` (the interface's QoS)."""
    with AnyReader([voyage['path']], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        offered = {c.topic: list(c.ext.offered_qos_profiles) for c in reader.connections}
    (origin,) = offered['/truth/origin']
    assert (origin.durability, origin.reliability, origin.depth) == \
        (QosDurability.TRANSIENT_LOCAL, QosReliability.RELIABLE, 1)
    for topic in sim.TOPICS.keys() - {'/truth/origin'}:
        (profile,) = offered[topic]
        assert profile.durability == QosDurability.VOLATILE, topic
    # As rosbag2 reads it: in metadata.yaml, per topic.
    metadata = yaml.safe_load((Path(voyage['path']) / 'metadata.yaml').read_text())
    in_metadata = {t['topic_metadata']['name']: t['topic_metadata']['offered_qos_profiles']
                   for t in metadata['rosbag2_bagfile_information']['topics_with_message_count']}
    assert [(q['durability'], q['depth']) for q in in_metadata['/truth/origin']] == \
        [('transient_local', 1)]


def _stamp_ns(msg: object) -> int:
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


#: The default delivery latency of each input, (min, max) s.
LATENCY = {'/fix': (0.1, 0.5), '/imu': (0.001, 0.005), '/velocity': (0.001, 0.005)}


def test_inputs_are_logged_their_latency_after_their_stamps(voyage: dict) -> None:
    """A fix reaches the bag 0.1-0.5 s after its stamp, the IMU and the log 1-5 ms after."""
    for topic, messages in voyage['bag'].items():
        if topic == '_types':
            continue
        logs = [log_ns for log_ns, _ in messages]
        assert logs == sorted(logs), topic
        # Each sensor's messages arrive in the order they were measured (first in first out).
        stamps = [_stamp_ns(msg) for _, msg in messages]
        assert stamps == sorted(stamps), topic
        latency = np.array([log_ns - _stamp_ns(msg) for log_ns, msg in messages]) * 1e-9
        if topic.startswith('/truth'):
            assert np.all(latency == 0.0), topic
            continue
        low, high = LATENCY[topic]
        assert np.all(latency >= low - 1e-9) and np.all(latency <= high + 1e-9), topic
        # Jitter per message, drawn across the whole range.
        assert latency.min() < low + 0.1 * (high - low), topic
        assert latency.max() > high - 0.1 * (high - low), topic
        assert latency.std() > 0.2 * (high - low), topic
    # The NO_FIX reports of the outage come late as well.
    no_fix = [log_ns - _stamp_ns(m) for log_ns, m in voyage['bag']['/fix'] if m.status.status < 0]
    assert no_fix and all(0.1e9 <= d <= 0.5e9 for d in no_fix)


def test_the_bag_is_written_in_log_time_order(monkeypatch: pytest.MonkeyPatch,
                                              tmp_path: Path) -> None:
    """Records in stamp order are written to the bag by log time, never backwards."""
    config = _config(duration=10.0)
    records = sim.sensor_records(sim.simulate(config), config)
    assert [r.stamp_ns for r in records] == sorted(r.stamp_ns for r in records)
    assert [r.log_ns for r in records] != sorted(r.log_ns for r in records)
    written: list[tuple[str, int, bytes]] = []
    original = sim_bag.bags.write_bag

    def spy(path: Path, messages: Any, *args: Any, **kwargs: Any) -> Path:
        written.extend(messages)
        return original(path, written, *args, **kwargs)

    monkeypatch.setattr(sim_bag.bags, 'write_bag', spy)
    sim.write_bag(tmp_path / 'bag', records)
    assert len(written) == len(records)
    logs = [log_ns for _, log_ns, _ in written]
    assert logs == sorted(logs)
    # A record made without a log time is logged at its stamp (the truth, hand-made records).
    assert sim.Record('/fix', 5, b'').log_ns == 5


def _latencies(records: list) -> dict[str, list[int]]:
    return {topic: [r.log_ns - r.stamp_ns for r in records if r.topic == topic]
            for topic in LATENCY}


def test_latency_is_seeded_and_leaves_the_readings_unchanged() -> None:
    config = _config(duration=10.0)
    truth = sim.simulate(config)
    first = sim.sensor_records(truth, config)
    again = sim.sensor_records(sim.simulate(config), config)
    assert [(r.topic, r.stamp_ns, r.log_ns) for r in first] == \
        [(r.topic, r.stamp_ns, r.log_ns) for r in again]
    other = sim.sensor_records(sim.simulate(config), _config(duration=10.0, seed=8))
    for topic in LATENCY:
        assert _latencies(first)[topic] != _latencies(other)[topic], topic
    # Without latency the same seed gives the same messages, logged at their stamps: the
    # latencies come from streams of their own.
    still = _config(duration=10.0, fix_latency=(0.0, 0.0), imu_latency=(0.0, 0.0),
                    velocity_latency=(0.0, 0.0))
    plain = sim.sensor_records(sim.simulate(still), still)
    assert all(r.log_ns == r.stamp_ns for r in plain)
    assert _contents(plain) == _contents(first)
    # Another range, other latencies from the same seed, within it.
    slow = _config(duration=10.0, fix_latency=(1.0, 2.0))
    fixes = _latencies(sim.sensor_records(sim.simulate(slow), slow))['/fix']
    assert all(1_000_000_000 <= d <= 2_000_000_000 for d in fixes)


def test_delivery_is_first_in_first_out_within_the_range() -> None:
    """Latencies wider than the period: a message held up holds the next one behind it."""
    stamps = [k * 100_000_000 for k in range(2000)]          # 10 Hz, latencies of 0.1-0.9 s
    latencies = sim.delivery_latencies(stamps, (0.1, 0.9), np.random.default_rng(3))
    arrivals = [s + d for s, d in zip(stamps, latencies)]
    assert all(b > a for a, b in zip(arrivals, arrivals[1:]))
    assert min(latencies) >= 100_000_000 and max(latencies) <= 900_000_000
    held = [b - a for a, b in zip(arrivals, arrivals[1:]) if b - a == sim_sensors.FIFO_GAP_NS]
    assert len(held) > 100        # many are held up, each right behind the one before
    assert sim.delivery_latencies(stamps[:5], (0.2, 0.2), np.random.default_rng(0)) == \
        [200_000_000] * 5


def test_drivers_stamping_on_receipt() -> None:
    """--stamp-on-receipt: every input's stamp is its log time, late by the latency."""
    config = _config(duration=20.0, stamp_on_receipt=True)
    truth = sim.simulate(config)
    records = sim.sensor_records(truth, config)
    measured = sim.sensor_records(truth, _config(duration=20.0))
    for topic, (low, high) in LATENCY.items():
        receipt = [r for r in records if r.topic == topic]
        at_measurement = [r for r in measured if r.topic == topic]
        assert receipt and len(receipt) == len(at_measurement)
        assert all(r.stamp_ns == r.log_ns for r in receipt), topic
        # The same arrivals; the stamps off by the latency (an error the navigator cannot see).
        assert [r.log_ns for r in receipt] == [r.log_ns for r in at_measurement], topic
        error = np.array([a.stamp_ns - b.stamp_ns for a, b in zip(receipt, at_measurement)])
        assert np.all(error >= low * 1e9 - 1) and np.all(error <= high * 1e9 + 1), topic
        store = get_typestore(Stores.ROS2_JAZZY)
        for rec in receipt[:50]:
            msg = store.deserialize_cdr(rec.data, sim.TOPICS[topic])
            assert _stamp_ns(msg) == rec.log_ns
    truth_records = [r for r in records if r.topic.startswith('/truth')]
    assert all(r.log_ns == r.stamp_ns for r in truth_records)
    assert [(r.stamp_ns, r.data) for r in truth_records] == \
        [(r.stamp_ns, r.data) for r in measured if r.topic.startswith('/truth')]


def test_latency_command_line(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    defaults = sim.VoyageConfig()
    assert (defaults.fix_latency, defaults.imu_latency, defaults.velocity_latency,
            defaults.stamp_on_receipt) == ((0.1, 0.5), (0.001, 0.005), (0.001, 0.005), False)
    args = sim._parse_args(['out', '--fix-latency', '0.2', '0.3', '--imu-latency', '0', '0.01',
                            '--velocity-latency', '0.05', '0.06', '--stamp-on-receipt'])
    assert sim.config_from_args(args) == sim.VoyageConfig(
        fix_latency=(0.2, 0.3), imu_latency=(0.0, 0.01), velocity_latency=(0.05, 0.06),
        stamp_on_receipt=True)
    args = sim._parse_args(['out', '--no-latency', '--fix-latency', '1', '2'])
    config = sim.config_from_args(args)
    assert (config.fix_latency, config.imu_latency, config.velocity_latency) == ((0.0, 0.0),) * 3
    assert sim.main([str(tmp_path / 'ok'), '--duration', '3', '--stamp-on-receipt']) == 0
    out = capsys.readouterr().out
    assert 'delivery latency: fix 100..500 ms, imu 1..5 ms, velocity 1..5 ms' in out
    assert 'stamped on receipt' in out
    for bad, name in ((['--fix-latency', '0.5', '0.1'], '--fix-latency'),
                      (['--imu-latency', '-0.001', '0.001'], '--imu-latency'),
                      (['--velocity-latency', '0', 'nan'], '--velocity-latency'),
                      (['--fix-latency', '0', '11'], '--fix-latency')):
        assert sim.main([str(tmp_path / 'bad'), '--duration', '3'] + bad) == 2
        assert name in capsys.readouterr().err


def _plain(value: Any) -> Any:
    """Return a deserialised message as nested tuples of plain values, comparable with ==."""
    if dataclasses.is_dataclass(value):
        return tuple(_plain(getattr(value, f.name)) for f in dataclasses.fields(value))
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, (list, tuple)):
        return tuple(_plain(v) for v in value)
    if isinstance(value, float) and math.isnan(value):
        return 'nan'                       # NaN != NaN: the NO_FIX reports of the outage
    return value


def _contents(records: Any) -> list:
    """Return (topic, stamp, message fields) of serialised records."""
    store = get_typestore(Stores.ROS2_JAZZY)
    return [(r.topic, r.stamp_ns, _plain(store.deserialize_cdr(r.data, sim.TOPICS[r.topic])))
            for r in records]


def test_same_seed_same_messages_other_seed_other_noise(tmp_path: Path) -> None:
    config = _config(duration=10.0)
    first = sim.sensor_records(sim.simulate(config), config)
    second = sim.sensor_records(sim.simulate(config), config)
    # Byte by byte: the padding is written as zeros (rclpy's Fast CDR leaves it unwritten,
    # which made two runs of one voyage differ in a few bytes).
    assert [(r.topic, r.stamp_ns, r.log_ns, r.data) for r in first] == \
        [(r.topic, r.stamp_ns, r.log_ns, r.data) for r in second]
    imu = next(r.data for r in first if r.topic == '/imu')
    assert imu[4 + 8 + 4 + len(b'imu_link\x00'):][:3] == bytes(3)    # padding before float64
    other = sim.sensor_records(sim.simulate(config), _config(duration=10.0, seed=8))
    fixes = [r.data for r in first if r.topic == '/fix']
    assert fixes != [r.data for r in other if r.topic == '/fix']
    assert _contents(r for r in first if r.topic.startswith('/truth')) == \
        _contents(r for r in other if r.topic.startswith('/truth'))
    # The written bags hold the same messages too.
    a = sim.write_bag(tmp_path / 'a', first)
    b = sim.write_bag(tmp_path / 'b', second)
    read_a, read_b = _read(a), _read(b)
    assert [(t, [log for log, _ in read_a[t]]) for t in sim.TOPICS] == \
        [(t, [log for log, _ in read_b[t]]) for t in sim.TOPICS]


# --- truth self-consistency -----------------------------------------------------------------


def test_truth_course_is_atan2_of_velocity_and_chi_is_psi_plus_beta(voyage: dict) -> None:
    bag = voyage['bag']
    odometry = [m for _, m in bag['/truth/odometry']]
    angles = [m for _, m in bag['/truth/course_sideslip']]
    checked_beta = 0
    for odo, cs in zip(odometry, angles):
        assert _stamp_s(odo) == pytest.approx(_stamp_s(cs))
        yaw = _yaw_enu(odo.pose.pose.orientation)
        psi = math.pi / 2 - yaw                                   # NED heading
        u, v_flu = odo.twist.twist.linear.x, odo.twist.twist.linear.y
        # Velocity over ground in ENU from the FLU body velocity, by scipy.
        v_enu = Rotation.from_euler('z', yaw).apply([u, v_flu, 0.0])
        chi = math.atan2(v_enu[0], v_enu[1])                       # from north, clockwise
        assert math.remainder(cs.vector.x - chi, 2 * math.pi) == pytest.approx(0.0, abs=1e-9)
        beta = math.asin(-v_flu / math.hypot(u, v_flu))             # Fossen: asin(v/U), v FRD
        assert cs.vector.y == pytest.approx(beta, abs=1e-9)
        assert math.remainder(cs.vector.x - (psi + cs.vector.y), 2 * math.pi) == \
            pytest.approx(0.0, abs=1e-9)
        assert cs.vector.z == 0.0
        checked_beta += abs(beta) > math.radians(3.0)
    # The current and the turns make the sideslip far from zero most of the time.
    assert checked_beta > len(angles) // 2


def test_truth_odometry_follows_rep103(voyage: dict) -> None:
    odometry = [m for _, m in voyage['bag']['/truth/odometry']]
    first = odometry[0]
    assert first.header.frame_id == 'map'
    assert first.child_frame_id == 'base_link'
    # Initial heading 30 deg from north (NED) is yaw 60 deg in ENU.
    assert math.degrees(_yaw_enu(first.pose.pose.orientation)) == pytest.approx(60.0, abs=1e-6)
    positions = np.array([[m.pose.pose.position.x, m.pose.pose.position.y] for m in odometry])
    t = np.array([_stamp_s(m) for m in odometry])
    # Position differences agree with the body velocity rotated into ENU (trapezoid rule).
    v_enu = np.array([Rotation.from_euler('z', _yaw_enu(m.pose.pose.orientation)).apply(
        [m.twist.twist.linear.x, m.twist.twist.linear.y, 0.0])[:2] for m in odometry])
    integrated = np.cumsum(0.5 * (v_enu[1:] + v_enu[:-1]) * np.diff(t)[:, None], axis=0)
    np.testing.assert_allclose(positions[1:] - positions[0], integrated, atol=0.05)
    # Going north-east at the start: +x east, +y north.
    assert positions[10, 0] > 0 and positions[10, 1] > 0
    # Yaw rate in FLU: a starboard (clockwise) turn has angular.z < 0 while ENU yaw decreases.
    yaw = np.unwrap([_yaw_enu(m.pose.pose.orientation) for m in odometry])
    rate = np.array([m.twist.twist.angular.z for m in odometry])
    np.testing.assert_allclose(np.diff(yaw) / np.diff(t), 0.5 * (rate[1:] + rate[:-1]),
                               atol=2e-3)
    assert rate.min() < -0.05   # the turning circle is to starboard


def test_truth_current_matches_velocity_difference(voyage: dict) -> None:
    truth = voyage['truth']
    bag = voyage['bag']
    current = np.array([[m.vector.x, m.vector.y] for _, m in bag['/truth/current']])
    speed = np.hypot(current[:, 0], current[:, 1])
    assert np.all((speed > 0.5) & (speed < 0.7))
    # v_ground - R(psi) nu_r is the current (NED) at every step.
    c, s = np.cos(truth.psi), np.sin(truth.psi)
    v_ned = truth.ground_velocity_ned()
    np.testing.assert_allclose(v_ned[:, 0] - (c * truth.u_r - s * truth.v_r), truth.current_n,
                               atol=1e-12)
    np.testing.assert_allclose(v_ned[:, 1] - (s * truth.u_r + c * truth.v_r), truth.current_e,
                               atol=1e-12)
    step = int(100 / 20)
    np.testing.assert_allclose(current[:, 0], truth.current_e[::step], atol=1e-12)
    np.testing.assert_allclose(current[:, 1], truth.current_n[::step], atol=1e-12)


def test_manoeuvres_are_there() -> None:
    truth = sim.simulate(sim.VoyageConfig(duration=300.0, seed=1))
    phases = set(truth.phase)
    assert phases == {'straight', 'turning circle', 'zig-zag'}
    circle = np.array([p == 'turning circle' for p in truth.phase])
    turned = truth.psi[circle][-1] - truth.psi[circle][0]
    assert turned == pytest.approx(2 * math.pi, abs=0.01)
    zigzag = np.array([p == 'zig-zag' for p in truth.phase])
    rudder_sign_changes = np.count_nonzero(np.diff(np.sign(truth.rudder[zigzag])) != 0)
    assert rudder_sign_changes >= 3
    beta = np.degrees(truth.sideslip())
    assert beta.min() < -10.0 and beta.max() > 10.0


# --- sensors -------------------------------------------------------------------------------


def test_fixes_scatter_around_truth_with_stated_sigma(voyage: dict) -> None:
    config = _config()
    truth = voyage['truth']
    lat0, lon0, h0 = config.origin
    fixes = [m for _, m in voyage['bag']['/fix'] if m.status.status >= 0]
    errors = []
    for m in fixes:
        k = int(round(_stamp_s(m) * config.imu_rate))
        n, e, d = pymap3d.geodetic2ned(m.latitude, m.longitude, m.altitude, lat0, lon0, h0)
        psi = truth.psi[k]
        ax, ay, az = config.antenna
        # The antenna: FLU lever arm rotated by the heading (NED, FRD).
        n_true = truth.north[k] + math.cos(psi) * ax + math.sin(psi) * ay
        e_true = truth.east[k] + math.sin(psi) * ax - math.cos(psi) * ay
        errors.append((n - n_true, e - e_true, d + az))
        assert m.position_covariance_type == m.COVARIANCE_TYPE_DIAGONAL_KNOWN
        np.testing.assert_allclose(m.position_covariance[[0, 4, 8]],
                                   [1.5 ** 2, 1.5 ** 2, 3.0 ** 2])
    errors = np.array(errors)
    count = len(errors)
    sigma = errors.std(axis=0)
    # Sample standard deviations within 5 standard errors (sigma / sqrt(2 n)) of the stated.
    tolerance = 5.0 / math.sqrt(2 * count)
    assert sigma[0] == pytest.approx(1.5, rel=tolerance)
    assert sigma[1] == pytest.approx(1.5, rel=tolerance)
    assert sigma[2] == pytest.approx(3.0, rel=tolerance)
    assert np.all(np.abs(errors.mean(axis=0)) < 5.0 * np.array([1.5, 1.5, 3.0]) / math.sqrt(count))


def test_outage_has_no_valid_fix_but_no_fix_messages(voyage: dict) -> None:
    start, end = voyage['outage']
    assert end - start == pytest.approx(min(25.0, round(0.085 * DURATION)))
    fixes = [m for _, m in voyage['bag']['/fix']]
    inside = [m for m in fixes if start <= _stamp_s(m) < end]
    assert inside, 'the receiver still reports during the outage'
    for m in inside:
        assert m.status.status == m.status.STATUS_NO_FIX
        assert math.isnan(m.latitude) and math.isnan(m.longitude)
    valid = [_stamp_s(m) for m in fixes if m.status.status >= 0]
    assert max(np.diff(valid)) == pytest.approx(end - start + 0.2, abs=1e-6)
    assert all(not start <= t < end for t in valid)


def test_no_outage_option(tmp_path: Path) -> None:
    assert sim.main([str(tmp_path / 'bag'), '--duration', '5', '--no-outage']) == 0
    fixes = [m for _, m in _read(tmp_path / 'bag')['/fix']]
    assert all(m.status.status >= 0 for m in fixes) and len(fixes) == 26


def test_imu_rates_integrate_to_truth_heading(voyage: dict) -> None:
    truth = voyage['truth']
    imu = [m for _, m in voyage['bag']['/imu']]
    rate_z = np.array([m.angular_velocity.z for m in imu])
    # Remove the (known to the simulator) bias; FLU z rate is minus the NED yaw rate r.
    heading_change = -np.cumsum((rate_z[:-1] - truth.gyro_bias[2]) * 0.01)
    expected = truth.psi[1:] - truth.psi[0]
    # White noise of 0.1 deg/s per sample integrates to 0.1 deg/s * 0.01 s * sqrt(n).
    n = len(heading_change)
    allowed = 5 * math.radians(0.1) * 0.01 * math.sqrt(n) + 0.01
    assert np.max(np.abs(heading_change - expected)) < allowed
    # The bias is there: integrating the raw rate drifts by bias * t.
    assert abs(truth.gyro_bias[2]) > 0.0
    for m in imu[:5]:
        np.testing.assert_allclose(m.angular_velocity_covariance[[0, 4, 8]],
                                   [math.radians(0.1) ** 2] * 3)


def test_imu_orientation_and_specific_force(voyage: dict) -> None:
    truth = voyage['truth']
    imu = [m for _, m in voyage['bag']['/imu']]
    yaw = np.array([_yaw_enu(m.orientation) for m in imu])
    heading_error = np.array([math.remainder(math.pi / 2 - y - p, 2 * math.pi)
                              for y, p in zip(yaw, truth.psi)])
    assert np.std(heading_error) == pytest.approx(math.radians(0.5), rel=0.1)
    assert abs(np.mean(heading_error)) < math.radians(0.05)
    assert imu[0].orientation_covariance[8] == pytest.approx(math.radians(0.5) ** 2)
    # Level vessel: specific force z is +g (REP-145: gravity reads +9.8 on z up).
    accel_z = np.array([m.linear_acceleration.z for m in imu])
    assert np.mean(accel_z) == pytest.approx(9.8215, abs=0.01)
    # Lateral specific force in FLU is minus the FRD body acceleration over ground.
    accel_y = np.array([m.linear_acceleration.y for m in imu])
    np.testing.assert_allclose(np.mean(accel_y + truth.accel_y), 0.0, atol=0.01)


def test_velocity_is_water_or_ground_referenced(tmp_path: Path) -> None:
    for reference in ('water', 'ground'):
        config = _config(duration=20.0, reference=reference)
        truth = sim.simulate(config)
        path = sim.write_bag(tmp_path / reference, sim.sensor_records(truth, config))
        twists = [m for _, m in _read(path)['/velocity']]
        measured = np.array([[m.twist.twist.linear.x, -m.twist.twist.linear.y]
                             for m in twists])
        u, v = (truth.u_r, truth.v_r) if reference == 'water' else (truth.u, truth.v)
        expected = np.stack([u[::20], v[::20]], axis=-1)
        error = measured - expected
        assert np.all(np.abs(error.mean(axis=0)) < 0.02), reference
        assert np.all(error.std(axis=0) < 0.05), reference
        cov = np.asarray(twists[0].twist.covariance).reshape(6, 6)
        np.testing.assert_allclose(np.diag(cov), [0.03 ** 2] * 3 + [1e6] * 3)
    # In a current, the two references differ by the current in body axes.
    assert np.max(np.abs(truth.u - truth.u_r)) > 0.3


def test_command_line_errors(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    existing = tmp_path / 'exists'
    existing.mkdir()
    assert sim.main([str(existing), '--duration', '2']) == 2
    assert 'exists' in capsys.readouterr().err
    assert sim.main([str(tmp_path / 'x'), '--duration', '0']) == 2
    assert '--duration' in capsys.readouterr().err
    assert sim.main([str(tmp_path / 'y'), '--current', '9', '90']) == 2
    assert sim.main([str(existing), '--duration', '2', '--overwrite']) == 0
    assert 'wrote' in capsys.readouterr().out


# --- log scale, leeway, IMU yaw offset, standstill ------------------------------------------

LEEWAY = math.radians(6.0)
CALIBRATED = {'log_scale': 0.8, 'log_surge_only': True, 'leeway': LEEWAY,
              'imu_yaw_offset': math.pi / 2, 'standstill_start': 50.0, 'standstill_end': 65.0}


def _voyage_bag(tmp_path: Path, name: str, config: sim.VoyageConfig) -> tuple[Any, dict]:
    truth = sim.simulate(config)
    path = sim.write_bag(tmp_path / name, sim.sensor_records(truth, config))
    return truth, _read(path)


@pytest.fixture(scope='module')
def calibrated(tmp_path_factory: pytest.TempPathFactory) -> dict:
    """
    Simulate 90 s with every new effect in still water, and the same without the sensor ones.

    Same seed and the same standstill, so both draw the same noise and the hull moves alike:
    their differences are the log scale, the leeway and the yaw offset alone.
    """
    path = tmp_path_factory.mktemp('calibrated')
    config = _config(duration=90.0, current_speed=0.0, **CALIBRATED)
    plain = _config(duration=90.0, current_speed=0.0, standstill_start=50.0,
                    standstill_end=65.0)
    truth, bag = _voyage_bag(path, 'calibrated', config)
    plain_truth, plain_bag = _voyage_bag(path, 'plain', plain)
    return {'config': config, 'truth': truth, 'bag': bag,
            'plain_truth': plain_truth, 'plain_bag': plain_bag}


def _check_truth_angles(bag: dict) -> int:
    """
    Check /truth/course_sideslip against /truth/odometry; return the count of samples at rest.

    Going ahead chi = atan2 of the ground velocity (by scipy) and chi = psi + beta with
    beta = asin(v/U); at rest (U = 0) chi = psi and beta = 0, Fossen's U = 0 convention.
    """
    at_rest = 0
    for (_, odo), (_, cs) in zip(bag['/truth/odometry'], bag['/truth/course_sideslip']):
        assert _stamp_s(odo) == pytest.approx(_stamp_s(cs))
        yaw = _yaw_enu(odo.pose.pose.orientation)
        psi = math.pi / 2 - yaw
        u, v_flu = odo.twist.twist.linear.x, odo.twist.twist.linear.y
        speed = math.hypot(u, v_flu)
        if speed == 0.0:
            at_rest += 1
            assert math.remainder(cs.vector.x - psi, 2 * math.pi) == pytest.approx(0.0, abs=1e-12)
            assert cs.vector.y == 0.0
            continue
        v_enu = Rotation.from_euler('z', yaw).apply([u, v_flu, 0.0])
        chi = math.atan2(v_enu[0], v_enu[1])
        assert math.remainder(cs.vector.x - chi, 2 * math.pi) == pytest.approx(0.0, abs=1e-9)
        assert cs.vector.y == pytest.approx(math.asin(-v_flu / speed), abs=1e-9)
        assert math.remainder(cs.vector.x - (psi + cs.vector.y), 2 * math.pi) == \
            pytest.approx(0.0, abs=1e-9)
    return at_rest


def test_defaults_are_unchanged() -> None:
    config = sim.VoyageConfig()
    assert (config.log_scale, config.log_surge_only, config.leeway, config.imu_yaw_offset,
            config.standstill_window()) == (1.0, False, 0.0, 0.0, None)
    args = sim._parse_args(['out'])
    assert sim.config_from_args(args) == sim.VoyageConfig()


def test_truth_calibration_topic(voyage: dict, calibrated: dict) -> None:
    for bag, expected in ((voyage['bag'], (1.0, 0.0, 0.0)),
                          (calibrated['bag'], (0.8, LEEWAY, math.pi / 2))):
        messages = [m for _, m in bag['/truth/calibration']]
        assert len(messages) == len(bag['/truth/odometry'])
        for m in messages:
            assert m.header.frame_id == 'base_link'
            assert (m.vector.x, m.vector.y, m.vector.z) == expected


def test_log_reads_scale_times_surge_and_surge_only(calibrated: dict) -> None:
    truth = calibrated['truth']
    twists = [m for _, m in calibrated['bag']['/velocity']]
    plain = [m for _, m in calibrated['plain_bag']['/velocity']]
    surge = np.array([m.twist.twist.linear.x for m in twists])
    u_r = truth.u_r[::20]
    moving = u_r > 1.0
    # Reading / true surge is the scale, within the noise (0.03 m/s on >= 1 m/s).
    assert np.mean(surge[moving] / u_r[moving]) == pytest.approx(0.8, abs=0.003)
    # Exactly: the same noise on 0.8 u_r instead of u_r (the hull moves alike in both runs).
    plain_surge = np.array([m.twist.twist.linear.x for m in plain])
    np.testing.assert_allclose(surge - plain_surge, -0.2 * u_r, atol=1e-12)
    # Surge only: sway and heave are zero and unmeasured, as the real NMEA logs publish them.
    for m in twists:
        assert m.twist.twist.linear.y == 0.0 and m.twist.twist.linear.z == 0.0
        np.testing.assert_allclose(np.diag(np.asarray(m.twist.covariance).reshape(6, 6)),
                                   [0.03 ** 2] + [1e6] * 5)


def test_imu_yaw_is_off_by_the_offset(calibrated: dict) -> None:
    truth = calibrated['truth']
    imu = [m for _, m in calibrated['bag']['/imu']]
    plain_imu = [m for _, m in calibrated['plain_bag']['/imu']]
    true_yaw = math.pi / 2 - truth.psi                       # ENU yaw of the true heading
    error = np.array([math.remainder(_yaw_enu(m.orientation) - y - math.pi / 2, 2 * math.pi)
                      for m, y in zip(imu, true_yaw)])
    assert abs(np.mean(error)) < math.radians(0.05)           # the offset, up to the noise
    assert np.std(error) == pytest.approx(math.radians(0.5), rel=0.1)
    # Only the orientation's yaw: the rates and the truth keep the true heading.
    for m, p in zip(imu[::50], plain_imu[::50]):
        assert m.angular_velocity.z == p.angular_velocity.z
    truth_yaw = [_yaw_enu(m.pose.pose.orientation)
                 for _, m in calibrated['bag']['/truth/odometry']]
    np.testing.assert_allclose(np.unwrap(truth_yaw), np.unwrap(true_yaw[::5]), atol=1e-9)


def test_any_yaw_offset_wraps() -> None:
    for offset in (-math.pi / 2, 3.0, 2 * math.pi + 0.1):
        config = _config(duration=1.0, imu_yaw_offset=offset)
        truth = sim.simulate(config)
        store = get_typestore(Stores.ROS2_JAZZY)
        imu = [store.deserialize_cdr(r.data, sim.TOPICS[r.topic])
               for r in sim.sensor_records(truth, config) if r.topic == '/imu']
        error = [math.remainder(_yaw_enu(m.orientation) - (math.pi / 2 - p) - offset,
                                2 * math.pi) for m, p in zip(imu, truth.psi)]
        assert abs(np.mean(error)) < math.radians(0.2), offset


def test_leeway_adds_sway_through_water(calibrated: dict) -> None:
    truth, plain = calibrated['truth'], calibrated['plain_truth']
    tan_leeway = math.tan(LEEWAY)
    # The hull's own motion is the same; the leeway adds u_r tan(lambda) to the sway.
    np.testing.assert_array_equal(truth.psi, plain.psi)
    np.testing.assert_array_equal(truth.u_r, plain.u_r)
    np.testing.assert_allclose(truth.v_r - plain.v_r, truth.u_r * tan_leeway, atol=1e-12)
    # On the first straight leg (no hull sway) sway / surge through the water is tan(lambda).
    first_leg = truth.t < 0.08 * 90.0
    np.testing.assert_allclose(truth.v_r[first_leg] / truth.u_r[first_leg], tan_leeway,
                               atol=1e-9)
    # ... and the sideslip through the water is the leeway; in still water over ground too.
    cs = np.array([m.vector.y for _, m in calibrated['bag']['/truth/course_sideslip']])
    assert np.mean(cs[first_leg[::5]]) == pytest.approx(math.asin(math.sin(LEEWAY)), abs=1e-9)
    # The position integrates it: drifting to starboard of the plain voyage's track.
    leg = int(np.count_nonzero(first_leg))
    psi = truth.psi[leg]
    offset_n = truth.north[leg] - plain.north[leg]
    offset_e = truth.east[leg] - plain.east[leg]
    sideways = -math.sin(psi) * offset_n + math.cos(psi) * offset_e     # starboard, m
    expected = float(np.sum(0.5 * (truth.u_r[1:leg + 1] + truth.u_r[:leg]))) * 0.01 * tan_leeway
    assert sideways == pytest.approx(expected, rel=1e-3)
    assert sideways > 3.0


def test_leeway_in_the_measured_sway(tmp_path: Path) -> None:
    """Sway / surge of the DVL's water track averages tan(lambda) on the first straight leg."""
    config = _config(duration=50.0, leeway=-LEEWAY)
    truth, bag = _voyage_bag(tmp_path, 'leeway', config)
    twists = [m for _, m in bag['/velocity']]
    first_leg = [m for m in twists if _stamp_s(m) < 0.08 * 50.0]
    ratio = [-m.twist.twist.linear.y / m.twist.twist.linear.x for m in first_leg]
    assert np.mean(ratio) == pytest.approx(math.tan(-LEEWAY), abs=0.005)
    assert _check_truth_angles(bag) == 0


def test_truth_stays_consistent_with_every_effect(calibrated: dict) -> None:
    bag = calibrated['bag']
    at_rest = _check_truth_angles(bag)
    assert at_rest == 15 * 20 + 1     # the whole standstill at 20 Hz, and its end: from rest
    # Positions still integrate the truth's own ground velocity (ENU, trapezoid).
    odometry = [m for _, m in bag['/truth/odometry']]
    positions = np.array([[m.pose.pose.position.x, m.pose.pose.position.y] for m in odometry])
    v_enu = np.array([Rotation.from_euler('z', _yaw_enu(m.pose.pose.orientation)).apply(
        [m.twist.twist.linear.x, m.twist.twist.linear.y, 0.0])[:2] for m in odometry])
    integrated = np.cumsum(0.5 * (v_enu[1:] + v_enu[:-1]) * 0.05, axis=0)
    np.testing.assert_allclose(positions[1:] - positions[0], integrated, atol=0.05)


def test_standstill_in_still_water(calibrated: dict) -> None:
    truth, bag = calibrated['truth'], calibrated['bag']
    start, end = 50.0, 65.0
    inside = (truth.t >= start) & (truth.t < end)
    assert set(np.array(truth.phase)[inside]) == {'standstill'}
    assert 'stopping' in truth.phase
    for values in (truth.u_r, truth.v_r, truth.r, truth.u, truth.v, truth.rudder):
        assert np.all(values[inside] == 0.0)
    assert np.ptp(truth.north[inside]) == 0.0 and np.ptp(truth.east[inside]) == 0.0
    # The log reads its noise only; the fixes stay put; the gyro reads its bias.
    twists = [m for _, m in bag['/velocity'] if start <= _stamp_s(m) < end]
    surge = np.array([m.twist.twist.linear.x for m in twists])
    assert abs(np.mean(surge)) < 0.03 and np.max(np.abs(surge)) < 0.15
    rate = np.array([m.angular_velocity.z for _, m in bag['/imu'] if start <= _stamp_s(m) < end])
    assert np.mean(rate) == pytest.approx(truth.gyro_bias[2], abs=math.radians(0.02))
    # It braked before and gets under way again after.
    assert truth.u_r[int((start - sim.BRAKING_TIME - 0.5) * 100)] > 4.0
    assert truth.u_r[-1] > 2.0


def test_standstill_drifts_with_the_current(tmp_path: Path) -> None:
    config = _config(duration=40.0, standstill_start=15.0, standstill_end=30.0)
    truth, bag = _voyage_bag(tmp_path, 'drift', config)
    inside = (truth.t >= 15.0) & (truth.t < 30.0)
    assert np.all(truth.u_r[inside] == 0.0) and np.all(truth.v_r[inside] == 0.0)
    v_ned = truth.ground_velocity_ned()[inside]
    np.testing.assert_allclose(v_ned[:, 0], truth.current_n[inside], atol=1e-12)
    np.testing.assert_allclose(v_ned[:, 1], truth.current_e[inside], atol=1e-12)
    # Course is the direction the current sets (moving over ground: no U = 0 fallback).
    np.testing.assert_allclose(truth.course()[inside],
                               np.arctan2(truth.current_e, truth.current_n)[inside], atol=1e-9)
    assert _check_truth_angles(bag) == 0


def test_new_effects_are_deterministic() -> None:
    config = _config(duration=30.0, **{**CALIBRATED, 'standstill_start': 12.0,
                                       'standstill_end': 20.0})
    first = sim.sensor_records(sim.simulate(config), config)
    second = sim.sensor_records(sim.simulate(config), config)
    assert _contents(first) == _contents(second)


def test_new_command_line_flags(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    args = sim._parse_args(['out', '--log-scale', '0.8', '--log-surge-only', '--leeway', '6',
                            '--imu-yaw-offset', '90', '--standstill', '50', '65'])
    assert sim.config_from_args(args) == sim.VoyageConfig(
        log_scale=0.8, log_surge_only=True, leeway=math.radians(6.0),
        imu_yaw_offset=math.radians(90.0), standstill_start=50.0, standstill_end=65.0)
    assert sim.main([str(tmp_path / 'ok'), '--duration', '5', '--log-scale', '1.1',
                     '--standstill', '1', '3', '--current', '0', '0']) == 0
    assert 'standstill 1.0 .. 3.0 s' in capsys.readouterr().out
    for bad, name in ((['--log-scale', '0'], '--log-scale'), (['--leeway', '45'], '--leeway'),
                      (['--standstill', '4', '2'], '--standstill'),
                      (['--standstill', '1', '9'], '--standstill'),
                      (['--imu-yaw-offset', 'nan'], '--imu-yaw-offset')):
        assert sim.main([str(tmp_path / 'bad'), '--duration', '5'] + bad) == 2
        assert name in capsys.readouterr().err
    with pytest.raises(ValueError, match='both'):
        sim.validate(sim.VoyageConfig(standstill_start=1.0))


@pytest.mark.parametrize('window', [(0.0, 5.0), (4.0, 10.0), (3.0, 6.0)])
def test_standstill_edges(window: tuple[float, float]) -> None:
    """A standstill from the start, to the end, or closer to the start than the braking."""
    config = _config(duration=10.0, current_speed=0.0, standstill_start=window[0],
                     standstill_end=window[1])
    sim.validate(config)
    truth = sim.simulate(config)
    inside = (truth.t >= window[0]) & (truth.t <= window[1])
    assert np.all(truth.u_r[inside] == 0.0) and np.all(truth.u[inside] == 0.0)
    assert np.all(np.isfinite(truth.accel_x)) and np.all(np.isfinite(truth.north))
    wrapped = np.remainder(truth.course()[inside] - truth.psi[inside] + math.pi, 2 * math.pi)
    np.testing.assert_allclose(wrapped - math.pi, 0.0, atol=1e-12)    # course = heading
    assert np.all(truth.sideslip()[inside] == 0.0)


# --- the fleet's effects: manoeuvres, sensor faults, GNSS alone, the ellipsoid -------------

def test_a_surge_profile_is_followed_with_a_ramped_acceleration() -> None:
    """Knots (t, u_r): the surge passes through them; its acceleration ramps over 1 s."""
    config = _config(duration=40.0, helm='straight',
                     surge_profile=((0.0, 10.0), (10.0, 10.0), (13.0, 0.0), (20.0, 0.0),
                                    (23.0, 14.7)))
    truth = sim.simulate(config)
    at = {t: truth.u_r[int(round(t * 100))] for t in (5.0, 11.5, 16.0, 21.5, 30.0)}
    assert at[5.0] == pytest.approx(10.0, abs=1e-9)
    assert at[11.5] == pytest.approx(5.0, abs=0.05)
    assert at[16.0] == pytest.approx(0.0, abs=1e-9)
    assert at[21.5] == pytest.approx(7.35, abs=0.05)
    assert at[30.0] == pytest.approx(14.7, abs=1e-9)
    accel = np.diff(truth.u_r) / np.diff(truth.t)
    assert accel.max() == pytest.approx(4.9, abs=0.05)       # 0.5 g, reached, never exceeded
    assert accel.min() == pytest.approx(-10.0 / 3.0, abs=0.05)
    assert np.abs(np.diff(accel)).max() / 0.01 < 4.95        # jerk ≤ 0.5 g per second
    np.testing.assert_allclose(truth.accel_x[1000:1100], accel[1000:1100], atol=0.05)


def test_log_outage_and_freeze_windows(tmp_path: Path) -> None:
    """No log message in an outage; a frozen log repeats its first reading of the window."""
    config = _config(duration=30.0, log_outage=(5.0, 5.0), log_freeze=(15.0, 10.0))
    bag = _voyage_bag(tmp_path, 'log', config)[1]
    twists = [(_stamp_s(m), m.twist.twist.linear.x) for _, m in bag['/velocity']]
    assert not [t for t, _ in twists if 5.0 <= t < 10.0]
    frozen = [x for t, x in twists if 15.0 <= t < 25.0]
    assert len(frozen) == 50 and len(set(frozen)) == 1
    assert len({x for t, x in twists if 25.0 <= t}) > 10


def test_a_frozen_compass_holds_its_orientation_and_the_gyro_goes_on(tmp_path: Path) -> None:
    """In the window the orientation is the first sample's; the rates keep turning."""
    config = _config(duration=60.0, compass_freeze=(30.0, 10.0))
    truth, bag = _voyage_bag(tmp_path, 'compass', config)
    imu = [(_stamp_s(m), m) for _, m in bag['/imu']]
    held = [m for t, m in imu if 30.0 <= t < 40.0]
    assert len({(m.orientation.z, m.orientation.w) for m in held}) == 1
    turned = np.ptp(truth.psi[3000:4000])
    assert turned > math.radians(10.0)                       # the turning circle goes on
    assert len({m.angular_velocity.z for m in held}) > 100


def test_outlier_fixes_are_that_share_and_that_far(tmp_path: Path) -> None:
    """2 % of the fixes displaced by 60 m in random directions; the others as before."""
    base = _config(duration=200.0, outage=(0.0, 0.0))
    config = dataclasses.replace(base, fix_outlier_fraction=0.02, fix_outlier_distance=60.0)
    clean = sim.sensor_readings(sim.simulate(base), base)
    dirty = sim.sensor_readings(sim.simulate(config), config)
    lat0, lon0, h0 = base.origin
    jumps = []
    for a, b in zip(clean.fix_llh, dirty.fix_llh):
        n, e, _ = pymap3d.geodetic2ned(b[0], b[1], b[2], a[0], a[1], a[2])
        jumps.append(math.hypot(n, e))
    jumps = np.array(jumps)
    moved = jumps > 1e-6
    assert 0.01 < moved.mean() < 0.03
    np.testing.assert_allclose(jumps[moved], 60.0, rtol=1e-3)


def test_a_heading_only_compass_at_its_own_rate() -> None:
    """compass_rate: orientation at that rate, level, no rate and no acceleration (-1)."""
    config = _config(duration=20.0, imu_rate=90.0, fix_rate=9.0, velocity_rate=9.0,
                     truth_rate=9.0, compass_rate=4.5)
    readings = sim.sensor_readings(sim.simulate(config), config)
    assert len(readings.imu_steps) == int(20.0 * 4.5) + 1
    orientation, rate, accel = readings.imu_covariances
    assert orientation[0] == orientation[4] == 1e3 and rate[0] == accel[0] == -1.0
    for x, y, z, w in readings.imu_orientation:
        assert abs(x) < 1e-12 and abs(y) < 1e-12                 # heading only


def test_fixes_lie_on_the_ellipsoid_far_from_the_origin() -> None:
    """10 km from the start the fixes' heights are the surface's, not the tangent plane's."""
    config = _config(duration=700.0, helm='straight', speed=15.0, current_speed=0.0,
                     outage=(0.0, 0.0), fix_sigma_up=0.0)
    readings = sim.sensor_readings(sim.simulate(config), config)
    heights = np.array([llh[2] for llh in readings.fix_llh])
    np.testing.assert_allclose(heights, config.origin[2] + config.antenna[2], atol=1e-6)
    truth = sim.simulate(config)
    lat, lon, h = sim.surface_llh(truth.north[-1:], truth.east[-1:],
                                  (math.radians(config.origin[0]),
                                   math.radians(config.origin[1]), config.origin[2]))
    n, e, d = pymap3d.geodetic2ned(math.degrees(lat[0]), math.degrees(lon[0]), h[0],
                                   *config.origin)
    assert math.hypot(n, e) > 10e3
    assert d == pytest.approx((n * n + e * e) / (2 * 6_371_000.0), rel=0.01)   # below the plane
    np.testing.assert_allclose((n, e), (truth.north[-1], truth.east[-1]), atol=1e-3)


def test_fleet_command_line_flags(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """Every fleet effect has its flag, checked, and main() says which are on."""
    args = sim._parse_args(['out', '--helm', 'figure8', '--surge-profile', '0:5', '10:2',
                            '--log-outage', '5', '3', '--log-freeze', '20', '4',
                            '--compass-freeze', '1', '2', '--fix-outliers', '0.02', '60',
                            '--compass-rate', '5'])
    assert sim.config_from_args(args) == sim.VoyageConfig(
        helm='figure8', surge_profile=((0.0, 5.0), (10.0, 2.0)), log_outage=(5.0, 3.0),
        log_freeze=(20.0, 4.0), compass_freeze=(1.0, 2.0), fix_outlier_fraction=0.02,
        fix_outlier_distance=60.0, compass_rate=5.0)
    assert sim.main([str(tmp_path / 'ok'), '--duration', '5', '--log-freeze', '1', '2']) == 0
    assert 'log freeze 1.0 .. 3.0 s' in capsys.readouterr().out
    for bad, name in ((['--surge-profile', '3:x'], '--surge-profile'),
                      (['--surge-profile', '3:1', '2:1'], '--surge-profile'),
                      (['--fix-outliers', '0.9', '60'], '--fix-outliers')):
        assert sim.main([str(tmp_path / 'bad'), '--duration', '5'] + bad) == 2
        assert name in capsys.readouterr().err
    with pytest.raises(SystemExit):                 # argparse refuses an unknown helm
        sim.main([str(tmp_path / 'bad'), '--helm', 'zigzag'])
    assert '--helm' in capsys.readouterr().err

"""
Marine logs read whole, real and simulated, good and damaged.

The given NMEA 0183 logs against their bags, the simulator's own logs and captures against
its messages and truth, and malformed logs.

The given logs (``../shared/data``; skipped where it is absent) must give the messages of
their bags: the same messages, values to the last bit but float rounding, and the same
stamps to 1 us (the bags' stamps went through a float), but in the second after a repeated
RMC time in the IJsselmeer log, where the two bags differ between themselves (see
:func:`test_given_logs_give_the_messages_of_their_bags`). The simulator-based tests always
run: a voyage written by :mod:`vessel_kinematics.marine.writer` and read back gives its
messages to the formats' resolution, and replayed it scores against the truth as the
simulator's own bag does.
"""

from __future__ import annotations

import gzip
import math
import os
from pathlib import Path
import struct
from typing import Any, Callable

from hypothesis import given, HealthCheck, settings, strategies as st
import numpy as np
import pytest
from vessel_kinematics import marine
from vessel_kinematics.core import frames, quaternion
from vessel_kinematics.marine import files as marine_files, messages, nmea2000, pcap, writer
from vessel_kinematics.marine.records import KNOT, SKIP_REASONS
from vessel_kinematics.tools import bags, evaluate, replay
from vessel_kinematics.tools.sim_bag import records, TOPICS
from vessel_kinematics.tools.sim_model import simulate, VoyageConfig
from vessel_kinematics.tools.sim_sensors import sensor_readings

NS = 1_000_000_000
DEG = math.pi / 180.0
TRUTH_TOPICS = {t: ty for t, ty in TOPICS.items() if t.startswith('/truth')}


def _stamp(msg: Any) -> int:
    return msg.header.stamp.sec * NS + msg.header.stamp.nanosec


def _read_log(path: Path, **kwargs: Any) -> tuple[marine.MarineLog, dict[str, list]]:
    log = marine.open_log(path, **kwargs)
    out: dict[str, list] = {topic: [] for topic in marine.TOPICS}
    for connection, arrival, raw in log.messages():
        out[connection.topic].append((arrival, log.deserialize(raw, connection.msgtype)))
    return log, out


#: The topics the given bags hold: a log's ``/vel`` is its ``/gnss/cog_sog`` again, checked
#: against it (:func:`_check_receiver_velocity`).
BAG_TOPICS = [t for t in marine.TOPICS if t != messages.GNSS_VELOCITY_TOPIC]


def _check_receiver_velocity(got: dict[str, list]) -> None:
    """Check that a log's ``/vel`` is its COG/SOG as an ENU velocity, message for message."""
    cog_sog, vel = got['/gnss/cog_sog'], got[messages.GNSS_VELOCITY_TOPIC]
    assert len(vel) == len(cog_sog) > 0
    for (arrival, a), (arrival_v, v) in zip(cog_sog, vel):
        assert (arrival_v, _stamp(v), v.header.frame_id) == (arrival, _stamp(a), 'gnss')
        chi, sog = a.vector.x, a.vector.y
        assert (v.twist.linear.x, v.twist.linear.y, v.twist.linear.z) == pytest.approx(
            (sog * math.sin(chi), sog * math.cos(chi), 0.0), abs=1e-12)


def _euler(msg: Any) -> tuple[float, float, float]:
    o = msg.orientation
    return quaternion.q2euler(frames.q_nb_from_ros([o.x, o.y, o.z, o.w]))


# ---------------------------------------------------------------------------------------------
# The given logs and their bags


GIVEN = {
    'ijsselmeer': ('sailboat_ijsselmeer_nmea0183.log', 'sailboat_ijsselmeer',
                   {'/fix': 'GGA (GP)', '/imu': 'HDG (SD)', '/speed_log': 'VHW (SD)',
                    '/gnss/cog_sog': 'RMC (GP)'}),
    'geneva': ('sailboat_geneva_nmea0183.log', 'sailboat_geneva',
               {'/fix': 'RMC (II)', '/imu': 'HDG (II)', '/speed_log': 'VHW (II)',
                '/gnss/cog_sog': 'RMC (II)'}),
}


def _values(topic: str, msg: Any) -> np.ndarray:
    if topic == '/fix':
        return np.array([msg.latitude, msg.longitude, msg.altitude, *msg.position_covariance,
                         msg.position_covariance_type, msg.status.status, msg.status.service])
    if topic == '/imu':
        return np.array([*msg.orientation_covariance, msg.angular_velocity.x,
                         msg.angular_velocity.y, msg.angular_velocity.z,
                         *msg.angular_velocity_covariance, *msg.linear_acceleration_covariance])
    if topic == '/speed_log':
        t = msg.twist.twist
        return np.array([t.linear.x, t.linear.y, t.linear.z, *msg.twist.covariance])
    return np.array([msg.vector.x, msg.vector.y, msg.vector.z])


@pytest.fixture(scope='module', params=sorted(GIVEN))
def given_log(request: pytest.FixtureRequest, shared_data: Path) -> tuple:
    """Return (name, the log's reader, its messages by topic, the bag's messages by topic)."""
    name = request.param
    log_name, bag_name, _ = GIVEN[name]
    log, from_log = _read_log(shared_data / log_name)
    from_bag = bags.read_topics([shared_data / bag_name], marine.TOPICS)
    return name, log, from_log, from_bag


def test_given_logs_give_the_messages_of_their_bags(given_log: tuple) -> None:
    name, log, from_log, from_bag = given_log
    assert log.format == 'nmea0183'
    assert {t: log.counts.sources[t] for t in BAG_TOPICS} == GIVEN[name][2]
    assert log.counts.sources['clock'] == GIVEN[name][2]['/gnss/cog_sog']
    assert log.counts.sources['/vel'] == GIVEN[name][2]['/gnss/cog_sog']
    _check_receiver_velocity(from_log)
    counts = {t: (len(from_bag[t]), len(from_log[t])) for t in BAG_TOPICS}
    print(f'\n{name}: messages (bag, log) {counts}')
    print(log.counts.text())
    for topic in BAG_TOPICS:
        bag = [m for _, m in from_bag[topic]]
        got = [(arrival, m) for arrival, m in from_log[topic]]
        if name == 'ijsselmeer' and topic == '/gnss/cog_sog':
            # The IJsselmeer bag keeps the RMC repeating 09:49:45 (a second /gnss/cog_sog at
            # that stamp), the Geneva bag drops its 34 repeats: a repeated time is a repeat
            # here, in both.
            stamps = [_stamp(m) for m in bag]
            repeated = [i for i in range(1, len(bag)) if stamps[i] == stamps[i - 1]]
            assert len(repeated) == 1
            del bag[repeated[0]]
        assert len(bag) == len(got), topic
        dt = np.array([(_stamp(m) - _stamp(b)) * 1e-9 for b, (_, m) in zip(bag, got)])
        late = np.flatnonzero(np.abs(dt) > 1e-6)
        if name == 'ijsselmeer':
            # The second after the repeated RMC: the bag spaces the lines from the repeat,
            # this reader over the whole second from the first one.
            window = (1_534_758_585 * NS, 1_534_758_586 * NS)
            assert all(window[0] <= _stamp(got[i][1]) < window[1] for i in late)
            assert len(late) <= 14 and np.abs(dt).max() <= 0.25
        else:
            assert late.size == 0
        assert all(arrival == _stamp(m) for arrival, m in got)   # no logger times
        values = np.array([_values(topic, m) for _, m in got])
        expected = np.array([_values(topic, b) for b in bag])
        np.testing.assert_allclose(values, expected, rtol=1e-12, atol=1e-12, equal_nan=True)
        if topic == '/imu':      # the same rotation (the quaternions may differ in sign)
            dots = [abs(a.orientation.x * b.orientation.x + a.orientation.y * b.orientation.y
                        + a.orientation.z * b.orientation.z + a.orientation.w * b.orientation.w)
                    for (_, a), b in zip(got, bag)]
            assert min(dots) == pytest.approx(1.0, abs=1e-12)
        frame_ids = {m.header.frame_id for _, m in got} | {b.header.frame_id for b in bag}
        assert len(frame_ids) == 1
        print(f'  {topic}: {len(got)} messages, |stamp difference| max {np.abs(dt).max():.4f} s'
              f' ({late.size} over 1 us)')


def test_given_logs_skip_only_what_they_cannot_time(given_log: tuple) -> None:
    name, log, _, _ = given_log
    assert set(log.counts.skipped) <= {'untimed', 'repeated', 'not_available'}
    assert log.counts.skipped['repeated'] == (1 if name == 'ijsselmeer' else 34)


def test_a_dual_speed_log_reads_as_the_speed_log(shared_data: Path, tmp_path: Path) -> None:
    """
    A VBW's longitudinal water speed is the speed log, as a VHW's speed is.

    The Geneva log with every VHW written as the VBW of the same speed (water status A, V
    where VHW has none) gives the bag's /speed_log, stamps (to 1 us) and values, from ``VBW (II)``.
    """
    lines = (shared_data / GIVEN['geneva'][0]).read_text().splitlines()
    for i, line in enumerate(lines):
        if line[3:6] == 'VHW':
            knots = line.split('*')[0].split(',')[5]
            lines[i] = _checksummed(f'IIVBW,{knots},,{"A" if knots else "V"},,,V')
    assert sum(line[3:6] == 'VBW' for line in lines) > 4000
    path = tmp_path / 'geneva_vbw.log'
    path.write_text('\n'.join(lines) + '\n')
    log, got = _read_log(path)
    assert log.counts.sources['/speed_log'] == 'VBW (II)'
    bag = [m for _, m in bags.read_topics([shared_data / GIVEN['geneva'][1]],
                                          ['/speed_log'])['/speed_log']]
    stamps = np.array([_stamp(m) for _, m in got['/speed_log']])
    assert len(stamps) == len(bag)
    assert np.abs(stamps - [_stamp(m) for m in bag]).max() <= 1000   # the bag's float stamps
    np.testing.assert_allclose([_values('/speed_log', m) for _, m in got['/speed_log']],
                               [_values('/speed_log', m) for m in bag], rtol=1e-12, atol=1e-12)


# ---------------------------------------------------------------------------------------------
# The simulator's logs and captures


@pytest.fixture(scope='module')
def voyage() -> tuple[list, list]:
    """Return a 60 s voyage with a GNSS outage: records and (topic, stamp, message)."""
    config = VoyageConfig(duration=60.0, imu_rate=20.0, truth_rate=20.0, log_surge_only=True,
                          outage=(35.0, 6.0))
    recs = records(sensor_readings(simulate(config), config))
    store = messages.typestore()
    items = [(r.topic, r.stamp_ns, store.deserialize_cdr(r.data, TOPICS[r.topic]))
             for r in recs]
    return recs, items


def _inputs(items: list, topic: str) -> list:
    return [(stamp, msg) for t, stamp, msg in items if t == topic]


def _paired(sent: list, back: list, value: Any) -> list[tuple[tuple, tuple]]:
    """
    Pair the messages read back with those sent, in order: the first or the last may be lost.

    Which one is told by ``value(msg)`` (a heading, a speed), not by the stamps: an NMEA 0183
    log's spacing moves them by as much as an IMU period.
    """
    assert len(sent) - 1 <= len(back) <= len(sent)
    if len(back) == len(sent):
        return list(zip(sent, back))

    def cost(pairs: Any) -> float:
        return sum(abs(value(a) - value(b)) for (_, a), (_, b) in pairs)

    first, last = list(zip(sent[1:], back)), list(zip(sent, back))
    return first if cost(first) < cost(last) else last


def _check_round_trip(items: list, got: dict[str, list], *, stamp_tolerance: float,
                      tilt: bool, exact_position: bool) -> None:
    """Compare what a log gave back with the voyage's messages, at the formats' resolution."""
    # fixes: by stamp (129025 has no no-fix; the first fix of an NMEA 0183 log is untimed)
    fixes = _inputs(items, '/fix')
    out = got['/fix']
    with_fix = sum(m.status.status >= 0 for _, m in fixes)
    assert with_fix - 1 <= len(out) <= len(fixes)
    by_time = {round(_stamp(m) * 1e-9, 1): m for _, m in out}
    compared = 0
    for stamp, msg in fixes:
        back = by_time.get(round(stamp * 1e-9, 1))
        if back is None:            # no 129025 without a fix; an NMEA 0183 log's last GGA
            assert msg.status.status < 0 or stamp == fixes[-1][0]
            continue
        compared += 1
        assert abs(_stamp(back) - stamp) <= stamp_tolerance * NS
        assert back.status.status == msg.status.status
        if msg.status.status < 0:
            assert math.isnan(back.latitude)
            continue
        north = (back.latitude - msg.latitude) * 111_320.0
        east = (back.longitude - msg.longitude) * 111_320.0 * math.cos(msg.latitude * DEG)
        assert math.hypot(north, east) < 0.01                        # 1 cm
        if exact_position:                                           # GGA: height and HDOP
            assert back.altitude == pytest.approx(msg.altitude, abs=1e-3)
            assert list(back.position_covariance) == pytest.approx(
                list(msg.position_covariance), rel=1e-3)
    assert compared >= len(fixes) - 8
    # headings, attitude, rates: in order (the lines after an NMEA 0183 log's last time lost)
    imus = _paired(_inputs(items, '/imu'), got['/imu'], lambda m: math.cos(_euler(m)[2]))
    for (stamp, msg), (_, back) in imus:
        assert abs(_stamp(back) - stamp) <= stamp_tolerance * NS
        phi, theta, psi = _euler(msg)
        phi_b, theta_b, psi_b = _euler(back)
        assert abs(math.remainder(psi_b - psi, 2 * math.pi)) < 0.006 * DEG
        if tilt:
            assert (phi_b, theta_b) == pytest.approx((phi, theta), abs=0.006 * DEG)
        else:          # a heading sentence: roll and pitch unknown
            assert list(back.orientation_covariance[[0, 4]]) == [1e3, 1e3]
        # d psi / dt of the body rates, published as the ENU yaw rate
        assert back.angular_velocity.z == pytest.approx(msg.angular_velocity.z, abs=0.01 * DEG)
    # speed through water: in order
    logs = _paired(_inputs(items, '/velocity'), got['/speed_log'],
                   lambda m: m.twist.twist.linear.x)
    for (stamp, msg), (_, back) in logs:
        assert abs(_stamp(back) - stamp) <= stamp_tolerance * NS
        assert back.twist.twist.linear.x == pytest.approx(msg.twist.twist.linear.x, abs=0.006)
    # the receiver's COG/SOG: the truth's velocity at a fix (the writer takes the latest truth
    # within 60 ms of it)
    truth = [(stamp, writer.course_of(msg)) for stamp, msg in _inputs(items, '/truth/odometry')]
    cog_sog = got['/gnss/cog_sog']
    assert len(cog_sog) >= len(fixes) - 15
    _check_receiver_velocity(got)
    for _, back in cog_sog:
        errors = [(abs(math.remainder(back.vector.x - c.cog, 2 * math.pi)),
                   abs(back.vector.y - c.sog)) for t, c in truth
                  if abs(t - _stamp(back)) <= 0.06 * NS + stamp_tolerance * NS]
        assert min(errors) <= (0.006 * DEG, 0.006)


@pytest.mark.parametrize('heading, logger_times', [
    ('HDT', False), ('HDT', True), ('HDG', False), ('PASHR', True), ('PSAT', True)])
def test_nmea0183_logs_of_the_simulator_round_trip(voyage: tuple, tmp_path: Path,
                                                   heading: str, logger_times: bool) -> None:
    _, items = voyage
    path = writer.write_nmea0183(tmp_path / 'voyage.txt', items, heading=heading,
                                 variation_deg=-7.5, logger_times=logger_times)
    log, got = _read_log(path)
    assert log.format == 'nmea0183' and log.counts.sources['/imu'].startswith(heading)
    assert set(log.counts.skipped) == {'untimed'}
    assert log.counts.notes == []                        # HDG's variation was applied
    # With logger times the stamps are exact (ms); without, the lines between two RMCs
    # (5 Hz) are spaced evenly, within a few lines of their time.
    _check_round_trip(items, got, stamp_tolerance=0.0 if logger_times else 0.1,
                      tilt=heading in ('PASHR', 'PSAT'), exact_position=True)
    assert all(arrival == _stamp(m) for arrival, m in got['/imu'])


@pytest.mark.parametrize('fmt', sorted(nmea2000.CAPTURE_FORMATS))
def test_nmea2000_captures_of_the_simulator_round_trip(voyage: tuple, tmp_path: Path,
                                                       fmt: str) -> None:
    _, items = voyage
    path = writer.write_nmea2000(tmp_path / 'voyage.log', items, fmt=fmt, heading_pgn=True,
                                 variation_deg=2.0)
    log, got = _read_log(path)
    assert log.format == f'nmea2000/{fmt}'
    assert log.counts.sources == {
        '/fix': 'PGN 129025 (source 1)', '/imu': 'PGN 127257 (source 2)',
        '/speed_log': 'PGN 128259 (source 3)', '/gnss/cog_sog': 'PGN 129026 (source 1)',
        '/vel': 'PGN 129026 (source 1)', '/imu attitude': 'PGN 127257 (source 2)',
        '/imu rate': 'PGN 127251 (source 2)'}
    assert log.counts.skipped == {}
    assert log.counts.sentences['129029'] == len(_inputs(items, '/fix'))   # reassembled
    _check_round_trip(items, got, stamp_tolerance=0.0, tilt=True, exact_position=False)
    if fmt in ('actisense', 'ydraw'):               # times of day: the date of PGN 126992
        assert any(n.startswith('capture times put on UTC by PGN 126992') for n in
                   log.counts.notes)


@pytest.mark.parametrize('fmt', ['canboat', 'ydraw', 'ikonvert'])
def test_a_capture_in_signal_ks_data_log_reads_as_the_capture(
        voyage: tuple, tmp_path: Path, fmt: str) -> None:
    # Signal K server's data log (skserver-raw_*.log) writes each gateway line after its
    # receipt time and the provider's kind, beside Signal K deltas and NMEA 0183 of other
    # providers: the capture's own lines read as they do alone, the rest is skipped.
    _, items = voyage
    path = writer.write_nmea2000(tmp_path / 'voyage.log', items, fmt=fmt, heading_pgn=True,
                                 variation_deg=2.0)
    lines = path.read_text().splitlines()
    wrapped = []
    for i, line in enumerate(lines):
        received = 1_471_172_400_000 + 10 * i
        wrapped.append(f'{received};A;{line}')
        if i % 50 == 0:
            wrapped.append(f'{received};I;{{"updates":[{{"values":[{{"path":"a","value":1}}]}}]}}')
            wrapped.append(f'{received};N;$IIMTW,12.5,C*1D')
    sk = tmp_path / 'skserver-raw_2016-08-14T11.log'
    sk.write_text('\n'.join(wrapped) + '\n')
    alone, want = _read_log(path)
    log, got = _read_log(sk)
    assert log.format == alone.format == f'nmea2000/{fmt}'
    assert log.counts.sources == alone.counts.sources
    assert log.counts.skipped == {'not_nmea': 2 * len(range(0, len(lines), 50))}
    for topic, wanted in want.items():
        assert len(got[topic]) == len(wanted) > 0, topic
        assert [a for a, _ in got[topic]] == [a for a, _ in wanted], topic


def test_a_pcan_view_trace_written_by_python_can_reads_back(
        voyage: tuple, tmp_path: Path) -> None:
    # An independent writer of PEAK's trace format (python-can's TRCWriter: version 2.1, times
    # in ms since the trace began, its header of ';' lines): the voyage's CAN frames come back
    # as the simulator sent them, put on UTC by the capture's PGN 126992.
    can = pytest.importorskip('can')
    _, items = voyage
    path = tmp_path / 'voyage.trc'
    trace = can.TRCWriter(str(path))
    for frame in writer.nmea2000_frames(items, fmt='pcan'):
        trace.on_message_received(can.Message(
            timestamp=frame.time_ns * 1e-9, is_extended_id=True, data=frame.data,
            arbitration_id=nmea2000.can_id(frame.priority, frame.pgn, frame.source,
                                           frame.destination)))
    trace.stop()
    log, got = _read_log(path)
    assert log.format == 'nmea2000/pcan'
    assert set(log.counts.skipped) <= {'not_nmea'}       # nothing but its header
    assert any(n.startswith('capture times put on UTC by PGN 126992') for n in log.counts.notes)
    _check_round_trip(items, got, stamp_tolerance=2e-6, tilt=True, exact_position=False)


@pytest.mark.parametrize('fmt', ['nmea0183', 'canboat', 'pcap', 'ebl'])
def test_a_gzipped_log_reads_as_the_log(voyage: tuple, tmp_path: Path, fmt: str) -> None:
    # Told by its content (RFC 1952's magic), whatever its name; cut short (copied while its
    # logger wrote it), it reads up to where it ends.
    _, items = voyage
    if fmt == 'nmea0183':
        path = writer.write_nmea0183(tmp_path / 'voyage.log', items, heading='HDT')
    else:
        path = writer.write_nmea2000(tmp_path / 'voyage.log', items, fmt=fmt)
    packed = gzip.compress(path.read_bytes())
    whole, cut = tmp_path / 'voyage.log.gz', tmp_path / 'cut.log'
    whole.write_bytes(packed)
    cut.write_bytes(packed[:len(packed) // 2])
    plain, want = _read_log(path)
    log, got = _read_log(whole)
    assert log.format == plain.format and log.counts == plain.counts
    for topic in want:
        assert [(a, bytes(bags.serialize(m))) for a, m in got[topic]] == [
            (a, bytes(bags.serialize(m))) for a, m in want[topic]], topic
    half, part = _read_log(cut)
    assert half.format == plain.format
    for topic in want:
        assert len(part[topic]) < len(want[topic]) or not want[topic]
        assert [a for a, _ in part[topic]] == [a for a, _ in want[topic]][:len(part[topic])]


def test_a_gzip_file_of_several_members_or_damaged_reads_up_to_its_end(tmp_path: Path) -> None:
    # gzip writes a file written in parts as several members, and what follows the damage
    # of a damaged one cannot be read: the content up to there comes back.
    path = tmp_path / 'parts.gz'
    one, two = b'$GPGGA,1\r\n' * 5000, b'$GPGGA,2\r\n' * 5000
    path.write_bytes(gzip.compress(one) + gzip.compress(two))
    assert b''.join(marine_files.chunks(path, 1000)) == one + two
    packed = bytearray(gzip.compress(one + two))
    packed[len(packed) // 2] ^= 0xFF
    path.write_bytes(packed)
    got = b''.join(marine_files.chunks(path))
    assert (one + two).startswith(got) and len(got) < len(one + two)


def _pcap_with(tmp_path: Path, items: list, name: str, shift_ns: int = 0,
               during: tuple[float, float] = (0.0, 0.0)) -> Path:
    """Write the voyage's pcap capture, its frames of ``during`` (s from its start) shifted."""
    captured = list(writer.nmea2000_frames(items, fmt='pcap'))
    start, end = (captured[0].time_ns + round(s * NS) for s in during)
    path = tmp_path / name
    path.write_bytes(b''.join(pcap.packets(
        nmea2000.Frame(f.time_ns + shift_ns, f.time_kind, f.priority, f.pgn, f.source,
                       f.destination, f.data, f.whole) if start <= f.time_ns < end else f
        for f in captured)))
    return path


def test_a_capture_glitch_of_frames_stamped_days_early_is_skipped(
        voyage: tuple, tmp_path: Path) -> None:
    # canboat's can0-1.pcap (a SocketCAN capture of a moored yacht) holds 0.4 s of frames
    # stamped 13.9 days early among frames in order: they are skipped as time_jump, and the
    # replay neither re-initialises nor hears a sensor come back after 13.9 days.
    _, items = voyage
    clean = _pcap_with(tmp_path, items, 'clean.pcap')
    glitched = _pcap_with(tmp_path, items, 'glitched.pcap', -1_197_905 * NS, (20.0, 20.4))
    _, want = _read_log(clean)
    log, got = _read_log(glitched)
    assert log.format == 'nmea2000/pcap'
    assert log.counts.skipped['time_jump'] > 20
    for topic in marine.TOPICS:                # the messages of those 0.4 s are gone, no other
        kept = {a for a, _ in got[topic]}
        assert kept <= {a for a, _ in want[topic]}
        assert len(kept) >= len(want[topic]) - 10
    out = tmp_path / 'out'
    summary = replay.run(glitched, out, replay.load_params(None), [], progress=False,
                         accuracy=False)
    assert summary.resets == 0


def test_a_capture_clock_set_back_is_followed_after_ten_seconds(
        voyage: tuple, tmp_path: Path) -> None:
    # An hour back from 20 s on, and it stays back: the frames of the first 10 s after the
    # step are skipped (a glitch would have ended by then), and the rest follow the new clock.
    _, items = voyage
    back = -3600 * NS
    log, got = _read_log(_pcap_with(tmp_path, items, 'set_back.pcap', back, (20.0, 1e9)))
    start = got['/fix'][0][0]
    fixes = [a - start for a, _ in got['/fix']]
    after = [t for t in fixes if t < 0]
    assert after and min(after) >= back + 29 * NS and max(after) <= back + 60 * NS
    assert [t for t in fixes if t >= 0][-1] < 20 * NS
    assert log.counts.skipped['time_jump'] > 0


def test_isolated_far_future_stamps_are_refused_never_the_capture_s_time(
        voyage: tuple, tmp_path: Path) -> None:
    # A fuzzed canboat capture: 10 of 15,000 lines stamped 9999-12-31 had made 9999 the
    # capture's newest time, and 7000 good frames were skipped as time_jump after it. Each
    # such frame, the first one of the capture too, is refused alone; the rest keep theirs.
    _, items = voyage
    clean = writer.write_nmea2000(tmp_path / 'clean.canboat', items, fmt='canboat')
    lines = clean.read_text().splitlines()
    glitched = [0, 200, 900, 1500]
    for i in glitched:
        lines[i] = '9999-12-31T23:59:59.000Z' + lines[i][lines[i].index(','):]
    path = tmp_path / 'glitched.canboat'
    path.write_text('\n'.join(lines) + '\n')
    _, want = _read_log(clean)
    log, got = _read_log(path)
    assert log.counts.skipped['time_jump'] == len(glitched)
    assert log.counts.skipped['bad_time'] == 0
    for topic in marine.TOPICS:
        kept = {a for a, _ in got[topic]}
        assert kept <= {a for a, _ in want[topic]}
        assert len(kept) >= len(want[topic]) - len(glitched)


@pytest.mark.parametrize('days', [0, 0xFFFC, 11_323], ids=['1970', '2149', '2001'])
def test_one_wrong_system_time_does_not_date_a_capture(voyage: tuple, tmp_path: Path,
                                                       days: int) -> None:
    # The first PGN 126992 alone had dated a capture of times of day: with date 0 (a receiver
    # before its fix) the whole capture was stamped 1970, with 2149 nothing could be stamped.
    # The median of the GNSS times dates it, those no GNSS time can be left out.
    _, items = voyage
    clean = writer.write_nmea2000(tmp_path / 'clean.actisense', items, fmt='actisense')
    lines = clean.read_text().splitlines()
    first = next(i for i, line in enumerate(lines) if line.split()[2] == '1F010')
    time_, address, pgn, data = lines[first].split()
    date = days.to_bytes(2, 'little').hex()
    lines[first] = f'{time_} {address} {pgn} {data[:4]}{date}{data[8:]}'
    path = tmp_path / 'wrong_date.actisense'
    path.write_text('\n'.join(lines) + '\n')
    _, want = _read_log(clean)
    _, got = _read_log(path)
    for topic in want:
        assert [a for a, _ in got[topic]] == [a for a, _ in want[topic]], topic


def test_one_time_of_day_far_off_does_not_turn_the_capture_s_day(voyage: tuple,
                                                                 tmp_path: Path) -> None:
    # A capture of times of day (Actisense): one frame just over 12 h off had turned the day
    # for every frame after it, so the capture jumped a day in its middle. It is refused alone.
    _, items = voyage
    clean = writer.write_nmea2000(tmp_path / 'clean.actisense', items, fmt='actisense')
    lines = clean.read_text().splitlines()
    i = len(lines) // 2
    h, m, sec = int(lines[i][1:3]), int(lines[i][3:5]), float(lines[i][5:11])
    day_s = h * 3600 + m * 60 + sec
    off = day_s + 43_220 if day_s < 43_180 else day_s - 43_220
    lines[i] = (f'A{int(off // 3600):02d}{int(off // 60 % 60):02d}{off % 60:06.3f}'
                + lines[i][11:])
    path = tmp_path / 'glitch.actisense'
    path.write_text('\n'.join(lines) + '\n')
    _, want = _read_log(clean)
    log, got = _read_log(path)
    assert log.counts.skipped['time_jump'] == 1
    for topic in want:
        kept = [a for a, _ in got[topic]]
        assert set(kept) <= {a for a, _ in want[topic]} and len(kept) >= len(want[topic]) - 1


def _with_rmcs(shared_data: Path, tmp_path: Path, pick: Callable[[list[int]], list[int]],
               edit: Callable[[list[str]], None]) -> tuple[marine.MarineLog, dict, dict]:
    """Return the IJsselmeer log read with the RMCs ``pick`` chooses edited, and the clean."""
    clean = shared_data / GIVEN['ijsselmeer'][0]
    lines = clean.read_text().splitlines()
    for i in pick([i for i, line in enumerate(lines) if line.startswith('$GPRMC')]):
        fields = lines[i][1:lines[i].index('*')].split(',')
        edit(fields)
        lines[i] = _checksummed(','.join(fields))
    path = tmp_path / 'edited.log'
    path.write_text('\n'.join(lines) + '\n')
    log, got = _read_log(path)
    return log, got, _read_log(clean)[1]


@pytest.mark.parametrize('date', ['200899', '200817'], ids=['2099', 'a_year_back'])
def test_times_of_a_wrong_date_among_the_clock_s_are_refused(shared_data: Path, tmp_path: Path,
                                                             date: str) -> None:
    # Every other RMC (the IJsselmeer log's clock) dated wrong: years ahead, or a year back.
    # Each had made the clock step and back again, so every line around it was untimed.
    # Each is refused alone (its course and speed too); every other line keeps a time
    # within a second of the clean log's.
    picked: list[int] = []

    def pick(rmc: list[int]) -> list[int]:
        text = (shared_data / GIVEN['ijsselmeer'][0]).read_text().splitlines()
        times = [text[i].split(',')[1] for i in rmc]
        unique = [i for i, t in zip(rmc, times) if times.count(t) == 1]   # not the repeat
        picked.extend(unique[1:-1:2])
        return picked

    log, got, want = _with_rmcs(shared_data, tmp_path, pick,
                                lambda fields: fields.__setitem__(9, date))
    assert log.counts.skipped['time_jump'] == len(picked)
    assert log.counts.skipped['untimed'] <= 30 and log.counts.skipped['bad_time'] == 0
    for topic in want:
        from_rmc = topic in ('/gnss/cog_sog', messages.GNSS_VELOCITY_TOPIC)
        assert len(got[topic]) == len(want[topic]) - (len(picked) if from_rmc else 0), topic
        if not from_rmc:
            offsets = np.array([a for a, _ in got[topic]]) - [a for a, _ in want[topic]]
            assert np.abs(offsets).max() < NS, topic


def _stick_minute() -> Callable[[list[str]], None]:
    """Return an RMC edit that keeps the minute of the first RMC it edits."""
    minute: list[str] = []

    def edit(fields: list[str]) -> None:
        minute[:] = minute or [fields[1][2:4]]
        fields[1] = fields[1][:2] + minute[0] + fields[1][4:]
    return edit


@pytest.mark.parametrize('fault', ['week_rollover', 'minute_stuck'])
def test_a_receiver_s_clock_fault_keeps_the_log_s_times(shared_data: Path, tmp_path: Path,
                                                        fault: str) -> None:
    # The IJsselmeer log's clock (RMC) as two real receivers' faults have it:
    # - from the 50th RMC on dated 1999-01-04, 1024 weeks early (a receiver past a GPS week
    #   rollover): the log had stepped back 19.6 years (untimed lines, a reset);
    # - its minute stuck for 100 s, as one yacht's receiver had it ("09:48:59" then
    #   "09:48:00" again): each went round had stepped the clock back (a reset a minute).
    # Read 1024 weeks later, or by its seconds, every line keeps the clean log's time.
    if fault == 'week_rollover':
        log, got, want = _with_rmcs(shared_data, tmp_path, lambda rmc: rmc[50:],
                                    lambda fields: fields.__setitem__(9, '040199'))
    else:
        log, got, want = _with_rmcs(shared_data, tmp_path, lambda rmc: rmc[20:120],
                                    _stick_minute())
    assert log.counts.skipped['time_jump'] == 0
    said = 'week rollover' if fault == 'week_rollover' else 'minute stuck'
    assert any(said in note for note in log.counts.notes), log.counts.notes
    for topic in want:
        assert [a for a, _ in got[topic]] == [a for a, _ in want[topic]], topic


def test_a_pcap_record_of_a_garbage_length_is_noted(voyage: tuple, tmp_path: Path) -> None:
    # A record of a garbage length (pcap.Damaged) had stopped the reading, counted as one
    # not_nmea: the reader resumes at the next record, and the summary says where and what
    # it skipped.
    _, items = voyage
    path = _pcap_with(tmp_path, items, 'damaged.pcap')
    data = bytearray(path.read_bytes())
    offset = 24 + 1000 * 32                            # record 1001 (16 + 16 bytes each)
    data[offset + 8:offset + 12] = struct.pack('<I', 0xFFFFFFF0)
    path.write_bytes(data)
    _, want = _read_log(_pcap_with(tmp_path, items, 'clean.pcap'))
    log, got = _read_log(path)
    assert (f'the capture is damaged at byte {offset}: a record 4294967280 bytes long; '
            '32 bytes skipped to the next record') in log.counts.notes
    for topic in want:
        assert len(want[topic]) - 1 <= len(got[topic]) <= len(want[topic]), topic


@pytest.mark.slow
def test_a_capture_of_the_simulator_replays_as_its_bag(voyage: tuple, tmp_path: Path,
                                                       repo: Path) -> None:
    # The navigator on the NMEA 2000 capture scores against the truth as on the voyage's bag.
    recs, items = voyage
    capture = writer.write_nmea2000(tmp_path / 'voyage.n2k', items, fmt='candump')
    log = marine.open_log(capture)
    inputs = [(c.topic, t, raw) for c, t, raw in log.messages()]
    truth = [(r.topic, r.stamp_ns, r.data) for r in recs if r.topic in TRUTH_TOPICS]
    bags.write_bag(tmp_path / 'from_capture', sorted(inputs + truth, key=lambda m: m[1]),
                   {**marine.TOPICS, **TRUTH_TOPICS})
    bags.write_bag(tmp_path / 'voyage', ((r.topic, r.stamp_ns, r.data) for r in recs), TOPICS)
    params = replay.load_params(repo / 'config' / 'demo.yaml')
    scores = {}
    for name, remap in (('voyage', 'velocity:=/velocity'),
                        ('from_capture', 'velocity:=/speed_log')):
        out = tmp_path / f'out_{name}'
        replay.run(tmp_path / name, out, params, [remap], progress=False, accuracy=False)
        scores[name] = evaluate.accuracy(evaluate.load_run(out, fix_topic='/fix'))
        print(f'\n{name}: ' + ', '.join(f'{k} RMS {v.rms:.3f}' for k, v in scores[name].items()
                                        if v is not None))
    for field, margin in (('position', 0.1), ('heading', 0.02 * DEG), ('course', 0.2 * DEG)):
        voyage_rms, capture_rms = scores['voyage'][field].rms, scores['from_capture'][field].rms
        assert capture_rms <= 1.2 * voyage_rms + margin, field


# ---------------------------------------------------------------------------------------------
# Malformed logs


def _checksummed(body: str) -> str:
    checksum = 0
    for c in body:
        checksum ^= ord(c)
    return f'${body}*{checksum:02X}'


def test_malformed_lines_are_counted_and_skipped(voyage: tuple, tmp_path: Path) -> None:
    _, items = voyage
    clean = writer.write_nmea0183(tmp_path / 'clean.nmea', items)
    lines = clean.read_bytes().split(b'\r\n')
    # Corrupt heading lines only (not the clock's RMC): every other line keeps its time.
    targets = [i for i, line in enumerate(lines) if line.startswith(b'$HEHDT')][5:305:30]
    damage = {
        'truncated': lambda s: s[:9],
        'bad checksum': lambda s: s[:-1] + (b'0' if s[-1:] != b'0' else b'1'),
        'junk': lambda s: bytes(range(0, 256, 7)),
        'too long': lambda s: b'$' + b'A' * 5000,
        'field count': lambda s: _checksummed('GPGGA,094736,5251.0094,N').encode(),
        'out of range': lambda s: _checksummed('HEHDT,400.0,T').encode(),
        'not a number': lambda s: _checksummed('HEHDT,4O.0,T').encode(),
        'empty value': lambda s: _checksummed('HEHDT,,T').encode(),
        'no checksum': lambda s: s.split(b'*')[0],
        'ais': lambda s: b'!AIVDM,1,1,,A,13aEOK?P00PD2wVMdLDRhgvL289?,0*26',
    }
    reasons = {'truncated': 'no_checksum', 'bad checksum': 'bad_checksum', 'junk': 'not_nmea',
               'too long': 'too_long', 'field count': 'field_count',
               'out of range': 'out_of_range', 'not a number': 'bad_field',
               'empty value': 'not_available', 'no checksum': 'no_checksum', 'ais': None}
    assert len(targets) == len(damage)
    broken = list(lines)
    for i, (name, spoil) in zip(targets, damage.items()):
        broken[i] = spoil(lines[i])
    dirty = tmp_path / 'dirty.nmea'
    dirty.write_bytes(b'\r\n'.join(broken))
    log0, good = _read_log(clean)
    log, got = _read_log(dirty)
    expected = dict(log0.counts.skipped)
    for reason in reasons.values():
        if reason is not None:
            expected[reason] = expected.get(reason, 0) + 1
    assert dict(log.counts.skipped) == expected
    assert log.counts.sentences['VDM'] == 1                # AIS: counted, not used
    lost = {_stamp(m) for _, m in good['/imu']} - {_stamp(m) for _, m in got['/imu']}
    assert len(lost) == len(damage)
    for topic in marine.TOPICS:                            # the rest unchanged
        kept = [(a, bags.serialize(m)) for a, m in good[topic] if _stamp(m) not in lost]
        assert [(a, bags.serialize(m)) for a, m in got[topic]] == kept, topic


def test_wrong_checksums_everywhere_are_not_compared(voyage: tuple, tmp_path: Path) -> None:
    """
    A logger writing every checksum wrong has its sentences read without them.

    As in Irene's 2013 Flensburg logs: the sentences are read, with a note; one wrong checksum
    in a sound log is still a ``bad_checksum``.
    """
    _, items = voyage
    clean = writer.write_nmea0183(tmp_path / 'clean.nmea', items)
    lines = clean.read_text().splitlines()
    wrong = [line[:-2] + f'{int(line[-2:], 16) ^ 0x19:02X}' for line in lines]
    dirty = tmp_path / 'wrong_checksums.nmea'
    dirty.write_text('\r\n'.join(wrong))
    log0, good = _read_log(clean)
    log, got = _read_log(dirty)
    assert 'bad_checksum' not in log.counts.skipped
    assert any("checksums are wrong: the logger's checksums are not compared" in note
               for note in log.counts.notes)
    for topic in marine.TOPICS:
        assert ([(a, bags.serialize(m)) for a, m in got[topic]]
                == [(a, bags.serialize(m)) for a, m in good[topic]]), topic
    one = list(lines)
    one[100] = wrong[100]
    single = tmp_path / 'one_wrong.nmea'
    single.write_text('\r\n'.join(one))
    log1, _ = _read_log(single)
    assert log1.counts.skipped['bad_checksum'] == 1
    assert not any('checksums are wrong' in note for note in log1.counts.notes)


def test_a_damaged_capture_keeps_its_good_frames(voyage: tuple, tmp_path: Path) -> None:
    _, items = voyage
    clean = writer.write_nmea2000(tmp_path / 'clean.log', items, fmt='canboat')
    lines = clean.read_text().splitlines()
    fast = [i for i, line in enumerate(lines) if ',129029,' in line]
    drop = {fast[10 * 7 + 3]}                              # a frame of the 11th 129029
    attitude = [i for i, line in enumerate(lines) if ',127257,' in line]
    lines[attitude[5]] = lines[attitude[5]][:20]           # a cut line
    lines[attitude[9]] = '\x00\x01garbage'
    kept = [line for i, line in enumerate(lines) if i not in drop]
    dirty = tmp_path / 'dirty.log'
    dirty.write_text('\r\n'.join(kept))
    log, got = _read_log(dirty)
    assert log.counts.skipped == {'not_nmea': 2, 'fast_packet': 1}
    assert log.counts.sentences['129029'] == len(_inputs(items, '/fix')) - 1
    assert len(got['/fix']) >= len(_inputs(items, '/fix')) - 8
    assert len(got['/imu']) == len(_inputs(items, '/imu')) - 2


def test_a_log_without_a_position_is_one_clear_error(tmp_path: Path) -> None:
    path = tmp_path / 'compass.nmea'
    path.write_text('\r\n'.join([
        _checksummed('GPZDA,094737,20,08,2018,-01,00'), _checksummed('HEHDT,10.0,T'),
        _checksummed('GPGGA,094737,,,,,0,00,,,M,,M,,'), _checksummed('SDVHW,,T,,M,5.0,N,,K'),
        _checksummed('GPZDA,094738,20,08,2018,-01,00')]))
    with pytest.raises(marine.NoPositionError) as error:
        marine.open_log(path)
    message = str(error.value)
    assert '\n' not in message and 'no usable position' in message and 'GGA 1' in message


@pytest.mark.parametrize('junk', [b'\0' * 100_000 + b'\n', b'$GPGSV,9' + b',9' * 35_000 + b'\n',
                                  bytes(range(14, 256)) * 330 + b'\n'],
                         ids=['nul block', 'long line', 'binary'])
def test_junk_at_the_start_does_not_hide_the_log(voyage: tuple, tmp_path: Path,
                                                 junk: bytes) -> None:
    # Format detection had read the first 64 KiB only and left out a line too long whole:
    # a log after 100 kB of NULs, one 70 kB line or 80 kB of binary was "not an NMEA 0183
    # log", though the same junk further on is skipped and counted.
    _, items = voyage
    clean = writer.write_nmea0183(tmp_path / 'clean.nmea', items, heading='HDT')
    path = tmp_path / 'junk_first.nmea'
    path.write_bytes(junk + clean.read_bytes())
    _, want = _read_log(clean)
    log, got = _read_log(path)
    assert log.format == 'nmea0183'
    for topic in want:
        assert [a for a, _ in got[topic]] == [a for a, _ in want[topic]], topic


@pytest.mark.parametrize('content', [b'', b'\n\n\n', bytes(range(256)) * 64,
                                     b'# only\n# comments\n', b'hello world\n' * 100])
def test_what_is_no_marine_log_is_refused(tmp_path: Path, content: bytes) -> None:
    path = tmp_path / 'x.nmea'
    path.write_bytes(content)
    assert not marine.is_marine_log(path)
    with pytest.raises(marine.MarineLogError) as error:
        marine.open_log(path)
    assert '\n' not in str(error.value)


def test_bags_and_directories_are_no_marine_logs(tmp_path: Path, voyage: tuple) -> None:
    recs, _ = voyage
    bag = bags.write_bag(tmp_path / 'bag', ((r.topic, r.stamp_ns, r.data) for r in recs[:50]),
                         TOPICS)
    for path in (bag, next(bag.glob('*.mcap')), tmp_path / 'missing.log'):
        assert not marine.is_marine_log(path)
        with pytest.raises(marine.MarineLogError):
            marine.open_log(path)


def test_time_problems_are_one_clear_error(tmp_path: Path) -> None:
    # times of day only: no date
    gga = tmp_path / 'gga.nmea'
    gga.write_text('\n'.join(_checksummed(f'GPGGA,0947{s:02d},5251.0094,N,00518.8172,E,1,12,'
                                          f'0.6,-4,M,46.8,M,,') for s in range(10)))
    with pytest.raises(marine.MarineLogError, match='no date'):
        marine.open_log(gga)
    import datetime
    log, got = _read_log(gga, date=datetime.date(2018, 8, 20))
    assert [_stamp(m) for _, m in got['/fix']] == [(1_534_758_420 + s) * NS for s in range(10)]
    # positions but no time at all
    untimed = tmp_path / 'untimed.nmea'
    untimed.write_text('\n'.join([_checksummed('GPGGA,,5251.0094,N,00518.8172,E,1,12,0.6,-4,M,'
                                               '46.8,M,,')] * 5))
    with pytest.raises(marine.MarineLogError, match='no time'):
        marine.open_log(untimed)
    # a capture with times of day and no GNSS time to date them
    capture = tmp_path / 'capture.n2k'
    payload = nmea2000.encode(marine_position())[1]
    capture.write_text('\n'.join(nmea2000.format_line('ydraw', nmea2000.Frame(
        (36_000 + s) * NS, nmea2000.TIME_DAY, 2, 129025, 1, 255, payload)) for s in range(10)))
    with pytest.raises(marine.MarineLogError, match='no date'):
        marine.open_log(capture)


def marine_position() -> Any:
    """Return a position off Trondheim."""
    from vessel_kinematics.marine.records import Position
    return Position(63.44, 10.4)


def test_logs_without_checksums_are_read(tmp_path: Path) -> None:
    path = tmp_path / 'old.nmea'
    path.write_text('\n'.join(
        line for s in range(5) for line in (
            f'$GPRMC,0947{s:02d},A,5251.0093,N,00518.8170,E,5.6,230.5,200818,1.4,E',
            '$HEHDT,231.0,T')))
    log, got = _read_log(path)
    assert len(got['/fix']) == 5 and len(got['/imu']) == 4 and not log.counts.skipped.get(
        'no_checksum')
    assert got['/gnss/cog_sog'][0][1].vector.y == pytest.approx(5.6 * KNOT)


def test_the_format_comes_from_the_content(voyage: tuple, tmp_path: Path) -> None:
    _, items = voyage
    n2k = writer.write_nmea2000(tmp_path / 'looks_like.nmea', items[:400], fmt='actisense')
    n0183 = writer.write_nmea0183(tmp_path / 'looks_like.n2k', items[:400])
    assert marine.detect_format(n2k) == 'nmea2000/actisense'
    assert marine.detect_format(n0183) == 'nmea0183'


def test_the_writer_never_leaves_half_a_file(voyage: tuple, tmp_path: Path) -> None:
    _, items = voyage
    path = writer.write_nmea0183(tmp_path / 'a.nmea', items[:100])
    before = path.read_bytes()
    with pytest.raises(FileExistsError):
        writer.write_nmea0183(path, items[:10])
    assert path.read_bytes() == before

    def failing() -> Any:
        yield from items[:200]
        raise RuntimeError('the voyage ends badly')

    with pytest.raises(RuntimeError):
        writer.write_nmea2000(tmp_path / 'b.log', failing())
    assert sorted(os.listdir(tmp_path)) == ['a.nmea']


def test_the_marine_package_sits_with_the_tools() -> None:
    # The replay reads through it; it reads through tools.bags (rosbags' one user), never the
    # replay, and no ROS driver.
    import ast
    import importlib
    package = Path(marine.__file__).parent
    for path in sorted(package.glob('*.py')):
        tree = ast.parse(path.read_text())
        names = {alias.name for node in ast.walk(tree) if isinstance(node, ast.Import)
                 for alias in node.names}
        names |= {node.module or '' for node in ast.walk(tree)
                  if isinstance(node, ast.ImportFrom)}
        names |= {f'{node.module}.{alias.name}' for node in ast.walk(tree)
                  if isinstance(node, ast.ImportFrom) for alias in node.names}
        ours = {n for n in names if n.startswith('vessel_kinematics.tools.')}
        assert ours <= {'vessel_kinematics.tools.bags'}, path
        drivers = {n for n in names if n.split('.')[0] in ('rclpy', 'matplotlib', 'rosbags')}
        assert not drivers, path
        module = importlib.import_module(f'vessel_kinematics.marine.{path.stem}'
                                         if path.stem != '__init__'
                                         else 'vessel_kinematics.marine')
        assert [n for n in module.__all__ if not hasattr(module, n)] == [], path


def test_the_nmea2000_bag_written_as_a_capture_reads_back_as_itself(
        shared_data: Path, tmp_path: Path) -> None:
    # The motor vessel's bag came from an NMEA 2000 capture (canboat's samples): written back as
    # one (127257 + 127251, 129025, 128259, 129026) and read, it gives its own messages again,
    # with its conventions (covariances, frames) exactly and its values to the PGNs' resolution.
    bag = shared_data / 'motorboat_wide_turn'
    topics = bags.read_topics([bag], BAG_TOPICS)
    items = sorted(((t, _stamp(m), m) for t, rows in topics.items() for _, m in rows),
                   key=lambda item: item[1])
    capture = writer.write_nmea2000(tmp_path / 'motorboat.can', items, fmt='candump',
                                    topics={'fix': '/fix', 'imu': '/imu',
                                            'velocity': '/speed_log',
                                            'cog_sog': '/gnss/cog_sog'})
    log, got = _read_log(capture)
    assert log.counts.skipped == {}
    _check_receiver_velocity(got)
    for topic in BAG_TOPICS:
        sent, back = [m for _, m in topics[topic]], [m for _, m in got[topic]]
        assert len(back) == len(sent), topic
        # the capture's clock: the bag's stamps to its microseconds
        assert max(abs(_stamp(a) - _stamp(b)) for a, b in zip(sent, back)) < 1_000
        values = np.array([_values(topic, m) for m in back])
        expected = np.array([_values(topic, m) for m in sent])
        step = {'/fix': 1e-7, '/imu': 1e-4, '/speed_log': 0.01, '/gnss/cog_sog': 0.01}[topic]
        np.testing.assert_allclose(values, expected, rtol=1e-3, atol=0.51 * step,
                                   equal_nan=True)
        assert {m.header.frame_id for m in back} == {m.header.frame_id for m in sent}
    for a, b in zip(topics['/imu'], got['/imu']):
        angles, angles_back = _euler(a[1]), _euler(b[1])
        assert angles_back == pytest.approx(angles, abs=0.51e-4)


_DAMAGE = st.lists(st.tuples(st.integers(0, 10 ** 6), st.integers(0, 5),
                             st.binary(min_size=0, max_size=40)), min_size=1, max_size=40)


def _damaged(lines: list[bytes], damage: list[tuple[int, int, bytes]]) -> bytes:
    """Return ``lines`` with some bytes changed, lines cut, junk put in, fields altered."""
    out = list(lines)
    for where, how, junk in damage:
        i = where % len(out)
        line = bytearray(out[i])
        if how == 0 and line:
            line[where % len(line)] = junk[0] if junk else 0
        elif how == 1:
            line = line[:where % (len(line) + 1)]
        elif how == 2:
            line = bytearray(junk)
        elif how == 3:
            at = where % (len(line) + 1)
            line[at:at] = junk or b','
        elif how == 4 and line.startswith(b'$') and b'*' in line:
            # a field altered, the checksum made to match: only the field checks catch it
            body = bytearray(line[1:line.index(b'*')])
            for k, b in enumerate(junk):
                body[(where + k) % max(len(body), 1)] = b'0123456789,.-NSEWV9'[b % 19]
            checksum = 0
            for b in body:
                checksum ^= b
            line = b'$' + body + b'*%02X' % checksum
        else:
            line = bytearray(b'\r'.join([bytes(line), junk]))
        out[i] = bytes(line)
    return b'\n'.join(out)


@pytest.fixture(scope='module')
def small_logs(tmp_path_factory: pytest.TempPathFactory, voyage: tuple) -> dict[str, list]:
    """Return the lines of a short NMEA 0183 log and a short NMEA 2000 capture."""
    _, items = voyage
    directory = tmp_path_factory.mktemp('small')
    short = [item for item in items if item[1] < items[0][1] + 5 * NS]
    return {
        'nmea0183': writer.write_nmea0183(directory / 'a.nmea', short, heading='PASHR')
        .read_bytes().split(b'\r\n'),
        'nmea2000': writer.write_nmea2000(directory / 'a.log', short, fmt='canboat')
        .read_bytes().split(b'\r\n'),
        'candump': writer.write_nmea2000(directory / 'a.can', short, fmt='candump')
        .read_bytes().split(b'\r\n'),
        'pcan': writer.write_nmea2000(directory / 'a.trc', short, fmt='pcan')
        .read_bytes().split(b'\r\n')}


def test_sentences_between_binary_records_are_a_log(small_logs: dict, tmp_path: Path) -> None:
    # A receiver's raw output, its binary protocol beside its NMEA (gpsd's u-blox ZED-F9P
    # sample: 106 of the first 945 'lines' are sentences, the rest UBX records with newline
    # bytes in them): the binary is no line of any format, and the sentences are read.
    clean = small_logs['nmea0183']
    rng = np.random.default_rng(7)
    mixed = bytearray()
    for line in clean:
        mixed += line + b'\r\n'
        for _ in range(3):
            record = bytes(rng.integers(0x80, 0x100, 40, dtype=np.uint8)) + b'\x00\x01'
            mixed += b'\xb5\x62' + record + b'\n'
    path = tmp_path / 'raw.ubx'
    path.write_bytes(bytes(mixed))
    want_path = tmp_path / 'clean.nmea'
    want_path.write_bytes(b'\r\n'.join(clean))
    log, got = _read_log(path)
    _, want = _read_log(want_path)
    assert log.format == 'nmea0183'
    for topic in marine.TOPICS:
        assert [(a, bags.serialize(m)) for a, m in got[topic]] == [
            (a, bags.serialize(m)) for a, m in want[topic]]


@pytest.mark.parametrize('kind', ['nmea0183', 'nmea2000', 'candump', 'pcan'])
@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(damage=_DAMAGE)
def test_damage_is_never_fatal(small_logs: dict, tmp_path: Path, kind: str,
                               damage: list) -> None:
    # Whatever a line becomes, the reader counts it and goes on; the only exceptions are the
    # one-line errors of a log that cannot be replayed at all.
    path = tmp_path / f'damaged.{kind}'
    path.write_bytes(_damaged(small_logs[kind], damage))
    try:
        log = marine.open_log(path)
    except marine.MarineLogError as error:
        assert '\n' not in str(error)
        return
    n = 0
    for connection, arrival, raw in log.messages():
        msg = log.deserialize(raw, connection.msgtype)
        assert 0 <= arrival and 0 <= _stamp(msg)
        n += 1
    assert n == sum(log.counts.messages.values())
    assert set(log.counts.skipped) <= set(SKIP_REASONS)


@pytest.mark.parametrize('fmt, header', [
    ('candump', None), ('ikonvert', '$PDGY,000000,4,,5,482,1,0'),
    ('garmin', 'Sequence #,Timestamp,PGN,Name,Manufacturer,Remote Address,Local Address,'
               'Priority,Single Frame,Size,Packet')])
def test_a_capture_of_relative_times_is_dated_by_its_system_time(
        voyage: tuple, tmp_path: Path, fmt: str, header: str | None) -> None:
    # candump -tz / -td: seconds since the capture began; a Garmin plotter's CSV: ms since it
    # started (canboat's sample3_GPSMAP4008 log); an iKonvert: seconds since it started, among
    # its status lines. PGN 126992 gives the date and time.
    _, items = voyage
    capture = writer.write_nmea2000(tmp_path / 'utc.can', items[:600], fmt=fmt)
    start = None
    lines = [] if header is None else [header]
    for line in capture.read_text().splitlines():
        frame = nmea2000.parse_line(fmt, line)
        start = frame.time_ns if start is None else start
        lines.append(nmea2000.format_line(fmt, nmea2000.Frame(
            frame.time_ns - start + 2 * NS, nmea2000.TIME_RELATIVE, frame.priority, frame.pgn,
            frame.source, frame.destination, frame.data, frame.whole)))
    relative = tmp_path / 'relative.can'
    relative.write_text('\n'.join(lines))
    _, want = _read_log(capture)
    log, got = _read_log(relative)
    assert any('put on UTC by PGN 126992' in note for note in log.counts.notes)
    for topic in marine.TOPICS:
        assert [(a, bags.serialize(m)) for a, m in got[topic]] == [
            (a, bags.serialize(m)) for a, m in want[topic]]

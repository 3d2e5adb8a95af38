"""
Marine logs of a voyage's messages: an NMEA 0183 log or an NMEA 2000 capture, as boats write them.

The inverse of the reader, for the simulator's voyages (the tests replay "a capture made by
the simulator's own writer" and compare with its truth). The input is the voyage's messages,
``(topic, stamp ns, message)`` in stamp order (rclpy messages or rosbags' dataclasses, read by
their fields): the fixes (sensor_msgs/NavSatFix), the IMU (sensor_msgs/Imu, taken as the
vessel's attitude: REP-103 ENU/FLU, mounted along the hull), the log (a twist, its surge) and
optionally the truth (nav_msgs/Odometry, twist over ground in the body frame), whose velocity
becomes the receiver's COG/SOG, or the receiver's own COG/SOG (``/gnss/cog_sog``,
geometry_msgs/Vector3Stamped, as the marine bags hold it).

NMEA 0183 (:func:`write_nmea0183`): at each fix an RMC (the log's clock, with COG/SOG and the
variation) then a GGA (HDOP = sigma_h / UERE of the fix's covariance, ellipsoidal height as
altitude + a geoid separation of 0), at each IMU message a heading sentence (HDT, HDG with the
variation, $PASHR or $PSAT,HPR) and a ROT (d psi / dt of the body rates, Fossen eq. 2.29), at
each log message a VHW (the ROT before the heading: the reader pairs each heading with the
latest rate of turn). Positions to 1e-6 minute (2 mm), angles to 0.01 deg, speeds to 0.01 kn.
``logger_times`` prefixes each line with its stamp (ISO 8601 UTC, ms), as a logger does.

NMEA 2000 (:func:`write_nmea2000`): at each fix 129025, 129029 (a fast packet) and 129026, at
each IMU message 127257 (and 127250 with ``heading_pgn``) and 127251, at each log message
128259, and 126992 once a second; in any of the capture formats of
``nmea2000.CAPTURE_FORMATS`` (fast packets as their CAN frames where the format carries frames;
``'pcap'``: SocketCAN packets, :mod:`~vessel_kinematics.marine.pcap`; ``'ebl'``: Actisense's
log, :mod:`~vessel_kinematics.marine.ebl`; ``'dle'``: a raw NGT-1 stream,
:mod:`~vessel_kinematics.marine.dle`).

A file is written whole or not at all: in a hidden sibling, renamed into place when complete;
an existing file is not replaced.
"""

from __future__ import annotations

import datetime
import math
import os
from pathlib import Path
from typing import Any, Iterable, Iterator, Mapping

import numpy as np
import pynmea2
from vessel_kinematics.core import frames, quaternion
from vessel_kinematics.marine import messages, nmea2000
from vessel_kinematics.marine.log import BINARY_FORMATS
from vessel_kinematics.marine.records import (Attitude, ClockTime, CourseSpeed, Heading, KNOT,
                                              Position, TurnRate, WaterSpeed, wrap_2pi)

__all__ = ['attitude_of', 'course_of', 'HEADING_SENTENCES', 'nmea0183_lines', 'nmea2000_frames',
           'position_of', 'SIM_TOPICS', 'write_nmea0183', 'write_nmea2000']

#: The voyage's topics by role (the simulator's names; ``cog_sog``: a marine bag's).
SIM_TOPICS: dict[str, str] = {'fix': '/fix', 'imu': '/imu', 'velocity': '/velocity',
                              'truth': '/truth/odometry', 'cog_sog': messages.COG_SOG_TOPIC}
#: The heading sentences :func:`write_nmea0183` writes.
HEADING_SENTENCES = ('HDT', 'HDG', 'PASHR', 'PSAT')

_NS = 1_000_000_000
#: How far (ns) the truth's COG/SOG may be from a fix to go into its RMC or 129026.
_TRUTH_TOLERANCE_NS = 60_000_000


def position_of(msg: Any) -> Position:
    """Return the position of a sensor_msgs/NavSatFix (HDOP = sigma_h / UERE, if known)."""
    status = int(msg.status.status)
    if status < 0 or not (math.isfinite(msg.latitude) and math.isfinite(msg.longitude)):
        return Position(math.nan, math.nan, status=-1)
    cov = list(msg.position_covariance)
    hdop = None
    if msg.position_covariance_type > 0 and cov[0] > 0.0 and cov[4] > 0.0:
        hdop = math.sqrt(0.5 * (cov[0] + cov[4])) / messages.UERE_M
    return Position(float(msg.latitude), float(msg.longitude), float(msg.altitude), hdop,
                    min(status, 2))


def attitude_of(msg: Any) -> tuple[Attitude | None, TurnRate | None]:
    """
    Return the attitude (psi, theta, phi) and the rate of turn d psi/dt of a sensor_msgs/Imu.

    The orientation (ENU/FLU) becomes Fossen's zyx angles of q_nb; the body rates p, q, r
    (FRD) give psi_dot = (q sin phi + r cos phi) / cos theta (eq. 2.29). None where the message
    marks the data unused (covariance element 0 = -1).
    """
    o = msg.orientation
    attitude = None
    phi = theta = 0.0
    if msg.orientation_covariance[0] != -1.0:
        q_nb = frames.q_nb_from_ros([o.x, o.y, o.z, o.w])
        phi, theta, psi = quaternion.q2euler(quaternion.normalize(q_nb))
        attitude = Attitude(wrap_2pi(float(psi)), float(theta), float(phi))
    rate = None
    if msg.angular_velocity_covariance[0] != -1.0:
        w = msg.angular_velocity
        q, r = -w.y, -w.z                          # FLU -> FRD
        rate = TurnRate((q * math.sin(phi) + r * math.cos(phi)) / math.cos(theta))
    return attitude, rate


def course_of(msg: Any) -> CourseSpeed:
    """Return the COG/SOG of a nav_msgs/Odometry (twist over ground in the body frame, FLU)."""
    o, v = msg.pose.pose.orientation, msg.twist.twist.linear
    r = quaternion.rquat(quaternion.normalize([o.w, o.x, o.y, o.z]))
    east, north, _ = r @ np.array([v.x, v.y, v.z])
    return CourseSpeed(wrap_2pi(math.atan2(east, north)), math.hypot(east, north))


def _by_role(items: Iterable[tuple[str, int, Any]],
             topics: Mapping[str, str]) -> Iterator[tuple[str, int, Any]]:
    roles = {topic: role for role, topic in topics.items()}
    for topic, stamp_ns, msg in items:
        role = roles.get(topic)
        if role is not None:
            yield role, stamp_ns, msg


class _Truth:
    """The latest truth COG/SOG, for the fix at hand."""

    def __init__(self) -> None:
        self.latest: tuple[int, CourseSpeed] | None = None

    def at(self, stamp_ns: int) -> CourseSpeed | None:
        if self.latest is None or abs(self.latest[0] - stamp_ns) > _TRUTH_TOLERANCE_NS:
            return None
        return self.latest[1]


def _atomic(path: str | Path, chunks: Iterable[bytes]) -> Path:
    path = Path(path)
    if path.exists() or path.is_symlink():
        raise FileExistsError(f'{path} exists: not replacing it')
    staging = path.parent / f'.{path.name}.writing-{os.getpid()}'
    try:
        with open(staging, 'wb') as f:
            for chunk in chunks:
                f.write(chunk)
        os.rename(staging, path)
    except BaseException:
        staging.unlink(missing_ok=True)
        raise
    return path


def _crlf(lines: Iterable[str]) -> Iterator[bytes]:
    return (line.encode('ascii') + b'\r\n' for line in lines)


# ---------------------------------------------------------------------------------------------
# NMEA 0183


def _sentence(body: str) -> str:
    return f'${body}*{pynmea2.NMEASentence.checksum(body):02X}'


def _hhmmss(stamp_ns: int) -> str:
    moment = datetime.datetime.fromtimestamp(stamp_ns // _NS, tz=datetime.timezone.utc)
    return moment.strftime('%H%M%S') + f'.{stamp_ns % _NS // 10_000_000:02d}'


def _ddmmyy(stamp_ns: int) -> str:
    return datetime.datetime.fromtimestamp(stamp_ns // _NS, tz=datetime.timezone.utc).strftime(
        '%d%m%y')


def _dm(value: float, positive: str, negative: str, width: int) -> tuple[str, str]:
    hemisphere = positive if value >= 0.0 else negative
    value = abs(value)
    degrees = int(value)
    minutes = round((value - degrees) * 60.0, 6)
    if minutes >= 60.0:
        degrees, minutes = degrees + 1, minutes - 60.0
    return f'{degrees:0{width}d}{minutes:09.6f}', hemisphere


def _lat_lon(p: Position) -> str:
    lat, ns = _dm(p.lat_deg, 'N', 'S', 2)
    lon, ew = _dm(p.lon_deg, 'E', 'W', 3)
    return f'{lat},{ns},{lon},{ew}'


def _variation(variation_deg: float) -> str:
    return f'{abs(variation_deg):.1f},{"E" if variation_deg >= 0 else "W"}'


def _rmc(stamp_ns: int, p: Position, course: CourseSpeed | None, variation_deg: float) -> str:
    when = _hhmmss(stamp_ns)
    cog_sog = ',' if course is None else (
        f'{course.sog / KNOT:.2f},{math.degrees(course.cog) % 360.0:.2f}')
    if p.status < 0:
        return _sentence(f'GPRMC,{when},V,,,,,,,{_ddmmyy(stamp_ns)},{_variation(variation_deg)},N')
    return _sentence(f'GPRMC,{when},A,{_lat_lon(p)},{cog_sog},{_ddmmyy(stamp_ns)},'
                     f'{_variation(variation_deg)},A')


def _gga(stamp_ns: int, p: Position) -> str:
    when = _hhmmss(stamp_ns)
    if p.status < 0:
        return _sentence(f'GPGGA,{when},,,,,0,00,,,M,,M,,')
    quality = {0: 1, 1: 2, 2: 4}[p.status]
    hdop = '' if p.hdop is None else f'{p.hdop:.3f}'
    height = '' if math.isnan(p.height_m) else f'{p.height_m:.3f}'
    return _sentence(f'GPGGA,{when},{_lat_lon(p)},{quality},10,{hdop},{height},M,0.000,M,,')


def _heading_sentence(kind: str, stamp_ns: int, a: Attitude, variation_deg: float) -> str:
    assert a.psi is not None
    psi = math.degrees(a.psi) % 360.0
    pitch, roll = math.degrees(a.theta or 0.0), math.degrees(a.phi or 0.0)
    if kind == 'HDT':
        return _sentence(f'HEHDT,{psi:.2f},T')
    if kind == 'HDG':
        return _sentence(f'HCHDG,{(psi - variation_deg) % 360.0:.2f},,,'
                         f'{_variation(variation_deg)}')
    if kind == 'PASHR':
        sigma = math.degrees(messages.ATTITUDE_SIGMA)
        heading_sigma = math.degrees(messages.HEADING_SIGMA)
        return _sentence(f'PASHR,{_hhmmss(stamp_ns)},{psi:.2f},T,{roll:.2f},{pitch:.2f},,'
                         f'{sigma:.3f},{sigma:.3f},{heading_sigma:.3f},1,1')
    if kind == 'PSAT':
        return _sentence(f'PSAT,HPR,{_hhmmss(stamp_ns)},{psi:.2f},{pitch:.2f},{roll:.2f},N')
    raise ValueError(f'heading sentence {kind!r} is not one of {", ".join(HEADING_SENTENCES)}')


def _iso(stamp_ns: int) -> str:
    moment = datetime.datetime.fromtimestamp(stamp_ns // _NS, tz=datetime.timezone.utc)
    return moment.strftime('%Y-%m-%dT%H:%M:%S') + f'.{stamp_ns % _NS // 1_000_000:03d}Z'


def nmea0183_lines(items: Iterable[tuple[str, int, Any]], *,
                   topics: Mapping[str, str] = SIM_TOPICS, heading: str = 'HDT',
                   variation_deg: float = 0.0, rate: bool = True,
                   logger_times: bool = False) -> Iterator[str]:
    """Yield the lines of :func:`write_nmea0183` (same arguments, no file)."""
    if heading not in HEADING_SENTENCES:
        raise ValueError(f'heading sentence {heading!r} is not one of '
                         f'{", ".join(HEADING_SENTENCES)}')
    truth = _Truth()
    for role, stamp_ns, msg in _by_role(items, topics):
        out: list[str] = []
        if role == 'truth':
            truth.latest = (stamp_ns, course_of(msg))
        elif role == 'cog_sog':
            truth.latest = (stamp_ns, CourseSpeed(msg.vector.x, msg.vector.y))
        elif role == 'fix':
            p = position_of(msg)
            out.append(_rmc(stamp_ns, p, truth.at(stamp_ns), variation_deg))
            out.append(_gga(stamp_ns, p))
        elif role == 'imu':
            # The rate first: the reader pairs a heading with the latest rate of turn.
            attitude, turn = attitude_of(msg)
            if rate and turn is not None:
                out.append(_sentence(f'TIROT,{math.degrees(turn.rate) * 60.0:.2f},A'))
            if attitude is not None:
                out.append(_heading_sentence(heading, stamp_ns, attitude, variation_deg))
        elif role == 'velocity':
            surge = float(msg.twist.twist.linear.x if hasattr(msg.twist, 'twist')
                          else msg.twist.linear.x)
            out.append(_sentence(f'VWVHW,,T,,M,{surge / KNOT:.2f},N,{surge * 3.6:.2f},K'))
        for line in out:
            yield f'{_iso(stamp_ns)} {line}' if logger_times else line


def write_nmea0183(path: str | Path, items: Iterable[tuple[str, int, Any]], *,
                   topics: Mapping[str, str] = SIM_TOPICS, heading: str = 'HDT',
                   variation_deg: float = 0.0, rate: bool = True,
                   logger_times: bool = False) -> Path:
    """
    Write the NMEA 0183 log of a voyage's messages at ``path`` (a new file); return it.

    ``topics``: the topic of each role (``fix``, ``imu``, ``velocity``, ``truth``);
    ``heading``: the heading sentence (:data:`HEADING_SENTENCES`); ``variation_deg``: the
    magnetic variation written in RMC and HDG (east positive); ``rate``: write ROT;
    ``logger_times``: each line prefixed with its stamp.
    """
    return _atomic(path, _crlf(nmea0183_lines(items, topics=topics, heading=heading,
                                              variation_deg=variation_deg, rate=rate,
                                              logger_times=logger_times)))


# ---------------------------------------------------------------------------------------------
# NMEA 2000

_GNSS, _COMPASS, _LOG = 1, 2, 3          # source addresses of the three devices


def _frames(fmt: str, stamp_ns: int, priority: int, pgn: int, source: int, payload: bytes,
            counter: int) -> list[nmea2000.Frame]:
    kind = (nmea2000.TIME_UTC if fmt in ('canboat', 'candump', 'pcap', 'ebl')
            else nmea2000.TIME_DAY)
    if pgn not in nmea2000.FAST_PGNS or fmt in ('actisense', 'garmin', 'ikonvert', 'ebl', 'dle'):
        return [nmea2000.Frame(stamp_ns, kind, priority, pgn, source, 255, payload,
                               whole=len(payload) > 8)]
    return [nmea2000.Frame(stamp_ns, kind, priority, pgn, source, 255, data)
            for data in nmea2000.fast_packet_frames(payload, counter)]


def nmea2000_frames(items: Iterable[tuple[str, int, Any]], *, fmt: str = 'canboat',
                    topics: Mapping[str, str] = SIM_TOPICS, heading_pgn: bool = False,
                    variation_deg: float = 0.0) -> Iterator[nmea2000.Frame]:
    """Yield the frames of :func:`write_nmea2000` (same arguments, no file)."""
    if fmt not in nmea2000.CAPTURE_FORMATS:
        raise ValueError(f'capture format {fmt!r} is not one of '
                         f'{", ".join(nmea2000.CAPTURE_FORMATS)}')
    truth = _Truth()
    sid = 0
    counter = 0
    last_second: int | None = None
    variation = math.radians(variation_deg)
    own_cog = False                                      # the receiver's COG/SOG given
    for role, stamp_ns, msg in _by_role(items, topics):
        out: list[tuple[int, int, int, bytes]] = []      # priority, pgn, source, payload
        second = stamp_ns // _NS
        if role not in ('truth', 'cog_sog') and second != last_second:
            last_second = second
            pgn, payload = nmea2000.encode(ClockTime(stamp_ns % (86_400 * _NS), stamp_ns), sid)
            out.append((3, pgn, _GNSS, payload))
        if role == 'truth':
            truth.latest = (stamp_ns, course_of(msg))
        elif role == 'cog_sog':                    # the receiver's own: at its own time
            own_cog = True
            pgn, payload = nmea2000.encode(CourseSpeed(msg.vector.x, msg.vector.y), sid)
            out.append((2, pgn, _GNSS, payload))
        elif role == 'fix':
            p = position_of(msg)
            sid = (sid + 1) % 250
            if p.status >= 0:
                pgn, payload = nmea2000.encode(p, sid)
                out.append((2, pgn, _GNSS, payload))
            out.append((3, 129029, _GNSS, nmea2000.encode_gnss(p, stamp_ns, sid)))
            course = None if own_cog else truth.at(stamp_ns)
            if course is not None and p.status >= 0:
                pgn, payload = nmea2000.encode(course, sid)
                out.append((2, pgn, _GNSS, payload))
        elif role == 'imu':
            attitude, turn = attitude_of(msg)
            if turn is not None:                   # first, as in the NMEA 0183 log
                pgn, payload = nmea2000.encode(turn, sid)
                out.append((2, pgn, _COMPASS, payload))
            if attitude is not None:
                pgn, payload = nmea2000.encode(attitude, sid)
                out.append((3, pgn, _COMPASS, payload))
                if heading_pgn:
                    assert attitude.psi is not None
                    pgn, payload = nmea2000.encode(
                        Heading(wrap_2pi(attitude.psi - variation), True, 0.0, variation), sid)
                    out.append((2, pgn, _COMPASS, payload))
        elif role == 'velocity':
            surge = float(msg.twist.twist.linear.x if hasattr(msg.twist, 'twist')
                          else msg.twist.linear.x)
            pgn, payload = nmea2000.encode(WaterSpeed(max(surge, 0.0)), sid)
            out.append((2, pgn, _LOG, payload))
        for priority, pgn, source, payload in out:
            counter = (counter + 1) % 8
            yield from _frames(fmt, stamp_ns, priority, pgn, source, payload, counter)


def write_nmea2000(path: str | Path, items: Iterable[tuple[str, int, Any]], *,
                   fmt: str = 'canboat', topics: Mapping[str, str] = SIM_TOPICS,
                   heading_pgn: bool = False, variation_deg: float = 0.0) -> Path:
    """
    Write the NMEA 2000 capture of a voyage's messages at ``path`` (a new file); return it.

    ``fmt``: the capture format (``nmea2000.CAPTURE_FORMATS``); ``topics`` as
    :func:`write_nmea0183`; ``heading_pgn``: also 127250 (magnetic, with ``variation_deg``)
    beside 127257.
    """
    captured = nmea2000_frames(items, fmt=fmt, topics=topics, heading_pgn=heading_pgn,
                               variation_deg=variation_deg)
    if fmt in BINARY_FORMATS:
        return _atomic(path, BINARY_FORMATS[fmt].packets(captured))
    return _atomic(path, _crlf(nmea2000.format_line(fmt, frame) for frame in captured))

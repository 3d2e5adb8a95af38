"""
What a marine log says, in SI units and Fossen's conventions, before any ROS message.

Both protocols decode into these records (:mod:`~vessel_kinematics.marine.nmea0183`,
:mod:`~vessel_kinematics.marine.nmea2000`), :mod:`~vessel_kinematics.marine.assemble` turns
them into the navigator's input messages, and :mod:`~vessel_kinematics.marine.writer` encodes
them back into sentences and PGNs. Angles are radians: a heading psi or a course chi from
north, clockwise (NED), in [0, 2 pi); roll phi positive starboard down, pitch theta positive
bow up (Fossen's zyx angles of BODY/FRD in NED, eq. 2.18); speeds m/s.

A decoded sentence or PGN is a :class:`Decoded`: its records and the one-word reason it was
skipped, if it was (:data:`SKIP_REASONS`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math

from vessel_kinematics.core.frames import KNOT

__all__ = ['Attitude', 'ClockTime', 'CourseSpeed', 'Decoded', 'Heading', 'KNOT', 'Position',
           'Record', 'SKIP_REASONS', 'TurnRate', 'Variation', 'WaterSpeed', 'wrap_2pi']


#: Why a line, sentence or PGN is skipped (the keys of ``MarineLog.counts.skipped``).
SKIP_REASONS: dict[str, str] = {
    'not_nmea': "not a sentence or frame of the log's format (binary junk, a cut line)",
    'too_long': 'a line longer than any sentence or frame',
    'bad_checksum': 'the checksum does not match',
    'no_checksum': "no checksum, where the log's other sentences carry one",
    'field_count': 'fewer fields or bytes than the sentence or PGN defines',
    'bad_field': 'a field that is not a number, time or date where one is due',
    'out_of_range': 'a value outside the range the sentence or PGN defines',
    'not_available': "the value is marked not available (empty, or NMEA 2000's no-data)",
    'invalid': 'the sentence flags its own data invalid (ROT status V, THS mode not A, '
               'VTG mode N)',
    'fast_packet': 'a fast-packet frame out of sequence, or a message never completed',
    'untimed': "outside the log's clock: before its first or after its last time, "
               'or in a gap too long to space (see nmea0183.Clock)',
    'repeated': 'a time sentence repeating the previous time (its data too)',
    'time_jump': "a clock time out of line with the log's clock (back, or far ahead) that "
                 'the next times do not agree on, its data too, or the lines before a step '
                 'they do agree on (NMEA 0183); a frame stamped seconds before the frames '
                 'around it, or ahead of them where the next frames do not agree (NMEA 2000)',
    'bad_time': 'a time a ROS stamp cannot hold (before 1970, after 2038)',
}


def wrap_2pi(angle: float) -> float:
    """Return ``angle`` (rad) wrapped to [0, 2 pi)."""
    wrapped = math.fmod(angle, 2.0 * math.pi)
    if wrapped < 0.0:
        wrapped += 2.0 * math.pi
    return 0.0 if wrapped >= 2.0 * math.pi else wrapped


@dataclass(frozen=True, slots=True)
class Position:
    """
    A GNSS position: latitude, longitude (deg, WGS-84), ellipsoidal height (m, NaN unknown).

    ``hdop`` the horizontal dilution of precision (None unknown); ``status`` the
    sensor_msgs/NavSatStatus status (-1 no fix, 0 fix, 1 SBAS, 2 GBAS).
    """

    lat_deg: float
    lon_deg: float
    height_m: float = math.nan
    hdop: float | None = None
    status: int = 0


@dataclass(frozen=True, slots=True)
class Heading:
    """
    A compass heading psi (rad): true, or magnetic with the deviation and variation it gives.

    True heading = magnetic + deviation + variation (east positive); None: not given.
    ``variance`` (rad^2) when the sensor states its accuracy.
    """

    psi: float
    magnetic: bool = False
    deviation: float | None = None
    variation: float | None = None
    variance: float | None = None


@dataclass(frozen=True, slots=True)
class Attitude:
    """
    Attitude of an attitude sensor: true heading psi, pitch theta, roll phi (rad; None unknown).

    The variances (rad^2) when the sensor states them, else None.
    """

    psi: float | None = None
    theta: float | None = None
    phi: float | None = None
    var_psi: float | None = None
    var_theta: float | None = None
    var_phi: float | None = None


@dataclass(frozen=True, slots=True)
class TurnRate:
    """The rate of turn: d psi / dt (rad/s), positive turning to starboard."""

    rate: float


@dataclass(frozen=True, slots=True)
class WaterSpeed:
    """Speed through the water along the keel (surge relative to the water, m/s)."""

    speed: float


@dataclass(frozen=True, slots=True)
class CourseSpeed:
    """The receiver's course over ground chi (rad, true or magnetic) and speed (m/s)."""

    cog: float
    sog: float
    magnetic: bool = False


@dataclass(frozen=True, slots=True)
class Variation:
    """The magnetic variation (declination) the log states (rad, east positive)."""

    variation: float


@dataclass(frozen=True, slots=True)
class ClockTime:
    """
    A time the log states: UTC in ns since the epoch, or only the time of day.

    ``utc_ns`` None when the sentence has no date (GGA, GLL): ``day_ns`` is then the time of
    day (ns since midnight UTC); with a date both are set. ``fixed``: the receiver had a fix
    (a receiver without one may send its clock's own idea of the time, 1980 even).
    """

    day_ns: int
    utc_ns: int | None = None
    fixed: bool = True


Record = (Position | Heading | Attitude | TurnRate | WaterSpeed | CourseSpeed | Variation
          | ClockTime)


@dataclass(slots=True)
class Decoded:
    """
    One sentence or PGN decoded: its type (``'GGA'``, ``'129029'``), its source, its records.

    ``source`` tells two talkers or devices apart (``'GP'``, ``'II'``; an NMEA 2000 source
    address); ``skip`` the reason it yields nothing (:data:`SKIP_REASONS`), None when used.
    """

    kind: str
    source: str = ''
    records: list[Record] = field(default_factory=list)
    skip: str | None = None

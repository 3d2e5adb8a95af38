r"""
NMEA 0183 logs: lines into sentences (pynmea2), sentences into records, and the log's clock.

Reading (:func:`split_line`, :func:`decode`): pynmea2 frames each sentence, checks its
checksum and knows each type's fields; the fields are then read strictly here (pynmea2 returns
a field it cannot convert as its text), into :mod:`~vessel_kinematics.marine.records`:

=========================  ==================================================================
sentence                   records
=========================  ==================================================================
RMC                        position (status A), COG/SOG, magnetic variation, date and time
GGA, GNS                   position with HDOP, ellipsoidal height = altitude + geoid
                           separation (NaN when either is missing), time of day
GLL                        position (status A), time of day
ZDA                        date and time
HDT, THS                   true heading (THS: mode A only)
HDG                        magnetic heading with its deviation and variation
HDM                        magnetic heading (variation from RMC or HDG)
ROT                        rate of turn (deg/min, status A)
VHW                        speed through water (knots, else km/h)
VBW                        longitudinal speed through water (knots, signed: astern is
                           negative; water status A); its transverse and ground speeds are
                           not read (the leeway and the current are estimated)
VTG                        COG/SOG (true track; knots, else km/h)
XDR                        pitch and roll of angle transducers named PTCH/PITCH, ROLL (deg)
$PASHR                     true heading, roll, pitch and their accuracies (the RT300/Trimble
                           form), or ``$PASHR,HPR`` heading, pitch, roll
$PSAT,HPR                  true heading, pitch, roll (Hemisphere; roll or pitch may be empty)
=========================  ==================================================================

A fix of no quality (RMC/GLL status V, GGA quality 0, 6 = dead reckoning, 7 manual, 8
simulated; GNS mode N/E/M/S) is a no-fix position (published as NO_FIX, as receivers send).

A line may carry a logger's time: an NMEA 4.10 TAG block ``\c:<unix s>*hh\`` or a leading
ISO 8601 UTC time or Unix time (s, or ms as Signal K's ``1436182345632;A;$GPGGA...``) before
the sentence; anything else before ``$`` or ``!`` is ignored (the checksum still guards the
sentence).

Timing (:class:`Clock`): the log's time sentences (its clock, :func:`clock_priority`: RMC,
else ZDA, else the time of day of GGA/GNS/GLL) stamp themselves; every other line between two
of them gets a time spaced evenly by its position between them: its line number, or its
logger time where every line has one. So a log of RMC at 1 Hz and 33 lines a second stamps the
4th line after an RMC at t + 4/33 s, as the project's bags of these logs do. Lines before the
first or after the last time, or between two times more than :data:`MAX_SPACED_GAP_NS` apart,
are untimed (skipped, counted), unless they came at the rate of the interval before (a GNSS
outage of up to :data:`MAX_OUTAGE_NS`: the other instruments talked on). A time repeating the
previous one is no new time (its data is a repeat: skipped). A time out of line (back, or
ahead by more than can be spaced) is the clock's new time once :data:`CONFIRM_TIMES` times
agree on it; alone (a date of 9999) it is refused, its data too. Two faults of real
receivers are read instead: a time in line once 1024 weeks are added is read so (a receiver
past a GPS week rollover, as gpsd reads it), and a time back within the hour of the clock's
last whose minute alone disagrees is read by its seconds (a receiver whose minute stuck).
The clock starts at the first time of a receiver with a fix (RMC status A, GGA quality > 0):
before it, a receiver may send its own clock's guess.
"""

from __future__ import annotations

import calendar
from dataclasses import dataclass
import datetime
import math
import re
from typing import Any, Callable, Iterator

import pynmea2
from vessel_kinematics.core.frames import GPS_WEEK_ROLLOVER_S
from vessel_kinematics.marine.records import (Attitude, ClockTime, CourseSpeed, Decoded,
                                              Heading, KNOT, Position, Record, TurnRate,
                                              Variation, WaterSpeed)

__all__ = ['checksum_holds', 'Clock', 'clock_priority', 'CONFIRM_TIMES', 'decode',
           'has_checksum', 'KINDS', 'Line', 'MAX_OUTAGE_NS', 'MAX_SPACED_GAP_NS', 'PRIORITIES',
           'RATE_FACTOR', 'split_line', 'Timed']

#: The longest interval between two clock times over which lines are always spaced (ns).
MAX_SPACED_GAP_NS = 10_000_000_000
#: The longest interval over which lines are spaced when they came at the rate of the interval
#: before (a GNSS outage: the other instruments talk on), ns; longer ones are untimed.
MAX_OUTAGE_NS = 3600 * 1_000_000_000
#: How far the line rate over a long interval may stray from the one before it (a factor).
RATE_FACTOR = 2.0
#: Clock times in line with each other that make a step of the clock its new time.
CONFIRM_TIMES = 3

_NS = 1_000_000_000
_MINUTE_NS = 60 * _NS
_ROLLOVER_NS = GPS_WEEK_ROLLOVER_S * _NS
_HOUR_NS = 3600 * _NS
_DAY_NS = 86_400 * _NS

#: The sentence types each role is read from, best first (``assemble`` picks one per log).
PRIORITIES: dict[str, tuple[str, ...]] = {
    'fix': ('GGA', 'GNS', 'RMC', 'GLL'),
    'heading': ('PASHR', 'PSAT', 'HDT', 'THS', 'HDG', 'HDM'),
    'attitude': ('PASHR', 'PSAT', 'XDR'),
    'rate': ('ROT',),
    'speed': ('VHW', 'VBW'),
    'cog': ('RMC', 'VTG'),
}

_CHECKSUM_RE = re.compile(r'\*[0-9A-Fa-f]{2}\s*$')
_ISO_RE = re.compile(r'^(\d{4})-(\d\d)-(\d\d)[T ](\d\d):(\d\d):(\d\d)(?:[.,](\d{1,9}))?'
                     r'(Z|[+-]\d\d:?\d\d)?$')
_NUMBER_RE = re.compile(r'^[+-]?(\d+\.?\d*|\.\d+)$')


def clock_priority() -> tuple[str, ...]:
    """Return the sentence types of the log's clock, best first (date and time before time)."""
    return ('RMC', 'ZDA', 'GGA', 'GNS', 'GLL')


@dataclass(frozen=True, slots=True)
class Line:
    """A line of the log split: its sentence (None if there is none), logger time, problem."""

    sentence: str | None
    logger_ns: int | None = None
    skip: str | None = None


def _iso_ns(text: str) -> int | None:
    m = _ISO_RE.match(text)
    if m is None:
        return None
    year, month, day, hour, minute, second = (int(g) for g in m.groups()[:6])
    fraction, zone = m.group(7), m.group(8)
    try:
        moment = datetime.datetime(year, month, day, hour, minute, second,
                                   tzinfo=datetime.timezone.utc)
    except ValueError:
        return None
    ns = calendar.timegm(moment.timetuple()) * _NS
    if fraction:
        ns += int(fraction.ljust(9, '0'))
    if zone and zone != 'Z':
        sign = 1 if zone[0] == '+' else -1
        digits = zone[1:].replace(':', '')
        ns -= sign * (int(digits[:2]) * 3600 + int(digits[2:]) * 60) * _NS
    return ns


def _epoch_ns(text: str) -> int | None:
    """Return a Unix time in s (or ms, above 1e11) as ns; None unless it is after 1973."""
    if not _NUMBER_RE.match(text):
        return None
    value = float(text)
    if value > 1e11:
        value *= 1e-3
    if not 1e8 <= value < 2 ** 31:
        return None
    return int(round(value * 1e6)) * 1000


def _tag_time(tag: str) -> int | None:
    """Return the ``c:`` time of a TAG block's body (``c:1534758457,s:r1``), ns."""
    for item in tag.split(','):
        if item.startswith('c:'):
            return _epoch_ns(item[2:])
    return None


def split_line(text: str) -> Line:
    """
    Split one line of a log into its sentence and the logger's time, if it carries one.

    ``Line.skip``: ``'not_nmea'`` when the line holds no sentence, ``'bad_checksum'`` for a TAG
    block whose checksum does not match.
    """
    text = text.strip()
    logger_ns = None
    if text.startswith('\\'):
        end = text.find('\\', 1)
        if end < 0:
            return Line(None, skip='not_nmea')
        tag = text[1:end]
        body, star, checksum = tag.partition('*')
        if star and (len(checksum) != 2 or not _is_hex(checksum)
                     or int(checksum, 16) != pynmea2.NMEASentence.checksum(body)):
            return Line(None, skip='bad_checksum')
        logger_ns = _tag_time(body)
        text = text[end + 1:]
    start = min((i for i in (text.find('$'), text.find('!')) if i >= 0), default=-1)
    if start < 0:
        return Line(None, skip='not_nmea')
    if start > 0 and logger_ns is None:
        prefix = text[:start].strip(' \t,;')
        first = re.split(r'[\s,;]+', prefix, maxsplit=1)[0]     # Signal K: 1436182345632;A;
        logger_ns = _iso_ns(prefix) or _epoch_ns(prefix) or _epoch_ns(first)
    return Line(text[start:], logger_ns)


def _is_hex(text: str) -> bool:
    return all(c in '0123456789abcdefABCDEF' for c in text)


def has_checksum(sentence: str) -> bool:
    """Return True when a sentence ends with ``*hh``."""
    return _CHECKSUM_RE.search(sentence) is not None


def checksum_holds(sentence: str) -> bool:
    """Return True when a sentence ending with ``*hh`` has the checksum of its content."""
    sentence = sentence.strip()
    star = sentence.rfind('*')
    try:
        return int(sentence[star + 1:], 16) == pynmea2.NMEASentence.checksum(sentence[1:star])
    except ValueError:
        return False


# ---------------------------------------------------------------------------------------------
# Fields, read strictly


class _Bad(Exception):
    """A field that cannot be read: its reason (a key of ``records.SKIP_REASONS``)."""

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


def _raw(msg: Any, name: str) -> str:
    i = type(msg).name_to_idx[name]
    if i >= len(msg.data):
        raise _Bad('field_count')
    return msg.data[i].strip()


def _float(text: str, required: bool = True) -> float | None:
    if text == '':
        if required:
            raise _Bad('not_available')
        return None
    if not _NUMBER_RE.match(text):
        raise _Bad('bad_field')
    value = float(text)
    if not math.isfinite(value):
        raise _Bad('bad_field')
    return value


def _number(msg: Any, name: str, required: bool = True) -> float | None:
    return _float(_raw(msg, name), required)


def _day_ns(text: str) -> int:
    """Return hhmmss[.sss] as ns since midnight."""
    if len(text) < 6 or not text[:6].isdigit():
        raise _Bad('bad_field' if text else 'not_available')
    hour, minute, second = int(text[0:2]), int(text[2:4]), int(text[4:6])
    fraction = text[6:]
    if hour > 23 or minute > 59 or second > 60:
        raise _Bad('out_of_range')
    ns = ((hour * 60 + minute) * 60 + second) * _NS
    if fraction:
        if fraction[0] != '.' or not (fraction[1:].isdigit() or fraction == '.'):
            raise _Bad('bad_field')
        ns += int(fraction[1:10].ljust(9, '0')) if len(fraction) > 1 else 0
    return ns


def _date_ns(day: int, month: int, year: int) -> int:
    try:
        moment = datetime.datetime(year, month, day, tzinfo=datetime.timezone.utc)
    except ValueError:
        raise _Bad('out_of_range') from None
    return calendar.timegm(moment.timetuple()) * _NS


def _ddmmyy_ns(text: str) -> int:
    if len(text) != 6 or not text.isdigit():
        raise _Bad('bad_field' if text else 'not_available')
    year = int(text[4:6])
    return _date_ns(int(text[0:2]), int(text[2:4]), year + (2000 if year < 80 else 1900))


def _angle_dm(text: str, hemisphere: str, positive: str, negative: str, limit: float) -> float:
    """Return (d)ddmm.mmm with its hemisphere as signed degrees."""
    value = _float(text)
    assert value is not None
    if value < 0.0:
        raise _Bad('bad_field')
    degrees = math.floor(value / 100.0)
    minutes = value - 100.0 * degrees
    if minutes >= 60.0:
        raise _Bad('out_of_range')
    result = degrees + minutes / 60.0
    if hemisphere == negative:
        result = -result
    elif hemisphere != positive:
        raise _Bad('bad_field' if hemisphere else 'not_available')
    if result > limit or result < -limit:
        raise _Bad('out_of_range')
    return result


def _lat_lon(msg: Any) -> tuple[float, float]:
    return (_angle_dm(_raw(msg, 'lat'), _raw(msg, 'lat_dir'), 'N', 'S', 90.0),
            _angle_dm(_raw(msg, 'lon'), _raw(msg, 'lon_dir'), 'E', 'W', 180.0))


def _direction(value: float | None, allow_360: bool = True) -> float:
    """Return degrees in [0, 360] as rad in [0, 2 pi) (360 is north); None is not available."""
    if value is None:
        raise _Bad('not_available')
    if value < 0.0 or value > 360.0 or (value == 360.0 and not allow_360):
        raise _Bad('out_of_range')
    return math.radians(value % 360.0)


def _signed(value: float | None, direction: str) -> float | None:
    """Return a magnitude with its E/W letter as east-positive degrees (None if absent)."""
    if value is None:
        return None
    if direction == 'W':
        return -value
    if direction in ('E', ''):
        return value
    raise _Bad('bad_field')


def _speed(value: float | None) -> float | None:
    if value is not None and value < 0.0:
        raise _Bad('out_of_range')
    return value


# ---------------------------------------------------------------------------------------------
# Sentences


_GGA_STATUS = {1: 0, 2: 1, 3: 0, 4: 2, 5: 2, 9: 1}   # quality -> NavSatStatus (else no fix)


def _rmc(msg: Any) -> list[Record]:
    out: list[Record] = []
    status = _raw(msg, 'status')
    mode = _raw(msg, 'mode_indicator') if len(msg.data) > 11 else ''
    fixed = status == 'A' and mode != 'N'
    day = _raw(msg, 'timestamp')
    date = _raw(msg, 'datestamp')
    if day and date:
        day_ns = _day_ns(day)
        out.append(ClockTime(day_ns, _ddmmyy_ns(date) + day_ns, fixed))
    variation = _signed(_number(msg, 'mag_variation', False), _raw(msg, 'mag_var_dir'))
    if variation is not None:
        if abs(variation) > 180.0:
            raise _Bad('out_of_range')
        out.append(Variation(math.radians(variation)))
    if not fixed:
        if status not in ('A', 'V'):
            raise _Bad('bad_field')
        out.append(Position(math.nan, math.nan, status=-1))
        return out
    lat, lon = _lat_lon(msg)
    out.append(Position(lat, lon))
    sog = _speed(_number(msg, 'spd_over_grnd', False))
    cog = _number(msg, 'true_course', False)
    if sog is not None and cog is not None:
        out.append(CourseSpeed(_direction(cog), sog * KNOT))
    return out


def _height(msg: Any, altitude: str, separation: str) -> float:
    alt = _number(msg, altitude, False)
    sep = _number(msg, separation, False)
    return math.nan if alt is None or sep is None else alt + sep


def _hdop(msg: Any, name: str) -> float | None:
    hdop = _number(msg, name, False)
    if hdop is not None and hdop <= 0.0:
        raise _Bad('out_of_range')
    return hdop


def _gga(msg: Any) -> list[Record]:
    out: list[Record] = []
    quality = _raw(msg, 'gps_qual')
    if not quality.isdigit():
        raise _Bad('bad_field' if quality else 'not_available')
    status = _GGA_STATUS.get(int(quality), -1)
    day = _raw(msg, 'timestamp')
    if day:
        out.append(ClockTime(_day_ns(day), fixed=status >= 0))
    if status < 0:
        out.append(Position(math.nan, math.nan, status=-1))
        return out
    lat, lon = _lat_lon(msg)
    out.append(Position(lat, lon, _height(msg, 'altitude', 'geo_sep'),
                        _hdop(msg, 'horizontal_dil'), status))
    return out


def _gns(msg: Any) -> list[Record]:
    out: list[Record] = []
    mode = _raw(msg, 'mode_indicator').upper()
    if not mode:
        raise _Bad('not_available')
    status = (2 if any(c in 'RF' for c in mode) else 1 if 'D' in mode
              else 0 if any(c in 'AP' for c in mode) else -1)
    day = _raw(msg, 'timestamp')
    if day:
        out.append(ClockTime(_day_ns(day), fixed=status >= 0))
    if status < 0:
        out.append(Position(math.nan, math.nan, status=-1))
        return out
    lat, lon = _lat_lon(msg)
    out.append(Position(lat, lon, _height(msg, 'altitude', 'geo_sep'), _hdop(msg, 'hdop'),
                        status))
    return out


def _gll(msg: Any) -> list[Record]:
    out: list[Record] = []
    status = _raw(msg, 'status')
    mode = _raw(msg, 'faa_mode') if len(msg.data) > 6 else ''
    day = _raw(msg, 'timestamp')
    if day:
        out.append(ClockTime(_day_ns(day), fixed=status == 'A' and mode != 'N'))
    if status != 'A' or mode == 'N':
        if status not in ('A', 'V'):
            raise _Bad('bad_field' if status else 'field_count')
        out.append(Position(math.nan, math.nan, status=-1))
        return out
    lat, lon = _lat_lon(msg)
    out.append(Position(lat, lon))
    return out


def _zda(msg: Any) -> list[Record]:
    day_ns = _day_ns(_raw(msg, 'timestamp'))
    values = [_raw(msg, name) for name in ('day', 'month', 'year')]
    if not all(v.isdigit() for v in values):
        raise _Bad('bad_field' if all(values) else 'not_available')
    day, month, year = (int(v) for v in values)
    return [ClockTime(day_ns, _date_ns(day, month, year) + day_ns)]


def _hdt(msg: Any) -> list[Record]:
    return [Heading(_direction(_float(msg.data[0]) if msg.data else _float('')))]


def _hdg(msg: Any) -> list[Record]:
    heading = _direction(_number(msg, 'heading'))
    deviation = _signed(_number(msg, 'deviation', False), _raw(msg, 'dev_dir'))
    variation = _signed(_number(msg, 'variation', False), _raw(msg, 'var_dir'))
    for value in (deviation, variation):
        if value is not None and abs(value) > 180.0:
            raise _Bad('out_of_range')
    return [Heading(heading, True, None if deviation is None else math.radians(deviation),
                    None if variation is None else math.radians(variation))]


def _hdm(msg: Any) -> list[Record]:
    return [Heading(_direction(_float(msg.data[0]) if msg.data else _float('')), True)]


def _rot(msg: Any) -> list[Record]:
    rate = _number(msg, 'rate_of_turn')
    status = _raw(msg, 'status') if len(msg.data) > 1 else 'A'
    if status not in ('A', ''):
        raise _Bad('invalid')
    assert rate is not None
    return [TurnRate(math.radians(rate) / 60.0)]


def _vhw(msg: Any) -> list[Record]:
    knots = _speed(_number(msg, 'water_speed_knots', False))
    if knots is not None:
        return [WaterSpeed(knots * KNOT)]
    kmh = _speed(_number(msg, 'water_speed_km', False))
    if kmh is None:
        raise _Bad('not_available')
    return [WaterSpeed(kmh / 3.6)]


def _vbw(msg: Any) -> list[Record]:
    if _raw(msg, 'data_validity_water_spd') != 'A':
        raise _Bad('invalid')
    knots = _number(msg, 'lon_water_spd')
    assert knots is not None
    return [WaterSpeed(knots * KNOT)]


def _vtg(msg: Any) -> list[Record]:
    mode = _raw(msg, 'faa_mode') if len(msg.data) > 8 else ''
    if mode == 'N':
        raise _Bad('invalid')
    cog = _number(msg, 'true_track', False)
    knots = _speed(_number(msg, 'spd_over_grnd_kts', False))
    if knots is None:
        kmh = _speed(_number(msg, 'spd_over_grnd_kmph', False))
        knots = None if kmh is None else kmh / 3.6 / KNOT
    if cog is None or knots is None:
        raise _Bad('not_available')
    return [CourseSpeed(_direction(cog), knots * KNOT)]


_XDR_PITCH = ('PTCH', 'PITCH')
_XDR_ROLL = ('ROLL',)


def _xdr(msg: Any) -> list[Record]:
    theta = phi = None
    data = msg.data
    for i in range(0, len(data) - 3, 4):
        kind, value, unit, name = (d.strip() for d in data[i:i + 4])
        if kind != 'A' or unit != 'D' or not value:
            continue
        name = name.upper()
        if name in _XDR_PITCH or name in _XDR_ROLL:
            angle = _float(value)
            assert angle is not None
            if abs(angle) > 180.0:
                raise _Bad('out_of_range')
            if name in _XDR_PITCH:
                theta = math.radians(angle)
            else:
                phi = math.radians(angle)
    if theta is None and phi is None:
        return []
    return [Attitude(None, theta, phi)]


def _tilt(value: float | None) -> float | None:
    if value is None:
        return None
    if abs(value) > 90.0:
        raise _Bad('out_of_range')
    return math.radians(value)


def _accuracy(value: float | None) -> float | None:
    """Return a stated accuracy (deg, one sigma) as a variance (rad^2); None if not > 0."""
    return None if value is None or value <= 0.0 else math.radians(value) ** 2


def _hpr(data: list[str]) -> list[Record]:
    """Return the attitude of [time, heading, pitch, roll, ...] (``$PSAT,HPR``, ``$PASHR,HPR``)."""
    if len(data) < 4:
        raise _Bad('field_count')
    heading = _float(data[1].strip())
    assert heading is not None
    return [Attitude(_direction(heading), _tilt(_float(data[2].strip(), False)),
                     _tilt(_float(data[3].strip(), False)))]


def _pashr(data: list[str]) -> list[Record]:
    """Return the attitude of ``$PASHR``: the RT300/Trimble form, or ``$PASHR,HPR``."""
    fields = [d.strip() for d in data]
    if fields and fields[0] == 'HPR':
        return _hpr(fields[1:])
    # hhmmss.sss, heading, T, roll, pitch, heave, roll acc, pitch acc, heading acc, gnss, imu
    if len(fields) < 5:
        raise _Bad('field_count')
    if fields[2] != 'T':
        raise _Bad('invalid' if fields[2] == '' else 'bad_field')
    heading = _float(fields[1])
    assert heading is not None
    roll_acc, pitch_acc, heading_acc = (_float(fields[i], False) if len(fields) > i else None
                                        for i in (6, 7, 8))
    return [Attitude(_direction(heading), _tilt(_float(fields[4], False)),
                     _tilt(_float(fields[3], False)), _accuracy(heading_acc),
                     _accuracy(pitch_acc), _accuracy(roll_acc))]


def _psat(data: list[str]) -> list[Record]:
    """Return the attitude of ``$PSAT,HPR`` (Hemisphere); other ``$PSAT`` are not read."""
    if not data or data[0].strip() != 'HPR':
        return []
    return _hpr(data[1:])


_TALKER: dict[str, Callable[[Any], list[Record]]] = {
    'RMC': _rmc, 'GGA': _gga, 'GNS': _gns, 'GLL': _gll, 'ZDA': _zda, 'HDT': _hdt, 'HDG': _hdg,
    'HDM': _hdm, 'ROT': _rot, 'VHW': _vhw, 'VBW': _vbw, 'VTG': _vtg, 'XDR': _xdr,
}
_PROPRIETARY: dict[str, Callable[[list[str]], list[Record]]] = {'PASHR': _pashr, 'PSAT': _psat}
#: The sentence types read (the others are counted, not decoded).
KINDS = frozenset(_TALKER) | {'THS'} | frozenset(_PROPRIETARY)


def _ths(data: list[str]) -> list[Record]:
    if len(data) < 2:
        raise _Bad('field_count')
    if data[1].strip() != 'A':
        raise _Bad('invalid')
    heading = _float(data[0].strip())
    assert heading is not None
    return [Heading(_direction(heading))]


_FRAME_RE = re.compile(r'^[$!](?P<address>[A-Za-z0-9]{2,6}),(?P<data>[^*]*)'
                       r'(?:\*(?P<checksum>[0-9A-Fa-f]{2}))?$')


def _address(address: str) -> tuple[str, str]:
    """
    Return (type, talker) of an address field: ``GPGGA`` (GGA, GP), ``PASHR`` (PASHR, '').

    An address starting with P is proprietary (no talker begins with P): its type is the
    whole address.
    """
    if address[0] == 'P':
        return address, ''
    return address[-3:], address[:-3]


def decode(sentence: str, require_checksum: bool, kinds: frozenset[str] | None = None,
           trust_checksum: bool = True) -> Decoded:
    """
    Return the records of one sentence (``$GPRMC,...*hh``), or why it yields none.

    ``require_checksum``: a sentence without ``*hh`` is ``'no_checksum'``; ``trust_checksum``
    False: a checksum is not compared (a logger that writes wrong ones). A sentence type
    that is none of :data:`KINDS` (``$GPGSV``...) is a :class:`Decoded` without records and
    without a skip reason when its checksum holds: well formed, not used. ``kinds``: decode
    only these types; any other is returned as such, its checksum unchecked (a second pass
    that knows what it needs).
    """
    sentence = sentence.strip()
    frame = _FRAME_RE.match(sentence)
    if frame is None:
        return Decoded('', skip='not_nmea')
    checksum = frame.group('checksum')
    if require_checksum and checksum is None:
        return Decoded('', skip='no_checksum')
    kind, talker = _address(frame.group('address').upper())
    if kinds is not None and kind not in kinds:
        return Decoded(kind, talker)
    if checksum is not None:
        if trust_checksum and not checksum_holds(sentence):
            return Decoded('', skip='bad_checksum')
        sentence = sentence[:sentence.rindex('*')]      # checked, or not to be (pynmea2 would)
    if kind not in KINDS or sentence[0] == '!':
        return Decoded(kind, talker)
    if kind == 'THS':
        return _records(kind, talker, lambda: _ths(frame.group('data').split(',')))
    proprietary = _PROPRIETARY.get(kind)
    if proprietary is not None:
        return _records(kind, talker, lambda: proprietary(frame.group('data').split(',')))
    try:
        msg = pynmea2.parse(sentence)
    except (pynmea2.ParseError, ValueError, TypeError, IndexError):
        return Decoded(kind, talker, skip='not_nmea')
    if not isinstance(msg, pynmea2.TalkerSentence):
        return Decoded(kind, talker)
    return _records(kind, talker, lambda: _TALKER[kind](msg))


def _records(kind: str, talker: str, read: Callable[[], list[Record]]) -> Decoded:
    try:
        records = read()
    except _Bad as bad:
        return Decoded(kind, talker, skip=bad.reason)
    except (ValueError, TypeError, IndexError, ArithmeticError, KeyError):
        return Decoded(kind, talker, skip='bad_field')
    return Decoded(kind, talker, records)


# ---------------------------------------------------------------------------------------------
# The clock


@dataclass(slots=True)
class Timed:
    """A decoded line with its time: stamp and arrival (ns), or the reason it has none."""

    decoded: Decoded
    stamp_ns: int
    arrival_ns: int
    skip: str | None = None


class Clock:
    """
    The stamps of a log's lines: its clock sentences' times, and lines spaced evenly between.

    ``kind``, ``talker``: the clock sentence (:func:`clock_priority`); ``date_ns``: the UTC
    midnight of the first day, for a clock of times of day (GGA, GNS, GLL). :meth:`push` takes
    each line in log order (its position: line number or logger time, and its decoded
    sentence) and returns the lines it can now stamp; :meth:`finish` the rest (untimed).
    Lines wait only until the next clock time, so memory stays bounded by the lines of one
    interval (:data:`MAX_SPACED_GAP_NS`, at most ``max_pending`` lines).

    A time out of line with the clock (back, or ahead by more than can be spaced) waits:
    :data:`CONFIRM_TIMES` times in line with each other make it the clock's, and the lines
    before it are untimed; a time back in line with the clock first makes the waiting ones a
    glitch (``time_jump``, their data too) and the lines around them are spaced as if they
    were not there. One garbage date (year 9999) never becomes the time the good lines are
    measured against.
    """

    def __init__(self, kind: str, talker: str, date_ns: int | None = None,
                 max_pending: int = 200_000) -> None:
        self.kind = kind
        self.talker = talker
        self.date_ns = date_ns
        self.max_pending = max_pending
        self._anchor: tuple[int, int] | None = None       # (position, time ns)
        self._anchor_raw: int | None = None                # the anchor's time as said
        #: Times read by their seconds: the receiver's minute had stuck (:meth:`_by_seconds`).
        self.minute_stuck = 0
        #: Times read 1024 weeks later: the receiver is past a GPS week rollover.
        self.rollover = 0
        # Lines since the anchor: (position, logger ns, decoded, its time if a waiting time)
        self._pending: list[tuple[int, int | None, Decoded, int | None]] = []
        self._waiting: list[tuple[int, int]] = []          # the waiting times (position, ns)
        self._trusted = False                             # a time with a fix was seen
        self._rate: float | None = None                   # positions per ns, last interval

    def time_of(self, decoded: Decoded) -> int | None:
        """
        Return the clock time (ns) of a clock sentence, None for any other.

        Until the receiver has had a fix its times are not the clock's: a receiver without
        one sends its own clock's idea of the time (its last, or 1980).
        """
        if decoded.kind != self.kind or decoded.source != self.talker or decoded.skip:
            return None
        for record in decoded.records:
            if isinstance(record, ClockTime):
                if not (record.fixed or self._trusted):
                    return None
                self._trusted = True
                if record.utc_ns is not None:
                    return record.utc_ns
                return self._from_day(record.day_ns)
        return None

    def _from_day(self, day_ns: int) -> int | None:
        """Return a time of day on the day of the clock's time (the next, past its midnight)."""
        if self._anchor is None:
            return None if self.date_ns is None else self.date_ns + day_ns
        last_day = self._anchor[1] % _DAY_NS              # date_ns is a UTC midnight
        base = self._anchor[1] - last_day
        return base + day_ns + (_DAY_NS if day_ns < last_day - _DAY_NS // 2 else 0)

    def push(self, position: int, logger_ns: int | None, decoded: Decoded) -> list[Timed]:
        """Take the next line; return the lines stamped by it (in log order)."""
        t = self.time_of(decoded)
        if t is None:
            return self._hold(position, logger_ns, decoded, None)
        newest = self._waiting[-1] if self._waiting else self._anchor
        if newest is not None and (t == newest[1] or t == self._anchor_raw):
            return self._hold(position, logger_ns,
                              Decoded(decoded.kind, decoded.source, skip='repeated'), None)
        if self._anchor is None or self._in_line(self._anchor, position, t):
            self._refuse()
            return self._stamp(position, logger_ns, decoded, t)
        read = self._past_rollover(position, t)
        if read is not None:
            self.rollover += 1
        else:
            read = self._by_seconds(position, t)
            self.minute_stuck += read is not None
        if read is not None:
            self._refuse()
            return self._stamp(position, logger_ns, decoded, read, raw=t)
        if self._waiting and not self._in_line(self._waiting[-1], position, t):
            self._refuse()
        out = self._hold(position, logger_ns, decoded, t)
        self._waiting.append((position, t))
        return out + (self._adopt() if len(self._waiting) >= CONFIRM_TIMES else [])

    def _past_rollover(self, position: int, t: int) -> int | None:
        """
        Return the time a receiver past a GPS week rollover means, None for any other.

        Such a receiver dates its times 1024 weeks early (its week number wrapped): a time
        in line with the clock once 1024 weeks are added is read so, as gpsd does.
        """
        read = t + _ROLLOVER_NS
        if self._anchor is None or not self._in_line(self._anchor, position, read):
            return None
        return read

    def _by_seconds(self, position: int, t: int) -> int | None:
        """
        Return the time a clock whose minute field stuck means, None for any other.

        A receiver whose minute stopped counting (one given yacht's: its seconds went round
        from :59 to :00 thirteen times within "08:02") gives times back in the hour of the
        clock's last: the seconds are right, so the time is the clock's next one with these
        seconds, when in line.
        """
        raw = self._anchor_raw
        if raw is None or t // _HOUR_NS != raw // _HOUR_NS or t % _MINUTE_NS == raw % _MINUTE_NS:
            return None
        t0 = self._anchor[1]                                  # type: ignore[index]
        read = t0 + (t - t0) % _MINUTE_NS
        return read if self._in_line(self._anchor, position, read) else None  # type: ignore

    def _in_line(self, since: tuple[int, int], position: int, t: int) -> bool:
        """Return True when a time at ``position`` follows the one ``since`` (spaceable)."""
        p0, t0 = since
        return t > t0 and position > p0 and self._spaceable(t - t0, position - p0)

    def _hold(self, position: int, logger_ns: int | None, decoded: Decoded,
              t: int | None) -> list[Timed]:
        """Keep a line until the next clock time; the oldest is untimed past ``max_pending``."""
        self._pending.append((position, logger_ns, decoded, t))
        if len(self._pending) <= self.max_pending:
            return []
        _, _, old, old_t = self._pending.pop(0)
        if old_t is not None:
            self._waiting.pop(0)
        return [Timed(old, -1, -1, 'untimed')]

    def _stamp(self, position: int, logger_ns: int | None, decoded: Decoded,
               t: int, raw: int | None = None) -> list[Timed]:
        """
        Take ``t`` as the clock's next time: stamp the lines since the last one, and it.

        ``raw``: the time the sentence said, where ``t`` is read otherwise (:meth:`_by_seconds`).
        """
        out: list[Timed] = []
        if self._anchor is None:
            out.extend(self._drop('untimed'))
        else:
            p0, t0 = self._anchor
            span, length = t - t0, position - p0
            self._rate = length / span
            for p, logger, item, _ in self._pending:
                # t0 + (p - p0) (t - t0) / (p1 - p0), rounded to the ns, in integers
                stamp = t0 + (2 * (p - p0) * span + length) // (2 * length)
                stamp = min(max(stamp, t0), t)
                out.append(Timed(item, stamp, stamp if logger is None else logger, item.skip))
            self._pending.clear()
        self._anchor = (position, t)
        self._anchor_raw = t if raw is None else raw
        out.append(Timed(decoded, t, t if logger_ns is None else logger_ns))
        return out

    def _refuse(self) -> None:
        """Make the waiting times a glitch: their lines are skipped, the others wait on."""
        if not self._waiting:
            return
        self._waiting.clear()
        self._pending = [(p, logger, item if t is None else
                          Decoded(item.kind, item.source, skip='time_jump'), None)
                         for p, logger, item, t in self._pending]

    def _adopt(self) -> list[Timed]:
        """Take the waiting times as the clock's: the lines before the first are untimed."""
        first = next(i for i, line in enumerate(self._pending) if line[3] is not None)
        before, after = self._pending[:first], self._pending[first:]
        back = self._anchor is not None and self._waiting[0][1] < self._anchor[1]
        self._pending, self._waiting = before, []
        out = list(self._drop('time_jump' if back else 'untimed'))
        self._anchor = self._anchor_raw = None
        for p, logger, item, t in after:
            if t is None:
                self._pending.append((p, logger, item, None))
            else:
                out.extend(self._stamp(p, logger, item, t))
        return out

    def _spaceable(self, span: int, length: int) -> bool:
        """
        Return True when lines can be spaced over ``span`` ns of the clock.

        Up to :data:`MAX_SPACED_GAP_NS` always; up to :data:`MAX_OUTAGE_NS` when the lines
        came at the rate of the interval before, within :data:`RATE_FACTOR` (the clock's
        receiver was silent, the other instruments were not). A logger restarted hours later
        has a few lines in hours: those are untimed.
        """
        if span <= MAX_SPACED_GAP_NS:
            return True
        if self._rate is None or span > MAX_OUTAGE_NS:
            return False
        ratio = length / span / self._rate
        return 1.0 / RATE_FACTOR <= ratio <= RATE_FACTOR

    def _drop(self, reason: str) -> Iterator[Timed]:
        for _, _, item, _ in self._pending:
            yield Timed(item, -1, -1, item.skip or reason)
        self._pending.clear()

    def finish(self) -> list[Timed]:
        """Return the lines after the last clock time (untimed; a step unconfirmed, refused)."""
        self._refuse()
        return list(self._drop('untimed'))

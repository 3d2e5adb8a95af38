"""
The marine readers' parts, each on its own.

NMEA 0183 sentences and clock, NMEA 2000 frames, PGNs and fast packets, the choice of
sources, and the messages.

Independent references: the expected numbers are worked out by hand from the sentences; the
PGNs are checked against the ``nmea2000`` package's decoder (canboat's compiled database, a
test-only dependency); the IMU orientation against scipy's Rotation.
"""

from __future__ import annotations

import datetime
import logging
import math

from hypothesis import given, strategies as st
import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from vessel_kinematics.marine import messages, nmea0183, nmea2000
from vessel_kinematics.marine.assemble import Assembler, Survey
from vessel_kinematics.marine.log import open_log
from vessel_kinematics.marine.nmea0183 import Clock, decode, split_line
from vessel_kinematics.marine.records import (Attitude, ClockTime, CourseSpeed, Decoded,
                                              Heading, KNOT, Position, SKIP_REASONS, TurnRate,
                                              Variation, WaterSpeed)
from vessel_kinematics.tools import bags

NS = 1_000_000_000
DEG = math.pi / 180.0


def _sentence(body: str) -> str:
    checksum = 0
    for c in body:
        checksum ^= ord(c)
    return f'${body}*{checksum:02X}'


def _records(body: str) -> list:
    decoded = decode(_sentence(body), True)
    assert decoded.skip is None, decoded
    return decoded.records


# ---------------------------------------------------------------------------------------------
# NMEA 0183 sentences


def test_rmc_gives_position_course_variation_and_time() -> None:
    clock, variation, position, course = _records(
        'GPRMC,094737,A,5251.0093,N,00518.8170,E,5.6,230.5,200818,1.4,E,A')
    assert clock == ClockTime(35_257 * NS, 1_534_758_457 * NS)
    assert variation.variation == pytest.approx(1.4 * DEG)
    assert position.lat_deg == pytest.approx(52 + 51.0093 / 60, abs=1e-12)
    assert position.lon_deg == pytest.approx(5 + 18.8170 / 60, abs=1e-12)
    assert math.isnan(position.height_m) and position.hdop is None
    assert course.cog == pytest.approx(230.5 * DEG) and course.sog == pytest.approx(5.6 * KNOT)


def test_gga_height_is_altitude_plus_geoid_separation() -> None:
    clock, p = _records('GPGGA,094736.50,5251.0094,S,00518.8172,W,1,12,0.60,-4,M,46.8,M,,')
    assert clock == ClockTime(35_256 * NS + NS // 2)
    assert (p.lat_deg, p.lon_deg) == pytest.approx((-(52 + 51.0094 / 60), -(5 + 18.8172 / 60)))
    assert p.height_m == pytest.approx(42.8) and p.hdop == 0.6 and p.status == 0
    _, no_separation = _records('GPGGA,094736,5251.0094,N,00518.8172,E,2,12,0.6,-4,M,,M,,')
    assert math.isnan(no_separation.height_m) and no_separation.status == 1   # DGPS: SBAS
    _, rtk = _records('GNGGA,094736,5251.0094,N,00518.8172,E,4,12,0.6,-4,M,46.8,M,,')
    assert rtk.status == 2
    for quality in (0, 6, 7, 8):
        _, none = _records(f'GPGGA,094736,,,,,{quality},00,,,M,,M,,')
        assert none.status == -1


def test_headings_true_magnetic_and_attitude() -> None:
    assert _records('HEHDT,231.6,T') == [Heading(pytest.approx(231.6 * DEG))]
    hdg, = _records('HCHDG,229.8,2.0,W,1.3,E')
    assert hdg.magnetic and hdg.psi == pytest.approx(229.8 * DEG)
    assert hdg.deviation == pytest.approx(-2.0 * DEG) and hdg.variation == pytest.approx(1.3 * DEG)
    assert _records('HCHDM,12.5,M')[0].magnetic
    assert _records('HETHS,120.5,A')[0].psi == pytest.approx(120.5 * DEG)
    assert decode(_sentence('HETHS,120.5,V'), True).skip == 'invalid'
    # $PASHR: time, heading, T, roll, pitch, heave, roll/pitch/heading accuracy (deg), ...
    a, = _records('PASHR,094737.000,231.60,T,-2.50,1.25,0.10,0.050,0.060,0.100,2,1')
    assert (a.psi, a.phi, a.theta) == pytest.approx((231.6 * DEG, -2.5 * DEG, 1.25 * DEG))
    assert (a.var_phi, a.var_theta, a.var_psi) == pytest.approx(
        ((0.05 * DEG) ** 2, (0.06 * DEG) ** 2, (0.1 * DEG) ** 2))
    hpr, = _records('PSAT,HPR,094737.10,231.60,1.25,,N')
    assert hpr.psi == pytest.approx(231.6 * DEG) and hpr.theta == pytest.approx(1.25 * DEG)
    assert hpr.phi is None
    ashtech, = _records('PASHR,HPR,094737.10,231.60,1.25,-2.5,0.1,0.2,0,0,2.9,1.5')
    assert ashtech.phi == pytest.approx(-2.5 * DEG)


def test_rate_speed_course_and_attitude_transducers() -> None:
    assert _records('TIROT,-60.0,A')[0].rate == pytest.approx(-DEG)   # deg/min
    assert decode(_sentence('TIROT,12.0,V'), True).skip == 'invalid'
    assert _records('SDVHW,231.3,T,229.9,M,6.6,N,12.3,K')[0].speed == pytest.approx(6.6 * KNOT)
    assert _records('IIVHW,,,252,M,,,12.6,K')[0].speed == pytest.approx(3.5)
    # VBW: the longitudinal water speed, signed (astern negative); the rest is not read
    assert _records('VWVBW,5.6,-0.2,A,5.5,0.1,A')[0].speed == pytest.approx(5.6 * KNOT)
    assert _records('VDVBW,-1.2,0.0,A,,,V')[0].speed == pytest.approx(-1.2 * KNOT)
    vtg, = _records('GPVTG,230.5,T,229.1,M,5.6,N,10.4,K,A')
    assert vtg.cog == pytest.approx(230.5 * DEG) and vtg.sog == pytest.approx(5.6 * KNOT)
    xdr, = _records('YXXDR,A,-1.4,D,PTCH,A,0.8,D,ROLL')
    assert (xdr.theta, xdr.phi) == pytest.approx((-1.4 * DEG, 0.8 * DEG)) and xdr.psi is None
    # B&G's HEEL and TRIM (sailing instruments, brand-specific signs) are not read.
    assert _records('IIXDR,C,,C,AIRTEMP,A,-1.0,D,HEEL,A,2.9,D,TRIM,P,,B,BARO') == []


def test_zda_and_two_digit_years() -> None:
    assert _records('GPZDA,094737.25,20,08,2018,-01,00') == [
        ClockTime(35_257 * NS + NS // 4, 1_534_758_457 * NS + NS // 4)]
    rmc = _records('GPRMC,000000,A,0000.000,N,00000.000,E,0,0,010199,,,A')
    assert rmc[0].utc_ns == 915_148_800 * NS


@pytest.mark.parametrize('line, reason', [
    ('$GPRMC,094737,A,5251.0093,N,00518.8170,E,5.6,230.5,200818,1.4,E,A*10', 'bad_checksum'),
    ('$GPRMC,094737,A,5251.0093,N,00518.8170,E,5.6,230.5,200818,1.4,E,A', 'no_checksum'),
    ('$GPRMC,094737,A,5251.0093,N,00518.8', 'no_checksum'),          # a cut line
    ('$GPRMC,094737,A,5251.0093,N,00518.8170,E,5.6,230.5,200818,1.4,E,A*1', 'not_nmea'),
    ('\x00\x17\xff\xfe$$GP', 'not_nmea'),
    ('GPRMC,094737,A', 'not_nmea'),
])
def test_malformed_sentences_have_their_reason(line: str, reason: str) -> None:
    split = split_line(line)
    decoded = decode(split.sentence, True) if split.sentence else Decoded('', skip=split.skip)
    assert decoded.skip == reason
    assert reason in SKIP_REASONS


@pytest.mark.parametrize('body, reason', [
    ('GPGGA,094736,5251.0094,N,00518.8172,E,1,12,0.60,-4,M', 'field_count'),
    ('GPGGA,094736,52x1.0094,N,00518.8172,E,1,12,0.60,-4,M,46.8,M,,', 'bad_field'),
    ('GPGGA,094736,5261.0094,N,00518.8172,E,1,12,0.60,-4,M,46.8,M,,', 'out_of_range'),
    ('GPGGA,094736,9100.0000,N,00518.8172,E,1,12,0.60,-4,M,46.8,M,,', 'out_of_range'),
    ('GPGGA,094736,5251.0094,X,00518.8172,E,1,12,0.60,-4,M,46.8,M,,', 'bad_field'),
    ('GPGGA,256036,5251.0094,N,00518.8172,E,1,12,0.60,-4,M,46.8,M,,', 'out_of_range'),
    ('GPGGA,094736,5251.0094,N,00518.8172,E,1,12,0.00,-4,M,46.8,M,,', 'out_of_range'),
    ('GPGGA,094736,,,,,1,12,0.6,-4,M,46.8,M,,', 'not_available'),
    ('GPRMC,094737,A,5251.0093,N,00518.8170,E,-5.6,230.5,200818,1.4,E,A', 'out_of_range'),
    ('GPRMC,094737,A,5251.0093,N,00518.8170,E,5.6,230.5,320818,1.4,E,A', 'out_of_range'),
    ('HEHDT,361.0,T', 'out_of_range'),
    ('HEHDT,nan,T', 'bad_field'),
    ('HEHDT,,T', 'not_available'),
    ('SDVHW,,T,,M,,N,,K', 'not_available'),
    ('VWVBW,5.6,-0.2,V,5.5,0.1,A', 'invalid'),
    ('VWVBW,,,A,5.5,0.1,A', 'not_available'),
    ('VWVBW,5.6', 'field_count'),
    ('IIXDR,A,200,D,ROLL', 'out_of_range'),
])
def test_fields_are_read_strictly(body: str, reason: str) -> None:
    assert decode(_sentence(body), True).skip == reason


def test_a_wrong_checksum_is_compared_unless_the_log_says_not() -> None:
    body = 'GPRMC,094737,A,5251.0093,N,00518.8170,E,5.6,230.5,200818,1.4,E,A'
    line = _sentence(body)
    wrong = line[:-2] + f'{int(line[-2:], 16) ^ 0x19:02X}'
    assert nmea0183.checksum_holds(line) and not nmea0183.checksum_holds(wrong)
    assert decode(wrong, True).skip == 'bad_checksum'
    assert decode(wrong, True, trust_checksum=False).records == decode(line, True).records


def test_sentences_not_read_are_counted_not_skipped() -> None:
    for body in ('GPGSV,3,1,12,07,10,333,39', 'WIMWV,57.5,R,13.0,N,A', 'GPGLC,9960,,,,,,,'):
        decoded = decode(_sentence(body), True)
        assert decoded.skip is None and decoded.records == [] and decoded.kind == body[2:5]
    ais = '!AIVDM,1,1,,A,13aEOK?P00PD2wVMdLDRhgvL289?,0*26'
    assert decode(ais, True).kind == 'VDM' and decode(ais, True).skip is None
    # without checksums where the log has none
    assert decode('$HEHDT,10.0,T', False).records == [Heading(pytest.approx(10.0 * DEG))]


def test_logger_times_tag_blocks_and_prefixes() -> None:
    sentence = _sentence('HEHDT,10.0,T')
    tag = 'c:1534758457'
    checksum = 0
    for c in tag:
        checksum ^= ord(c)
    assert split_line(f'\\{tag}*{checksum:02X}\\{sentence}') == nmea0183.Line(
        sentence, 1_534_758_457 * NS)
    assert split_line(f'\\{tag}*00\\{sentence}').skip == 'bad_checksum'
    assert split_line(f'2018-08-20T09:47:37.125Z {sentence}') == nmea0183.Line(
        sentence, 1_534_758_457_125_000_000)
    assert split_line(f'2018-08-20 11:47:37.125+02:00,{sentence}').logger_ns == (
        1_534_758_457_125_000_000)
    assert split_line(f'1534758457.125;{sentence}').logger_ns == 1_534_758_457_125_000_000
    assert split_line(f'5409218 {sentence}') == nmea0183.Line(sentence)      # a counter
    assert split_line(f'junk{sentence}') == nmea0183.Line(sentence)


# ---------------------------------------------------------------------------------------------
# The NMEA 0183 clock


def _clock_line(t_s: float | None) -> Decoded:
    if t_s is None:
        return Decoded('HDT', 'HE', [Heading(0.0)])
    utc = int(round(t_s * NS))
    return Decoded('RMC', 'GP', [ClockTime(utc % (86_400 * NS), utc)])


def _run_clock(times: list[float | None]) -> list[nmea0183.Timed]:
    clock = Clock('RMC', 'GP')
    out = []
    for i, t in enumerate(times):
        out.extend(clock.push(i, None, _clock_line(t)))
    return out + clock.finish()


def test_lines_between_two_times_are_spaced_evenly() -> None:
    # An RMC, 32 lines, the next RMC a second later: line i at t0 + i/33 s (the bags' rule).
    t0 = 1_534_758_457.0
    timed = _run_clock([t0] + [None] * 32 + [t0 + 1.0])
    stamps = [t.stamp_ns for t in timed]
    assert stamps == [int(t0) * NS + round(i * NS / 33) for i in range(33)] + [int(t0 + 1) * NS]
    assert all(t.skip is None and t.arrival_ns == t.stamp_ns for t in timed)


def test_untimed_repeated_and_stepping_back() -> None:
    timed = _run_clock([None, 100.0, None, 100.0, None, 101.0, None])
    skips = [t.skip for t in timed]
    # before the first time and after the last: untimed; the repeat: its data too
    assert skips == ['untimed', None, None, 'repeated', None, None, 'untimed']
    assert [t.stamp_ns for t in timed[2:6]] == [100_250_000_000, 100_500_000_000,
                                                100_750_000_000, 101 * NS]
    # a step back, in line three times: the clock's new time; the lines before it untimed
    timed = _run_clock([100.0, None, 90.0, None, 91.0, None, 92.0, None])
    assert [t.skip for t in timed] == [None, 'time_jump'] + [None] * 5 + ['untimed']
    assert [t.stamp_ns for t in timed[2:7]] == [90 * NS, 90_500_000_000, 91 * NS,
                                                91_500_000_000, 92 * NS]
    # ... a step ahead that cannot be spaced: the same
    timed = _run_clock([100.0, None, 111.0, None, 112.0, None, 113.0])
    assert [t.skip for t in timed] == [None, 'untimed'] + [None] * 5
    # ... and one the log ended before confirming: refused
    timed = _run_clock([100.0, None, 90.0, None, 91.0])
    assert [t.skip for t in timed] == [None, 'untimed', 'time_jump', 'untimed', 'time_jump']


@pytest.mark.parametrize('glitch', [253_402_300_799.0, 0.0, 100.5 - 86_400.0],
                         ids=['9999', '1970', 'a_day_back'])
def test_clock_times_out_of_line_alone_are_refused(glitch: float) -> None:
    # Every other clock time garbage (a date of 9999, 1970, a day back): each had made the
    # clock step and back, and every line around it was untimed. Each is refused alone (its
    # data too); the others are spaced by their places as if it were not there.
    timed = _run_clock([100.0, None, glitch, None, 101.0, None, glitch, None, 102.0])
    assert [t.skip for t in timed] == [None, None, 'time_jump', None, None, None, 'time_jump',
                                       None, None]
    good = [i for i, t in enumerate(timed) if t.skip is None]
    assert [timed[i].stamp_ns for i in good] == [
        100 * NS, 100_250_000_000, 100_750_000_000, 101 * NS, 101_250_000_000,
        101_750_000_000, 102 * NS]


def test_a_receiver_past_a_gps_week_rollover_is_read_1024_weeks_later() -> None:
    # From its fourth time on (and in every other time after), 1024 weeks early: read so.
    rollover = 1024 * 7 * 86_400.0
    said = [1000.0, 1001.0, 1002.0, 1003.0 - rollover, None, 1004.0 - rollover, 1005.0,
            1006.0 - rollover]
    timed = _run_clock(said)
    assert [t.skip for t in timed] == [None] * 8
    assert [t.stamp_ns for t in timed] == [
        1000 * NS, 1001 * NS, 1002 * NS, 1003 * NS, 1_003_500_000_000, 1004 * NS, 1005 * NS,
        1006 * NS]


def test_a_clock_whose_minute_stuck_is_read_by_its_seconds() -> None:
    # A yacht's receiver whose minute stopped counting: 08:02:58, 08:02:59, 08:02:00... Each
    # time back in the hour of the last is read as the clock's next with these seconds (a
    # repeat stays a repeat) until the minute is right again; another hour's is a step.
    day = 1_406_016_000.0                                   # 2014-07-22
    said = [8 * 3600 + 2 * 60 + s for s in (57, 58, 59, 0, 1, 1, 2)] + [8 * 3600 + 3 * 60 + 3]
    timed = _run_clock([day + s for s in said])
    assert [t.skip for t in timed] == [None] * 5 + ['repeated', None, None]
    assert [t.stamp_ns - int(day + said[0]) * NS for t in timed if t.skip is None] == [
        s * NS for s in (0, 1, 2, 3, 4, 5, 6)]
    timed = _run_clock([day + s for s in said[:3]] + [day + said[3] + 3600.0, None])
    assert [t.skip for t in timed] == [None, None, None, 'time_jump', 'untimed']


def test_a_gnss_outage_is_spaced_when_the_lines_came_on() -> None:
    # 10 lines a second, then no time for 60 s: 600 lines (the instruments talked on) are
    # spaced; 3 lines in an hour (a logger restarted) are not.
    t0 = 1000.0
    times = [t0] + [None] * 9 + [t0 + 1.0] + [None] * 599 + [t0 + 61.0]
    timed = _run_clock(times)
    assert [t.skip for t in timed].count(None) == len(times)
    assert timed[310].stamp_ns == int((t0 + 1.0 + 300 / 600 * 60.0) * NS)
    timed = _run_clock([t0] + [None] * 9 + [t0 + 1.0] + [None] * 3 + [t0 + 3601.0])
    assert [t.skip for t in timed[11:14]] == ['untimed'] * 3
    timed = _run_clock([t0, None, t0 + 20.0])            # no rate known yet
    assert timed[1].skip == 'untimed'


def test_a_clock_of_times_of_day_passes_midnight() -> None:
    clock = Clock('GGA', 'GP', date_ns=1_534_723_200 * NS)          # 2018-08-20
    out = []
    for i, day_s in enumerate((86_399.0, None, 0.5)):
        decoded = (Decoded('HDT', 'HE', [Heading(0.0)]) if day_s is None
                   else Decoded('GGA', 'GP', [ClockTime(int(day_s * NS))]))
        out.extend(clock.push(i, None, decoded))
    assert [t.stamp_ns for t in out] == [1_534_809_599 * NS, 1_534_809_599_750_000_000,
                                         1_534_809_600_500_000_000]


def test_logger_time_positions_the_lines() -> None:
    clock = Clock('RMC', 'GP')
    out = []
    for position, decoded in ((0, _clock_line(10.0)), (900_000_000, _clock_line(None)),
                              (1_000_000_000, _clock_line(11.0))):
        out.extend(clock.push(position, position + 5 * NS, decoded))
    assert out[1].stamp_ns == 10_900_000_000 and out[1].arrival_ns == 5_900_000_000


# ---------------------------------------------------------------------------------------------
# NMEA 2000


@given(st.integers(0, 7), st.sampled_from(sorted(nmea2000.PGNS) + [59904, 60928, 126208]),
       st.integers(0, 253), st.integers(0, 255))
def test_can_ids_round_trip(priority: int, pgn: int, source: int, destination: int) -> None:
    ident = nmea2000.can_id(priority, pgn, source, destination)
    got = nmea2000.split_can_id(ident)
    addressed = ((pgn >> 8) & 0xFF) < 240
    assert got == (priority, pgn, source, destination if addressed else 255)


def test_can_id_of_a_known_frame() -> None:
    # canboat's example: 09F80103 is priority 2, PGN 129025 from source 3
    assert nmea2000.split_can_id(0x09F80103) == (2, 129025, 3, 255)


_FRAMES = st.builds(
    nmea2000.Frame, st.integers(1_500_000_000, 2_000_000_000).map(lambda s: s * NS + 123_000_000),
    st.just(nmea2000.TIME_UTC), st.integers(0, 7), st.sampled_from(sorted(nmea2000.PGNS)),
    st.integers(0, 252), st.just(255), st.binary(min_size=8, max_size=8))


@pytest.mark.parametrize('fmt', sorted(nmea2000.FORMATS))
@given(frame=_FRAMES)
def test_capture_lines_round_trip(fmt: str, frame: nmea2000.Frame) -> None:
    if fmt in ('actisense', 'ydraw'):                     # times of day
        frame = nmea2000.Frame(frame.time_ns % (86_400 * NS), nmea2000.TIME_DAY, frame.priority,
                               frame.pgn, frame.source, 255, frame.data, fmt == 'actisense')
    if fmt == 'ikonvert':                                 # whole messages
        frame = nmea2000.Frame(frame.time_ns, frame.time_kind, frame.priority, frame.pgn,
                               frame.source, 255, frame.data, True)
    line = nmea2000.format_line(fmt, frame)
    assert nmea2000.detect([line]) == fmt
    assert nmea2000.parse_line(fmt, line) == frame


def test_capture_lines_of_the_gateways() -> None:
    plain = nmea2000.parse_line('canboat', '2011-11-24-22:42:04.388,2,127251,36,255,8,'
                                           '7d,0b,7d,02,00,ff,ff,ff')
    assert plain.pgn == 127251 and plain.source == 36 and plain.time_kind == nmea2000.TIME_UTC
    assert plain.time_ns == 1_322_174_524_388_000_000
    acti = nmea2000.parse_line('actisense', 'A173321.107 23FF7 1F513 012F3070002F30709F')
    assert (acti.source, acti.destination, acti.priority, acti.pgn) == (0x23, 0xFF, 7, 0x1F513)
    assert acti.time_ns == (17 * 3600 + 33 * 60 + 21) * NS + 107_000_000 and acti.whole
    dump = nmea2000.parse_line('candump', '(1502979132.106111) can0 09F80103#05A0BE1C00A0A0C0')
    assert dump.pgn == 129025 and dump.data == bytes.fromhex('05A0BE1C00A0A0C0')
    ta = nmea2000.parse_line('candump', '(1502979132.106111)  can0  09F80103   [8]  05 A0 BE 1C'
                                        ' 00 A0 A0 C0')
    assert ta == dump
    yd = nmea2000.parse_line('ydraw', '17:33:21.107 R 19F51323 01 2F 30 70 00 2F 30 70')
    assert yd.pgn == 0x1F513 and yd.source == 0x23
    # canboat's sample of a Digital Yacht iKonvert: seconds since it started, base64 data
    ik = nmea2000.parse_line('ikonvert', '!PDGY,127250,2,3,255,481.734,2C20AAAAAAE=')
    assert (ik.pgn, ik.priority, ik.source, ik.destination) == (127250, 2, 3, 255)
    assert ik.time_ns == 481_734_000_000 and ik.time_kind == nmea2000.TIME_RELATIVE
    assert ik.data == bytes.fromhex('d82db40000000001') and ik.whole
    assert nmea2000.parse_line('ikonvert', '!PDGY,127250,2,3,255,481.734,2C20AAAAA') is None
    assert nmea2000.parse_line('ikonvert', '$PDGY,000000,4,,5,482,1,0') is None
    # canboat's Garmin GPSMAP 820 CSV: its clock, then the ms since it started (read)
    g820 = nmea2000.parse_line('garmin', '0,6_21_2015_16_11_14_24931648,127508,Processed,'
                                         'Battery Status,Unknown Manufacturer,6,255,2,1,8,'
                                         '0x017505FF7FFFFFFF')
    assert (g820.pgn, g820.source, g820.priority) == (127508, 6, 2) and not g820.whole
    assert g820.time_ns == 24_931_648_000_000 and g820.time_kind == nmea2000.TIME_RELATIVE
    # PEAK PCAN-View traces: canboat's sample (version 1.1), and the layouts of 1.3 and 2.1
    # (a bus column, a reserved '-', the direction after the id): ms since the trace began
    for line in ('     1)        48.6  Rx     09F11201  8  FF 50 7A FF 7F FF 7F FD ',
                 '     1)        48.6 1  Rx     09F11201 -  8    FF 50 7A FF 7F FF 7F FD',
                 '     1        48.600 DT 1      09F11201 Rx -  8    FF 50 7A FF 7F FF 7F FD'):
        pcan = nmea2000.parse_line('pcan', line)
        assert (pcan.pgn, pcan.source, pcan.priority) == (127250, 1, 2), line
        assert pcan.time_ns == 48_600_000 and pcan.time_kind == nmea2000.TIME_RELATIVE
        assert pcan.data == bytes.fromhex('FF507AFF7FFF7FFD') and not pcan.whole
        assert nmea2000.detect([line, ';$FILEVERSION=1.1']) == 'pcan'
    for fmt, bad in (('pcan', '     1)        48.6  Rx     09F11201  8  FF 50 7A FF 7F FF 7F'),
                     ('pcan', '     1)        48.6  Rx     0201  8  FF 50 7A FF 7F FF 7F FD'),
                     ('canboat', '2011-11-24-22:42:04.388,2,127251,36,255,8,7d,0b'),
                     ('candump', '(1502979132.106111) can0 09F80103#05A0BE1C00A0A0C'),
                     ('actisense', 'A173321.107 23FF7 1F513 012F307')):
        assert nmea2000.parse_line(fmt, bad) is None


def test_fast_packets_are_reassembled_per_source() -> None:
    payload_a, payload_b = bytes(range(43)), bytes(range(100, 143))
    fast = nmea2000.FastPacket()
    frames_a = nmea2000.fast_packet_frames(payload_a, 1)
    frames_b = nmea2000.fast_packet_frames(payload_b, 5)
    assert len(frames_a) == 7 and all(len(f) == 8 for f in frames_a)
    done = []
    for fa, fb in zip(frames_a, frames_b):                  # two receivers, interleaved
        for source, data in ((1, fa), (2, fb)):
            got = fast.push(nmea2000.Frame(0, nmea2000.TIME_UTC, 3, 129029, source, 255, data))
            if got is not None:
                done.append((source, got))
    assert done == [(1, payload_a), (2, payload_b)] and fast.broken == 0
    # a frame lost: the message is dropped and counted; a start missed: nothing
    for data in frames_a[:3] + frames_a[4:]:
        assert fast.push(nmea2000.Frame(0, nmea2000.TIME_UTC, 3, 129029, 1, 255, data)) is None
    assert fast.broken == 1
    for data in frames_a[1:]:
        assert fast.push(nmea2000.Frame(0, nmea2000.TIME_UTC, 3, 129029, 1, 255, data)) is None
    assert fast.finish() == 0


_RECORDS = st.one_of(
    st.builds(Position, st.floats(-90, 90), st.floats(-180, 180)),
    st.builds(Heading, st.floats(0, 6.28318), st.booleans(),
              st.none() | st.floats(-3.14, 3.14), st.none() | st.floats(-3.14, 3.14)),
    st.builds(TurnRate, st.floats(-60, 60)),
    st.builds(Attitude, st.none() | st.floats(0, 6.28318), st.none() | st.floats(-1.5, 1.5),
              st.none() | st.floats(-3.14, 3.14)),
    st.builds(Variation, st.floats(-3.14, 3.14)),
    st.builds(WaterSpeed, st.floats(0, 600)),
    st.builds(CourseSpeed, st.floats(0, 6.28318), st.floats(0, 600), st.booleans()),
)


def _close(a: float | None, b: float | None, resolution: float) -> bool:
    if a is None or b is None:
        return a is b
    return abs(a - b) <= 0.51 * resolution + 1e-12


@given(_RECORDS)
def test_pgns_round_trip_to_their_resolution(record) -> None:
    pgn, payload = nmea2000.encode(record, sid=3)
    decoded = nmea2000.decode(pgn, payload, 1)
    if isinstance(record, Attitude) and record.psi is record.theta is record.phi is None:
        assert decoded.skip == 'not_available'
        return
    assert decoded.skip is None, decoded
    got, = decoded.records
    assert type(got) is type(record)
    resolution = {Position: 1e-7, TurnRate: 3.125e-8, WaterSpeed: 0.01, CourseSpeed: 1e-4}.get(
        type(record), 1e-4)
    for name in record.__slots__:
        want, have = getattr(record, name), getattr(got, name)
        if isinstance(want, bool) or name in ('hdop', 'status', 'variance') or (
                name.startswith('var_')):
            continue
        if name == 'height_m':
            assert math.isnan(have)
            continue
        if name in ('psi', 'cog') and want is not None and have is not None:
            want, have = math.remainder(want, 2 * math.pi), math.remainder(have, 2 * math.pi)
        step = 0.01 if name == 'sog' else resolution
        assert _close(want, have, step), (name, want, have)


def test_gnss_position_data_round_trips() -> None:
    p = Position(63.4412345678, -10.4012345678, -12.345678, 0.66, 1)
    payload = nmea2000.encode_gnss(p, 1_717_200_000 * NS + 3_600_500_000_000, sid=9)
    assert len(payload) == 43
    when, got = nmea2000.decode(129029, payload, 1).records
    assert when == ClockTime(3_600_500_000_000, 1_717_203_600_500_000_000)
    assert (got.lat_deg, got.lon_deg) == pytest.approx((p.lat_deg, p.lon_deg), abs=1e-13)
    assert got.height_m == pytest.approx(p.height_m, abs=1e-6)
    assert got.hdop == pytest.approx(0.66) and got.status == 1
    no_fix = nmea2000.encode_gnss(Position(math.nan, math.nan, status=-1), 0)
    assert nmea2000.decode(129029, no_fix, 1).records[-1].status == -1


def test_a_height_no_vessel_has_leaves_the_fix_horizontal() -> None:
    """
    A 129029 whose height field is a receiver's fill goes out with a NaN altitude.

    The payload is the first 129029 of source 3 in canboat's
    ``furuno-fap7011c-autopilot-maneuvers.raw``: its height reads 1.44e12 m, which the
    navigator refuses (with the whole fix); the position itself is sound.
    """
    payload = bytes.fromhex('ae000014000014007885a6a50b37050098fc6cca2bf6ee0014000014000014'
                            '1000140000140000140000140000140000')
    position = nmea2000.decode(129029, payload, 3).records[-1]
    assert position.height_m == pytest.approx(1.4411519666579e12)
    fix = messages.fix_msg(1_628_250_330 * NS, position)
    assert math.isnan(fix.altitude) and fix.status.status == 0
    assert (fix.latitude, fix.longitude) == pytest.approx((37.57819, -122.77457))
    for height in (-11_000.0, 0.0, 49_000.0):        # within the navigator's limits: kept
        kept = messages.fix_msg(0, Position(37.5, -122.7, height, None, 0))
        assert kept.altitude == height


def test_pgns_marked_not_available_or_short() -> None:
    assert nmea2000.decode(129025, b'\xff\xff\xff\x7f\x00\x00\x00\x00').skip == 'not_available'
    assert nmea2000.decode(127250, b'\x00\xff\xff' + b'\x00' * 5).skip == 'not_available'
    assert nmea2000.decode(129025, b'\x00' * 7).skip == 'field_count'
    assert nmea2000.decode(129025, (1_000_000_000).to_bytes(4, 'little', signed=True)
                           + b'\x00' * 4).skip == 'out_of_range'        # latitude 100 deg
    assert nmea2000.decode(130306, b'\x00' * 8) == Decoded('130306', '0')   # not read


def _reference(pgn: int, payload: bytes) -> dict:
    """Decode one PGN with the nmea2000 package (canboat's database): {field id: value}."""
    package = pytest.importorskip('nmea2000.decoder')
    logging.getLogger('nmea2000').setLevel(logging.ERROR)
    decoder = package.NMEA2000Decoder(already_combined=True)
    line = (f'2024-06-01T12:00:00.000Z,2,{pgn},1,255,{len(payload)},'
            + ','.join(f'{b:02x}' for b in payload))
    msg = decoder.decode(line)
    return {f.id: f.value for f in msg.fields}


#: Per PGN, fields drawn within their range (offset, bits, signed, low, high raw), over random
#: bytes, so that most payloads are values (a random angle is mostly out of range).
_IN_RANGE = {
    127250: [(8, 16, False, 0, 62831), (56, 2, False, 0, 1)],
    127257: [(8, 16, True, -31415, 31415), (24, 16, True, -15707, 15707),
             (40, 16, True, -31415, 31415)],
    127258: [(32, 16, True, -31415, 31415)],
    129025: [(0, 32, True, -900_000_000, 900_000_000),
             (32, 32, True, -1_800_000_000, 1_800_000_000)],
    129026: [(8, 2, False, 0, 1), (16, 16, False, 0, 62831)],
    129029: [(56, 64, True, -9 * 10 ** 17, 9 * 10 ** 17),
             (120, 64, True, -18 * 10 ** 17, 18 * 10 ** 17), (252, 4, False, 1, 5)],
}
_FIELDS = {
    127250: ('heading', 'deviation', 'variation'), 127251: ('rate',),
    127257: ('yaw', 'pitch', 'roll'), 127258: ('variation',), 128259: ('speedWaterReferenced',),
    129025: ('latitude', 'longitude'), 129026: ('cog', 'sog'), 126992: ('date', 'time'),
    129029: ('latitude', 'longitude', 'altitude', 'hdop'),
}


def _payload(rng: np.random.Generator, pgn: int) -> bytes:
    length = 43 if pgn == 129029 else 8
    bits = int.from_bytes(rng.bytes(length), 'little')
    for offset, size, _, low, high in _IN_RANGE.get(pgn, ()):
        if rng.random() < 0.1:
            continue                                   # sometimes out of range, or missing
        raw = int(rng.integers(low, high, endpoint=True)) % (1 << size)
        bits = bits & ~(((1 << size) - 1) << offset) | raw << offset
    return bits.to_bytes(length, 'little')


def _values(decoded: Decoded) -> dict:
    """Return our decoded values under canboat's field ids."""
    values: dict = {}
    for record in decoded.records:
        if isinstance(record, Heading):
            values.update(heading=record.psi, deviation=record.deviation,
                          variation=record.variation)
        elif isinstance(record, TurnRate):
            values['rate'] = record.rate
        elif isinstance(record, Attitude):
            values.update(yaw=None if record.psi is None else math.remainder(record.psi,
                                                                             2 * math.pi),
                          pitch=record.theta, roll=record.phi)
        elif isinstance(record, Variation):
            values['variation'] = record.variation
        elif isinstance(record, WaterSpeed):
            values['speedWaterReferenced'] = record.speed
        elif isinstance(record, CourseSpeed):
            values.update(cog=record.cog, sog=record.sog)
        elif isinstance(record, Position) and record.status >= 0:
            values.update(latitude=record.lat_deg, longitude=record.lon_deg,
                          altitude=None if math.isnan(record.height_m) else record.height_m,
                          hdop=record.hdop)
        elif isinstance(record, ClockTime):
            values.update(date=datetime.date(1970, 1, 1) + datetime.timedelta(
                days=record.utc_ns // (86_400 * NS)), time=record.day_ns // NS)
    return values


@pytest.mark.parametrize('pgn', sorted(nmea2000.PGNS))
def test_pgns_decode_as_canboat_does(pgn: int) -> None:
    rng = np.random.default_rng(pgn)
    compared = 0
    for _ in range(300):
        payload = _payload(rng, pgn)
        ours = nmea2000.decode(pgn, payload, 1)
        ref = _reference(pgn, payload)
        if ours.skip is not None:
            # refused: marked missing, or outside the field's range (canboat decodes those)
            assert ours.skip in ('not_available', 'out_of_range'), ours
            continue
        compared += 1
        values = _values(ours)
        for name in _FIELDS[pgn]:
            if name not in values:
                continue
            mine, theirs = values[name], ref[name]
            if name == 'time' and theirs is not None:
                theirs = theirs.hour * 3600 + theirs.minute * 60 + theirs.second
            elif name == 'hdop' and theirs is not None and theirs <= 0:
                theirs = None                          # ours: a non-positive HDOP is unknown
            if mine is None or theirs is None:
                assert mine is None and theirs is None, (name, mine, theirs)
            elif isinstance(mine, float):
                assert mine == pytest.approx(theirs, rel=1e-12, abs=1e-12), (name, mine, theirs)
            else:
                assert mine == theirs, (name, mine, theirs)
    # most payloads are values: the test cannot pass by refusing them all
    assert compared >= 150, compared


def test_detect_needs_a_third_of_the_lines() -> None:
    line = '(1502979132.106111) can0 09F80103#05A0BE1C00A0A0C0'
    assert nmea2000.detect([line, 'junk', '# comment']) == 'candump'
    assert nmea2000.detect([line, 'junk', 'junk', 'junk']) is None
    assert nmea2000.detect([]) is None


# ---------------------------------------------------------------------------------------------
# Choosing the sources; composing the IMU


def _decoded(kind: str, source: str, *records) -> Decoded:
    return Decoded(kind, source, list(records))


def test_one_source_per_role_by_priority_and_plenty() -> None:
    survey = Survey()
    for _ in range(10):
        survey.add(_decoded('RMC', 'GP', Position(1, 2), CourseSpeed(0, 1)))
        survey.add(_decoded('GLL', 'GP', Position(1, 2)))
        survey.add(_decoded('HDT', 'HE', Heading(0)))
        survey.add(_decoded('HDT', 'IN', Heading(0)))
        survey.add(_decoded('HDT', 'IN', Heading(0)))
    for _ in range(6):
        survey.add(_decoded('GGA', 'GP', Position(1, 2, hdop=1.0)))
    survey.add(_decoded('PASHR', '', Attitude(0.0, 0.1, 0.1)))          # once
    survey.add(_decoded('GGA', 'GN', Position(math.nan, math.nan, status=-1)))
    roles = survey.roles(nmea0183.PRIORITIES)
    assert roles['fix'] == ('GGA', 'GP')           # 6 >= 10 / 2
    assert roles['heading'] == ('HDT', 'IN')       # 20 of IN against 10 of HE; PASHR once
    assert roles['cog'] == ('RMC', 'GP')
    assert roles['attitude'] == ('PASHR', '') and roles['rate'] is None


def test_the_position_comes_from_the_receiver_of_the_course_over_ground() -> None:
    # Two receivers on one bus, as in canboat's Furuno captures: source 25 sends positions at
    # 8 Hz, the satellite compass (52) at 5 Hz with the COG/SOG at 4 Hz (25's at 3.6 Hz).
    survey = Survey()
    for n, source in ((8, '25'), (5, '52')):
        for _ in range(n):
            survey.add(_decoded('129025', source, Position(1, 2)))
    for n, source in ((36, '25'), (40, '52')):
        for _ in range(n):
            survey.add(_decoded('129026', source, CourseSpeed(0, 1)))
    roles = survey.roles(nmea2000.PRIORITIES)
    assert roles['cog'] == ('129026', '52') and roles['fix'] == ('129025', '52')
    # ... unless that receiver sends fewer than half as many positions as the other.
    for _ in range(3):
        survey.add(_decoded('129025', '25', Position(1, 2)))
    assert survey.roles(nmea2000.PRIORITIES)['fix'] == ('129025', '25')     # 5 < 11 / 2


def test_a_source_reading_one_value_throughout_is_left_out() -> None:
    # Three paddlewheels on one bus, as on canboat's triton-engine-setup capture: two read
    # 0.00 m/s throughout (unfitted, uncalibrated), the one that works sends fewest.
    survey = Survey()
    for i in range(20):
        survey.add(_decoded('128259', '33', WaterSpeed(0.0)))
        survey.add(_decoded('128259', '34', WaterSpeed(0.0)))
        if i % 2:
            survey.add(_decoded('128259', '35', WaterSpeed(3.0 + 0.01 * i)))
        survey.add(_decoded('129025', '52', Position(1.0 + 1e-5 * i, 2.0)))
        survey.add(_decoded('127250', '27', Heading(0.5)))          # one heading source
    roles = survey.roles(nmea2000.PRIORITIES)
    assert roles['speed'] == ('128259', '35')
    assert set(survey.constant('speed')) == {('128259', '33'), ('128259', '34')}
    # A constant source is no fault when nothing else gives the role (a moored boat, a
    # steady course): the one compass is used.
    assert roles['heading'] == ('127250', '27') and survey.constant('heading') == {}
    # Once another compass turns, the stuck one is left out, however plentiful.
    survey.add(_decoded('127250', '20', Heading(0.1)))
    survey.add(_decoded('127250', '20', Heading(0.2)))
    assert survey.roles(nmea2000.PRIORITIES)['heading'] == ('127250', '20')


def test_a_true_heading_before_a_magnetic_one_of_the_same_pgn() -> None:
    # A fluxgate (magnetic, 20 Hz) and a satellite compass (true, 10 Hz) both send 127250,
    # as on canboat's maneuvers capture: the true one, as NMEA 0183's HDT before HDM ...
    survey = Survey()
    for i in range(20):
        survey.add(_decoded('127250', '27', Heading(0.1 * i, magnetic=True)))
        survey.add(_decoded('127250', '27', Heading(0.1 * i + 0.05, magnetic=True)))
        survey.add(_decoded('127250', '52', Heading(0.1 * i + 0.02)))
    assert survey.roles(nmea2000.PRIORITIES)['heading'] == ('127250', '52')
    # ... unless it sends fewer than half as many.
    for i in range(10):
        survey.add(_decoded('127250', '27', Heading(0.01 * i, magnetic=True)))
    assert survey.roles(nmea2000.PRIORITIES)['heading'] == ('127250', '27')


def test_a_dead_paddlewheel_is_named_in_the_logs_summary(tmp_path) -> None:
    # The same through a capture: the summary says which source was left out, and why.
    t0 = 1_700_000_000 * 1_000_000_000
    lines = []
    for i in range(40):
        t = t0 + i * 250_000_000
        for source, record in ((52, Position(52.0 + 1e-5 * i, 5.0)),
                               (33, WaterSpeed(0.0)), (35, WaterSpeed(2.0 + 0.05 * (i % 7)))):
            pgn, payload = nmea2000.encode(record)
            lines.append(nmea2000.format_line('canboat', nmea2000.Frame(
                t, nmea2000.TIME_UTC, 2, pgn, source, 255, payload)))
    path = tmp_path / 'bus.raw'
    path.write_text('\n'.join(lines) + '\n')
    log = open_log(path)
    log.open()
    assert log.roles['speed'] == ('128259', '35')
    assert log.counts.sources['/speed_log'] == 'PGN 128259 (source 35)'
    assert ('speed: PGN 128259 (source 33) read 0.00 m/s throughout while another source '
            'changed: a dead instrument, not used') in log.counts.notes


def _imu(out: list) -> object:
    (topic, msg), = out
    assert topic == messages.IMU_TOPIC
    return msg


def _yaw_enu(msg) -> float:
    o = msg.orientation
    return math.atan2(2 * (o.w * o.z + o.x * o.y), 1 - 2 * (o.y ** 2 + o.z ** 2))


def test_magnetic_headings_made_true_with_the_logs_variation() -> None:
    roles = {'fix': ('RMC', 'GP'), 'heading': ('HDM', 'HC'), 'attitude': ('XDR', 'YX'),
             'rate': ('ROT', 'TI'), 'speed': None, 'cog': ('RMC', 'GP')}
    a = Assembler(roles)
    msg = _imu(a.feed(0, _decoded('HDM', 'HC', Heading(10 * DEG, True))))
    assert a.magnetic_only == 1 and _yaw_enu(msg) == pytest.approx(80 * DEG)
    out = a.feed(1, _decoded('RMC', 'GP', Variation(-4 * DEG), Position(1, 2),
                             CourseSpeed(10 * DEG, 1.0, True)))
    assert [t for t, _ in out] == [messages.FIX_TOPIC, messages.COG_SOG_TOPIC,
                                   messages.GNSS_VELOCITY_TOPIC]
    assert out[1][1].vector.x == pytest.approx(6 * DEG)
    a.feed(2, _decoded('ROT', 'TI', TurnRate(0.1)))
    a.feed(3, _decoded('XDR', 'YX', Attitude(None, 0.02, -0.03)))
    msg = _imu(a.feed(4, _decoded('HDM', 'HC', Heading(10 * DEG, True, 1 * DEG))))
    assert _yaw_enu(msg) == pytest.approx(83 * DEG)             # 10 + 1 - 4 = 7 deg true
    assert msg.angular_velocity.z == pytest.approx(-0.1)
    assert msg.orientation_covariance[0] == messages.ATTITUDE_SIGMA ** 2
    late = 4 + 2 * 1_500_000_000
    msg = _imu(a.feed(late, _decoded('HDM', 'HC', Heading(10 * DEG, True))))
    assert msg.angular_velocity_covariance[0] == -1.0            # the rate is stale
    assert msg.orientation_covariance[0] == messages.UNKNOWN_ANGLE_VARIANCE


# ---------------------------------------------------------------------------------------------
# Messages


@given(st.floats(0, 2 * math.pi, exclude_max=True), st.floats(-1.4, 1.4), st.floats(-3.1, 3.1))
def test_imu_orientation_is_reps_enu_flu(psi: float, theta: float, phi: float) -> None:
    msg = messages.imu_msg(0, psi, theta, phi)
    # independently: R_enu_flu = A_world R_nb A_body, R_nb = Rz(psi) Ry(theta) Rx(phi)
    r_nb = Rotation.from_euler('ZYX', [psi, theta, phi]).as_matrix()
    a_world = np.array([[0.0, 1, 0], [1, 0, 0], [0, 0, -1]])
    a_body = np.diag([1.0, -1, -1])
    want = Rotation.from_matrix(a_world @ r_nb @ a_body).as_quat()
    o = msg.orientation
    assert abs(np.dot(want, [o.x, o.y, o.z, o.w])) == pytest.approx(1.0, abs=1e-9)


def test_message_conventions_of_the_bags() -> None:
    fix = messages.fix_msg(5, Position(52.0, 5.0, 42.8, 0.6))
    assert list(fix.position_covariance) == pytest.approx([2.25, 0, 0, 0, 2.25, 0, 0, 0, 9.0])
    assert fix.position_covariance_type == 1 and fix.header.frame_id == 'gnss'
    unknown = messages.fix_msg(5, Position(52.0, 5.0))
    assert unknown.position_covariance_type == 0 and not any(unknown.position_covariance)
    no_fix = messages.fix_msg(5, Position(math.nan, math.nan, status=-1))
    assert no_fix.status.status == -1 and math.isnan(no_fix.latitude)
    imu = messages.imu_msg(5, 1.0)
    assert list(imu.orientation_covariance[[0, 4, 8]]) == pytest.approx(
        [1e3, 1e3, (1 * DEG) ** 2])
    assert imu.angular_velocity_covariance[0] == imu.linear_acceleration_covariance[0] == -1
    speed = messages.speed_msg(5, 3.0)
    assert speed.twist.covariance[0] == 0.01 and speed.twist.covariance[7] == 1e6
    cog = messages.cog_sog_msg(7, 1.5, 2.5)
    assert (cog.vector.x, cog.vector.y, cog.header.stamp.nanosec) == (1.5, 2.5, 7)
    store = messages.typestore()
    for msg in (fix, imu, speed, cog):
        back = store.deserialize_cdr(bags.serialize(msg), msg.__msgtype__)
        assert back.header == msg.header


def test_gns_and_gll_positions() -> None:
    clock, p = _records('GNGNS,094736.00,5251.0094,N,00518.8172,E,ADN,14,0.7,-4.0,46.8,,')
    assert clock == ClockTime(35_256 * NS) and p.status == 1 and p.hdop == 0.7
    assert p.height_m == pytest.approx(42.8)
    _, none = _records('GNGNS,094736.00,,,,,NNN,00,,,,,')
    assert none.status == -1
    clock, p = _records('GPGLL,5251.0093,N,00518.8170,E,094736,A,A')
    assert clock.fixed and p.lat_deg == pytest.approx(52 + 51.0093 / 60)
    clock, none = _records('GPGLL,,,,,094736,V,N')
    assert not clock.fixed and none.status == -1


def test_the_clock_starts_with_the_first_fix() -> None:
    # A receiver without a fix sends its own clock's time (here 1980): not the log's time.
    def rmc(body: str) -> Decoded:
        return decode(_sentence(body), True)

    clock = Clock('RMC', 'GP')
    out = []
    for i, decoded in enumerate((
            rmc('GPRMC,000012,V,,,,,,,060180,,,N'), rmc('HEHDT,1.0,T'),
            rmc('GPRMC,094737,A,5251.0093,N,00518.8170,E,5.6,230.5,200818,1.4,E,A'),
            rmc('HEHDT,2.0,T'), rmc('GPRMC,094738,V,,,,,,,200818,,,N'), rmc('HEHDT,3.0,T'),
            rmc('GPRMC,094739,V,,,,,,,200818,,,N'))):
        out.extend(clock.push(i, None, decoded))
    out.extend(clock.finish())
    assert [t.skip for t in out] == ['untimed', 'untimed', None, None, None, None, None]
    # after the first fix, the receiver's time goes on through an outage
    assert [t.stamp_ns for t in out[2:]] == [
        1_534_758_457 * NS, 1_534_758_457_500_000_000, 1_534_758_458 * NS,
        1_534_758_458_500_000_000, 1_534_758_459 * NS]


def test_prefixes_of_other_loggers() -> None:
    sentence = _sentence('HEHDT,10.0,T')
    assert split_line(f'1436182345632;A;{sentence}').logger_ns == 1_436_182_345_632_000_000
    frame = nmea2000.parse_line('canboat', '2016-04-09T18:41:09.078+02:00,3,127257,17,255,8,'
                                           '00,ff,7f,52,00,21,fe,ff')
    assert frame.time_ns == 1_460_220_069_078_000_000        # 16:41:09.078Z

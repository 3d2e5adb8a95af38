"""
NMEA 2000 captures: gateway log lines into frames, fast packets into messages, PGNs into records.

Capture formats (:data:`FORMATS`; :func:`detect` tells them apart by their lines):

==============  ===========================================================  ================
name            a line                                                       time
==============  ===========================================================  ================
``canboat``     ``2016-04-09T16:41:09.078Z,3,127257,17,255,8,00,ff,...``     UTC date, time
                canboat's PLAIN (one CAN frame, len <= 8) and FAST (a whole  (or time of day)
                message, len > 8) text, as actisense-serial, candump2analyzer
                and Signal K's canboatjs write it
``actisense``   ``A173321.107 23FF7 1F513 012F3070002F30709F``               time of day
                Actisense N2K ASCII (NGT-1/W2K-1 "N2K ASCII", NMEA Reader):
                whole messages
``candump``     ``(1502979132.106111) can0 09F80103#05A0BE1C00A0A0C0``       Unix time
                SocketCAN ``candump -l``, also ``candump -ta`` (``[8] 05 A0 ...``):
                CAN frames
``ydraw``       ``17:33:21.107 R 19F51323 01 2F 30 70 00 2F 30 70``          time of day
                Yacht Devices YDWG-02/YDEN-02 RAW: CAN frames
``garmin``      ``133,491411,129025,Position - Rapid Update,Unknown ...,3,   ms since the
                255,2,1,8,0x04D2FB1C46CE9105``                               plotter started
                a Garmin chartplotter's NMEA 2000 CSV (sequence, time, PGN,  (or Unix ms)
                name, manufacturer, source, destination, priority, single
                frame, size, data): whole messages; a GPSMAP 8x0's time
                ``6_21_2015_16_11_14_24931648`` (its clock, then the ms
                since it started: those are read)
``pcan``        ``  1)  48.6  Rx  09F11201  8  FF 50 7A FF 7F FF 7F FD``     ms since the
                PEAK PCAN-View trace (``.trc``, versions 1.1-2.1: message    trace began
                number, time offset, [bus], direction, CAN id, length,
                data): CAN frames; its ``;`` header lines are skipped
``ikonvert``    ``!PDGY,127250,2,3,255,481.734,2C20AAAAAAE=``                s since the
                Digital Yacht iKonvert (PGN, priority, source, destination,  gateway started
                time, base64 data): whole messages; its ``$PDGY`` status
                lines are skipped
==============  ===========================================================  ================

Each of these may also come as Signal K server's data log writes it (``skserver-raw_*.log``:
``1471172400153;A;`` before the gateway's line, the server's receipt time in Unix ms, ignored:
the line's own time is the gateway's).

A capture of SocketCAN packets, ``pcap`` (tcpdump, Wireshark: pcap or pcapng), is read by
:mod:`vessel_kinematics.marine.pcap` into the same frames, an Actisense NMEA Reader log, ``ebl``,
by :mod:`vessel_kinematics.marine.ebl`, a raw NGT-1 stream (Yacht Devices' ``.dle``), ``dle``, by
:mod:`vessel_kinematics.marine.dle` (:data:`CAPTURE_FORMATS`: all of them).

A capture without a date (time of day) or with relative times is put on UTC by its GNSS times
(PGN 126992 system time, else 129029's date and time): one offset for the whole capture, the
median of its first messages' (one wrong date, 0 before a fix, does not date it), so the
capture's own clock keeps its resolution.

PGNs (field layouts from canboat's PGN database, ``canboat.json``: bit offsets, resolutions,
the reserved top values that mean "not available" or "error"):

=========  ========================  ====================================================
PGN        canboat id                records
=========  ========================  ====================================================
126992     systemTime                date and time
127250     vesselHeading             heading (true, or magnetic with deviation, variation)
127251     rateOfTurn                rate of turn
127257     attitude                  yaw (true heading), pitch, roll
127258     magneticVariation         variation
128259     speed                     speed through water
129025     positionRapidUpdate       position
129026     cogSogRapidUpdate         COG (true or magnetic), SOG
129029     gnssPositionData          position, WGS-84 height, HDOP, method; date and time
                                     (a fast packet: reassembled from its frames)
=========  ========================  ====================================================

Decoding by hand, not through the ``nmea2000`` package (a compiled wheel built on canboat's
database): it reads gateways' streams well, but for logs it stamps some formats with the
reading computer's clock (N2K ASCII, candump without time), it needs python-can, pyserial-asyncio,
tenacity and orjson at run time, and the nine PGNs here are fixed-layout structs of a few lines
each. The tests check every PGN and the writer's frames against ``nmea2000``'s decoder.
"""

from __future__ import annotations

import binascii
import calendar
from dataclasses import dataclass
import datetime
import math
import re
from typing import Callable, Iterable

from vessel_kinematics.marine.records import (Attitude, ClockTime, CourseSpeed, Decoded,
                                              Heading, Position, Record, TurnRate, Variation,
                                              WaterSpeed, wrap_2pi)

__all__ = ['can_id', 'CAPTURE_FORMATS', 'decode', 'detect', 'encode', 'encode_gnss',
           'FAST_PGNS', 'fast_packet_frames', 'FastPacket', 'format_line', 'FORMATS', 'Frame',
           'COMMENTS', 'matches', 'parse_line', 'PGNS', 'PRIORITIES', 'split_can_id', 'TIME_DAY',
           'time_kind', 'TIME_RELATIVE', 'TIME_UTC', 'unwrap']

_NS = 1_000_000_000
_DAY_NS = 86_400 * _NS

#: Kinds of capture time: UTC, time of day (no date), relative (since the capture began).
TIME_UTC, TIME_DAY, TIME_RELATIVE = 'utc', 'day', 'relative'

#: The PGNs read, and their canboat ids.
PGNS: dict[int, str] = {
    126992: 'systemTime', 127250: 'vesselHeading', 127251: 'rateOfTurn', 127257: 'attitude',
    127258: 'magneticVariation', 128259: 'speed', 129025: 'positionRapidUpdate',
    129026: 'cogSogRapidUpdate', 129029: 'gnssPositionData',
}
#: The fast-packet PGNs among them (a message spread over several CAN frames).
FAST_PGNS = frozenset({129029})

#: The PGNs each role is read from, best first (the rapid position first, as the given bag).
PRIORITIES: dict[str, tuple[str, ...]] = {
    'fix': ('129025', '129029'),
    'heading': ('127257', '127250'),
    'attitude': ('127257',),
    'rate': ('127251',),
    'speed': ('128259',),
    'cog': ('129026',),
}


@dataclass(frozen=True, slots=True)
class Frame:
    """One line of a capture: its time (ns, of ``time_kind``), CAN header and data bytes."""

    time_ns: int
    time_kind: str
    priority: int
    pgn: int
    source: int
    destination: int
    data: bytes
    #: True when ``data`` is a whole message (a gateway reassembled it), not one CAN frame.
    whole: bool = False


def split_can_id(can_id: int) -> tuple[int, int, int, int]:
    """Return (priority, PGN, source, destination) of a 29-bit CAN id (ISO 11783-3)."""
    priority = (can_id >> 26) & 0x7
    pdu_format = (can_id >> 16) & 0xFF
    specific = (can_id >> 8) & 0xFF
    source = can_id & 0xFF
    if pdu_format < 240:                                  # PDU1: addressed
        return priority, (can_id >> 8) & 0x3FF00, source, specific
    return priority, (can_id >> 8) & 0x3FFFF, source, 255


def can_id(priority: int, pgn: int, source: int, destination: int = 255) -> int:
    """Return the 29-bit CAN id of a frame (the inverse of :func:`split_can_id`)."""
    if ((pgn >> 8) & 0xFF) < 240:
        pgn = (pgn & 0x3FF00) | (destination & 0xFF)
    return ((priority & 0x7) << 26) | ((pgn & 0x3FFFF) << 8) | (source & 0xFF)


# ---------------------------------------------------------------------------------------------
# Capture formats

_HEX2 = r'[0-9A-Fa-f]{1,2}'
#: Signal K server's data log (``skserver-raw_*.log``) puts its receipt time (Unix ms) and the
#: provider's kind before each line: ``1471172400153;A;<the gateway's line>``.
_SIGNALK_RE = re.compile(r'^\d{10,13};[A-Z];')
_CANBOAT_RE = re.compile(r'^(?P<time>[^,]+),(?P<prio>\d+),(?P<pgn>\d+),(?P<src>\d+),'
                         r'(?P<dst>\d+),(?P<len>\d+)(?P<data>(?:,' + _HEX2 + r')*)\s*$')
_ACTISENSE_RE = re.compile(r'^A(?P<time>\d{6}\.\d{1,3})\s+(?P<addr>[0-9A-Fa-f]{5})\s+'
                           r'(?P<pgn>[0-9A-Fa-f]{5,6})\s+(?P<data>[0-9A-Fa-f]*)\s*$')
_CANDUMP_RE = re.compile(r'^\((?P<time>\d+\.\d+)\)\s+\S+\s+(?:(?P<id>[0-9A-Fa-f]{8})#'
                         r'(?P<data>[0-9A-Fa-f]*)|(?P<id2>[0-9A-Fa-f]{8})\s+\[(?P<len>\d)\]'
                         r'(?P<data2>(?:\s+' + _HEX2 + r')*))\s*$')
_YDRAW_RE = re.compile(r'^(?P<time>\d\d:\d\d:\d\d\.\d{1,3})\s+[RT]\s+(?P<id>[0-9A-Fa-f]{8})'
                       r'(?P<data>(?:\s+' + _HEX2 + r')*)\s*$')
_GARMIN_RE = re.compile(r'^\d+,(?:\d+_\d+_\d+_\d+_\d+_\d+_)?(?P<time>\d+),(?P<pgn>\d+),.*,'
                        r'(?P<src>\d+),(?P<dst>\d+),'
                        r'(?P<prio>\d),(?P<single>[01]),(?P<len>\d+),0x(?P<data>[0-9A-Fa-f]*)\s*$')
_IKONVERT_RE = re.compile(r'^!PDGY,(?P<pgn>\d+),(?P<prio>\d),(?P<src>\d+),(?P<dst>\d+),'
                          r'(?P<time>\d+\.\d+),(?P<data>[A-Za-z0-9+/]+=*)'
                          r'(?:\*[0-9A-Fa-f]{2})?\s*$')
_PCAN_RE = re.compile(r'^\s*\d+\)?\s+(?P<time>\d+)(?:\.(?P<fraction>\d+))?\s+'
                      r'(?:DT\s+)?(?:\d+\s+)?(?:[RT]x\s+)?(?P<id>[0-9A-Fa-f]{5,8})\s+'
                      r'(?:[RT]x\s+)?(?:-\s+)?(?P<len>\d)(?P<data>(?:\s+' + _HEX2 + r')*)\s*$')
_DAY_RE = re.compile(r'^(\d\d):(\d\d):(\d\d)(?:[.,](\d{1,9}))?$')
_UTC_RE = re.compile(r'^(\d{4})-(\d\d)-(\d\d)[T -](\d\d):(\d\d):(\d\d)(?:[.,](\d{1,9}))?'
                     r'(Z|[+-]\d\d:?\d\d)?$')

#: The capture formats read, each with its line pattern.
FORMATS: dict[str, re.Pattern[str]] = {
    'canboat': _CANBOAT_RE, 'actisense': _ACTISENSE_RE, 'candump': _CANDUMP_RE,
    'ydraw': _YDRAW_RE, 'garmin': _GARMIN_RE, 'ikonvert': _IKONVERT_RE, 'pcan': _PCAN_RE,
}
#: How comment lines of the line formats start (PCAN-View's header: ``;``).
COMMENTS = ('#', ';')
#: Every capture format read: the line formats, SocketCAN packets (``marine.pcap``) and
#: Actisense EBL logs (``marine.ebl``) and raw NGT-1 streams (``marine.dle``).
CAPTURE_FORMATS: tuple[str, ...] = (*FORMATS, 'pcap', 'ebl', 'dle')
#: A capture time this large (ns, 1973) is Unix time; smaller, time since the capture (the
#: gateway, the plotter) began: candump -td, iKonvert, a Garmin CSV, pcap.
_UNIX_NS = 100_000_000 * _NS


def time_kind(time_ns: int) -> str:
    """Return the kind of a capture time that is either Unix time or time since its start."""
    return TIME_UTC if time_ns >= _UNIX_NS else TIME_RELATIVE


def unwrap(line: str) -> str:
    """Return a capture line without the prefix of Signal K's data log, and stripped."""
    line = line.strip()
    m = _SIGNALK_RE.match(line)
    return line[m.end():] if m is not None else line


def matches(fmt: str, line: str) -> bool:
    """Return True when ``line`` is one of capture format ``fmt`` (in Signal K's log or not)."""
    return FORMATS[fmt].match(unwrap(line)) is not None


def detect(lines: Iterable[str]) -> str | None:
    """Return the capture format most of ``lines`` are in, None when none holds a third."""
    counts = dict.fromkeys(FORMATS, 0)
    total = 0
    for line in lines:
        line = unwrap(line)
        if not line or line.startswith(COMMENTS):
            continue
        total += 1
        for name, pattern in FORMATS.items():
            if pattern.match(line):
                counts[name] += 1
                break
    if not total:
        return None
    best = max(counts, key=lambda name: counts[name])
    return best if counts[best] * 3 >= total else None


def _fraction_ns(text: str | None) -> int:
    return int(text.ljust(9, '0')[:9]) if text else 0


def _time(text: str) -> tuple[int, str] | None:
    """Return (ns, kind) of a canboat timestamp: UTC date and time, or a time of day."""
    m = _UTC_RE.match(text)
    if m is not None:
        year, month, day, hour, minute, second = (int(g) for g in m.groups()[:6])
        try:
            moment = datetime.datetime(year, month, day, hour, minute, second,
                                       tzinfo=datetime.timezone.utc)
        except ValueError:
            return None
        ns = calendar.timegm(moment.timetuple()) * _NS + _fraction_ns(m.group(7))
        zone = m.group(8)
        if zone and zone != 'Z':
            digits = zone[1:].replace(':', '')
            offset = (int(digits[:2]) * 3600 + int(digits[2:]) * 60) * _NS
            ns -= offset if zone[0] == '+' else -offset
        return ns, TIME_UTC
    m = _DAY_RE.match(text)
    if m is not None:
        hour, minute, second = (int(g) for g in m.groups()[:3])
        if hour > 23 or minute > 59 or second > 60:
            return None
        return ((hour * 60 + minute) * 60 + second) * _NS + _fraction_ns(m.group(4)), TIME_DAY
    return None


def _hex_bytes(text: str, separator: str | None) -> bytes:
    parts = text.split(separator) if separator is not None else [
        text[i:i + 2] for i in range(0, len(text), 2)]
    return bytes(int(p, 16) for p in parts if p)


def parse_line(fmt: str, line: str) -> Frame | None:
    """Return the frame of one capture line in format ``fmt``, None when it is not one."""
    line = unwrap(line)
    m = FORMATS[fmt].match(line)
    if m is None:
        return None
    if fmt == 'canboat':
        when = _time(m.group('time').strip())
        if when is None:
            return None
        data = _hex_bytes(m.group('data'), ',')
        if len(data) != int(m.group('len')):
            return None
        return Frame(when[0], when[1], int(m.group('prio')) & 7, int(m.group('pgn')),
                     int(m.group('src')) & 0xFF, int(m.group('dst')) & 0xFF, data,
                     whole=len(data) > 8)
    if fmt == 'actisense':
        text = m.group('time')
        hour, minute, second = int(text[0:2]), int(text[2:4]), int(text[4:6])
        if hour > 23 or minute > 59 or second > 60:
            return None
        day_ns = ((hour * 60 + minute) * 60 + second) * _NS + _fraction_ns(text[7:])
        address = int(m.group('addr'), 16)
        data_hex = m.group('data')
        if len(data_hex) % 2:
            return None
        return Frame(day_ns, TIME_DAY, address & 0xF, int(m.group('pgn'), 16),
                     (address >> 12) & 0xFF, (address >> 4) & 0xFF, bytes.fromhex(data_hex),
                     whole=True)
    if fmt == 'candump':
        seconds, _, fraction = m.group('time').partition('.')
        time_ns = int(seconds) * _NS + _fraction_ns(fraction)
        kind = time_kind(time_ns)
        if m.group('id') is not None:
            ident, data_hex = m.group('id'), m.group('data')
            if len(data_hex) % 2 or len(data_hex) > 16:
                return None
            data = bytes.fromhex(data_hex)
        else:
            ident = m.group('id2')
            data = bytes(int(p, 16) for p in m.group('data2').split())
            if len(data) != int(m.group('len')):
                return None
        priority, pgn, source, destination = split_can_id(int(ident, 16))
        return Frame(time_ns, kind, priority, pgn, source, destination, data)
    if fmt == 'garmin':
        data_hex = m.group('data')
        if len(data_hex) % 2 or len(data_hex) != 2 * int(m.group('len')):
            return None
        time_ns = int(m.group('time')) * 1_000_000
        return Frame(time_ns, time_kind(time_ns), int(m.group('prio')) & 7, int(m.group('pgn')),
                     int(m.group('src')) & 0xFF, int(m.group('dst')) & 0xFF,
                     bytes.fromhex(data_hex), whole=m.group('single') == '0')
    if fmt == 'ikonvert':
        try:
            data = binascii.a2b_base64(m.group('data'), strict_mode=True)
        except binascii.Error:
            return None
        seconds, _, fraction = m.group('time').partition('.')
        time_ns = int(seconds) * _NS + _fraction_ns(fraction)
        return Frame(time_ns, time_kind(time_ns),
                     int(m.group('prio')) & 7, int(m.group('pgn')), int(m.group('src')) & 0xFF,
                     int(m.group('dst')) & 0xFF, data, whole=True)
    if fmt == 'pcan':
        data = _hex_bytes(m.group('data'), ' ')
        if len(data) != int(m.group('len')):
            return None
        time_ns = int(m.group('time')) * 1_000_000 + _fraction_ns(m.group('fraction')) // 1000
        priority, pgn, source, destination = split_can_id(int(m.group('id'), 16))
        return Frame(time_ns, time_kind(time_ns), priority, pgn, source, destination, data)
    # ydraw
    when = _time(m.group('time'))
    data = _hex_bytes(m.group('data'), ' ')
    if when is None or len(data) > 8:
        return None
    priority, pgn, source, destination = split_can_id(int(m.group('id'), 16))
    return Frame(when[0], TIME_DAY, priority, pgn, source, destination, data)


def format_line(fmt: str, frame: Frame) -> str:
    """Return ``frame`` as a line of capture format ``fmt`` (its time as its kind says)."""
    ns = frame.time_ns
    if fmt == 'canboat':
        if frame.time_kind == TIME_UTC:
            moment = datetime.datetime.fromtimestamp(ns // _NS, tz=datetime.timezone.utc)
            stamp = moment.strftime('%Y-%m-%dT%H:%M:%S') + f'.{ns % _NS // 1_000_000:03d}Z'
        else:
            stamp = _day_text(ns, ':') + f'.{ns % _NS // 1_000_000:03d}'
        data = ','.join(f'{b:02x}' for b in frame.data)
        return (f'{stamp},{frame.priority},{frame.pgn},{frame.source},{frame.destination},'
                f'{len(frame.data)},{data}')
    if fmt == 'actisense':
        address = (frame.source << 12) | (frame.destination << 4) | frame.priority
        return (f'A{_day_text(ns % _DAY_NS, "")}.{ns % _NS // 1_000_000:03d} {address:05X} '
                f'{frame.pgn:05X} {frame.data.hex().upper()}')
    ident = can_id(frame.priority, frame.pgn, frame.source, frame.destination)
    if fmt == 'candump':
        return f'({ns // _NS}.{ns % _NS // 1000:06d}) can0 {ident:08X}#{frame.data.hex().upper()}'
    if fmt == 'garmin':
        return (f'0,{ns // 1_000_000},{frame.pgn},{PGNS.get(frame.pgn, "")},Unknown Manufacturer,'
                f'{frame.source},{frame.destination},{frame.priority},{int(not frame.whole)},'
                f'{len(frame.data)},0x{frame.data.hex().upper()}')
    if fmt == 'ikonvert':
        text = binascii.b2a_base64(frame.data, newline=False).decode('ascii')
        return (f'!PDGY,{frame.pgn},{frame.priority},{frame.source},{frame.destination},'
                f'{ns // _NS}.{ns % _NS // 1_000_000:03d},{text}')
    if fmt == 'pcan':
        data = ' '.join(f'{b:02X}' for b in frame.data)
        return (f'     1)  {ns // 1_000_000}.{ns % 1_000_000 // 1000:03d}  Rx     {ident:08X}  '
                f'{len(frame.data)}  {data}')
    if fmt == 'ydraw':
        data = ' '.join(f'{b:02X}' for b in frame.data)
        return f'{_day_text(ns % _DAY_NS, ":")}.{ns % _NS // 1_000_000:03d} R {ident:08X} {data}'
    raise ValueError(f'unknown capture format {fmt!r} (one of {", ".join(FORMATS)})')


def _day_text(ns: int, separator: str) -> str:
    seconds = ns // _NS % 86_400
    return separator.join(f'{v:02d}' for v in (seconds // 3600, seconds // 60 % 60, seconds % 60))


# ---------------------------------------------------------------------------------------------
# Fast packets


class FastPacket:
    """
    Reassembles fast-packet messages from their CAN frames, per PGN and source.

    Frame 0 holds the sequence counter (bits 5-7 of byte 0), frame index 0 (bits 0-4), the
    message length (byte 1) and 6 data bytes; frame n the same counter, index n and 7 more
    bytes. A frame out of sequence drops the message it belongs to; :attr:`broken` counts them.
    """

    def __init__(self) -> None:
        self._open: dict[tuple[int, int], tuple[int, int, bytearray, int]] = {}
        #: Messages dropped: a frame out of sequence, or a new message before one completed.
        self.broken = 0

    def push(self, frame: Frame) -> bytes | None:
        """Take one frame; return the message it completes, else None."""
        data = frame.data
        if not data:
            self.broken += 1
            return None
        key = (frame.pgn, frame.source)
        counter, index = data[0] >> 5, data[0] & 0x1F
        if index == 0:
            if key in self._open:
                self.broken += 1
            if len(data) < 2:
                self.broken += 1
                return None
            length = data[1]
            message = bytearray(data[2:8])
            if len(message) >= length:
                self._open.pop(key, None)
                return bytes(message[:length])
            self._open[key] = (counter, 1, message, length)
            return None
        pending = self._open.get(key)
        if pending is None:
            return None                       # the rest of a message whose start we missed
        expected_counter, expected_index, message, length = pending
        if counter != expected_counter or index != expected_index:
            del self._open[key]
            self.broken += 1
            return None
        message.extend(data[1:8])
        if len(message) >= length:
            del self._open[key]
            return bytes(message[:length])
        self._open[key] = (counter, index + 1, message, length)
        return None

    def finish(self) -> int:
        """Return the number of messages never completed, and forget them."""
        n = len(self._open)
        self._open.clear()
        return n


def fast_packet_frames(payload: bytes, counter: int) -> list[bytes]:
    """Return the CAN frames (8 bytes, 0xFF padded) of a fast-packet message."""
    if len(payload) > 223:
        raise ValueError(f'a fast packet holds at most 223 bytes, not {len(payload)}')
    head = (counter & 0x7) << 5
    frames = [bytes([head, len(payload)]) + payload[:6]]
    for index, start in enumerate(range(6, len(payload), 7), start=1):
        frames.append(bytes([head | index]) + payload[start:start + 7])
    return [frame.ljust(8, b'\xff') for frame in frames]


# ---------------------------------------------------------------------------------------------
# PGN fields


class _NotAvailable(Exception):
    pass


class _Fields:
    """The payload of one PGN as a little-endian bit field, read per canboat's definitions."""

    def __init__(self, data: bytes, length: int) -> None:
        if len(data) < length:
            raise _Short()
        self.bits = int.from_bytes(data, 'little')

    def raw(self, offset: int, length: int, signed: bool = False) -> int | None:
        """Return a field's raw value, None when it is one of the reserved top values."""
        value = (self.bits >> offset) & ((1 << length) - 1)
        if signed:
            top = (1 << (length - 1)) - 1
            if value > top:
                return value - (1 << length)
            return None if value > top - 3 else value
        return None if length >= 8 and value > (1 << length) - 4 else value

    def value(self, offset: int, length: int, resolution: float, signed: bool = False,
              required: bool = True) -> float | None:
        raw = self.raw(offset, length, signed)
        if raw is None:
            if required:
                raise _NotAvailable()
            return None
        return raw * resolution


class _Short(Exception):
    pass


class _Range(Exception):
    pass


def _angle(value: float | None, low: float, high: float) -> float | None:
    if value is not None and not low - 1e-4 <= value <= high + 1e-4:
        raise _Range()
    return value


def _date_time(fields: _Fields, date_offset: int, time_offset: int) -> ClockTime | None:
    days = fields.raw(date_offset, 16)
    ticks = fields.raw(time_offset, 32)
    if days is None or ticks is None or ticks > 864_010_000:
        return None
    day_ns = ticks * 100_000
    return ClockTime(day_ns % _DAY_NS, days * _DAY_NS + day_ns)


_PI = math.pi
_TWO_PI = 2.0 * math.pi


def _126992(f: _Fields) -> list[Record]:
    when = _date_time(f, 16, 32)
    return [] if when is None else [when]


def _127250(f: _Fields) -> list[Record]:
    heading = _angle(f.value(8, 16, 1e-4), 0.0, _TWO_PI)
    deviation = _angle(f.value(24, 16, 1e-4, True, False), -_PI, _PI)
    variation = _angle(f.value(40, 16, 1e-4, True, False), -_PI, _PI)
    reference = f.raw(56, 2)
    if reference not in (0, 1):
        raise _NotAvailable()
    assert heading is not None
    return [Heading(wrap_2pi(heading), reference == 1, deviation, variation)]


def _127251(f: _Fields) -> list[Record]:
    rate = f.value(8, 32, 3.125e-8, True)
    assert rate is not None
    return [TurnRate(rate)]


def _127257(f: _Fields) -> list[Record]:
    yaw = _angle(f.value(8, 16, 1e-4, True, False), -_PI, _PI)
    pitch = _angle(f.value(24, 16, 1e-4, True, False), -_PI / 2, _PI / 2)
    roll = _angle(f.value(40, 16, 1e-4, True, False), -_PI, _PI)
    if yaw is None and pitch is None and roll is None:
        raise _NotAvailable()
    return [Attitude(None if yaw is None else wrap_2pi(yaw), pitch, roll)]


def _127258(f: _Fields) -> list[Record]:
    variation = _angle(f.value(32, 16, 1e-4, True), -_PI, _PI)
    assert variation is not None
    return [Variation(variation)]


def _128259(f: _Fields) -> list[Record]:
    speed = f.value(8, 16, 0.01)
    assert speed is not None
    return [WaterSpeed(speed)]


def _129025(f: _Fields) -> list[Record]:
    lat = _angle(f.value(0, 32, 1e-7, True), -90.0, 90.0)
    lon = _angle(f.value(32, 32, 1e-7, True), -180.0, 180.0)
    assert lat is not None and lon is not None
    return [Position(lat, lon)]


def _129026(f: _Fields) -> list[Record]:
    reference = f.raw(8, 2)
    cog = _angle(f.value(16, 16, 1e-4), 0.0, _TWO_PI)
    sog = f.value(32, 16, 0.01)
    if reference not in (0, 1):
        raise _NotAvailable()
    assert cog is not None and sog is not None
    return [CourseSpeed(wrap_2pi(cog), sog, reference == 1)]


#: 129029's method (GNS_METHOD) -> NavSatStatus: 1 GNSS fix, 2 DGNSS, 3 precise, 4 RTK fixed,
#: 5 RTK float; 0 no GNSS, 6 estimated (DR), 7 manual, 8 simulated: no fix.
_METHOD_STATUS = {1: 0, 2: 1, 3: 0, 4: 2, 5: 2}


def _129029(f: _Fields) -> list[Record]:
    out: list[Record] = []
    method = (f.bits >> 252) & 0xF
    status = _METHOD_STATUS.get(method, -1)
    when = _date_time(f, 8, 24)
    if when is not None:
        out.append(ClockTime(when.day_ns, when.utc_ns, status >= 0))
    if status < 0:
        out.append(Position(math.nan, math.nan, status=-1))
        return out
    lat = _angle(f.value(56, 64, 1e-16, True), -90.0, 90.0)
    lon = _angle(f.value(120, 64, 1e-16, True), -180.0, 180.0)
    height = f.value(184, 64, 1e-6, True, False)
    hdop = f.value(272, 16, 0.01, True, False)
    if hdop is not None and hdop <= 0.0:
        hdop = None
    assert lat is not None and lon is not None
    out.append(Position(lat, lon, math.nan if height is None else height, hdop, status))
    return out


#: Per PGN: its fixed length (bytes) and its reader.
_READERS: dict[int, tuple[int, Callable[[_Fields], list[Record]]]] = {
    126992: (8, _126992), 127250: (8, _127250), 127251: (5, _127251), 127257: (7, _127257),
    127258: (6, _127258), 128259: (3, _128259), 129025: (8, _129025), 129026: (6, _129026),
    129029: (43, _129029),
}


def decode(pgn: int, data: bytes, source: int = 0) -> Decoded:
    """Return the records of one whole PGN message, or why it yields none."""
    kind = str(pgn)
    reader = _READERS.get(pgn)
    if reader is None:
        return Decoded(kind, str(source))
    length, read = reader
    try:
        records = read(_Fields(data, length))
    except _Short:
        return Decoded(kind, str(source), skip='field_count')
    except _NotAvailable:
        return Decoded(kind, str(source), skip='not_available')
    except _Range:
        return Decoded(kind, str(source), skip='out_of_range')
    return Decoded(kind, str(source), records)


# ---------------------------------------------------------------------------------------------
# Encoding (the writer's)


class _Packer:

    def __init__(self, length: int) -> None:
        self.length = length
        self.bits = (1 << (8 * length)) - 1          # reserved bits all ones

    def put(self, offset: int, length: int, raw: int) -> None:
        mask = (1 << length) - 1
        self.bits &= ~(mask << offset)
        self.bits |= (raw & mask) << offset

    def number(self, offset: int, length: int, value: float | None, resolution: float,
               signed: bool = False) -> None:
        if value is None or math.isnan(value):
            raw = (1 << (length - 1)) - 1 if signed else (1 << length) - 1
        else:
            raw = int(round(value / resolution))
            high = (1 << (length - 1)) - 4 if signed else (1 << length) - 4
            low = -(1 << (length - 1)) if signed else 0
            raw = min(max(raw, low), high)
        self.put(offset, length, raw)

    def payload(self) -> bytes:
        return self.bits.to_bytes(self.length, 'little')


def encode(record: Record, sid: int = 0) -> tuple[int, bytes]:
    """
    Return (PGN, payload) of a record, as an NMEA 2000 device sends it.

    A :class:`~vessel_kinematics.marine.records.Position` becomes 129025 (the GNSS fix with
    height and HDOP, 129029, is :func:`encode_gnss`); a :class:`ClockTime` 126992; the others
    their PGN of the table above.
    """
    if isinstance(record, Position):
        p = _Packer(8)
        p.number(0, 32, record.lat_deg, 1e-7, True)
        p.number(32, 32, record.lon_deg, 1e-7, True)
        return 129025, p.payload()
    if isinstance(record, Heading):
        p = _Packer(8)
        p.put(0, 8, sid)
        p.number(8, 16, record.psi, 1e-4)
        p.number(24, 16, record.deviation, 1e-4, True)
        p.number(40, 16, record.variation, 1e-4, True)
        p.put(56, 2, 1 if record.magnetic else 0)
        return 127250, p.payload()
    if isinstance(record, TurnRate):
        p = _Packer(8)
        p.put(0, 8, sid)
        p.number(8, 32, record.rate, 3.125e-8, True)
        return 127251, p.payload()
    if isinstance(record, Attitude):
        p = _Packer(8)
        p.put(0, 8, sid)
        yaw = None if record.psi is None else math.remainder(record.psi, _TWO_PI)
        p.number(8, 16, yaw, 1e-4, True)
        p.number(24, 16, record.theta, 1e-4, True)
        p.number(40, 16, record.phi, 1e-4, True)
        return 127257, p.payload()
    if isinstance(record, Variation):
        p = _Packer(8)
        p.put(0, 8, sid)
        p.put(8, 4, 0)                                 # source: manual
        p.number(16, 16, None, 1.0)
        p.number(32, 16, record.variation, 1e-4, True)
        return 127258, p.payload()
    if isinstance(record, WaterSpeed):
        p = _Packer(8)
        p.put(0, 8, sid)
        p.number(8, 16, record.speed, 0.01)
        p.number(24, 16, None, 0.01)
        p.put(40, 8, 0)                                # paddle wheel
        return 128259, p.payload()
    if isinstance(record, CourseSpeed):
        p = _Packer(8)
        p.put(0, 8, sid)
        p.put(8, 2, 1 if record.magnetic else 0)
        p.number(16, 16, wrap_2pi(record.cog), 1e-4)
        p.number(32, 16, record.sog, 0.01)
        return 129026, p.payload()
    if isinstance(record, ClockTime):
        if record.utc_ns is None:
            raise ValueError('126992 needs a date: a ClockTime with utc_ns')
        p = _Packer(8)
        p.put(0, 8, sid)
        p.put(8, 4, 0)                                 # source: GPS
        p.put(16, 16, record.utc_ns // _DAY_NS)
        p.put(32, 32, record.utc_ns % _DAY_NS // 100_000)
        return 126992, p.payload()
    raise TypeError(f'no PGN for {type(record).__name__}')


def encode_gnss(position: Position, utc_ns: int, sid: int = 0, satellites: int = 10) -> bytes:
    """Return the 129029 payload (43 bytes, no reference stations) of a GNSS position."""
    p = _Packer(43)
    p.put(0, 8, sid)
    p.put(8, 16, utc_ns // _DAY_NS)
    p.put(24, 32, utc_ns % _DAY_NS // 100_000)
    p.number(56, 64, position.lat_deg, 1e-16, True)
    p.number(120, 64, position.lon_deg, 1e-16, True)
    p.number(184, 64, None if math.isnan(position.height_m) else position.height_m, 1e-6, True)
    p.put(248, 4, 0)                                   # GPS
    method = {0: 1, 1: 2, 2: 4}.get(position.status, 0)
    p.put(252, 4, method)
    p.put(256, 2, 0)                                   # integrity: none
    p.put(264, 8, satellites)
    p.number(272, 16, position.hdop, 0.01, True)
    p.number(288, 16, position.hdop, 0.01, True)       # PDOP: not simulated, HDOP's value
    p.number(304, 32, 0.0, 0.01, True)
    p.put(336, 8, 0)                                   # no reference stations
    return p.payload()

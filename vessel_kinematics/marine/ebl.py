"""
NMEA 2000 logged by Actisense's NMEA Reader: ``.ebl`` files of an NGT-1 or W2K-1 gateway.

An EBL file interleaves two kinds of record (canboat's ``actisense-serial`` and
``crates/canboat-core/src/format/ebl.rs`` document the same):

* a header, ``ESC SOH <type> <payload> ESC LF``: type ``0x03`` is the time of the message that
  follows, a Windows FILETIME (8 bytes little-endian, 100 ns ticks since 1601-01-01 UTC); type
  ``0x01`` the logger's version. Inside a header only ``ESC`` escapes (``ESC ESC`` is 0x1b);
* a message, ``DLE STX <command> <length> <payload> <checksum> DLE ETX``, the gateway's own
  serial framing, with ``DLE`` and ``ESC`` escaped by doubling; command, length, payload and
  checksum sum to 0 mod 256. Command ``0x93`` is an NMEA 2000 message received, whole (the
  gateway reassembled fast packets): priority, PGN (3 bytes LE), destination, source, the
  gateway's own ms counter (4 bytes), data length, data. ``0x94`` (a message sent: priority,
  PGN, destination, length, data) comes in logs of what was transmitted.

Each message takes the time of the header before it. Read by hand: no PyPI package reads EBL
(``nmea2000`` decodes gateways' streams, not their log files).

The same gateway framing without the headers is a raw NGT-1 stream, as Yacht Devices' USB
gateway (YDNU-02) logs it in its ``.dle`` files: :mod:`vessel_kinematics.marine.dle`.
"""

from __future__ import annotations

from pathlib import Path
import struct
from typing import Iterable, Iterator

from vessel_kinematics.marine import files
from vessel_kinematics.marine.nmea2000 import Frame, TIME_RELATIVE, TIME_UTC

__all__ = ['frames', 'is_capture', 'packets', 'read_ngt1', 'received']

SOH, STX, ETX, LF, DLE, ESC = 0x01, 0x02, 0x03, 0x0A, 0x10, 0x1B
N2K_MSG_RECEIVED, N2K_MSG_SEND = 0x93, 0x94
EBL_TIMESTAMP = 0x03
#: FILETIME ticks (100 ns) from 1601-01-01 to 1970-01-01.
_FILETIME_UNIX = 116_444_736_000_000_000

_START, _HEADER, _MESSAGE, _ESCAPE = range(4)


def is_capture(head: bytes) -> bool:
    """Return True when a file starting with ``head`` is an EBL log (it opens with a header)."""
    return head[:2] == bytes((ESC, SOH))


def _message(body: bytes, time_ns: int | None) -> Frame | None:
    """
    Return the frame of one unescaped message, None for what is no usable N2K message.

    ``time_ns``: the EBL header's time (UTC); None takes the gateway's ms counter of a received
    message (time since it started: a raw stream's only time).
    """
    if len(body) < 3 or sum(body) & 0xFF:
        return None
    command, payload = body[0], body[2:2 + body[1]]
    kind = TIME_UTC
    if command == N2K_MSG_RECEIVED and len(payload) >= 11:
        source, length, start = payload[5], payload[10], 11
        if time_ns is None:
            time_ns, kind = struct.unpack_from('<I', payload, 6)[0] * 1_000_000, TIME_RELATIVE
    elif command == N2K_MSG_SEND and len(payload) >= 6 and time_ns is not None:
        source, length, start = 0, payload[5], 6
    else:
        return None
    data = bytes(payload[start:start + length])
    if len(data) != length:
        return None
    pgn = payload[1] | payload[2] << 8 | payload[3] << 16
    return Frame(time_ns, kind, payload[0] & 7, pgn, source & 0xFF, payload[4], data,
                 whole=True)


def frames(path: str | Path) -> Iterator[Frame | None]:
    """
    Yield the frame of each message of an EBL log, in file order.

    None for a message that is no NMEA 2000 message (the gateway's own, a bad checksum, one
    before any time) and for a broken escape sequence.
    """
    return read_ngt1(path, headers=True)


def read_ngt1(path: str | Path, *, headers: bool) -> Iterator[Frame | None]:
    """
    Yield the frame of each message of an EBL log, or (``headers`` False) of a raw NGT-1 stream.

    A raw stream has no headers, ``ESC`` is data in it, and its messages take the gateway's
    counter for their time.
    """
    escapes = (DLE, ESC) if headers else (DLE,)
    state, previous = _START, _START
    body = bytearray()
    time_ns: int | None = None
    for chunk in files.chunks(path):
        for c in chunk:
            if state == _ESCAPE:
                if c == SOH:
                    body.clear()
                    state = _HEADER
                elif c == LF:
                    if len(body) == 9 and body[0] == EBL_TIMESTAMP:
                        ticks = struct.unpack('<Q', body[1:9])[0]
                        time_ns = (ticks - _FILETIME_UNIX) * 100
                    state = _START
                elif c == STX:
                    body.clear()
                    state = _MESSAGE
                elif c == ETX:
                    if headers and time_ns is None:
                        yield None                   # before the log's first time
                    else:
                        yield _message(bytes(body), time_ns)
                    state = _START
                elif c in escapes:
                    body.append(c)
                    state = previous
                else:
                    yield None
                    state = _START
            elif state == _MESSAGE:
                if c in escapes:
                    previous, state = state, _ESCAPE
                else:
                    body.append(c)
            elif state == _HEADER:                   # only ESC escapes in a header
                if c == ESC:
                    previous, state = state, _ESCAPE
                else:
                    body.append(c)
            elif c in escapes:                       # between records
                previous, state = state, _ESCAPE


def _escaped(data: Iterable[int], escapes: tuple[int, ...]) -> bytes:
    out = bytearray()
    for b in data:
        out.append(b)
        if b in escapes:
            out.append(b)
    return bytes(out)


def packets(captured: Iterable[Frame]) -> Iterator[bytes]:
    """
    Yield an EBL log of ``captured`` whole messages: per message its time header, then it.

    Received messages (``0x93``) with the gateway's counter 0, as canboat's encoder writes them.
    """
    for frame in captured:
        ticks = frame.time_ns // 100 + _FILETIME_UNIX
        yield (bytes((ESC, SOH)) + _escaped(bytes((EBL_TIMESTAMP,)) + struct.pack('<Q', ticks),
                                            (ESC,)) + bytes((ESC, LF)))
        yield received(frame, 0, (DLE, ESC))


def received(frame: Frame, counter_ms: int, escapes: tuple[int, ...]) -> bytes:
    """Return the framed NGT-1 message ``0x93`` (an N2K message in) of a frame and counter."""
    payload = (bytes((frame.priority, frame.pgn & 0xFF, frame.pgn >> 8 & 0xFF,
                      frame.pgn >> 16 & 0xFF, frame.destination, frame.source))
               + struct.pack('<I', counter_ms & 0xFFFFFFFF) + bytes((len(frame.data),))
               + frame.data)
    body = bytes((N2K_MSG_RECEIVED, len(payload))) + payload
    body += bytes(((-sum(body)) & 0xFF,))
    return bytes((DLE, STX)) + _escaped(body, escapes) + bytes((DLE, ETX))

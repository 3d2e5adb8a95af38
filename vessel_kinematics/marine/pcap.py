"""
NMEA 2000 captured as SocketCAN packets: pcap and pcapng files (tcpdump, Wireshark, dumpcap).

A capture taken with ``tcpdump -i can0 -w bus.pcap`` or Wireshark on a SocketCAN interface
holds one CAN frame per packet, link type ``LINKTYPE_CAN_SOCKETCAN`` (227): the CAN id with its
flags (4 bytes, big-endian; some early captures wrote the host's order), the data length, three
bytes of padding, then up to 8 data bytes. :func:`frames` reads both file formats:

* pcap: a 24-byte header (its magic gives the byte order and micro- or nanosecond times), then
  per packet a 16-byte header (seconds, fraction, captured length, original length) and the
  packet;
* pcapng: blocks of (type, length, body, length); the section header gives the byte order, each
  interface description its link type and time resolution (``if_tsresol``, microseconds when
  absent), each enhanced packet its interface, 64-bit time and packet.

Read by hand (about sixty lines of ``struct``) rather than through ``dpkt``, whose readers give
float seconds and which would be a run-time dependency for one file format; the tests check
every frame and time against ``dpkt``'s readers.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
import struct
from typing import BinaryIO, Iterable, Iterator

from vessel_kinematics.marine import files
from vessel_kinematics.marine.nmea2000 import can_id, Frame, split_can_id, time_kind

__all__ = ['Damaged', 'frames', 'is_capture', 'LINKTYPE_CAN_SOCKETCAN', 'MAX_RECORD',
           'packets']

#: The link type of a SocketCAN interface's packets.
LINKTYPE_CAN_SOCKETCAN = 227

_NS = 1_000_000_000
#: A record (pcap) or block (pcapng) longer than this is corrupt (bytes): no capture writes
#: one (tcpdump's packets are 256 KiB at most), and reading it would take its length in memory.
MAX_RECORD = 1 << 24
#: How far past a damaged pcap record the next record is looked for (bytes) ...
_RESYNC_BYTES = 1 << 16
#: ... a record header of a packet this long at most, within a day of the last record's time,
#: followed by another; at most this many times in a capture (then reading stops).
_MAX_PACKET = 1 << 16
_MAX_RESYNCS = 100

#: pcap magic numbers as read little-endian: (byte order, ns per time fraction unit).
_PCAP_MAGIC = {0xA1B2C3D4: ('<', 1000), 0xD4C3B2A1: ('>', 1000),
               0xA1B23C4D: ('<', 1), 0x4D3CB2A1: ('>', 1)}
_PCAPNG_SHB = 0x0A0D0D0A
_PCAPNG_SHB_BYTES = struct.pack('<I', _PCAPNG_SHB)
_PCAPNG_IDB, _PCAPNG_EPB = 1, 6
_BYTE_ORDER_MAGIC = 0x1A2B3C4D
_CAN_EFF_FLAG = 0x80000000                 # a 29-bit id, as every NMEA 2000 frame has
_CAN_RTR_ERR_FLAGS = 0x60000000            # a remote request or an error frame


@dataclass(frozen=True, slots=True)
class Damaged:
    """
    A record whose length is corrupt, where reading a capture stops.

    ``offset``: its header's, in the (decompressed) file; ``length``: the length it states;
    ``unread``: the bytes from its header not read: up to the next record where ``resumed``
    (pcap: two plausible record headers in a row found), else to the file's end.
    """

    offset: int
    length: int
    unread: int
    resumed: bool = False


def is_capture(head: bytes) -> bool:
    """Return True when a file starting with ``head`` is a pcap or pcapng file."""
    if len(head) < 4:
        return False
    magic = struct.unpack('<I', head[:4])[0]
    return magic in _PCAP_MAGIC or magic == _PCAPNG_SHB


def _frame(time_ns: int, packet: bytes) -> Frame | None:
    """Return the frame of one SocketCAN packet, None for what is not an NMEA 2000 frame."""
    if len(packet) < 8:
        return None
    ident = struct.unpack('>I', packet[:4])[0]
    if not ident & _CAN_EFF_FLAG:
        swapped = struct.unpack('<I', packet[:4])[0]
        if not swapped & _CAN_EFF_FLAG:
            return None
        ident = swapped
    length = packet[4]
    if ident & _CAN_RTR_ERR_FLAGS or length > 8 or len(packet) < 8 + length:
        return None
    priority, pgn, source, destination = split_can_id(ident & 0x1FFFFFFF)
    return Frame(time_ns, time_kind(time_ns), priority, pgn, source, destination,
                 bytes(packet[8:8 + length]))


def _damaged(f: BinaryIO, offset: int, length: int) -> Damaged:
    """Return the damage at ``offset`` of a record ``length`` long, reading ``f`` to its end."""
    unread = f.tell() - offset
    while chunk := f.read(1 << 20):
        unread += len(chunk)
    return Damaged(offset, length, unread)


def _resync(f: BinaryIO, order: str, unit_ns: int, offset: int, seconds: int) -> int | None:
    """
    Return where the first record after a damaged one at ``offset`` starts, None when unknown.

    A record there has a plausible header (its lengths, its time within a day of ``seconds``)
    and so has the next (or the file ends after it), within :data:`_RESYNC_BYTES`.
    """
    def plausible(at: int) -> int | None:
        if at + 16 > len(window):
            return None
        second, fraction, captured, original = struct.unpack_from(order + 'IIII', window, at)
        ok = (captured <= original <= _MAX_PACKET and fraction * unit_ns < _NS
              and abs(second - seconds) <= 86_400)
        return at + 16 + captured if ok else None

    f.seek(offset + 1)
    wanted = _RESYNC_BYTES + 2 * (16 + _MAX_PACKET)
    window = f.read(wanted)
    for at in range(min(len(window), _RESYNC_BYTES)):
        end = plausible(at)
        if end is not None and (plausible(end) or end == len(window) < wanted):
            return offset + 1 + at
    return None


def _pcap(f: BinaryIO, order: str, unit_ns: int) -> Iterator[Frame | Damaged | None]:
    header = f.read(20)
    if len(header) < 20:
        yield None
        return
    linktype = struct.unpack(order + 'I', header[16:20])[0] & 0x0FFFFFFF
    last: int | None = None                            # the last good record's seconds
    resyncs = 0
    while record := f.read(16):
        if len(record) < 16:
            yield None                                 # the capture was cut
            return
        seconds, fraction, captured, _ = struct.unpack(order + 'IIII', record)
        if captured > MAX_RECORD:
            offset = f.tell() - 16
            resyncs += 1
            found = None if last is None or resyncs > _MAX_RESYNCS else _resync(
                f, order, unit_ns, offset, last)
            if found is None:
                f.seek(offset + 16)
                yield _damaged(f, offset, captured)
                return
            f.seek(found)
            yield Damaged(offset, captured, found - offset, resumed=True)
            continue
        last = seconds
        packet = f.read(captured)
        if len(packet) < captured:
            yield None
            return
        yield (_frame(seconds * _NS + fraction * unit_ns, packet)
               if linktype == LINKTYPE_CAN_SOCKETCAN else None)


def _resolution_ns(options: bytes, order: str) -> tuple[int, int]:
    """Return an interface's time unit as (numerator, denominator) of ns, from if_tsresol."""
    offset = 0
    while offset + 4 <= len(options):
        code, length = struct.unpack(order + 'HH', options[offset:offset + 4])
        if code == 0:
            break
        if code == 9 and length >= 1:
            value = options[offset + 4]
            if value & 0x80:
                return _NS, 1 << (value & 0x7F)
            return _NS, 10 ** value
        offset += 4 + (length + 3) // 4 * 4
    return 1000, 1


def _pcapng(f: BinaryIO) -> Iterator[Frame | Damaged | None]:
    order = '<'
    interfaces: list[tuple[int, int, int]] = []        # link type, ns numerator, denominator
    while head := f.read(8):
        if head[:4] == _PCAPNG_SHB_BYTES:              # a section: its own byte order
            magic = f.read(4)
            order = '<' if magic == struct.pack('<I', _BYTE_ORDER_MAGIC) else '>'
            interfaces = []
            length = struct.unpack(order + 'I', head[4:8])[0] if len(head) == 8 else 0
            if length > MAX_RECORD:
                yield _damaged(f, f.tell() - len(head) - len(magic), length)
                return
            body = f.read(max(length - 12, 0))
            if len(magic) < 4 or length < 28 or len(body) < length - 12:
                yield None                             # the capture was cut
                return
            continue
        kind, length = struct.unpack(order + 'II', head) if len(head) == 8 else (0, 0)
        if length > MAX_RECORD:
            yield _damaged(f, f.tell() - 8, length)
            return
        body = f.read(max(length - 8, 0))
        if length < 12 or len(body) < length - 8:
            yield None
            return
        body = body[:-4]                               # the trailing copy of the length
        if kind == _PCAPNG_IDB and len(body) >= 8:
            linktype = struct.unpack(order + 'H', body[:2])[0]
            interfaces.append((linktype, *_resolution_ns(body[8:], order)))
        elif kind == _PCAPNG_EPB and len(body) >= 20:
            interface, high, low, captured, _ = struct.unpack(order + 'IIIII', body[:20])
            if interface >= len(interfaces) or (
                    interfaces[interface][0] != LINKTYPE_CAN_SOCKETCAN):
                yield None
                continue
            _, numerator, denominator = interfaces[interface]
            units = (high << 32) | low
            yield _frame(units * numerator // denominator, body[20:20 + captured])


def frames(path: str | Path) -> Iterator[Frame | Damaged | None]:
    """
    Yield the frame of each packet of a pcap or pcapng capture, in file order.

    None for a packet that is no NMEA 2000 frame (another link type, an 11-bit id, an error
    frame) and once for a capture cut short, where reading stops; :class:`Damaged` for a
    record longer than :data:`MAX_RECORD` (its length is garbage): a pcap capture resumes at
    the next record where it is found (:func:`_resync`), else reading stops there.
    """
    with files.open_read(path) as f:
        try:
            magic = f.read(4)
            if len(magic) < 4:
                return
            value = struct.unpack('<I', magic)[0]
            if value in _PCAP_MAGIC:
                yield from _pcap(f, *_PCAP_MAGIC[value])
            elif value == _PCAPNG_SHB:
                f.seek(0)
                yield from _pcapng(f)
        except files.TRUNCATED:
            yield None                  # a gzipped capture cut short: read up to there


def packets(captured: Iterable[Frame]) -> Iterator[bytes]:
    """
    Yield a pcap file of ``captured`` CAN frames (8 bytes or fewer), microsecond times.

    First the file's header, then each packet with its record header.
    """
    yield struct.pack('<IHHiIII', 0xA1B2C3D4, 2, 4, 0, 0, 65535, LINKTYPE_CAN_SOCKETCAN)
    for frame in captured:
        ident = can_id(frame.priority, frame.pgn, frame.source, frame.destination)
        packet = struct.pack('>IB3x', ident | _CAN_EFF_FLAG, len(frame.data)) + frame.data
        seconds, ns = divmod(frame.time_ns, _NS)
        yield struct.pack('<IIII', seconds, ns // 1000, len(packet), len(packet)) + packet

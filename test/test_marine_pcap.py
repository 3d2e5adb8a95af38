"""
SocketCAN captures (pcap, pcapng) read frame for frame as dpkt reads them.

``dpkt`` (tests only) is the independent reader and writer: our pcap read back by it, its pcap
and pcapng (micro- and nanosecond times, both byte orders) read by ours. The packets that are
no NMEA 2000 frame and a capture cut short give None, never an exception.
"""

from __future__ import annotations

from decimal import Decimal
import io
from pathlib import Path
import struct

import dpkt
from hypothesis import given, strategies as st
import pytest
from vessel_kinematics.marine import nmea2000, pcap

NS = 1_000_000_000
EFF = 0x80000000

_FRAMES = st.lists(st.builds(
    nmea2000.Frame, st.integers(1_500_000_000 * 10 ** 6, 2_000_000_000 * 10 ** 6).map(
        lambda us: us * 1000),
    st.just(nmea2000.TIME_UTC), st.integers(0, 7), st.sampled_from(sorted(nmea2000.PGNS)),
    st.integers(0, 252), st.just(255), st.binary(min_size=0, max_size=8)), min_size=1,
    max_size=20)


def _packet(frame: nmea2000.Frame, order: str = '>') -> bytes:
    ident = nmea2000.can_id(frame.priority, frame.pgn, frame.source, frame.destination) | EFF
    return struct.pack(order + 'I', ident) + struct.pack('B3x', len(frame.data)) + frame.data


def _read(data: bytes, tmp_path: Path) -> list:
    path = tmp_path / 'capture.pcap'
    path.write_bytes(data)
    return list(pcap.frames(path))


@given(captured=_FRAMES)
def test_our_pcap_reads_back_in_dpkt(captured: list) -> None:
    data = b''.join(pcap.packets(captured))
    read = list(dpkt.pcap.Reader(io.BytesIO(data)))
    assert dpkt.pcap.Reader(io.BytesIO(data)).datalink() == pcap.LINKTYPE_CAN_SOCKETCAN
    assert [round(ts * 1e6) * 1000 for ts, _ in read] == [f.time_ns for f in captured]
    assert [buf for _, buf in read] == [_packet(f) for f in captured]


def _capture(kind: str, order: str, stamped: list[tuple[int, bytes]]) -> bytes:
    """Return a pcap or pcapng file of (ticks, packet): micro- or nanosecond ticks (``-ns``)."""
    nano = kind.endswith('-ns')
    if kind.startswith('pcapng'):
        ng = dpkt.pcapng
        le = order == '<'
        option = ng.PcapngOptionLE if le else ng.PcapngOption
        options = [option(code=ng.PCAPNG_OPT_IF_TSRESOL, data=b'\x09')] if nano else []
        interface = (ng.InterfaceDescriptionBlockLE if le else ng.InterfaceDescriptionBlock)(
            linktype=pcap.LINKTYPE_CAN_SOCKETCAN, snaplen=64,
            opts=options + [option(code=ng.PCAPNG_OPT_ENDOFOPT)])
        packet = ng.EnhancedPacketBlockLE if le else ng.EnhancedPacketBlock
        blocks = [ng.SectionHeaderBlockLE() if le else ng.SectionHeaderBlock(), interface]
        blocks += [packet(ts_high=t >> 32, ts_low=t & 0xFFFFFFFF, caplen=len(p),
                          pkt_len=len(p), pkt_data=p) for t, p in stamped]
        return b''.join(bytes(b) for b in blocks)
    magic = 0xA1B23C4D if nano else 0xA1B2C3D4
    out = [struct.pack(order + 'IHHiIII', magic, 2, 4, 0, 0, 64, pcap.LINKTYPE_CAN_SOCKETCAN)]
    per = 10 ** 9 if nano else 10 ** 6
    for t, p in stamped:
        out.append(struct.pack(order + 'IIII', t // per, t % per, len(p), len(p)) + p)
    return b''.join(out)


@pytest.mark.parametrize('kind', ['pcap', 'pcap-ns', 'pcapng', 'pcapng-ns'])
@pytest.mark.parametrize('order', ['<', '>'])
def test_captures_read_as_dpkt_reads_them(tmp_path: Path, kind: str, order: str) -> None:
    # Both byte orders of the file; the CAN id big-endian as the link type says, and in the
    # host's (little-endian) order as some early captures wrote it.
    nano = kind.endswith('-ns')
    frames = [nmea2000.Frame(1_669_809_629 * NS + k * 1_234_567 // (1 if nano else 1000) * (
        1 if nano else 1000), nmea2000.TIME_UTC, k % 8, (129025, 127250, 59904)[k % 3], k % 250,
        255 if k % 3 < 2 else 7, bytes(range(k % 9))) for k in range(50)]
    ticks = [f.time_ns // (1 if nano else 1000) for f in frames]
    packets = [_packet(f, '>' if k % 2 else '<') for k, f in enumerate(frames)]
    data = _capture(kind, order, list(zip(ticks, packets)))
    reader = (dpkt.pcapng.Reader if kind.startswith('pcapng') else dpkt.pcap.Reader)(
        io.BytesIO(data))
    theirs = list(reader)
    assert [buf for _, buf in theirs] == packets
    # dpkt gives pcapng times as float seconds: 0.2 us off at these dates; ours are exact.
    slack = 500 if kind == 'pcapng-ns' else 0
    assert all(abs(round(Decimal(ts) * (NS if nano else 10 ** 6)) - t) <= slack
               for (ts, _), t in zip(theirs, ticks, strict=True))
    assert _read(data, tmp_path) == frames


def test_what_is_no_nmea2000_frame_gives_none(tmp_path: Path) -> None:
    frame = nmea2000.Frame(1_669_809_629 * NS, nmea2000.TIME_UTC, 2, 129025, 3, 255, bytes(8))
    good = _packet(frame)
    standard = struct.pack('>IB3x', 0x123, 8) + bytes(8)            # an 11-bit id
    error = struct.pack('>IB3x', EFF | 0x20000000 | 0x123, 8) + bytes(8)
    long = good[:4] + b'\x09' + good[5:] + b'\x00'                  # a length over 8
    stamped = [(k * 1000 + 1_669_809_629 * 10 ** 6, p)
               for k, p in enumerate([good, standard, error, long, good[:6]])]
    got = _read(_capture('pcap', '<', stamped), tmp_path)
    assert got[0] == frame and got[1:] == [None] * 4
    # Another link type: every packet None; a file cut inside a packet: one None, then the end.
    ethernet = bytearray(_capture('pcap', '<', stamped[:2]))
    ethernet[20:24] = struct.pack('<I', 1)
    assert _read(bytes(ethernet), tmp_path) == [None, None]
    cut = _capture('pcapng', '<', stamped[:3])
    assert _read(cut[:-7], tmp_path) == [frame, None, None]
    assert _read(_capture('pcap', '<', stamped[:1])[:-3], tmp_path) == [None]
    assert not pcap.is_capture(b'$GP') and pcap.is_capture(_capture('pcapng', '>', [])[:4])


@pytest.mark.parametrize('kind', ['pcap', 'pcapng'])
def test_a_record_of_a_garbage_length_is_said_where_reading_stops(tmp_path: Path,
                                                                  kind: str) -> None:
    # A fuzzed capture whose record 1001 said 0xFFFFFFF0 bytes: reading stopped there with
    # one None, 14 s of 219 read, and nothing said it. Now the damage is told: where, and
    # how much of the file was not read; a pcap capture resumes at the next record (two
    # plausible record headers in a row), a pcapng one stops (no resync).
    frame = nmea2000.Frame(1_669_809_629 * NS, nmea2000.TIME_UTC, 2, 129025, 3, 255, bytes(8))
    stamped = [(k * 1000 + 1_669_809_629 * 10 ** 6, _packet(frame)) for k in range(4)]
    data = bytearray(_capture(kind, '<', stamped))
    whole = _read(bytes(data), tmp_path)
    offset = len(data) - 2 * (len(data) - len(_capture(kind, '<', stamped[:3])))
    if kind == 'pcap':                                 # the third record's captured length
        data[offset + 8:offset + 12] = struct.pack('<I', 0xFFFFFFF0)
    else:                                              # the third block's length
        data[offset + 4:offset + 8] = struct.pack('<I', 0xFFFFFFF0)
    got = _read(bytes(data), tmp_path)
    if kind == 'pcap':
        size = len(data) - offset - (len(data) - len(_capture(kind, '<', stamped[:3])))
        assert got == [*whole[:2], pcap.Damaged(offset, 0xFFFFFFF0, size, True), whole[3]]
    else:
        assert got == [*whole[:2], pcap.Damaged(offset, 0xFFFFFFF0, len(data) - offset)]

"""
Actisense EBL logs read as canboat documents them, and round trips through our writer.

The expected values of canboat's sample come from canboat, not from our reader: the time is
the one its EBL encoder's test writes into that sample's header (2025-04-25T17:05:21.993Z,
``crates/canboat-core/src/format/ebl.rs``), and the PGNs and route names are in the bytes.
"""

from __future__ import annotations

import datetime
from pathlib import Path

from hypothesis import given, strategies as st
from vessel_kinematics.marine import dle, ebl, nmea2000

NS = 1_000_000_000

#: The first 180 bytes of canboat's samples/actisense1.ebl (Apache-2.0): the logger's version
#: header, a time header and two NGT-1 messages of route and waypoint names, the second
#: ending in an escaped ESC.
CANBOAT_HEAD = bytes.fromhex(
    '1b010390e3c83a04b6db011b0a1b0101e90300001b0a1b010390e3c83a04b6db011b0a10029348041010fc01'
    '63ffe50300003dffff0200010001000c0153514c2053657276657210105cab24eb4ef3020045000000000400'
    '000200050144423210105cab24eb4eff200060000000f33f0000601003100293360411fc0163ffe50300002b'
    'ffff02001600ffff01000d0148657265546f5468657265270200101001416e64204261636b20416761696e1b'
    '1b551003')


def _read(data: bytes, tmp_path: Path) -> list:
    path = tmp_path / 'log.ebl'
    path.write_bytes(data)
    return list(ebl.frames(path))


def test_canboats_sample_reads_as_canboat_documents(tmp_path: Path) -> None:
    assert ebl.is_capture(CANBOAT_HEAD) and not ebl.is_capture(b'$GPRMC')
    got = _read(CANBOAT_HEAD, tmp_path)
    when = datetime.datetime(2025, 4, 25, 17, 5, 21, 993000, tzinfo=datetime.timezone.utc)
    assert [f.pgn for f in got] == [130064, 130065]
    assert all(f.time_ns == int(when.timestamp()) * NS + 993_000_000 for f in got)
    assert all(f.priority == 4 and f.whole and f.time_kind == nmea2000.TIME_UTC for f in got)
    assert b'SQL Server' in got[0].data
    assert b'HereToThere' in got[1].data and got[1].data.endswith(b'And Back Again\x1b')


def test_what_is_no_message_gives_none(tmp_path: Path) -> None:
    time_header = CANBOAT_HEAD[20:35]
    first = CANBOAT_HEAD[35:CANBOAT_HEAD.index(b'\x10\x03') + 2]
    assert len(_read(time_header + first, tmp_path)) == 1
    bad = bytearray(first)
    bad[-3] ^= 0x01                                              # the checksum
    assert _read(time_header + bytes(bad), tmp_path) == [None]
    assert _read(first, tmp_path) == [None]                      # before any time
    assert _read(time_header + first[:10] + b'\x10\x7f' + first[10:], tmp_path)[0] is None
    assert _read(b'', tmp_path) == []


_FRAMES = st.lists(st.builds(
    nmea2000.Frame, st.integers(1_000_000_000, 2_000_000_000).map(lambda s: s * NS + 12_345_600),
    st.just(nmea2000.TIME_UTC), st.integers(0, 7), st.sampled_from(sorted(nmea2000.PGNS)),
    st.integers(0, 252), st.sampled_from([255, 0x10, 0x1B]),
    st.binary(max_size=40) | st.lists(st.sampled_from([0x10, 0x1B, 0x02, 0x03]),
                                      max_size=12).map(bytes),
    st.just(True)), min_size=1, max_size=12)


@given(captured=_FRAMES)
def test_our_ebl_reads_back(captured: list, tmp_path_factory) -> None:
    # DLE and ESC in the data, the addresses and the time escape and come back.
    path = tmp_path_factory.mktemp('ebl') / 'log.ebl'
    path.write_bytes(b''.join(ebl.packets(captured)))
    assert list(ebl.frames(path)) == captured


#: Bytes of canboat's samples/ydnu-02-raymarine-ev1.dle (Apache-2.0), a Yacht Devices YDNU-02
#: log of a Raymarine EV1 autopilot: the file's start (the end of a message, then 127250 from
#: source 0xCC at the gateway's 679,345 ms), a message whose data holds a DLE (doubled), and one
#: whose counter holds an ESC (0x1b: data in a raw stream, not an escape as in EBL).
YDNU = bytes.fromhex(
    '1003' '100293130212f101ffccb15d0a0008ff4bedff7fff7ffd391003'
    '100293130213f101ffcce3670a0008ffab10100000ffffff751003'
    '100293140700ef01ffcc1b670a00093b9ff081ae02010ca5551003')


def test_a_yacht_devices_dle_stream_reads_as_its_bytes_say(tmp_path: Path) -> None:
    assert dle.is_capture(YDNU) and not ebl.is_capture(YDNU)
    assert not dle.is_capture(CANBOAT_HEAD) and not dle.is_capture(b'$GPRMC')
    path = tmp_path / 'log.dle'
    path.write_bytes(YDNU)
    start, heading, rate, autopilot = dle.frames(path)
    assert start is None                        # the end of a message begun before the file
    assert (heading.pgn, heading.source, heading.priority) == (127250, 0xCC, 2)
    assert heading.time_ns == 679_345 * 1_000_000
    assert heading.time_kind == nmea2000.TIME_RELATIVE and heading.whole
    assert heading.data == bytes.fromhex('ff4bedff7fff7ffd')
    assert rate.pgn == 127251 and rate.data == bytes.fromhex('ffab100000ffffff')
    assert (autopilot.pgn, autopilot.priority) == (126720, 7)
    assert autopilot.time_ns == 0x0A671B * 1_000_000
    assert autopilot.data == bytes.fromhex('3b9ff081ae02010ca5')


@given(captured=_FRAMES)
def test_our_dle_reads_back(captured: list, tmp_path_factory) -> None:
    # The same through a raw stream: only DLE escapes, the times as the gateway's counter
    # since the first message (ms), relative.
    path = tmp_path_factory.mktemp('dle') / 'log.dle'
    path.write_bytes(b''.join(dle.packets(captured)))
    first = captured[0].time_ns
    want = [nmea2000.Frame((f.time_ns - first) // 1_000_000 % (1 << 32) * 1_000_000,
                           nmea2000.TIME_RELATIVE, f.priority, f.pgn, f.source, f.destination,
                           f.data, True) for f in captured]
    assert list(dle.frames(path)) == want


@given(data=st.binary(max_size=300), cut=st.integers(0, len(YDNU)))
def test_damage_to_a_dle_stream_is_never_fatal(data: bytes, cut: int, tmp_path_factory) -> None:
    # Whatever bytes come between or into the messages: frames or None, never an exception.
    path = tmp_path_factory.mktemp('dle') / 'log.dle'
    path.write_bytes(YDNU[:cut] + data + YDNU[cut:])
    for frame in dle.frames(path):
        assert frame is None or (frame.whole and frame.time_kind == nmea2000.TIME_RELATIVE)

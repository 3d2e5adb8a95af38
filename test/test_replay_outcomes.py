"""
The replay fails loudly when nothing useful came out (issue 25, item 5), on real bags.

A run with no navigation output (payloads that lie about their type: every fix garbage) exits
1 with no output and says why; a run that refused most of an input writes its output but exits
:data:`~vessel_kinematics.tools.replay.cli.SUSPECT` (3) with one line saying which input; a
stamp gap and a stamp reset are in the summary; a FIFO (or a bag directory holding one) is
refused before anything is read, instead of blocking for ever.
"""

from __future__ import annotations

import os
from pathlib import Path
import struct
import subprocess
import sys

import pytest
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import StoragePlugin, Writer
from test_replay import write_voyage
from test_replay_safety import fails, leftovers, rewrite, snapshot, STORE
from vessel_kinematics.tools import replay
from vessel_kinematics.tools.replay.cli import SUSPECT


@pytest.fixture
def voyage(tmp_path: Path) -> Path:
    """Return a voyage bag of 20 s."""
    return write_voyage(tmp_path / 'in', duration=20.0)


def _garbage(raw: bytes) -> bytes:
    return raw[:4] + b'\xff' * 24 + raw[28:]          # a string length of 4 GB


def test_no_navigation_output_is_an_error_that_says_why(voyage: Path, tmp_path: Path,
                                                        capsys: pytest.CaptureFixture) -> None:
    source = rewrite(voyage, tmp_path / 'lying',
                     lambda topic, index, raw: _garbage(raw) if topic == '/fix' else raw)
    err = fails([str(source), str(tmp_path / 'out')], capsys, 'no navigation output',
                'waiting for origin', 'fix 0 of')
    assert 'imu' in err
    assert not (tmp_path / 'out').exists() and not leftovers(tmp_path)


def test_most_of_an_input_refused_is_written_but_suspect(voyage: Path, tmp_path: Path,
                                                         capsys: pytest.CaptureFixture) -> None:
    source = rewrite(voyage, tmp_path / 'spoilt', lambda topic, index, raw:
                     _garbage(raw) if topic == '/velocity' and index % 3 else raw)
    out = tmp_path / 'out'
    assert replay.main([str(source), str(out), '--no-progress']) == SUSPECT
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith('replay: error: output written but suspect'), \
        lines
    assert 'velocity messages refused (cdr_error' in lines[0], lines[0]
    assert 'rejected' in captured.out and out.is_dir()       # the summary, and the output


def _shift(seconds: int, after: int, topic_name: str = '/fix'):
    """Return a change adding ``seconds`` to the header stamps of ``topic_name`` from ``after``."""
    def change(topic: str, index: int, raw: bytes) -> bytes:
        if topic != topic_name or index < after:
            return raw
        (sec,) = struct.unpack_from('<i', raw, 4)
        return raw[:4] + struct.pack('<i', sec + seconds) + raw[8:]
    return change


def _pause(voyage: Path, target: Path, seconds: int, after_ns: int) -> Path:
    """Copy a bag with a recording pause: stamps and log times after ``after_ns`` move on."""
    with AnyReader([voyage]) as reader, Writer(target, version=9,
                                               storage_plugin=StoragePlugin.MCAP) as writer:
        connections = {c.id: writer.add_connection(c.topic, c.msgtype, typestore=STORE)
                       for c in reader.connections}
        start = reader.start_time
        for connection, ns, raw in reader.messages():
            raw = bytes(raw)
            if ns - start > after_ns:
                (sec,) = struct.unpack_from('<i', raw, 4)
                raw = raw[:4] + struct.pack('<i', sec + seconds) + raw[8:]
                ns += seconds * 10 ** 9
            writer.write(connections[connection.id], ns, raw)
    return target


def test_a_stamp_gap_and_a_reset_are_in_the_summary(voyage: Path, tmp_path: Path) -> None:
    gap = replay.run(_pause(voyage, tmp_path / 'gap', 120, 1_500_000_000), tmp_path / 'out1',
                     progress=False)
    assert gap.gaps['fix'] == 1 and gap.largest_gap['fix'][0] > 100.0, gap.largest_gap
    text = gap.text()
    assert '(1 over max_gap)' in text and 'gaps       ' in text and 'resets     ' in text, text
    # Fixes stamped 120 s back from the 10th on: refused as too late, and said.
    back = replay.run(rewrite(voyage, tmp_path / 'back', _shift(-120, 10)), tmp_path / 'out2',
                      progress=False)
    assert back.stamp_resets['fix'] >= 1, back.stamp_resets
    assert back.rejected['fix/too_late'] >= 1 and back.resets == 0
    assert 'back' in back.text()


@pytest.mark.parametrize('where', ['file', 'in_a_bag_directory'])
def test_a_fifo_as_input_is_refused(voyage: Path, tmp_path: Path, where: str) -> None:
    if where == 'file':
        source = tmp_path / 'in.mcap'
        os.mkfifo(source)
    else:
        source = tmp_path / 'bag'
        source.mkdir()
        (source / 'metadata.yaml').write_text((voyage / 'metadata.yaml').read_text())
        os.mkfifo(source / 'bag_0.mcap')
    before = snapshot(voyage)
    done = subprocess.run([sys.executable, '-m', 'vessel_kinematics.tools.replay', str(source),
                           str(tmp_path / 'out'), '--no-progress'],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 1, done.stderr
    assert done.stderr.count('\n') == 1 and 'is a FIFO' in done.stderr, done.stderr
    assert not (tmp_path / 'out').exists() and snapshot(voyage) == before


def _later_log_times(voyage: Path, target: Path, seconds: int) -> Path:
    """Copy a bag with its log times (not its stamps) ``seconds`` later."""
    with AnyReader([voyage]) as reader, Writer(target, version=9,
                                               storage_plugin=StoragePlugin.MCAP) as writer:
        connections = {c.id: writer.add_connection(c.topic, c.msgtype, typestore=STORE)
                       for c in reader.connections}
        for connection, ns, raw in reader.messages():
            writer.write(connections[connection.id], ns + seconds * 10 ** 9, bytes(raw))
    return target


def test_log_times_past_2038_are_refused_in_one_line(voyage: Path, tmp_path: Path,
                                                     capsys: pytest.CaptureFixture) -> None:
    source = _later_log_times(voyage, tmp_path / 'y2100', 80 * 365 * 86_400)
    err = fails([str(source), str(tmp_path / 'out')], capsys,
                f'cannot replay {source}', 'no ROS time stamp holds', '--by-stamp')
    assert 'unexpected' not in err
    assert not (tmp_path / 'out').exists() and not leftovers(tmp_path)
    # By header stamp, the log times are only those of the copies: replayed.
    assert replay.main([str(source), str(tmp_path / 'out'), '--no-progress',
                        '--by-stamp']) == 0


def test_a_cdr_stamp_past_2038_is_a_clear_value_error() -> None:
    from vessel_kinematics.ros import cdr
    with pytest.raises(ValueError, match='not a ROS time stamp'):
        cdr.vector3_stamped(2 ** 31 * 10 ** 9, 'base_link', 0.0, 0.0, 0.0)


def _spoil_mcap_chunk(bag: Path) -> None:
    """Flip a bit of the length of the first message in a bag's mcap file (+ 1 TB)."""
    mcap = next(bag.glob('*.mcap'))
    data = bytearray(mcap.read_bytes())
    at = 8                                              # after the magic
    while data[at] != 0x06:                             # the first Chunk record
        at += 9 + struct.unpack_from('<Q', data, at + 1)[0]
    at += 9 + 8 + 8 + 8 + 4                             # times, size, crc
    at += 4 + struct.unpack_from('<I', data, at)[0]     # the compression's name
    at += 8                                             # the records' length
    while data[at] != 0x05:                             # the first Message record
        at += 9 + struct.unpack_from('<Q', data, at + 1)[0]
    data[at + 1 + 5] ^= 0x01
    mcap.write_bytes(bytes(data))


def _spoil_ros1_chunk(tmp_path: Path) -> Path:
    """Return a bz2-compressed ROS 1 bag whose first chunk's compressed data is garbage."""
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.typesys import get_typestore, Stores
    source = write_voyage(tmp_path / 'plain.bag', fmt='ros1', duration=2.0)
    spoilt = tmp_path / 'spoilt.bag'
    store = get_typestore(Stores.ROS1_NOETIC)
    writer = Writer1(spoilt)
    writer.set_compression(Writer1.CompressionFormat.BZ2)
    with AnyReader([source]) as reader, writer:
        connections = {c.id: writer.add_connection(c.topic, c.msgtype, typestore=store)
                       for c in reader.connections}
        for connection, ns, raw in reader.messages():
            writer.write(connections[connection.id], ns, bytes(raw))
    data = bytearray(spoilt.read_bytes())
    block = data.index(b'1AY&SY')                       # the first bz2 block's magic
    data[block:block + 6] = bytes(6)
    spoilt.write_bytes(bytes(data))
    return spoilt


@pytest.mark.parametrize('kind', ['mcap', 'ros1'])
def test_a_corrupt_bag_is_one_line_naming_it(voyage: Path, tmp_path: Path, kind: str,
                                             capsys: pytest.CaptureFixture) -> None:
    if kind == 'mcap':
        _spoil_mcap_chunk(voyage)
        source = voyage
    else:
        source = _spoil_ros1_chunk(tmp_path)
    before = snapshot(source)
    err = fails([str(source), str(tmp_path / 'out')], capsys,
                f'replay: error: cannot read {source} as a bag: ')
    assert 'unexpected' not in err
    assert not (tmp_path / 'out').exists() and not leftovers(tmp_path)
    assert snapshot(source) == before


def _one_later(voyage: Path, target: Path, topic: str, index: int, seconds: int,
               stamp: bool) -> Path:
    """Copy a bag with one message of ``topic`` ``seconds`` later: its stamp, or its log time."""
    with AnyReader([voyage]) as reader, Writer(target, version=9,
                                               storage_plugin=StoragePlugin.MCAP) as writer:
        connections = {c.id: writer.add_connection(c.topic, c.msgtype, typestore=STORE)
                       for c in reader.connections}
        seen = 0
        for connection, ns, raw in reader.messages():
            raw = bytes(raw)
            if connection.topic == topic:
                if seen == index and stamp:
                    (sec,) = struct.unpack_from('<i', raw, 4)
                    raw = raw[:4] + struct.pack('<i', sec + seconds) + raw[8:]
                elif seen == index:
                    ns += seconds * 10 ** 9
                seen += 1
            writer.write(connections[connection.id], ns, raw)
    return target


@pytest.mark.parametrize('what', ['stamp_by_stamp', 'log_time'])
def test_one_time_glitched_years_ahead_does_not_move_the_clock(voyage: Path, tmp_path: Path,
                                                               what: str) -> None:
    ten_years = 10 * 365 * 86_400
    source = _one_later(voyage, tmp_path / 'glitch', '/fix', 10, ten_years,
                        stamp=what.startswith('stamp'))
    summary = replay.run(source, tmp_path / 'out', progress=False,
                         by_stamp=what == 'stamp_by_stamp')
    assert summary.duration_s < 60.0, summary.text()
    assert summary.resets == 0, summary.text()
    if what == 'stamp_by_stamp':                    # arrived at the clock: a future stamp
        assert summary.rejected['fix/future_stamp'] == 1, summary.rejected
    latest = summary.end_ns
    with AnyReader([tmp_path / 'out']) as reader:
        outputs = [c for c in reader.connections if c.topic in ('/odometry', '/diagnostics')]
        assert all(ns <= latest for _, ns, _ in reader.messages(connections=outputs))

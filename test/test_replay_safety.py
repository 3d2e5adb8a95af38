"""
The replay never destroys or half-writes anything: real bags in tmp dirs, the real CLI.

Every refused or failed run must leave the input bag byte-identical, no output (or the previous
output untouched) and no hidden staging directory behind, and say why in one line on stderr
with a non-zero exit.
"""

from __future__ import annotations

import errno
import hashlib
import multiprocessing
import os
from pathlib import Path
import subprocess
import sys
from typing import Any

import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import get_typestore, Stores
from test_replay import read_bag, write_voyage
from vessel_kinematics.ros import params_file
from vessel_kinematics.ros.params import ParameterError
from vessel_kinematics.tools import bags, replay
from vessel_kinematics.tools.replay import bag_output

STORE = get_typestore(Stores.ROS2_JAZZY)


def snapshot(path: Path) -> dict[str, str]:
    """Return {relative path: sha256} of every file under ``path`` (or of the file itself)."""
    if path.is_file():
        return {path.name: hashlib.sha256(path.read_bytes()).hexdigest()}
    return {str(p.relative_to(path)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(path.rglob('*')) if p.is_file()}


def leftovers(directory: Path) -> list[str]:
    """Return the replay's staging or replaced directories left in ``directory``."""
    return [p.name for p in directory.iterdir()
            if p.name.startswith('.') and ('.replay-' in p.name or '.replaced-' in p.name)]


def fails(argv: list[str], capsys: pytest.CaptureFixture, *needles: str) -> str:
    """Run main(), assert a one-line error with a non-zero exit; return the line."""
    rc = replay.main(argv + ['--no-progress'])
    err = capsys.readouterr().err.strip()
    assert rc != 0
    assert err.startswith('replay: error:') and '\n' not in err, err
    for needle in needles:
        assert needle in err, err
    return err


@pytest.fixture
def voyage(tmp_path: Path) -> Path:
    """Return a short voyage bag (mcap) in its own directory."""
    return write_voyage(tmp_path / 'in', duration=3.0)


def rewrite(source: Path, target: Path, change: Any) -> Path:
    """
    Copy a bag's messages to a new bag, through ``change(topic, index, raw) -> raw | None``.

    ``None`` drops the message; the connections are kept (so a bag may hold topics and no
    messages).
    """
    with AnyReader([source]) as reader, Writer(target, version=9,
                                               storage_plugin=StoragePlugin.MCAP) as writer:
        connections = {c.id: writer.add_connection(c.topic, c.msgtype, typestore=STORE)
                       for c in reader.connections}
        counts: dict[str, int] = {}
        for connection, ns, raw in reader.messages():
            index = counts.get(connection.topic, 0)
            counts[connection.topic] = index + 1
            raw = change(connection.topic, index, bytes(raw))
            if raw is not None:
                writer.write(connections[connection.id], ns, raw)
    return target


# ------------------------------------------------------------------------- paths


@pytest.mark.parametrize('overwrite', [False, True])
def test_output_equal_to_input_is_refused(voyage: Path, tmp_path: Path, overwrite: bool,
                                          capsys: pytest.CaptureFixture) -> None:
    before = snapshot(voyage)
    extra = ['--overwrite'] if overwrite else []
    fails([str(voyage), str(voyage)] + extra, capsys, 'is the input')
    # The same directory by another spelling and through a symlink.
    fails([str(voyage), str(tmp_path / 'x' / '..' / 'in')] + extra, capsys, 'is the input')
    link = tmp_path / 'link'
    link.symlink_to(voyage)
    fails([str(voyage), str(link)] + extra, capsys, 'is the input')
    fails([str(link), str(voyage)] + extra, capsys, 'is the input')
    assert snapshot(voyage) == before
    assert not leftovers(tmp_path)


def test_output_inside_or_containing_the_input_is_refused(tmp_path: Path,
                                                          capsys: pytest.CaptureFixture) -> None:
    (tmp_path / 'runs').mkdir()
    source = write_voyage(tmp_path / 'runs' / 'in', duration=2.0)
    before = snapshot(tmp_path / 'runs')
    fails([str(source), str(source / 'out'), '--overwrite'], capsys, 'inside the input')
    fails([str(source), str(source / 'a' / 'b')], capsys, 'inside the input')
    fails([str(source), str(tmp_path / 'runs'), '--overwrite'], capsys, 'contains the input')
    fails([str(source), str(tmp_path / 'out'), '--plot', str(source / 'x.png')], capsys,
          'plot')
    assert snapshot(tmp_path / 'runs') == before
    assert not (tmp_path / 'out').exists()
    assert not leftovers(tmp_path) and not leftovers(tmp_path / 'runs')


def test_ros1_bag_file_is_not_overwritten(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    source = write_voyage(tmp_path / 'in.bag', fmt='ros1', duration=2.0)
    before = snapshot(source)
    fails([str(source), str(source), '--overwrite'], capsys, 'is the input')
    fails([str(source), str(source / 'out')], capsys, 'inside the input')
    assert snapshot(source) == before


# ---------------------------------------------------------------------- overwrite


def test_overwrite_replaces_only_a_previous_output(voyage: Path, tmp_path: Path,
                                                   capsys: pytest.CaptureFixture) -> None:
    out = tmp_path / 'out'
    assert replay.main([str(voyage), str(out), '--no-progress', '-p', 'map_frame:=one']) == 0
    capsys.readouterr()
    assert replay.is_bag_directory(out)
    assert replay.main([str(voyage), str(out), '--no-progress', '--overwrite',
                        '-p', 'map_frame:=two']) == 0
    _, messages = read_bag(out)
    assert messages['/odometry'][0][1].header.frame_id == 'two'
    assert sorted(p.name for p in out.iterdir()) == ['metadata.yaml', 'out.mcap']
    assert not leftovers(tmp_path)
    # A directory with something else in it, a plain file, a symlink to a bag: refused.
    other = tmp_path / 'other'
    other.mkdir()
    (other / 'metadata.yaml').write_text('not yours\n')
    (other / 'notes.txt').write_text('precious\n')
    plain = tmp_path / 'plain.txt'
    plain.write_text('precious\n')
    link = tmp_path / 'link'
    link.symlink_to(out)
    before = {p: snapshot(p) for p in (other, plain, out)}
    for target in (other, plain, link):
        fails([str(voyage), str(target), '--overwrite'], capsys, 'not a rosbag2 bag')
    fails([str(voyage), str(out)], capsys, 'exists already')
    assert {p: snapshot(p) for p in (other, plain, out)} == before
    assert link.is_symlink()
    assert not leftovers(tmp_path)


def test_a_failed_run_leaves_the_previous_output_untouched(voyage: Path, tmp_path: Path,
                                                           capsys: pytest.CaptureFixture) -> None:
    out = tmp_path / 'out'
    assert replay.main([str(voyage), str(out), '--no-progress']) == 0
    previous = snapshot(out)
    empty = rewrite(voyage, tmp_path / 'empty', lambda topic, index, raw: None)
    before = snapshot(empty)
    fails([str(empty), str(out), '--overwrite'], capsys, 'no messages', '/imu')
    assert snapshot(out) == previous and snapshot(empty) == before
    assert not leftovers(tmp_path)


def test_interrupt_leaves_nothing_behind(voyage: Path, tmp_path: Path,
                                         capsys: pytest.CaptureFixture,
                                         monkeypatch: pytest.MonkeyPatch) -> None:
    """A Ctrl-C half-way through writing: the staging bag is removed, the old output kept."""
    out = tmp_path / 'out'
    assert replay.main([str(voyage), str(out), '--no-progress']) == 0
    previous = snapshot(out)
    before = snapshot(voyage)
    write = bag_output.OutputBag.write
    seen: list[Path] = []
    sent = [0]

    def interrupted(self: Any, emission: Any) -> None:
        write(self, emission)
        sent[0] += 1
        if sent[0] % 50 == 0:
            seen.extend(p for p in tmp_path.iterdir() if '.replay-' in p.name)
            raise KeyboardInterrupt

    monkeypatch.setattr(bag_output.OutputBag, 'write', interrupted)
    for argv in ([str(voyage), str(out), '--overwrite'],
                 [str(voyage), str(tmp_path / 'new')]):
        rc = replay.main(argv + ['--no-progress'])
        err = capsys.readouterr().err.strip()
        assert rc == 130 and err == 'replay: error: interrupted; no output written'
    assert len(seen) == 2  # the staging directory existed while writing
    assert snapshot(out) == previous and snapshot(voyage) == before
    assert not (tmp_path / 'new').exists()
    assert not leftovers(tmp_path)
    assert not multiprocessing.active_children()  # nothing of the run left running


def test_a_failing_bag_writer_is_one_line_and_leaves_nothing(
        voyage: Path, tmp_path: Path, capsys: pytest.CaptureFixture,
        monkeypatch: pytest.MonkeyPatch) -> None:
    """A full disk half-way (injected: ENOSPC on the 300th write)."""
    write = bags.BagWriter.write
    calls = [0]

    def full_disk(self: Any, *args: Any) -> None:
        calls[0] += 1
        if calls[0] == 300:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        write(self, *args)

    monkeypatch.setattr(bags.BagWriter, 'write', full_disk)
    out = tmp_path / 'out'
    before = snapshot(voyage)
    fails([str(voyage), str(out)], capsys, 'cannot write', 'No space left on device')
    assert not out.exists() and snapshot(voyage) == before
    assert not leftovers(tmp_path)
    assert not multiprocessing.active_children()


# ------------------------------------------------------------------------ failures


def test_unwritable_output_directory(voyage: Path, tmp_path: Path,
                                     capsys: pytest.CaptureFixture) -> None:
    before = snapshot(voyage)
    plain = tmp_path / 'file'
    plain.write_text('x')
    fails([str(voyage), str(plain / 'out')], capsys, 'does not exist')
    # /proc refuses new directories even to root (the tests may run as root, so no chmod).
    fails([str(voyage), '/proc/vk_replay_out'], capsys, '/proc')
    assert snapshot(voyage) == before
    assert not os.path.exists('/proc/vk_replay_out')


def test_params_file_refusals(voyage: Path, tmp_path: Path,
                              capsys: pytest.CaptureFixture) -> None:
    bomb = tmp_path / 'bomb.yaml'
    lines = ['a0: &a0 [x, x, x, x, x, x, x, x, x]']
    lines += [f'a{i}: &a{i} [{", ".join([f"*a{i - 1}"] * 9)}]' for i in range(1, 7)]
    bomb.write_text('\n'.join(lines) + '\n')
    assert len(bomb.read_bytes()) < 600  # 9**7 = 4.8 M names once expanded
    latin1 = tmp_path / 'latin1.yaml'
    latin1.write_bytes('navigator:\n  ros__parameters:\n    map_frame: k\xf8l\n'.encode('latin-1'))
    big = tmp_path / 'big.yaml'
    big.write_text('# ' + 'x' * params_file.MAX_BYTES + '\n')
    deep = tmp_path / 'deep.yaml'
    deep.write_text('[' * 100 + ']' * 100 + '\n')
    broken = tmp_path / 'broken.yaml'
    broken.write_text('navigator: [\n  ros__parameters: {\n')
    cases = [(bomb, 'anchors and aliases'), (latin1, 'not UTF-8'), (big, 'larger than'),
             (deep, 'deeper than'), (broken, 'not valid YAML'),
             (tmp_path / 'missing.yaml', 'cannot read'), (tmp_path, 'cannot read')]
    for path, needle in cases:
        fails([str(voyage), str(tmp_path / 'out'), '--params-file', str(path)], capsys, needle)
        assert not (tmp_path / 'out').exists()
    fails([str(voyage), str(tmp_path / 'out'), '-p', 'origin:=&a [1, 2, 3]'], capsys,
          'anchors and aliases')
    assert not leftovers(tmp_path)


def test_params_file_check_is_a_function(tmp_path: Path) -> None:
    good = tmp_path / 'good.yaml'
    good.write_text('navigator:\n  ros__parameters:\n    gnss:\n      enabled: false\n')
    assert params_file.read_params_file(good).values == {'gnss.enabled': False}
    good.write_text('navigator:\n  ros__parameters:\n    map_frame: "&not_an_anchor"\n')
    assert params_file.read_params_file(good).values == {'map_frame': '&not_an_anchor'}
    good.write_text('x: &anchor 1\n')
    with pytest.raises(ParameterError, match='anchors'):
        params_file.read_params_file(good)


def test_tiny_publish_rate_is_one_line(voyage: Path, tmp_path: Path,
                                       capsys: pytest.CaptureFixture) -> None:
    for value in ('1e-300', '1e-10', '0.05', '1e6', 'nan', '.inf'):
        fails([str(voyage), str(tmp_path / 'out'), '-p', f'publish_rate:={value}'], capsys,
              "'publish_rate'")
    assert not (tmp_path / 'out').exists()


def test_garbage_cdr_is_counted_and_the_run_goes_on(voyage: Path, tmp_path: Path,
                                                    capsys: pytest.CaptureFixture) -> None:
    rng = np.random.default_rng(8)
    garbage: dict[str, list[bytes]] = {'/velocity': [], '/fix': []}

    def spoil(topic: str, index: int, raw: bytes) -> bytes:
        if topic in garbage and index % 7 == 3:
            if index % 2:  # a string length of 4 GB
                bad = raw[:4] + b'\xff' * 24 + raw[28:]
            else:
                bad = raw[:4] + rng.integers(0, 256, 9, dtype=np.uint8).tobytes()
            garbage[topic].append(bad)
            return bad
        return raw

    source = rewrite(voyage, tmp_path / 'spoilt', spoil)
    before = snapshot(source)
    out = tmp_path / 'out'
    assert replay.main([str(source), str(out), '--no-progress']) == 0
    text = capsys.readouterr().out
    summary_counts = sum(len(v) for v in garbage.values())
    assert summary_counts > 5
    for topic, bad in garbage.items():
        if bad:
            assert f'{topic[1:]}/cdr_error' in text, text
    with AnyReader([out]) as reader:
        copied = {c.topic: [bytes(raw) for c2, _, raw in reader.messages([c])]
                  for c in reader.connections if c.topic in garbage}
    for topic, bad in garbage.items():
        assert all(b in copied[topic] for b in bad)  # the copy keeps the input's bytes
    assert snapshot(source) == before
    summary = replay.run(source, tmp_path / 'again', progress=False)
    assert summary.rejected['velocity/cdr_error'] == len(garbage['/velocity'])
    assert summary.rejected['fix/cdr_error'] == len(garbage['/fix'])
    assert summary.messages_out['/odometry'] > 0


def _bad_stamps(topic: str, index: int, raw: bytes) -> bytes:
    """Set every input message's header nanosec to 2e9 (CDR: after 4 + 4 bytes)."""
    return raw[:8] + (2_000_000_000).to_bytes(4, 'little') + raw[12:]


def test_all_rejected_is_an_error_that_says_why(voyage: Path, tmp_path: Path,
                                                capsys: pytest.CaptureFixture) -> None:
    source = rewrite(voyage, tmp_path / 'stamps', _bad_stamps)
    before = snapshot(source)
    err = fails([str(source), str(tmp_path / 'out')], capsys, 'no usable input message',
                'imu/bad_stamp', 'fix/bad_stamp', 'velocity/bad_stamp')
    assert 'all' in err
    assert snapshot(source) == before
    assert not (tmp_path / 'out').exists() and not leftovers(tmp_path)


def test_command_line_refusals_have_no_traceback(voyage: Path, tmp_path: Path) -> None:
    before = snapshot(voyage)
    for argv, code in (([str(voyage), str(voyage), '--overwrite'], 1),
                       ([str(voyage), str(tmp_path / 'out'), '-p', 'publish_rate:=1e-300'], 2)):
        done = subprocess.run([sys.executable, '-m', 'vessel_kinematics.tools.replay', *argv],
                              capture_output=True, text=True, timeout=120)
        assert done.returncode == code
        assert done.stderr.startswith('replay: error:') and done.stderr.count('\n') == 1
        assert 'Traceback' not in done.stderr
    assert snapshot(voyage) == before
    assert not (tmp_path / 'out').exists()


def test_relative_and_dot_outputs(voyage: Path, tmp_path: Path) -> None:
    work = tmp_path / 'work'
    work.mkdir()
    (work / 'keep.txt').write_text('precious\n')
    command = [sys.executable, '-m', 'vessel_kinematics.tools.replay', str(voyage)]
    env = {**os.environ, 'PYTHONPATH': os.pathsep.join(
        [str(Path(replay.__file__).parents[3]), os.environ.get('PYTHONPATH', '')])}
    for output in ('.', 'sub/..', '..'):
        done = subprocess.run(command + [output, '--overwrite'], cwd=work, env=env,
                              capture_output=True, text=True, timeout=120)
        assert done.returncode == 1 and 'Traceback' not in done.stderr, done.stderr
        assert done.stderr.count('\n') == 1
    done = subprocess.run(command + ['out', '--no-copy-inputs'], cwd=work, env=env,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert 'replay ' + str(voyage) + ' -> out' in done.stdout
    assert replay.is_bag_directory(work / 'out')
    assert sorted(p.name for p in work.iterdir()) == ['keep.txt', 'out']


def test_garbage_ros1_payload_is_counted_not_copied(tmp_path: Path,
                                                    capsys: pytest.CaptureFixture) -> None:
    from rosbags.rosbag1 import Writer as Writer1
    source = write_voyage(tmp_path / 'in.bag', fmt='ros1', duration=2.0)
    store = get_typestore(Stores.ROS1_NOETIC)
    spoilt = tmp_path / 'spoilt.bag'
    bad = 0
    with AnyReader([source]) as reader, Writer1(spoilt) as writer:
        connections = {c.id: writer.add_connection(c.topic, c.msgtype, typestore=store)
                       for c in reader.connections}
        for index, (connection, ns, raw) in enumerate(reader.messages()):
            if connection.topic == '/velocity' and index % 5 == 2:
                raw, bad = bytes(raw)[:7], bad + 1
            writer.write(connections[connection.id], ns, bytes(raw))
    assert bad > 0
    before = snapshot(spoilt)
    assert replay.main([str(spoilt), str(tmp_path / 'out'), '--no-progress']) == 0
    text = capsys.readouterr().out
    assert f'velocity/cdr_error {bad}' in text
    assert f'not copied (ROS 1 payload not convertible to CDR): /velocity {bad}' in text
    assert snapshot(spoilt) == before


# -------------------------------------------------------------------------- plot


def test_a_plot_directory_missing_is_refused_before_the_run(voyage: Path, tmp_path: Path,
                                                            capsys: pytest.CaptureFixture) -> None:
    figure = tmp_path / 'nowhere' / 'deeper' / 'p.png'
    fails([str(voyage), str(tmp_path / 'out'), '--plot', str(figure)], capsys,
          f'plot directory {figure.parent} does not exist')
    assert not (tmp_path / 'nowhere').exists() and not (tmp_path / 'out').exists()
    fails([str(voyage), str(tmp_path / 'out'), '--plot', str(tmp_path)], capsys,
          'is a directory')
    assert not (tmp_path / 'out').exists() and not leftovers(tmp_path)


def test_a_plot_that_fails_after_the_output_is_a_warning(voyage: Path, tmp_path: Path,
                                                         monkeypatch: pytest.MonkeyPatch,
                                                         capsys: pytest.CaptureFixture) -> None:
    from vessel_kinematics.tools import plot

    def full_disk(source: Any, path: Path, **options: Any) -> Path:
        Path(path).write_bytes(b'\x89PNG half')             # half a file, then the disk is full
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(plot, 'plot', full_disk)
    figure, out = tmp_path / 'figures' / 'p.png', tmp_path / 'out'
    figure.parent.mkdir()
    assert replay.main([str(voyage), str(out), '--plot', str(figure), '--no-progress']) == 0
    captured = capsys.readouterr()
    assert captured.err.strip() == (f'replay: warning: plot {figure} not written: '
                                    'No space left on device'), captured.err
    assert 'rejected' in captured.out and bag_output.is_bag_directory(out)   # the summary
    assert list(figure.parent.iterdir()) == []                               # no half a file

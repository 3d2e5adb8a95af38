"""
``replay`` over many bags: a directory or several inputs, parallel processes, one table.

Real small bags from the simulator (20 s voyages), a ROS 1-named file that is no bag at all,
and the single-bag rules holding for each output.
"""

from __future__ import annotations

from pathlib import Path
import shutil

import pytest
from rosbags.highlevel import AnyReader
from vessel_kinematics.tools import replay, sim


def _raw(path: Path) -> dict[str, list[tuple[int, bytes]]]:
    """Return {topic: [(log ns, raw bytes)]} of a bag."""
    out: dict[str, list[tuple[int, bytes]]] = {}
    with AnyReader([path]) as reader:
        for connection, ns, raw in reader.messages():
            out.setdefault(connection.topic, []).append((ns, bytes(raw)))
    return out


@pytest.fixture(scope='module')
def archive(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """
    Return a directory of bags: two rosbag2 voyages, one bare .mcap file, one broken .bag.

    Plus a text file and a hidden directory, which are not bags and are left alone.
    """
    root = tmp_path_factory.mktemp('archive') / 'bags'
    root.mkdir()
    sim.generate(root / 'first', sim.VoyageConfig(duration=20.0, seed=1))
    sim.generate(root / 'second', sim.VoyageConfig(duration=20.0, seed=2))
    work = tmp_path_factory.mktemp('mcap')
    sim.generate(work / 'third', sim.VoyageConfig(duration=20.0, seed=3))
    shutil.copy(next((work / 'third').glob('*.mcap')), root / 'third.mcap')
    (root / 'broken.bag').write_bytes(b'#ROSBAG V2.0\nnot a bag at all')
    (root / 'notes.txt').write_text('not a bag')
    (root / '.hidden').mkdir()
    return root


def test_find_bags(archive: Path) -> None:
    bags = replay.find_bags([archive])
    assert [b.name for b in bags] == ['broken.bag', 'first', 'second', 'third.mcap']
    assert replay.is_many([archive]) and not replay.is_many([archive / 'first'])
    assert replay.is_many([archive / 'first', archive / 'second'])
    assert [replay.output_name(b) for b in bags] == ['broken', 'first', 'second', 'third']
    with pytest.raises(replay.ReplayError, match='neither a bag nor a directory of bags'):
        replay.find_bags([archive / '.hidden'])


def test_directory_in_parallel_with_a_failing_bag(archive: Path, tmp_path: Path,
                                                  capsys: pytest.CaptureFixture) -> None:
    """Two processes, one output per bag, a row per bag; the broken bag fails alone."""
    out = tmp_path / 'out'
    status = replay.main([str(archive), str(out), '--jobs', '2', '--no-progress'])
    printed = capsys.readouterr().out
    assert status == 1
    lines = printed.splitlines()
    assert lines[0].split()[:2] == ['bag', 'bag']
    rows = {line.split()[0]: line for line in lines[1:]}
    assert set(rows) == {'broken', 'first', 'second', 'third', 'total'}
    assert 'error: cannot read' in rows['broken'] and str(archive / 'broken.bag') in printed
    for name in ('first', 'second', 'third'):
        assert rows[name].endswith(' ok'), rows[name]
        assert replay.is_bag_directory(out / name)
    assert rows['total'].endswith('3 ok, 1 failed')
    assert sorted(p.name for p in out.iterdir()) == ['first', 'second', 'third']
    # Each output is exactly what the single-bag replay writes for that bag.
    single = replay.run(archive / 'second', tmp_path / 'single', progress=False, accuracy=False)
    assert _raw(out / 'second') == _raw(tmp_path / 'single')
    assert f'{single.distance_m:.1f}' in rows['second']
    # A second run refuses to replace the outputs (the single-bag rule), row by row.
    status = replay.main([str(archive / 'first'), str(archive / 'third.mcap'), str(out)])
    printed = capsys.readouterr().out
    assert status == 1 and printed.count('exists already (use --overwrite') == 2
    status = replay.main([str(archive / 'first'), str(archive / 'third.mcap'), str(out),
                          '--overwrite'])
    assert status == 0 and capsys.readouterr().out.splitlines()[-1].endswith('2 ok, 0 failed')


def test_rows_of_run_many_in_one_process(archive: Path, tmp_path: Path) -> None:
    rows = replay.run_many([archive / 'first', archive / 'missing'], tmp_path / 'o', jobs=1)
    assert [r.name for r in rows] == ['first', 'missing']
    assert rows[0].ok and rows[0].messages_in > 1000 and rows[0].messages_out > 0
    assert rows[0].duration_s == pytest.approx(20.0, abs=0.5) and rows[0].distance_m > 10.0
    assert not rows[1].ok and 'input bag not found' in rows[1].error


@pytest.mark.parametrize('where', ['inside', 'equal'])
def test_output_never_with_the_inputs(archive: Path, where: str,
                                      capsys: pytest.CaptureFixture) -> None:
    """A directory of bags cannot take its outputs; nor can a directory holding the inputs."""
    before = sorted(p.name for p in archive.iterdir())
    if where == 'inside':
        argv = [str(archive), str(archive / 'out')]
    else:
        argv = [str(archive / 'first'), str(archive / 'second'), str(archive)]
    assert replay.main(argv) == 1
    assert 'refusing' in capsys.readouterr().err
    assert sorted(p.name for p in archive.iterdir()) == before


def test_output_file_and_plot_and_jobs_refused(archive: Path, tmp_path: Path,
                                               capsys: pytest.CaptureFixture) -> None:
    (tmp_path / 'file').write_text('x')
    assert replay.main([str(archive), str(tmp_path / 'file')]) == 1
    assert 'is not a directory' in capsys.readouterr().err
    assert replay.main([str(archive), str(tmp_path / 'o'), '--plot', 'x.png']) == 1
    assert '--plot takes one input' in capsys.readouterr().err
    assert replay.main([str(archive), str(tmp_path / 'o'), '--jobs', '0']) == 1
    assert 'must be at least 1' in capsys.readouterr().err
    assert not (tmp_path / 'o').exists()


def _nmea(body: str) -> str:
    checksum = 0
    for char in body:
        checksum ^= ord(char)
    return f'${body}*{checksum:02X}\r\n'


def test_a_directory_takes_marine_logs_and_names_what_it_skips(
        tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    logs = tmp_path / 'logs'
    logs.mkdir()
    (logs / 'trip.log').write_text(''.join(
        _nmea(f'GPRMC,1200{s:02d}.00,A,5230.000,N,00500.000,E,5.0,90.0,010624,,,A')
        for s in range(10)))
    (logs / 'notes.txt').write_text('not a bag, not a log')
    skipped: list[Path] = []
    assert replay.find_bags([logs], skipped) == [logs / 'trip.log']
    assert skipped == [logs / 'notes.txt']
    assert replay.main([str(logs), str(tmp_path / 'out'), '--jobs', '1', '--no-progress']) == 0
    captured = capsys.readouterr()
    assert captured.err.strip() == ('replay: warning: skipped, neither a bag nor a marine log: '
                                    f'{logs / "notes.txt"}'), captured.err
    assert '1 ok, 0 failed' in captured.out and (tmp_path / 'out' / 'trip').is_dir()


def test_a_stop_during_many_bags_says_which_outputs_are_written(
        archive: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture) -> None:
    import signal
    from vessel_kinematics.tools.replay import many
    from vessel_kinematics.tools.replay.cli import Stopped
    real, calls = many.run, []

    def stopped_at_the_third(*args: object, **options: object) -> object:
        calls.append(args[0])
        if len(calls) == 3:
            raise Stopped(signal.SIGTERM)
        return real(*args, **options)

    monkeypatch.setattr(many, 'run', stopped_at_the_third)
    out = tmp_path / 'out'
    assert replay.main([str(archive), str(out), '--jobs', '1', '--no-progress']) == 143
    err = capsys.readouterr().err.strip().splitlines()[-1]       # after the skipped line
    assert err == (f'replay: error: terminated (SIGTERM); the outputs of the bags done before '
                   f'it are in {out}, none written for the others (no table)'), err
    assert (out / 'first').is_dir() and not (out / 'second').exists()

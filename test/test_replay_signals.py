"""
The replay stops cleanly on SIGTERM and SIGHUP as on SIGINT, and cleans up after SIGKILL.

The real ``replay`` command in a subprocess on a real bag: the signal is sent once the run's
staging directory exists (it is writing), and the run must end with its documented status
(128 + the signal), one line on stderr, no traceback, no output and no staging directory left,
the previous output untouched. A run killed outright (SIGKILL) cannot clean up: the next run on
the same output recognises its staging directory (its process is gone), removes it and says so
in one line.
"""

from __future__ import annotations

import os
from pathlib import Path
import signal
import subprocess
import sys
import time

import pytest
from test_replay import write_voyage
from test_replay_safety import leftovers, snapshot


def _replay(*argv: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, '-m', 'vessel_kinematics.tools.replay', *argv,
                             '--no-progress'], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)


def _staging_seen(directory: Path, process: subprocess.Popen, timeout: float = 120.0) -> bool:
    """Wait until a staging directory of ``process`` exists (it is writing)."""
    name = f'.replay-{process.pid}'
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and process.poll() is None:
        if any(p.name.endswith(name) for p in directory.iterdir()):
            return True
        time.sleep(0.01)
    return False


@pytest.fixture(scope='module')
def long_voyage(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Return a voyage long enough that the replay is still writing when the signal comes."""
    return write_voyage(tmp_path_factory.mktemp('signals') / 'in', duration=120.0)


@pytest.mark.parametrize('signum, status, line', [
    (signal.SIGTERM, 143, 'replay: error: terminated (SIGTERM); no output written'),
    (signal.SIGHUP, 129, 'replay: error: hung up (SIGHUP); no output written'),
    (signal.SIGINT, 130, 'replay: error: interrupted; no output written')])
def test_a_stop_signal_ends_the_run_cleanly(long_voyage: Path, tmp_path: Path,
                                            signum: int, status: int, line: str) -> None:
    before = snapshot(long_voyage)
    previous = tmp_path / 'previous'
    for target, extra in ((tmp_path / 'new', ()), (previous, ('--overwrite',))):
        if extra:
            done = subprocess.run([sys.executable, '-m', 'vessel_kinematics.tools.replay',
                                   str(long_voyage), str(previous), '--no-progress'],
                                  capture_output=True, timeout=300)
            assert done.returncode == 0, done.stderr
            kept = snapshot(previous)
        process = _replay(str(long_voyage), str(target), *extra)
        assert _staging_seen(tmp_path, process), process.communicate()
        process.send_signal(signum)
        out, err = process.communicate(timeout=120)
        assert process.returncode == status, (process.returncode, err)
        assert err.strip() == line, err
        assert 'Traceback' not in err + out
        assert not leftovers(tmp_path)
        if extra:
            assert snapshot(previous) == kept
        else:
            assert not target.exists()
    assert snapshot(long_voyage) == before


def _dead_pid() -> int:
    child = subprocess.Popen([sys.executable, '-c', 'pass'])
    child.wait()
    return child.pid


def test_what_a_killed_run_left_is_removed_by_the_next(long_voyage: Path,
                                                       tmp_path: Path) -> None:
    out = tmp_path / 'out'
    process = _replay(str(long_voyage), str(out))
    assert _staging_seen(tmp_path, process), process.communicate()
    process.send_signal(signal.SIGKILL)
    process.communicate(timeout=60)
    assert leftovers(tmp_path) == [f'.out.replay-{process.pid}']
    # A staging directory of a process still alive (another replay running) is not touched.
    alive = tmp_path / f'.out.replay-{os.getpid()}'
    alive.mkdir()
    other = tmp_path / f'.other.replay-{_dead_pid()}'         # another output's
    other.mkdir()
    done = subprocess.run([sys.executable, '-m', 'vessel_kinematics.tools.replay',
                           str(long_voyage), str(out), '--no-progress'],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    warnings = [w for w in done.stderr.splitlines() if w.startswith('replay: warning:')]
    assert len(warnings) == 1, done.stderr
    assert f'removed .out.replay-{process.pid}/' in warnings[0]
    assert f'process {process.pid} is gone' in warnings[0]
    assert sorted(leftovers(tmp_path)) == sorted([alive.name, other.name])
    assert out.is_dir()


def test_a_kill_between_the_renames_restores_the_previous_output(long_voyage: Path,
                                                                 tmp_path: Path) -> None:
    out = tmp_path / 'out'
    done = subprocess.run([sys.executable, '-m', 'vessel_kinematics.tools.replay',
                           str(long_voyage), str(out), '--no-progress'],
                          capture_output=True, timeout=300)
    assert done.returncode == 0
    kept = snapshot(out)
    pid = _dead_pid()
    out.rename(tmp_path / f'.out.replaced-{pid}')      # what a kill mid --overwrite leaves
    done = subprocess.run([sys.executable, '-m', 'vessel_kinematics.tools.replay',
                           str(long_voyage), str(out), '--no-progress'],
                          capture_output=True, text=True, timeout=300)
    # The previous output is back, so this run (without --overwrite) refuses to replace it.
    assert done.returncode == 1
    assert f'restored {out} from .out.replaced-{pid}' in done.stderr, done.stderr
    assert 'exists already' in done.stderr
    assert snapshot(out) == kept and not leftovers(tmp_path)


def test_a_stop_once_the_output_is_in_place_says_it_is_written(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture) -> None:
    from vessel_kinematics.tools import plot, replay
    from vessel_kinematics.tools.replay import bag_output
    from vessel_kinematics.tools.replay.cli import Stopped

    def stopped(*args: object, **options: object) -> Path:
        raise Stopped(signal.SIGTERM)                   # the signal while drawing

    monkeypatch.setattr(plot, 'plot', stopped)
    source = write_voyage(tmp_path / 'in', duration=3.0)
    out = tmp_path / 'out'
    assert replay.main([str(source), str(out), '--plot', str(tmp_path / 'p.png'),
                        '--no-progress']) == 143
    err = capsys.readouterr().err.strip()
    assert err == (f'replay: error: terminated (SIGTERM) after the output was written: {out} '
                   'is complete (no summary, no plot)'), err
    assert bag_output.is_bag_directory(out) and not leftovers(tmp_path)
    assert not (tmp_path / 'p.png').exists()

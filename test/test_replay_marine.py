"""
``replay`` on marine logs directly: NMEA 0183 logs and NMEA 2000 captures, good and damaged.

* the two given NMEA 0183 logs (``../shared/data``: IJsselmeer, Geneva) replay as their bags do:
  the same track (to the stamping difference) and the same course and speed against the
  receiver's COG/SOG, which the summary scores;
* an NMEA 2000 capture written by the simulator's writer (:mod:`vessel_kinematics.marine.
  writer`) replays, scored against the simulator's truth, as well as the voyage's own bag;
* damaged logs (truncated lines, bad checksums, binary junk) are counted and skipped and
  replay as the clean log; a log with no position exits 1 with one line.
"""

from __future__ import annotations

import math
from pathlib import Path
import subprocess
import sys
from typing import Any

import numpy as np
import pynmea2
import pytest
from vessel_kinematics.marine import messages as marine_messages, writer
from vessel_kinematics.tools import bags, evaluate, replay
from vessel_kinematics.tools.sim_bag import records, TOPICS
from vessel_kinematics.tools.sim_model import simulate, VoyageConfig
from vessel_kinematics.tools.sim_sensors import sensor_readings

SAILBOAT_REMAPS = ['imu:=/imu', 'velocity:=/speed_log']
DEG = math.pi / 180.0


def _track_difference(a: evaluate.Run, b: evaluate.Run) -> np.ndarray:
    """Return the horizontal distance (m) of run a's track from run b's, at b's stamps."""
    inside = (b.odometry.t >= a.odometry.t[0]) & (b.odometry.t <= a.odometry.t[-1])
    t = b.odometry.t[inside]
    east = np.interp(t, a.odometry.t, a.odometry['east'])
    north = np.interp(t, a.odometry.t, a.odometry['north'])
    return np.hypot(east - b.odometry['east'][inside], north - b.odometry['north'][inside])


def _replay(source: Path, out: Path, params: Any, remaps: list[str] | None = None
            ) -> tuple[replay.Summary, evaluate.Run]:
    summary = replay.run(source, out, params, remaps, progress=False)
    return summary, evaluate.load_run(out, fix_topic='/fix')


@pytest.mark.parametrize('name', ['sailboat_ijsselmeer', 'sailboat_geneva'])
def test_a_given_log_replays_as_its_bag(name: str, shared_data: Path, repo: Path,
                                        tmp_path: Path) -> None:
    params = replay.load_params(repo / 'config' / 'sailboat.yaml')
    log_summary, log_run = _replay(shared_data / f'{name}_nmea0183.log', tmp_path / 'log',
                                   params)
    bag_summary, bag_run = _replay(shared_data / name, tmp_path / 'bag', params,
                                   SAILBOAT_REMAPS)
    assert log_summary.topics == bag_summary.topics
    assert log_run.origin == pytest.approx(bag_run.origin, abs=1e-9)
    d = _track_difference(log_run, bag_run)
    print(f'{name}: log vs bag track median {np.median(d):.2e} m, max {d.max():.3f} m')
    assert len(d) > 0.95 * len(bag_run.odometry)
    assert np.median(d) < 0.01 and d.max() < 0.5
    # The summary scores both against the receiver's COG/SOG, alike.
    assert log_summary.reference is not None and 'course - COG' in log_summary.reference
    for quantity in (evaluate.course_vs_reference, evaluate.speed_vs_reference):
        got, expected = quantity(log_run), quantity(bag_run)
        assert got is not None and expected is not None
        assert got['rms'] == pytest.approx(expected['rms'], abs=0.2 if 'mean_abs' in got
                                           else 0.005)
    assert any(note.startswith('nmea0183: used ') for note in log_summary.notes)


@pytest.fixture(scope='module')
def voyage() -> tuple[list, list]:
    """Return a 90 s simulated voyage: its records and (topic, stamp, message)."""
    config = VoyageConfig(duration=90.0, imu_rate=20.0, truth_rate=20.0, log_surge_only=True,
                          outage=(0.0, 0.0))
    recs = records(sensor_readings(simulate(config), config))
    store = marine_messages.typestore()
    return recs, [(r.topic, r.stamp_ns, store.deserialize_cdr(r.data, TOPICS[r.topic]))
                  for r in recs]


def test_an_nmea2000_capture_replays_against_the_truth(voyage: tuple, tmp_path: Path,
                                                       repo: Path) -> None:
    recs, items = voyage
    capture = writer.write_nmea2000(tmp_path / 'voyage.can', items, fmt='candump')
    truth = [(r.topic, r.stamp_ns, r.data) for r in recs if r.topic.startswith('/truth')]
    bags.write_bag(tmp_path / 'truth', truth, {t: TOPICS[t] for t in {r[0] for r in truth}})
    bags.write_bag(tmp_path / 'voyage', ((r.topic, r.stamp_ns, r.data) for r in recs), TOPICS)
    params = replay.load_params(repo / 'config' / 'demo.yaml')
    summary = replay.run(capture, tmp_path / 'out_capture', params, progress=False)
    assert summary.topics['velocity'] == '/speed_log' and summary.reference is not None
    assert any(note.startswith('nmea2000/candump: used ') for note in summary.notes)
    scores = {}
    for name, out in (('capture', tmp_path / 'out_capture'), ('voyage', tmp_path / 'out_bag')):
        if name == 'voyage':
            replay.run(tmp_path / 'voyage', out, params, ['velocity:=/velocity'],
                       progress=False, accuracy=False)
        held = bags.read_topics([out, tmp_path / 'truth'],
                                set(evaluate.OUTPUT_TOPICS) | set(evaluate.TRUTH_TOPICS)
                                | {'/fix', evaluate.COG_SOG_TOPIC})
        scores[name] = evaluate.accuracy(evaluate.run_from_messages(held, fix_topic='/fix'))
        print(f'{name}: ' + ', '.join(f'{k} RMS {v.rms:.3f}' for k, v in scores[name].items()
                                      if v is not None))
    for field, margin in (('position', 0.1), ('heading', 0.02 * DEG), ('course', 0.2 * DEG)):
        assert scores['capture'][field].rms <= 1.2 * scores['voyage'][field].rms + margin, field


def _damaged(clean: Path, path: Path) -> tuple[Path, dict[str, int]]:
    """Write ``clean`` with every 40th line damaged in turn: truncated, bad checksum, junk."""
    lines = clean.read_bytes().split(b'\n')
    out = []
    damage = [lambda s: s[:len(s) // 2], lambda s: s[:-2] + (b'00' if s[-2:] != b'00'
                                                             else b'11'),
              lambda s: bytes(range(0, 256, 3)), lambda s: s[:5] + b'\x00\xff' + s[7:]]
    count = 0
    for i, line in enumerate(lines):
        if i % 40 == 7 and line.startswith(b'$') and not line[3:6] in (b'RMC', b'ZDA'):
            out.append(damage[count % len(damage)](line.rstrip(b'\r')))
            count += 1
        else:
            out.append(line)
    path.write_bytes(b'\n'.join(out))
    return path, {'damaged': count}


def test_damaged_logs_are_counted_and_skipped(shared_data: Path, repo: Path,
                                              tmp_path: Path) -> None:
    params = replay.load_params(repo / 'config' / 'sailboat.yaml')
    clean = shared_data / 'sailboat_ijsselmeer_nmea0183.log'
    damaged, info = _damaged(clean, tmp_path / 'damaged.nmea')
    assert info['damaged'] > 50
    summary, run = _replay(damaged, tmp_path / 'out', params)
    clean_summary, clean_run = _replay(clean, tmp_path / 'clean', params)

    def counted(summary: replay.Summary) -> tuple[str, int]:
        line = next(n for n in summary.notes if n.startswith('nmea0183: used '))
        return line, int(line.split('skipped ')[1].split(':')[0])
    skipped, total = counted(summary)
    assert total - counted(clean_summary)[1] == info['damaged'], skipped
    for reason in ('bad_checksum', 'not_nmea'):
        assert reason in skipped, skipped
    d = _track_difference(run, clean_run)
    assert np.median(d) < 0.5 and d.max() < 5.0, (np.median(d), d.max())


def test_a_log_without_heading_is_replayed_from_its_fixes(shared_data: Path,
                                                          tmp_path: Path) -> None:
    # The IJsselmeer log without its compass (HDG): positions at 1 Hz and a speed log. The
    # log's speed cannot be placed without a heading (the current took the whole course:
    # 10 kn of it on Signal K's plaka.log); the fixes and the receiver's own COG/SOG give
    # course and speed.
    clean = shared_data / 'sailboat_ijsselmeer_nmea0183.log'
    path = tmp_path / 'no_heading.nmea'
    path.write_text(''.join(line for line in clean.read_text(errors='replace').splitlines(
        keepends=True) if not line.startswith('$SDHDG')))
    summary, run = _replay(path, tmp_path / 'out', replay.load_params(None))
    assert any('has no heading: its speed log is not used' in n for n in summary.notes)
    assert any("the receiver's own COG/SOG is the receiver velocity" in n
               for n in summary.notes)
    assert set(summary.messages_in) == {'fix', 'gnss_velocity'} and not summary.rejected
    assert 'a receiver velocity fused' in summary.reference    # scored partly against itself
    course = evaluate.course_vs_reference(run, 1.0)
    speed = evaluate.speed_vs_reference(run, 1.0)
    print(f"\ncourse - COG RMS {course['rms']:.2f} deg, speed - SOG RMS {speed['rms']:.3f} m/s")
    # the fixes alone gave 4.40 deg and 0.222 m/s
    assert course['n'] > 100 and course['rms'] < 4.0 and speed['rms'] < 0.2


def test_a_log_without_speed_log_uses_the_fixes_for_the_speed(
        shared_data: Path, tmp_path: Path) -> None:
    # Heading and positions, no speed log: velocity.source none, said once; a log held
    # missing for the whole run would be an error in /diagnostics throughout. The receiver's
    # COG/SOG is its velocity over ground.
    clean = shared_data / 'sailboat_ijsselmeer_nmea0183.log'
    path = tmp_path / 'no_log.nmea'
    path.write_text(''.join(line for line in clean.read_text(errors='replace').splitlines(
        keepends=True) if line[3:6] not in ('VHW', 'VLW')))
    summary, run = _replay(path, tmp_path / 'out', replay.load_params(None))
    assert any('has no speed log (velocity.source none)' in n for n in summary.notes)
    assert set(summary.messages_in) == {'fix', 'imu', 'gnss_velocity'}
    assert not [line for line in summary.text().splitlines() if 'health     log' in line]
    course = evaluate.course_vs_reference(run, 1.0)
    print(f"\ncourse - COG RMS {course['rms']:.2f} deg")
    assert course['n'] > 100 and course['rms'] < 6.0


def test_a_log_too_short_for_an_output_says_so(shared_data: Path, tmp_path: Path) -> None:
    # One position and no heading (gpsd's april6_2019 sample): the estimator has a position,
    # and the first output waits max_gap for a heading that never comes.
    clean = shared_data / 'sailboat_ijsselmeer_nmea0183.log'
    lines = [line for line in clean.read_text(errors='replace').splitlines(keepends=True)
             if line[3:6] == 'RMC']
    path = tmp_path / 'one_fix.nmea'
    path.write_text(''.join(lines[:1]))
    with pytest.raises(replay.ReplayError, match='stayed fused .* the input is too short'):
        replay.run(path, tmp_path / 'out', replay.load_params(None), progress=False)


def test_a_file_neither_log_nor_bag_is_one_line(tmp_path: Path) -> None:
    path = tmp_path / 'notes.txt'
    path.write_text('Left the harbour at ten.\nWind NW 4.\n')
    run = subprocess.run([sys.executable, '-m', 'vessel_kinematics.tools.replay', str(path),
                          str(tmp_path / 'out')], capture_output=True, text=True, timeout=120)
    assert run.returncode == 1, run.stderr
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and 'is not an NMEA 0183 log or an NMEA 2000 capture' in lines[0] \
        and 'nor is it a bag' in lines[0], run.stderr


def test_a_log_of_times_of_day_takes_its_date_from_the_command_line(shared_data: Path,
                                                                    tmp_path: Path) -> None:
    # GGA's times of day and no RMC or ZDA (Signal K's plaka.log: GLL only): without --date one
    # line says how to give it; with it the stamps fall on that day.
    clean = shared_data / 'sailboat_ijsselmeer_nmea0183.log'
    path = tmp_path / 'gga_only.nmea'
    path.write_text(''.join(line for line in clean.read_text(errors='replace').splitlines(
        keepends=True) if line[3:6] in ('GGA', 'HDG')))
    command = [sys.executable, '-m', 'vessel_kinematics.tools.replay', str(path),
               str(tmp_path / 'out'), '--no-progress']
    run = subprocess.run(command, capture_output=True, text=True, timeout=120)
    assert run.returncode == 1 and 'replay --date YYYY-MM-DD' in run.stderr, run.stderr
    bad = subprocess.run(command + ['--date', '20-08-2018'], capture_output=True, text=True,
                         timeout=120)
    assert bad.returncode == 2 and 'is not a date (YYYY-MM-DD)' in bad.stderr, bad.stderr
    run = subprocess.run(command + ['--date', '2018-08-20'], capture_output=True, text=True,
                         timeout=120)
    assert run.returncode == 0, run.stderr
    fixes = evaluate.load_run(tmp_path / 'out', fix_topic='/fix').fixes
    assert 1_534_723_200 <= fixes.t[0] < 1_534_723_200 + 86_400


def test_a_log_without_position_exits_1_with_one_line(shared_data: Path, tmp_path: Path) -> None:
    clean = shared_data / 'sailboat_ijsselmeer_nmea0183.log'
    kept = [line for line in clean.read_text(errors='replace').splitlines()
            if line[3:6] in ('HDG', 'VHW', 'ZDA', 'MWV')]
    path = tmp_path / 'no_position.nmea'
    path.write_text('\n'.join(kept) + '\n')
    run = subprocess.run([sys.executable, '-m', 'vessel_kinematics.tools.replay', str(path),
                          str(tmp_path / 'out')], capture_output=True, text=True, timeout=120)
    assert run.returncode == 1, run.stderr
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith('replay: error: ') and \
        'no usable position' in lines[0], run.stderr
    assert not (tmp_path / 'out').exists()


def test_a_log_none_of_whose_lines_is_usable_says_why(tmp_path: Path) -> None:
    """Every time of the log refused (RMC dated 01-01-70, read as 2070): the log's counts."""
    lines = []
    for k in range(60):
        hhmmss = f'0000{k:02d}.00'
        rmc = (hhmmss, 'A', '5251.0000', 'N', '00518.6000', 'E', '6.0', '230.0', '010170',
               '1.3', 'E', 'A')
        gga = (hhmmss, '5251.0000', 'N', '00518.6000', 'E', '1', '12', '0.6', '-4', 'M',
               '46.8', 'M', '', '')
        lines += [str(pynmea2.RMC('GP', 'RMC', rmc)), str(pynmea2.GGA('GP', 'GGA', gga)),
                  str(pynmea2.HDT('HE', 'HDT', ('232.0', 'T')))]
    path = tmp_path / 'dated_1970.nmea'
    path.write_text('\n'.join(lines) + '\n')
    run = subprocess.run([sys.executable, '-m', 'vessel_kinematics.tools.replay', str(path),
                          str(tmp_path / 'out')], capture_output=True, text=True, timeout=120)
    assert run.returncode == 1, run.stderr
    (line,) = run.stderr.strip().splitlines()
    assert 'nothing to replay; the log: 180 lines' in line and 'bad_time' in line, line
    assert not (tmp_path / 'out').exists()

"""
The instrument-fault tests (estimation/faults.py): their thresholds, and no false alarm.

Each detector at its threshold, and the false-alarm rate on clean data: the simulator's clean
voyages (several seeds and sensor sets) and the real recordings of ../shared/data (83 minutes
of Lake Geneva with an integer-degree compass and a log at 0.1 kn, the IJsselmeer sailboat, the
motor vessel with its satellite compass, the Husky's IMU and wheel odometry): not one sample
refused as ``frozen_input``.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import sim_records as sr
from vessel_kinematics.estimation.config import (FROZEN_COG_BASELINE,
                                                 FROZEN_HEADING_JUMP_HOLD,
                                                 FROZEN_HEADING_TOLERANCE, FROZEN_HEADING_TURN,
                                                 FROZEN_HEADING_WINDOW,
                                                 FROZEN_LOG_SPEED_CHANGE, FROZEN_LOG_WINDOW)
from vessel_kinematics.estimation.faults import FrozenHeading, GnssTrack, repeated, StuckLog
from vessel_kinematics.tools import sim

T0 = 1_700_000_000 * 10 ** 9


# ------------------------------------------------------------------ the detectors

def test_a_frozen_compass_needs_the_gyro_to_turn_beyond_the_threshold() -> None:
    """Frozen when within 1 deg of its value while the gyro turned 10 deg in the window."""
    detector = FrozenHeading()
    assert detector.heading(T0, 1.0, None) is None
    rate = math.radians(3.0)                            # 3 deg/s
    t = T0
    for _ in range(int(math.degrees(FROZEN_HEADING_TURN) / 3.0) - 1):
        t += 10 ** 9
        detector.rate(1.0, rate)
        assert detector.heading(t, 1.0 + 0.5 * FROZEN_HEADING_TOLERANCE, None) is None
    t += 2 * 10 ** 9
    detector.rate(2.0, rate)
    why = detector.heading(t, 1.0, None)
    assert why is not None and 'gyro turned' in why
    assert detector.heading(t + 10 ** 9, 1.0, None) == 'compass frozen'
    assert detector.correction(None) == pytest.approx(detector.turn)
    # A compass that moves again is live: a new run starts.
    assert detector.heading(t + 2 * 10 ** 9, 1.0 + 2.0 * FROZEN_HEADING_TOLERANCE, None) is None
    assert not detector.frozen


def test_a_steady_heading_with_a_biased_gyro_is_no_frozen_compass() -> None:
    """A gyro bias of 0.05 deg/s for 10 minutes on a steady heading: never frozen."""
    detector = FrozenHeading()
    t = T0
    for _ in range(600):
        t += 10 ** 9
        detector.rate(1.0, math.radians(0.05))
        assert detector.heading(t, 0.3, None) is None


def test_without_a_gyro_the_course_over_ground_tells_a_frozen_compass() -> None:
    """No gyro: frozen when the fixes' course turns 45 deg at speed, the compass unchanged."""
    track, detector = GnssTrack(), FrozenHeading()
    speed, t = 3.0, 0.0
    n = e = 0.0
    course = None
    for k in range(120):
        t = float(k)
        heading = 0.0 if k < 60 else math.radians(0.9 * (k - 60))   # turning at 0.9 deg/s
        n += speed * math.cos(heading)
        e += speed * math.sin(heading)
        track.add(t, n, e)
        why = detector.heading(T0 + k * 10 ** 9, 0.2, track.course)
        if why is not None:
            course = track.course
            break
    assert why is not None and 'course over ground' in why
    assert abs(course) >= math.radians(45.0) - math.radians(1.0)
    assert FROZEN_COG_BASELINE / speed < 60.0


def _compass(detector: FrozenHeading, degrees: list[float], start: int = T0,
             step_s: float = 1.0) -> list[str | None]:
    """Feed a 1 Hz (``step_s``) compass's headings to ``detector``; return each answer."""
    return [detector.heading(start + int(k * step_s * 1e9), math.radians(d), None)
            for k, d in enumerate(degrees)]


def _heard(detector: FrozenHeading, degrees: float) -> int:
    """Feed a steady compass for the first window (no jump told in it); return the next stamp."""
    n = int(FROZEN_HEADING_WINDOW) + 1
    assert _compass(detector, [degrees] * n) == [None] * n
    return T0 + n * 10 ** 9


def test_a_compass_that_jumps_and_holds_is_frozen_there() -> None:
    """
    A yacht's compass jumped 307 -> 196 deg in a second and held it for 30 s (no gyro).

    Every held sample is refused at once, at any speed; the compass is live again when it
    moves on, and the first sample off the held value is taken.
    """
    detector = FrozenHeading()
    start = _heard(detector, 301.0)
    live = [303.0, 305.0, 306.0, 307.0]
    held = [196.0, 196.0, 195.0, 196.0] * 7 + [196.0, 196.0]
    answers = _compass(detector, live + held + [261.0, 261.0, 262.0], start)
    assert answers[:4] == [None] * 4
    assert all(a is not None and 'jumped -111 deg to 196.0 deg' in a for a in answers[4:34])
    assert answers[34:] == [None] * 3
    assert detector.jump is None and not detector.frozen


def test_one_glitched_compass_sample_costs_one_sample() -> None:
    """A compass reading 0 for one sample in 70 deg: that sample alone is refused."""
    detector = FrozenHeading()
    answers = _compass(detector, [71.0, 70.0, 0.0, 69.0, 70.0], _heard(detector, 71.0))
    assert [a is None for a in answers] == [True, True, False, True, True]


def test_a_turn_at_the_jump_rate_or_a_compass_back_is_no_jump() -> None:
    """40 deg a second in a hard turn, 10 Hz samples, or 120 deg after 3 s: all taken."""
    detector = FrozenHeading()
    turn = [0.0, 40.0, 80.0, 120.0, 160.0, 200.0]
    assert _compass(detector, turn, _heard(detector, 0.0)) == [None] * 6
    detector = FrozenHeading()
    turn = [4.0 * k for k in range(30)]
    assert _compass(detector, turn, _heard(detector, 0.0), step_s=0.1) == [None] * 30
    detector = FrozenHeading()
    start = _heard(detector, 0.0)       # the last sample 1 s before start: back 3 s after it
    assert detector.heading(start + 2 * 10 ** 9, math.radians(120.0), None) is None
    # The same 120 deg a second after the last sample is a jump.
    assert detector.heading(start + 3 * 10 ** 9, math.radians(240.0), None) is not None


def test_a_jump_the_gyro_made_or_the_course_confirms_is_taken() -> None:
    """The gyro turned with the jump, or the fixes' course at speed agrees with it."""
    detector = FrozenHeading()
    t = _heard(detector, 0.0)
    detector.rate(1.0, math.radians(90.0))
    assert detector.heading(t, math.radians(90.0), None) is None
    detector = FrozenHeading()
    t = _heard(detector, 0.0)
    detector.rate(1.0, 0.0)
    assert detector.heading(t, math.radians(90.0), None) is not None
    assert detector.heading(t + 10 ** 9, math.radians(90.0), math.radians(80.0)) is None
    detector = FrozenHeading()                  # the course agrees from the jump's first sample
    t = _heard(detector, 0.0)
    assert detector.heading(t, math.radians(90.0), math.radians(80.0)) is None
    assert detector.heading(t + 10 ** 9, math.radians(90.0), math.radians(80.0)) is None


def test_a_jump_in_the_compass_first_window_is_taken() -> None:
    """An AHRS up at a default heading jumps to the vessel's 5 s later: taken at once."""
    assert _compass(FrozenHeading(), [0.0] * 5 + [250.0] * 20) == [None] * 25


def test_a_jump_held_longer_than_the_limit_is_taken_as_the_heading() -> None:
    """A compass that jumps to a value and holds it, moored: taken after the limit."""
    detector = FrozenHeading()
    answers = _compass(detector, [0.0] * 15 + [250.0] * int(FROZEN_HEADING_JUMP_HOLD + 3))
    refused = [a for a in answers if a is not None]
    assert FROZEN_HEADING_JUMP_HOLD <= len(refused) <= FROZEN_HEADING_JUMP_HOLD + 1
    assert answers[-1] is None and detector.jump is None


def test_a_stuck_log_needs_the_fixes_speed_to_change_beyond_the_threshold() -> None:
    """A constant reading: stuck only once the fixes' speed changed by 1 m/s between windows."""
    for change, stuck in ((0.8 * FROZEN_LOG_SPEED_CHANGE, False),
                          (1.2 * FROZEN_LOG_SPEED_CHANGE, True)):
        track, detector = GnssTrack(), StuckLog()
        north, found = 0.0, None
        for k in range(int(4 * FROZEN_LOG_WINDOW)):
            t = float(k)
            speed = 5.0 if t < 1.5 * FROZEN_LOG_WINDOW else 5.0 - change
            north += speed
            track.add(t, north, 0.0)
            found = found or detector.reading(t, 4.0, track, (0.0, 0.0))
        assert (found is not None) is stuck, change


def test_a_turn_in_an_unknown_current_is_no_stuck_log() -> None:
    """A steady log in a turn, the current 0.5 m/s but not known (σ 0.5): never stuck."""
    track, detector = GnssTrack(), StuckLog()
    n = e = 0.0
    for k in range(60):
        psi = math.radians(6.0 * k)
        vn, ve = 5.0 * math.cos(psi) + 0.5, 5.0 * math.sin(psi)
        n, e = n + vn, e + ve
        track.add(float(k), n, e)
        assert detector.reading(float(k), 5.0, track, (0.0, 0.0), current_sigma=0.5) is None


def test_a_repeat_is_the_same_stamp_and_values() -> None:
    """Only an identical sample is a repeat: the same stamp with other values is not."""
    assert repeated((1, 2.0, 3.0), (1, 2.0, 3.0))
    assert not repeated((1, 2.0, 3.0), (1, 2.0, 3.5))
    assert not repeated(None, (1, 2.0, 3.0))


# ------------------------------------------------------------------ no false alarm

@pytest.mark.parametrize('changes, filter_changes, velocity', [
    ({}, {}, True),
    ({'seed': 5, 'log_surge_only': True, 'log_scale': 0.8, 'leeway': math.radians(4.0)}, {},
     True),
    ({'seed': 9, 'standstill_start': 100.0, 'standstill_end': 150.0}, {}, True),
    ({'seed': 11, 'imu_rate': 90.0, 'fix_rate': 9.0, 'velocity_rate': 9.0, 'truth_rate': 9.0,
      'compass_rate': 4.5}, {'velocity_input': False, 'water': False}, False),
])
def test_clean_voyages_raise_no_fault(changes: dict, filter_changes: dict,
                                      velocity: bool) -> None:
    """The simulator's clean voyages: no sample refused as a fault, no fault said."""
    config = sim.VoyageConfig(**changes)
    run = sr.run(config, sr.water_config(config, **filter_changes), velocity=velocity,
                 every=5.0)
    assert [r for _, _, r in run.rejections if r.reason.value == 'frozen_input'] == []
    assert not [e for _, e in run.events if 'frozen' in e.text or 'stuck' in e.text]


RECORDINGS = {
    'motorboat': ('motorboat_wide_turn', {'velocity.reference': 'water'},
                  {'fix': '/fix', 'imu': '/imu', 'velocity': '/speed_log'}),
    'sailboat': ('sailboat_ijsselmeer', {'velocity.reference': 'water'},
                 {'fix': '/fix', 'imu': '/imu', 'velocity': '/speed_log'}),
    'geneva': ('sailboat_geneva', {'velocity.reference': 'water'},
               {'fix': '/fix', 'imu': '/imu', 'velocity': '/speed_log'}),
    'husky': ('husky_gnss_imu_odom.bag',
              {'motion': 'ground', 'velocity.source': 'odometry', 'velocity.reference': 'ground',
               'imu.mounting_rpy': [math.pi / 2, 0.0, math.pi], 'imu.yaw_offset': 0.257},
              {'fix': '/fix', 'imu': '/imu/data', 'velocity': '/husky_velocity_controller/odom'}),
}


@pytest.mark.slow
@pytest.mark.parametrize('name', sorted(RECORDINGS))
def test_real_recordings_raise_no_fault(name: str, shared_data: Path) -> None:
    """The given recordings, through the replay's own loop: no sample refused as a fault."""
    from vessel_kinematics.ros.params import NavigatorParams
    from vessel_kinematics.ros.pipeline import INPUTS
    from vessel_kinematics.tools.replay import BagInput, Summary
    from vessel_kinematics.tools.replay.loop import Replay
    path, flat, remaps = RECORDINGS[name]
    params = NavigatorParams.from_flat({'velocity.source': 'twist_with_covariance', **flat})
    summary = Summary(input_path=shared_data / path, output_path=None)
    with BagInput(shared_data / path, params, [f'{k}:={v}' for k, v in remaps.items()]) as bag:
        run = Replay(bag, params, summary, lambda emission: None)
        run.run(None, None)
    counts = run.pipeline.counts
    assert sum(counts.get(input_name, 0) for input_name in INPUTS) > 1000     # accepted
    assert not [key for key in summary.rejected if key.endswith('/frozen_input')], \
        dict(summary.rejected)
    est = run.pipeline.estimator
    assert not [e for e in est.pop_events() if 'frozen' in e.text or 'stuck' in e.text]
    assert np.isfinite(est.state().p).all()

"""
The estimator on a whole fleet's troubles (issue 22), each against the simulator's truth.

A log silent for 15 minutes, a crash stop and a full-throttle run from rest, a compass frozen
in a turn, a log stuck while the boat slows, GNSS alone at 9 Hz with 2 % of its fixes 60 m
off, a receiver's own velocity, an origin 100 km and 300 km away, a figure-8 that separates
the current from the log's scale, and a stale compass at start-up. The estimator alone is fed
(``sim_records``): what a measurement does to the state, not what a message does to it.
"""

from __future__ import annotations

from collections.abc import Callable
import math
import re

import numpy as np
import pymap3d
import pytest
import sim_records as sr
from vessel_kinematics.core import flow, geodesy
from vessel_kinematics.core.frames import KNOT
from vessel_kinematics.estimation import (Estimator, FilterConfig, GnssFix, GroundVelocity,
                                          ImuSample, Level)
from vessel_kinematics.tools import sim, sim_sensors


def _speed_errors(run: sr.Run, t_from: float = 0.0, t_to: float = math.inf) -> np.ndarray:
    """Return the speed-over-ground errors (kn) of the samples within [t_from, t_to]."""
    return np.array([(est - true) / KNOT for t, est, true in sr.speeds(run)
                     if t_from <= t <= t_to])


def _heading(q: np.ndarray) -> float:
    return math.atan2(2.0 * (q[0] * q[3] + q[1] * q[2]), 1.0 - 2.0 * (q[2] ** 2 + q[3] ** 2))


# ------------------------------------------------------------------ a log silent for 15 minutes

GAP = (600.0, 900.0)


@pytest.fixture(scope='module')
def dropout() -> sr.Run:
    """Return a 30-minute voyage, a speed log (surge only) 20 % low, silent from 10 to 25 min."""
    config = sim.VoyageConfig(duration=1800.0, imu_rate=20.0, log_surge_only=True,
                              log_scale=0.8, log_outage=GAP, outage=(0.0, 0.0))
    return sr.run(config, sr.water_config(config), every=1.0)


def test_a_silent_log_holds_the_scale_and_the_current(dropout: sr.Run) -> None:
    """Scale and current stay within their pre-gap 2σ throughout the gap (issue 22's 0.95→0.13)."""
    before, _ = dropout.at(GAP[0] - 1.0)
    k0, c0 = before.calibration.log_scale, before.current[0:2]
    c_sigma = np.sqrt(np.diag(before.cov_current)[0:2])
    for t, s in zip(dropout.t, dropout.states):
        if not GAP[0] <= t <= GAP[0] + GAP[1]:
            continue
        assert abs(s.calibration.log_scale.value - k0.value) <= 2.0 * k0.sigma, t
        assert np.all(np.abs(s.current[0:2] - c0) <= 2.0 * c_sigma), t
        # Held, and honestly: the variance grows by the process noise alone.
        assert s.calibration.log_scale.sigma >= k0.sigma
    after_gap, _ = dropout.at(GAP[0] + GAP[1] - 1.0)
    assert after_gap.calibration.log_scale.sigma < 3.0 * k0.sigma
    # The speed over ground comes from the fixes meanwhile.
    assert np.sqrt(np.mean(_speed_errors(dropout, GAP[0] + 30.0, sum(GAP)) ** 2)) < 0.3


def test_a_returning_log_moves_no_output(dropout: sr.Run) -> None:
    """No speed jump over 0.5 kn when the log speaks again; it is reported gone and back."""
    errors = _speed_errors(dropout, sum(GAP), sum(GAP) + 60.0)
    assert np.max(np.abs(errors)) < 0.5
    # Across the first reading the estimate changes as the truth does, to 0.5 kn.
    before, k0 = dropout.at(sum(GAP) - 0.5)
    after, k1 = dropout.at(sum(GAP) + 1.5)
    v = dropout.truth.ground_velocity_ned()
    jump = (math.hypot(*after.v_n[0:2]) - math.hypot(*before.v_n[0:2])
            - (math.hypot(*v[k1, 0:2]) - math.hypot(*v[k0, 0:2])))
    assert abs(jump) / KNOT < 0.5
    texts = [e.text for _, e in dropout.events]
    assert any('back after 900 s' in text for text in texts)
    assert dropout.estimator.recoveries == 0
    # And after it the scale stays physical (the hidden recordings ask it above 0.6).
    assert min(s.calibration.log_scale.value for s in dropout.states) > 0.6


def test_a_missing_log_is_an_error_in_health() -> None:
    """With velocity.reference water and no reading for velocity_timeout: health says so."""
    config = sim.VoyageConfig(duration=60.0, log_outage=(20.0, 40.0), outage=(0.0, 0.0))
    seen: dict[str, object] = {}

    def watch(t: float, name: str, est) -> None:
        log = {h.name: h for h in est.health()}['log']
        seen.setdefault(log.level, (t, log.summary))

    sr.run(config, sr.water_config(config, velocity_timeout=10.0), watch=watch)
    t, summary = seen[Level.ERROR]
    assert 29.5 <= t <= 31.0                      # the last reading at 19.8 s, 10 s timeout
    assert 'missing' in summary and 'log scale' in summary and 'held' in summary
    assert Level.OK in seen


def test_a_log_reading_zero_while_the_boat_moves_calibrates_nothing() -> None:
    """
    A log reading 0 while the boat moves (astern, drifting) moves neither scale nor speed.

    The wheel at a standstill is not fused while the fixes give the speed, and health says so.
    One of the psaros33's 2014 logs read 0.0 kn for 150 s of sternway at 2 kn: fused, the scale
    went from 0.88 to 0.06, and the first reading after it gave 21 kn.
    """
    config = sim.VoyageConfig(duration=900.0, imu_rate=20.0, log_surge_only=True,
                              log_scale=0.8, outage=(0.0, 0.0))
    stall = (400.0, 550.0)

    def zero_log(readings: sim_sensors.Readings) -> None:
        for j, k in enumerate(readings.velocity_steps):
            if stall[0] <= (readings.stamps[k] - sim.START_NS) * 1e-9 < stall[1]:
                readings.velocity[j] = [0.0, 0.0, 0.0]

    seen: dict[str, str] = {}

    def watch(t: float, name: str, est) -> None:
        log = {h.name: h for h in est.health()}['log']
        if stall[0] + 20.0 <= t < stall[1]:
            seen[log.level.name] = log.summary

    run = sr.run(config, sr.water_config(config), every=1.0, alter=zero_log, watch=watch)
    before, _ = run.at(stall[0] - 1.0)
    k0 = before.calibration.log_scale
    for t, state in zip(run.t, run.states):
        if stall[0] <= t:
            assert abs(state.calibration.log_scale.value - k0.value) <= 2.0 * k0.sigma + 0.02, t
    errors = _speed_errors(run, stall[0], stall[1] + 60.0)
    print(f'scale {k0.value:.3f} -> {run.states[-1].calibration.log_scale.value:.3f}; speed '
          f'RMS {np.sqrt(np.mean(errors ** 2)):.2f} kn, max {np.max(np.abs(errors)):.2f} kn')
    assert np.max(np.abs(errors)) < 1.0 and run.estimator.recoveries == 0
    assert 'at a standstill' in seen.get('WARN', '')       # the fixes give more than 2 kn


def test_a_log_recalibrated_under_way_has_its_scale_relearnt_by_the_fixes() -> None:
    """
    A log whose reading steps from 1.6 times the speed to the speed: its scale is relearnt.

    A Flensburg training log (2013-07-31) did so within 2 s at 6 kn. The step is taken as a
    deceleration, the fixes disagree until they are refused and re-initialise the position; the
    log heard all along, it is its calibration that changed, so the recovery sets the scale's σ
    back to its prior as the log's own recovery does. The scale had stayed at 1.4-1.5, and the
    current took the difference (2.6 kn against a true 1.2 kn).
    """
    config = sim.VoyageConfig(duration=2400.0, imu_rate=20.0, compass_rate=1.0, fix_rate=1.0,
                              velocity_rate=1.0, speed=3.2, log_surge_only=True, log_scale=1.6,
                              outage=(0.0, 0.0))
    step = 900.0

    def recalibrate(readings: sim_sensors.Readings) -> None:
        for j, k in enumerate(readings.velocity_steps):
            if (readings.stamps[k] - sim.START_NS) * 1e-9 >= step:
                readings.velocity[j] = [v / config.log_scale for v in readings.velocity[j]]

    run = sr.run(config, sr.water_config(config), every=1.0, alter=recalibrate)
    assert run.estimator.recoveries == 1
    (t, event), = run.events
    assert step < t < step + 60.0 and 'position re-initialised' in event.text
    after = [s for t, s in zip(run.t, run.states) if t >= step + 300.0]
    scales = [s.calibration.log_scale.value for s in after]
    currents = [math.hypot(*s.current[0:2]) / KNOT for s in after]
    errors = _speed_errors(run, step + 300.0)
    print(f'scale {min(scales):.3f}-{max(scales):.3f}, current at most {max(currents):.2f} kn '
          f'(true {config.current_speed / KNOT:.2f}), speed error at most '
          f'{np.max(np.abs(errors)):.2f} kn')
    # Relearnt from 1.6, short of the truth by up to 0.09 as the first learning is (1.49 for
    # a true 1.6): the linearised tie stops short from a start 3σ off (docs/validation.md).
    assert all(abs(k - 1.0) < 0.1 for k in scales)
    assert max(currents) < config.current_speed / KNOT + 0.5
    assert np.max(np.abs(errors)) < 0.5


# ------------------------------------------------------------------ hard acceleration

PROFILE = ((0.0, 10.0), (130.0, 10.0), (133.0, 0.0), (160.0, 0.0), (163.0, 14.7),
           (330.0, 14.7), (333.0, 7.0))


@pytest.fixture(scope='module')
def manoeuvres() -> sr.Run:
    """Return at 10 m/s a turning circle, a 3 s crash stop, 0.5 g to 14.7 m/s, off the plane."""
    config = sim.VoyageConfig(duration=400.0, outage=(0.0, 0.0), velocity_rate=10.0,
                              surge_profile=PROFILE)
    return sr.run(config, sr.water_config(config))


def test_hard_acceleration_refuses_no_consistent_measurement(manoeuvres: sr.Run) -> None:
    """No fix and no log reading refused in a crash stop, 0.5 g from rest, off the plane."""
    assert manoeuvres.refused('fix') == []
    assert manoeuvres.refused('velocity', 'innovation_gate') == []
    assert manoeuvres.estimator.recoveries == 0
    truth = manoeuvres.truth
    accel = np.gradient(truth.u_r, truth.t)
    assert accel.min() < -3.0 and accel.max() > 4.5          # the crash stop, 0.5 g


def test_hard_acceleration_keeps_the_speed_within_half_a_knot(manoeuvres: sr.Run) -> None:
    """Speed over ground within 0.5 kn of the truth through every manoeuvre."""
    errors = _speed_errors(manoeuvres, 120.0)
    assert np.max(np.abs(errors)) < 0.5
    level = manoeuvres.estimator.accel
    assert level.sigma < 0.2            # back at cruising level after the last manoeuvre


def test_gnss_alone_through_a_crash_stop_never_recovers() -> None:
    """Without a log a crash stop is seen late, but as a manoeuvre: no recovery, no lock-out."""
    config = sim.VoyageConfig(duration=200.0, helm='straight', outage=(0.0, 0.0),
                              surge_profile=((0.0, 10.0), (60.0, 10.0), (63.0, 0.0)))
    run = sr.run(config, FilterConfig(velocity_input=False, antenna_b=(-3.0, 0.0, -5.0)),
                 velocity=False)
    assert run.estimator.recoveries == 0
    assert len(run.refused('fix')) <= 5
    errors = _speed_errors(run, 80.0)
    assert np.sqrt(np.mean(errors ** 2)) < 0.5


def test_a_speed_log_read_in_a_turn_follows_the_vessel_accelerating() -> None:
    """
    Full throttle in a figure-8, 7.5 to 19 kn in 10 s: the speed follows the log, surge only.

    A speed log at 2 Hz, fixes at 1 Hz. In a turn the log counts less (the hull's turning
    drift across its wheel, :mod:`.velocity_update`), and the acceleration its readings show
    was tested against that larger variance too: none was seen, and the speed lagged the
    truth by up to 5.6 kn (a random fleet of simulated voyages, 2026-12-06).
    """
    config = sim.VoyageConfig(duration=200.0, seed=8, helm='figure8', speed=3.87,
                              heading=4.95, current_speed=1.3, current_direction=2.46,
                              imu_rate=40.0, fix_rate=1.0, velocity_rate=2.0, fix_sigma=0.77,
                              log_scale=0.99, log_surge_only=True, leeway=-0.036,
                              outage=(0.0, 0.0),
                              surge_profile=((0.0, 3.87), (138.8, 3.87), (149.0, 9.86)))
    run = sr.run(config, sr.water_config(config), every=0.5)
    errors = _speed_errors(run, 120.0)
    print(f'speed error at most {np.max(np.abs(errors)):.2f} kn')
    assert np.max(np.abs(errors)) < 3.0


def test_a_position_that_steps_and_stays_is_no_manoeuvre() -> None:
    """
    A receiver whose position steps 80 m ahead at 12 s and stays there; fixes every 2 s, a log.

    The log reads a steady speed through the water, so no manoeuvre explains the step: the
    fixes are refused, the position is re-initialised once, and the speed stays within a knot.
    (One of Irene's 2008 logs on Lake Geneva did this: taken as a manoeuvre, the step gave
    60 kn of speed, a log scale of 0.06 and a recovery every 12 s for the rest of the race;
    here, before, 19 kn of speed error and no recovery.)
    """
    config = sim.VoyageConfig(duration=240.0, imu_rate=20.0, fix_rate=0.5, velocity_rate=1.0,
                              speed=2.0, helm='straight', log_surge_only=True, log_scale=0.9,
                              outage=(0.0, 0.0))
    north = 80.0 * math.cos(config.heading) / 111_320.0                     # deg
    east = 80.0 * math.sin(config.heading) / (111_320.0 * math.cos(math.radians(
        config.origin[0])))

    def step(readings: sim.Readings) -> None:
        t0 = readings.stamps[0]
        readings.fix_llh = [
            llh if llh is None or readings.stamps[k] - t0 < 12 * 10 ** 9
            else (llh[0] + north, llh[1] + east, llh[2])
            for k, llh in zip(readings.fix_steps, readings.fix_llh)]
    run = sr.run(config, sr.water_config(config), every=1.0, alter=step)
    assert run.estimator.recoveries == 1
    assert np.max(np.abs(_speed_errors(run, 30.0))) < 1.0


@pytest.mark.parametrize('sigma, recoveries', [(1.5, 1), (3.0, 0)])
def test_a_position_that_steps_at_rest_moves_no_speed(sigma: float, recoveries: int) -> None:
    """
    Nearly at rest, the log's wheel still, the receiver's position steps 25 m and stays.

    A receiver's static hold released (anemomind's coach boat: 21 and 32 m at 0-1 kn). The
    fixes are refused; with fixes of 1.5 m the position is re-initialised after 10 and keeps
    the log's speed (it was widened: 1.7 kn of error), with fixes of 3 m the first one its
    grown σ lets in, still 3σ off, moves the position alone (it moved the speed: 2.3 kn).
    """
    config = sim.VoyageConfig(duration=120.0, imu_rate=20.0, fix_rate=1.0, velocity_rate=1.0,
                              speed=0.2, helm='straight', log_surge_only=True,
                              outage=(0.0, 0.0), fix_sigma=sigma)
    north = 25.0 / 111_320.0                                                 # deg

    def step(readings: sim.Readings) -> None:
        t0 = readings.stamps[0]
        readings.fix_llh = [
            llh if llh is None or readings.stamps[k] - t0 < 60 * 10 ** 9
            else (llh[0] + north, llh[1], llh[2])
            for k, llh in zip(readings.fix_steps, readings.fix_llh)]
    run = sr.run(config, sr.water_config(config), every=1.0, alter=step)
    errors = _speed_errors(run, 30.0)
    print(f'speed error max {np.max(np.abs(errors)):.2f} kn, recoveries '
          f'{run.estimator.recoveries}')
    assert np.max(np.abs(errors)) < 1.2 and run.estimator.recoveries == recoveries


# ------------------------------------------------------------------ faulty instruments

def test_a_compass_frozen_in_a_turn_is_found_and_bridged_by_the_gyro() -> None:
    """Frozen for 30 s in the turning circle: found within 5 s, heading error ≤ gyro drift."""
    freeze = (40.0, 30.0)
    config = sim.VoyageConfig(duration=120.0, compass_freeze=freeze, outage=(0.0, 0.0))
    run = sr.run(config, sr.water_config(config))
    refused = run.refused('imu', 'frozen_input')
    assert refused and freeze[0] < refused[0][0] <= freeze[0] + 5.0
    assert refused[-1][0] < sum(freeze) + 0.1                 # live again after it
    drift = abs(run.truth.gyro_bias[2]) * freeze[1]
    for t, s in zip(run.t, run.states):
        if refused[0][0] + 0.1 <= t <= sum(freeze):
            k = run.index(t)
            error = abs(flow.ssa(_heading(s.q) - run.truth.psi[k]))
            assert error <= drift + math.radians(1.5), t
    texts = [e.text for _, e in run.events]
    assert any('compass frozen' in text for text in texts)
    assert any('compass live again' in text for text in texts)


def test_a_compass_that_jumps_and_holds_is_refused_at_once_with_no_gyro() -> None:
    """
    A rate-less compass jumps 110 deg and holds that value for 30 s in a figure-8 at 4 kn.

    A yacht's compass did so leaving the harbour (307 -> 196 deg, held 30 s while the boat
    turned at 1-3.6 kn): every held sample is refused from the jump on, the compass is live
    again after it, and the heading never goes to the held value.
    """
    hold = (120.0, 150.0)
    jump = math.radians(110.0)
    config = sim.VoyageConfig(duration=200.0, imu_rate=20.0, compass_rate=1.0, fix_rate=1.0,
                              log_surge_only=True, helm='figure8', outage=(0.0, 0.0),
                              surge_profile=((0.0, 2.0), (200.0, 2.0)))
    held: list[float] = []

    def jump_and_hold(readings) -> None:
        for j, k in enumerate(readings.imu_steps):
            if hold[0] <= (readings.stamps[k] - sim.START_NS) * 1e-9 < hold[1]:
                if not held:        # the published (ENU) yaw turns the other way: less jump
                    x, y, z, w = readings.imu_orientation[j]
                    yaw = 2.0 * math.atan2(z, w) - jump
                    held.extend((0.0, 0.0, math.sin(0.5 * yaw), math.cos(0.5 * yaw)))
                readings.imu_orientation[j] = list(held)

    run = sr.run(config, sr.water_config(config), alter=jump_and_hold)
    refused = run.refused('imu', 'frozen_input')
    assert refused and hold[0] <= refused[0][0] < hold[0] + 1.01
    assert len(refused) == int(hold[1] - hold[0])                 # every held sample, no other
    assert refused[-1][0] < hold[1]
    k0 = run.index(hold[0])
    value = run.truth.psi[k0] + jump
    for t, s in zip(run.t, run.states):
        if hold[0] <= t < hold[1]:
            error = abs(flow.ssa(_heading(s.q) - run.truth.psi[run.index(t)]))
            assert error < math.radians(45.0), t
            assert abs(flow.ssa(_heading(s.q) - value)) > math.radians(45.0), t
    texts = [e.text for _, e in run.events]
    assert any(re.search(r'compass jumped \+1[01][0-9] deg', text) for text in texts), texts
    assert any('compass live again' in text for text in texts)


def test_a_silent_compass_and_log_leave_the_speed_to_the_fixes_in_every_turn() -> None:
    """
    Compass and log silent for 5 min of circles: the heading follows the course, the speed holds.

    A rate-less compass (as NMEA's HDG) and the log stop together while the fixes go on (a
    psaros33 log of 2014: 15 min). Held on its last heading, the velocity could turn only by
    its sway: the speed fell by up to 3 kn in each turn. Now the heading follows the velocity
    through the water at each fix, and health says the compass is silent.
    """
    gap = (150.0, 450.0)
    config = sim.VoyageConfig(duration=600.0, imu_rate=20.0, compass_rate=1.0,
                              fix_rate=1.0, log_surge_only=True, helm='figure8',
                              log_outage=(gap[0], gap[1] - gap[0]), outage=(0.0, 0.0))

    def silence(readings) -> None:
        keep = [j for j, k in enumerate(readings.imu_steps)
                if not gap[0] <= (readings.stamps[k] - sim.START_NS) * 1e-9 < gap[1]]
        readings.imu_steps = [readings.imu_steps[j] for j in keep]
        for name in ('imu_orientation', 'imu_angular_velocity', 'imu_linear_acceleration'):
            setattr(readings, name, [getattr(readings, name)[j] for j in keep])

    summaries: list[tuple[float, str]] = []

    def watch(t: float, name: str, est) -> None:
        heading = {h.name: h for h in est.health()}['heading']
        if heading.level is Level.WARN:
            summaries.append((t, heading.summary))

    run = sr.run(config, sr.water_config(config), alter=silence, watch=watch)
    errors = _speed_errors(run, gap[0] + 30.0, gap[1])
    # Circles of 75 s at 8-10 kn and 1 Hz fixes: before, RMS 2.2 kn and up to 7 kn off.
    assert np.sqrt(np.mean(errors ** 2)) < 1.0 and np.max(np.abs(errors)) < 2.5
    assert summaries and gap[0] + 9.0 < summaries[0][0] < gap[0] + 13.0
    assert 'compass silent' in summaries[0][1]
    assert summaries[-1][0] < gap[1] + 1.0                  # the compass back: OK again
    texts = [e.text for _, e in run.events]
    assert any('compass back' in text for text in texts)


def test_a_log_stuck_while_the_boat_slows_is_found() -> None:
    """A log stuck while the boat slows from 10 to 5 m/s: found, refused, the fixes carry on."""
    stuck = (150.0, 60.0)
    config = sim.VoyageConfig(duration=260.0, log_surge_only=True, outage=(0.0, 0.0),
                              log_freeze=stuck,
                              surge_profile=((0.0, 10.0), (160.0, 10.0), (170.0, 5.0)))
    run = sr.run(config, sr.water_config(config))
    refused = run.refused('velocity', 'frozen_input')
    assert refused and refused[0][0] < sum(stuck)
    assert all(stuck[0] <= t < sum(stuck) for t, _ in refused)
    # The fixes alone carry the speed from then on (they had fought the stuck log a while).
    after = _speed_errors(run, refused[0][0] + 10.0, sum(stuck))
    assert np.max(np.abs(after)) < 1.5 and np.sqrt(np.mean(after ** 2)) < 0.5
    assert any('log stuck' in e.text for _, e in run.events)


def test_a_repeated_sample_is_refused_and_nothing_changes() -> None:
    """A driver sending the same message twice: the second is refused as frozen_input."""
    config = sim.VoyageConfig(duration=20.0, outage=(0.0, 0.0))
    truth = sim.simulate(config)
    records = sr.records(sim.sensor_readings(truth, config), truth)
    est = sr.Estimator(sr.water_config(config))
    for name, rec in records[:4000]:
        getattr(est, name)(rec)
    for name in ('fix', 'imu', 'velocity'):
        last = [rec for n, rec in records[:4000] if n == name][-1]
        before = est.x.copy()
        out = getattr(est, name)(last)
        assert out is not None and out.reason.value == 'frozen_input'
        np.testing.assert_array_equal(est.x, before)


# ------------------------------------------------------------------ GNSS alone

@pytest.fixture(scope='module')
def gnss_only() -> sr.Run:
    """Return fixes at 9 Hz, 2 % of them 60 m off, a heading-only compass at 4.5 Hz, no log."""
    config = sim.VoyageConfig(duration=300.0, imu_rate=90.0, fix_rate=9.0, velocity_rate=9.0,
                              truth_rate=9.0, compass_rate=4.5, fix_outlier_fraction=0.02,
                              outage=(0.0, 0.0))
    return sr.run(config, FilterConfig(velocity_input=False, antenna_b=(-3.0, 0.0, -5.0)),
                  velocity=False)


def test_gnss_only_speed_within_a_third_of_a_knot(gnss_only: sr.Run) -> None:
    """Speed over ground within 0.3 kn RMS of the truth; each 60 m jump refused."""
    errors = _speed_errors(gnss_only, 10.0)
    assert np.sqrt(np.mean(errors ** 2)) < 0.3
    assert np.percentile(np.abs(errors), 99) < 1.0
    outliers = gnss_only.refused('fix', 'innovation_gate')
    assert 0.01 * 2700 < len(outliers) < 0.03 * 2700
    assert gnss_only.estimator.recoveries == 0


def test_gnss_only_at_one_hertz_takes_no_outlier_for_a_manoeuvre() -> None:
    """
    Fixes at 1 Hz, 1 % of them 60 m off, a compass at 1 Hz, no log: no outlier moves the speed.

    With no velocity measured, a refused fix is tested as a manoeuvre begun when the fixes'
    innovations last turned, up to 10 s back: 0.6 g over 5 s explains 60 m, and one outlier
    was taken as 70-100 kn for 8 s (a random fleet of simulated voyages, 2026-12-06). A fix
    continues a manoeuvre only when the one before it was off the same way, refused or at
    least a quarter as far.
    """
    config = sim.VoyageConfig(duration=900.0, seed=27, helm='voyage', speed=2.0908,
                              heading=2.0332, current_speed=1.3968, current_direction=4.9616,
                              imu_rate=100.0, fix_rate=1.0, velocity_rate=5.0, fix_sigma=1.2328,
                              compass_rate=1.0, fix_outlier_fraction=0.01)
    run = sr.run(config, FilterConfig(velocity_input=False, antenna_b=(-3.0, 0.0, -5.0)),
                 every=1.0, velocity=False)
    errors = _speed_errors(run, 10.0)
    print(f'speed error at most {np.max(np.abs(errors)):.2f} kn, '
          f'{len(run.refused("fix", "innovation_gate"))} fixes refused')
    assert np.max(np.abs(errors)) < 3.0
    assert run.estimator.recoveries == 0


def test_a_heading_only_compass_gives_its_rate(gnss_only: sr.Run) -> None:
    """With no gyro the yaw rate comes from the compass's headings, within 0.5 deg/s."""
    errors = []
    for t, s in zip(gnss_only.t, gnss_only.states):
        if t > 10.0:
            errors.append(s.omega[2] - gnss_only.truth.r[gnss_only.index(t)])
    assert math.degrees(np.sqrt(np.mean(np.square(errors)))) < 0.5
    assert {h.name: h.level for h in gnss_only.estimator.health()}['heading'] == Level.OK


def test_a_receiver_alone_at_half_a_hertz_gives_the_speed() -> None:
    """
    Fixes every 2 s and no other sensor (a yacht's GLL-only log) give the speed over ground.

    Each step is the usual one, not a gap, so the position is integrated from the speed (every
    step crossed as a gap left the speed at 0, 10 kn off), with no heading error in its process
    noise (the unknown attitude's made the speed collapse in turns); the fixes falling behind
    the turning circle's onset for 18 s are a manoeuvre begun within 10 s (they were refused,
    and a recovery followed). A 30 s outage is still a gap.
    """
    config = sim.VoyageConfig(duration=600.0, fix_rate=0.5, truth_rate=0.5, antenna=(0, 0, 0),
                              outage=(300.0, 30.0))

    def no_imu(readings: sim_sensors.Readings) -> None:
        readings.imu_steps.clear()

    run = sr.run(config, FilterConfig(velocity_input=False), velocity=False, alter=no_imu)
    errors = _speed_errors(run, 60.0)
    print(f'speed RMS {np.sqrt(np.mean(errors ** 2)):.2f} kn, p99 '
          f'{np.percentile(np.abs(errors), 99):.2f} kn over {errors.size} samples')
    assert np.sqrt(np.mean(errors ** 2)) < 0.5
    assert run.estimator.recoveries == 0 and not run.rejections


def test_a_receivers_own_velocity_is_fused_over_ground() -> None:
    """GNSS at 1 Hz and the receiver's velocity (0.05 m/s): the speed follows it, not the fixes."""
    config = sim.VoyageConfig(duration=200.0, fix_rate=1.0, outage=(0.0, 0.0))
    plain = sr.run(config, FilterConfig(velocity_input=False, antenna_b=(-3.0, 0.0, -5.0)),
                   velocity=False)
    fused = sr.run(config, FilterConfig(velocity_input=False, antenna_b=(-3.0, 0.0, -5.0)),
                   velocity=False, ground_velocity=0.05)
    rms = [np.sqrt(np.mean(_speed_errors(r, 20.0) ** 2)) for r in (plain, fused)]
    assert rms[1] < 0.15 and rms[1] < 0.5 * rms[0]
    assert fused.refused('ground_velocity') == []


def test_the_first_heading_keeps_a_receivers_velocity_where_it_was() -> None:
    """
    A receiver's fixes and velocity before the compass's first heading (no log): no turn.

    Until a heading is told the velocity over ground is held in the axes of heading 0. A 2008
    Lake Geneva log (Irene, RMC at 0.5 Hz, HDG from 1 s) went out at 284° and then 212° at
    0.9 kn while its receiver said 142° at 2.2 kn, and its next three velocities were refused:
    the first heading, 145°, had turned the velocity with it.
    """
    course, speed = math.radians(142.0), 1.15
    v_ned = np.array([speed * math.cos(course), speed * math.sin(course), 0.0])
    est = Estimator(FilterConfig(velocity_input=False))
    lat0, lon0, t0 = math.radians(46.4989), math.radians(6.6725), 1_214_000_000 * 10 ** 9
    fix_cov, vel_cov = np.diag([6.25, 6.25, 25.0]), np.diag([0.04, 0.04, 1e6])
    yaw = math.radians(145.0)
    heading = (math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2))
    refused, before = [], None
    for k in range(12):
        t = t0 + k * 10 ** 9
        lat, lon, h = geodesy.ned2llh(tuple(v_ned * k), lat0, lon0, 0.0)
        refused.append(est.fix(GnssFix(t, lat, lon, h, fix_cov)))
        refused.append(est.ground_velocity(GroundVelocity(t, v_ned, vel_cov)))
        if k == 2:
            before = est.velocity_ned()
        if k >= 2:                                 # the compass speaks from 2.5 s
            refused.append(est.imu(ImuSample(t + 5 * 10 ** 8, heading, None, None, None)))
            if k == 2:
                after = est.velocity_ned()
                assert np.allclose(after[0:2], before[0:2], atol=0.05), (before, after)
    assert refused == [None] * len(refused)
    np.testing.assert_allclose(est.velocity_ned()[0:2], v_ned[0:2], atol=0.05)


def test_a_heading_back_after_a_pause_keeps_a_receivers_velocity() -> None:
    """
    A log paused for 858 s resumes on another course, its receiver's velocity before the compass.

    Irene's 2008 log of 11 July (no log used, RMC at 0.5 Hz) stopped at 254° and resumed at
    050°, its first fix and receiver's velocity a second before the compass. That heading
    turned the velocity with it by 156°, the next receiver's velocity and fix were refused,
    and the velocity taken as a manoeuvre reached 22 kn. A heading back after
    ``velocity_timeout`` s of silence keeps the velocity over ground where it was.
    """
    est = Estimator(FilterConfig(velocity_input=False))
    lat0, lon0, t0 = math.radians(46.2302), math.radians(6.1700), 1_215_783_000 * 10 ** 9
    fix_cov, vel_cov = np.diag([6.25, 6.25, 25.0]), np.diag([0.04, 0.04, 1e6])
    refused, speeds = [], []

    def leg(start: np.ndarray, course_deg: float, knots: float, t_from: float,
            seconds: float) -> None:
        course = math.radians(course_deg)
        v_ned = knots * KNOT * np.array([math.cos(course), math.sin(course), 0.0])
        heading = (math.cos(course / 2), 0.0, 0.0, math.sin(course / 2))
        for k in range(int(seconds / 2.0)):
            t = t0 + round((t_from + 2.0 * k) * 1e9)
            lat, lon, h = geodesy.ned2llh(tuple(start + v_ned * 2.0 * k), lat0, lon0, 0.0)
            refused.append(est.fix(GnssFix(t, lat, lon, h, fix_cov)))
            refused.append(est.ground_velocity(GroundVelocity(t, v_ned, vel_cov)))
            speeds.append(float(np.hypot(*est.velocity_ned()[0:2])) / KNOT)
            refused.append(est.imu(ImuSample(t + 10 ** 9, heading, None, None, None)))
            speeds.append(float(np.hypot(*est.velocity_ned()[0:2])) / KNOT)

    leg(np.zeros(3), 254.0, 5.8, 0.0, 120.0)
    leg(np.array([-930.0, -240.0, 0.0]), 50.0, 7.0, 120.0 + 858.0, 60.0)
    assert refused == [None] * len(refused)
    assert max(speeds) < 7.5, max(speeds)
    assert est.resets == 0


def _walked_north(metres: Callable[[float], float]) -> Callable[[sim.Readings], None]:
    """Return an ``alter`` that moves each fix north by ``metres(t)``, t s after the start."""
    def walk(readings: sim.Readings) -> None:
        t0 = readings.stamps[0]
        readings.fix_llh = [
            llh if llh is None else (llh[0] + metres((t - t0) * 1e-9) / 111_320.0, llh[1], llh[2])
            for t, llh in zip((readings.stamps[k] for k in readings.fix_steps),
                              readings.fix_llh)]
    return walk


def test_a_receiver_wandering_at_start_up_moves_neither_current_nor_speed() -> None:
    """
    Just started, the receiver walks its fixes 25 m north in 6 s; the log reads on.

    Four of the 41 yacht logs start so (Irene, 7 May and 18 June 2008: 14-25 m within 2-6 s
    while the receiver's SOG and the log read 1.5-3 kn). Fused in full, the current took the
    wander, 3.1 kn within 16 s, and the speed followed it. In the first minute, a fix more than
    3σ of its own off moves the position only, its σ grown by the step.
    """
    config = sim.VoyageConfig(duration=300.0, imu_rate=20.0, compass_rate=1.0, fix_rate=1.0,
                              velocity_rate=1.0, speed=1.5, log_surge_only=True,
                              outage=(0.0, 0.0), current_speed=0.1)
    run = sr.run(config, sr.water_config(config), every=1.0,
                 alter=_walked_north(lambda t: 25.0 * min(max((t - 10.0) / 6.0, 0.0), 1.0)))
    errors = _speed_errors(run)
    currents = [math.hypot(*s.current[0:2]) / KNOT for s in run.states]
    true = config.current_speed / KNOT
    print(f'speed error at most {np.max(np.abs(errors)):.2f} kn, current at most '
          f'{max(currents):.2f} kn (true {true:.2f})')
    assert np.max(np.abs(errors)) < 1.5           # what is under 3σ of each fix still moves it
    assert max(currents) < true + 0.6
    assert run.estimator.recoveries == 0


@pytest.mark.parametrize('seed', [2, 3])
def test_a_receiver_wandering_in_steps_at_start_up_moves_neither_current_nor_speed(
        seed: int) -> None:
    """
    Just started, a receiver at 0.5 Hz steps 11, 5.6 and 5.5 m north at three fixes in a row.

    As Irene's 7 May 2008 log does, while the boat sails at 1.5 kn and the log reads on. Only
    the first step is beyond 3σ of its own (σ 2.5 m); the two after it, taken in full, went to
    the current and the speed (1.44 and 0.92 kn of current against 0.19 kn). A fix beyond 1σ
    that goes on the way of a wander found at the fix before it is the wander too.
    """
    config = sim.VoyageConfig(duration=300.0, seed=seed, imu_rate=20.0, compass_rate=1.0,
                              fix_rate=0.5, velocity_rate=1.0, speed=0.77, log_surge_only=True,
                              fix_sigma=2.5, outage=(0.0, 0.0), current_speed=0.1)
    steps = ((10.0, 11.0), (12.0, 5.6), (14.0, 5.5))                      # (s, m north)
    run = sr.run(config, sr.water_config(config), every=1.0,
                 alter=_walked_north(lambda t: sum(d for at, d in steps if t >= at)))
    errors = _speed_errors(run)
    currents = [math.hypot(*s.current[0:2]) / KNOT for s in run.states]
    print(f'speed error at most {np.max(np.abs(errors)):.2f} kn, current at most '
          f'{max(currents):.2f} kn')
    assert np.max(np.abs(errors)) < 1.0
    assert max(currents) < 0.8
    assert run.estimator.recoveries == 0


@pytest.mark.parametrize('north', [2.0, 5.0, 8.0, 12.0])
def test_a_fix_claiming_an_axis_exact_at_start_up_is_taken(north: float) -> None:
    """A fix whose east variance is 0 (PSD, so admitted) stepping north: no singular matrix."""
    est = Estimator(FilterConfig(velocity_input=False))
    lat0, lon0, t0 = math.radians(46.2122), math.radians(6.1708), 1_403_795_421 * 10 ** 9
    for k in range(12):
        t = t0 + k * 10 ** 9
        lat, lon, h = geodesy.ned2llh((north if k >= 6 else 0.0, 0.0, 0.0), lat0, lon0, 0.0)
        est.ground_velocity(GroundVelocity(t, np.zeros(3), np.diag([0.04, 0.04, 1e6])))
        refused = est.fix(GnssFix(t, lat, lon, h, np.diag([1.0, 0.0, 4.0])))
        assert refused is None or refused.reason.value == 'innovation_gate', refused
    assert np.all(np.isfinite(est.x)) and abs(float(est.x[est.layout.p][1])) < 1e-3


def test_a_tidal_stream_at_start_up_is_still_learnt() -> None:
    """A 2.9 kn stream from the start: its fixes drift steadily, none is taken as wander."""
    config = sim.VoyageConfig(duration=180.0, imu_rate=20.0, compass_rate=1.0, fix_rate=1.0,
                              velocity_rate=1.0, speed=2.0, log_surge_only=True,
                              outage=(0.0, 0.0), current_speed=1.5, fix_sigma=0.5)
    run = sr.run(config, sr.water_config(config), every=1.0)
    true = config.current_speed / KNOT
    late = [math.hypot(*s.current[0:2]) / KNOT for t, s in zip(run.t, run.states) if t >= 90.0]
    errors = _speed_errors(run)
    print(f'current {min(late):.2f}-{max(late):.2f} kn after 90 s (true {true:.2f}), speed '
          f'error at most {np.max(np.abs(errors)):.2f} kn')
    assert all(abs(c - true) < 0.5 for c in late)
    assert np.max(np.abs(errors)) < 1.5


def test_a_receiver_settling_at_rest_moves_no_speed() -> None:
    """
    A receiver just started walks its fixes 180 m in 20 s while its own velocity says 0.

    A psaros33 log of 2014 (RMC at 1 Hz, SOG 0.0 at the mooring) replayed with no log: the
    fixes refused, then taken as a manoeuvre, gave 86-115 kn for 5 s and the filtered position
    170 m past the fixes. The receiver's own velocity would show a manoeuvre: with it heard,
    the fixes are a step, and the position, re-initialised, keeps the speed it says.
    """
    est = Estimator(FilterConfig(velocity_input=False))
    lat0, lon0, t0 = math.radians(46.2122), math.radians(6.1708), 1_403_795_421 * 10 ** 9
    fix_cov, vel_cov = np.diag([6.25, 6.25, 25.0]), np.diag([0.04, 0.04, 1e6])
    north = [0.0, 51.9, 122.5, 126.2, 128.0, 137.3, 146.0, 155.8, 155.8, 163.3, 165.1, 168.0,
             172.5, 176.3, 175.0, 174.4, 174.4, 174.4, 174.4, 178.1] + [178.1] * 20
    speeds = []
    for k, n in enumerate(north):
        t = t0 + k * 10 ** 9
        lat, lon, h = geodesy.ned2llh((n, 0.0, 0.0), lat0, lon0, 0.0)
        est.fix(GnssFix(t, lat, lon, h, fix_cov))
        est.ground_velocity(GroundVelocity(t, np.zeros(3), vel_cov))
        speeds.append(float(np.hypot(*est.velocity_ned()[0:2])))
    assert max(speeds) / KNOT < 1.0, [round(s / KNOT, 1) for s in speeds]
    assert est.recoveries >= 1                  # the position re-initialised on the fixes
    lay = est.layout
    assert abs(float(est.x[lay.p][0]) - north[-1]) < 5.0


# ------------------------------------------------------------------ far from the origin

@pytest.mark.parametrize('distance', [0.0, 100e3, 300e3])
def test_far_from_the_origin_the_outputs_stay_on_the_fixes(distance: float) -> None:
    """
    The origin 0, 100 and 300 km away: fix/filtered within 1 m (RMS) and 5 m of the truth.

    The current is in the map's axes (its frame) and its set in /diagnostics from true north.
    """
    config = sim.VoyageConfig(duration=200.0, outage=(0.0, 0.0))
    lat0, lon0, h0 = math.radians(config.origin[0]), math.radians(config.origin[1]), \
        config.origin[2]
    lat, lon, _ = geodesy.ned2llh((0.6 * distance, 0.8 * distance, 0.0), lat0, lon0, h0)
    origin = (math.degrees(lat), math.degrees(lon), 0.0)
    run = sr.run(config, sr.water_config(config, origin=origin), every=1.0)
    truth = run.truth
    t_lat, t_lon, t_h = sim_sensors.surface_llh(truth.north, truth.east, (lat0, lon0, h0))
    horizontal, vertical, course, current = [], [], [], []
    for t, s in zip(run.t, run.states):
        if t < 20.0:
            continue
        k = run.index(t)
        # The current is published in map: the truth's (true north) turned by the meridians'
        # convergence, found here from where the vessel's north points in the origin's ENU.
        lat_d, lon_d = math.degrees(s.llh[0]), math.degrees(s.llh[1])
        north = pymap3d.enu2geodetic(0.0, 100.0, 0.0, lat_d, lon_d, 0.0)
        e0, n0, _ = pymap3d.geodetic2enu(lat_d, lon_d, 0.0, *origin)
        e1, n1, _ = pymap3d.geodetic2enu(north[0], north[1], 0.0, *origin)
        gamma = math.atan2(e1 - e0, n1 - n0)
        if t >= 100.0:             # learnt by then
            current.append(flow.ssa(math.atan2(s.current[1], s.current[0]) - gamma
                                    - math.atan2(truth.current_e[k], truth.current_n[k])))
        e, n, u = pymap3d.geodetic2enu(math.degrees(s.llh[0]), math.degrees(s.llh[1]), s.llh[2],
                                       math.degrees(t_lat[k]), math.degrees(t_lon[k]), t_h[k])
        horizontal.append(math.hypot(e, n))
        vertical.append(abs(u))
        course.append(abs(flow.ssa(s.course - truth.course()[k])))
        # p and llh are one point: the map position is where the geodetic one is.
        np.testing.assert_allclose(
            pymap3d.geodetic2ned(math.degrees(s.llh[0]), math.degrees(s.llh[1]), s.llh[2],
                                 *origin), s.p, atol=1e-3)
    assert math.sqrt(np.mean(np.square(horizontal))) < 1.0
    assert np.percentile(horizontal, 95) < 1.0
    assert max(vertical) < 5.0
    assert math.degrees(np.mean(course)) < 1.0
    assert abs(math.degrees(np.mean(current))) < 0.5     # 4.5 deg at 300 km in map axes
    # /diagnostics says the set from the vessel's true north, as a navigator reads it.
    set_true = math.radians(float(run.estimator.estimates()['current set (deg)']))
    assert abs(flow.ssa(set_true - math.atan2(truth.current_e[-1], truth.current_n[-1]))) \
        < math.radians(3.0)
    assert run.rejections == []


# ------------------------------------------------------------------ current against scale

def test_a_figure_eight_separates_the_current_from_the_scale() -> None:
    """
    Circles to port and starboard: the mean current within 0.1 m/s of a least-squares fit.

    The fit V = s · z · [cos ψ, sin ψ] + c of the ground velocity against the log's reading
    z and the heading, over the figure-8 (a navigator's way to calibrate a log and find the
    set), against the estimator's current averaged over the same stretch.
    """
    config = sim.VoyageConfig(duration=600.0, imu_rate=20.0, helm='figure8', log_scale=0.8,
                              log_surge_only=True, outage=(0.0, 0.0))
    run = sr.run(config, sr.water_config(config), every=1.0)
    truth = run.truth
    readings = sim.sensor_readings(truth, config)
    v_ned = truth.ground_velocity_ned()
    rows, rhs = [], []
    for k, nu in zip(readings.velocity_steps, readings.velocity):
        if truth.t[k] < 100.0:
            continue
        c, s = math.cos(truth.psi[k]), math.sin(truth.psi[k])
        rows += [[nu[0] * c, 1.0, 0.0], [nu[0] * s, 0.0, 1.0]]
        rhs += [v_ned[k, 0], v_ned[k, 1]]
    fit = np.linalg.lstsq(np.array(rows), np.array(rhs), rcond=None)[0]
    mean = np.mean([s.current[0:2] for t, s in zip(run.t, run.states) if t >= 100.0], axis=0)
    assert np.linalg.norm(mean - fit[1:3]) < 0.1
    assert abs(run.states[-1].calibration.log_scale.value - 1.0 / fit[0]) < 0.03


@pytest.mark.parametrize('log_sigma, fix_sigma', [(0.03, 1.5), (0.0, 0.1)])
def test_a_straight_leg_leaves_the_scale_where_it_was(log_sigma: float,
                                                      fix_sigma: float) -> None:
    """
    A straight leg at a steady 4 kn, a 1 Hz log exact in scale: k stays within its prior's σ.

    Nothing on the leg tells the scale from a current along the track, so neither may move
    far. Two Jacobians taken at noisy estimates walked them in these 15 minutes
    (docs/validation.md): ∂z/∂k at the prior's speed, with the log's own noise (σ 0.03 m/s),
    k 0.59 ± 0.02 and the current 1.4 m/s; the drift ratio's share of ∂v/∂u, with an exact
    log and fixes of σ 0.1 m, k 1.38 ± 0.07 and 0.58 m/s. Now k stays within 0.90-1.0 and
    0.98-1.0 (σ 0.07-0.1), the current within 0.26 and 0.06 m/s.
    """
    config = sim.VoyageConfig(duration=900.0, helm='straight', speed=2.06, current_speed=0.0,
                              log_surge_only=True, velocity_rate=1.0, velocity_sigma=log_sigma,
                              fix_sigma=fix_sigma, imu_rate=20.0, fix_rate=1.0,
                              outage=(0.0, 0.0))
    run = sr.run(config, sr.water_config(config), every=10.0)
    for state in run.states:
        assert abs(state.calibration.log_scale.value - 1.0) < 0.2
        assert np.linalg.norm(state.current[0:2]) < 0.5


# ------------------------------------------------------------------ start-up

def test_nothing_is_published_from_a_stale_compass_at_start_up() -> None:
    """A compass sample 3 s older than the first fix: not ready until a fresh heading comes."""
    config = sim.VoyageConfig(duration=20.0, outage=(0.0, 0.0))
    truth = sim.simulate(config)
    records = sr.records(sim.sensor_readings(truth, config), truth)
    est = sr.Estimator(sr.water_config(config))
    first_imu = next(rec for n, rec in records if n == 'imu')
    assert est.imu(first_imu) is None
    later = [(n, rec) for n, rec in records if rec.stamp_ns >= first_imu.stamp_ns + 3_000_000_000]
    fix = next(rec for n, rec in later if n == 'fix')
    assert est.fix(fix) is None
    assert not est.ready                         # the heading is 3 s old
    imu = next(rec for n, rec in later if n == 'imu' and rec.stamp_ns >= fix.stamp_ns)
    assert est.imu(imu) is None
    assert not est.ready                         # nothing has told the velocity yet
    log = next(rec for n, rec in later if n == 'velocity' and rec.stamp_ns >= imu.stamp_ns)
    assert est.velocity(log) is None
    assert est.ready


@pytest.mark.parametrize('sensors', ['log', 'fixes'])
def test_nothing_is_published_before_a_measurement_tells_the_velocity(sensors: str) -> None:
    """
    The first state out carries a measured velocity, never the prior's 0 m/s.

    A vessel under way at 5 m/s: a first fix and a heading alone would go out at 0 kn (canboat's
    Furuno figure-8 began so: 6.2 kn off the receiver's SOG, the run's largest error). With a
    log the first reading tells it; with fixes alone, the second fix.
    """
    config = sim.VoyageConfig(duration=10.0, outage=(0.0, 0.0), antenna=(0.0, 0.0, 0.0))
    filter_config = (sr.water_config(config) if sensors == 'log'
                     else FilterConfig(velocity_input=False))
    run = sr.run(config, filter_config, every=0.0, velocity=sensors == 'log')
    speeds = list(sr.speeds(run))
    t, first, true = speeds[0]
    print(f'{sensors}: first state at {t:.2f} s, {first:.2f} m/s (truth {true:.2f})')
    assert abs(first - true) < 1.0
    assert all(abs(est - true) < 1.5 for _, est, true in speeds)


# ------------------------------------------------------------------ low speed

def test_slow_turns_keep_the_course_between_heading_and_track() -> None:
    """
    Circles at 0.8 m/s (1.6 kn) in a 0.3 m/s current, a speed log: the course stays physical.

    Never more than 15° off both the true course and the heading, and the sideslip through the
    water within 30° (the hull's own reaches 12° here; a drift is a share of the speed).
    """
    config = sim.VoyageConfig(duration=400.0, helm='figure8', surge_profile=((0.0, 0.8),),
                              current_speed=0.3, log_surge_only=True, outage=(0.0, 0.0))
    run = sr.run(config, sr.water_config(config), every=1.0)
    truth = run.truth
    assert np.max(np.abs(np.arctan2(truth.v_r, truth.u_r))) < math.radians(15.0)
    for t, s in zip(run.t, run.states):
        if t < 60.0:
            continue
        k = run.index(t)
        off = min(abs(flow.ssa(s.course - truth.course()[k])),
                  abs(flow.ssa(s.course - truth.psi[k])))
        assert off < math.radians(15.0), t
        assert abs(s.relative_flow.sideslip) < math.radians(30.0), t


# ------------------------------------------------------------------ a log just started

def test_a_log_settling_after_power_on_moves_neither_current_nor_speed() -> None:
    """
    The log's damping ramps its first readings up from a third of the speed (τ 4 s).

    Two of Irene's logs start so (2013 and 2014: 0.8 → 2.9 kn over 6 s, 1.7 → 4.7 kn over
    15 s, at a steady 3.9 and 5.8 kn over ground). Fused as they came, the ramp went to the
    current (1.3 kn here, 3.0 kn on the lake), and the first output went out at the first
    reading, 3.9 kn slow. A log settles first (``config.LOG_SETTLE_TIME``): while its reading
    rises, the fixes tell the speed and the current and the scale are held.
    """
    config = sim.VoyageConfig(duration=240.0, imu_rate=20.0, compass_rate=1.0, fix_rate=1.0,
                              velocity_rate=1.0, speed=3.0, log_surge_only=True,
                              outage=(0.0, 0.0), current_speed=0.1)

    def power_on(readings: sim.Readings) -> None:
        t0 = readings.stamps[0]
        for j, k in enumerate(readings.velocity_steps):
            lag = 1.0 - (2.0 / 3.0) * math.exp(-(readings.stamps[k] - t0) * 1e-9 / 4.0)
            readings.velocity[j] = [v * lag for v in readings.velocity[j]]
    said: dict[int, str] = {}

    def watch(t: float, name: str, est) -> None:
        if name == 'velocity':
            said[round(t)] = {h.name: h for h in est.health()}['log'].summary
    run = sr.run(config, sr.water_config(config), every=1.0, alter=power_on, watch=watch)
    assert said[1].startswith('settling') and said[30] == 'ok', said
    errors = _speed_errors(run)
    settled = _speed_errors(run, 20.0)
    currents = [math.hypot(*s.current[0:2]) / KNOT for s in run.states]
    true = config.current_speed / KNOT
    print(f'current at most {max(currents):.2f} kn (true {true:.2f}), speed error at most '
          f'{np.max(np.abs(errors)):.2f} kn, {np.max(np.abs(settled)):.2f} kn after 20 s')
    assert max(currents) < true + 0.6
    assert np.max(np.abs(errors)) < 1.5             # the first output: 5 s of fixes at 1 Hz
    assert np.max(np.abs(settled)) < 0.5
    assert run.estimator.recoveries == 0


# ------------------------------------------------------------------ a wheel stalling under way

def test_a_wheel_stalling_under_way_moves_neither_current_nor_scale() -> None:
    """
    The log's wheel stalls at 5 kn for 40 s: it reads 0, and now and then a third of the speed.

    One of the psaros33's 2014 logs reads so for 30 s while leaving the harbour (0.0, 1.0,
    1.2 kn at 3 kn over ground). A reading at the stall is not fused and, the hull making way
    through the water, makes the log silent at once; the few in between are a wheel turning
    again, which settles as at power-on (``config.LOG_SETTLE_MIN``). Nothing observes the
    current or the scale meanwhile, so neither moves (before: the current 1.6 kn off, the
    scale 0.10; on that log the current reached 2.3 kn).
    """
    config = sim.VoyageConfig(duration=240.0, imu_rate=20.0, compass_rate=1.0, fix_rate=1.0,
                              velocity_rate=1.0, speed=3.0, log_surge_only=True,
                              outage=(0.0, 0.0), current_speed=0.1)
    stall = (100.0, 140.0)

    def fouled(readings: sim.Readings) -> None:
        t0 = readings.stamps[0]
        for j, k in enumerate(readings.velocity_steps):
            t = (readings.stamps[k] - t0) * 1e-9
            if stall[0] <= t < stall[1]:
                share = 1.0 / 3.0 if (int(t) - 100) % 8 in (4, 5, 6) else 0.0
                readings.velocity[j] = [v * share for v in readings.velocity[j]]
    run = sr.run(config, sr.water_config(config), every=1.0, alter=fouled)
    before, _ = run.at(stall[0] - 1.0)
    k0, c0 = before.calibration.log_scale.value, before.current[0:2]
    moved = [(t, float(np.hypot(*(s.current[0:2] - c0))) / KNOT,
              s.calibration.log_scale.value - k0)
             for t, s in zip(run.t, run.states) if stall[0] <= t <= stall[1] + 20.0]
    worst_c = max(m[1] for m in moved)
    worst_k = max(abs(m[2]) for m in moved)
    print(f'current moved at most {worst_c:.2f} kn, scale at most {worst_k:.3f}')
    assert worst_c < 0.3 and worst_k < 0.02
    assert np.max(np.abs(_speed_errors(run, stall[0], stall[1] + 20.0))) < 1.0

"""
The marine estimator against the simulator's truth (issue 7).

Log scale, leeway, heading offset, current, standstill, and physical bounds that nothing can
push a state past.

Each voyage is the simulator's default 300 s voyage (a straight leg, a turning circle from
24 s to 104 s, a straight leg, a zig-zag with a GNSS outage, a last leg) with one sensor error
switched on, its readings fed to the estimator (``sim_records``).
"""

from __future__ import annotations

import math
from pathlib import Path

from hypothesis import given, settings, strategies as st
import numpy as np
import pytest
import sim_records as sr
from vessel_kinematics.core import flow
from vessel_kinematics.estimation import BodyVelocity, Estimator, GnssFix, ImuSample
from vessel_kinematics.estimation.config import MAX_STATE_SPEED
from vessel_kinematics.ros.params import filter_config, NavigatorParams
from vessel_kinematics.tools import sim

DEG = math.pi / 180.0
#: After the turning circle (it ends at 104 s), before the zig-zag (from 144 s).
AFTER_TURN = 140.0


def voyage(tmp: Path, config: sim.VoyageConfig, **changes) -> sr.Run:
    """Simulate ``config`` and run the estimator, water-referenced; sample every 1 s."""
    return sr.run(config, sr.water_config(config, **changes), every=1.0)


@pytest.fixture(scope='module')
def scaled_log(tmp_path_factory: pytest.TempPathFactory) -> sr.Run:
    """Replay a speed log (surge only) reading 20 % low, in the default 0.6 m/s current."""
    return voyage(tmp_path_factory.mktemp('scale'),
                  sim.VoyageConfig(log_scale=0.8, log_surge_only=True))


def test_log_scale_within_2_percent_after_a_turn(scaled_log: sr.Run) -> None:
    s, _ = scaled_log.at(AFTER_TURN)
    scale = s.calibration.log_scale
    assert scale.value == pytest.approx(0.8, rel=0.02)
    assert abs(scale.value - 0.8) < 3.0 * scale.sigma + 1e-3      # its sigma covers it
    # Before the turn the scale and the current cannot be told apart: near the prior.
    before, _ = scaled_log.at(20.0)
    assert before.calibration.log_scale.sigma > 3.0 * scale.sigma


def test_current_within_0_1_m_s_after_a_turn(scaled_log: sr.Run) -> None:
    s, k = scaled_log.at(AFTER_TURN)
    truth = scaled_log.truth
    error = math.hypot(s.current[0] - truth.current_n[k], s.current[1] - truth.current_e[k])
    assert error < 0.1
    sigma = math.sqrt(s.cov_current[0, 0] + s.cov_current[1, 1])
    assert error < 3.0 * sigma


def test_course_and_sideslip_against_truth_with_a_surge_only_log(scaled_log: sr.Run) -> None:
    truth = scaled_log.truth
    chi, beta = truth.course(), truth.sideslip()
    errors_chi, errors_beta = [], []
    for t, s in zip(scaled_log.t, scaled_log.states):
        if t < AFTER_TURN:
            continue
        k = min(int(round(t * 100.0)), truth.t.size - 1)
        errors_chi.append(abs(flow.ssa(s.course - chi[k])))
        errors_beta.append(abs(flow.ssa(s.sideslip - beta[k])))
    # 1.96 and 1.88 deg before the log counted less in turns, 2.00 and 1.92 since: this
    # simulated log reads as well turning as on a straight leg, a real one does not.
    assert math.degrees(np.mean(errors_chi)) < 2.1
    assert math.degrees(np.mean(errors_beta)) < 2.1


def test_relative_flow_is_the_velocity_through_the_water(scaled_log: sr.Run) -> None:
    s, k = scaled_log.at(AFTER_TURN)
    truth = scaled_log.truth
    assert s.relative_flow.speed == pytest.approx(math.hypot(truth.u_r[k], truth.v_r[k]),
                                                  abs=0.15)
    assert s.relative_flow.sideslip == pytest.approx(math.atan2(truth.v_r[k], truth.u_r[k]),
                                                     abs=3.0 * DEG)


@pytest.mark.parametrize('offset_deg', [90.0, -135.0])
def test_heading_offset_of_any_angle_within_1_degree(tmp_path: Path, offset_deg: float) -> None:
    run = voyage(tmp_path, sim.VoyageConfig(imu_yaw_offset=offset_deg * DEG),
                 estimate_heading_offset=True)
    first, _ = run.at(1.0)
    assert first.calibration.heading_offset is None      # waits for the vessel to move 20 m
    assert run.at(10.0)[0].calibration.heading_offset is not None
    s, k = run.at(AFTER_TURN)
    # The IMU yaw (ENU) is the truth's plus the offset: the heading (NED) is psi - offset.
    offset = s.calibration.heading_offset
    assert math.degrees(flow.ssa(offset.value - offset_deg * DEG)) == pytest.approx(0.0, abs=1.0)
    assert abs(flow.ssa(offset.value - offset_deg * DEG)) < 3.0 * offset.sigma
    # It corrects the attitude of every output: the published heading is the true one.
    q = s.q
    psi = math.atan2(2.0 * (q[0] * q[3] + q[1] * q[2]), 1.0 - 2.0 * (q[2] ** 2 + q[3] ** 2))
    assert math.degrees(flow.ssa(psi - run.truth.psi[k])) == pytest.approx(0.0, abs=1.5)
    last = run.estimator.state().calibration.heading_offset
    estimate = {h.name: h for h in run.estimator.health()}['estimate']
    assert estimate.values['heading offset (deg)'] == (
        f'{math.degrees(last.value):.1f} ± {math.degrees(last.sigma):.1f}')
    assert any('heading offset found' in e.text for _, e in run.events)


def test_leeway_is_learnt_and_covered(tmp_path: Path) -> None:
    run = voyage(tmp_path, sim.VoyageConfig(leeway=5.0 * DEG, log_surge_only=True))
    s, _ = run.at(299.0)
    leeway = s.calibration.leeway
    assert leeway.value > 2.0 * DEG                       # toward the 5 deg of the truth
    assert abs(leeway.value - 5.0 * DEG) < 3.0 * leeway.sigma


def test_standstill_course_is_heading_and_sideslip_zero(tmp_path: Path) -> None:
    run = voyage(tmp_path, sim.VoyageConfig(standstill_start=130.0, standstill_end=160.0,
                                            current_speed=0.0))
    for t in (140.0, 145.0, 150.0):
        s, k = run.at(t)
        q = s.q
        psi = math.atan2(2.0 * (q[0] * q[3] + q[1] * q[2]), 1.0 - 2.0 * (q[2] ** 2 + q[3] ** 2))
        assert s.low_speed
        assert s.sideslip == 0.0 and s.angle_of_attack == 0.0
        # χ = ψ, from true north; q is against the map, turned by the convergence (2e-5 rad).
        assert s.course == pytest.approx(psi, abs=1e-4)
        assert math.hypot(s.v_n[0], s.v_n[1]) < 0.3
    moving, _ = run.at(100.0)
    assert not moving.low_speed


# ------------------------------------------------------------------------ physical bounds

ORIGIN = (math.radians(63.44), math.radians(10.40), 0.0)


@settings(max_examples=25, deadline=None)
@given(st.lists(st.tuples(st.floats(-0.3, 0.3), st.floats(-8.0, 8.0), st.floats(-30.0, 30.0),
                          st.floats(-3.0, 3.0)), min_size=20, max_size=60),
       st.sampled_from(['ground', 'water']), st.booleans())
def test_states_stay_within_physical_bounds(steps, reference: str, nan_altitude: bool) -> None:
    """
    Surge-only logs, NaN-altitude fixes and random motion: no velocity or height runs away.

    Each step: a yaw rate (rad/s), a logged surge (m/s), a fix offset (m) and a pitch (deg),
    one second each at 10 Hz IMU, 5 Hz log, 1 Hz fix. Surface motion: the vertical velocity
    stays zero, the height the surface's, the heave in the body the pitch's share of the
    surge.
    """
    config = filter_config(NavigatorParams.from_flat({'velocity.reference': reference}))
    est = Estimator(config)
    t_ns = 1_700_000_000 * 10 ** 9
    psi = 0.0
    p = np.zeros(2)
    for rate, surge, offset, pitch in steps:
        for i in range(10):
            t_ns += 100_000_000
            psi += rate * 0.1
            theta = pitch * DEG
            q = (math.cos(psi / 2) * math.cos(theta / 2), -math.sin(psi / 2) * math.sin(theta / 2),
                 math.cos(psi / 2) * math.sin(theta / 2), math.sin(psi / 2) * math.cos(theta / 2))
            est.imu(ImuSample(t_ns, q, np.eye(3) * 1e-4, (0.0, 0.0, rate), np.eye(3) * 1e-6))
            p += 0.1 * surge * np.array([math.cos(psi), math.sin(psi)])
            if i % 2 == 0:
                est.velocity(BodyVelocity(t_ns, np.array([surge, 0.0, 0.0]),
                                          np.diag([0.01, 1e6, 1e6])))
        north, east = p + offset
        lat = ORIGIN[0] + north / 6_378_137.0
        lon = ORIGIN[1] + east / (6_378_137.0 * math.cos(ORIGIN[0]))
        est.fix(GnssFix(t_ns, lat, lon, math.nan if nan_altitude else 10.0 + offset,
                        np.eye(3) * 4.0))
        if est.ready:
            s = est.state()
            # On the surface: the fixes' height, no vertical velocity (the map's z is the
            # surface's, below the origin's height by what the fixes say and the curvature).
            assert s.v_n[2] == 0.0 and s.p_local[2] == 0.0
            assert abs(s.p[2] + (s.llh[2] - s.origin[2])) < 1.0
            assert np.linalg.norm(s.v_n) < MAX_STATE_SPEED
            assert abs(s.nu[2]) <= abs(math.sin(theta)) * np.linalg.norm(s.v_n) + 1e-9
            assert np.all(np.isfinite(s.cov_p)) and np.all(np.linalg.eigvalsh(s.cov_p) >= 0.0)
            if s.current is not None:
                assert np.linalg.norm(s.current) < 5.0


def test_dead_reckoning_leaves_the_unobservable_at_their_priors(tmp_path: Path) -> None:
    """
    A speed log without fixes: nothing tells the scale, the current or the leeway.

    They must stay at their priors (the EKF must not drift along z = k·u, which a velocity in
    true units would: k fell to 0.36 and u rose to 12 m/s in 300 s), and the position's
    covariance must cover the real error that this leaves.
    """
    config = sim.VoyageConfig(log_scale=0.9, log_surge_only=True, leeway=3.0 * DEG)
    run = voyage(tmp_path, config, gnss_enabled=False)
    s, k = run.at(299.0)
    cal = s.calibration
    assert cal.log_scale.value == pytest.approx(1.0, abs=1e-6)
    assert cal.log_scale.sigma == pytest.approx(0.2, rel=0.01)
    assert cal.leeway.value == pytest.approx(0.0, abs=1e-9)
    np.testing.assert_allclose(s.current[0:2], 0.0, atol=1e-9)
    speed = math.hypot(s.v_n[0], s.v_n[1])
    assert speed == pytest.approx(0.9 * run.truth.u_r[k], rel=0.05)   # the log as read
    origin_truth = np.array([run.truth.north[0], run.truth.east[0]])
    error = s.p[0:2] - (np.array([run.truth.north[k], run.truth.east[k]]) - origin_truth)
    assert float(error @ np.linalg.solve(s.cov_p[0:2, 0:2], error)) < 9.0   # within 3 sigma

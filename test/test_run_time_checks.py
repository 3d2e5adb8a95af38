"""
Harmful-but-legal run-time values are refused with a reason (issue 25, item 6).

The checks alone (:mod:`vessel_kinematics.ros.node.checks`, the distance against
geographiclib's geodesic) and through the live node over DDS: an origin at the pole while the
vessel sails at 63° N, and a ``max_gap`` shorter than the IMU's period, are refused by
``set_parameters`` with their reason; the node goes on publishing at its origin. The static
floor of ``max_gap`` is in the one table.
"""

from __future__ import annotations

import math

from geographiclib.geodesic import Geodesic
import pytest
from test_navigator_node import ORIGIN, Scenario, Voyage
from vessel_kinematics.ros.node.checks import (great_circle, MAX_ORIGIN_DISTANCE,
                                               RunTimeChecks)
from vessel_kinematics.ros.params import MIN_MAX_GAP, NavigatorParams, ParameterError


@pytest.mark.parametrize('a, b', [((63.4, 10.4), (63.5, 10.6)), ((63.4, 10.4), (90.0, 0.0)),
                                  ((-33.9, 151.2), (51.5, -0.1)), ((0.0, 179.9), (0.0, -179.9))])
def test_the_distance_against_the_geodesic(a, b) -> None:
    geodesic = Geodesic.WGS84.Inverse(a[0], a[1], b[0], b[1])['s12']
    assert great_circle(*a, *b) == pytest.approx(geodesic, rel=5e-3)


def _params(**values) -> NavigatorParams:
    return NavigatorParams.from_flat({'origin': list(ORIGIN), **values})


def test_an_origin_far_from_the_vessel_or_the_first_fix() -> None:
    checks, old = RunTimeChecks(), _params()
    pole = _params(origin=[90.0, 0.0, 0.0])
    near = _params(origin=[63.5, 10.5, 0.0])
    assert checks.problem(old, pole, None) is None          # nothing known of the vessel yet
    checks.first_fix = (63.44, 10.40)
    line = checks.problem(old, pole, None)
    assert line is not None and 'from the first fix' in line and '2953 km' in line, line
    line = checks.problem(old, pole, (63.44, 10.40))
    assert line is not None and "from the vessel's current position" in line, line
    assert checks.problem(old, near, (63.44, 10.40)) is None
    edge = great_circle(63.44, 10.40, 63.44 + math.degrees(MAX_ORIGIN_DISTANCE * 1.01
                                                           / 6_371_008.8), 10.40)
    assert edge > MAX_ORIGIN_DISTANCE
    assert checks.problem(old, _params(origin=[63.44 + math.degrees(
        MAX_ORIGIN_DISTANCE * 1.01 / 6_371_008.8), 10.40, 0.0]), (63.44, 10.40)) is not None


def test_max_gap_against_the_inputs_rates() -> None:
    checks, old = RunTimeChecks(), _params()
    assert checks.problem(old, _params(max_gap=0.02), None) is None    # no rate known
    stamps = {'imu': 5 * 10 ** 9, 'fix': 5 * 10 ** 9, 'velocity': None}
    checks.observe({'imu': 0, 'fix': 0, 'fix/no_fix': 0, 'resets': 0}, stamps)
    stamps = {'imu': 7 * 10 ** 9, 'fix': 7 * 10 ** 9, 'velocity': None}
    checks.observe({'imu': 800, 'fix': 20, 'fix/no_fix': 50, 'resets': 3}, stamps)
    assert checks.rates == {'imu': 400.0, 'fix': 10.0}     # per second of their stamps
    assert checks.problem(old, _params(max_gap=0.05), None) is None    # 20 IMU periods
    checks.rates['imu'] = 100.0
    line = checks.problem(old, _params(max_gap=0.02), None)
    assert line is not None and 'imu (100 Hz)' in line and '0.03 s' in line, line
    with pytest.raises(ParameterError, match="'max_gap': must be in"):
        _params(max_gap=1e-3)                                 # below the table's floor
    assert MIN_MAX_GAP == 0.01


@pytest.mark.dds
def test_the_node_refuses_them_and_goes_on(dds, run_navigator) -> None:
    voyage = Voyage(speed=2.0)
    scenario = Scenario(dds, run_navigator)
    # Two /diagnostics ticks apart, each after some of the voyage: the IMU's rate is known.
    for start in (0.0, 3.0):
        scenario.play(voyage.events(3.0, imu_hz=100.0, start=start))
        ticks = len(scenario.diagnostics)
        assert dds.spin_until(lambda: len(scenario.diagnostics) >= ticks + 2, 10.0)
    (result,) = dds.set_parameters('/navigator', {'origin': [90.0, 0.0, 0.0]})
    assert not result.successful and "vessel's current position" in result.reason, result.reason
    (result,) = dds.set_parameters('/navigator', {'max_gap': 0.02})
    assert not result.successful and 'periods of imu' in result.reason, result.reason
    (result,) = dds.set_parameters('/navigator', {'max_gap': 2.0})
    assert result.successful, result.reason
    assert list(dds.get_parameters('/navigator', ['origin'])['origin']) == list(ORIGIN)
    cut = len(scenario.out['odometry'])
    scenario.play(voyage.events(1.0, imu_hz=100.0, start=6.0))
    assert len(scenario.out['odometry']) > cut and scenario.process.alive()
    position = scenario.out['odometry'][-1].pose.pose.position
    assert math.hypot(position.x, position.y) < 100.0, position

"""
The navigator's services over real DDS, called with robot_localization's own types.

* ``fromLL``, ``toLL`` and ``datum`` (r_l's FromLL, ToLL, SetDatum) against pymap3d, to 1 mm;
* a client as nav2's GPS waypoint follower is one (test/nav2_style_client.py: a process of its
  own that knows r_l's types and nothing of the package) gets the same answers;
* ``~/enable`` (std_srvs/SetBool), r_l's ``toggle`` and ``~/reset`` (std_srvs/Trigger) while
  a voyage's messages flow: nothing is fused or published while paused, /diagnostics says
  ``paused`` and counts the paused inputs, the origin survives a reset, and the estimate is
  back on the reference voyage (pymap3d, scipy: test_navigator_node) after each.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
import subprocess
import sys

from dds_harness import diagnostic_values, LATCHED, seconds
from geographic_msgs.msg import GeoPoint, GeoPose
from geometry_msgs.msg import Point
import pymap3d
import pytest
from robot_localization.srv import FromLL, SetDatum, ToggleFilterProcessing, ToLL
from sensor_msgs.msg import NavSatFix
from std_srvs.srv import SetBool, Trigger
from test_navigator_node import ORIGIN, POSITION_TOL, Scenario, SPEED_TOL, T0, Voyage

pytestmark = pytest.mark.dds

CLIENT = Path(__file__).resolve().parent / 'nav2_style_client.py'
MM = 1e-3
#: Waypoints about the origin (lat deg, lon deg, height m), out to 20 km.
WAYPOINTS = [(ORIGIN[0] + dlat, ORIGIN[1] + dlon, h) for dlat, dlon, h in
             ((0.0, 0.0, ORIGIN[2]), (1e-4, -2e-4, 41.5), (0.01, 0.02, 30.0),
              (-0.18, 0.25, 0.0))]


def _from_ll(dds, lat: float, lon: float, h: float) -> tuple[float, float, float]:
    answer = dds._call(FromLL, '/fromLL', FromLL.Request(
        ll_point=GeoPoint(latitude=lat, longitude=lon, altitude=h)), 10.0).map_point
    return answer.x, answer.y, answer.z


def _to_ll(dds, x: float, y: float, z: float) -> tuple[float, float, float]:
    answer = dds._call(ToLL, '/toLL', ToLL.Request(map_point=Point(x=x, y=y, z=z)),
                       10.0).ll_point
    return answer.latitude, answer.longitude, answer.altitude


def _close(a, b, tol: float = MM) -> bool:
    return max(abs(x - y) for x, y in zip(a, b)) < tol


def test_geodesy_services_agree_with_pymap3d(dds, run_navigator, navigator_env) -> None:
    scenario = Scenario(dds, run_navigator)
    for lat, lon, h in WAYPOINTS:
        got = _from_ll(dds, lat, lon, h)
        assert _close(got, pymap3d.geodetic2enu(lat, lon, h, *ORIGIN)), (lat, lon, got)
    for point in ((0.0, 0.0, 0.0), (12.5, -7.25, 1.0), (-15e3, 9e3, -20.0)):
        lat, lon, h = _to_ll(dds, *point)
        assert _close(pymap3d.geodetic2enu(lat, lon, h, *ORIGIN), point), (point, lat, lon)

    # nav2's client (its own process, r_l's types only) gets the very answers (altitude 0).
    args = [str(v) for lat, lon, _ in WAYPOINTS for v in (lat, lon)]
    run = subprocess.run([sys.executable, str(CLIENT), *args], env=navigator_env,
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    nav2 = json.loads(run.stdout.strip().splitlines()[-1])
    for (lat, lon, _), answer in zip(WAYPOINTS, nav2):
        assert tuple(answer) == _from_ll(dds, lat, lon, 0.0)
        assert _close(answer, pymap3d.geodetic2enu(lat, lon, 0.0, *ORIGIN))

    # datum: the origin moves there (the parameter, the latched topic, fromLL's zero).
    origins = dds.collect('/origin', NavSatFix, LATCHED)
    datum = (ORIGIN[0] + 0.05, ORIGIN[1] - 0.1, 12.0)
    pose = GeoPose(position=GeoPoint(latitude=datum[0], longitude=datum[1], altitude=datum[2]))
    pose.orientation.w = 1.0
    assert isinstance(dds._call(SetDatum, '/datum', SetDatum.Request(geo_pose=pose), 10.0),
                      SetDatum.Response)
    assert dds.get_parameters('/navigator', ['origin'])['origin'].tolist() == list(datum)
    assert _close(_from_ll(dds, *datum), (0.0, 0.0, 0.0), 1e-9)
    lat, lon, h = WAYPOINTS[2]
    assert _close(_from_ll(dds, lat, lon, h), pymap3d.geodetic2enu(lat, lon, h, *datum))
    assert dds.spin_until(lambda: origins and abs(origins[-1].latitude - datum[0]) < 1e-12,
                          10.0), origins

    # No point, no answer: NaN, never a map point that looks like one (the origin's zeros).
    for lat, lon, h in ((math.inf, -math.inf, 0.0), (91.0, 10.0, 0.0), (1e300, 0.0, 0.0),
                        (60.0, 10.0, math.nan)):
        assert all(math.isnan(c) for c in _from_ll(dds, lat, lon, h)), (lat, lon, h)
    assert all(math.isnan(c) for c in _to_ll(dds, math.inf, 0.0, 0.0))
    # A datum that is no point is refused: the parameter and the origin in use stay.
    pose.position.altitude = math.nan
    dds._call(SetDatum, '/datum', SetDatum.Request(geo_pose=pose), 10.0)
    assert dds.get_parameters('/navigator', ['origin'])['origin'].tolist() == list(datum)
    assert scenario.counts()['internal_errors'] == '0'
    assert 'Traceback' not in scenario.process.output()
    assert scenario.process.alive(), scenario.process.output()


def _paused_counts(scenario: Scenario) -> dict[str, str]:
    """Return the diagnostics' values once the estimate says paused (fail after 10 s)."""
    def said() -> bool:
        return bool(scenario.diagnostics) and 'paused' in diagnostic_values(
            scenario.diagnostics[-1])
    assert scenario.dds.spin_until(said, 10.0), 'diagnostics never said paused'
    return diagnostic_values(scenario.diagnostics[-1])


def _on_voyage(voyage: Voyage, scenario: Scenario, start: float) -> None:
    """Check the last seconds of odometry (from ``start`` + 2 s) against the voyage."""
    judged = scenario.after('odometry', start + 2.0)
    assert len(judged) > 20, len(judged)
    for msg in judged:
        t = seconds(msg.header.stamp) - T0
        n, e, _ = voyage.ned(t)
        p = msg.pose.pose.position
        assert math.hypot(p.x - e, p.y - n) < POSITION_TOL, (t, p, (e, n))
        assert abs(msg.twist.twist.linear.x - voyage.speed) < SPEED_TOL, t


def test_enable_toggle_and_reset_while_messages_flow(dds, run_navigator) -> None:
    voyage = Voyage(speed=3.0, heading0=0.5)
    scenario = Scenario(dds, run_navigator)
    scenario.play(voyage.events(5.0))
    _on_voyage(voyage, scenario, 0.0)

    # Paused: what arrives is counted as paused, nothing fused, nothing published.
    answer = dds._call(SetBool, '/navigator/enable', SetBool.Request(data=False), 10.0)
    assert answer.success and answer.message == 'fusion paused'
    accepted = {k: v for k, v in scenario.counts().items() if k.startswith('accepted ')}
    published = len(scenario.out['odometry'])
    paused_events = voyage.events(3.0, start=5.0)
    dds.play(paused_events)

    def all_counted() -> bool:
        values = diagnostic_values(scenario.diagnostics[-1]) if scenario.diagnostics else {}
        return sum(int(values.get(f'rejected {name}/paused', 0))
                   for name in ('fix', 'imu', 'velocity')) == len(paused_events)
    assert dds.spin_until(all_counted, 15.0), diagnostic_values(scenario.diagnostics[-1])
    values = _paused_counts(scenario)
    assert {k: v for k, v in values.items() if k.startswith('accepted ')} == accepted
    assert not [m for m in scenario.out['odometry'][published:]
                if seconds(m.header.stamp) >= T0 + 5.0], 'published while paused'
    assert 'paused' in scenario.diagnostics[-1].status[0].message
    assert scenario.diagnostics[-1].status[0].level == b'\x01'     # WARN

    # r_l's toggle resumes it: the estimate is back on the voyage.
    assert dds._call(ToggleFilterProcessing, '/toggle',
                     ToggleFilterProcessing.Request(on=True), 10.0).status is True
    scenario.play(voyage.events(5.0, start=8.0))
    _on_voyage(voyage, scenario, 8.0)
    assert 'paused' not in scenario.counts()

    # Reset mid-voyage: the estimate starts again, the origin is kept.
    before = _from_ll(dds, *WAYPOINTS[2])
    resets = int(scenario.counts()['resets'])
    answer = dds._call(Trigger, '/navigator/reset', Trigger.Request(), 10.0)
    assert answer.success, answer.message
    assert int(scenario.counts()['resets']) == resets + 1
    assert _from_ll(dds, *WAYPOINTS[2]) == before
    scenario.play(voyage.events(6.0, start=13.0))
    _on_voyage(voyage, scenario, 13.0)
    assert scenario.process.alive(), scenario.process.output()
    assert 'internal_error' not in scenario.process.output()


def test_without_robot_localization_one_line_names_the_missing(dds, navigator_env,
                                                               tmp_path) -> None:
    """Where r_l's package is not installed, its services are named once; the rest served."""
    import dds_harness
    env = dict(navigator_env)
    env['PYTHONPATH'] = ':'.join(p for p in env.get('PYTHONPATH', '').split(':')
                                 if '/robot_localization/' not in p)
    process = dds_harness.NodeProcess(dds_harness.resolve_executable(env, 'navigator'),
                                      [], env, tmp_path / 'navigator.log')
    try:
        dds.wait_for_node('navigator', process)
        assert dds._call(Trigger, '/navigator/reset', Trigger.Request(), 10.0).success
        lines = [line for line in process.output().splitlines() if 'services not offered' in line]
        assert len(lines) == 1, process.output()
        assert ('fromLL, toLL, datum, setDatum, toggle (install ros-jazzy-robot-localization)'
                in lines[0])
    finally:
        assert process.stop() == 0, process.output()

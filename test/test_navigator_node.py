"""
The navigator node over real DDS: the installed executable runs, a test node feeds and listens.

Each test starts ``lib/vessel_kinematics/navigator`` as ``ros2 run`` would (fixture
``run_navigator`` of conftest.py), publishes NavSatFix / Imu / TwistWithCovarianceStamped
messages generated here from a closed-form reference trajectory, and checks what the node
publishes. The reference is independent of the package: geodetic coordinates from pymap3d,
quaternions from scipy.

Reference trajectory (Fossen's notation, NED, BODY = FRD): constant speed U, sideslip beta and
yaw rate r, so the course is chi(t) = psi(t) + beta = psi0 + beta + r t and
    N(t) = U / r (sin chi - sin chi0),    E(t) = -U / r (cos chi - cos chi0)    (r != 0)
    N(t) = U t cos chi0,                  E(t) = U t sin chi0                    (r == 0)
with the body velocity nu = [U cos beta, U sin beta, 0] (m/s, FRD).
"""

from __future__ import annotations

from dataclasses import dataclass
import math
import signal
from typing import Any

import dds_harness
from dds_harness import (diagnostic_values, LATCHED, make_fix, make_imu, make_twist,
                         seconds)
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import TwistStamped, TwistWithCovarianceStamped
import numpy as np
import pymap3d
import pytest
from rclpy.serialization import serialize_message
from rosgraph_msgs.msg import Clock
from scipy.spatial.transform import Rotation
from sensor_msgs.msg import Imu, NavSatFix, NavSatStatus
from vessel_kinematics.ros import interface

pytestmark = pytest.mark.dds

#: Origin of the tests: Trondheim harbour (lat deg, lon deg, ellipsoidal height m).
ORIGIN = (63.4389, 10.3994, 40.0)
#: First stamp of every scenario (s): any positive time; the node goes by header stamps.
T0 = 1000.0
DEG = math.pi / 180.0

# Stated tolerances (the estimator fuses exact fixes with sigma 0.5 m and exact body velocity).
POSITION_TOL = 0.3        # m, fused position against the reference
SPEED_TOL = 0.05          # m/s
HEADING_TOL = 0.1 * DEG   # rad, attitude comes straight from the IMU orientation
ANGLE_TOL = 0.5 * DEG     # rad, course and sideslip
SETTLE = 1.0              # s of each scenario not judged (the first fix and velocity arrive)


@dataclass(frozen=True)
class Voyage:
    """Constant speed U (m/s), sideslip beta (rad) and yaw rate r (rad/s) from heading psi0."""

    speed: float
    sideslip: float = 0.0
    yaw_rate: float = 0.0
    heading0: float = 0.0

    def heading(self, t: float) -> float:
        """Return psi(t) (rad, from north, clockwise)."""
        return self.heading0 + self.yaw_rate * t

    def course(self, t: float) -> float:
        """Return chi(t) = psi(t) + beta (rad)."""
        return self.heading(t) + self.sideslip

    def ned(self, t: float) -> np.ndarray:
        """Return the NED position (m) about the origin at t s."""
        chi0, chi = self.course(0.0), self.course(t)
        if self.yaw_rate == 0.0:
            return self.speed * t * np.array([math.cos(chi0), math.sin(chi0), 0.0])
        radius = self.speed / self.yaw_rate
        return np.array([radius * (math.sin(chi) - math.sin(chi0)),
                         -radius * (math.cos(chi) - math.cos(chi0)), 0.0])

    def body_velocity_frd(self) -> np.ndarray:
        """Return nu = [u, v, w] (m/s, FRD)."""
        return np.array([self.speed * math.cos(self.sideslip),
                         self.speed * math.sin(self.sideslip), 0.0])

    def quaternion_enu_flu(self, t: float) -> np.ndarray:
        """Return the REP-103 orientation (ENU world, FLU body) as xyzw: yaw_enu = pi/2 - psi."""
        return Rotation.from_euler('z', math.pi / 2 - self.heading(t)).as_quat()

    def geodetic(self, t: float, origin: tuple[float, float, float] = ORIGIN) -> tuple:
        """Return (lat deg, lon deg, h m) of the position at t s (pymap3d, WGS-84)."""
        n, e, d = self.ned(t)
        return pymap3d.ned2geodetic(n, e, d, *origin)

    def events(self, duration: float, imu_hz: float = 50.0, velocity_hz: float = 10.0,
               fix_hz: float = 2.0, fix_offset_enu: tuple[float, float] = (0.0, 0.0),
               start: float = 0.0) -> list[tuple[str, Any]]:
        """
        Return the input messages of [start, start + duration) s, ordered by stamp.

        Velocity and fix stamps are offset by 1 and 2 ms so that no two inputs share a stamp.
        ``fix_offset_enu`` (m) displaces every fix, as a GNSS bias would.
        """
        timed: list[tuple[float, str, Any]] = []
        u, v, w = self.body_velocity_frd()
        for k in range(int(round(duration * imu_hz))):
            t = start + k / imu_hz
            timed.append((t, 'imu', make_imu(T0 + t, self.quaternion_enu_flu(t),
                                             (0.0, 0.0, -self.yaw_rate))))
        for k in range(int(round(duration * velocity_hz))):
            t = start + k / velocity_hz + 0.001
            timed.append((t, 'velocity', make_twist(T0 + t, (u, -v, -w))))
        for k in range(int(round(duration * fix_hz))):
            t = start + k / fix_hz + 0.002
            n, e, d = self.ned(t)
            lat, lon, h = pymap3d.ned2geodetic(n + fix_offset_enu[1], e + fix_offset_enu[0], d,
                                               *ORIGIN)
            timed.append((t, 'fix', make_fix(T0 + t, lat, lon, h)))
        timed.sort(key=lambda item: item[0])
        return [(topic, msg) for _, topic, msg in timed]


def _yaw_enu(orientation: Any) -> float:
    q = [orientation.x, orientation.y, orientation.z, orientation.w]
    return Rotation.from_quat(q).as_euler('ZYX')[0]


def _angle_error(a: float, b: float) -> float:
    return abs(math.remainder(a - b, 2 * math.pi))


def _finite(msg: Any) -> bool:
    """Return True when every float of ``msg`` (recursively) is finite."""
    if isinstance(msg, float):
        return math.isfinite(msg)
    if isinstance(msg, (list, tuple)) or type(msg).__name__ == 'array':
        return all(_finite(v) for v in msg)
    if hasattr(msg, 'get_fields_and_field_types'):
        return all(_finite(getattr(msg, f)) for f in msg.get_fields_and_field_types())
    return True


class Scenario:
    """A running navigator and a test node collecting its outputs."""

    #: Every per-update output of the interface table with a velocity over ground (not the
    #: water-referenced ones, not the latched origin).
    OUTPUTS = {t.name: interface.message_class(t.msg_type)
               for t in interface.by_role(interface.Role.OUTPUT)
               if not t.water_only and not t.latched and t.msg_type is not None}

    def __init__(self, dds: Any, run_navigator: Any, **params: Any) -> None:
        # Outputs on every update (publish_rate 0): the tests wait for each input's outputs.
        params = {'sensor_qos': 'reliable', 'origin': list(ORIGIN), 'publish_rate': 0.0,
                  **params}
        self.dds = dds
        self.process = run_navigator(params=params)
        self.out = {topic: dds.collect(topic, msg_type)
                    for topic, msg_type in self.OUTPUTS.items()}
        self.diagnostics = dds.collect('/diagnostics', DiagnosticArray)
        dds.publisher('fix', NavSatFix)
        dds.publisher('imu', Imu)
        dds.publisher('velocity', TwistWithCovarianceStamped)
        dds.wait_for_node('navigator', self.process)
        dds.wait_for_match(['fix', 'imu', 'velocity', *self.OUTPUTS])

    def play(self, events: list[tuple[str, Any]], tolerance: float = 0.0) -> None:
        """
        Feed ``events`` in lock-step with ``odometry`` and wait for every last output.

        ``tolerance`` (s): with ``publish_rate`` > 0 the last output is the last snapshot, up
        to one period before the last event (the pipeline emits by stamp).
        """
        self.dds.play(events, sync=self.out['odometry'])
        assert self.process.alive(), self.process.output()
        # The outputs of one update travel on separate topics: wait for each topic's message of
        # the last event, not only odometry's, before anyone reads them.
        last = max(seconds(msg.header.stamp) for _, msg in events)

        def all_arrived() -> bool:
            return all(messages and seconds(messages[-1].header.stamp) >= last - tolerance - 1e-9
                       for messages in self.out.values())
        assert self.dds.spin_until(all_arrived, 10.0), {
            topic: seconds(messages[-1].header.stamp) - last if messages else None
            for topic, messages in self.out.items()}

    def after(self, topic: str, t: float = SETTLE) -> list[Any]:
        """Return the messages of ``topic`` stamped at or after T0 + t."""
        return [m for m in self.out[topic] if seconds(m.header.stamp) >= T0 + t - 1e-9]

    def counts(self) -> dict[str, str]:
        """Wait for the next /diagnostics and return its key/values."""
        seen = len(self.diagnostics)
        assert self.dds.spin_until(lambda: len(self.diagnostics) > seen, 5.0), 'no /diagnostics'
        return diagnostic_values(self.diagnostics[-1])


def _check_against(voyage: Voyage, scenario: Scenario) -> None:
    """Check odometry, odometry/ned and course_sideslip against the reference voyage."""
    odometry = scenario.after('odometry')
    ned = scenario.after('odometry/ned')
    angles = scenario.after('course_sideslip')
    assert len(odometry) > 10 and len(ned) > 10 and len(angles) > 10
    for msg in odometry:
        t = seconds(msg.header.stamp) - T0
        n, e, d = voyage.ned(t)
        p = msg.pose.pose.position
        assert math.hypot(p.x - e, p.y - n) < POSITION_TOL, (t, p, (e, n))
        assert _angle_error(_yaw_enu(msg.pose.pose.orientation),
                            math.pi / 2 - voyage.heading(t)) < HEADING_TOL, t
        linear = msg.twist.twist.linear     # FLU body frame
        u, v, _ = voyage.body_velocity_frd()
        assert abs(linear.x - u) < SPEED_TOL and abs(linear.y + v) < SPEED_TOL, (t, linear)
        assert msg.header.frame_id == 'map' and msg.child_frame_id == 'base_link'
    for msg in ned:
        t = seconds(msg.header.stamp) - T0
        n, e, d = voyage.ned(t)
        p = msg.pose.pose.position
        assert math.hypot(p.x - n, p.y - e) < POSITION_TOL, (t, p, (n, e))
        assert msg.header.frame_id == 'map_ned' and msg.child_frame_id == 'base_link_frd'
    for msg in angles:
        t = seconds(msg.header.stamp) - T0
        assert _angle_error(msg.vector.x, voyage.course(t)) < ANGLE_TOL, (t, msg.vector)
        assert _angle_error(msg.vector.y, voyage.sideslip) < ANGLE_TOL, (t, msg.vector)


def test_straight_run_north(dds, run_navigator) -> None:
    voyage = Voyage(speed=2.0)
    scenario = Scenario(dds, run_navigator)
    scenario.play(voyage.events(6.0))
    _check_against(voyage, scenario)
    # North is +y in ENU (odometry) and +x in NED (odometry/ned): the run covered ~10 m.
    last = scenario.out['odometry'][-1].pose.pose.position
    last_ned = scenario.out['odometry/ned'][-1].pose.pose.position
    assert last.y > 9.0 and abs(last.x) < POSITION_TOL
    assert last_ned.x > 9.0 and abs(last_ned.y) < POSITION_TOL
    fixes = scenario.after('fix/filtered')
    assert fixes[-1].latitude > ORIGIN[0] and abs(fixes[-1].longitude - ORIGIN[1]) < 1e-5


def test_local_odometry_never_jumps_at_a_fix(dds, run_navigator) -> None:
    # From t = 2 s the fixes are 3 m east of where the velocity takes the vessel: odometry
    # (map) is pulled east at each fix, odometry/local (odom) only integrates the velocity.
    voyage = Voyage(speed=2.0)
    # The gate is off: a sudden 3 m offset of exact fixes is what this test makes.
    scenario = Scenario(dds, run_navigator, **{'gnss.gate_sigma': 0.0})
    scenario.play(voyage.events(2.0) + voyage.events(3.0, start=2.0, fix_offset_enu=(3.0, 0.0)))
    local = scenario.after('odometry/local', 0.5)
    fused = scenario.after('odometry', 0.5)
    assert len(local) > 50
    assert all(m.header.frame_id == 'odom' for m in local)
    worst_local = 0.0
    for before, after in zip(local, local[1:]):
        dt = seconds(after.header.stamp) - seconds(before.header.stamp)
        a, b = before.pose.pose.position, after.pose.pose.position
        step = math.hypot(b.x - a.x, b.y - a.y)
        worst_local = max(worst_local, abs(step - voyage.speed * dt))
    assert worst_local < 0.01, f'odometry/local jumped by {worst_local:.3f} m'
    # ...while the fused pose did move east, in jumps at the fixes.
    assert fused[-1].pose.pose.position.x > 0.5
    jumps = []
    for before, after in zip(fused, fused[1:]):
        a, b = before.pose.pose.position, after.pose.pose.position
        jumps.append(abs(b.x - a.x))
    assert max(jumps) > 0.05


def test_crabbing_vessel_has_sideslip_minus_heading(dds, run_navigator) -> None:
    # Heading 10 deg, course over ground 0: the current sets the vessel to port; beta = -10 deg.
    voyage = Voyage(speed=2.0, sideslip=-10 * DEG, heading0=10 * DEG)
    scenario = Scenario(dds, run_navigator)
    scenario.play(voyage.events(4.0))
    _check_against(voyage, scenario)
    last = scenario.after('course_sideslip')[-1].vector
    assert abs(last.x) < ANGLE_TOL and abs(last.y + 10 * DEG) < ANGLE_TOL


def test_turning_vessel_follows_the_reference(dds, run_navigator) -> None:
    # 3 m/s, yaw rate 4 deg/s (starboard turn), sideslip -5 deg: 60 deg of a 43 m radius circle.
    voyage = Voyage(speed=3.0, sideslip=-5 * DEG, yaw_rate=4 * DEG, heading0=30 * DEG)
    scenario = Scenario(dds, run_navigator)
    scenario.play(voyage.events(15.0, imu_hz=25.0, fix_hz=5.0))
    _check_against(voyage, scenario)
    assert scenario.after('course_sideslip', 14.9), 'the whole turn was published'


def _bad_fixes(t: float) -> list[tuple[str, Any]]:
    lat, lon, h = ORIGIN
    nan_fix = make_fix(T0 + t, math.nan, lon, h)
    polar = make_fix(T0 + t + 0.001, 95.0, lon, h)
    no_fix = make_fix(T0 + t + 0.002, lat, lon, h, status=NavSatStatus.STATUS_NO_FIX)
    negative = make_fix(T0 + t + 0.003, lat, lon, h)
    negative.position_covariance[0] = -1.0
    return [('fix', nan_fix), ('fix', polar), ('fix', no_fix), ('fix', negative)]


def test_barrage_of_bad_messages(dds, run_navigator) -> None:
    voyage = Voyage(speed=2.0)
    scenario = Scenario(dds, run_navigator)
    scenario.play(voyage.events(1.0))
    before = scenario.counts()
    q = voyage.quaternion_enu_flu(1.1)
    zero_quaternion = make_imu(T0 + 1.1, (0.0, 0.0, 0.0, 0.0))
    nan_rate = make_imu(T0 + 1.11, q, (math.nan, 0.0, 0.0))
    no_rates = make_imu(T0 + 1.12, q)
    no_rates.angular_velocity_covariance[0] = -1.0
    no_orientation = make_imu(T0 + 1.13, (0.0, 0.0, 0.0, 0.0))
    no_orientation.orientation_covariance[0] = -1.0
    unknown = make_fix(T0 + 1.14, *voyage.geodetic(1.14))
    unknown.position_covariance_type = NavSatFix.COVARIANCE_TYPE_UNKNOWN
    unknown.position_covariance = [0.0] * 9
    inf_velocity = make_twist(T0 + 1.15, (math.inf, 0.0, 0.0))
    backwards = make_imu(T0 + 0.2, q)          # 0.95 s back: older than the reorder window
    far_future = make_imu(T0 + 1e6, q)         # a jump forward
    # Payloads that are no message of their topic's type at all, sent raw (the node reads every
    # input raw: the middleware would drop them unseen, uncounted).
    truncated = serialize_message(make_imu(T0 + 1.16, q))[:40]
    garbage = b'\x00\x01\x00\x00garbage'
    bad = [*_bad_fixes(1.05), ('imu', zero_quaternion), ('imu', nan_rate),
           ('imu', no_rates), ('imu', no_orientation), ('fix', unknown),
           ('velocity', inf_velocity), ('imu', backwards), ('imu', garbage),
           ('imu', truncated), ('fix', garbage),
           ('velocity', serialize_message(make_twist(T0 + 1.17, (2.0, 0.0, 0.0)))[:30])]
    dds.play(bad, pace=0.01)
    # Valid data again, then a stamp far in the future and back.
    scenario.play(voyage.events(1.0, start=1.2))
    dds.play([('imu', far_future)], pace=0.01)
    scenario.play(voyage.events(1.0, start=2.2))
    assert scenario.process.alive(), scenario.process.output()
    for topic, messages in scenario.out.items():
        assert messages and all(_finite(m) for m in messages), topic
    after = scenario.counts()

    def rejected(name: str) -> int:
        def total(values: dict[str, str]) -> int:
            return sum(int(v) for k, v in values.items() if k.startswith(f'rejected {name}/'))
        return total(after) - total(before)
    # Every invalid fix (NaN, |lat| > 90, NO_FIX, negative variance) is counted as rejected.
    assert rejected('fix') >= 4, after
    # The zero quaternion, the NaN rate and the stamp behind the window at least.
    assert rejected('imu') >= 3, after
    assert rejected('velocity') >= 1, after
    # Every undecodable payload, counted by its input and reason.
    for name, count in (('imu', 2), ('fix', 1), ('velocity', 1)):
        key = f'rejected {name}/cdr_error'
        assert int(after.get(key, '0')) - int(before.get(key, '0')) == count, after
    assert int(after.get('internal_errors', '0')) == 0, after
    # The node still follows the voyage after the barrage.
    last = scenario.out['odometry'][-1]
    n, e, _ = voyage.ned(seconds(last.header.stamp) - T0)
    assert math.hypot(last.pose.pose.position.x - e, last.pose.pose.position.y - n) < 1.0


def test_parameters_set_at_run_time(dds, run_navigator) -> None:
    voyage = Voyage(speed=2.0, heading0=45 * DEG)
    scenario = Scenario(dds, run_navigator)
    origins = dds.collect('origin', NavSatFix, LATCHED)
    scenario.play(voyage.events(2.0))
    # A new origin 100 m north, 50 m east of the old one, via the real parameter service.
    new_origin = pymap3d.ned2geodetic(100.0, 50.0, 0.0, *ORIGIN)
    results = dds.set_parameters('/navigator', {'origin': list(new_origin)})
    assert all(r.successful for r in results), [r.reason for r in results]
    assert dds.spin_until(
        lambda: origins and abs(origins[-1].latitude - new_origin[0]) < 1e-9, 5.0), origins
    assert abs(origins[-1].longitude - new_origin[1]) < 1e-9
    cut = len(scenario.out['odometry'])
    scenario.play(voyage.events(2.0, start=2.0))
    after = scenario.out['odometry'][cut:]
    assert after and all(m.header.frame_id == 'map' for m in after)
    for msg in after:
        t = seconds(msg.header.stamp) - T0
        n, e, _ = voyage.ned(t)
        p = msg.pose.pose.position
        # Re-expressed about the new origin (an ENU offset of about (-50, -100) m).
        assert math.hypot(p.x - (e - 50.0), p.y - (n - 100.0)) < POSITION_TOL + 0.05, (t, p)
    # fix/filtered did not jump: it stays on the voyage's latitude/longitude throughout.
    for msg in scenario.after('fix/filtered'):
        t = seconds(msg.header.stamp) - T0
        n, e, _ = voyage.ned(t)
        back = pymap3d.geodetic2ned(msg.latitude, msg.longitude, ORIGIN[2], *ORIGIN)
        assert math.hypot(back[0] - n, back[1] - e) < POSITION_TOL, t
    # Invalid values are refused with the reason, and nothing changes; frames and the
    # projection are read-only (renaming a TF frame at run time strands every listener).
    refused = dds.set_parameters('/navigator', {'gnss.default_sigma': -1.0})[0]
    assert not refused.successful and 'gnss.default_sigma' in refused.reason
    refused = dds.set_parameters('/navigator', {'origin': [95.0, 0.0, 0.0]})[0]
    assert not refused.successful and 'latitude' in refused.reason
    for name, value in (('map_frame', 'world'), ('projection', 'flat')):
        refused = dds.set_parameters('/navigator', {name: value})[0]
        assert not refused.successful and 'read-only' in refused.reason, refused.reason
    values = dds.get_parameters('/navigator', ['projection', 'map_frame', 'origin'])
    assert values['projection'] == 'tangent' and values['map_frame'] == 'map'
    assert list(values['origin']) == pytest.approx(list(new_origin))
    assert scenario.process.alive()


def test_origin_is_latched_for_a_late_subscriber(dds, run_navigator) -> None:
    voyage = Voyage(speed=2.0)
    scenario = Scenario(dds, run_navigator)
    scenario.play(voyage.events(1.0))
    late = dds.collect('origin', NavSatFix, LATCHED)
    assert dds.spin_until(lambda: bool(late), 5.0), 'the origin is not latched'
    assert len(late) == 1
    assert late[0].latitude == pytest.approx(ORIGIN[0], abs=1e-12)
    assert late[0].longitude == pytest.approx(ORIGIN[1], abs=1e-12)


def test_use_sim_time_follows_clock(dds, run_navigator) -> None:
    # publish_rate > 0: outputs come from a timer on the node clock, i.e. /clock in sim time.
    voyage = Voyage(speed=2.0)
    scenario = Scenario(dds, run_navigator, use_sim_time=True, publish_rate=10.0)
    clock = dds.publisher('/clock', Clock)
    events = voyage.events(2.0)
    index = 0
    for step in range(201):                  # 2 s of sim time in 10 ms steps
        t = step * 0.01
        while index < len(events) and seconds(events[index][1].header.stamp) <= T0 + t:
            dds.publish(*events[index])
            index += 1
        msg = Clock()
        msg.clock.sec, msg.clock.nanosec = int(T0 + t), round((T0 + t) % 1 * 1e9) % 10 ** 9
        clock.publish(msg)
        dds.spin_for(0.003)
    dds.spin_for(0.3)
    published = len(scenario.out['odometry'])
    # About 10 Hz x 2 s of sim time (timers may lag a tick; the first output needs a fix).
    assert 10 <= published <= 22, published
    # The sim clock stops: so do the timer's outputs, though wall time goes on.
    dds.spin_for(1.0)
    assert len(scenario.out['odometry']) == published
    # Diagnostics run on the steady clock, and measure ages against the sim clock.
    values = scenario.counts()
    ages = [float(v) for k, v in values.items() if 'age' in k and _is_number(v)]
    assert ages and min(ages) < 5.0, values
    assert scenario.process.stop(signal.SIGINT) == 0


def _is_number(text: str) -> bool:
    try:
        return math.isfinite(float(text))
    except ValueError:
        return False


@pytest.mark.parametrize('executor', ['events', 'single'])
def test_switching_qos_rate_and_velocity_source_while_messages_flow(
        dds, run_navigator, navigator_env, monkeypatch, executor) -> None:
    # Issue 8: each run-time change recreates subscriptions or the timer while messages flow;
    # the outputs must go on, on the EventsExecutor (default) and the SingleThreadedExecutor.
    monkeypatch.setitem(navigator_env, 'VK_NAVIGATOR_EXECUTOR', executor)
    voyage = Voyage(speed=2.0)
    scenario = Scenario(dds, run_navigator)
    scenario.play(voyage.events(1.0))
    start = 1.0
    for change in ({'sensor_qos': 'sensor_data'}, {'publish_rate': 20.0},
                   {'publish_rate': 0.0}, {'sensor_qos': 'reliable'}):
        results = dds.set_parameters('/navigator', change)
        assert all(r.successful for r in results), (change, [r.reason for r in results])
        cut = len(scenario.out['odometry'])
        scenario.play(voyage.events(1.0, start=start), tolerance=0.06)
        start += 1.0
        after = scenario.out['odometry'][cut:]
        assert after and seconds(after[-1].header.stamp) >= T0 + start - 0.1, change
    # velocity.source: a subscription of another type on the same topic.
    accepted = int(scenario.counts()['accepted velocity'])
    results = dds.set_parameters('/navigator', {'velocity.source': 'twist'})
    assert all(r.successful for r in results), [r.reason for r in results]
    # One participant cannot hold two types on one topic (Fast DDS refuses): the tester drops
    # its old publisher first, as the node must drop its old subscription.
    dds.node.destroy_publisher(dds._publishers.pop('velocity'))
    twist_pub = dds.node.create_publisher(TwistStamped, 'velocity', dds_harness.RELIABLE)
    assert dds.spin_until(lambda: twist_pub.get_subscription_count() > 0, 10.0), \
        'no velocity subscription of the new type'
    cut = len(scenario.out['odometry'])
    for topic, msg in voyage.events(1.0, start=start):
        if topic == 'velocity':
            twist = TwistStamped()
            twist.header = msg.header
            twist.twist = msg.twist.twist
            twist_pub.publish(twist)
        else:
            dds.publish(topic, msg)
        dds.spin_for(0.002)
    last = T0 + start + 0.9

    def arrived() -> bool:
        out = scenario.out['odometry']
        return len(out) > cut and seconds(out[-1].header.stamp) >= last
    assert dds.spin_until(arrived, 10.0)
    assert int(scenario.counts()['accepted velocity']) > accepted
    assert scenario.process.alive() and 'Traceback' not in scenario.process.output()

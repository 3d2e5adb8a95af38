"""
The whole pipeline with rclpy message objects (no DDS): messages in, the bytes to send out.

A small simulated vessel (constant body velocity and yaw rate, closed form) publishes
NavSatFix, Imu and TwistWithCovarianceStamped; the emissions are read back with rclpy and
checked in ROS terms, as a subscriber sees them.
"""

from __future__ import annotations

import math
from pathlib import Path
import re
from typing import Any, Iterable

from geometry_msgs.msg import TwistWithCovarianceStamped
import numpy as np
import pytest
from rclpy.serialization import deserialize_message
from reference import ConstantTurn, convergence
from sensor_msgs.msg import Imu, NavSatFix
from vessel_kinematics.core import geodesy
from vessel_kinematics.estimation import Reason
from vessel_kinematics.ros import interface, outputs
from vessel_kinematics.ros.params import NavigatorParams
from vessel_kinematics.ros.pipeline import Emission, OUTPUTS, Pipeline

#: The type of every topic the pipeline emits on (relative names, as the node publishes).
TYPES = interface.types(interface.Role.OUTPUT, interface.Role.AUXILIARY, absolute=False)

ORIGIN_DEG = (59.9, 10.7, 40.0)
ORIGIN = (math.radians(59.9), math.radians(10.7), 40.0)
T0 = 1_700_000_000.0


def make(**values) -> Pipeline:
    """Return a pipeline with the test origin; keys in ROS dotted form with '__' for '.'."""
    flat = {'origin': list(ORIGIN_DEG), 'publish_rate': 0.0}  # outputs on every update
    flat.update({k.replace('__', '.'): v for k, v in values.items()})
    return Pipeline(NavigatorParams.from_flat(flat))


def stamp(msg, t: float):
    """Set the header time of a message (seconds after T0) and return the message."""
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(int(round((T0 + t) * 1e9)), 10 ** 9)
    return msg


def fix_msg(t: float, p_ned, sigma: float = 0.3) -> NavSatFix:
    """Return a NavSatFix at NED position p_ned about the origin."""
    lat, lon, h = geodesy.ned2llh(tuple(float(c) for c in p_ned), *ORIGIN)
    msg = stamp(NavSatFix(), t)
    msg.latitude, msg.longitude, msg.altitude = math.degrees(lat), math.degrees(lon), h
    msg.position_covariance = np.eye(3).reshape(9) * sigma ** 2
    msg.position_covariance_type = NavSatFix.COVARIANCE_TYPE_DIAGONAL_KNOWN
    return msg


def imu_msg(t: float, psi: float, r: float) -> Imu:
    """Return an Imu of a level vessel with heading psi (NED, rad) and yaw rate r (FRD)."""
    msg = stamp(Imu(), t)
    yaw = math.pi / 2 - psi                     # ROS yaw: from east, counter-clockwise
    msg.orientation.z, msg.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
    msg.angular_velocity.z = -r
    return msg


def vel_msg(t: float, u: float, v: float) -> TwistWithCovarianceStamped:
    """Return a body velocity u forward, v starboard (FRD) as a FLU twist."""
    msg = stamp(TwistWithCovarianceStamped(), t)
    msg.twist.twist.linear.x, msg.twist.twist.linear.y = u, -v
    msg.twist.covariance = np.diag([1e-4] * 6).reshape(36)
    return msg


class Vessel(ConstantTurn):
    """The reference turn, and the messages a vessel following it would send."""

    def messages(self, t_end: float, imu_hz: float = 50.0, vel_hz: float = 10.0,
                 fix_hz: float = 2.0, t_start: float = 0.0, fix_offset=(0.0, 0.0, 0.0)):
        """Yield (name, msg) in stamp order."""
        events = []
        for rate, name in ((imu_hz, 'imu'), (vel_hz, 'velocity'), (fix_hz, 'fix')):
            if rate:
                first, last = int(math.ceil(t_start * rate)), int(t_end * rate) + 1
                events += [(k / rate, name) for k in range(first, last)]
        events.sort(key=lambda e: (e[0], ('fix', 'imu', 'velocity').index(e[1])))
        for t, name in events:
            if name == 'imu':
                yield name, imu_msg(t, self.psi(t), self.r)
            elif name == 'velocity':
                yield name, vel_msg(t, self.u, self.v)
            else:
                yield name, fix_msg(t, self.position(t) + np.asarray(fix_offset))


def decoded(emissions: Iterable[Emission]) -> dict[str, Any]:
    """Return {relative topic: rclpy message} of emissions (read as a subscriber reads them)."""
    out = {}
    for e in emissions:
        topic = e.topic if e.topic in TYPES else e.topic.lstrip('/')
        out[topic] = deserialize_message(e.cdr, interface.message_class(TYPES[topic]))
    return out


def handle(pipe: Pipeline, name: str, msg: Any, arrival: float | None = None):
    """Hand one message to the pipeline, arriving at its stamp (or at ``arrival``, s)."""
    if arrival is not None:
        return pipe.handle(name, msg, int(round((T0 + arrival) * 1e9)))
    return pipe.handle(name, msg, msg.header.stamp.sec * 10 ** 9 + msg.header.stamp.nanosec)


def feed(pipe: Pipeline, stream) -> list[dict]:
    """Feed messages; return the outputs of each message, then of the end, as {topic: msg}."""
    out = []
    for name, msg in stream:
        result = handle(pipe, name, msg)
        assert result.rejected is None, (name, result.rejected, result.detail)
        out.append(decoded(result.emissions))
    last = pipe.flush().emissions                  # what waited for the next IMU sample
    return out + [decoded(last)] if last else out


def map_convergence(o: dict) -> float:
    """Return the meridians' convergence (rad) at the published position (``fix/filtered``)."""
    fix = o['fix/filtered']
    return convergence(fix.latitude, fix.longitude, ORIGIN_DEG)


def state_outputs(o: dict) -> dict:
    """Return the outputs of the state alone (no origin, no transforms)."""
    return {k: v for k, v in o.items() if k in OUTPUTS and k != 'origin'}


def all_finite(outputs: dict) -> bool:
    """Return True when every number in the output messages is finite."""
    def numbers(msg):
        if isinstance(msg, (float, int)):
            yield float(msg)
        elif isinstance(msg, np.ndarray):
            yield from msg.ravel().tolist()
        elif hasattr(msg, 'get_fields_and_field_types'):
            for field in msg.get_fields_and_field_types():
                yield from numbers(getattr(msg, field))
        elif isinstance(msg, (list, tuple)):
            for item in msg:
                yield from numbers(item)
    return all(math.isfinite(x) for m in outputs.values() for x in numbers(m))


# ------------------------------------------------------------------------------ scenarios

def test_straight_run_north():
    pipe = make()
    vessel = Vessel(2.0)
    outs = [o for o in feed(pipe, vessel.messages(20.0)) if o]
    last = outs[-1]
    # Every output of the interface table but the water-referenced ones and the origin (once).
    assert set(state_outputs(last)) == {o for o in OUTPUTS
                                        if not interface.topic(o).water_only} - {'origin'}
    # /tf_static as soon as the origin is known, the origin with the first state, once.
    assert '/tf_static' in outs[0] and 'origin' in next(o for o in outs if 'odometry' in o)
    outs = [o for o in outs if 'odometry' in o]
    stamps = {(o['odometry'].header.stamp.sec, o['odometry'].header.stamp.nanosec) for o in outs}
    assert sum('/tf' in o for o in outs) == len(stamps) <= len(outs)   # one /tf per stamp
    assert sum('origin' in o for o in outs) == 1              # emitted once
    pos = last['odometry'].pose.pose.position
    assert (pos.x, pos.y) == (pytest.approx(0.0, abs=1e-3), pytest.approx(40.0, abs=1e-3))
    ned = last['odometry/ned'].pose.pose.position
    assert (ned.x, ned.y) == (pytest.approx(40.0, abs=1e-3), pytest.approx(0.0, abs=1e-3))
    cs = last['course_sideslip'].vector
    assert cs.x == pytest.approx(0.0, abs=1e-6) and cs.y == pytest.approx(0.0, abs=1e-6)
    assert last['odometry'].twist.twist.linear.x == pytest.approx(2.0, abs=1e-4)
    assert last['odometry/local'].header.frame_id == 'odom'
    lat, lon, h = geodesy.ned2llh((40.0, 0.0, 0.0), *ORIGIN)
    assert last['fix/filtered'].latitude == pytest.approx(math.degrees(lat), abs=1e-8)
    assert all(all_finite(o) for o in outs)


def test_local_never_jumps_at_a_fix():
    """Fixes offset 5 m east pull the fused pose; odometry/local moves only by v dt."""
    pipe = make(gnss__gate_sigma=0.0)      # a sudden 5 m offset would be gated at first
    vessel = Vessel(2.0)
    feed(pipe, vessel.messages(5.0))
    outs = [o for o in feed(pipe, vessel.messages(15.0, t_start=5.01, fix_offset=(0, 5.0, 0)))
            if o]
    local = np.array([[o['odometry/local'].pose.pose.position.x,
                       o['odometry/local'].pose.pose.position.y] for o in outs])
    fused = np.array([[o['odometry'].pose.pose.position.x,
                       o['odometry'].pose.pose.position.y] for o in outs])
    assert np.max(np.linalg.norm(np.diff(local, axis=0), axis=1)) < 2.0 * 0.02 + 1e-6
    assert np.max(np.abs(np.diff(fused[:, 0]))) > 0.2          # the fused pose jumps east
    assert fused[-1, 0] > 2.5                                  # towards the fixes
    assert abs(local[-1, 0]) < 0.01                            # local never saw the offset
    # map->odom carries the correction: map->odom o odom->base = fused pose.
    last = next(o for o in reversed(outs) if '/tf' in o)
    map_odom, odom_base = last['/tf'].transforms
    assert (map_odom.transform.translation.x + odom_base.transform.translation.x
            == pytest.approx(last['odometry'].pose.pose.position.x, abs=1e-9))


def test_crabbing_vessel_sideslip_minus_10_degrees():
    psi = math.radians(10.0)
    vessel = Vessel(2.0 * math.cos(psi), -2.0 * math.sin(psi), 0.0, psi0=psi)
    pipe = make()
    last = [o for o in feed(pipe, vessel.messages(10.0)) if o][-1]
    cs = last['course_sideslip'].vector
    # The sway's Markov prior pulls toward zero between measurements: ~v dt / tau (0.002 deg).
    assert math.degrees(cs.x) == pytest.approx(0.0, abs=5e-3)
    assert math.degrees(cs.y) == pytest.approx(-10.0, abs=5e-3)
    assert cs.z == pytest.approx(0.0, abs=1e-9)


def test_turning_vessel():
    """Turn at r = 0.1 rad/s, u = 3, v = 0.4 m/s for 60 s (almost a circle), fixes at 2 Hz."""
    vessel = Vessel(3.0, 0.4, 0.1, psi0=0.3)
    pipe = make()
    last = [o for o in feed(pipe, vessel.messages(60.0)) if o][-1]
    ned = last['odometry/ned'].pose.pose
    np.testing.assert_allclose([ned.position.x, ned.position.y], vessel.position(60.0)[0:2],
                               atol=0.05)
    q = ned.orientation
    psi = math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y ** 2 + q.z ** 2))
    # The IMU's heading is against the vessel's own north; the map's north at the origin is
    # turned from it by the meridians' convergence (7e-7 rad here, 2.5 m east), by pymap3d.
    gamma = map_convergence(last)
    assert abs(gamma) > 1e-7
    assert math.remainder(psi - vessel.psi(60.0) - gamma, 2 * math.pi) == pytest.approx(
        0.0, abs=1e-9)
    beta = math.atan2(0.4, 3.0)
    cs = last['course_sideslip'].vector
    assert math.remainder(cs.x - (vessel.psi(60.0) + beta), 2 * math.pi) == pytest.approx(
        0.0, abs=1e-3)
    assert cs.y == pytest.approx(beta, abs=1e-3)


def test_water_reference_publishes_current_enu():
    pipe = make(velocity__reference='water')
    vessel = Vessel(2.0, 0.0, 0.02)
    current = np.array([0.3, 0.2])          # NED: 0.3 north, 0.2 east
    out = None
    for name, msg in vessel.messages(300.0, imu_hz=5.0, vel_hz=2.0, fix_hz=1.0):
        if name == 'velocity':
            t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9 - T0
            psi = vessel.psi(t)
            c_b = np.array([[math.cos(psi), math.sin(psi)],
                            [-math.sin(psi), math.cos(psi)]]) @ current
            msg = vel_msg(t, 2.0 - c_b[0], -c_b[1])
        out = decoded(handle(pipe, name, msg).emissions) or out
    cur = out['current']
    assert cur.header.frame_id == 'map'
    assert (cur.vector.x, cur.vector.y) == (pytest.approx(0.2, abs=0.03),
                                            pytest.approx(0.3, abs=0.03))


def test_no_velocity_source():
    pipe = make(velocity__source='none')
    vessel = Vessel(2.0, 0.0, 0.0, psi0=math.radians(30.0))
    outs = feed(pipe, ((n, m) for n, m in vessel.messages(30.0, fix_hz=5.0)
                       if n != 'velocity'))
    cs = outs[-1]['course_sideslip'].vector
    assert math.degrees(cs.x) == pytest.approx(30.0, abs=1.0)
    result = handle(pipe, 'velocity', vel_msg(30.0, 1.0, 0.0))
    assert result.rejected == 'unused_input' == Reason.UNUSED_INPUT
    assert type(result.rejected) is str and pipe.counts['velocity/unused_input'] == 1


def test_yaw_offset_rotates_heading():
    pipe = make(imu__yaw_offset=math.radians(5.0))
    vessel = Vessel(2.0)
    last = [o for o in feed(pipe, vessel.messages(2.0)) if o][-1]
    # The IMU says north; +5 deg ENU (counter-clockwise) is heading -5 deg (NED) against the
    # vessel's north, turned into the map's by the meridians' convergence (4e-8 rad here).
    gamma = math.degrees(map_convergence(last))
    q = last['odometry/ned'].pose.pose.orientation
    psi = math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y ** 2 + q.z ** 2))
    assert math.degrees(psi) == pytest.approx(-5.0 + gamma, abs=1e-9)
    o = last['odometry'].pose.pose.orientation
    yaw = math.atan2(2 * (o.w * o.z + o.x * o.y), 1 - 2 * (o.y ** 2 + o.z ** 2))
    assert math.degrees(yaw) == pytest.approx(95.0 - gamma, abs=1e-9)


# ------------------------------------------------------------------------------ bad input

def test_reasons_are_one_enum_of_distinct_snake_case_keys():
    values = [r.value for r in Reason]
    assert len(set(values)) == len(values)
    assert all(type(v) is str and v.isidentifier() and v == v.lower() for v in values)
    assert all(r.name == r.value.upper() and r == r.value for r in Reason)
    # docs/architecture.md lists them all, and nothing else: a new reason is documented there.
    docs = (Path(__file__).resolve().parents[1] / 'docs' / 'architecture.md').read_text()
    table = docs[docs.index('## Rejection reasons'):]
    listed = {word for line in table.splitlines() if line.startswith('| ')
              for word in re.findall(r'`([a-z_]+)`', line.split('|')[2])}
    assert listed == set(values)


def test_barrage_of_bad_messages():
    pipe = make()
    vessel = Vessel(2.0)
    feed(pipe, vessel.messages(2.0))
    t = 2.001
    bad = []
    f = fix_msg(t, (0, 0, 0))
    f.latitude = math.nan
    bad.append(('fix', f, 'nan_field'))
    f = fix_msg(t, (0, 0, 0))
    f.latitude = 95.0
    bad.append(('fix', f, 'lat_out_of_range'))
    f = fix_msg(t, (0, 0, 0))
    f.status.status = -1
    bad.append(('fix', f, 'no_fix'))
    f = fix_msg(t, (0, 0, 0))
    f.longitude = math.inf
    bad.append(('fix', f, 'nan_field'))
    i = imu_msg(t, 0.0, 0.0)
    i.orientation.w, i.orientation.z = 0.0, 0.0
    bad.append(('imu', i, 'zero_quaternion'))
    i = imu_msg(t, 0.0, 0.0)
    i.orientation.w = 2.0
    bad.append(('imu', i, 'non_unit_quaternion'))
    i = imu_msg(t, 0.0, 0.0)
    i.angular_velocity.x = math.nan
    bad.append(('imu', i, 'nan_field'))
    i = imu_msg(t, 0.0, 0.0)
    i.orientation_covariance[0] = -1.0
    i.angular_velocity_covariance[0] = -1.0
    bad.append(('imu', i, 'no_data'))
    v = vel_msg(t, 2.0, 0.0)
    v.twist.twist.linear.x = math.inf
    bad.append(('velocity', v, 'nan_field'))
    bad.append(('imu', imu_msg(t - 5.0, 0.0, 0.0), 'too_late'))   # beyond history_length
    z = imu_msg(0.0, 0.0, 0.0)
    z.header.stamp.sec, z.header.stamp.nanosec = 0, 0
    bad.append(('imu', z, 'zero_stamp'))
    for name, msg, reason in bad:
        result = handle(pipe, name, msg, arrival=t)
        assert result.rejected == reason, (name, reason, result)
        assert result.emissions == () and result.detail
    counts = pipe.counts
    assert counts['fix/nan_field'] == 2 and counts['fix/no_fix'] == 1
    assert counts['fix/lat_out_of_range'] == 1 and counts['imu/zero_quaternion'] == 1
    assert counts['imu/non_unit_quaternion'] == 1 and counts['imu/nan_field'] == 1
    assert counts['velocity/nan_field'] == 1 and counts['imu/too_late'] == 1
    assert counts['imu/zero_stamp'] == 1 and counts['imu/no_data'] == 1
    # The keys and results are the reasons' plain text (an f-string of the enum is not).
    assert all(type(k) is str and 'Reason' not in k for k in counts)
    assert type(result.rejected) is str
    # Accepted special cases: no orientation (-1): integrate rates; NaN altitude fix.
    i = imu_msg(t, 0.0, 0.0)
    i.orientation_covariance[0] = -1.0
    assert handle(pipe, 'imu', i).rejected is None
    f = fix_msg(t + 0.001, vessel.position(t + 0.001))
    f.altitude = math.nan
    f.position_covariance_type = NavSatFix.COVARIANCE_TYPE_UNKNOWN
    assert handle(pipe, 'fix', f).rejected is None
    outs = [o for o in feed(pipe, vessel.messages(6.0, t_start=2.01)) if o]
    assert all(all_finite(o) for o in outs)
    pos = outs[-1]['odometry/ned'].pose.pose.position
    assert (pos.x, pos.y) == (pytest.approx(12.0, abs=0.01), pytest.approx(0.0, abs=0.01))
    diag = decoded([pipe.diagnostics(int((T0 + 6.0) * 1e9))])['/diagnostics']
    values = {kv.key: kv.value for kv in diag.status[0].values}
    assert values['rejected fix/no_fix'] == '1'
    assert values['rejected imu/zero_quaternion'] == '1'
    assert values['mode'] == 'fused'


def test_stamp_backwards_resets():
    """A bag looped (its clock 70 s back): refused as too late for less than 0.5 s, one reset."""
    pipe = make()
    for name, msg in Vessel(2.0).messages(10.0):
        t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9 - T0
        assert handle(pipe, name, msg, arrival=t + 60.0).rejected is None
    looped = [handle(pipe, name, msg) for name, msg in Vessel(2.0).messages(5.0)]
    assert pipe.counts['resets'] == 1
    refused = [r.rejected for r in looped if r.rejected is not None]
    assert set(refused) == {'too_late'} and len(refused) <= 35, refused    # 0.5 s of 62 Hz
    outs = [decoded(r.emissions) for r in looped if r.emissions] + [
        decoded(pipe.flush().emissions)]
    outs = [o for o in outs if o]
    pos = outs[-1]['odometry/ned'].pose.pose.position
    assert pos.x == pytest.approx(10.0, abs=0.01)
    assert not any('origin' in o for o in outs)                  # origin kept


def test_out_of_order_within_window():
    pipe = make()
    vessel = Vessel(2.0)
    feed(pipe, vessel.messages(5.0))
    result = handle(pipe, 'velocity', vel_msg(5.0 - 0.05, 2.0, 0.0))
    # Fused at its stamp; the outputs follow the IMU: the next sample's carry it.
    assert result.rejected is None and result.emissions == ()
    result = handle(pipe, 'imu', imu_msg(5.02, 0.0, 0.0))
    odometry = decoded(result.emissions)['odometry']
    stamp_ns = odometry.header.stamp.sec * 10 ** 9 + odometry.header.stamp.nanosec
    assert stamp_ns == int(round((T0 + 5.02) * 1e9)) == result.emissions[0].stamp_ns


# ------------------------------------------------------------------------------ parameters

def test_origin_change_at_run_time_keeps_fix_filtered():
    pipe = make(motion='free')            # 3-D: the height is a state and re-expressed too
    vessel = Vessel(2.0, 0.0, 0.01)
    last = [o for o in feed(pipe, vessel.messages(10.0)) if o][-1]
    before = last['fix/filtered']
    flat = pipe.params.to_flat()
    flat['origin'] = [59.91, 10.71, 20.0]
    sent = pipe.set_params(NavigatorParams.from_flat(flat))
    assert [e.topic for e in sent] == ['/origin', '/tf_static']
    assert decoded(sent)['origin'].latitude == pytest.approx(59.91, abs=1e-12)
    after = decoded(Emission('/' + name, 0, data)
                    for name, data in outputs.state_outputs(pipe.state(), pipe.params))
    assert after['fix/filtered'].latitude == pytest.approx(before.latitude, abs=1e-12)
    assert after['fix/filtered'].longitude == pytest.approx(before.longitude, abs=1e-12)
    assert after['fix/filtered'].altitude == pytest.approx(before.altitude, abs=1e-6)
    assert after['odometry/ned'].pose.pose.position.x < -1000.0
    earth_map = decoded(sent)['/tf_static'].transforms[0]
    assert earth_map.child_frame_id == 'map'
    ecef = geodesy.llh2ecef(math.radians(59.91), math.radians(10.71), 20.0)
    assert earth_map.transform.translation.x == pytest.approx(ecef[0], abs=1e-6)
    # Continue: no jump on the next messages.
    nxt = [o for o in feed(pipe, vessel.messages(11.0, t_start=10.01)) if o][0]
    assert nxt['fix/filtered'].latitude == pytest.approx(before.latitude, abs=1e-6)


def test_publish_rate_emits_once_per_period_of_stamps():
    """At 10 Hz: one set of outputs as each accepted stamp crosses a tenth of a second."""
    pipe = make(publish_rate=10.0)
    assert pipe.start()[0].topic == '/tf_static' and pipe.state() is None
    emitted = []
    for name, msg in Vessel(2.0).messages(3.0, imu_hz=50.0, vel_hz=10.0, fix_hz=2.0):
        result = handle(pipe, name, msg)
        if any(e.topic == '/odometry' for e in result.emissions):
            emitted.append(result.emissions[0].stamp_ns)
    periods = [round((t - emitted[0]) * 1e-8) for t in emitted]
    assert periods == list(range(len(periods))) and len(periods) >= 29


def test_waiting_for_origin_diagnostics_and_no_outputs():
    pipe = Pipeline(NavigatorParams(publish_rate=0.0))  # outputs on every update
    # Before the origin, only the static NED/FRD twins (earth -> map needs the origin).
    (statics,) = pipe.start()
    assert [(t.header.frame_id, t.child_frame_id)
            for t in decoded([statics])['/tf_static'].transforms] == [
        ('map', 'map_ned'), ('base_link', 'base_link_frd')]
    result = handle(pipe, 'imu', imu_msg(0.0, 0.0, 0.0))
    assert result.rejected is None and result.emissions == () and pipe.state() is None
    status = decoded([pipe.diagnostics(int(T0 * 1e9))])['/diagnostics'].status[0]
    assert status.name == 'navigator: estimate' and status.level == b'\x01'
    values = {kv.key: kv.value for kv in status.values}
    assert values['mode'] == 'waiting_for_origin' and values['age fix (s)'] == 'never'
    assert values['accepted imu'] == '1'
    result = handle(pipe, 'fix', fix_msg(0.1, (0.0, 0.0, 0.0)))
    # Stamped after the last IMU sample, the fix waits for the IMU to reach its stamp.
    assert result.rejected is None and result.emissions == () and pipe.timeline.waiting == 1
    result = handle(pipe, 'imu', imu_msg(0.1, 0.0, 0.0))
    # Placed and headed, but nothing has told the velocity: no state out at 0 m/s yet, only
    # earth -> map now that the origin is known.
    assert [e.topic for e in result.emissions] == ['/tf_static']
    handle(pipe, 'velocity', vel_msg(0.15, 2.0, 0.0))
    result = handle(pipe, 'imu', imu_msg(0.15, 0.0, 0.0))
    topics = [e.topic for e in result.emissions]
    assert topics[:1] == ['/odometry'] and topics[-2:] == ['/origin', '/tf']
    later = decoded([pipe.diagnostics(int((T0 + 0.2) * 1e9))])['/diagnostics']
    assert later.status[0].level == b'\x00'


def test_ground_motion_outputs_planar():
    pipe = make(motion='ground')
    vessel = Vessel(2.0, 0.0, 0.05)
    last = [o for o in feed(pipe, vessel.messages(5.0)) if o][-1]
    assert last['odometry'].pose.pose.position.z == 0.0
    o = last['odometry'].pose.pose.orientation
    assert abs(o.x) < 1e-12 and abs(o.y) < 1e-12
    assert last['odometry'].twist.twist.linear.z == 0.0


def test_unknown_input_name():
    with pytest.raises(ValueError):
        make().handle('gps', NavSatFix(), 0)


@pytest.mark.parametrize('reference', ['ground', 'water'])
def test_the_outputs_never_change_the_filter(reference):
    """Emitting on every update or at 30 Hz: the same filter, bit for bit, message by message."""
    every = make(velocity__reference=reference)
    rated = make(velocity__reference=reference, publish_rate=30.0)
    counts = [0, 0]
    for name, msg in Vessel(2.0, 0.3, 0.05).messages(5.0, fix_hz=5.0):
        counts[0] += bool(handle(every, name, msg).emissions)
        counts[1] += bool(handle(rated, name, msg).emissions)
        np.testing.assert_array_equal(every.estimator.x, rated.estimator.x)
        np.testing.assert_array_equal(every.estimator.P, rated.estimator.P)
    assert counts[0] > counts[1] > 140
    assert every.counts == rated.counts


def test_an_emission_carries_the_state_it_was_built_from():
    """Result.state is the state of the emission's messages, as state() gives it then."""
    pipe = make(velocity__reference='water')
    checked = 0
    for name, msg in Vessel(2.0, 0.3, 0.05).messages(3.0):
        result = handle(pipe, name, msg)
        if not any(e.topic == '/odometry' for e in result.emissions):
            assert result.state is None
            continue
        assert result.state is not None
        now = pipe.state()
        np.testing.assert_array_equal(result.state.p, now.p)
        np.testing.assert_array_equal(result.state.cov_nu, now.cov_nu)
        odometry = decoded(result.emissions)['odometry']
        assert odometry.pose.pose.position.x == result.state.p[1]          # ENU x = east
        assert all(e.stamp_ns == result.state.stamp_ns for e in result.emissions)
        checked += 1
    assert checked > 100


def test_a_message_of_another_type_is_refused_as_unused():
    """A TwistWithCovarianceStamped still queued after velocity.source became odometry."""
    pipe = make(velocity__source='odometry')
    feed(pipe, ((n, m) for n, m in Vessel(2.0).messages(2.0) if n != 'velocity'))
    result = handle(pipe, 'velocity', vel_msg(2.001, 2.0, 0.0))
    assert result.rejected == 'unused_input' and 'nav_msgs/msg/Odometry' in result.detail
    assert pipe.counts['velocity/unused_input'] == 1
    assert handle(pipe, 'imu', NavSatFix()).rejected == 'unused_input'


def test_outputs_go_on_while_a_frozen_compass_is_refused():
    """
    A compass frozen in a turn is refused at every sample: the outputs still follow its pace.

    The IMU paces the outputs; refused as ``frozen_input`` sample after sample, it used to
    leave the fixes and log readings taken meanwhile unsent until the compass spoke again
    (seconds of silence on a real yacht's log). Each pace sample now sends what was taken since
    the last outputs, so the odometry keeps its rate and follows the turn by the gyro.
    """
    pipe = make()
    vessel = Vessel(3.0, r=math.radians(5.0))
    frozen_psi = vessel.psi(20.0)
    rejected, per_second = 0, {}
    for name, msg in vessel.messages(40.0, imu_hz=10.0, vel_hz=5.0, fix_hz=1.0):
        t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9 - T0
        if name == 'imu' and t >= 20.0:           # the compass holds; the gyro goes on
            msg = imu_msg(t, frozen_psi, vessel.r)
        result = handle(pipe, name, msg)
        rejected += result.rejected == Reason.FROZEN_INPUT.value
        if any(e.topic == '/odometry' for e in result.emissions):
            per_second[int(t)] = per_second.get(int(t), 0) + 1
            last, t_last = decoded(result.emissions)['odometry'], t
    assert rejected > 150                       # found frozen, refused from then on
    assert all(per_second.get(s, 0) >= 5 for s in range(10, 40)), per_second
    q = last.pose.pose.orientation              # ENU yaw, from east counter-clockwise
    psi = math.pi / 2 - 2.0 * math.atan2(q.z, q.w)
    assert abs(math.remainder(psi - vessel.psi(t_last), math.tau)) < math.radians(3.0)

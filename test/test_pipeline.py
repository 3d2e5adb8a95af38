"""
The whole pipeline with rclpy message objects (no DDS): messages in, messages out.

A small simulated vessel (constant body velocity and yaw rate, closed form) publishes
NavSatFix, Imu and TwistWithCovarianceStamped; the outputs are checked in ROS terms.
"""

from __future__ import annotations

import dataclasses
import math

from geometry_msgs.msg import TwistWithCovarianceStamped
import numpy as np
import pytest
from reference import ConstantTurn
from sensor_msgs.msg import Imu, NavSatFix
from vessel_kinematics.core import geodesy
from vessel_kinematics.estimation import NavPose, NavState, Reason
from vessel_kinematics.ros import interface
from vessel_kinematics.ros.params import NavigatorParams
from vessel_kinematics.ros.pipeline import OUTPUTS, Pipeline

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


def feed(pipe: Pipeline, stream) -> list[dict]:
    """Feed messages; return the outputs of each accepted message as {topic: msg}."""
    out = []
    for name, msg in stream:
        result = pipe.handle(name, msg)
        assert result.rejected is None, (name, result.rejected, result.detail)
        out.append({o.topic: o.msg for o in result.outputs})
    return out


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
    assert set(last) == {o for o in OUTPUTS if not interface.topic(o).water_only} - {'origin'}
    assert 'origin' in outs[0]
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
    map_odom, odom_base = pipe.transforms()
    assert (map_odom.transform.translation.x + odom_base.transform.translation.x
            == pytest.approx(fused[-1, 0], abs=1e-9))


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
    assert math.remainder(psi - vessel.psi(60.0), 2 * math.pi) == pytest.approx(0.0, abs=1e-9)
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
        result = pipe.handle(name, msg)
        out = {o.topic: o.msg for o in result.outputs} or out
    cur = out['current']
    assert cur.header.frame_id == 'map'
    assert (cur.vector.x, cur.vector.y) == (pytest.approx(0.2, abs=0.03),
                                            pytest.approx(0.3, abs=0.03))


def test_no_velocity_source():
    pipe = make(velocity__source='none')
    assert pipe.velocity_type() is None
    vessel = Vessel(2.0, 0.0, 0.0, psi0=math.radians(30.0))
    outs = feed(pipe, ((n, m) for n, m in vessel.messages(30.0, fix_hz=5.0)
                       if n != 'velocity'))
    cs = outs[-1]['course_sideslip'].vector
    assert math.degrees(cs.x) == pytest.approx(30.0, abs=1.0)
    result = pipe.handle('velocity', vel_msg(30.0, 1.0, 0.0))
    assert result.rejected == 'unused_input' == Reason.UNUSED_INPUT
    assert type(result.rejected) is str and pipe.counts['velocity/unused_input'] == 1


def test_yaw_offset_rotates_heading():
    pipe = make(imu__yaw_offset=math.radians(5.0))
    vessel = Vessel(2.0)
    last = [o for o in feed(pipe, vessel.messages(2.0)) if o][-1]
    # The IMU says north; +5 deg ENU (counter-clockwise) is heading -5 deg (NED).
    q = last['odometry/ned'].pose.pose.orientation
    psi = math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y ** 2 + q.z ** 2))
    assert math.degrees(psi) == pytest.approx(-5.0, abs=1e-9)
    o = last['odometry'].pose.pose.orientation
    yaw = math.atan2(2 * (o.w * o.z + o.x * o.y), 1 - 2 * (o.y ** 2 + o.z ** 2))
    assert math.degrees(yaw) == pytest.approx(95.0, abs=1e-9)


# ------------------------------------------------------------------------------ bad input

def test_reasons_are_one_enum_of_distinct_snake_case_keys():
    values = [r.value for r in Reason]
    assert len(set(values)) == len(values) == 20   # 18 of the inputs, 2 of /tf_static
    assert all(type(v) is str and v.isidentifier() and v == v.lower() for v in values)
    assert all(r.name == r.value.upper() and r == r.value for r in Reason)


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
    bad.append(('imu', imu_msg(t - 0.5, 0.0, 0.0), 'stale_stamp'))
    z = imu_msg(0.0, 0.0, 0.0)
    z.header.stamp.sec, z.header.stamp.nanosec = 0, 0
    bad.append(('imu', z, 'zero_stamp'))
    for name, msg, reason in bad:
        result = pipe.handle(name, msg)
        assert result.rejected == reason, (name, reason, result)
        assert result.outputs == [] and result.detail
    counts = pipe.counts
    assert counts['fix/nan_field'] == 2 and counts['fix/no_fix'] == 1
    assert counts['fix/lat_out_of_range'] == 1 and counts['imu/zero_quaternion'] == 1
    assert counts['imu/non_unit_quaternion'] == 1 and counts['imu/nan_field'] == 1
    assert counts['velocity/nan_field'] == 1 and counts['imu/stale_stamp'] == 1
    assert counts['imu/zero_stamp'] == 1 and counts['imu/no_data'] == 1
    # The keys and results are the reasons' plain text (an f-string of the enum is not).
    assert all(type(k) is str and 'Reason' not in k for k in counts)
    assert type(result.rejected) is str
    # Accepted special cases: no orientation (-1): integrate rates; NaN altitude fix.
    i = imu_msg(t, 0.0, 0.0)
    i.orientation_covariance[0] = -1.0
    assert pipe.handle('imu', i).rejected is None
    f = fix_msg(t + 0.001, vessel.position(t + 0.001))
    f.altitude = math.nan
    f.position_covariance_type = NavSatFix.COVARIANCE_TYPE_UNKNOWN
    assert pipe.handle('fix', f).rejected is None
    outs = [o for o in feed(pipe, vessel.messages(6.0, t_start=2.01)) if o]
    assert all(all_finite(o) for o in outs)
    pos = outs[-1]['odometry/ned'].pose.pose.position
    assert (pos.x, pos.y) == (pytest.approx(12.0, abs=0.01), pytest.approx(0.0, abs=0.01))
    diag = pipe.diagnostics(int((T0 + 6.0) * 1e9))
    values = {kv.key: kv.value for kv in diag.status[0].values}
    assert values['rejected fix/no_fix'] == '1'
    assert values['rejected imu/zero_quaternion'] == '1'
    assert values['mode'] == 'fused'


def test_stamp_backwards_resets():
    pipe = make()
    vessel = Vessel(2.0)
    feed(pipe, vessel.messages(10.0))
    result = pipe.handle('imu', imu_msg(-50.0, 0.0, 0.0))      # the bag looped
    assert result.rejected is None and result.outputs == []    # waiting for a fix again
    assert pipe.counts['resets'] == 1
    outs = [o for o in feed(pipe, Vessel(2.0).messages(5.0)) if o]
    pos = outs[-1]['odometry/ned'].pose.pose.position
    assert pos.x == pytest.approx(10.0, abs=0.01)
    assert not any('origin' in o for o in outs)                  # origin kept


def test_out_of_order_within_window():
    pipe = make()
    vessel = Vessel(2.0)
    feed(pipe, vessel.messages(5.0))
    result = pipe.handle('velocity', vel_msg(5.0 - 0.05, 2.0, 0.0))
    assert result.rejected is None
    stamp_ns = (result.outputs[0].msg.header.stamp.sec * 10 ** 9
                + result.outputs[0].msg.header.stamp.nanosec)
    assert stamp_ns == int(round((T0 + 5.0) * 1e9))             # the state's time, not older


# ------------------------------------------------------------------------------ parameters

def test_origin_change_at_run_time_keeps_fix_filtered():
    pipe = make(motion='free')            # 3-D: the height is a state and re-expressed too
    vessel = Vessel(2.0, 0.0, 0.01)
    last = [o for o in feed(pipe, vessel.messages(10.0)) if o][-1]
    before = last['fix/filtered']
    flat = pipe.params.to_flat()
    flat['origin'] = [59.91, 10.71, 20.0]
    outputs = pipe.set_params(NavigatorParams.from_flat(flat))
    assert [o.topic for o in outputs] == ['origin']
    assert outputs[0].msg.latitude == pytest.approx(59.91, abs=1e-12)
    after = {o.topic: o.msg for o in pipe.snapshot()}
    assert after['fix/filtered'].latitude == pytest.approx(before.latitude, abs=1e-12)
    assert after['fix/filtered'].longitude == pytest.approx(before.longitude, abs=1e-12)
    assert after['fix/filtered'].altitude == pytest.approx(before.altitude, abs=1e-6)
    assert after['odometry/ned'].pose.pose.position.x < -1000.0
    earth_map = pipe.static_transforms()[0]
    assert earth_map.child_frame_id == 'map'
    ecef = geodesy.llh2ecef(math.radians(59.91), math.radians(10.71), 20.0)
    assert earth_map.transform.translation.x == pytest.approx(ecef[0], abs=1e-6)
    # Continue: no jump on the next messages.
    nxt = [o for o in feed(pipe, vessel.messages(11.0, t_start=10.01)) if o][0]
    assert nxt['fix/filtered'].latitude == pytest.approx(before.latitude, abs=1e-6)


def test_publish_rate_defers_outputs_to_snapshot():
    pipe = make(publish_rate=10.0)
    assert pipe.snapshot() == []
    outs = feed(pipe, Vessel(2.0).messages(1.0))
    assert all(o == {} for o in outs)
    snap = {o.topic: o.msg for o in pipe.snapshot()}
    assert 'origin' in snap and 'odometry' in snap
    assert 'origin' not in {o.topic for o in pipe.snapshot()}


def test_waiting_for_origin_diagnostics_and_no_outputs():
    pipe = Pipeline(NavigatorParams(publish_rate=0.0))  # outputs on every update
    result = pipe.handle('imu', imu_msg(0.0, 0.0, 0.0))
    assert result.rejected is None and result.outputs == []
    assert pipe.snapshot() == [] and pipe.transforms() == []
    # Before the origin, only the static NED/FRD twins (earth -> map needs the origin).
    assert [(t.header.frame_id, t.child_frame_id) for t in pipe.static_transforms()] == [
        ('map', 'map_ned'), ('base_link', 'base_link_frd')]
    diag = pipe.diagnostics(int(T0 * 1e9))
    status = diag.status[0]
    assert status.name == 'navigator: estimate' and status.level == b'\x01'
    values = {kv.key: kv.value for kv in status.values}
    assert values['mode'] == 'waiting_for_origin' and values['age fix (s)'] == 'never'
    assert values['accepted imu'] == '1'
    result = pipe.handle('fix', fix_msg(0.1, (0.0, 0.0, 0.0)))
    assert {o.topic for o in result.outputs} >= {'origin', 'odometry'}
    assert pipe.diagnostics(int((T0 + 0.2) * 1e9)).status[0].level == b'\x00'


def test_two_d_outputs_planar():
    pipe = make(two_d=True)
    vessel = Vessel(2.0, 0.0, 0.05)
    last = [o for o in feed(pipe, vessel.messages(5.0)) if o][-1]
    assert last['odometry'].pose.pose.position.z == 0.0
    o = last['odometry'].pose.pose.orientation
    assert abs(o.x) < 1e-12 and abs(o.y) < 1e-12
    assert last['odometry'].twist.twist.linear.z == 0.0


def test_unknown_input_name():
    with pytest.raises(ValueError):
        make().handle('gps', NavSatFix())


@pytest.mark.parametrize('reference', ['ground', 'water'])
def test_topics_builds_only_those_outputs_and_the_same_messages(reference):
    """handle(topics=...) builds a subset, message for message equal to the full build."""
    full, some = make(velocity__reference=reference), make(velocity__reference=reference)
    subsets = [frozenset(), frozenset({'odometry'}), frozenset({'current', 'fix/filtered'}),
               {'odometry/local', 'course_sideslip', 'origin'}, frozenset(OUTPUTS)]
    saw_origin = False
    for k, (name, msg) in enumerate(Vessel(2.0, 0.3, 0.05).messages(5.0, fix_hz=5.0)):
        topics = subsets[k % len(subsets)]
        everything = {o.topic: o.msg for o in full.handle(name, msg).outputs}
        built = some.handle(name, msg, topics).outputs
        state_outputs = [o for o in built if o.topic != 'origin']
        assert [o.topic for o in state_outputs] == [t for t in everything
                                                    if t in topics and t != 'origin']
        for o in state_outputs:
            assert o.msg == everything[o.topic], o.topic
        saw_origin |= any(o.topic == 'origin' for o in built)
    # The origin event waited for a call that asked for it; the filters never diverged.
    assert saw_origin
    np.testing.assert_array_equal(full.estimator.P, some.estimator.P)
    np.testing.assert_array_equal(full.estimator.x, some.estimator.x)
    with pytest.raises(ValueError, match='unknown outputs'):
        some.snapshot({'odometry', 'odom'})


def test_topics_keep_a_pending_origin_event_until_asked():
    pipe = make()
    outs = [pipe.handle(n, m, frozenset({'odometry'})).outputs
            for n, m in Vessel(2.0).messages(1.0)]
    assert 'origin' not in {o.topic for out in outs for o in out}
    assert 'odometry' in {o.topic for out in outs for o in out}
    assert [o.topic for o in pipe.snapshot(frozenset({'origin'}))] == ['origin']
    assert pipe.snapshot(frozenset({'origin'})) == []


@pytest.mark.parametrize('rate', [0.0, 30.0])
def test_step_and_a_handed_off_emission_equal_handle(rate: float) -> None:
    """
    Session.step + Pipeline.hand_off, built by a second session: what Session.handle sends.

    The replay's writer process builds the emissions so, from a copy of the session made
    before the first input (here: a second session of the same parameters, never fed).
    """
    from vessel_kinematics.ros.session import Session
    stream = list(Vessel(3.0, 0.2, 0.05).messages(8.0, imu_hz=100.0, vel_hz=10.0, fix_hz=2.0))
    direct, here, there = (Session(make(publish_rate=rate)) for _ in range(3))
    there.pipeline.cdr = here.pipeline.cdr = direct.pipeline.cdr = True

    def sent(emissions) -> list:
        return [(e.topic, e.stamp_ns, e.payload if isinstance(e.payload, bytes)
                 else repr(e.payload)) for e in emissions]

    expected = sent(direct.statics())
    got = sent(there.statics())
    for name, msg in stream:
        result, emissions = direct.handle(name, msg)
        expected += sent(emissions)
        result2, due = here.step(name, msg)
        assert (result2.rejected, result2.outputs) == (result.rejected, [])
        if due:
            there.pipeline.take_over(here.pipeline.hand_off())
            got += sent(there.emissions())
    topics = [topic for topic, _, _ in expected]
    assert topics.count('/origin') == 1 and topics.count('/tf_static') >= 1
    assert topics.count('/tf') > 200          # one per stamp (TF_REPEATED_DATA)
    assert topics.count('/odometry') > (700 if rate == 0.0 else 200)
    assert got == expected


@pytest.mark.parametrize('reference', ['ground', 'water'])
def test_the_odometry_leaves_before_the_rest_of_the_state_is_computed(reference) -> None:
    """staged_state: its pose is state()'s, its completion is state(), called after odometry."""
    pipe = make(velocity__reference=reference, publish_rate=30.0)
    est = pipe.estimator
    completions: list[int] = []
    taken: list[str] = []
    completed = est._completed

    def counted(*args):                       # the real completion, counted
        completions.append(len(taken))
        return completed(*args)
    est._completed = counted
    checked = 0
    for name, msg in Vessel(2.0, 0.3, 0.05).messages(5.0, fix_hz=5.0):
        pipe.handle(name, msg)
        if not est.ready:
            continue
        whole = est.state()
        pose, complete = est.staged_state()
        for field in dataclasses.fields(NavPose):
            np.testing.assert_array_equal(getattr(pose, field.name), getattr(whole, field.name))
        again = complete()
        for field in dataclasses.fields(NavState):
            value, expected = getattr(again, field.name), getattr(whole, field.name)
            if isinstance(expected, np.ndarray) or field.name == 'llh':
                np.testing.assert_array_equal(value, expected, field.name)
            else:
                assert value == expected, field.name
        completions.clear()
        pipe._updates += 1                    # as a new update: the pipeline computes anew
        taken.clear()
        for output in pipe.iter_snapshot():
            taken.append(output.topic)
        # Computed once, after the three odometries were taken, before the next output.
        assert taken[:3] == ['odometry', 'odometry/local', 'odometry/ned']
        assert completions == [3], (completions, taken)
        # Pipeline.pose is the pose of Pipeline.state, computed once.
        assert pipe.pose() is pipe.pose() and completions == [3]
        np.testing.assert_array_equal(pipe.pose().p_local, pipe.state().p_local)
        checked += 1
    assert checked > 100

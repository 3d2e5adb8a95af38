"""
The outputs: every message the navigator sends, from its CDR bytes, checked two ways.

Each builder's bytes are deserialised by ``rclpy.serialization.deserialize_message`` and by
rosbags, which must agree field by field (bit for bit) and re-serialise to the same bytes; the
values are then checked against the state, with the REP-103 axes written out here independently
of ``vessel_kinematics.core.frames`` and the rotations through scipy (and pymap3d for ECEF).
"""

from __future__ import annotations

from dataclasses import replace
import math
import struct
from typing import Any

from diagnostic_msgs.msg import DiagnosticStatus
from hypothesis import given, settings, strategies as st
import numpy as np
import pytest
from rclpy.serialization import deserialize_message
from reference import r_nb, rotations
from rosbags.typesys import get_typestore, Stores
from scipy.spatial.transform import Rotation
from sensor_msgs.msg import NavSatFix
from vessel_kinematics.core import geodesy
from vessel_kinematics.estimation import (Calibration, Estimate, Estimator, GnssFix, Mode,
                                          NavState, RelativeFlow)
from vessel_kinematics.ros import cdr, inputs, interface, outputs, tf
from vessel_kinematics.ros.params import filter_config, NavigatorParams

STORE = get_typestore(Stores.ROS2_JAZZY)
# NED <-> ENU and FRD <-> FLU written out here, independently of vessel_kinematics.core.frames.
W = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
B = np.diag([1.0, -1.0, -1.0])
PARAMS = NavigatorParams()
WATER = NavigatorParams.from_flat({'velocity.reference': 'water'})
TYPES = interface.types(interface.Role.OUTPUT, interface.Role.AUXILIARY, absolute=False)


def _bits(value: Any) -> Any:
    """Return a field value in a form equal bit for bit (NaN equals NaN, -0.0 is not 0.0)."""
    if isinstance(value, float):
        return struct.pack('<d', value)
    if isinstance(value, bytes) and len(value) == 1:      # rclpy's byte type
        return value[0]
    if hasattr(value, 'tolist') and not isinstance(value, (int, float)):
        return np.asarray(value, dtype=float).tobytes()
    return value


def same_fields(ours: Any, theirs: Any, where: str) -> None:
    """Assert an rclpy message and rosbags' dataclass hold the same fields, bit for bit."""
    if hasattr(ours, 'get_fields_and_field_types'):
        for name in ours.get_fields_and_field_types():
            same_fields(getattr(ours, name), getattr(theirs, name), f'{where}.{name}')
    elif isinstance(ours, list):
        assert len(ours) == len(theirs), where
        for i, (a, b) in enumerate(zip(ours, theirs)):
            same_fields(a, b, f'{where}[{i}]')
    else:
        assert _bits(ours) == _bits(theirs), (where, ours, theirs)


def decode(data: bytes, msgtype: str) -> Any:
    """Return rclpy's message of ``data``, checked field by field against rosbags' reading."""
    msg = deserialize_message(data, interface.message_class(msgtype))
    theirs = STORE.deserialize_cdr(data, msgtype)
    same_fields(msg, theirs, msgtype)
    assert bytes(STORE.serialize_cdr(theirs, msgtype)) == data, msgtype   # zero padding
    return msg


def a_state(q_nb, p=(10.0, 20.0, -3.0), nu=(2.0, 0.5, 0.1), omega=(0.01, 0.02, 0.03),
            **fields: Any) -> NavState:
    """Return a NavState with distinct covariance entries."""
    rng = np.random.default_rng(3)

    def spd(n, scale):
        a = rng.normal(size=(n, n))
        return scale * (a @ a.T + np.eye(n))

    p = np.array(p)
    values: dict[str, Any] = {
        'stamp_ns': 123_456_789_012, 'mode': Mode.FUSED, 'origin': (1.0, 0.2, 30.0), 'p': p,
        'q': np.asarray(q_nb, dtype=float), 'nu': np.array(nu), 'omega': np.array(omega),
        'v_n': r_nb(q_nb) @ np.array(nu), 'current': np.array([0.3, -0.1, 0.0]),
        'p_local': p - np.array([1.0, -2.0, 0.5]), 'llh': (1.0, 0.2, 33.0), 'course': 0.1,
        'sideslip': -0.2, 'angle_of_attack': 0.05, 'cov_p': spd(3, 1.0),
        'cov_att': spd(3, 1e-3), 'cov_nu': spd(3, 1e-2), 'cov_omega': spd(3, 1e-4),
        'cov_current': np.eye(3) * 0.01, 'cov_p_local': spd(3, 2.0),
        'relative_flow': RelativeFlow(1.5, 0.04, -0.01)}
    values.update(fields)
    return NavState(**values)


def built(s: NavState, params: NavigatorParams = PARAMS) -> dict[str, Any]:
    """Return {output name: rclpy message} of every output of the state, checked both ways."""
    return {name: decode(data, TYPES[name]) for name, data in outputs.state_outputs(s, params)}


def stamp_ns(msg: Any) -> int:
    return msg.header.stamp.sec * 10 ** 9 + msg.header.stamp.nanosec


# ------------------------------------------------------------------------------- the table

def test_every_output_of_the_table_has_its_builder_in_its_order() -> None:
    rows = [t for t in interface.by_role(interface.Role.OUTPUT) if t.name != 'origin']
    assert list(outputs.STATE_OUTPUTS) == [t.name for t in rows]
    s = a_state([1.0, 0.0, 0.0, 0.0])
    assert list(built(s)) == [t.name for t in rows if not t.water_only]
    assert list(built(s, WATER)) == [t.name for t in rows]


# ------------------------------------------------------------------------------- odometry

@settings(max_examples=30, deadline=None)
@given(rotations)
def test_odometry_against_scipy(rot):
    x, y, z, w = rot.as_quat()
    s = a_state([w, x, y, z])
    out = built(s)
    odom, local, ned = out['odometry'], out['odometry/local'], out['odometry/ned']
    assert odom.header.frame_id == 'map' and odom.child_frame_id == 'base_link'
    assert local.header.frame_id == 'odom' and local.child_frame_id == 'base_link'
    assert ned.header.frame_id == 'map_ned' and ned.child_frame_id == 'base_link_frd'
    assert stamp_ns(odom) == stamp_ns(local) == stamp_ns(ned) == s.stamp_ns
    o = odom.pose.pose.orientation
    np.testing.assert_allclose(Rotation.from_quat([o.x, o.y, o.z, o.w]).as_matrix(),
                               W @ r_nb(s.q) @ B, atol=1e-12)
    pos = odom.pose.pose.position
    np.testing.assert_allclose([pos.x, pos.y, pos.z], W @ s.p)
    lp = local.pose.pose.position
    np.testing.assert_allclose([lp.x, lp.y, lp.z], W @ s.p_local)
    for msg in (odom, local):
        lin, ang = msg.twist.twist.linear, msg.twist.twist.angular
        np.testing.assert_allclose([lin.x, lin.y, lin.z], B @ s.nu)
        np.testing.assert_allclose([ang.x, ang.y, ang.z], B @ s.omega)
        twist_cov = msg.twist.covariance.reshape(6, 6)
        np.testing.assert_allclose(twist_cov[0:3, 0:3], B @ s.cov_nu @ B.T)
        np.testing.assert_allclose(twist_cov[3:6, 3:6], B @ s.cov_omega @ B.T)
        np.testing.assert_array_equal(twist_cov[0:3, 3:6], 0.0)
    pose_cov = odom.pose.covariance.reshape(6, 6)
    np.testing.assert_allclose(pose_cov[0:3, 0:3], W @ s.cov_p @ W.T)
    np.testing.assert_allclose(pose_cov[3:6, 3:6], B @ s.cov_att @ B.T)
    np.testing.assert_allclose(local.pose.covariance.reshape(6, 6)[0:3, 0:3],
                               W @ s.cov_p_local @ W.T)
    # The NED/FRD message is Fossen's form, the same numbers.
    qn = ned.pose.pose.orientation
    np.testing.assert_allclose(Rotation.from_quat([qn.x, qn.y, qn.z, qn.w]).as_matrix(),
                               r_nb(s.q), atol=1e-12)
    np.testing.assert_allclose([ned.pose.pose.position.x, ned.pose.pose.position.y,
                                ned.pose.pose.position.z], s.p)
    np.testing.assert_allclose(ned.pose.covariance.reshape(6, 6)[0:3, 0:3], s.cov_p)
    np.testing.assert_allclose(ned.twist.covariance.reshape(6, 6)[3:6, 3:6], s.cov_omega)


# ------------------------------------------------------------------------------- the others

def test_vectors_fix_and_origin():
    s = a_state([1.0, 0.0, 0.0, 0.0])
    out = built(s, WATER)
    cs = out['course_sideslip']
    assert (cs.vector.x, cs.vector.y, cs.vector.z) == (0.1, -0.2, 0.05)
    assert cs.header.frame_id == 'base_link' and stamp_ns(cs) == s.stamp_ns
    cur = out['current']
    assert (cur.vector.x, cur.vector.y, cur.vector.z) == (-0.1, 0.3, 0.0)   # ENU
    assert cur.header.frame_id == 'map'
    flow = out['relative_flow']
    assert (flow.vector.x, flow.vector.y, flow.vector.z) == (1.5, 0.04, -0.01)
    fix = out['fix/filtered']
    assert fix.latitude == pytest.approx(math.degrees(1.0)) and fix.altitude == 33.0
    assert fix.position_covariance_type == NavSatFix.COVARIANCE_TYPE_KNOWN
    assert fix.status.status == 0 and fix.header.frame_id == 'base_link'
    np.testing.assert_allclose(fix.position_covariance.reshape(3, 3), W @ s.cov_p @ W.T)
    dead = built(replace(s, mode=Mode.DEAD_RECKONING))['fix/filtered']
    assert dead.status.status == -1                      # no GNSS fix: STATUS_NO_FIX
    nothing = built(replace(s, current=None, relative_flow=None), WATER)
    assert nothing['current'].vector.x == nothing['relative_flow'].vector.x == 0.0
    origin = decode(outputs.origin((0.5, -0.25, 12.0), 7, PARAMS), 'sensor_msgs/msg/NavSatFix')
    assert origin.latitude == pytest.approx(math.degrees(0.5))
    assert origin.longitude == pytest.approx(math.degrees(-0.25))
    assert origin.altitude == 12.0 and origin.header.frame_id == 'map'
    assert origin.position_covariance_type == NavSatFix.COVARIANCE_TYPE_UNKNOWN
    assert stamp_ns(origin) == 7


def test_calibration_output_is_the_calibration_in_use():
    """Calibration: x = log scale, y = leeway, z = heading offset (rad); 1, 0, 0 if none."""
    s = a_state([1.0, 0.0, 0.0, 0.0])
    none = built(s, WATER)['calibration']
    assert none.header.frame_id == PARAMS.base_frame
    assert (none.vector.x, none.vector.y, none.vector.z) == (1.0, 0.0, 0.0)
    learnt = replace(s, calibration=Calibration(
        log_scale=Estimate(0.9, 0.01), leeway=Estimate(0.05, 0.02), turn_drift=Estimate(-8.0, 2.0),
        heading_offset=Estimate(-0.2, 0.01), declination=0.1))
    msg = built(learnt)['calibration']
    assert (msg.vector.x, msg.vector.y, msg.vector.z) == (0.9, 0.05, -0.2)


frame_names = st.from_regex(r'\A[a-h][a-h_]{0,8}\Z')  # 1 to 9 characters: every padding


@settings(max_examples=40, deadline=None)
@given(rotations, frame_names, frame_names, frame_names, frame_names,
       st.integers(0, 2 ** 31 - 1), st.integers(0, 999_999_999), st.booleans())
def test_every_frame_length_and_stamp_reads_back(rot, map_frame, odom_frame, base_frame,
                                                 earth_frame, sec, nanosec, water):
    """Frame names of every length move the alignment of everything after them."""
    x, y, z, w = rot.as_quat()
    s = a_state([w, x, y, z], stamp_ns=sec * 10 ** 9 + nanosec)
    params = NavigatorParams.from_flat({'map_frame': map_frame, 'odom_frame': odom_frame,
                                        'base_frame': base_frame, 'earth_frame': earth_frame,
                                        'velocity.reference': 'water' if water else 'ground'})
    for name, msg in built(s, params).items():
        assert stamp_ns(msg) == s.stamp_ns, name
        assert msg.header.frame_id in (map_frame, odom_frame, base_frame,
                                       map_frame + '_ned'), name
    for transforms in (tf.dynamic_transforms(s, params),
                       tf.static_transforms(s.origin, s.stamp_ns, params)):
        msg = decode(cdr.tf_message(transforms), 'tf2_msgs/msg/TFMessage')
        assert [(t.header.frame_id, t.child_frame_id) for t in msg.transforms] == [
            (parent, child) for _, parent, child, _, _ in transforms]
        assert all(stamp_ns(t) == s.stamp_ns for t in msg.transforms)


# ------------------------------------------------------------------------------- TF

def _matrix(transform: Any) -> np.ndarray:
    t, r = transform.transform.translation, transform.transform.rotation
    m = np.eye(4)
    m[0:3, 0:3] = Rotation.from_quat([r.x, r.y, r.z, r.w]).as_matrix()
    m[0:3, 3] = [t.x, t.y, t.z]
    return m


def test_transforms_compose_to_the_fused_pose():
    rot = Rotation.from_euler('ZYX', [0.3, 0.1, -0.05])
    x, y, z, w = rot.as_quat()
    s = a_state([w, x, y, z])
    msg = decode(cdr.tf_message(tf.dynamic_transforms(s, PARAMS)), 'tf2_msgs/msg/TFMessage')
    map_odom, odom_base = msg.transforms
    assert (map_odom.header.frame_id, map_odom.child_frame_id) == ('map', 'odom')
    assert (odom_base.header.frame_id, odom_base.child_frame_id) == ('odom', 'base_link')
    fused = _matrix(map_odom) @ _matrix(odom_base)
    odom = built(s)['odometry']
    pos, o = odom.pose.pose.position, odom.pose.pose.orientation
    np.testing.assert_allclose(fused[0:3, 3], [pos.x, pos.y, pos.z], atol=1e-12)
    np.testing.assert_allclose(fused[0:3, 0:3],
                               Rotation.from_quat([o.x, o.y, o.z, o.w]).as_matrix(), atol=1e-12)


def test_static_transforms_earth_to_map_and_the_ned_frd_twins():
    pymap3d = pytest.importorskip('pymap3d')
    lat, lon, h = math.radians(59.9), math.radians(10.7), 40.0
    msg = decode(cdr.tf_message(tf.static_transforms((lat, lon, h), 0, PARAMS)),
                 'tf2_msgs/msg/TFMessage')
    earth, ned, frd = msg.transforms
    assert (earth.header.frame_id, earth.child_frame_id) == ('earth', 'map')
    t, r = earth.transform.translation, earth.transform.rotation
    np.testing.assert_allclose([t.x, t.y, t.z], pymap3d.geodetic2ecef(59.9, 10.7, 40.0),
                               atol=1e-6)
    rot = Rotation.from_quat([r.x, r.y, r.z, r.w])
    for enu in ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]):
        np.testing.assert_allclose(rot.apply(enu), pymap3d.enu2uvw(*enu, 59.9, 10.7),
                                   atol=1e-12)
    assert (ned.header.frame_id, ned.child_frame_id) == ('map', 'map_ned')
    np.testing.assert_allclose(_matrix(ned)[0:3, 0:3].T, W, atol=1e-15)   # ENU -> NED axes
    assert (frd.header.frame_id, frd.child_frame_id) == ('base_link', 'base_link_frd')
    np.testing.assert_allclose(_matrix(frd)[0:3, 0:3], B, atol=1e-15)
    # Before the origin, the twins alone; tf.publish chooses.
    assert len(tf.static_transforms(None, 0, PARAMS)) == 2
    none = NavigatorParams.from_flat({'tf.publish': ['none']})
    assert tf.static_transforms((lat, lon, h), 0, none) == []


def test_tf_is_sent_once_per_stamp_and_statics_when_they_change():
    s = a_state([1.0, 0.0, 0.0, 0.0])
    output = tf.TfOutput()
    assert output.dynamic(s, PARAMS) is not None
    assert output.dynamic(s, PARAMS) is None                       # the same stamp: nothing
    assert output.dynamic(replace(s, stamp_ns=s.stamp_ns + 1), PARAMS) is not None
    origin = (1.0, 0.2, 30.0)
    assert output.static(origin, 5, PARAMS) is not None
    assert output.static(origin, 6, PARAMS) is None                # the same set: nothing
    assert output.static((1.0, 0.2, 31.0), 7, PARAMS) is not None


def test_estimator_state_through_the_outputs_and_inputs_round_trip():
    """An estimator state turned into NavSatFix and back gives the same position."""
    params = NavigatorParams.from_flat({'origin': [59.9, 10.7, 40.0], 'motion': 'free'})
    est = Estimator(filter_config(params))
    lat, lon, h = geodesy.ned2llh((100.0, -50.0, 2.0), math.radians(59.9),
                                  math.radians(10.7), 40.0)
    est.fix(GnssFix(10 ** 18, lat, lon, h, np.eye(3)))
    msg = built(est.state(), params)['fix/filtered']
    back = inputs.fix_from_msg(msg, params)
    assert back.lat == pytest.approx(lat, abs=1e-14) and back.lon == pytest.approx(lon, abs=1e-14)
    assert back.height == pytest.approx(h, abs=1e-6)


# ------------------------------------------------------------------------------- diagnostics

#: Any text but NUL (a C string ends there: rclpy reads 'a\x00b' back as 'a'); '±' and others.
#: No lone surrogates (category Cs, e.g. '\ud800'): they have no UTF-8, so no ROS string holds
#: one (a Python str can).
_NO_NUL = st.characters(blacklist_characters='\x00', blacklist_categories=('Cs',))


@settings(max_examples=30, deadline=None)
@given(st.lists(st.tuples(st.text(_NO_NUL, max_size=7), st.text(_NO_NUL, max_size=7)),
                max_size=5),
       st.text(_NO_NUL, max_size=9), st.sampled_from([0, 1, 2]), st.integers(0, 3))
def test_diagnostics_read_back(values, summary, level, statuses):
    """Every string length moves the alignment; both readers read the same array back."""
    array = [cdr.Status(level, f'navigator: task {i}', summary, tuple(values))
             for i in range(statuses)]
    msg = decode(cdr.diagnostic_array(123_456_789_012, array),
                 'diagnostic_msgs/msg/DiagnosticArray')
    assert stamp_ns(msg) == 123_456_789_012 and len(msg.status) == statuses
    for status, expected in zip(msg.status, array):
        assert status.level == bytes((level,)) and status.level in (
            DiagnosticStatus.OK, DiagnosticStatus.WARN, DiagnosticStatus.ERROR)
        assert (status.name, status.message, status.hardware_id) == (
            expected.name, summary, 'vessel_kinematics')
        assert [(kv.key, kv.value) for kv in status.values] == values

"""
The inputs: sensor messages to the estimator's records, checked with scipy; the Imu CDR view.

No DDS: rclpy message classes are plain Python objects, built here. Every frame conversion is
checked against scipy's Rotation with the REP-103 axes written out independently:
ENU (x east, y north, z up) vs NED, FLU (x fwd, y left, z up) vs FRD.
"""

from __future__ import annotations

import math

from geometry_msgs.msg import TwistStamped, TwistWithCovarianceStamped
from hypothesis import given, settings, strategies as st
from nav_msgs.msg import Odometry
import numpy as np
import pytest
from reference import r_nb, rotations
from scipy.spatial.transform import Rotation
from sensor_msgs.msg import Imu, NavSatFix, NavSatStatus
from vessel_kinematics.core import frames
from vessel_kinematics.estimation import BodyVelocity, GnssFix, ImuSample, Reason, Rejection
from vessel_kinematics.ros import imu_cdr, inputs, interface
from vessel_kinematics.ros.params import NavigatorParams

# NED <-> ENU and FRD <-> FLU written out here, independently of vessel_kinematics.core.frames.
W = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
B = np.diag([1.0, -1.0, -1.0])
PARAMS = NavigatorParams()
# The husky's imu_link in base_link as [roll, pitch, yaw]. robot_localization's test launch
# publishes it with `static_transform_publisher 0 -0.3 0.52 -1.570796327 0 1.570796327
# base_link imu_link`, whose angle order is yaw, pitch, roll: yaw = -pi/2, roll = +pi/2 (read
# as roll -pi/2, yaw pi/2 the robot comes out upside down: see the bag test below).
HUSKY_MOUNT = (math.pi / 2, 0.0, -math.pi / 2)


def stamp(msg, t: float):
    """Set the header time of a message (seconds) and return the message."""
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(int(round(t * 1e9)), 10 ** 9)
    return msg


def imu_msg(rot_enu_flu: Rotation | None, omega_flu=None, t: float = 100.0,
            o_cov=None, w_cov=None) -> Imu:
    """Return an Imu with orientation (FLU -> ENU) and rate (FLU, rad/s)."""
    msg = stamp(Imu(), t)
    if rot_enu_flu is None:
        msg.orientation_covariance[0] = -1.0
    else:
        x, y, z, w = rot_enu_flu.as_quat()
        msg.orientation.x, msg.orientation.y, msg.orientation.z, msg.orientation.w = x, y, z, w
        if o_cov is not None:
            msg.orientation_covariance = np.asarray(o_cov, dtype=float).reshape(9)
    if omega_flu is None:
        msg.angular_velocity_covariance[0] = -1.0
    else:
        av = msg.angular_velocity
        av.x, av.y, av.z = (float(c) for c in omega_flu)
        if w_cov is not None:
            msg.angular_velocity_covariance = np.asarray(w_cov, dtype=float).reshape(9)
    return msg


# ------------------------------------------------------------------------------- time

@given(st.integers(0, 2 ** 62))
def test_stamp_round_trip(ns):
    assert frames.stamp_to_ns(*frames.ns_to_stamp(ns)) == ns


# ------------------------------------------------------------------------------- fix

def nav_fix(lat=59.9, lon=10.7, alt=40.0, cov=None, cov_type=2, status=0, t=100.0):
    """Return a NavSatFix."""
    msg = stamp(NavSatFix(), t)
    msg.status.status = status
    msg.latitude, msg.longitude, msg.altitude = lat, lon, alt
    if cov is not None:
        msg.position_covariance = np.asarray(cov, dtype=float).reshape(9)
    msg.position_covariance_type = cov_type
    return msg


def test_fix_conversion_and_covariance_enu_to_ned():
    cov_enu = np.array([[4.0, 0.5, 0.1], [0.5, 9.0, 0.2], [0.1, 0.2, 16.0]])
    out = inputs.fix_from_msg(nav_fix(cov=cov_enu), PARAMS)
    assert isinstance(out, GnssFix)
    assert out.stamp_ns == 100 * 10 ** 9
    assert out.lat == pytest.approx(math.radians(59.9), abs=1e-15)
    assert out.lon == pytest.approx(math.radians(10.7), abs=1e-15)
    np.testing.assert_allclose(out.cov_ned, W @ cov_enu @ W.T)
    assert out.cov_ned[0, 0] == 9.0 and out.cov_ned[1, 1] == 4.0   # north from ENU y


@pytest.mark.parametrize('cov, cov_type', [(None, 0), (np.eye(3) * 7.0, 0), (np.zeros(9), 2)])
def test_fix_unknown_covariance_gets_default_sigma(cov, cov_type):
    params = NavigatorParams.from_flat({'gnss.default_sigma': 3.0})
    out = inputs.fix_from_msg(nav_fix(cov=cov, cov_type=cov_type), params)
    np.testing.assert_allclose(out.cov_ned, np.eye(3) * 9.0)


def test_fix_nan_altitude_is_horizontal_only():
    out = inputs.fix_from_msg(nav_fix(alt=math.nan), PARAMS)
    assert isinstance(out, GnssFix) and math.isnan(out.height)


@pytest.mark.parametrize('kwargs, reason', [
    ({'status': NavSatStatus.STATUS_NO_FIX}, 'no_fix'),
    ({'lat': math.nan}, 'nan_field'),
    ({'lon': math.inf}, 'nan_field'),
    ({'alt': -math.inf}, 'nan_field'),
    ({'lat': 90.5}, 'lat_out_of_range'),
    ({'lon': -180.01}, 'lat_out_of_range'),
    ({'cov': [math.nan] * 9}, 'nan_field'),
    ({'cov': np.diag([-1.0, 1.0, 1.0])}, 'bad_covariance'),
])
def test_fix_rejections(kwargs, reason):
    out = inputs.fix_from_msg(nav_fix(**kwargs), PARAMS)
    assert isinstance(out, Rejection) and out.reason == reason


# ------------------------------------------------------------------------------- imu

@settings(max_examples=50, deadline=None)
@given(rotations)
def test_imu_orientation_to_q_nb_against_scipy(rot_enu_flu):
    """R_nb = A_W R_enu_flu A_B, with the axes written out here."""
    out = inputs.imu_from_msg(imu_msg(rot_enu_flu), PARAMS)
    assert isinstance(out, ImuSample)
    np.testing.assert_allclose(r_nb(out.q_nb), W @ rot_enu_flu.as_matrix() @ B, atol=1e-12)
    assert out.q_nb[0] >= 0.0


def test_imu_heading_north_is_ros_yaw_90():
    out = inputs.imu_from_msg(imu_msg(Rotation.from_euler('z', 90, degrees=True)), PARAMS)
    np.testing.assert_allclose(out.q_nb, [1.0, 0.0, 0.0, 0.0], atol=1e-12)


@settings(max_examples=50, deadline=None)
@given(rotations, st.lists(st.floats(-2.0, 2.0), min_size=3, max_size=3),
       st.lists(st.floats(-3.2, 3.2), min_size=3, max_size=3), st.floats(-3.0, 3.0))
def test_imu_mounting_and_yaw_offset_against_scipy(rot_base, omega_base, rpy, yaw_offset):
    """An IMU mounted at rpy in the base reports q_imu = q_base (x) q_mount; undo it."""
    mount = Rotation.from_euler('ZYX', [rpy[2], rpy[1], rpy[0]])   # Rz(yaw) Ry(pitch) Rx(roll)
    params = NavigatorParams.from_flat({'imu.mounting_rpy': list(rpy),
                                        'imu.yaw_offset': yaw_offset})
    rot_imu = rot_base * mount
    omega_imu = mount.inv().apply(omega_base)
    out = inputs.imu_from_msg(imu_msg(rot_imu, omega_imu), params)
    expected = Rotation.from_euler('z', yaw_offset) * rot_base
    np.testing.assert_allclose(r_nb(out.q_nb), W @ expected.as_matrix() @ B, atol=1e-9)
    np.testing.assert_allclose(out.omega_b, B @ np.array(omega_base), atol=1e-12)


def test_husky_mounting_is_gravity_free():
    """
    The husky's IMU (roll pi/2, yaw -pi/2 in base_link) has the world's up on its +y axis.

    A level base heading east: the IMU's own orientation has up along IMU +y (where its
    accelerometer reads +g); after the mounting correction the vessel is level (roll = pitch =
    0) and heads east (psi = 90 deg); a yaw rate about the base's up axis comes out as r < 0
    in FRD.
    """
    mount = Rotation.from_euler('ZYX', [HUSKY_MOUNT[2], 0.0, HUSKY_MOUNT[0]])
    rot_imu = Rotation.identity() * mount       # base: level, ROS yaw 0 = east
    np.testing.assert_allclose(rot_imu.inv().apply([0.0, 0.0, 1.0]), [0.0, 1.0, 0.0],
                               atol=1e-12)
    params = NavigatorParams.from_flat({'imu.mounting_rpy': list(HUSKY_MOUNT)})
    out = inputs.imu_from_msg(imu_msg(rot_imu, [0.0, 0.0, 0.0]), params)
    phi, theta, psi = Rotation.from_matrix(r_nb(out.q_nb)).as_euler('ZYX')[::-1]
    assert phi == pytest.approx(0.0, abs=1e-12) and theta == pytest.approx(0.0, abs=1e-12)
    assert psi == pytest.approx(math.pi / 2, abs=1e-12)
    omega_imu = mount.inv().apply([0.0, 0.0, 0.2])
    np.testing.assert_allclose(omega_imu, [0.0, 0.2, 0.0], atol=1e-12)   # on the IMU's y
    out = inputs.imu_from_msg(imu_msg(rot_imu, omega_imu), params)
    np.testing.assert_allclose(out.omega_b, [0.0, 0.0, -0.2], atol=1e-12)


def test_husky_bag_orientation_is_level_after_mounting(shared_data):
    """
    On the real bag, the mounted IMU gives a level robot and its specific force points up.

    With the mounting read the other way round (roll -pi/2, yaw pi/2) the roll comes out as
    180 deg: this test tells the two apart.
    """
    rosbags = pytest.importorskip('rosbags.highlevel')
    bag = shared_data / 'husky_gnss_imu_odom.bag'
    if not bag.exists():
        pytest.skip('husky bag not found')
    params = NavigatorParams.from_flat({'imu.mounting_rpy': list(HUSKY_MOUNT)})
    mount = Rotation.from_euler('ZYX', [HUSKY_MOUNT[2], 0.0, HUSKY_MOUNT[0]])
    rolls, pitches, ups = [], [], []
    with rosbags.AnyReader([bag]) as reader:
        conns = [c for c in reader.connections if c.topic == '/imu/data']
        for k, (conn, _, raw) in enumerate(reader.messages(connections=conns)):
            if k >= 200:
                break
            msg = reader.deserialize(raw, conn.msgtype)
            out = inputs.imu_from_msg(msg, params)
            assert isinstance(out, ImuSample)
            phi, theta, _ = Rotation.from_matrix(r_nb(out.q_nb)).as_euler('ZYX')[::-1]
            rolls.append(phi)
            pitches.append(theta)
            a = msg.linear_acceleration
            ups.append(mount.apply([a.x, a.y, a.z]))
    assert max(abs(np.degrees(rolls))) < 5.0 and max(abs(np.degrees(pitches))) < 5.0
    f = np.mean(ups, axis=0)
    assert f[2] > 9.0 and abs(f[0]) < 1.0 and abs(f[1]) < 1.0   # specific force up in FLU


def test_imu_covariances_rotated_and_defaults():
    o_cov = np.diag([0.01, 0.02, 0.03])
    w_cov = np.diag([1e-4, 2e-4, 3e-4])
    out = inputs.imu_from_msg(imu_msg(Rotation.identity(), [0, 0, 0], o_cov=o_cov,
                                      w_cov=w_cov), PARAMS)
    np.testing.assert_allclose(out.att_cov, B @ o_cov @ B)
    np.testing.assert_allclose(out.omega_cov, B @ w_cov @ B)
    out = inputs.imu_from_msg(imu_msg(Rotation.identity(), [0, 0, 0]), PARAMS)
    assert out.att_cov is None and out.omega_cov is None    # unknown: the estimator's default


def test_imu_absent_fields():
    out = inputs.imu_from_msg(imu_msg(None, [0.0, 0.0, 0.1]), PARAMS)
    assert out.q_nb is None and out.omega_b is not None
    out = inputs.imu_from_msg(imu_msg(Rotation.identity(), None), PARAMS)
    assert out.q_nb is not None and out.omega_b is None
    params = NavigatorParams.from_flat({'imu.use_orientation': False})
    out = inputs.imu_from_msg(imu_msg(Rotation.identity(), [0.0, 0.0, 0.1]), params)
    assert out.q_nb is None
    out = inputs.imu_from_msg(imu_msg(None, None), PARAMS)
    assert isinstance(out, Rejection) and out.reason == 'no_data'


def test_imu_quaternion_checks():
    msg = imu_msg(Rotation.identity(), [0.0, 0.0, 0.0])
    msg.orientation.w = 0.0
    assert inputs.imu_from_msg(msg, PARAMS).reason == 'zero_quaternion'
    msg.orientation.w = 1.01
    assert inputs.imu_from_msg(msg, PARAMS).reason == 'non_unit_quaternion'
    msg.orientation.w = 1.0005     # small deviation: normalised
    out = inputs.imu_from_msg(msg, PARAMS)
    assert np.linalg.norm(out.q_nb) == pytest.approx(1.0, abs=1e-15)
    msg.orientation.w = math.nan
    assert inputs.imu_from_msg(msg, PARAMS).reason == 'nan_field'
    msg = imu_msg(None, [0.0, math.inf, 0.0])
    assert inputs.imu_from_msg(msg, PARAMS).reason == 'nan_field'
    # A zero quaternion is fine when the orientation is not used.
    msg = imu_msg(Rotation.identity(), [0.0, 0.0, 0.0])
    msg.orientation.w = 0.0
    params = NavigatorParams.from_flat({'imu.use_orientation': False})
    assert isinstance(inputs.imu_from_msg(msg, params), ImuSample)


# ------------------------------------------------------------------------------- velocity

def test_velocity_types_flu_to_frd():
    for source, cls in (('twist_with_covariance', TwistWithCovarianceStamped),
                        ('twist', TwistStamped), ('odometry', Odometry)):
        params = NavigatorParams.from_flat({'velocity.source': source,
                                            'velocity.default_sigma': 0.2})
        msg = stamp(cls(), 5.0)
        twist = msg.twist if cls is TwistStamped else msg.twist.twist
        twist.linear.x, twist.linear.y, twist.linear.z = 2.0, 0.5, -0.1
        twist.angular.z = 0.3
        out = inputs.velocity_from_msg(msg, params)
        assert isinstance(out, BodyVelocity)
        np.testing.assert_allclose(out.nu_b, [2.0, -0.5, 0.1])
        np.testing.assert_allclose(out.omega_b, [0.0, 0.0, -0.3])
        np.testing.assert_allclose(out.cov, np.eye(3) * 0.04)    # unknown: default sigma
        assert out.stamp_ns == 5 * 10 ** 9


def test_velocity_covariance_converted_and_rejections():
    msg = stamp(TwistWithCovarianceStamped(), 5.0)
    cov = np.zeros((6, 6))
    cov[0:3, 0:3] = [[0.01, 0.002, 0.0], [0.002, 1e6, 0.0], [0.0, 0.0, 1e6]]
    cov[3:6, 3:6] = np.eye(3) * 1e-4
    msg.twist.covariance = cov.reshape(36)
    out = inputs.velocity_from_msg(msg, PARAMS)
    np.testing.assert_allclose(out.cov, B @ cov[0:3, 0:3] @ B)
    np.testing.assert_allclose(out.omega_cov, np.eye(3) * 1e-4)
    msg.twist.twist.linear.y = math.nan
    assert inputs.velocity_from_msg(msg, PARAMS).reason == 'nan_field'
    msg.twist.twist.linear.y = 0.0
    cov[0, 0] = -1.0
    msg.twist.covariance = cov.reshape(36)
    out = inputs.velocity_from_msg(msg, PARAMS)      # [0] = -1: unknown covariance
    np.testing.assert_allclose(out.cov, np.eye(3) * 0.01)
    cov[0, 0], cov[1, 1] = 0.01, -2.0
    msg.twist.covariance = cov.reshape(36)
    assert inputs.velocity_from_msg(msg, PARAMS).reason == 'bad_covariance'


def test_velocity_types_of_the_interface():
    expected = {'twist_with_covariance': TwistWithCovarianceStamped, 'twist': TwistStamped,
                'odometry': Odometry, 'none': None}
    assert set(interface.VELOCITY_TYPES) == set(expected)
    for source, cls in expected.items():
        msg_type = interface.VELOCITY_TYPES[source]
        assert (None if msg_type is None else interface.message_class(msg_type)) is cls
        if cls is not None:
            assert interface.type_name(cls()) == msg_type


#: Any text but NUL (a C string ends there: rclpy reads 'a\x00b' back as 'a'); '±' and others.
#: No lone surrogates (category Cs, e.g. '\ud800'): they have no UTF-8, so no ROS string holds
#: one (a Python str can).
_NO_NUL = st.characters(blacklist_characters='\x00', blacklist_categories=('Cs',))


# --- The replay's direct Imu reader -----------------------------------------------------------

def _bits(values) -> bytes:
    """Return float64 values as bytes (NaN compares equal to itself, -0.0 differs from 0.0)."""
    return np.array(values, dtype=float).tobytes()


def _fields(sample) -> tuple:
    """Return an ImuSample's or a Rejection's fields, arrays as their bytes."""
    from dataclasses import astuple
    return tuple(f.tobytes() if isinstance(f, np.ndarray) else f for f in astuple(sample))


def _same_imu(view, msg) -> None:
    """Assert a CDR view holds exactly the fields of a deserialised Imu."""
    assert view.header == ((msg.header.stamp.sec, msg.header.stamp.nanosec),
                           msg.header.frame_id)
    o = msg.orientation
    assert _bits(view.orientation) == _bits((o.x, o.y, o.z, o.w))
    for name in ('angular_velocity', 'linear_acceleration'):
        v = getattr(msg, name)
        assert _bits(getattr(view, name)) == _bits((v.x, v.y, v.z))
    for name in ('orientation_covariance', 'angular_velocity_covariance',
                 'linear_acceleration_covariance'):
        assert (np.array(getattr(view, name), dtype=float).tobytes()
                == np.asarray(getattr(msg, name), dtype=float).tobytes())


_ANY_FLOAT = st.floats(allow_nan=True, allow_infinity=True, width=64)


@settings(max_examples=60, deadline=None)
@given(st.text(_NO_NUL, max_size=12), st.integers(-2 ** 31, 2 ** 31 - 1),
       st.integers(0, 2 ** 32 - 1), st.lists(_ANY_FLOAT, min_size=37, max_size=37))
def test_imu_cdr_view_is_rosbags_deserialisation(frame_id, sec, nanosec, values):
    """Every frame_id length (alignment), stamp and float64, NaN and -0.0 included."""
    from rosbags.typesys import get_typestore, Stores
    store = get_typestore(Stores.ROS2_JAZZY)
    t = store.types
    vec = t['geometry_msgs/msg/Vector3']
    msg = t['sensor_msgs/msg/Imu'](
        header=t['std_msgs/msg/Header'](stamp=t['builtin_interfaces/msg/Time'](sec, nanosec),
                                        frame_id=frame_id),
        orientation=t['geometry_msgs/msg/Quaternion'](*values[0:4]),
        orientation_covariance=np.array(values[4:13]), angular_velocity=vec(*values[13:16]),
        angular_velocity_covariance=np.array(values[16:25]),
        linear_acceleration=vec(*values[25:28]),
        linear_acceleration_covariance=np.array(values[28:37]))
    raw = bytes(store.serialize_cdr(msg, 'sensor_msgs/msg/Imu'))
    view = imu_cdr.imu_from_cdr(raw)
    assert view is not None
    _same_imu(view, store.deserialize_cdr(raw, 'sensor_msgs/msg/Imu'))
    assert _bits(imu_cdr.imu_from_cdr(memoryview(raw)).values) == _bits(view.values)
    # What is not exactly a little-endian Imu is left to the generic deserialiser.
    assert imu_cdr.imu_from_cdr(raw[:-1]) is None
    assert imu_cdr.imu_from_cdr(raw + b'\x00' * 8) is None
    assert imu_cdr.imu_from_cdr(b'\x00\x00' + raw[2:]) is None          # big-endian CDR
    assert imu_cdr.imu_from_cdr(raw[:12] + b'\xff\xff\xff\x7f' + raw[16:]) is None


def test_imu_cdr_view_reads_every_imu_of_the_real_bags_as_rosbags(shared_data):
    """The sailboat's and the motorboat's Imu messages, and the results of imu_from_msg."""
    from vessel_kinematics.tools import bags
    checked = 0
    for name in ('sailboat_ijsselmeer', 'motorboat_wide_turn'):
        with bags.reader(shared_data / name) as reader:
            wanted = [c for c in reader.connections if c.msgtype == 'sensor_msgs/msg/Imu']
            assert wanted, name
            for connection, _, raw in reader.messages(connections=wanted):
                msg = reader.deserialize(raw, connection.msgtype)
                view = imu_cdr.imu_from_cdr(raw)
                _same_imu(view, msg)
                assert _fields(inputs.imu_from_msg(view, PARAMS)) == _fields(
                    inputs.imu_from_msg(msg, PARAMS))
                checked += 1
    assert checked > 3000


def test_imu_cdr_view_converts_as_the_message_rclpy_deserialises():
    """imu_from_msg reads the view and the rclpy message alike, rejections included."""
    from rclpy.serialization import serialize_message
    rot = Rotation.from_euler('zyx', [0.4, -0.1, 0.05])
    cases = [imu_msg(rot, [0.01, -0.02, 0.3], o_cov=np.eye(3) * 1e-4, w_cov=np.eye(3) * 1e-6),
             imu_msg(None, [0.0, 0.0, 0.1]), imu_msg(rot, None), imu_msg(None, None),
             imu_msg(rot, [np.nan, 0.0, 0.0]), imu_msg(rot, [30.0, 0.0, 0.0])]
    cases[-1].header.frame_id = 'imu_link'
    for msg in cases:
        view = imu_cdr.imu_from_cdr(serialize_message(msg))
        assert view is not None and view.header.frame_id == msg.header.frame_id
        assert _fields(inputs.imu_from_msg(view, PARAMS)) == _fields(
            inputs.imu_from_msg(msg, PARAMS))


def test_a_raw_imu_payload_is_read_directly_else_by_rclpy_else_refused():
    """imu_from_raw (the node's raw imu subscription): the CDR view, rclpy's message, a Reason."""
    from rclpy.serialization import serialize_message
    msg = imu_msg(Rotation.from_euler('zyx', [0.4, -0.1, 0.05]), [0.01, -0.02, 0.3],
                  o_cov=np.eye(3) * 1e-4, w_cov=np.eye(3) * 1e-6)
    raw = serialize_message(msg)
    direct = imu_cdr.imu_from_raw(raw)
    assert type(direct) is imu_cdr.ImuCdr
    expected = _fields(inputs.imu_from_msg(msg, PARAMS))
    assert _fields(inputs.imu_from_msg(direct, PARAMS)) == expected
    # Trailing bytes: not the plain size the view takes, but rclpy's deserialiser reads it.
    padded = imu_cdr.imu_from_raw(raw + b'\x00' * 8)
    assert type(padded) is Imu
    expected = _fields(inputs.imu_from_msg(msg, PARAMS))
    assert _fields(inputs.imu_from_msg(padded, PARAMS)) == expected
    for garbage in (b'', b'garbage!', raw[:40], raw[:12] + b'\xff\xff\xff\x7f' + raw[16:]):
        refused = imu_cdr.imu_from_raw(garbage)
        assert isinstance(refused, Rejection) and refused.reason == Reason.CDR_ERROR, garbage
        assert f'{len(garbage)} bytes' in refused.detail


def test_the_pipeline_counts_a_payload_its_driver_could_not_decode():
    """A Rejection handed in for a message is counted by its reason, and changes nothing else."""
    from vessel_kinematics.ros.pipeline import Pipeline
    pipe = Pipeline(PARAMS)
    result = pipe.handle('imu', imu_cdr.imu_from_raw(b'garbage!'), 0)
    assert result.rejected == 'cdr_error' and 'does not deserialise' in result.detail
    assert {k: v for k, v in pipe.counts.items() if v} == {'imu/cdr_error': 1}
    assert not pipe.estimator.ready and pipe.estimator.t is None

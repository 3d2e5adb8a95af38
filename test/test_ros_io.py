"""
The ROS edge: messages to measurements and the state back to messages, checked with scipy.

No DDS: rclpy message classes are plain Python objects, built here. Every frame conversion is
checked against scipy's Rotation with the REP-103 axes written out independently:
ENU (x east, y north, z up) vs NED, FLU (x fwd, y left, z up) vs FRD.
"""

from __future__ import annotations

from dataclasses import replace
import math

from geometry_msgs.msg import TwistStamped, TwistWithCovarianceStamped
from hypothesis import given, settings, strategies as st
from nav_msgs.msg import Odometry
import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from sensor_msgs.msg import Imu, NavSatFix, NavSatStatus
from vessel_kinematics.core import geodesy
from vessel_kinematics.estimation import (BodyVelocity, Calibration, Estimate, Estimator,
                                          GnssFix, ImuSample, NavState, Reason, Rejection)
from vessel_kinematics.ros import interface, ros_io
from vessel_kinematics.ros.params import filter_config, NavigatorParams

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


def r_nb(q_nb) -> np.ndarray:
    """Return R_b^n of a scalar-first q_nb through scipy."""
    w, x, y, z = q_nb
    return Rotation.from_quat([x, y, z, w]).as_matrix()


rotations = st.builds(lambda v: Rotation.from_rotvec(v),
                      st.lists(st.floats(-3.0, 3.0), min_size=3, max_size=3).map(np.array))


# ------------------------------------------------------------------------------- time

@given(st.integers(0, 2 ** 62))
def test_stamp_round_trip(ns):
    assert ros_io.stamp_to_ns(ros_io.ns_to_stamp(ns)) == ns


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
    out = ros_io.fix_from_msg(nav_fix(cov=cov_enu), PARAMS)
    assert isinstance(out, GnssFix)
    assert out.stamp_ns == 100 * 10 ** 9
    assert out.lat == pytest.approx(math.radians(59.9), abs=1e-15)
    assert out.lon == pytest.approx(math.radians(10.7), abs=1e-15)
    np.testing.assert_allclose(out.cov_ned, W @ cov_enu @ W.T)
    assert out.cov_ned[0, 0] == 9.0 and out.cov_ned[1, 1] == 4.0   # north from ENU y


@pytest.mark.parametrize('cov, cov_type', [(None, 0), (np.eye(3) * 7.0, 0), (np.zeros(9), 2)])
def test_fix_unknown_covariance_gets_default_sigma(cov, cov_type):
    params = NavigatorParams.from_flat({'gnss.default_sigma': 3.0})
    out = ros_io.fix_from_msg(nav_fix(cov=cov, cov_type=cov_type), params)
    np.testing.assert_allclose(out.cov_ned, np.eye(3) * 9.0)


def test_fix_nan_altitude_is_horizontal_only():
    out = ros_io.fix_from_msg(nav_fix(alt=math.nan), PARAMS)
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
    out = ros_io.fix_from_msg(nav_fix(**kwargs), PARAMS)
    assert isinstance(out, Rejection) and out.reason == reason


# ------------------------------------------------------------------------------- imu

@settings(max_examples=50, deadline=None)
@given(rotations)
def test_imu_orientation_to_q_nb_against_scipy(rot_enu_flu):
    """R_nb = A_W R_enu_flu A_B, with the axes written out here."""
    out = ros_io.imu_from_msg(imu_msg(rot_enu_flu), PARAMS)
    assert isinstance(out, ImuSample)
    np.testing.assert_allclose(r_nb(out.q_nb), W @ rot_enu_flu.as_matrix() @ B, atol=1e-12)
    assert out.q_nb[0] >= 0.0


def test_imu_heading_north_is_ros_yaw_90():
    out = ros_io.imu_from_msg(imu_msg(Rotation.from_euler('z', 90, degrees=True)), PARAMS)
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
    out = ros_io.imu_from_msg(imu_msg(rot_imu, omega_imu), params)
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
    out = ros_io.imu_from_msg(imu_msg(rot_imu, [0.0, 0.0, 0.0]), params)
    phi, theta, psi = Rotation.from_matrix(r_nb(out.q_nb)).as_euler('ZYX')[::-1]
    assert phi == pytest.approx(0.0, abs=1e-12) and theta == pytest.approx(0.0, abs=1e-12)
    assert psi == pytest.approx(math.pi / 2, abs=1e-12)
    omega_imu = mount.inv().apply([0.0, 0.0, 0.2])
    np.testing.assert_allclose(omega_imu, [0.0, 0.2, 0.0], atol=1e-12)   # on the IMU's y
    out = ros_io.imu_from_msg(imu_msg(rot_imu, omega_imu), params)
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
            out = ros_io.imu_from_msg(msg, params)
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
    out = ros_io.imu_from_msg(imu_msg(Rotation.identity(), [0, 0, 0], o_cov=o_cov,
                                      w_cov=w_cov), PARAMS)
    np.testing.assert_allclose(out.att_cov, B @ o_cov @ B)
    np.testing.assert_allclose(out.omega_cov, B @ w_cov @ B)
    out = ros_io.imu_from_msg(imu_msg(Rotation.identity(), [0, 0, 0]), PARAMS)
    assert out.att_cov is None and out.omega_cov is None    # unknown: the estimator's default


def test_imu_absent_fields():
    out = ros_io.imu_from_msg(imu_msg(None, [0.0, 0.0, 0.1]), PARAMS)
    assert out.q_nb is None and out.omega_b is not None
    out = ros_io.imu_from_msg(imu_msg(Rotation.identity(), None), PARAMS)
    assert out.q_nb is not None and out.omega_b is None
    params = NavigatorParams.from_flat({'imu.use_orientation': False})
    out = ros_io.imu_from_msg(imu_msg(Rotation.identity(), [0.0, 0.0, 0.1]), params)
    assert out.q_nb is None
    out = ros_io.imu_from_msg(imu_msg(None, None), PARAMS)
    assert isinstance(out, Rejection) and out.reason == 'no_data'


def test_imu_quaternion_checks():
    msg = imu_msg(Rotation.identity(), [0.0, 0.0, 0.0])
    msg.orientation.w = 0.0
    assert ros_io.imu_from_msg(msg, PARAMS).reason == 'zero_quaternion'
    msg.orientation.w = 1.01
    assert ros_io.imu_from_msg(msg, PARAMS).reason == 'non_unit_quaternion'
    msg.orientation.w = 1.0005     # small deviation: normalised
    out = ros_io.imu_from_msg(msg, PARAMS)
    assert np.linalg.norm(out.q_nb) == pytest.approx(1.0, abs=1e-15)
    msg.orientation.w = math.nan
    assert ros_io.imu_from_msg(msg, PARAMS).reason == 'nan_field'
    msg = imu_msg(None, [0.0, math.inf, 0.0])
    assert ros_io.imu_from_msg(msg, PARAMS).reason == 'nan_field'
    # A zero quaternion is fine when the orientation is not used.
    msg = imu_msg(Rotation.identity(), [0.0, 0.0, 0.0])
    msg.orientation.w = 0.0
    params = NavigatorParams.from_flat({'imu.use_orientation': False})
    assert isinstance(ros_io.imu_from_msg(msg, params), ImuSample)


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
        out = ros_io.velocity_from_msg(msg, params)
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
    out = ros_io.velocity_from_msg(msg, PARAMS)
    np.testing.assert_allclose(out.cov, B @ cov[0:3, 0:3] @ B)
    np.testing.assert_allclose(out.omega_cov, np.eye(3) * 1e-4)
    msg.twist.twist.linear.y = math.nan
    assert ros_io.velocity_from_msg(msg, PARAMS).reason == 'nan_field'
    msg.twist.twist.linear.y = 0.0
    cov[0, 0] = -1.0
    msg.twist.covariance = cov.reshape(36)
    out = ros_io.velocity_from_msg(msg, PARAMS)      # [0] = -1: unknown covariance
    np.testing.assert_allclose(out.cov, np.eye(3) * 0.01)
    cov[0, 0], cov[1, 1] = 0.01, -2.0
    msg.twist.covariance = cov.reshape(36)
    assert ros_io.velocity_from_msg(msg, PARAMS).reason == 'bad_covariance'


def test_velocity_type_of_pipeline():
    from vessel_kinematics.ros.pipeline import Pipeline
    from vessel_kinematics.ros import interface
    expected = {'twist_with_covariance': TwistWithCovarianceStamped, 'twist': TwistStamped,
                'odometry': Odometry, 'none': None}
    assert set(interface.VELOCITY_TYPES) == set(expected)
    for source, cls in expected.items():
        p = Pipeline(NavigatorParams.from_flat({'velocity.source': source}))
        assert p.velocity_type() is cls


# ------------------------------------------------------------------------------- outputs

def a_state(q_nb, p=(10.0, 20.0, -3.0), nu=(2.0, 0.5, 0.1), omega=(0.01, 0.02, 0.03)):
    """Return a NavState with distinct covariance entries."""
    rng = np.random.default_rng(3)

    def spd(n, scale):
        a = rng.normal(size=(n, n))
        return scale * (a @ a.T + np.eye(n))

    p = np.array(p)
    return NavState(
        stamp_ns=123_456_789_012, mode='fused', origin=(1.0, 0.2, 30.0), p=p,
        q=np.asarray(q_nb, dtype=float), nu=np.array(nu), omega=np.array(omega),
        v_n=r_nb(q_nb) @ np.array(nu), current=np.array([0.3, -0.1, 0.0]),
        p_local=p - np.array([1.0, -2.0, 0.5]), llh=(1.0, 0.2, 33.0), course=0.1,
        sideslip=-0.2, angle_of_attack=0.05, cov_p=spd(3, 1.0), cov_att=spd(3, 1e-3),
        cov_nu=spd(3, 1e-2), cov_omega=spd(3, 1e-4), cov_current=np.eye(3) * 0.01,
        cov_p_local=spd(3, 2.0))


@settings(max_examples=30, deadline=None)
@given(rotations)
def test_odometry_messages_against_scipy(rot):
    w, x, y, z = 0, 0, 0, 0
    x, y, z, w = rot.as_quat()
    s = a_state([w, x, y, z])
    odom, local, ned = ros_io.odometry_msgs(s, PARAMS)
    assert odom.header.frame_id == 'map' and odom.child_frame_id == 'base_link'
    assert local.header.frame_id == 'odom' and local.child_frame_id == 'base_link'
    assert ned.header.frame_id == 'map_ned' and ned.child_frame_id == 'base_link_frd'
    assert ros_io.stamp_to_ns(odom.header.stamp) == s.stamp_ns
    o = odom.pose.pose.orientation
    r_enu_flu = Rotation.from_quat([o.x, o.y, o.z, o.w]).as_matrix()
    np.testing.assert_allclose(r_enu_flu, W @ r_nb(s.q) @ B, atol=1e-12)
    pos = odom.pose.pose.position
    np.testing.assert_allclose([pos.x, pos.y, pos.z], W @ s.p)
    lp = local.pose.pose.position
    np.testing.assert_allclose([lp.x, lp.y, lp.z], W @ s.p_local)
    lin = odom.twist.twist.linear
    np.testing.assert_allclose([lin.x, lin.y, lin.z], B @ s.nu)
    ang = odom.twist.twist.angular
    np.testing.assert_allclose([ang.x, ang.y, ang.z], B @ s.omega)
    pose_cov = odom.pose.covariance.reshape(6, 6)
    np.testing.assert_allclose(pose_cov[0:3, 0:3], W @ s.cov_p @ W.T)
    np.testing.assert_allclose(pose_cov[3:6, 3:6], B @ s.cov_att @ B.T)
    twist_cov = odom.twist.covariance.reshape(6, 6)
    np.testing.assert_allclose(twist_cov[0:3, 0:3], B @ s.cov_nu @ B.T)
    np.testing.assert_allclose(twist_cov[3:6, 3:6], B @ s.cov_omega @ B.T)
    # The NED/FRD message is Fossen's form, the same numbers.
    qn = ned.pose.pose.orientation
    np.testing.assert_allclose(Rotation.from_quat([qn.x, qn.y, qn.z, qn.w]).as_matrix(),
                               r_nb(s.q), atol=1e-12)
    np.testing.assert_allclose([ned.pose.pose.position.x, ned.pose.pose.position.y,
                                ned.pose.pose.position.z], s.p)
    np.testing.assert_allclose(ned.pose.covariance.reshape(6, 6)[0:3, 0:3], s.cov_p)
    np.testing.assert_allclose(local.pose.covariance.reshape(6, 6)[0:3, 0:3],
                               W @ s.cov_p_local @ W.T)


def test_vector_and_fix_messages():
    s = a_state([1.0, 0.0, 0.0, 0.0])
    cs = ros_io.course_sideslip_msg(s, PARAMS)
    assert (cs.vector.x, cs.vector.y, cs.vector.z) == (0.1, -0.2, 0.05)
    assert cs.header.frame_id == 'base_link'
    cur = ros_io.current_msg(s, PARAMS)
    assert (cur.vector.x, cur.vector.y, cur.vector.z) == (-0.1, 0.3, 0.0)   # ENU
    assert cur.header.frame_id == 'map'
    fix = ros_io.filtered_fix_msg(s, PARAMS)
    assert fix.latitude == pytest.approx(math.degrees(1.0)) and fix.altitude == 33.0
    assert fix.position_covariance_type == NavSatFix.COVARIANCE_TYPE_KNOWN
    np.testing.assert_allclose(fix.position_covariance.reshape(3, 3), W @ s.cov_p @ W.T)
    origin = ros_io.origin_msg((0.5, -0.25, 12.0), 7, PARAMS)
    assert origin.latitude == pytest.approx(math.degrees(0.5))
    assert origin.longitude == pytest.approx(math.degrees(-0.25))
    assert origin.altitude == 12.0


def test_transforms_compose_to_the_fused_pose():
    rot = Rotation.from_euler('ZYX', [0.3, 0.1, -0.05])
    x, y, z, w = rot.as_quat()
    s = a_state([w, x, y, z])
    map_odom, odom_base = ros_io.transform_msgs(s, PARAMS)
    assert (map_odom.header.frame_id, map_odom.child_frame_id) == ('map', 'odom')
    assert (odom_base.header.frame_id, odom_base.child_frame_id) == ('odom', 'base_link')

    def matrix(tf):
        t, r = tf.transform.translation, tf.transform.rotation
        m = np.eye(4)
        m[0:3, 0:3] = Rotation.from_quat([r.x, r.y, r.z, r.w]).as_matrix()
        m[0:3, 3] = [t.x, t.y, t.z]
        return m

    fused = matrix(map_odom) @ matrix(odom_base)
    odom, _, _ = ros_io.odometry_msgs(s, PARAMS)
    pos, o = odom.pose.pose.position, odom.pose.pose.orientation
    np.testing.assert_allclose(fused[0:3, 3], [pos.x, pos.y, pos.z], atol=1e-12)
    np.testing.assert_allclose(fused[0:3, 0:3],
                               Rotation.from_quat([o.x, o.y, o.z, o.w]).as_matrix(), atol=1e-12)


def test_static_transform_earth_to_map():
    pymap3d = pytest.importorskip('pymap3d')
    lat, lon, h = math.radians(59.9), math.radians(10.7), 40.0
    (tf,) = ros_io.static_transform_msgs((lat, lon, h), 0, PARAMS)
    assert (tf.header.frame_id, tf.child_frame_id) == ('earth', 'map')
    t, r = tf.transform.translation, tf.transform.rotation
    np.testing.assert_allclose([t.x, t.y, t.z], pymap3d.geodetic2ecef(59.9, 10.7, 40.0),
                               atol=1e-6)
    rot = Rotation.from_quat([r.x, r.y, r.z, r.w])
    for enu in ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]):
        expected = pymap3d.enu2uvw(*enu, 59.9, 10.7)
        np.testing.assert_allclose(rot.apply(enu), expected, atol=1e-12)


def test_estimator_state_through_ros_io_round_trip():
    """An estimator state turned into NavSatFix and back gives the same position."""
    params = NavigatorParams.from_flat({'origin': [59.9, 10.7, 40.0], 'motion': 'free'})
    est = Estimator(filter_config(params))
    lat, lon, h = geodesy.ned2llh((100.0, -50.0, 2.0), math.radians(59.9),
                                  math.radians(10.7), 40.0)
    est.fix(GnssFix(10 ** 18, lat, lon, h, np.eye(3)))
    msg = ros_io.filtered_fix_msg(est.state(), params)
    back = ros_io.fix_from_msg(msg, params)
    assert back.lat == pytest.approx(lat, abs=1e-14) and back.lon == pytest.approx(lon, abs=1e-14)
    assert back.height == pytest.approx(h, abs=1e-6)


def test_state_outputs_are_the_interface_tables_outputs_in_its_order():
    """One builder per output row (but the origin, the pipeline's), built in the table's order."""
    rows = [t for t in interface.by_role(interface.Role.OUTPUT) if t.name != 'origin']
    assert list(ros_io.STATE_OUTPUTS) == [t.name for t in rows]
    s = a_state([1.0, 0.0, 0.0, 0.0])
    for water in (False, True):
        built = ros_io.state_msgs(s, PARAMS, water=water)
        assert [name for name, _ in built] == [t.name for t in rows
                                               if water or not t.water_only]
        for name, msg in built:      # each of the type its row says
            assert type(msg) is interface.message_class(interface.topic(name).msg_type), name


def test_calibration_output_is_the_calibration_in_use():
    """Calibration: x = log scale, y = leeway, z = heading offset (rad); 1, 0, 0 if none."""
    s = a_state([1.0, 0.0, 0.0, 0.0])
    [(_, none)] = ros_io.state_msgs(s, PARAMS, water=True, topics={'calibration'})
    assert none.header.frame_id == PARAMS.base_frame
    assert (none.vector.x, none.vector.y, none.vector.z) == (1.0, 0.0, 0.0)
    learnt = replace(s, calibration=Calibration(
        log_scale=Estimate(0.9, 0.01), leeway=Estimate(0.05, 0.02), turn_drift=Estimate(-8.0, 2.0),
        heading_offset=Estimate(-0.2, 0.01), declination=0.1))
    [(_, msg)] = ros_io.state_msgs(learnt, PARAMS, water=False, topics={'calibration'})
    assert (msg.vector.x, msg.vector.y, msg.vector.z) == (0.9, 0.05, -0.2)


def test_fast_built_messages_equal_the_field_checked_constructors(monkeypatch):
    """
    The outputs built unchecked (setters in place) equal rclpy's checked constructors.

    Also after serialising. Every slot of every message class is set (a missing one would fail
    in serialisation or comparison), with the types the generated setters accept under
    ROS_PYTHON_CHECK_FIELDS=1.
    """
    from rclpy.serialization import deserialize_message, serialize_message
    rot = Rotation.from_euler('ZYX', [0.3, 0.1, -0.05])
    x, y, z, w = rot.as_quat()
    s = a_state([w, x, y, z])
    fast = ros_io.state_msgs(s, PARAMS, water=True)
    monkeypatch.setattr(ros_io, '_CHECK_FIELDS', True)
    checked = ros_io.state_msgs(s, PARAMS, water=True)
    assert [name for name, _ in fast] == [name for name, _ in checked]
    for (name, a), (_, b) in zip(fast, checked):
        stack = [a]
        while stack:
            msg = stack.pop()
            for slot in type(msg).__slots__:
                value = getattr(msg, slot)     # AttributeError if a slot were left unset
                if hasattr(type(value), '__slots__') and hasattr(value, '_check_fields'):
                    stack.append(value)
        # Compared after a round trip, not byte by byte: Fast CDR leaves alignment padding
        # unwritten, so two serialisations of one message may differ in their padding bytes.
        back_a = deserialize_message(serialize_message(a), type(a))
        back_b = deserialize_message(serialize_message(b), type(b))
        assert back_a == a and back_b == b and back_a == back_b, name
    # Each message owns its objects: nothing is shared between two outputs.
    (_, odom), (_, local) = fast[0], fast[1]
    assert odom.header is not local.header and odom.header.stamp is not local.header.stamp
    assert not np.shares_memory(odom.twist.covariance, local.twist.covariance)


frame_names = st.from_regex(r'\A[a-h][a-h_]{0,8}\Z')  # 1 to 9 characters: every padding


@settings(max_examples=40, deadline=None)
@given(rotations, frame_names, frame_names, frame_names, frame_names,
       st.integers(0, 2 ** 31 - 1), st.integers(0, 999_999_999), st.booleans())
def test_cdr_outputs_are_the_serialised_messages(rot, map_frame, odom_frame, base_frame,
                                                 earth_frame, sec, nanosec, water):
    """
    The replay's CDR builders give the bytes of the node's messages, for every output type.

    Compared two ways, because Fast CDR (rclpy's serialiser) leaves alignment padding bytes
    unwritten, so its padding may hold anything: (1) rclpy deserialises our bytes to a message
    equal to the node's; (2) our bytes equal rosbags' zero-padded serialisation of the message
    rclpy serialised (and are as long as rclpy's). Frame names of every length move the
    alignment of everything after them.
    """
    from rclpy.serialization import deserialize_message, serialize_message
    from rosbags.typesys import get_typestore, Stores
    store = get_typestore(Stores.ROS2_JAZZY)
    x, y, z, w = rot.as_quat()
    s = replace(a_state([w, x, y, z]), stamp_ns=sec * 10 ** 9 + nanosec)
    params = NavigatorParams.from_flat({'map_frame': map_frame, 'odom_frame': odom_frame,
                                        'base_frame': base_frame, 'earth_frame': earth_frame})

    def same(ours: bytes, msg, msgtype: str) -> None:
        theirs = serialize_message(msg)
        assert len(ours) == len(theirs), msgtype
        assert deserialize_message(ours, type(msg)) == msg, msgtype
        zero_padded = store.serialize_cdr(store.deserialize_cdr(theirs, msgtype), msgtype)
        assert ours == bytes(zero_padded), msgtype

    msgs = ros_io.state_msgs(s, params, water)
    cdr = ros_io.state_msgs(s, params, water, cdr=True)
    assert [name for name, _ in msgs] == [name for name, _ in cdr]
    for (name, msg), (_, data) in zip(msgs, cdr):
        same(data, msg, interface.types(interface.Role.OUTPUT)['/' + name])
    subset = frozenset({'odometry/local', 'fix/filtered'})
    assert (ros_io.state_msgs(s, params, water, subset, cdr=True)
            == [(n, d) for n, d in cdr if n in subset])
    origin = (0.5, -0.25, 12.0)
    same(ros_io.origin_cdr(origin, s.stamp_ns, params),
         ros_io.origin_msg(origin, s.stamp_ns, params), 'sensor_msgs/msg/NavSatFix')


#: Any text but NUL (a C string ends there: rclpy reads 'a\x00b' back as 'a'); '±' and others.
#: No lone surrogates (category Cs, e.g. '\ud800'): they have no UTF-8, so no ROS string holds
#: one (a Python str can).
_NO_NUL = st.characters(blacklist_characters='\x00', blacklist_categories=('Cs',))


@settings(max_examples=30, deadline=None)
@given(st.lists(st.tuples(st.text(_NO_NUL, max_size=7), st.text(_NO_NUL, max_size=7)),
                max_size=5),
       st.text(_NO_NUL, max_size=9), st.sampled_from([ros_io.OK, ros_io.WARN]))
def test_diagnostics_cdr_is_the_zero_padded_serialisation(values, summary, level):
    """Every string length moves the alignment; rclpy reads our bytes back as the message."""
    from rclpy.serialization import deserialize_message, serialize_message
    from rosbags.typesys import get_typestore, Stores
    store = get_typestore(Stores.ROS2_JAZZY)
    msg = ros_io.diagnostics_msg(123_456_789_012, 'navigator: state', level, summary,
                                 dict(values))
    ours = ros_io.diagnostics_cdr(msg)
    theirs = serialize_message(msg)
    msgtype = 'diagnostic_msgs/msg/DiagnosticArray'
    assert len(ours) == len(theirs) and deserialize_message(ours, type(msg)) == msg
    assert ours == bytes(store.serialize_cdr(store.deserialize_cdr(theirs, msgtype), msgtype))


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
    view = ros_io.imu_from_cdr(raw)
    assert view is not None
    _same_imu(view, store.deserialize_cdr(raw, 'sensor_msgs/msg/Imu'))
    assert _bits(ros_io.imu_from_cdr(memoryview(raw)).values) == _bits(view.values)
    # What is not exactly a little-endian Imu is left to the generic deserialiser.
    assert ros_io.imu_from_cdr(raw[:-1]) is None
    assert ros_io.imu_from_cdr(raw + b'\x00' * 8) is None
    assert ros_io.imu_from_cdr(b'\x00\x00' + raw[2:]) is None          # big-endian CDR
    assert ros_io.imu_from_cdr(raw[:12] + b'\xff\xff\xff\x7f' + raw[16:]) is None


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
                view = ros_io.imu_from_cdr(raw)
                _same_imu(view, msg)
                assert _fields(ros_io.imu_from_msg(view, PARAMS)) == _fields(
                    ros_io.imu_from_msg(msg, PARAMS))
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
        view = ros_io.imu_from_cdr(serialize_message(msg))
        assert view is not None and view.header.frame_id == msg.header.frame_id
        assert _fields(ros_io.imu_from_msg(view, PARAMS)) == _fields(
            ros_io.imu_from_msg(msg, PARAMS))


def test_a_raw_imu_payload_is_read_directly_else_by_rclpy_else_refused():
    """imu_from_raw (the node's raw imu subscription): the CDR view, rclpy's message, a Reason."""
    from rclpy.serialization import serialize_message
    msg = imu_msg(Rotation.from_euler('zyx', [0.4, -0.1, 0.05]), [0.01, -0.02, 0.3],
                  o_cov=np.eye(3) * 1e-4, w_cov=np.eye(3) * 1e-6)
    raw = serialize_message(msg)
    direct = ros_io.imu_from_raw(raw)
    assert type(direct) is ros_io.ImuCdr
    expected = _fields(ros_io.imu_from_msg(msg, PARAMS))
    assert _fields(ros_io.imu_from_msg(direct, PARAMS)) == expected
    # Trailing bytes: not the plain size the view takes, but rclpy's deserialiser reads it.
    padded = ros_io.imu_from_raw(raw + b'\x00' * 8)
    assert type(padded) is Imu
    expected = _fields(ros_io.imu_from_msg(msg, PARAMS))
    assert _fields(ros_io.imu_from_msg(padded, PARAMS)) == expected
    for garbage in (b'', b'garbage!', raw[:40], raw[:12] + b'\xff\xff\xff\x7f' + raw[16:]):
        refused = ros_io.imu_from_raw(garbage)
        assert isinstance(refused, Rejection) and refused.reason == Reason.CDR_ERROR, garbage
        assert f'{len(garbage)} bytes' in refused.detail


def test_the_pipeline_counts_a_payload_its_driver_could_not_decode():
    """A Rejection handed in for a message is counted by its reason, and changes nothing else."""
    from vessel_kinematics.ros.pipeline import Pipeline
    pipe = Pipeline(PARAMS)
    result = pipe.handle('imu', ros_io.imu_from_raw(b'garbage!'))
    assert result.rejected == 'cdr_error' and 'does not deserialise' in result.detail
    assert {k: v for k, v in pipe.counts.items() if v} == {'imu/cdr_error': 1}
    assert not pipe.estimator.ready and pipe.estimator.t is None

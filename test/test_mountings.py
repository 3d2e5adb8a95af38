"""
Sensor mountings from /tf_static or from the parameters, through the whole pipeline (no DDS).

A turning vessel (closed form, test/reference.py) carries an IMU rotated in ``imu_link``, a
GNSS antenna on a mast (``gnss``) and a DVL rotated and offset in ``dvl_link``; each sensor
publishes in its own frame (the DVL its velocity v_s = Rᵀ(v_b + ω × r)). The same voyage with
the mountings as parameters and as a tf2_msgs/TFMessage on /tf_static gives the same outputs
(to 1e-12), and each mounting undone gives the base frame's own voyage back (ω × r included:
without it the velocity is off by |ω × r|).
"""

from __future__ import annotations

import math
from typing import Any, Iterator

from geometry_msgs.msg import TransformStamped, TwistWithCovarianceStamped
import numpy as np
import pytest
from reference import ConstantTurn
from scipy.spatial.transform import Rotation
from sensor_msgs.msg import Imu
from test_pipeline import decoded, fix_msg, handle, make, stamp, T0
from tf2_msgs.msg import TFMessage
from vessel_kinematics.ros.pipeline import Pipeline

IMU_RPY = (0.15, -0.1, 1.3)                 # imu_link in base_link (rad)
ANTENNA = (-3.0, 0.5, 5.0)                  # gnss in base_link (FLU, m)
DVL_RPY = (0.02, -0.03, math.pi / 2 + 0.1)  # dvl_link in base_link (rad)
DVL_AT = (2.0, -0.8, -1.5)                  # dvl_link in base_link (FLU, m)
YAW_RATE = 0.06                             # rad/s (FRD r): |ω × r| = 0.13 m/s at the DVL
BASE = (0.0, 0.0, 0.0)


def rot(rpy) -> Rotation:
    """Return R = Rz(yaw) Ry(pitch) Rx(roll), the static-transform convention."""
    return Rotation.from_euler('ZYX', [rpy[2], rpy[1], rpy[0]])


def in_sensor(mounting: Rotation, cov_base: np.ndarray) -> np.ndarray:
    """Return a base-frame covariance in the sensor frame, Rᵀ C R, row-major (9)."""
    r = mounting.as_matrix()
    c = r.T @ cov_base @ r
    return (0.5 * (c + c.T)).reshape(9)


class MountedVessel(ConstantTurn):
    """The reference turn, and the messages of sensors mounted as given (FLU, base_link)."""

    def __init__(self, imu_rpy=BASE, antenna=BASE, dvl_rpy=BASE, dvl_at=BASE,
                 frames=('imu_link', 'gnss', 'dvl_link')) -> None:
        super().__init__(3.0, 0.3, YAW_RATE, psi0=0.2)
        self.imu, self.antenna = rot(imu_rpy), np.array(antenna, dtype=float)
        self.dvl, self.dvl_at = rot(dvl_rpy), np.array(dvl_at, dtype=float)
        self.frames = frames

    def omega_flu(self) -> np.ndarray:
        return np.array([0.0, 0.0, -self.r])

    def imu_msg(self, t: float) -> Imu:
        msg = stamp(Imu(), t)
        msg.header.frame_id = self.frames[0]
        base = Rotation.from_euler('z', math.pi / 2 - self.psi(t))      # FLU in ENU
        x, y, z, w = (base * self.imu).as_quat()                         # q_imu = q_base ⊗ q_m
        msg.orientation.x, msg.orientation.y, msg.orientation.z, msg.orientation.w = x, y, z, w
        # Covariances given in base_link, published in the sensor frame: Rᵀ C R.
        msg.orientation_covariance = in_sensor(self.imu, np.diag([1e-4, 1e-4, 4e-4]))
        wx, wy, wz = self.imu.inv().apply(self.omega_flu())
        msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z = wx, wy, wz
        msg.angular_velocity_covariance = in_sensor(self.imu, np.diag([1e-6, 2e-6, 3e-6]))
        return msg

    def fix_msg(self, t: float) -> Any:
        a = self.antenna
        psi = self.psi(t)
        # The antenna FRD (a_x, -a_y, -a_z) turned by the heading into NED.
        offset = np.array([a[0] * math.cos(psi) + a[1] * math.sin(psi),
                           a[0] * math.sin(psi) - a[1] * math.cos(psi), -a[2]])
        msg = fix_msg(t, self.position(t) + offset)
        msg.header.frame_id = self.frames[1]
        return msg

    def velocity_msg(self, t: float) -> TwistWithCovarianceStamped:
        v_base = np.array([self.u, -self.v, 0.0])
        v_sensor = self.dvl.inv().apply(v_base + np.cross(self.omega_flu(), self.dvl_at))
        msg = stamp(TwistWithCovarianceStamped(), t)
        msg.header.frame_id = self.frames[2]
        lin = msg.twist.twist.linear
        lin.x, lin.y, lin.z = v_sensor
        cov = np.zeros((6, 6))
        cov[0:3, 0:3] = in_sensor(self.dvl, np.diag([1e-4, 2e-4, 5e-4])).reshape(3, 3)
        cov[3, 3] = -1.0                       # no angular part (a DVL)
        msg.twist.covariance = cov.reshape(36)
        return msg

    def messages(self, t_end: float) -> Iterator[tuple[str, Any]]:
        events = [(k / 50.0, 'imu') for k in range(int(t_end * 50.0) + 1)]
        events += [(k / 10.0 + 0.001, 'velocity') for k in range(int(t_end * 10.0))]
        events += [(k / 2.0 + 0.002, 'fix') for k in range(int(t_end * 2.0))]
        for t, name in sorted(events):
            yield name, getattr(self, f'{name}_msg')(t)


def tf_static(*transforms: tuple[str, Any, Any]) -> TFMessage:
    """Return a TFMessage of base_link -> child transforms (child, rpy, xyz)."""
    msg = TFMessage()
    for child, rpy, xyz in transforms:
        t = TransformStamped()
        t.header.frame_id, t.child_frame_id = 'base_link', child
        t.header.stamp = stamp(TransformStamped(), 0.0).header.stamp
        tr, q = t.transform.translation, t.transform.rotation
        tr.x, tr.y, tr.z = (float(c) for c in xyz)
        q.x, q.y, q.z, q.w = (float(c) for c in rot(rpy).as_quat())
        msg.transforms.append(t)
    return msg


def run(pipe: Pipeline, vessel: MountedVessel, t_end: float = 40.0) -> tuple[list, list]:
    """Feed the voyage; return the last outputs of each accepted message and the info lines."""
    outs, infos = [], []
    for name, msg in vessel.messages(t_end):
        result = handle(pipe, name, msg)
        assert result.rejected is None, (name, result.rejected, result.detail)
        if result.info:
            infos.append(result.info)
        outs.append({topic: msg for topic, msg in decoded(result.emissions).items()
                     if topic != 'origin'})
    return [o for o in outs if o], infos


def numbers(msg: Any) -> Iterator[float]:
    """Yield every number of a message (header stamps included), depth first."""
    if isinstance(msg, (float, int)) and not isinstance(msg, bool):
        yield float(msg)
    elif isinstance(msg, np.ndarray):
        yield from msg.ravel().tolist()
    elif hasattr(msg, 'get_fields_and_field_types'):
        for name in msg.get_fields_and_field_types():
            yield from numbers(getattr(msg, name))


def assert_same(a: list, b: list, atol: float) -> None:
    assert len(a) == len(b) and a
    for out_a, out_b in zip(a, b):
        assert set(out_a) == set(out_b)
        for topic in out_a:
            np.testing.assert_allclose(list(numbers(out_a[topic])), list(numbers(out_b[topic])),
                                       rtol=0.0, atol=atol, err_msg=topic)


MOUNTED = {'imu_rpy': IMU_RPY, 'antenna': ANTENNA, 'dvl_rpy': DVL_RPY, 'dvl_at': DVL_AT}
PARAMETERS = {'imu__mounting_rpy': list(IMU_RPY), 'gnss__antenna_position': list(ANTENNA),
              'velocity__mounting_rpy': list(DVL_RPY),
              'velocity__sensor_position': list(DVL_AT)}
TF_STATIC = (('imu_link', IMU_RPY, BASE), ('gnss', BASE, ANTENNA), ('dvl_link', DVL_RPY, DVL_AT))


def test_tf_static_gives_the_outputs_of_the_parameters() -> None:
    """IMU, antenna and DVL: parameters vs /tf_static, in a turn, equal to 1e-12."""
    vessel = MountedVessel(**MOUNTED)
    by_params, params_info = run(make(**PARAMETERS), vessel)
    pipe = make()
    assert pipe.tf_static(tf_static(*TF_STATIC)) == 3
    by_tf, tf_info = run(pipe, vessel)
    assert_same(by_params, by_tf, atol=1e-12)
    # Which source, said once per input and frame.
    assert sorted(tf_info) == [
        'gnss antenna from /tf_static: frame gnss (rpy (0, 0, 0) rad, xyz (-3, 0.5, 5) m)',
        'imu mounting from /tf_static: frame imu_link (rpy (0.15, -0.1, 1.3) rad, '
        'xyz (0, 0, 0) m)',
        'velocity mounting from /tf_static: frame dvl_link (rpy (0.02, -0.03, 1.67080) rad, '
        'xyz (2, -0.8, -1.5) m)'.replace('1.67080', f'{DVL_RPY[2]:.6g}')]
    assert sorted(params_info) == [
        'gnss antenna from parameters (gnss.antenna_position [-3.0, 0.5, 5.0]) '
        '(frame gnss not in /tf_static)',
        'imu mounting from parameters (imu.mounting_rpy [0.15, -0.1, 1.3]) '
        '(frame imu_link not in /tf_static)',
        f'velocity mounting from parameters (velocity.mounting_rpy {list(DVL_RPY)}, '
        f'velocity.sensor_position {list(DVL_AT)}) (frame dvl_link not in /tf_static)']
    array = decoded([pipe.diagnostics(int((T0 + 41) * 1e9))])['/diagnostics']
    values = {kv.key: kv.value for status in array.status for kv in status.values}
    assert values['imu mounting'] == 'tf_static imu_link'
    assert values['gnss antenna'] == 'tf_static gnss'
    assert values['velocity mounting'] == 'tf_static dvl_link'


@pytest.mark.parametrize('mounted, transform', [
    ({'imu_rpy': IMU_RPY}, ('imu_link', IMU_RPY, BASE)),
    ({'dvl_rpy': DVL_RPY, 'dvl_at': DVL_AT}, ('dvl_link', DVL_RPY, DVL_AT)),
], ids=['imu', 'dvl'])
def test_a_mounting_undone_is_the_base_voyage(mounted, transform) -> None:
    """A mounted sensor read through /tf_static gives the voyage of a sensor in base_link."""
    base, _ = run(make(), MountedVessel(frames=('base_link',) * 3))
    pipe = make()
    pipe.tf_static(tf_static(transform))
    undone, _ = run(pipe, MountedVessel(**mounted))
    # Rotations and ω × r exactly undone: equal to round-off.
    assert_same(base, undone, atol=1e-9)


def test_without_omega_cross_r_the_dvl_would_be_wrong() -> None:
    """The control: the DVL's rotation alone (lever arm not removed) is off by |ω × r|."""
    base, _ = run(make(), MountedVessel(frames=('base_link',) * 3), t_end=10.0)
    pipe = make()
    pipe.tf_static(tf_static(('dvl_link', DVL_RPY, BASE)))     # the lever arm left out
    wrong, _ = run(pipe, MountedVessel(dvl_rpy=DVL_RPY, dvl_at=DVL_AT), t_end=10.0)
    u_base = base[-1]['odometry'].twist.twist.linear
    u_wrong = wrong[-1]['odometry'].twist.twist.linear
    error = math.hypot(u_base.x - u_wrong.x, u_base.y - u_wrong.y)
    assert error > 0.05           # |ω × r| = 0.06 * hypot(2.0, 0.8) = 0.13 m/s, filtered


def test_late_tf_static_switches_the_source_and_says_so() -> None:
    """Parameters until /tf_static arrives, then the transform; each said once."""
    vessel = MountedVessel(imu_rpy=IMU_RPY)
    pipe = make()
    stream = list(vessel.messages(4.0))
    infos = []
    for index, (name, msg) in enumerate(stream):
        if index == len(stream) // 2:
            pipe.tf_static(tf_static(*TF_STATIC))
        result = handle(pipe, name, msg)
        infos += [result.info] if result.info else []
    imu = [i for i in infos if i.startswith('imu mounting')]
    assert len(imu) == 2
    assert imu[0].startswith('imu mounting from parameters') and 'not in /tf_static' in imu[0]
    assert imu[1].startswith('imu mounting from /tf_static: frame imu_link')
    # Re-publishing the same transforms changes nothing and says nothing.
    assert pipe.tf_static(tf_static(*TF_STATIC)) == 0
    later = list(MountedVessel(imu_rpy=IMU_RPY).messages(6.0))[len(stream):]
    assert not [info for name, msg in later if (info := handle(pipe, name, msg).info)]


def test_base_frame_and_disconnected_frames_take_the_parameters() -> None:
    pipe = make(imu__mounting_rpy=[0.0, 0.0, 0.5])
    other = TFMessage()
    t = TransformStamped()
    t.header.frame_id, t.child_frame_id = 'mast', 'imu_link'       # no path to base_link
    t.transform.rotation.w = 1.0
    other.transforms.append(t)
    pipe.tf_static(other)
    vessel = MountedVessel(frames=('imu_link', 'base_link', ''))
    _, infos = run(pipe, vessel, t_end=1.0)
    assert sorted(infos) == [
        'gnss antenna from parameters (gnss.antenna_position [0.0, 0.0, 0.0]) '
        '(frame base_link is the base frame)',
        'imu mounting from parameters (imu.mounting_rpy [0.0, 0.0, 0.5]) '
        '(frame imu_link not connected to base_link in /tf_static)',
        'velocity mounting from parameters (velocity.mounting_rpy [0.0, 0.0, 0.0], '
        'velocity.sensor_position [0.0, 0.0, 0.0]) (no frame_id)']


def test_replay_reads_tf_static_from_the_bag(tmp_path) -> None:
    """A bag with /tf_static (logged last: latched, read first) replays as the parameters."""
    from rclpy.serialization import serialize_message
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import get_typestore, Stores
    from vessel_kinematics.tools import replay

    vessel = MountedVessel(**MOUNTED)
    events = list(vessel.messages(20.0))
    types = {'/fix': 'sensor_msgs/msg/NavSatFix', '/imu': 'sensor_msgs/msg/Imu',
             '/velocity': 'geometry_msgs/msg/TwistWithCovarianceStamped',
             '/tf_static': 'tf2_msgs/msg/TFMessage'}
    store = get_typestore(Stores.ROS2_JAZZY)
    bag = tmp_path / 'in'
    with Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        connections = {topic: writer.add_connection(topic, msgtype, typestore=store)
                       for topic, msgtype in types.items()}
        last = 0
        for name, msg in events:
            last = msg.header.stamp.sec * 10 ** 9 + msg.header.stamp.nanosec
            writer.write(connections['/' + name], last, serialize_message(msg))
        # Two broadcasters: the mast's transforms, then the IMU's; logged after the inputs.
        writer.write(connections['/tf_static'], last + 1,
                     serialize_message(tf_static(*TF_STATIC[1:])))
        writer.write(connections['/tf_static'], last + 2,
                     serialize_message(tf_static(TF_STATIC[0])))
    out = tmp_path / 'out'
    summary = replay.run(bag, out, make().params, progress=False)
    assert '/tf_static: 2 messages read before the inputs, 3 static transforms' in summary.notes
    assert any(n.startswith('imu mounting from /tf_static: frame imu_link') for n in summary.notes)
    assert any(n.startswith('velocity mounting from /tf_static: frame dvl_link')
               for n in summary.notes)
    from rosbags.highlevel import AnyReader
    with AnyReader([out]) as reader:
        conns = [c for c in reader.connections if c.topic == '/odometry']
        odometry = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(conns)]
        statics = [c for c in reader.connections if c.topic == '/tf_static']
        static_children = {t.child_frame_id for c, _, raw in reader.messages(statics)
                           for t in reader.deserialize(raw, c.msgtype).transforms}
    # The output keeps the bag's own static transforms (copied: a listener merges every
    # /tf_static message) beside the navigator's.
    assert {t[0] for t in TF_STATIC} <= static_children, static_children
    assert make().params.map_frame in static_children
    # The parameter case, in memory: the same odometry to 1e-12.
    by_params, _ = run(make(**PARAMETERS), vessel, t_end=20.0)
    expected = [o['odometry'] for o in by_params if 'odometry' in o]
    assert len(odometry) == len(expected) > 100
    for got, want in zip(odometry, expected):
        p, q = got.pose.pose, want.pose.pose
        np.testing.assert_allclose(
            [p.position.x, p.position.y, p.orientation.x, p.orientation.w,
             got.twist.twist.linear.x, got.twist.twist.linear.y],
            [q.position.x, q.position.y, q.orientation.x, q.orientation.w,
             want.twist.twist.linear.x, want.twist.twist.linear.y], rtol=0.0, atol=1e-12)
        np.testing.assert_allclose(got.pose.covariance, want.pose.covariance, atol=1e-12)


def test_velocity_rate_sources_against_scipy() -> None:
    """v_base = R v_s − ω × r with ω: the given IMU rate, else the message's, else zero."""
    from vessel_kinematics.ros import inputs
    from vessel_kinematics.ros.static_tf import Mounting

    params = make().params
    r_mount = rot(DVL_RPY)
    x, y, z, w = r_mount.as_quat()
    mounting = Mounting((w, x, y, z), DVL_AT)
    v_s = np.array([1.5, -0.4, 0.2])
    msg = stamp(TwistWithCovarianceStamped(), 1.0)
    msg.twist.twist.linear.x, msg.twist.twist.linear.y, msg.twist.twist.linear.z = v_s
    w_msg = np.array([0.01, -0.02, 0.3])        # the sensor's own rate, sensor axes
    a = msg.twist.twist.angular
    a.x, a.y, a.z = w_msg
    msg.twist.covariance = np.diag([1e-4, 2e-4, 3e-4, 1e-6, 1e-6, 1e-6]).reshape(36)
    frd = np.array([1.0, -1.0, -1.0])
    w_imu = np.array([0.0, 0.1, -0.2])
    cases = [(w_imu, w_imu),                                # the IMU's rate (base axes)
             (None, r_mount.apply(w_msg))]                  # the message's, rotated
    for rate, omega in cases:
        m = inputs.velocity_from_msg(msg, params, mounting, rate)
        expected = r_mount.apply(v_s) - np.cross(omega, DVL_AT)
        np.testing.assert_allclose(m.nu_b, expected * frd, atol=1e-15)
        np.testing.assert_allclose(m.omega_b, r_mount.apply(w_msg) * frd, atol=1e-15)
        c = np.diag(frd) @ r_mount.as_matrix() @ np.diag([1e-4, 2e-4, 3e-4]) @ \
            r_mount.as_matrix().T @ np.diag(frd)
        np.testing.assert_allclose(m.cov, c, atol=1e-18)
    # No rate at all (angular part marked unused): ω × r is zero, and the pipeline says so.
    msg.twist.covariance[21] = -1.0
    m = inputs.velocity_from_msg(msg, params, mounting, None)
    np.testing.assert_allclose(m.nu_b, r_mount.apply(v_s) * frd, atol=1e-15)
    assert m.omega_b is None
    pipe = make()
    pipe.tf_static(tf_static(('dvl_link', DVL_RPY, DVL_AT)))
    msg.header.frame_id = 'dvl_link'
    info = handle(pipe, 'velocity', msg).info
    assert 'velocity mounting from /tf_static: frame dvl_link' in info
    assert 'no body rate known' in info and 'omega x r taken as zero' in info


def test_odometry_twist_is_in_its_child_frame() -> None:
    """nav_msgs/Odometry: the twist's frame is child_frame_id, not header.frame_id (odom)."""
    from nav_msgs.msg import Odometry

    pipe = make(velocity__source='odometry')
    pipe.tf_static(tf_static(('dvl_link', DVL_RPY, DVL_AT)))
    msg = stamp(Odometry(), 1.0)
    msg.header.frame_id, msg.child_frame_id = 'odom', 'dvl_link'
    msg.twist.twist.linear.x = 1.0
    info = handle(pipe, 'velocity', msg).info
    assert info.startswith('velocity mounting from /tf_static: frame dvl_link')

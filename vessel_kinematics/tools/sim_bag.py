"""
The simulated voyage at the ROS edge: its readings as ROS 2 messages (CDR) and a bag of them.

:func:`records` turns :class:`~vessel_kinematics.tools.sim_sensors.Readings` into serialised
messages, :func:`write_bag` writes them (:mod:`vessel_kinematics.tools.bags`) in log-time
order. The topics are the interface table's inputs and truth rows (:data:`TOPICS`).

Times, as a recorder on a vessel's ROS graph sees them: an input's log time is when its message
reached the graph, its sensor's measurement time plus the delivery latency the readings drew
(a fix 0.1 to 0.5 s, the IMU and the log 1 to 5 ms by default: :mod:`.sim_sensors`); its header
stamp is the measurement time, as a driver that stamps with the sensor's time of validity
writes it, or with ``VoyageConfig.stamp_on_receipt`` the log time (a driver that stamps on
receipt: the latency becomes an error of the stamp). The truth's log time is its stamp.

* ``/fix`` sensor_msgs/NavSatFix in ``gnss``: STATUS_FIX with a DIAGONAL_KNOWN covariance, or
  during the outage STATUS_NO_FIX with NaN position and an UNKNOWN covariance;
* ``/imu`` sensor_msgs/Imu in ``imu_link`` (REP-145), covariances filled (a heading-only
  compass: roll and pitch variance 1e3, rate and acceleration covariance[0] = -1);
* ``/velocity`` geometry_msgs/TwistWithCovarianceStamped in ``base_link``;
* ``/truth/odometry`` nav_msgs/Odometry ``map`` / ``base_link``, ``/truth/course_sideslip``
  (in ``base_link``), ``/truth/current`` (in ``map``), ``/truth/calibration`` (in
  ``base_link``) geometry_msgs/Vector3Stamped, and ``/truth/origin`` sensor_msgs/NavSatFix
  (in ``map``, once, STATUS_FIX, COVARIANCE_TYPE_KNOWN).
"""

from __future__ import annotations

from dataclasses import dataclass
import math
from pathlib import Path
from typing import Any, Sequence

import numpy as np
from vessel_kinematics.core.frames import ns_to_stamp
from vessel_kinematics.ros import interface
from vessel_kinematics.tools import bags
from vessel_kinematics.tools.sim_model import Truth, VoyageConfig
from vessel_kinematics.tools.sim_sensors import Readings, sensor_readings

__all__ = ['Record', 'records', 'sensor_records', 'TOPIC_FIX', 'TOPIC_IMU',
           'TOPIC_TRUTH_CALIBRATION', 'TOPIC_TRUTH_COURSE_SIDESLIP', 'TOPIC_TRUTH_CURRENT',
           'TOPIC_TRUTH_ODOMETRY', 'TOPIC_TRUTH_ORIGIN', 'TOPIC_VELOCITY', 'TOPICS', 'write_bag']

TOPIC_FIX = interface.topic('fix').absolute
TOPIC_IMU = interface.topic('imu').absolute
TOPIC_VELOCITY = interface.topic('velocity').absolute
TOPIC_TRUTH_ODOMETRY = interface.topic('/truth/odometry').absolute
TOPIC_TRUTH_COURSE_SIDESLIP = interface.topic('/truth/course_sideslip').absolute
TOPIC_TRUTH_CURRENT = interface.topic('/truth/current').absolute
TOPIC_TRUTH_ORIGIN = interface.topic('/truth/origin').absolute
TOPIC_TRUTH_CALIBRATION = interface.topic('/truth/calibration').absolute

#: Every topic of the voyage's bag and its message type (rosbag2 spelling): the navigator's
#: inputs (the DVL or log as a TwistWithCovarianceStamped) and the truth.
TOPICS: dict[str, str] = interface.types(interface.Role.INPUT, interface.Role.TRUTH)


@dataclass(frozen=True)
class Record:
    """
    One serialised message of the bag: topic, header stamp (ns), CDR bytes and log time (ns).

    ``log_ns`` is when the message reached the ROS graph (the bag's log time); None (the
    default) is the header stamp.
    """

    topic: str
    stamp_ns: int
    data: bytes
    log_ns: int | None = None

    def __post_init__(self) -> None:
        if self.log_ns is None:
            object.__setattr__(self, 'log_ns', self.stamp_ns)

    @property
    def logged_ns(self) -> int:
        """Return the log time (ns), typed: ``log_ns`` is the stamp where none was given."""
        return self.stamp_ns if self.log_ns is None else self.log_ns


def _header(stamp_ns: int, frame_id: str) -> Any:
    """Return a rosbags std_msgs/Header."""
    types = bags.jazzy().types
    sec, nanosec = ns_to_stamp(stamp_ns)
    return types['std_msgs/msg/Header'](
        stamp=types['builtin_interfaces/msg/Time'](sec=sec, nanosec=nanosec), frame_id=frame_id)


def records(readings: Readings) -> list[Record]:
    """
    Return the readings as serialised messages (inputs and truth), in header-stamp order.

    Each input's ``log_ns`` is its arrival (:meth:`Readings.log_ns`), its stamp
    :meth:`Readings.header_ns`; the truth's log time is its stamp. Serialised with rosbags,
    whose padding bytes are zeros: the same voyage gives the same bytes (rclpy's Fast CDR
    leaves its padding unwritten, so two runs would differ there).
    """
    store = bags.jazzy()
    types = store.types
    serialize = store.serialize_cdr
    vector, quaternion = types['geometry_msgs/msg/Vector3'], types['geometry_msgs/msg/Quaternion']
    status_type: Any = types['sensor_msgs/msg/NavSatStatus']
    fix_type: Any = types['sensor_msgs/msg/NavSatFix']

    def covariance(values: Sequence[float]) -> np.ndarray:
        return np.array(values, dtype=np.float64)

    stamps = readings.stamps
    out: list[Record] = []

    imu_type = 'sensor_msgs/msg/Imu'
    q_cov, w_cov, a_cov = (covariance(c) for c in readings.imu_covariances)
    q_imu, gyro, accel = (readings.imu_orientation, readings.imu_angular_velocity,
                          readings.imu_linear_acceleration)
    imu_stamps, imu_logs = readings.header_ns('imu'), readings.log_ns('imu')
    for j in range(len(readings.imu_steps)):
        x, y, z, w = (float(v) for v in q_imu[j])
        imu = types[imu_type](
            header=_header(imu_stamps[j], 'imu_link'),
            orientation=quaternion(x=x, y=y, z=z, w=w), orientation_covariance=q_cov,
            angular_velocity=vector(*(float(v) for v in gyro[j])),
            angular_velocity_covariance=w_cov,
            linear_acceleration=vector(*(float(v) for v in accel[j])),
            linear_acceleration_covariance=a_cov)
        out.append(Record(TOPIC_IMU, imu_stamps[j], bytes(serialize(imu, imu_type)),
                          imu_logs[j]))

    fix_type_name = TOPICS[TOPIC_FIX]
    no_fix_cov, fix_cov = covariance([0.0] * 9), covariance(readings.fix_covariance)
    fix_stamps, fix_logs = readings.header_ns('fix'), readings.log_ns('fix')
    for stamp, log, llh in zip(fix_stamps, fix_logs, readings.fix_llh):
        if llh is None:     # the outage: a NO_FIX report
            status, (lat, lon, alt) = status_type.STATUS_NO_FIX, (math.nan,) * 3
            cov, cov_type = no_fix_cov, fix_type.COVARIANCE_TYPE_UNKNOWN
        else:
            status, (lat, lon, alt) = status_type.STATUS_FIX, llh
            cov, cov_type = fix_cov, fix_type.COVARIANCE_TYPE_DIAGONAL_KNOWN
        fix = fix_type(header=_header(stamp, 'gnss'),
                       status=status_type(status=status, service=status_type.SERVICE_GPS),
                       latitude=float(lat), longitude=float(lon), altitude=float(alt),
                       position_covariance=cov, position_covariance_type=cov_type)
        out.append(Record(TOPIC_FIX, stamp, bytes(serialize(fix, fix_type_name)), log))

    twist_type = TOPICS[TOPIC_VELOCITY]
    twist_cov = covariance(readings.velocity_covariance)
    for stamp, log, measured in zip(readings.header_ns('velocity'),
                                    readings.log_ns('velocity'), readings.velocity):
        twist = types[twist_type](
            header=_header(stamp, 'base_link'),
            twist=types['geometry_msgs/msg/TwistWithCovariance'](
                twist=types['geometry_msgs/msg/Twist'](
                    linear=vector(*(float(v) for v in measured)), angular=vector(0.0, 0.0, 0.0)),
                covariance=twist_cov))
        out.append(Record(TOPIC_VELOCITY, stamp, bytes(serialize(twist, twist_type)), log))

    vector3_stamped = TOPICS[TOPIC_TRUTH_CURRENT]
    odometry_type = TOPICS[TOPIC_TRUTH_ODOMETRY]
    zero36 = covariance([0.0] * 36)

    def stamped(stamp: int, frame_id: str, values: Sequence[float]) -> bytes:
        msg = types[vector3_stamped](header=_header(stamp, frame_id),
                                     vector=vector(*(float(v) for v in values)))
        return bytes(serialize(msg, vector3_stamped))

    for j, k in enumerate(readings.truth_steps):
        stamp = stamps[k]
        x, y, z, w = (float(v) for v in readings.truth_orientation[j])
        u, v, w_speed, r = (float(v) for v in readings.truth_twist[j])
        odom = types[odometry_type](
            header=_header(stamp, 'map'), child_frame_id='base_link',
            pose=types['geometry_msgs/msg/PoseWithCovariance'](
                pose=types['geometry_msgs/msg/Pose'](
                    position=types['geometry_msgs/msg/Point'](
                        *(float(p) for p in readings.truth_position[j])),
                    orientation=quaternion(x=x, y=y, z=z, w=w)),
                covariance=zero36),
            twist=types['geometry_msgs/msg/TwistWithCovariance'](
                twist=types['geometry_msgs/msg/Twist'](
                    linear=vector(u, v, w_speed), angular=vector(0.0, 0.0, r)),
                covariance=zero36))
        out.append(Record(TOPIC_TRUTH_ODOMETRY, stamp, bytes(serialize(odom, odometry_type))))
        out.append(Record(TOPIC_TRUTH_COURSE_SIDESLIP, stamp,
                          stamped(stamp, 'base_link', readings.truth_course_sideslip[j])))
        out.append(Record(TOPIC_TRUTH_CURRENT, stamp,
                          stamped(stamp, 'map', readings.truth_current[j])))
        out.append(Record(TOPIC_TRUTH_CALIBRATION, stamp,
                          stamped(stamp, 'base_link', readings.calibration)))

    lat, lon, alt = readings.origin
    origin = fix_type(header=_header(stamps[0], 'map'),
                      status=status_type(status=status_type.STATUS_FIX,
                                         service=status_type.SERVICE_GPS),
                      latitude=float(lat), longitude=float(lon), altitude=float(alt),
                      position_covariance=covariance([0.0] * 9),
                      position_covariance_type=fix_type.COVARIANCE_TYPE_KNOWN)
    out.append(Record(TOPIC_TRUTH_ORIGIN, stamps[0],
                      bytes(serialize(origin, TOPICS[TOPIC_TRUTH_ORIGIN]))))

    order = {topic: i for i, topic in enumerate(TOPICS)}
    out.sort(key=lambda rec: (rec.stamp_ns, order[rec.topic]))
    return out


def sensor_records(truth: Truth, config: VoyageConfig) -> list[Record]:
    """
    Return the voyage's messages (inputs and truth), serialised, in stamp order.

    :func:`~vessel_kinematics.tools.sim_sensors.sensor_readings` then :func:`records`: the same
    configuration gives the same messages.
    """
    return records(sensor_readings(truth, config))


def write_bag(path: str | Path, records: Sequence[Record],
              topics: dict[str, str] | None = None) -> Path:
    """
    Write records to a new rosbag2 mcap bag at ``path`` (a directory), at their log times.

    In log-time order (a stable sort: records of equal log time keep their order), as a
    recorder writes what it receives.

    ``topics`` maps each topic to its type (default :data:`TOPICS`); the connections carry the
    message definitions of ROS 2 Jazzy and offer the interface table's QoS
    (:func:`vessel_kinematics.tools.bags.offered_qos`): the latched ``/truth/origin``
    transient-local, keep last 1, so ``ros2 bag play`` latches it; the others reliable.
    """
    return bags.write_bag(path, ((r.topic, r.logged_ns, r.data)
                                 for r in sorted(records, key=lambda r: r.logged_ns)),
                          TOPICS if topics is None else topics)

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


def records(readings: Readings) -> list[Record]:
    """
    Return the readings as serialised messages (inputs and truth), in header-stamp order.

    Each input's ``log_ns`` is its arrival (:meth:`Readings.log_ns`), its stamp
    :meth:`Readings.header_ns`; the truth's log time is its stamp. Serialised with rosbags
    (:func:`~vessel_kinematics.tools.bags.serialize`), whose padding bytes are zeros: the
    same voyage gives the same bytes (rclpy's Fast CDR leaves its padding unwritten).
    """
    types: Any = bags.jazzy().types
    header, vector3, cdr = bags.header, bags.vector3, bags.serialize
    status_type = types['sensor_msgs/msg/NavSatStatus']
    fix_type = types['sensor_msgs/msg/NavSatFix']
    quaternion = types['geometry_msgs/msg/Quaternion']

    def covariance(values: Sequence[float]) -> np.ndarray:
        return np.array(values, dtype=np.float64)

    def twist(linear: Sequence[float], angular: Sequence[float], cov: np.ndarray) -> Any:
        """Return a geometry_msgs/TwistWithCovariance."""
        return types['geometry_msgs/msg/TwistWithCovariance'](
            twist=types['geometry_msgs/msg/Twist'](linear=vector3(*linear),
                                                   angular=vector3(*angular)),
            covariance=cov)

    def vector3_stamped(stamp: int, frame_id: str, values: Sequence[float]) -> bytes:
        msg = types['geometry_msgs/msg/Vector3Stamped'](
            header=header(stamp, frame_id), vector=vector3(*values))
        return cdr(msg)

    def xyzw(q: Sequence[float]) -> Any:
        x, y, z, w = (float(c) for c in q)
        return quaternion(x=x, y=y, z=z, w=w)

    stamps = readings.stamps
    out: list[Record] = []

    q_cov, w_cov, a_cov = (covariance(c) for c in readings.imu_covariances)
    imu_stamps, imu_logs = readings.header_ns('imu'), readings.log_ns('imu')
    for j in range(len(readings.imu_steps)):
        imu = types['sensor_msgs/msg/Imu'](
            header=header(imu_stamps[j], 'imu_link'),
            orientation=xyzw(readings.imu_orientation[j]), orientation_covariance=q_cov,
            angular_velocity=vector3(*readings.imu_angular_velocity[j]),
            angular_velocity_covariance=w_cov,
            linear_acceleration=vector3(*readings.imu_linear_acceleration[j]),
            linear_acceleration_covariance=a_cov)
        out.append(Record(TOPIC_IMU, imu_stamps[j], cdr(imu), imu_logs[j]))

    no_fix_cov, fix_cov = covariance([0.0] * 9), covariance(readings.fix_covariance)
    for stamp, log, llh in zip(readings.header_ns('fix'), readings.log_ns('fix'),
                               readings.fix_llh):
        if llh is None:     # the outage: a NO_FIX report
            status, (lat, lon, alt) = status_type.STATUS_NO_FIX, (math.nan,) * 3
            cov, cov_type = no_fix_cov, fix_type.COVARIANCE_TYPE_UNKNOWN
        else:
            status, (lat, lon, alt) = status_type.STATUS_FIX, llh
            cov, cov_type = fix_cov, fix_type.COVARIANCE_TYPE_DIAGONAL_KNOWN
        fix = fix_type(header=header(stamp, 'gnss'),
                       status=status_type(status=status, service=status_type.SERVICE_GPS),
                       latitude=float(lat), longitude=float(lon), altitude=float(alt),
                       position_covariance=cov, position_covariance_type=cov_type)
        out.append(Record(TOPIC_FIX, stamp, cdr(fix), log))

    velocity_cov = covariance(readings.velocity_covariance)
    for stamp, log, measured in zip(readings.header_ns('velocity'),
                                    readings.log_ns('velocity'), readings.velocity):
        velocity = types['geometry_msgs/msg/TwistWithCovarianceStamped'](
            header=header(stamp, 'base_link'),
            twist=twist(measured, (0.0, 0.0, 0.0), velocity_cov))
        out.append(Record(TOPIC_VELOCITY, stamp, cdr(velocity), log))

    zero36 = covariance([0.0] * 36)
    for j, k in enumerate(readings.truth_steps):
        stamp = stamps[k]
        u, v, heave, r = readings.truth_twist[j]
        odom = types['nav_msgs/msg/Odometry'](
            header=header(stamp, 'map'), child_frame_id='base_link',
            pose=types['geometry_msgs/msg/PoseWithCovariance'](
                pose=types['geometry_msgs/msg/Pose'](
                    position=types['geometry_msgs/msg/Point'](
                        *(float(c) for c in readings.truth_position[j])),
                    orientation=xyzw(readings.truth_orientation[j])),
                covariance=zero36),
            twist=twist((u, v, heave), (0.0, 0.0, r), zero36))
        out.append(Record(TOPIC_TRUTH_ODOMETRY, stamp, cdr(odom)))
        out.append(Record(TOPIC_TRUTH_COURSE_SIDESLIP, stamp,
                          vector3_stamped(stamp, 'base_link', readings.truth_course_sideslip[j])))
        out.append(Record(TOPIC_TRUTH_CURRENT, stamp,
                          vector3_stamped(stamp, 'map', readings.truth_current[j])))
        out.append(Record(TOPIC_TRUTH_CALIBRATION, stamp,
                          vector3_stamped(stamp, 'base_link', readings.calibration)))

    lat, lon, alt = readings.origin
    origin = fix_type(header=header(stamps[0], 'map'),
                      status=status_type(status=status_type.STATUS_FIX,
                                         service=status_type.SERVICE_GPS),
                      latitude=float(lat), longitude=float(lon), altitude=float(alt),
                      position_covariance=covariance([0.0] * 9),
                      position_covariance_type=fix_type.COVARIANCE_TYPE_KNOWN)
    out.append(Record(TOPIC_TRUTH_ORIGIN, stamps[0], cdr(origin)))

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

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


def _stamp(header: Any, stamp_ns: int) -> None:
    header.stamp.sec, header.stamp.nanosec = ns_to_stamp(stamp_ns)


def records(readings: Readings) -> list[Record]:
    """
    Return the readings as serialised messages (inputs and truth), in header-stamp order.

    Each input's ``log_ns`` is its arrival (:meth:`Readings.log_ns`), its stamp
    :meth:`Readings.header_ns`; the truth's log time is its stamp.
    """
    from geometry_msgs.msg import TwistWithCovarianceStamped, Vector3Stamped
    from nav_msgs.msg import Odometry
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import Imu, NavSatFix, NavSatStatus

    stamps = readings.stamps
    out: list[Record] = []

    imu = Imu()
    imu.header.frame_id = 'imu_link'
    (imu.orientation_covariance, imu.angular_velocity_covariance,
     imu.linear_acceleration_covariance) = readings.imu_covariances
    q_imu, gyro, accel = (readings.imu_orientation, readings.imu_angular_velocity,
                          readings.imu_linear_acceleration)
    imu_stamps, imu_logs = readings.header_ns('imu'), readings.log_ns('imu')
    for j in range(len(readings.imu_steps)):
        _stamp(imu.header, imu_stamps[j])
        o = imu.orientation
        o.x, o.y, o.z, o.w = q_imu[j]
        w = imu.angular_velocity
        w.x, w.y, w.z = gyro[j]
        a = imu.linear_acceleration
        a.x, a.y, a.z = accel[j]
        out.append(Record(TOPIC_IMU, imu_stamps[j], serialize_message(imu), imu_logs[j]))

    fix = NavSatFix()
    fix.header.frame_id = 'gnss'
    fix.status.service = NavSatStatus.SERVICE_GPS
    fix_stamps, fix_logs = readings.header_ns('fix'), readings.log_ns('fix')
    for stamp, log, llh in zip(fix_stamps, fix_logs, readings.fix_llh):
        if llh is None:     # the outage: a NO_FIX report
            fix.status.status = NavSatStatus.STATUS_NO_FIX
            fix.latitude = fix.longitude = fix.altitude = math.nan
            fix.position_covariance = [0.0] * 9
            fix.position_covariance_type = NavSatFix.COVARIANCE_TYPE_UNKNOWN
        else:
            fix.status.status = NavSatStatus.STATUS_FIX
            fix.latitude, fix.longitude, fix.altitude = llh
            fix.position_covariance = readings.fix_covariance
            fix.position_covariance_type = NavSatFix.COVARIANCE_TYPE_DIAGONAL_KNOWN
        _stamp(fix.header, stamp)
        out.append(Record(TOPIC_FIX, stamp, serialize_message(fix), log))

    twist = TwistWithCovarianceStamped()
    twist.header.frame_id = 'base_link'
    twist.twist.covariance = readings.velocity_covariance
    for stamp, log, measured in zip(readings.header_ns('velocity'),
                                    readings.log_ns('velocity'), readings.velocity):
        _stamp(twist.header, stamp)
        lin = twist.twist.twist.linear
        lin.x, lin.y, lin.z = measured
        out.append(Record(TOPIC_VELOCITY, stamp, serialize_message(twist), log))

    odom = Odometry()
    odom.header.frame_id = 'map'
    odom.child_frame_id = 'base_link'
    angles = Vector3Stamped()
    angles.header.frame_id = 'base_link'
    current = Vector3Stamped()
    current.header.frame_id = 'map'
    calibration = Vector3Stamped()
    calibration.header.frame_id = 'base_link'
    calibration.vector.x, calibration.vector.y, calibration.vector.z = readings.calibration
    for j, k in enumerate(readings.truth_steps):
        stamp = stamps[k]
        _stamp(odom.header, stamp)
        p = odom.pose.pose.position
        p.x, p.y, p.z = readings.truth_position[j]
        o = odom.pose.pose.orientation
        o.x, o.y, o.z, o.w = readings.truth_orientation[j]
        lin = odom.twist.twist.linear
        lin.x, lin.y, lin.z, odom.twist.twist.angular.z = readings.truth_twist[j]
        out.append(Record(TOPIC_TRUTH_ODOMETRY, stamp, serialize_message(odom)))
        _stamp(angles.header, stamp)
        angles.vector.x, angles.vector.y, angles.vector.z = readings.truth_course_sideslip[j]
        out.append(Record(TOPIC_TRUTH_COURSE_SIDESLIP, stamp, serialize_message(angles)))
        _stamp(current.header, stamp)
        current.vector.x, current.vector.y, current.vector.z = readings.truth_current[j]
        out.append(Record(TOPIC_TRUTH_CURRENT, stamp, serialize_message(current)))
        _stamp(calibration.header, stamp)
        out.append(Record(TOPIC_TRUTH_CALIBRATION, stamp, serialize_message(calibration)))

    origin = NavSatFix()
    origin.header.frame_id = 'map'
    _stamp(origin.header, stamps[0])
    origin.status.status = NavSatStatus.STATUS_FIX
    origin.status.service = NavSatStatus.SERVICE_GPS
    origin.latitude, origin.longitude, origin.altitude = readings.origin
    origin.position_covariance_type = NavSatFix.COVARIANCE_TYPE_KNOWN
    out.append(Record(TOPIC_TRUTH_ORIGIN, stamps[0], serialize_message(origin)))

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

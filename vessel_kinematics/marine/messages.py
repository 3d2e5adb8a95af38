"""
The navigator's input messages of a marine log: one builder per topic, as the given bags hold them.

The topics and conventions are those of the recordings in ``../shared/data`` (their README):

=================  ==========================================  =================================
topic              type                                        content
=================  ==========================================  =================================
``/fix``           sensor_msgs/NavSatFix, frame ``gnss``       latitude, longitude, ellipsoidal
                                                               height (NaN unknown, or beyond
                                                               the navigator's limits: a
                                                               receiver's fill); covariance
                                                               APPROXIMATED from the HDOP, else
                                                               UNKNOWN
``/imu``           sensor_msgs/Imu, frame ``base_link``        orientation from heading, pitch,
                                                               roll (REP-103 ENU/FLU); rate of
                                                               turn in angular_velocity.z; no
                                                               acceleration
``/speed_log``     geometry_msgs/TwistWithCovarianceStamped,   speed through water as surge x;
                   frame ``base_link``                         the rest unmeasured
``/gnss/cog_sog``  geometry_msgs/Vector3Stamped, frame         the receiver's COG (x, rad from
                   ``gnss``                                    north, clockwise) and SOG (y,
                                                               m/s): the reference the replay
                                                               scores against
``/vel``           geometry_msgs/TwistStamped, frame ``gnss``  the same COG/SOG as a velocity
                                                               over ground, ENU (x east, y
                                                               north; nmea_navsat_driver's
                                                               ``vel``): the ``gnss_velocity``
                                                               input
=================  ==========================================  =================================

Covariances (the bags' own):

* fix: sigma_h = :data:`UERE_M` x HDOP on east and north, twice that vertically (type
  APPROXIMATED); without an HDOP all zero, type UNKNOWN (the navigator then uses its
  ``gnss.default_sigma``);
* imu orientation (about x, y, z of ENU): heading :data:`HEADING_SIGMA`; roll and pitch
  :data:`ATTITUDE_SIGMA` when measured, else :data:`UNKNOWN_ANGLE_VARIANCE` ("unknown");
  a sensor's own accuracy (``$PASHR``) where it states one;
* imu angular velocity: with a rate of turn, z = -d psi/dt (ENU yaw rate; x, y zero) and
  :data:`RATE_SIGMA` on the three axes; without, element 0 = -1 (REP-145: no data);
  linear acceleration: element 0 = -1;
* speed log: :data:`SPEED_VARIANCE` on surge, :data:`UNMEASURED_VARIANCE` on the other five.

The messages are rosbags' dataclasses of ROS 2 Jazzy (no rclpy needed; the typestore of
:mod:`vessel_kinematics.tools.bags`, the one place rosbags is used), serialised to CDR by
:func:`~vessel_kinematics.tools.bags.serialize`: what the replay reads from a bag.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from vessel_kinematics.core import frames, quaternion
from vessel_kinematics.marine.records import Position
from vessel_kinematics.ros import input_limits, interface
from vessel_kinematics.tools import bags

__all__ = ['ATTITUDE_SIGMA', 'cog_sog_msg', 'COG_SOG_TOPIC', 'FIX_TOPIC', 'fix_msg',
           'GNSS_FRAME', 'GNSS_VELOCITY_TOPIC', 'gnss_velocity_msg', 'HEADING_SIGMA',
           'IMU_TOPIC', 'imu_msg', 'INPUT_TOPICS', 'RATE_SIGMA',
           'SPEED_TOPIC', 'SPEED_VARIANCE', 'speed_msg', 'BASE_FRAME', 'TOPICS', 'typestore',
           'UERE_M', 'UNKNOWN_ANGLE_VARIANCE', 'UNMEASURED_VARIANCE', 'VELOCITY_REFERENCE',
           'VERTICAL_FACTOR']

FIX_TOPIC = interface.topic('fix').absolute
IMU_TOPIC = interface.topic('imu').absolute
#: The speed log's topic (the bags' name; the replay reads it with ``velocity:=/speed_log``).
SPEED_TOPIC = '/speed_log'
COG_SOG_TOPIC = interface.topic('/gnss/cog_sog').absolute
#: The receiver's velocity over ground (nmea_navsat_driver's ``vel``, read as gnss_velocity).
GNSS_VELOCITY_TOPIC = '/vel'

#: Every topic of a marine log and its type (ROS 2 spelling), in this order.
TOPICS: dict[str, str] = {
    FIX_TOPIC: 'sensor_msgs/msg/NavSatFix',
    IMU_TOPIC: 'sensor_msgs/msg/Imu',
    SPEED_TOPIC: 'geometry_msgs/msg/TwistWithCovarianceStamped',
    COG_SOG_TOPIC: interface.topic('/gnss/cog_sog').msg_type or 'geometry_msgs/msg/Vector3Stamped',
    GNSS_VELOCITY_TOPIC: 'geometry_msgs/msg/TwistStamped',
}

#: The navigator's inputs and the topic each is read from (the replay's remaps).
INPUT_TOPICS: dict[str, str] = {'fix': FIX_TOPIC, 'imu': IMU_TOPIC, 'velocity': SPEED_TOPIC,
                                'gnss_velocity': GNSS_VELOCITY_TOPIC}

#: A speed log measures through the water (the navigator's ``velocity.reference``).
VELOCITY_REFERENCE = 'water'

GNSS_FRAME = 'gnss'
BASE_FRAME = 'base_link'

#: The user equivalent range error (m): sigma_h = UERE x HDOP (the bags' rule).
UERE_M = 2.5
#: The vertical sigma as a multiple of the horizontal one.
VERTICAL_FACTOR = 2.0
#: Heading standard deviation (rad) unless the sensor states one: 1 deg.
HEADING_SIGMA = math.radians(1.0)
#: Roll and pitch standard deviation (rad) of an attitude sensor: 0.5 deg.
ATTITUDE_SIGMA = math.radians(0.5)
#: The variance (rad^2) of an angle the log does not give: "unknown".
UNKNOWN_ANGLE_VARIANCE = 1e3
#: Rate of turn standard deviation (rad/s): 0.2 deg/s.
RATE_SIGMA = math.radians(0.2)
#: Speed through water variance (m^2/s^2): sigma 0.1 m/s.
SPEED_VARIANCE = 1e-2
#: The variance of what a speed log does not measure (sway, heave, rates).
UNMEASURED_VARIANCE = 1e6

_NO_DATA = np.array([-1.0, 0, 0, 0, 0, 0, 0, 0, 0])


def typestore() -> Any:
    """Return the ROS 2 Jazzy types (``tools.bags.jazzy``, shared: register nothing in it)."""
    return bags.jazzy()


def _types() -> dict[str, Any]:
    return typestore().types


def fix_msg(stamp_ns: int, p: Position) -> Any:
    """Return the sensor_msgs/NavSatFix of a position (covariance from its HDOP, if any)."""
    t = _types()
    status = t['sensor_msgs/msg/NavSatStatus'](status=p.status, service=1)   # SERVICE_GPS
    cov = np.zeros(9)
    cov_type = 0                                                             # UNKNOWN
    if p.status >= 0 and p.hdop is not None:
        horizontal = (UERE_M * p.hdop) ** 2
        cov[0] = cov[4] = horizontal
        cov[8] = VERTICAL_FACTOR ** 2 * horizontal
        cov_type = 1                                                         # APPROXIMATED
    lat, lon, height = (p.lat_deg, p.lon_deg, p.height_m) if p.status >= 0 else (
        math.nan, math.nan, math.nan)
    if not input_limits.MIN_HEIGHT <= height <= input_limits.MAX_HEIGHT:
        # A height no vessel has (a receiver filling the field, 1.4e12 m in one of canboat's
        # captures) leaves the horizontal fix usable: the navigator would refuse it whole.
        height = math.nan
    return t['sensor_msgs/msg/NavSatFix'](
        header=bags.header(stamp_ns, GNSS_FRAME), status=status, latitude=lat, longitude=lon,
        altitude=height, position_covariance=cov, position_covariance_type=cov_type)


def imu_msg(stamp_ns: int, psi: float, theta: float | None = None, phi: float | None = None,
            rate: float | None = None, var_psi: float | None = None,
            var_theta: float | None = None, var_phi: float | None = None) -> Any:
    """
    Return the sensor_msgs/Imu of a heading psi, pitch theta, roll phi (rad) and rate of turn.

    The orientation is q_nb of Fossen's zyx angles (eq. 2.18; an unknown roll or pitch is
    zero, with :data:`UNKNOWN_ANGLE_VARIANCE`) in ROS's ENU/FLU
    (:func:`~vessel_kinematics.core.frames.q_nb_to_ros`); ``rate`` d psi/dt (rad/s) becomes
    angular_velocity.z = -rate (about ENU's up). Variances None take the defaults of the module.
    """
    t = _types()
    q_xyzw = frames.q_nb_to_ros(quaternion.euler2q(0.0 if phi is None else phi,
                                                   0.0 if theta is None else theta, psi))
    x, y, z, w = (float(c) for c in q_xyzw)
    orientation_cov = np.zeros(9)
    orientation_cov[0] = (UNKNOWN_ANGLE_VARIANCE if phi is None else
                          ATTITUDE_SIGMA ** 2 if var_phi is None else var_phi)
    orientation_cov[4] = (UNKNOWN_ANGLE_VARIANCE if theta is None else
                          ATTITUDE_SIGMA ** 2 if var_theta is None else var_theta)
    orientation_cov[8] = HEADING_SIGMA ** 2 if var_psi is None else var_psi
    if rate is None:
        omega, omega_cov = bags.vector3(0.0, 0.0, 0.0), _NO_DATA.copy()
    else:
        omega = bags.vector3(0.0, 0.0, -rate)
        omega_cov = np.zeros(9)
        omega_cov[0] = omega_cov[4] = omega_cov[8] = RATE_SIGMA ** 2
    return t['sensor_msgs/msg/Imu'](
        header=bags.header(stamp_ns, BASE_FRAME),
        orientation=t['geometry_msgs/msg/Quaternion'](x=x, y=y, z=z, w=w),
        orientation_covariance=orientation_cov, angular_velocity=omega,
        angular_velocity_covariance=omega_cov, linear_acceleration=bags.vector3(0.0, 0.0, 0.0),
        linear_acceleration_covariance=_NO_DATA.copy())


def speed_msg(stamp_ns: int, speed: float) -> Any:
    """Return the geometry_msgs/TwistWithCovarianceStamped of a speed through water (m/s)."""
    t = _types()
    cov = np.zeros(36)
    cov[0] = SPEED_VARIANCE
    cov[7] = cov[14] = cov[21] = cov[28] = cov[35] = UNMEASURED_VARIANCE
    twist = t['geometry_msgs/msg/Twist'](linear=bags.vector3(speed, 0.0, 0.0),
                                         angular=bags.vector3(0.0, 0.0, 0.0))
    return t['geometry_msgs/msg/TwistWithCovarianceStamped'](
        header=bags.header(stamp_ns, BASE_FRAME),
        twist=t['geometry_msgs/msg/TwistWithCovariance'](twist=twist, covariance=cov))


def cog_sog_msg(stamp_ns: int, cog: float, sog: float) -> Any:
    """Return the geometry_msgs/Vector3Stamped of a true COG (rad) and SOG (m/s)."""
    return _types()['geometry_msgs/msg/Vector3Stamped'](header=bags.header(stamp_ns, GNSS_FRAME),
                                                        vector=bags.vector3(cog, sog, 0.0))


def gnss_velocity_msg(stamp_ns: int, cog: float, sog: float) -> Any:
    """
    Return the geometry_msgs/TwistStamped of a true COG (rad) and SOG (m/s): ENU, as ``vel``.

    nmea_navsat_driver's ``vel`` from the same RMC: x = SOG sin COG (east), y = SOG cos COG
    (north); no climb (z 0, unmeasured without a covariance), no rates.
    """
    t = _types()
    twist = t['geometry_msgs/msg/Twist'](
        linear=bags.vector3(sog * math.sin(cog), sog * math.cos(cog), 0.0),
        angular=bags.vector3(0.0, 0.0, 0.0))
    return t['geometry_msgs/msg/TwistStamped'](header=bags.header(stamp_ns, GNSS_FRAME),
                                               twist=twist)

"""
The inputs: sensor messages to the estimator's measurement records, or why they cannot be used.

REP-103/REP-145 conventions (ENU world, FLU body, ``xyzw`` quaternions, degrees in NavSatFix,
row-major covariances) become the estimator's Fossen frames (NED, FRD, scalar-first q_nb,
radians). A message that cannot be used becomes a :class:`~vessel_kinematics.estimation.
Rejection` (a value, never an exception). The functions only read attributes, so they take
rclpy messages, rosbags' deserialised dataclasses (same field names; arrays are numpy arrays in
both) and the Imu CDR view (:mod:`.imu_cdr`) alike. The sensor's mounting comes from the caller
(:mod:`.mountings`: /tf_static or the parameters).

Rejection reasons (members of :class:`~vessel_kinematics.estimation.Reason`, counted by their
value): ``nan_field`` (a used field is NaN or infinite), ``lat_out_of_range`` (|lat| > 90 deg or
|lon| > 180 deg), ``no_fix`` (status NO_FIX), ``zero_quaternion``, ``non_unit_quaternion``
(| |q| - 1 | > 1e-3; smaller deviations are normalised), ``no_data`` (an Imu with neither a
usable orientation nor a rate), and the plausibility limits on finite values: ``bad_stamp``
(negative, ``nanosec`` >= 1e9, or ``sec`` beyond what builtin_interfaces/Time can carry out),
``implausible_speed``, ``implausible_rate``, ``implausible_height`` and ``bad_covariance`` (a
used 3x3 covariance block that is not symmetric positive semi-definite or holds a variance above
:data:`MAX_VARIANCE`). The limits are the ``MAX_*``/``MIN_*`` constants of :mod:`.input_limits`
(re-exported here), each with its reason; the checks are plain float comparisons (the IMU's
run at 400 Hz).
"""

from __future__ import annotations

from functools import lru_cache
import math
from typing import Any, Sequence

import numpy as np
from sensor_msgs.msg import NavSatFix, NavSatStatus
from vessel_kinematics.core import frames, quaternion
from vessel_kinematics.core.quaternion import mul4
from vessel_kinematics.estimation import (BodyVelocity, GnssFix, GroundVelocity, ImuSample,
                                          Reason, Rejection)
from vessel_kinematics.estimation.config import UNMEASURED_VARIANCE
from vessel_kinematics.ros.imu_cdr import ImuCdr
from vessel_kinematics.ros.input_limits import (all_finite, bad_stamp, cov3_problem,
                                                COVARIANCE_TOLERANCE, MAX_BODY_RATE, MAX_HEIGHT,
                                                MAX_SPEED, MAX_STAMP_SEC, MAX_VARIANCE,
                                                MIN_HEIGHT, QUATERNION_NORM_TOLERANCE,
                                                stamp_problem)
from vessel_kinematics.ros.params import NavigatorParams
from vessel_kinematics.ros.static_tf import Mounting

__all__ = ['COVARIANCE_TOLERANCE', 'cov3_problem', 'fix_from_msg', 'ground_velocity_from_msg',
           'heading_from_msg', 'imu_from_msg',
           'MAX_BODY_RATE', 'MAX_HEIGHT', 'MAX_SPEED', 'MAX_STAMP_SEC', 'MAX_VARIANCE',
           'MIN_HEIGHT', 'QUATERNION_NORM_TOLERANCE', 'stamp_problem', 'velocity_from_msg']

_MAX_SPEED2 = MAX_SPEED * MAX_SPEED
_MAX_RATE2 = MAX_BODY_RATE * MAX_BODY_RATE

_NS = frames.NS_PER_S


def _stamp_ns(stamp: Any) -> int:
    return frames.stamp_to_ns(stamp.sec, stamp.nanosec)


def _cov3(flat: Any) -> np.ndarray:
    return np.asarray(flat, dtype=float).reshape(3, 3)


def fix_from_msg(msg: NavSatFix, params: NavigatorParams,
                 mounting: Mounting | None = None) -> GnssFix | Rejection:
    """
    Return the fix of a sensor_msgs/NavSatFix, or why it cannot be used.

    Latitude and longitude in degrees become radians; a NaN altitude is a horizontal-only
    fix; the ENU covariance becomes NED, and an unknown one (type UNKNOWN, or all zero)
    ``gnss.default_sigma`` on each axis. ``mounting``: the antenna frame in the base frame
    (from /tf_static): its translation (FLU) becomes the fix's lever arm (FRD); None: the
    estimator's ``gnss.antenna_position``.
    """
    if msg.status.status == NavSatStatus.STATUS_NO_FIX:
        return Rejection(Reason.NO_FIX, 'NavSatFix status is NO_FIX')
    bad = bad_stamp(msg.header.stamp)
    if bad is not None:
        return bad
    lat, lon, alt = msg.latitude, msg.longitude, msg.altitude
    cov = msg.position_covariance
    if not (math.isfinite(lat) and math.isfinite(lon)) or math.isinf(alt):
        return Rejection(Reason.NAN_FIELD, 'NavSatFix latitude/longitude not finite or '
                                           'altitude infinite')
    if abs(lat) > 90.0 or abs(lon) > 180.0:
        return Rejection(Reason.LAT_OUT_OF_RANGE,
                         f'latitude {lat} or longitude {lon} deg out of range')
    if alt < MIN_HEIGHT or alt > MAX_HEIGHT:  # NaN (horizontal only) compares False
        return Rejection(Reason.IMPLAUSIBLE_HEIGHT,
                         f'NavSatFix altitude {alt} m outside [{MIN_HEIGHT:g}, {MAX_HEIGHT:g}]')
    known = msg.position_covariance_type != NavSatFix.COVARIANCE_TYPE_UNKNOWN
    if known:
        flat = cov.tolist() if isinstance(cov, np.ndarray) else list(cov)
        if not math.isfinite(sum(flat)):
            return Rejection(Reason.NAN_FIELD, 'NavSatFix covariance not finite')
        problem = cov3_problem(flat)
        if problem is not None:
            return Rejection(Reason.BAD_COVARIANCE, f'NavSatFix covariance: {problem}')
    if known and (cov[0] > 0.0 or cov[4] > 0.0):
        cov_ned = frames.cov3_enu_to_ned(_cov3(cov))
        if cov_ned[2, 2] <= 0.0:
            cov_ned[2, 2] = params.gnss_default_sigma ** 2
    else:
        cov_ned = np.eye(3) * params.gnss_default_sigma ** 2
    if mounting is not None:
        return GnssFix(_stamp_ns(msg.header.stamp), math.radians(lat), math.radians(lon),
                       float(alt), cov_ned, lever_b=frames.flip_body3(*mounting.t))
    return GnssFix(_stamp_ns(msg.header.stamp), math.radians(lat), math.radians(lon),
                   float(alt), cov_ned)


@lru_cache(maxsize=8)
def _mounting(rpy: tuple[float, float, float],
              yaw_offset: float) -> tuple[tuple, tuple, tuple]:
    """
    Return (q_mount⁻¹, q_yaw, R_mount) in ROS terms, scalar first.

    q_mount rotates the IMU frame into the base frame, R = Rz(yaw) Ry(pitch) Rx(roll) (the same
    zyx formula as Fossen's Euler angles); q_yaw rotates about the world up axis by
    ``imu.yaw_offset`` (counter-clockwise, ENU).
    """
    q_mount = quaternion.euler2q(*rpy)
    inverse = tuple(quaternion.quat_conjugate(q_mount).tolist())
    half = 0.5 * yaw_offset
    q_yaw = (math.cos(half), 0.0, 0.0, math.sin(half))
    return inverse, q_yaw, tuple(tuple(row) for row in quaternion.rquat(q_mount).tolist())


@lru_cache(maxsize=8)
def _mounting_q(q_mount: tuple[float, float, float, float],
                yaw_offset: float) -> tuple[tuple, tuple, tuple]:
    """Return (q_mount⁻¹, q_yaw, R_mount) as :func:`_mounting`, of a mounting quaternion."""
    w, x, y, z = q_mount
    half = 0.5 * yaw_offset
    q_yaw = (math.cos(half), 0.0, 0.0, math.sin(half))
    return ((w, -x, -y, -z), q_yaw,
            tuple(tuple(row) for row in quaternion.rquat(q_mount).tolist()))


_ImuCov = tuple[bool, bool, 'np.ndarray | None', 'str | None']
# A driver sends the same covariance in every message: checked and rotated once per value
# (its bytes and the mounting), because checking and rotating it per message at 400 Hz is the
# difference between the node's CPU guard met and not (docs/performance.md). Keyed by value,
# not by object: any message of those values hits.
_IMU_COV_CACHE: dict[tuple[bytes, tuple], _ImuCov] = {}


def _imu_cov(flat: Any, rpy: tuple[float, ...]) -> _ImuCov:
    """
    Return (marked unused, finite, 3x3 covariance in the base frame FRD or None, problem).

    ``rpy``: the mounting as roll, pitch, yaw, or (4 numbers) as a quaternion, scalar first.

    ``marked unused``: element 0 is -1 (REP-145: no such data). ``problem``: why a finite,
    used covariance is unusable (:func:`cov3_problem`), else None. Cached by value (a tuple
    of floats as it is, any other sequence by its float64 bytes): the returned array is shared
    and read only.
    """
    key: tuple = (flat if type(flat) is tuple else np.asarray(flat, dtype=float).tobytes(), rpy)
    try:
        return _IMU_COV_CACHE[key]
    except KeyError:
        pass
    arr = np.asarray(flat, dtype=float).reshape(-1)
    unused = bool(arr[0] == -1.0)
    finite = all_finite(arr)
    out = problem = None
    if finite and not unused:
        problem = cov3_problem(arr.tolist())
    if finite and not unused and problem is None and np.any(arr):
        r_mount = quaternion.rquat(rpy if len(rpy) == 4 else quaternion.euler2q(*rpy))
        out = frames.cov3_flu_to_frd(r_mount @ arr.reshape(3, 3) @ r_mount.T)
        out.flags.writeable = False
    if len(_IMU_COV_CACHE) > 256:
        _IMU_COV_CACHE.clear()
    result = (unused, finite, out, problem)
    _IMU_COV_CACHE[key] = result
    return result


def _q_nb(ow: float, ox: float, oy: float, oz: float, q_yaw: tuple, mount_inv: tuple,
          what: str) -> Any:
    """
    Return Fossen's q_nb (tuple, scalar first, η >= 0) of a REP-103 orientation, or why not.

    q_base = q_yaw ⊗ q_sensor ⊗ q_mount⁻¹ (the mounting taken off, ``imu.yaw_offset`` about
    the vertical), then the attitude swap ENU/FLU -> NED/FRD (:mod:`~vessel_kinematics.core.
    frames`). A norm off 1 by more than :data:`QUATERNION_NORM_TOLERANCE` is refused, less is
    normalised.
    """
    norm = math.sqrt(ow * ow + ox * ox + oy * oy + oz * oz)
    if norm < 1e-6:
        return Rejection(Reason.ZERO_QUATERNION, f'{what} orientation is the zero quaternion')
    if abs(norm - 1.0) > QUATERNION_NORM_TOLERANCE:
        return Rejection(Reason.NON_UNIT_QUATERNION, f'{what} orientation has norm {norm:.6f}')
    q_sensor = (ow / norm, ox / norm, oy / norm, oz / norm)
    q_nb = frames.swap_attitude4(*mul4(q_yaw, mul4(q_sensor, mount_inv)))
    if q_nb[0] < 0.0:
        q_nb = (-q_nb[0], -q_nb[1], -q_nb[2], -q_nb[3])
    return q_nb


def _imu_mounting(params: NavigatorParams, mounting: Mounting | None) -> tuple:
    """Return (rpy or q_mount, q_mount⁻¹, q_yaw, R_mount) of a mounting or the parameters."""
    if mounting is None:
        rpy: tuple[float, ...] = params.imu_mounting(0)
        return (rpy, *_mounting(rpy, params.imu_yaw_offset))
    return (mounting.q, *_mounting_q(mounting.q, params.imu_yaw_offset))


def heading_from_msg(msg: Any, params: NavigatorParams,
                     mounting: Mounting | None = None) -> ImuSample | Rejection:
    """
    Return the attitude of a geometry_msgs/QuaternionStamped heading (``imu.source: quaternion``).

    The quaternion is a REP-103 orientation (sensor frame FLU to ENU, ``xyzw``), taken as
    :func:`imu_from_msg` takes an Imu's: the mounting (``mounting``, else ``imu.mounting_rpy``)
    and ``imu.yaw_offset`` applied. It carries no covariance (the estimator's default attitude
    σ) and no rate: the estimator derives the yaw rate from successive headings (a least-squares
    slope over its last seconds) and integrates the heading forward with it between them.
    """
    _, mount_inv, q_yaw, _ = _imu_mounting(params, mounting)
    bad = bad_stamp(msg.header.stamp)
    if bad is not None:
        return bad
    q = msg.quaternion
    ox, oy, oz, ow = q.x, q.y, q.z, q.w
    if not math.isfinite(ow + ox + oy + oz):
        return Rejection(Reason.NAN_FIELD, 'QuaternionStamped quaternion not finite')
    q_nb = _q_nb(ow, ox, oy, oz, q_yaw, mount_inv, 'QuaternionStamped')
    if type(q_nb) is Rejection:
        return q_nb
    return ImuSample(_stamp_ns(msg.header.stamp), q_nb, None, None, None)


def _twist_of(msg: Any) -> Any:
    """
    Return (Twist, its 6x6 covariance or None) of a stamped twist message, or a bad stamp.

    Duck-typed (rclpy messages, or rosbags' dataclasses of the same fields): TwistStamped holds
    a Twist, TwistWithCovarianceStamped and Odometry a TwistWithCovariance.
    """
    twist = msg.twist
    cov = getattr(twist, 'covariance', None)
    if cov is not None:
        twist = twist.twist
    bad = bad_stamp(msg.header.stamp)
    return bad if bad is not None else (twist, cov)


def ground_velocity_from_msg(msg: Any, params: NavigatorParams,
                             mounting: Mounting | None = None) -> GroundVelocity | Rejection:
    """
    Return a receiver's velocity over ground (``gnss_velocity``): ENU Twist(WithCovariance)Stamped.

    nmea_navsat_driver's ``vel`` convention: ``twist.linear`` is the antenna's velocity over
    ground in ENU (x east, y north, z up; m/s), the angular part unused. It becomes NED
    [v_N, v_E, v_D]; the covariance's linear block ENU -> NED, ``gnss_velocity.default_sigma``
    per horizontal axis when absent, all zero or marked -1; without a covariance the vertical
    is not measured (TwistStamped: a receiver's course and speed have no climb). ``mounting``
    (the frame's in /tf_static): its translation is the antenna's lever arm; None: topic 0's
    ``gnss.antenna_position`` (the estimator's).
    """
    parts = _twist_of(msg)
    if type(parts) is Rejection:
        return parts
    twist, cov = parts
    lin = twist.linear
    east, north, up = lin.x, lin.y, lin.z
    if not all_finite((east, north)):
        return Rejection(Reason.NAN_FIELD, 'receiver velocity not finite')
    speed2 = east * east + north * north + (up * up if math.isfinite(up) else 0.0)
    if speed2 > _MAX_SPEED2:
        return Rejection(Reason.IMPLAUSIBLE_SPEED, f'receiver speed {math.sqrt(speed2):g} m/s '
                                                   f'exceeds {MAX_SPEED:g}')
    sigma2 = params.gnss_velocity_default_sigma ** 2
    lin_cov = None
    if cov is not None and float(np.asarray(cov, dtype=float).reshape(-1)[0]) != -1.0:
        block = np.asarray(cov, dtype=float).reshape(6, 6)[0:3, 0:3]
        if not np.isfinite(block).all():
            return Rejection(Reason.NAN_FIELD, 'receiver velocity covariance not finite')
        if np.any(block):
            problem = cov3_problem(block.reshape(9).tolist())
            if problem is not None:
                return Rejection(Reason.BAD_COVARIANCE, f'receiver velocity covariance: {problem}')
            lin_cov = frames.cov3_enu_to_ned(block)
            for i in range(3):
                if lin_cov[i, i] <= 0.0:
                    lin_cov[i, i] = sigma2
    if lin_cov is None:
        lin_cov = np.diag([sigma2, sigma2, sigma2 if cov is not None else UNMEASURED_VARIANCE])
    v_ned = np.array([north, east, -up if math.isfinite(up) else math.nan], dtype=float)
    lever = None if mounting is None else frames.flip_body3(*mounting.t)
    return GroundVelocity(_stamp_ns(msg.header.stamp), v_ned, lin_cov, lever)


def imu_from_msg(msg: Any, params: NavigatorParams,
                 mounting: Mounting | None = None) -> ImuSample | Rejection:
    """
    Return the attitude and body rate of the base frame from a sensor_msgs/Imu (REP-145).

    Orientation (IMU frame FLU to ENU, ``xyzw``) is used unless ``imu.use_orientation`` is
    false or ``orientation_covariance[0] == -1``; it is turned into the base frame with the
    mounting (q_base = q_imu ⊗ q_mount⁻¹), rotated by ``imu.yaw_offset`` about the vertical,
    then into Fossen's q_nb. The rate is used unless ``angular_velocity_covariance[0] == -1``:
    ω_base = R_mount ω_imu, FLU to FRD. Linear acceleration is not used (not checked).
    ``q_nb`` and ``omega_b`` come as tuples of floats (the estimator's scalar path).
    ``mounting``: the IMU frame in the base frame (from /tf_static; its rotation is used);
    None: ``imu.mounting_rpy``.
    """
    rpy, mount_inv, q_yaw, r_mount = _imu_mounting(params, mounting)
    stamp = msg.header.stamp
    sec, nanosec = stamp.sec, stamp.nanosec
    if not (0 <= sec <= MAX_STAMP_SEC and 0 <= nanosec < _NS):
        return Rejection(Reason.BAD_STAMP, stamp_problem(sec, nanosec) or 'bad stamp')
    stamp_ns = frames.stamp_to_ns(sec, nanosec)
    if type(msg) is ImuCdr:
        v = msg.values
        ox, oy, oz, ow, x, y, z = v[0], v[1], v[2], v[3], v[13], v[14], v[15]
        q_flat, omega_flat = v[4:13], v[16:25]
    else:
        o, r = msg.orientation, msg.angular_velocity
        ox, oy, oz, ow, x, y, z = o.x, o.y, o.z, o.w, r.x, r.y, r.z
        q_flat, omega_flat = msg.orientation_covariance, msg.angular_velocity_covariance
    q_nb = att_cov = omega = omega_cov = None
    if params.imu_use_orientation:
        unused, finite, cov, problem = _imu_cov(q_flat, rpy)
        if not unused:
            if not finite or not math.isfinite(ow + ox + oy + oz):
                return Rejection(Reason.NAN_FIELD,
                                 'Imu orientation or its covariance not finite')
            if problem is not None:
                return Rejection(Reason.BAD_COVARIANCE,
                                 f'Imu orientation covariance: {problem}')
            q_nb = _q_nb(ow, ox, oy, oz, q_yaw, mount_inv, 'Imu')
            if type(q_nb) is Rejection:
                return q_nb
            att_cov = cov
    unused, finite, cov, problem = _imu_cov(omega_flat, rpy)
    if not unused:
        if not finite or not math.isfinite(x + y + z):
            return Rejection(Reason.NAN_FIELD,
                             'Imu angular velocity or its covariance not finite')
        if problem is not None:
            return Rejection(Reason.BAD_COVARIANCE,
                             f'Imu angular velocity covariance: {problem}')
        if x * x + y * y + z * z > _MAX_RATE2:
            return Rejection(Reason.IMPLAUSIBLE_RATE,
                             f'Imu angular velocity |ω| = {math.sqrt(x * x + y * y + z * z):g}'
                             f' rad/s exceeds {MAX_BODY_RATE:g}')
        (r0, r1, r2) = r_mount
        omega = frames.flip_body3(r0[0] * x + r0[1] * y + r0[2] * z,   # R_mount ω, FLU -> FRD
                                  r1[0] * x + r1[1] * y + r1[2] * z,
                                  r2[0] * x + r2[1] * y + r2[2] * z)
        omega_cov = cov
    if q_nb is None and omega is None:
        return Rejection(Reason.NO_DATA, 'Imu without a usable orientation or angular velocity')
    return ImuSample(stamp_ns, q_nb, att_cov, omega, omega_cov)


def _twist_cov(cov: Any, sigma2: float) -> Rejection | tuple[np.ndarray, bool, np.ndarray | None]:
    """
    Return (linear 3x3 FRD, rate usable, angular 3x3 FRD or None) of a FLU twist covariance.

    ``cov`` None (TwistStamped), all zero or marked -1 gives ``sigma2`` on each linear axis;
    a zero linear variance becomes ``sigma2``.
    """
    arr = None if cov is None else np.asarray(cov, dtype=float)
    lin_cov = omega_cov = None
    rate_ok = True
    result: Any
    if arr is not None and arr.reshape(-1)[0] != -1.0:
        c = np.asarray(arr, dtype=float).reshape(6, 6)
        ang_cov = c[3:6, 3:6]
        ang_used = c[3, 3] != -1.0 and bool(np.isfinite(ang_cov).all())
        lin_problem = ang_problem = None
        if np.isfinite(c[0:3, 0:3]).all() and np.any(c[0:3, 0:3]):
            lin_problem = cov3_problem(c[0:3, 0:3].reshape(9).tolist())
        if ang_used:
            ang_problem = cov3_problem(ang_cov.reshape(9).tolist())
        if not np.isfinite(c[0:3, 0:3]).all():
            result = Rejection(Reason.NAN_FIELD, 'velocity covariance not finite')
        elif lin_problem is not None:
            result = Rejection(Reason.BAD_COVARIANCE,
                               f'velocity covariance (linear): {lin_problem}')
        elif ang_problem is not None:
            result = Rejection(Reason.BAD_COVARIANCE,
                               f'velocity covariance (angular): {ang_problem}')
        else:
            if np.any(c[0:3, 0:3]):
                lin_cov = frames.cov3_flu_to_frd(c[0:3, 0:3])
            if not ang_used:
                rate_ok = False
            elif np.any(ang_cov):
                omega_cov = frames.cov3_flu_to_frd(ang_cov)
            result = None
    else:
        result = None
    if result is None:
        if lin_cov is None:
            lin_cov = np.eye(3) * sigma2
        else:
            for i in range(3):
                if lin_cov[i, i] <= 0.0:
                    lin_cov[i, i] = sigma2
        result = (lin_cov, rate_ok, omega_cov)
    return result


def velocity_from_msg(msg: Any, params: NavigatorParams, mounting: Mounting | None = None,
                      rate_flu: Sequence[float] | None = None) -> BodyVelocity | Rejection:
    """
    Return the body velocity of a TwistWithCovarianceStamped, TwistStamped or Odometry.

    The twist is the sensor frame's velocity in FLU (Odometry: its twist, in the child
    frame); it becomes FRD. A covariance that is absent, all zero or marked -1 gives
    ``velocity.default_sigma`` on each axis. The angular part is passed on as a body rate
    (used when the IMU gives none) unless its covariance is marked -1 or not finite.

    The sensor's mounting (``mounting`` from /tf_static, else ``velocity.mounting_rpy`` and
    ``velocity.sensor_position``; none by default) turns it into the base frame's velocity
    by rigid-body kinematics (v_sensor = v_base + ω × r): v_base = R v_sensor − ω × r, R the
    sensor's rotation into the base frame, r its position in the base frame, ω the body rate
    (FLU): ``rate_flu`` when given (the pipeline passes the IMU's latest rate), else the
    message's own angular part (rotated by R) when usable, else zero. The covariances
    (linear and angular) are rotated by R; the rate's uncertainty in ω × r is not added.
    """
    parts = _twist_of(msg)
    if type(parts) is Rejection:
        return parts
    twist, cov = parts
    lin, ang = twist.linear, twist.angular
    nu = (lin.x, lin.y, lin.z)
    if not all_finite(nu):
        return Rejection(Reason.NAN_FIELD, 'velocity not finite')
    speed2 = nu[0] * nu[0] + nu[1] * nu[1] + nu[2] * nu[2]
    if speed2 > _MAX_SPEED2:
        return Rejection(Reason.IMPLAUSIBLE_SPEED, f'body speed {math.sqrt(speed2):g} m/s '
                                                   f'exceeds {MAX_SPEED:g}')
    rate = (ang.x, ang.y, ang.z)
    converted = _twist_cov(cov, params.velocity_default_sigma ** 2)
    if isinstance(converted, Rejection):
        return converted
    lin_cov, cov_rate_ok, omega_cov = converted
    rate_ok = cov_rate_ok and all_finite(rate)
    omega = None
    if rate_ok:
        rate2 = rate[0] * rate[0] + rate[1] * rate[1] + rate[2] * rate[2]
        if rate2 > _MAX_RATE2:
            return Rejection(Reason.IMPLAUSIBLE_RATE, f'velocity angular rate '
                                                      f'{math.sqrt(rate2):g} rad/s exceeds '
                                                      f'{MAX_BODY_RATE:g}')
        omega = np.array([rate[0], -rate[1], -rate[2]], dtype=float)
    if mounting is None:
        mounting = _velocity_mounting(params.velocity_mounting_rpy,
                                      params.velocity_sensor_position)
    if mounting is not None:
        return _mounted_velocity(_stamp_ns(msg.header.stamp), nu, lin_cov,
                                 rate if rate_ok else None, omega_cov, mounting, rate_flu)
    return BodyVelocity(_stamp_ns(msg.header.stamp),
                        np.array([nu[0], -nu[1], -nu[2]], dtype=float), lin_cov, omega, omega_cov)


@lru_cache(maxsize=8)
def _velocity_mounting(rpy: tuple[float, float, float],
                       position: tuple[float, float, float]) -> Mounting | None:
    """Return the velocity sensor's mounting of the parameters, None when there is none."""
    if not any(rpy) and not any(position):
        return None
    w, x, y, z = (float(c) for c in quaternion.euler2q(*rpy))
    return Mounting((w, x, y, z), (float(position[0]), float(position[1]), float(position[2])),
                    'parameters')


_FLU_FRD = frames.A_BODY      # FLU <-> FRD as a matrix (3x3)


def _mounted_velocity(stamp_ns: int, nu: tuple[float, float, float], lin_cov: np.ndarray,
                      rate: tuple[float, float, float] | None, omega_cov: np.ndarray | None,
                      mounting: Mounting, rate_flu: Sequence[float] | None) -> BodyVelocity:
    """
    Return the base frame's velocity of a mounted sensor: v = R v_s − ω × r (FLU in, FRD out).

    ``nu``, ``rate``: the sensor's linear and angular velocity (FLU, sensor axes; ``rate``
    None when unusable); ``lin_cov``, ``omega_cov``: their covariances (FRD, sensor axes).
    """
    r_flu = quaternion.rquat(mounting.q)
    r_frd = _FLU_FRD @ r_flu @ _FLU_FRD
    v = r_flu @ np.array(nu, dtype=float)
    omega_flu = None if rate is None else r_flu @ np.array(rate, dtype=float)
    w = rate_flu if rate_flu is not None else omega_flu
    if w is not None:
        v = v - np.cross(np.asarray(w, dtype=float), np.array(mounting.t, dtype=float))
    cov = r_frd @ lin_cov @ r_frd.T
    omega = None if omega_flu is None else _FLU_FRD @ omega_flu
    if omega_cov is not None:
        omega_cov = r_frd @ omega_cov @ r_frd.T
    return BodyVelocity(stamp_ns, _FLU_FRD @ v, 0.5 * (cov + cov.T), omega,
                        None if omega_cov is None else 0.5 * (omega_cov + omega_cov.T))

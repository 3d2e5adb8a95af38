"""
The edge: ROS messages to measurements, the navigation state back to ROS messages.

The only module of the core that knows message types. Inbound, REP-103/REP-145 conventions
(ENU world, FLU body, ``xyzw`` quaternions, degrees in NavSatFix, row-major covariances) become
the estimator's Fossen frames (NED, FRD, scalar-first q_nb, radians); a message that cannot be
used becomes an :class:`~vessel_kinematics.estimation.Rejection` (a value, never an exception).
Outbound, :class:`~vessel_kinematics.estimation.NavState` becomes nav_msgs/Odometry (ENU/FLU
and Fossen's NED/FRD), Vector3Stamped, NavSatFix, TransformStamped and DiagnosticArray.

Rejection reasons of the conversions (members of
:class:`~vessel_kinematics.estimation.Reason`, counted by their value): ``nan_field`` (a used
field is NaN or infinite), ``lat_out_of_range`` (|lat| > 90 deg or |lon| > 180 deg),
``no_fix`` (status NO_FIX), ``zero_quaternion``, ``non_unit_quaternion`` (| |q| - 1 | > 1e-3;
smaller deviations are normalised), ``no_data`` (an Imu with neither a usable orientation nor
a rate), and the plausibility limits on finite values: ``bad_stamp`` (negative, ``nanosec`` >=
1e9, or ``sec`` beyond what builtin_interfaces/Time can carry out), ``implausible_speed``,
``implausible_rate``, ``implausible_height`` and ``bad_covariance`` (a used 3x3 covariance
block that is not symmetric positive semi-definite or holds a variance above
:data:`MAX_VARIANCE`). The limits are the ``MAX_*``/``MIN_*`` constants below, each with its
reason; the checks are plain float comparisons (the IMU's run at 400 Hz).
"""

from __future__ import annotations

from functools import lru_cache
import math
import os
import struct
from typing import AbstractSet, Any, Callable, Iterator, NamedTuple, Sequence

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import (Point, Pose, PoseWithCovariance, Quaternion, TransformStamped,
                               Twist, TwistWithCovariance, Vector3, Vector3Stamped)
from nav_msgs.msg import Odometry
import numpy as np
from sensor_msgs.msg import NavSatFix, NavSatStatus
from std_msgs.msg import Header
from vessel_kinematics.core import frames, geodesy, quaternion
from vessel_kinematics.core.quaternion import mul4
from vessel_kinematics.estimation import (BodyVelocity, GnssFix, ImuSample, Mode, NavPose,
                                          NavState, Reason, Rejection)
from vessel_kinematics.ros import interface
from vessel_kinematics.ros.params import NavigatorParams
from vessel_kinematics.ros.static_tf import Mounting, StaticTransform

__all__ = ['CDR_BUILDERS', 'CDR_LE', 'course_sideslip_msg', 'cov3_problem', 'COVARIANCE_TOLERANCE',
           'current_msg', 'diagnostic_status', 'diagnostics_array_msg', 'diagnostics_cdr',
           'diagnostics_msg', 'ERROR', 'filtered_fix_msg', 'fix_from_msg', 'FRD_SUFFIX',
           'imu_from_cdr', 'imu_from_msg', 'imu_from_raw', 'ImuCdr', 'iter_state_msgs',
           'MAX_BODY_RATE', 'MAX_HEIGHT', 'MAX_SPEED',
           'MAX_STAMP_SEC', 'MAX_VARIANCE', 'MIN_HEIGHT', 'MSG_BUILDERS', 'NED_SUFFIX',
           'ns_to_stamp',
           'odometry_msgs', 'OK', 'origin_cdr', 'origin_msg', 'OutputBuilder', 'parts_of',
           'POSE_OUTPUTS',
           'QUATERNION_NORM_TOLERANCE', 'relative_flow_msg', 'stamp_problem', 'stamp_to_ns',
           'STATE_OUTPUTS', 'state_msgs', 'static_transform_msgs', 'static_transforms_from_msg',
           'tf_cdr', 'transform_msg', 'transform_msgs', 'transform_parts', 'TransformParts',
           'velocity_from_msg', 'WARN']

#: A quaternion whose norm differs from 1 by more than this is rejected; less is normalised.
QUATERNION_NORM_TOLERANCE = 1e-3

#: Largest body speed |ν| accepted (m/s), 194 kn. Fast ferries and patrol craft do 20-30 m/s,
#: racing hydroplanes under 100 m/s; a ground robot far less. Only outright water-speed
#: record attempts (142 m/s) go beyond, and they are not this package's users. A larger
#: reading is a sensor or driver fault, and dead-reckoning it would throw the track km away.
MAX_SPEED = 100.0

#: Largest body rate |ω| accepted (rad/s), 1146 deg/s or 3.2 turns/s. A vessel's roll rate
#: stays below ~2 rad/s and its yaw rate far below; the bound is 10x that and below the
#: ±2000 deg/s full scale of common MEMS gyros, so only spikes and glitches exceed it.
MAX_BODY_RATE = 20.0

#: Lowest ellipsoidal height of a fix accepted (m): below the deepest ocean floor (Challenger
#: Deep, -10.9 km, geoid-ellipsoid separation at most ±110 m) with margin.
MIN_HEIGHT = -12_000.0

#: Highest ellipsoidal height of a fix accepted (m): above any aircraft-borne or balloon
#: survey (the stratosphere ends at 50 km); no vessel or robot fixes from higher.
MAX_HEIGHT = 50_000.0

#: Largest header stamp ``sec`` accepted: builtin_interfaces/Time.sec is an int32, and the
#: outputs carry the inputs' stamps, so a later stamp would come out wrapped negative (ROS 1
#: bags hold uint32 seconds, garbage CDR anything).
MAX_STAMP_SEC = 2 ** 31 - 1

#: Largest variance accepted in a used covariance (m², (m/s)², rad², (rad/s)²): σ = 1e6 is
#: beyond "unknown" (drivers mark unobserved axes with 1e3 .. 1e6 variances), and products of
#: two such variances (1e24) stay far from overflow in the filter.
MAX_VARIANCE = 1e12

#: Relative tolerance of the covariance checks: |c_ij - c_ji| <= tol sqrt(c_ii c_jj), and the
#: smallest eigenvalue >= -tol trace (rounding of drivers that compute their covariance in
#: float32 or print it with few digits passes; a singular, e.g. rank-1, covariance too).
COVARIANCE_TOLERANCE = 1e-6

_MAX_SPEED2 = MAX_SPEED * MAX_SPEED
_MAX_RATE2 = MAX_BODY_RATE * MAX_BODY_RATE

_NS = frames.NS_PER_S
_SQRT_HALF = math.sqrt(0.5)


def stamp_to_ns(stamp: Any) -> int:
    """Return a builtin_interfaces/Time message as integer nanoseconds (frames.stamp_to_ns)."""
    return frames.stamp_to_ns(stamp.sec, stamp.nanosec)


def ns_to_stamp(ns: int) -> Time:
    """Return integer nanoseconds as a builtin_interfaces/Time."""
    sec, nanosec = divmod(int(ns), _NS)
    return Time(sec=sec, nanosec=nanosec)


def stamp_problem(sec: int, nanosec: int) -> str | None:
    """Return why a header stamp is unusable (see :data:`MAX_STAMP_SEC`), None if it is fine."""
    if not 0 <= nanosec < _NS:
        return f'stamp nanosec {nanosec} is not in [0, 1e9)'
    if sec < 0:
        return f'stamp sec {sec} is negative'
    if sec > MAX_STAMP_SEC:
        return f'stamp sec {sec} exceeds {MAX_STAMP_SEC} (int32 builtin_interfaces/Time)'
    return None


def _bad_stamp(stamp: Any) -> Rejection | None:
    """Return the rejection of an unusable stamp, None if it is fine (two comparisons)."""
    sec, nanosec = stamp.sec, stamp.nanosec
    if 0 <= sec <= MAX_STAMP_SEC and 0 <= nanosec < _NS:
        return None
    return Rejection(Reason.BAD_STAMP, stamp_problem(sec, nanosec) or 'bad stamp')


def cov3_problem(c: Sequence[float]) -> str | None:
    """
    Return why a row-major 3x3 covariance (9 finite floats) is unusable, None if it is fine.

    Usable: variances in [0, :data:`MAX_VARIANCE`], symmetric (|c_ij - c_ji| <= tol
    sqrt(c_ii c_jj)), and positive semi-definite to tol: every principal minor (the three 2x2
    and the determinant) of C + tol trace(C) I is >= 0, which for a symmetric matrix means its
    smallest eigenvalue is >= -tol trace(C) (tol = :data:`COVARIANCE_TOLERANCE`). Plain float
    arithmetic, no numpy.
    """
    a, b, c2, d, e, f, g, h, i = (float(v) for v in c)
    for v in (a, e, i):
        if v < 0.0:
            return 'a negative variance'
        if v > MAX_VARIANCE:
            return f'a variance above {MAX_VARIANCE:g}'
    tol = COVARIANCE_TOLERANCE
    if (abs(b - d) > tol * math.sqrt(a * e) or abs(c2 - g) > tol * math.sqrt(a * i)
            or abs(f - h) > tol * math.sqrt(e * i)):
        return 'not symmetric'
    shift = tol * (a + e + i)
    a, e, i = a + shift, e + shift, i + shift
    b, c2, f = 0.5 * (b + d), 0.5 * (c2 + g), 0.5 * (f + h)
    if a * e < b * b or a * i < c2 * c2 or e * i < f * f:
        return 'not positive semi-definite (an off-diagonal term exceeds its variances)'
    if a * (e * i - f * f) - b * (b * i - f * c2) + c2 * (b * f - e * c2) < 0.0:
        return 'not positive semi-definite (negative determinant)'
    return None


def _all_finite(values: Any) -> bool:
    """Return True when no value is NaN or infinite (their sum is then finite, bar overflow)."""
    if isinstance(values, np.ndarray):
        values = values.tolist()
    return math.isfinite(sum(values))


def _cov3(flat: Any) -> np.ndarray:
    return np.asarray(flat, dtype=float).reshape(3, 3)


# ---------------------------------------------------------------------------------- inbound
#
# The inbound functions only read attributes, so they take rclpy messages and rosbags'
# deserialised dataclasses (same field names; arrays are numpy arrays in both) alike.

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
    bad = _bad_stamp(msg.header.stamp)
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
        return GnssFix(stamp_to_ns(msg.header.stamp), math.radians(lat), math.radians(lon),
                       float(alt), cov_ned, lever_b=frames.flip_body3(*mounting.t))
    return GnssFix(stamp_to_ns(msg.header.stamp), math.radians(lat), math.radians(lon),
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
_BODY_COV_CACHE: dict[tuple[bytes, tuple], _ImuCov] = {}


def _imu_cov(flat: Any, rpy: tuple[float, ...]) -> _ImuCov:
    """
    Return (marked unused, finite, 3x3 covariance in the base frame FRD or None, problem).

    ``rpy``: the mounting as roll, pitch, yaw, or (4 numbers) as a quaternion, scalar first.

    ``marked unused``: element 0 is -1 (REP-145: no such data). ``problem``: why a finite,
    used covariance is unusable (:func:`cov3_problem`), else None. Drivers send the same
    covariance in every message: the answers are cached by the covariance (a tuple of floats as
    it is, any other sequence by its float64 bytes), and the returned array is shared and read
    only.
    """
    key: tuple = (flat if type(flat) is tuple else np.asarray(flat, dtype=float).tobytes(), rpy)
    try:
        return _BODY_COV_CACHE[key]
    except KeyError:
        pass
    arr = np.asarray(flat, dtype=float).reshape(-1)
    unused = bool(arr[0] == -1.0)
    finite = _all_finite(arr)
    out = problem = None
    if finite and not unused:
        problem = cov3_problem(arr.tolist())
    if finite and not unused and problem is None and np.any(arr):
        r_mount = quaternion.rquat(rpy if len(rpy) == 4 else quaternion.euler2q(*rpy))
        out = frames.cov3_flu_to_frd(r_mount @ arr.reshape(3, 3) @ r_mount.T)
        out.flags.writeable = False
    if len(_BODY_COV_CACHE) > 256:
        _BODY_COV_CACHE.clear()
    result = (unused, finite, out, problem)
    _BODY_COV_CACHE[key] = result
    return result


def _body_cov(flat: Any, rpy: tuple[float, float, float]) -> np.ndarray | None:
    """Return a 3x3 IMU-frame FLU covariance in the base frame, FRD; None when all zero."""
    return _imu_cov(flat, rpy)[2]


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
    if mounting is None:
        rpy: tuple[float, ...] = params.imu_mounting_rpy
        mount_inv, q_yaw, r_mount = _mounting(rpy, params.imu_yaw_offset)
    else:
        rpy = mounting.q
        mount_inv, q_yaw, r_mount = _mounting_q(rpy, params.imu_yaw_offset)
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
            norm = math.sqrt(ow * ow + ox * ox + oy * oy + oz * oz)
            if norm < 1e-6:
                return Rejection(Reason.ZERO_QUATERNION, 'Imu orientation is the zero quaternion')
            if abs(norm - 1.0) > QUATERNION_NORM_TOLERANCE:
                return Rejection(Reason.NON_UNIT_QUATERNION,
                                 f'Imu orientation has norm {norm:.6f}')
            q_imu = (ow / norm, ox / norm, oy / norm, oz / norm)
            # The attitude swap ENU/FLU -> NED/FRD (frames), scalar part made non-negative.
            q_nb = frames.swap_attitude4(*mul4(q_yaw, mul4(q_imu, mount_inv)))
            if q_nb[0] < 0.0:
                q_nb = (-q_nb[0], -q_nb[1], -q_nb[2], -q_nb[3])
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


_TWIST_COV_CACHE: dict[tuple[bytes | None, float], Any] = {}


def _twist_cov(cov: Any, sigma2: float) -> Rejection | tuple[np.ndarray, bool, np.ndarray | None]:
    """
    Return (linear 3x3 FRD, rate usable, angular 3x3 FRD or None) of a FLU twist covariance.

    ``cov`` None (TwistStamped), all zero or marked -1 gives ``sigma2`` on each linear axis;
    a zero linear variance becomes ``sigma2``. Cached by the covariance's bytes (drivers send
    the same one every time): the returned arrays are shared and read only.
    """
    arr = None if cov is None else (cov if isinstance(cov, np.ndarray)
                                    else np.asarray(cov, dtype=float))
    key = (None if arr is None else arr.tobytes(), sigma2)
    try:
        return _TWIST_COV_CACHE[key]
    except KeyError:
        pass
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
        for a in (lin_cov, omega_cov):
            if a is not None:
                a.flags.writeable = False
        result = (lin_cov, rate_ok, omega_cov)
    if len(_TWIST_COV_CACHE) > 256:
        _TWIST_COV_CACHE.clear()
    _TWIST_COV_CACHE[key] = result
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
    # Duck-typed (rclpy messages, or rosbags' dataclasses of the same fields): TwistStamped
    # holds a Twist, the other two a TwistWithCovariance.
    twist = msg.twist
    cov = getattr(twist, 'covariance', None)
    if cov is not None:
        twist = twist.twist
    bad = _bad_stamp(msg.header.stamp)
    if bad is not None:
        return bad
    lin, ang = twist.linear, twist.angular
    nu = (lin.x, lin.y, lin.z)
    if not _all_finite(nu):
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
    rate_ok = cov_rate_ok and _all_finite(rate)
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
        return _mounted_velocity(stamp_to_ns(msg.header.stamp), nu, lin_cov,
                                 rate if rate_ok else None, omega_cov, mounting, rate_flu)
    return BodyVelocity(stamp_to_ns(msg.header.stamp),
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


def static_transforms_from_msg(msg: Any) -> list[StaticTransform]:
    """
    Return the transforms of a tf2_msgs/TFMessage (``/tf_static``) as static-tree records.

    Each geometry_msgs/TransformStamped: parent ``header.frame_id``, ``child_frame_id``,
    translation (m) and rotation ``xyzw`` as published (checked by the tree). rclpy messages
    and rosbags' dataclasses alike.
    """
    out = []
    for t in msg.transforms:
        tr, rot = t.transform.translation, t.transform.rotation
        out.append(StaticTransform(str(t.header.frame_id), str(t.child_frame_id),
                                   (float(tr.x), float(tr.y), float(tr.z)),
                                   (float(rot.x), float(rot.y), float(rot.z), float(rot.w))))
    return out


# ---------------------------------------------------------------------------------- outbound
#
# Output messages are built through rclpy's public API only: each message is made by its
# generated constructor with ``check_fields=False`` (which builds its default sub-messages
# once), and the values are set in place through the public field setters, so each nested
# message is built exactly once. Passing the sub-messages as constructor keywords instead would
# build every one twice (the generated ``__init__`` evaluates ``kwargs.get('header',
# Header())``, its default, before looking at the keyword): 1.9 to 2.4 times slower. The
# public API costs: the seven outputs of one state (water reference) took 108 us against
# 31 us written into the private slots as before (best of 5 x 5 x 1000, shared 2-core
# machine). The values set are the types the checked setters accept (int, float, str,
# float64 numpy arrays of the right size). With ROS_PYTHON_CHECK_FIELDS=1 (rclpy's own field
# checking) the keyword constructors with ``check_fields=True`` are used instead, checking
# every field at every level; test_ros_io checks that both paths give equal messages that
# serialise to the same bytes.

_CHECK_FIELDS = os.environ.get('ROS_PYTHON_CHECK_FIELDS', '') == '1'


def _time_msg(ns: int) -> Time:
    """Return a checked builtin_interfaces/Time (the ROS_PYTHON_CHECK_FIELDS=1 path)."""
    sec, nanosec = divmod(int(ns), _NS)
    return Time(check_fields=True, sec=sec, nanosec=nanosec)


def _checked_header(ns: int, frame_id: str) -> Header:
    return Header(check_fields=True, stamp=_time_msg(ns), frame_id=frame_id)


def _checked_xyz(cls: Any, x: float, y: float, z: float) -> Any:
    return cls(check_fields=True, x=float(x), y=float(y), z=float(z))


def _set_header(header: Header, ns: int, frame_id: str) -> None:
    """Set a Header's stamp (integer nanoseconds) and frame in place, by its public setters."""
    stamp = header.stamp
    stamp.sec, stamp.nanosec = divmod(int(ns), _NS)
    header.frame_id = frame_id


def _set_xyz(m: Any, xyz: Any) -> None:
    """Set x, y, z of a Point or Vector3 in place (as floats)."""
    x, y, z = xyz
    m.x, m.y, m.z = float(x), float(y), float(z)


def _odometry(ns: int, frame_id: str, child: str, position: Any, q_xyzw: Any,
              pose_cov: np.ndarray, linear: Any, angular: Any,
              twist_cov: np.ndarray) -> Odometry:
    """Return an Odometry; the covariances are 36-element float64 arrays (copied)."""
    qx, qy, qz, qw = q_xyzw
    if _CHECK_FIELDS:
        quat = Quaternion(check_fields=True, x=float(qx), y=float(qy), z=float(qz),
                          w=float(qw))
        pose = Pose(check_fields=True, position=_checked_xyz(Point, *position),
                    orientation=quat)
        twist = Twist(check_fields=True, linear=_checked_xyz(Vector3, *linear),
                      angular=_checked_xyz(Vector3, *angular))
        return Odometry(
            check_fields=True, header=_checked_header(ns, frame_id), child_frame_id=child,
            pose=PoseWithCovariance(check_fields=True, pose=pose, covariance=pose_cov),
            twist=TwistWithCovariance(check_fields=True, twist=twist, covariance=twist_cov))
    m = Odometry(check_fields=False)
    _set_header(m.header, ns, frame_id)
    m.child_frame_id = child
    pwc = m.pose
    pose = pwc.pose
    _set_xyz(pose.position, position)
    o = pose.orientation
    o.x, o.y, o.z, o.w = float(qx), float(qy), float(qz), float(qw)
    pwc.covariance = pose_cov
    twc = m.twist
    twist = twc.twist
    _set_xyz(twist.linear, linear)
    _set_xyz(twist.angular, angular)
    twc.covariance = twist_cov
    return m


def _vector3_stamped(ns: int, frame_id: str, x: float, y: float, z: float) -> Vector3Stamped:
    if _CHECK_FIELDS:
        return Vector3Stamped(check_fields=True, header=_checked_header(ns, frame_id),
                              vector=_checked_xyz(Vector3, x, y, z))
    m = Vector3Stamped(check_fields=False)
    _set_header(m.header, ns, frame_id)
    v = m.vector
    v.x, v.y, v.z = float(x), float(y), float(z)
    return m


def _nav_sat_fix(ns: int, frame_id: str, status: int, lat: float, lon: float, alt: float,
                 cov: np.ndarray, cov_type: int) -> NavSatFix:
    """Return a NavSatFix (service 0); ``cov`` a 9-element float64 array (copied)."""
    if _CHECK_FIELDS:
        return NavSatFix(check_fields=True, header=_checked_header(ns, frame_id),
                         status=NavSatStatus(check_fields=True, status=status),
                         latitude=float(lat), longitude=float(lon), altitude=float(alt),
                         position_covariance=cov, position_covariance_type=cov_type)
    m = NavSatFix(check_fields=False)
    _set_header(m.header, ns, frame_id)
    m.status.status = status
    m.latitude, m.longitude, m.altitude = float(lat), float(lon), float(alt)
    m.position_covariance = cov
    m.position_covariance_type = cov_type
    return m


def _signed_permutation(a: np.ndarray) -> tuple[list[int], list[float]]:
    """Return (source index, sign) per row of a signed permutation matrix."""
    rows = [int(np.flatnonzero(row)[0]) for row in a]
    return rows, [float(a[i, j]) for i, j in enumerate(rows)]


# The outputs' covariances gathered from one vector of the state's blocks (row-major):
# cov_p, cov_att, cov_nu, cov_omega, cov_p_local and a zero, by one take and one multiply.
_SOURCE = {'p': 0, 'att': 9, 'nu': 18, 'omega': 27, 'p_local': 36}
_ZERO_AT = 45


def _gather(blocks: tuple[str, ...], a: np.ndarray) -> tuple[list[int], list[float]]:
    """
    Return source indices and signs of A C Aᵀ, C the block diagonal of ``blocks`` (3x3 each).

    A is a signed permutation (frames.A_WORLD, A_BODY, A6_*), so each entry of the result is
    ± one entry of C: C'[i, j] = s_i s_j C[π_i, π_j].
    """
    rows, signs = _signed_permutation(a)
    n = len(rows)
    index, sign = [], []
    for i in range(n):
        for j in range(n):
            bi, bj = divmod(rows[i], 3), divmod(rows[j], 3)
            if bi[0] != bj[0]:
                index.append(_ZERO_AT)
                sign.append(0.0)
                continue
            index.append(_SOURCE[blocks[bi[0]]] + 3 * bi[1] + bj[1])
            sign.append(signs[i] * signs[j])
    return index, sign


_LAYOUT = (  # (name, blocks, A): the order of the gathered covariances
    ('pose_map', ('p', 'att'), frames.A6_POSE),
    ('pose_odom', ('p_local', 'att'), frames.A6_POSE),
    ('twist_flu', ('nu', 'omega'), frames.A6_BODY),
    ('twist_flu_2', ('nu', 'omega'), frames.A6_BODY),
    ('pose_ned', ('p', 'att'), np.eye(6)),
    ('twist_frd', ('nu', 'omega'), np.eye(6)),
    ('fix_enu', ('p',), frames.A_WORLD),
)
_GATHER_INDEX = np.array([i for _, b, a in _LAYOUT for i in _gather(b, a)[0]], dtype=np.intp)
_GATHER_SIGN = np.array([s for _, b, a in _LAYOUT for s in _gather(b, a)[1]])


def _covariances(s: NavPose) -> dict[str, np.ndarray]:
    """Return every output covariance of ``s`` (views into one new array, one per message)."""
    source = np.concatenate((np.ravel(s.cov_p), np.ravel(s.cov_att), np.ravel(s.cov_nu),
                             np.ravel(s.cov_omega), np.ravel(s.cov_p_local), _ZERO1))
    gathered = source.take(_GATHER_INDEX)
    gathered *= _GATHER_SIGN
    out, start = {}, 0
    for name, _, a in _LAYOUT:
        size = a.shape[0] ** 2
        out[name] = gathered[start:start + size]
        start += size
    return out


_ZERO1 = np.zeros(1)


class _Covariances:
    """The output covariances of one state, gathered on first use and shared by its outputs."""

    __slots__ = ('_s', '_gathered')

    def __init__(self, s: NavPose) -> None:
        self._s = s
        self._gathered: dict[str, np.ndarray] | None = None

    def __getitem__(self, name: str) -> np.ndarray:
        """Return the covariance ``name`` of :data:`_LAYOUT` (row-major, output frames)."""
        if self._gathered is None:
            self._gathered = _covariances(self._s)
        return self._gathered[name]


def _q_ros(s: NavPose) -> tuple[float, float, float, float]:
    """Return q_enu_flu of the state by the attitude swap (frames), as x, y, z, w."""
    w, x, y, z = s.q.tolist()
    qw, qx, qy, qz = frames.swap_attitude4(w, x, y, z)
    return qx, qy, qz, qw


def _odometry_map(s: NavPose, params: NavigatorParams, cov: _Covariances,
                  build: _Builders) -> Any:
    """``odometry``: the fused pose in map (ENU) of base (FLU), the twist in base."""
    return build.odometry(s.stamp_ns, params.map_frame, params.base_frame,
                          frames.swap_world3(*s.p.tolist()), _q_ros(s), cov['pose_map'],
                          frames.flip_body3(*s.nu.tolist()),
                          frames.flip_body3(*s.omega.tolist()), cov['twist_flu'])


def _odometry_local(s: NavPose, params: NavigatorParams, cov: _Covariances,
                    build: _Builders) -> Any:
    """``odometry/local``: the dead-reckoned pose in odom (ENU), never corrected."""
    return build.odometry(s.stamp_ns, params.odom_frame, params.base_frame,
                          frames.swap_world3(*s.p_local.tolist()), _q_ros(s),
                          cov['pose_odom'], frames.flip_body3(*s.nu.tolist()),
                          frames.flip_body3(*s.omega.tolist()), cov['twist_flu_2'])


def _odometry_ned(s: NavPose, params: NavigatorParams, cov: _Covariances,
                  build: _Builders) -> Any:
    """``odometry/ned``: the fused state in Fossen's frames, map_ned (NED) / base_frd (FRD)."""
    w, x, y, z = s.q.tolist()
    return build.odometry(s.stamp_ns, params.map_frame + NED_SUFFIX,
                          params.base_frame + FRD_SUFFIX, s.p.tolist(), (x, y, z, w),
                          cov['pose_ned'], s.nu.tolist(), s.omega.tolist(), cov['twist_frd'])


def odometry_msgs(s: NavPose, params: NavigatorParams) -> tuple[Odometry, Odometry, Odometry]:
    """
    Return the fused ENU/FLU, the local (odom) ENU/FLU and the fused NED/FRD Odometry.

    Pose covariances [x, y, z, roll, pitch, yaw], twist covariances [linear, angular] in the
    child frame; the twist is the body velocity over ground.
    """
    cov = _Covariances(s)
    return (_odometry_map(s, params, cov, MSG_BUILDERS),
            _odometry_local(s, params, cov, MSG_BUILDERS),
            _odometry_ned(s, params, cov, MSG_BUILDERS))


def course_sideslip_msg(s: NavState, params: NavigatorParams) -> Vector3Stamped:
    """Return x = course χ, y = sideslip β, z = angle of attack α (rad), frame base_frame."""
    return _course_sideslip(s, params, _Covariances(s), MSG_BUILDERS)


def _course_sideslip(s: NavState, params: NavigatorParams, cov: _Covariances,
                     build: _Builders) -> Any:
    return build.vector3_stamped(s.stamp_ns, params.base_frame, s.course, s.sideslip,
                                 s.angle_of_attack)


def current_msg(s: NavState, params: NavigatorParams) -> Vector3Stamped:
    """Return the estimated current, ENU in map_frame (m/s); zero when not estimated."""
    return _current(s, params, _Covariances(s), MSG_BUILDERS)


def _current(s: NavState, params: NavigatorParams, cov: _Covariances, build: _Builders) -> Any:
    if s.current is None:
        return build.vector3_stamped(s.stamp_ns, params.map_frame, 0.0, 0.0, 0.0)
    return build.vector3_stamped(s.stamp_ns, params.map_frame,
                                 *frames.swap_world3(*s.current.tolist()))


def relative_flow_msg(s: NavState, params: NavigatorParams) -> Vector3Stamped:
    """
    Return the flow relative to the water: x = U_r (m/s), y = β_r, z = α_r (rad), base_frame.

    Fossen 2.4.2: the speed, sideslip (leeway and turning drift, the seed's sign) and angle of
    attack of the body velocity through the water ν_r = ν − ν_c; zero when not estimated.
    """
    return _relative_flow(s, params, _Covariances(s), MSG_BUILDERS)


def _relative_flow(s: NavState, params: NavigatorParams, cov: _Covariances,
                   build: _Builders) -> Any:
    f = s.relative_flow
    if f is None:
        return build.vector3_stamped(s.stamp_ns, params.base_frame, 0.0, 0.0, 0.0)
    return build.vector3_stamped(s.stamp_ns, params.base_frame, f.speed, f.sideslip,
                                 f.angle_of_attack)


def _filtered_fix(s: NavState, params: NavigatorParams, cov: _Covariances,
                  build: _Builders) -> Any:
    lat, lon, h = s.llh
    # A position from dead reckoning alone is no GNSS fix: STATUS_NO_FIX, so that nobody
    # (navsat_transform, a logger, a second filter) takes it for one, with its honest
    # (growing) covariance kept; STATUS_FIX while fixes are fused.
    status = (NavSatStatus.STATUS_FIX if s.mode is Mode.FUSED
              else NavSatStatus.STATUS_NO_FIX)
    return build.nav_sat_fix(s.stamp_ns, params.base_frame, status,
                             math.degrees(lat), math.degrees(lon), h, cov['fix_enu'],
                             NavSatFix.COVARIANCE_TYPE_KNOWN)


def filtered_fix_msg(s: NavState, params: NavigatorParams) -> NavSatFix:
    """Return the estimated base position as a NavSatFix (deg, m; covariance ENU, KNOWN)."""
    return _filtered_fix(s, params, _Covariances(s), MSG_BUILDERS)


def _calibration(s: NavState, params: NavigatorParams, cov: _Covariances,
                 build: _Builders) -> Any:
    """
    ``calibration``: the log scale k, the leeway λ and the IMU heading offset δψ in use.

    x = k (the log reads k times the speed through the water), y = λ (rad), z = δψ (rad, added
    to the IMU heading, NED: the IMU's published minus true yaw, ENU), in base_frame; 1, 0, 0
    where not estimated (:class:`~vessel_kinematics.estimation.Calibration`). The layout of the
    simulator's ``/truth/calibration``.
    """
    c = s.calibration
    return build.vector3_stamped(
        s.stamp_ns, params.base_frame, 1.0 if c.log_scale is None else c.log_scale.value,
        0.0 if c.leeway is None else c.leeway.value,
        0.0 if c.heading_offset is None else c.heading_offset.value)


#: An output's builder: (state, parameters, the state's shared covariances, the builders:
#: :data:`MSG_BUILDERS` or :data:`CDR_BUILDERS`) -> the message or its CDR bytes.
OutputBuilder = Callable[[NavState, NavigatorParams, _Covariances, '_Builders'], Any]

#: The code of each output made from the state, by its name in the interface table
#: (:mod:`.interface`, the rows of role OUTPUT): what :func:`state_msgs` builds, in the table's
#: order, leaving out the ``water_only`` rows without a water-referenced velocity. Adding an
#: output is a row there and a builder here. ``origin``, also an output of the table, is no
#: function of the state: the pipeline emits it when the origin is set (:func:`origin_msg`).
STATE_OUTPUTS: dict[str, OutputBuilder] = {
    'odometry': _odometry_map,
    'odometry/local': _odometry_local,
    'odometry/ned': _odometry_ned,
    'course_sideslip': _course_sideslip,
    'current': _current,
    'relative_flow': _relative_flow,
    'fix/filtered': _filtered_fix,
    'calibration': _calibration,
}

#: The state outputs made from the :class:`NavPose` alone (the odometry): with
#: ``Estimator.staged_state`` they are built before the rest of the state is computed.
POSE_OUTPUTS = frozenset({'odometry', 'odometry/local', 'odometry/ned'})

#: (name, water_only, pose only, builder) of every state output, in the interface table's order.
_STATE_ROWS: tuple[tuple[str, bool, bool, OutputBuilder], ...] = tuple(
    (t.name, t.water_only, t.name in POSE_OUTPUTS, STATE_OUTPUTS[t.name])
    for t in interface.by_role(interface.Role.OUTPUT) if t.name in STATE_OUTPUTS)
if len(_STATE_ROWS) != len(STATE_OUTPUTS):  # a builder without a row: a mistake, said at once
    raise RuntimeError(f'ros_io.STATE_OUTPUTS {sorted(STATE_OUTPUTS)}: not all are outputs of '
                       'the interface table')


def state_msgs(s: NavState, params: NavigatorParams, water: bool,
               topics: AbstractSet[str] | None = None, *,
               cdr: bool = False) -> list[tuple[str, Any]]:
    """
    Return (output name, message) of every per-update output of the state, in one pass.

    The outputs of :data:`STATE_OUTPUTS` in the interface table's order, the ``water_only``
    ones (``current``, ``relative_flow``) only when ``water``; the covariances are gathered
    once for all. ``topics``: only those names (None: all), in the same order; each message
    is the same as when all are built. ``cdr``: each message as its serialised CDR bytes
    instead (:data:`CDR_BUILDERS`: the bytes rclpy serialises the message to, without
    building it; what the replay writes).
    """
    return list(iter_state_msgs(s, params, water, topics, cdr=cdr))


def iter_state_msgs(s: NavPose, params: NavigatorParams, water: bool,
                    topics: AbstractSet[str] | None = None, *, cdr: bool = False,
                    complete: Callable[[], NavState] | None = None
                    ) -> Iterator[tuple[str, Any]]:
    """
    Yield :func:`state_msgs`' (output name, message), each built as it is taken.

    ``s`` the state, or only its pose with ``complete`` returning the whole state
    (``Estimator.staged_state``): called only once an output needs more than the pose
    (:data:`POSE_OUTPUTS`), so that ``odometry`` is built and sent before the rest is computed.
    """
    build = CDR_BUILDERS if cdr else MSG_BUILDERS
    cov = _Covariances(s)
    state = s
    for name, water_only, pose_only, builder in _STATE_ROWS:
        if (water or not water_only) and (topics is None or name in topics):
            if not pose_only and complete is not None:
                state, complete = complete(), None
            # A pose-only row's builder takes the NavPose (typed NavState in the table).
            yield name, builder(state, params, cov, build)  # type: ignore[arg-type]


def origin_msg(origin: tuple[float, float, float], stamp_ns: int,
               params: NavigatorParams) -> NavSatFix:
    """Return the origin (rad, rad, m) as a NavSatFix in degrees, frame map_frame."""
    msg = NavSatFix()
    msg.header.stamp = ns_to_stamp(stamp_ns)
    msg.header.frame_id = params.map_frame
    msg.status.status = NavSatStatus.STATUS_FIX
    msg.latitude = math.degrees(origin[0])
    msg.longitude = math.degrees(origin[1])
    msg.altitude = float(origin[2])
    msg.position_covariance_type = NavSatFix.COVARIANCE_TYPE_UNKNOWN
    return msg


#: One transform, ROS-free: (stamp ns, parent frame, child frame, translation x y z (m),
#: rotation x y z w). What :func:`transform_msgs` builds messages of and :func:`tf_cdr`
#: serialises.
TransformParts = tuple[int, str, str, tuple[float, float, float],
                       tuple[float, float, float, float]]


def _transform(stamp: Time, parent: str, child: str, t: Any, q_xyzw: Any) -> TransformStamped:
    msg = TransformStamped()
    msg.header.stamp = stamp
    msg.header.frame_id = parent
    msg.child_frame_id = child
    tr, rot = msg.transform.translation, msg.transform.rotation
    tr.x, tr.y, tr.z = (float(c) for c in t)
    rot.x, rot.y, rot.z, rot.w = (float(c) for c in q_xyzw)
    return msg


def transform_parts(s: NavPose, params: NavigatorParams,
                    which: AbstractSet[str] = frozenset({'map_odom', 'odom_base'}),
                    ) -> list[TransformParts]:
    """
    Return map->odom (``'map_odom'``) and odom->base_link (``'odom_base'``) of ``which``.

    odom->base_link is the local pose; map->odom = fused pose ∘ (local pose)⁻¹. Both poses
    share the attitude, so map->odom is the pure translation p_map - p_odom (ENU) (REP-105).
    """
    out: list[TransformParts] = []
    if 'map_odom' in which:
        out.append((s.stamp_ns, params.map_frame, params.odom_frame,
                    frames.swap_world3(*(s.p - s.p_local).tolist()), (0.0, 0.0, 0.0, 1.0)))
    if 'odom_base' in which:
        out.append((s.stamp_ns, params.odom_frame, params.base_frame,
                    frames.swap_world3(*s.p_local.tolist()), _q_ros(s)))
    return out


def transform_msg(parts: TransformParts) -> TransformStamped:
    """Return the geometry_msgs/TransformStamped of a :data:`TransformParts`."""
    stamp_ns, parent, child, t, q_xyzw = parts
    return _transform(ns_to_stamp(stamp_ns), parent, child, t, q_xyzw)


def transform_msgs(s: NavPose, params: NavigatorParams,
                   which: AbstractSet[str] = frozenset({'map_odom', 'odom_base'}),
                   ) -> list[TransformStamped]:
    """Return :func:`transform_parts` as geometry_msgs/TransformStamped messages."""
    return [transform_msg(parts) for parts in transform_parts(s, params, which)]


def parts_of(msg: Any) -> TransformParts:
    """Return the :data:`TransformParts` of a geometry_msgs/TransformStamped."""
    tr, rot = msg.transform.translation, msg.transform.rotation
    return (frames.stamp_to_ns(msg.header.stamp.sec, msg.header.stamp.nanosec),
            msg.header.frame_id, msg.child_frame_id, (tr.x, tr.y, tr.z),
            (rot.x, rot.y, rot.z, rot.w))


#: Suffixes of the NED/FRD twins of the map and base frames (``odometry/ned``'s frames).
NED_SUFFIX = '_ned'
FRD_SUFFIX = '_frd'
#: map (ENU) -> map_ned: x_ned = y_enu, y_ned = x_enu, z_ned = -z_enu; 180° about (1, 1, 0)/√2.
_Q_ENU_NED_XYZW = (_SQRT_HALF, _SQRT_HALF, 0.0, 0.0)
#: base (FLU) -> base_frd: 180° about x.
_Q_FLU_FRD_XYZW = (1.0, 0.0, 0.0, 0.0)


def static_transform_msgs(origin: tuple[float, float, float] | None, stamp_ns: int,
                          params: NavigatorParams,
                          which: AbstractSet[str] = frozenset({'earth_map'}),
                          ) -> list[TransformStamped]:
    """
    Return the static transforms of ``which``, all in one list (one /tf_static message).

    ``'earth_map'``: earth->map, the origin's ECEF position and the rotation ENU -> ECEF
    (REP-105), when ``origin`` (rad, rad, m) is known. ``'frd_ned'``: map->map_ned and
    base_link->base_link_frd, the frames of ``odometry/ned``.
    """
    stamp = ns_to_stamp(stamp_ns)
    out = []
    if 'earth_map' in which and origin is not None:
        lat, lon, h = origin
        p_e = geodesy.llh2ecef(lat, lon, h)
        r_e_enu = geodesy.rll(lon, lat) @ frames.A_WORLD
        q = quaternion.rot2q(r_e_enu)
        out.append(_transform(stamp, params.earth_frame, params.map_frame, p_e,
                              (q[1], q[2], q[3], q[0])))
    if 'frd_ned' in which:
        out.append(_transform(stamp, params.map_frame, params.map_frame + NED_SUFFIX,
                              (0.0, 0.0, 0.0), _Q_ENU_NED_XYZW))
        out.append(_transform(stamp, params.base_frame, params.base_frame + FRD_SUFFIX,
                              (0.0, 0.0, 0.0), _Q_FLU_FRD_XYZW))
    return out


def diagnostic_status(name: str, level: bytes, summary: str,
                      values: dict[str, str]) -> DiagnosticStatus:
    """Return one DiagnosticStatus ``name`` holding ``values``."""
    status = DiagnosticStatus()
    status.level = level
    status.name = name
    status.message = summary
    status.hardware_id = 'vessel_kinematics'
    status.values = [KeyValue(key=k, value=v) for k, v in values.items()]
    return status


def diagnostics_array_msg(now_ns: int, statuses: list[DiagnosticStatus]) -> DiagnosticArray:
    """Return a DiagnosticArray of ``statuses`` stamped ``now_ns``."""
    msg = DiagnosticArray()
    msg.header.stamp = ns_to_stamp(now_ns)
    msg.status = statuses
    return msg


def diagnostics_msg(now_ns: int, name: str, level: bytes, summary: str,
                    values: dict[str, str]) -> DiagnosticArray:
    """Return a DiagnosticArray with one status ``name`` holding ``values``."""
    return diagnostics_array_msg(now_ns, [diagnostic_status(name, level, summary, values)])


# --- Outputs as CDR bytes, without rclpy messages ----------------------------------------------
# The replay writes bags: it needs each output's serialised bytes, not a message object. These
# builders lay out the CDR (little-endian, XCDR1 as rmw_fastrtps and rosbags write it) with
# struct from the same values the message builders above store, so the bytes are those
# ``rclpy.serialization.serialize_message`` gives for the message (test_ros_io compares both,
# byte for byte, for every output type; the padding bytes are zeros here). Alignment counts from
# after the 4-byte encapsulation header; a header's frame strings and the padding after them
# depend only on the frame names, so they are laid out once per name (lru_cache).

#: CDR encapsulation header: little-endian plain CDR, no options.
CDR_LE = b'\x00\x01\x00\x00'
_U32 = struct.Struct('<I')
_TIME_CDR = struct.Struct('<iI')
_D3 = struct.Struct('<3d')
_D6 = struct.Struct('<6d')
_D7 = struct.Struct('<7d')


def _cdr_strings(offset: int, names: tuple[str, ...], align: int) -> bytes:
    """Return CDR strings ``names`` starting at ``offset``, padded to ``align`` after them."""
    out = bytearray()
    for name in names:
        out += bytes(-(offset + len(out)) % 4)
        data = name.encode() + b'\x00'
        out += _U32.pack(len(data)) + data
    out += bytes(-(offset + len(out)) % align)
    return bytes(out)


@lru_cache(maxsize=64)
def _after_stamp(names: tuple[str, ...]) -> bytes:
    """Return the frame strings after a Header's stamp, padded for the float64 that follows."""
    return _cdr_strings(8, names, 8)


@lru_cache(maxsize=16)
def _fix_middle(frame_id: str, status: int, service: int) -> bytes:
    """Return a NavSatFix's frame_id and NavSatStatus (int8, uint16), padded to float64."""
    strings = _cdr_strings(8, (frame_id,), 1)
    at = 8 + len(strings)
    status_cdr = struct.pack('<b', status) + bytes((at + 1) % 2) + struct.pack('<H', service)
    at += len(status_cdr)
    return strings + status_cdr + bytes(-at % 8)


def _stamp_cdr(ns: int) -> bytes:
    return _TIME_CDR.pack(*divmod(int(ns), _NS))


def _odometry_cdr(ns: int, frame_id: str, child: str, position: Any, q_xyzw: Any,
                  pose_cov: np.ndarray, linear: Any, angular: Any,
                  twist_cov: np.ndarray) -> bytes:
    """Return the CDR of :func:`_odometry`'s message (covariances: 36 float64 each)."""
    return b''.join((CDR_LE, _stamp_cdr(ns), _after_stamp((frame_id, child)),
                     _D7.pack(*position, *q_xyzw), pose_cov.tobytes(),
                     _D6.pack(*linear, *angular), twist_cov.tobytes()))


def _vector3_stamped_cdr(ns: int, frame_id: str, x: float, y: float, z: float) -> bytes:
    """Return the CDR of :func:`_vector3_stamped`'s message."""
    return b''.join((CDR_LE, _stamp_cdr(ns), _after_stamp((frame_id,)), _D3.pack(x, y, z)))


def _nav_sat_fix_cdr(ns: int, frame_id: str, status: int, lat: float, lon: float, alt: float,
                     cov: np.ndarray, cov_type: int) -> bytes:
    """Return the CDR of :func:`_nav_sat_fix`'s message (service 0)."""
    return b''.join((CDR_LE, _stamp_cdr(ns), _fix_middle(frame_id, status, 0),
                     _D3.pack(lat, lon, alt), cov.tobytes(), bytes((cov_type,))))


class _Builders:
    """The constructors of the per-update outputs: rclpy messages or their CDR bytes."""

    def __init__(self, odometry: Any, vector3_stamped: Any, nav_sat_fix: Any) -> None:
        self.odometry = odometry
        self.vector3_stamped = vector3_stamped
        self.nav_sat_fix = nav_sat_fix


#: The outputs as rclpy messages (what the node publishes).
MSG_BUILDERS = _Builders(_odometry, _vector3_stamped, _nav_sat_fix)
#: The outputs as the CDR bytes of those messages (what the replay writes).
CDR_BUILDERS = _Builders(_odometry_cdr, _vector3_stamped_cdr, _nav_sat_fix_cdr)


def origin_cdr(origin: tuple[float, float, float], stamp_ns: int,
               params: NavigatorParams) -> bytes:
    """Return the CDR bytes of :func:`origin_msg`'s message."""
    return _nav_sat_fix_cdr(stamp_ns, params.map_frame, NavSatStatus.STATUS_FIX,
                            math.degrees(origin[0]), math.degrees(origin[1]), float(origin[2]),
                            _ZERO9, NavSatFix.COVARIANCE_TYPE_UNKNOWN)


_ZERO9 = np.zeros(9)


@lru_cache(maxsize=64)
def _tf_strings(offset: int, parent: str, child: str) -> bytes:
    """Return a TransformStamped's frame strings after its stamp, padded to float64."""
    return _cdr_strings(offset, (parent, child), 8)


def tf_cdr(transforms: Sequence[TransformParts]) -> bytes:
    """
    Return the CDR (little-endian) of a tf2_msgs/TFMessage holding ``transforms``.

    A sequence of geometry_msgs/TransformStamped, laid out as rosbags' ``serialize_cdr`` and
    rclpy lay it out (the tests compare them), alignment counted from after the 4-byte
    encapsulation header; what the replay writes on /tf and /tf_static.
    """
    body = bytearray(_U32.pack(len(transforms)))
    for stamp_ns, parent, child, t, q in transforms:
        body += _stamp_cdr(stamp_ns)        # at a multiple of 4 (the previous ends on 8)
        body += _tf_strings(len(body), parent, child)
        body += _D7.pack(*t, *q)
    return CDR_LE + bytes(body)


def diagnostics_cdr(msg: DiagnosticArray) -> bytes:
    """
    Return the CDR of a diagnostic_msgs/DiagnosticArray, its padding bytes zero.

    ``serialize_message`` leaves Fast CDR's padding bytes unwritten (whatever the buffer held),
    so two serialisations of one message may differ; these bytes do not (the replay's output is
    reproducible byte for byte).
    """
    stamp = msg.header.stamp
    out = bytearray(_TIME_CDR.pack(stamp.sec, stamp.nanosec))

    def string(text: str) -> None:
        out.extend(bytes(-len(out) % 4))
        data = text.encode() + b'\x00'
        out.extend(_U32.pack(len(data)))
        out.extend(data)

    def count(n: int) -> None:
        out.extend(bytes(-len(out) % 4))
        out.extend(_U32.pack(n))

    string(msg.header.frame_id)
    count(len(msg.status))
    for status in msg.status:
        out.extend(status.level)
        for text in (status.name, status.message, status.hardware_id):
            string(text)
        count(len(status.values))
        for pair in status.values:
            string(pair.key)
            string(pair.value)
    return CDR_LE + bytes(out)


# --- An input read straight from its CDR bytes -------------------------------------------------
# The replay reads sensor_msgs/Imu, the 100-400 Hz input, from the bag's CDR with one struct
# call per block instead of a generic deserialiser (a fifth of the time). The view has the
# message's attributes, with the values rosbags' ``deserialize_cdr`` gives (the same bytes read
# as int32/float64; covariances as tuples): test_ros_io compares the two on every Imu of the
# simulated and the real bags and on random messages, and :func:`imu_from_msg` reads both
# alike. Anything but the exact layout of a little-endian Imu is left to the generic
# deserialiser (None), which decides what is garbage.


class CdrStamp(NamedTuple):
    """builtin_interfaces/Time of a CDR view."""

    sec: int
    nanosec: int


class CdrHeader(NamedTuple):
    """std_msgs/Header of a CDR view."""

    stamp: CdrStamp
    frame_id: str


class CdrQuaternion(NamedTuple):
    """geometry_msgs/Quaternion of a CDR view, ``xyzw`` as in the message."""

    x: float
    y: float
    z: float
    w: float


class CdrVector3(NamedTuple):
    """geometry_msgs/Vector3 of a CDR view."""

    x: float
    y: float
    z: float


class ImuCdr:
    """
    A sensor_msgs/Imu read from its CDR (:func:`imu_from_cdr`), with the message's attributes.

    ``values``: the 37 float64 after the header in message order: orientation ``xyzw`` (0:4),
    its covariance (4:13), ω (13:16), its covariance (16:25), the acceleration (25:28), its
    covariance (28:37). The vectors are made when asked for; :func:`imu_from_msg` reads
    ``values`` directly.
    """

    __slots__ = ('header', 'values')

    def __init__(self, header: CdrHeader, values: tuple[float, ...]) -> None:
        self.header = header
        self.values = values

    @property
    def orientation(self) -> CdrQuaternion:
        """Return the orientation, ``xyzw``."""
        return CdrQuaternion(*self.values[0:4])

    @property
    def orientation_covariance(self) -> tuple[float, ...]:
        """Return the orientation's covariance, 9 float64, row-major."""
        return self.values[4:13]

    @property
    def angular_velocity(self) -> CdrVector3:
        """Return the angular velocity (rad/s)."""
        return CdrVector3(*self.values[13:16])

    @property
    def angular_velocity_covariance(self) -> tuple[float, ...]:
        """Return the angular velocity's covariance, 9 float64, row-major."""
        return self.values[16:25]

    @property
    def linear_acceleration(self) -> CdrVector3:
        """Return the linear acceleration (m/s²)."""
        return CdrVector3(*self.values[25:28])

    @property
    def linear_acceleration_covariance(self) -> tuple[float, ...]:
        """Return the linear acceleration's covariance, 9 float64, row-major."""
        return self.values[28:37]


_HEADER_CDR = struct.Struct('<iiII')    # encapsulation, sec, nanosec, frame_id's length
#: Imu after its header: orientation (4), its covariance (9), ω (3), its covariance (9),
#: acceleration (3), its covariance (9), float64 each.
_IMU_BODY = struct.Struct('<37d')
_IMU_ENCAPSULATION = int.from_bytes(CDR_LE, 'little', signed=True)


def imu_from_cdr(raw: bytes | memoryview) -> ImuCdr | None:
    """
    Return a sensor_msgs/Imu's fields from its little-endian CDR, or None.

    None for anything but a plain little-endian Imu of exactly its size (another
    encapsulation, a truncated or longer payload, a frame_id that is not NUL-terminated UTF-8):
    the caller then deserialises generically and learns what is wrong.
    """
    size = len(raw)
    if size < 16 + _IMU_BODY.size:
        return None
    encapsulation, sec, nanosec, length = _HEADER_CDR.unpack_from(raw, 0)
    end = 16 + length                     # the string and its NUL
    body = end + (-(end - 4) % 8)         # float64 alignment counts from after encapsulation
    if (encapsulation != _IMU_ENCAPSULATION or length == 0 or body + _IMU_BODY.size != size
            or raw[end - 1] != 0):
        return None
    try:
        frame_id = bytes(raw[16:end - 1]).decode()
    except UnicodeDecodeError:
        return None
    return ImuCdr(CdrHeader(CdrStamp(sec, nanosec), frame_id), _IMU_BODY.unpack_from(raw, body))


def imu_from_raw(raw: bytes | memoryview) -> ImuCdr | Any | Rejection:
    """
    Return a serialised sensor_msgs/Imu (a raw subscription's payload) for :func:`imu_from_msg`.

    Its plain little-endian CDR is read directly (:func:`imu_from_cdr`, the replay's reader:
    the same values, a tenth of rclpy's time); anything else is deserialised by rclpy, and a
    payload that does not deserialise is ``Rejection(CDR_ERROR)``, never an exception.
    """
    msg = imu_from_cdr(raw)
    if msg is not None:
        return msg
    from rclpy.serialization import deserialize_message
    from sensor_msgs.msg import Imu
    try:
        return deserialize_message(bytes(raw), Imu)
    except Exception as error:  # noqa: B902 (rclpy raises RMWError for a garbage payload)
        first = str(error).splitlines()[0] if str(error) else type(error).__name__
        return Rejection(Reason.CDR_ERROR, f'Imu payload of {len(raw)} bytes does not '
                                           f'deserialise: {first}')


#: Diagnostic levels.
OK = DiagnosticStatus.OK
WARN = DiagnosticStatus.WARN
ERROR = DiagnosticStatus.ERROR

"""
Frame and angle conventions (REP-103 at the ROS edge), in one place.

Inside the core: world NED, body FRD (x forward, y starboard, z down), quaternions scalar
first [eta, eps1, eps2, eps3] with q_nb rotating BODY into NED (Fossen). In ROS: world ENU,
body FLU (x forward, y left/port, z up), quaternions ``xyzw`` (geometry_msgs/Quaternion).

- World vectors:  NED (n, e, d) <-> ENU (e, n, u): (x, y, z) -> (y, x, -z), matrix A_W.
- Body vectors:   FRD <-> FLU: (x, y, z) -> (x, -y, -z), matrix A_B = diag(1, -1, -1).
- Attitude:       R_enu_flu = A_W R_nb A_B, i.e. q_enu_flu = q_(ENU<-NED) (x) q_nb (x)
                  q_(FRD<-FLU) with q_(ENU<-NED) = [0, 1/sqrt2, 1/sqrt2, 0] and
                  q_(FRD<-FLU) = [0, 1, 0, 0]. Worked out, [w, x, y, z] -> [w + z, x + y,
                  x - y, w - z] / sqrt2 (the sign chosen so the map is its own inverse).
                  A vessel heading north level (q_nb = [1, 0, 0, 0]) has ROS yaw +90 deg.
- Euler angles:   roll_ros = phi, pitch_ros = -theta, yaw_ros = pi/2 - psi (wrapped).
- Angles:         wrapped to (-pi, pi] by :func:`ssa` (Fossen's smallest signed angle), the
                  same interval for scalars and arrays.
- Yaw of q:       psi = atan2(2 (eps1 eps2 + eta eps3), eta^2 + eps1^2 - eps2^2 - eps3^2)
                  (:func:`yaw_from_q`; of a ROS xyzw orientation: :func:`yaw_from_ros`).
- Stamps:         builtin_interfaces/Time (sec, nanosec) <-> integer ns (:func:`stamp_to_ns`,
                  :func:`ns_to_stamp`).
- Covariances:    C' = A C A^T with A = A_W, A_B or the block-diagonal 6x6 combinations.

A_W and A_B are symmetric proper rotations (det = +1) and their own inverses, so every
conversion here is an involution: ``ned_to_enu(ned_to_enu(v)) == v``. Angular quantities
(rates, small rotation vectors) transform like the linear ones of the same frame, since both
matrices are rotations. Shapes: vectors (..., 3), quaternions (..., 4), covariances (..., 3, 3)
and (..., 6, 6). NaN passes through as NaN. Return types follow
:mod:`vessel_kinematics.core.dispatch`: vectors, quaternions and covariances are float64 ndarrays;
angles of a one-point call are Python floats.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from vessel_kinematics.core.dispatch import FloatArray, is_point, is_scalar

__all__ = ['A6_BODY', 'A6_POSE', 'A6_WORLD', 'A_BODY', 'A_WORLD', 'GPS_WEEK_ROLLOVER_S', 'KNOT',
           'NS_PER_S',
           'cov3_enu_to_ned',
           'cov3_flu_to_frd', 'cov3_frd_to_flu', 'cov3_ned_to_enu', 'cov6_enu_to_ned',
           'cov6_flu_to_frd', 'cov6_frd_to_flu', 'cov6_ned_to_enu', 'cov6_pose_from_ros',
           'cov6_pose_to_ros', 'cov_transform', 'enu_to_ned', 'euler_enu_to_ned',
           'euler_ned_to_enu', 'flip_body3', 'flu_to_frd', 'frd_to_flu', 'ned_to_enu',
           'ns_to_stamp', 'swap_world3',
           'q_nb_from_ros', 'q_nb_from_ros_wxyz', 'q_nb_to_ros', 'q_nb_to_ros_wxyz',
           'quat_wxyz_to_xyzw', 'quat_xyzw_to_wxyz', 'ssa', 'stamp_to_ns', 'swap_attitude4',
           'yaw_enu_to_ned', 'yaw_from_q', 'yaw_from_ros', 'yaw_ned_to_enu']

#: Nanoseconds per second (builtin_interfaces/Time).
NS_PER_S = 1_000_000_000

#: One knot in m/s (1852 m per hour, exactly).
KNOT = 1852.0 / 3600.0

#: A GPS week-number rollover (s): 1024 weeks, by which a receiver past one dates its fixes early.
GPS_WEEK_ROLLOVER_S = 1024 * 7 * 86_400

#: NED <-> ENU for world vectors: (x, y, z) -> (y, x, -z). Symmetric, orthogonal, det +1.
A_WORLD = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
#: FRD <-> FLU for body vectors: (x, y, z) -> (x, -y, -z). Symmetric, orthogonal, det +1.
A_BODY = np.diag([1.0, -1.0, -1.0])
#: 6x6 NED <-> ENU for [linear, angular] both in world axes (e.g. a world-frame twist).
A6_WORLD = np.block([[A_WORLD, np.zeros((3, 3))], [np.zeros((3, 3)), A_WORLD]])
#: 6x6 FRD <-> FLU for [linear, angular] both in body axes (a body twist, TwistWithCovariance).
A6_BODY = np.block([[A_BODY, np.zeros((3, 3))], [np.zeros((3, 3)), A_BODY]])
#: 6x6 for a pose [position (world), orientation (roll, pitch, yaw / body-axis small angles)]:
#: NED/FRD <-> ENU/FLU, as in nav_msgs/Odometry pose.covariance.
A6_POSE = np.block([[A_WORLD, np.zeros((3, 3))], [np.zeros((3, 3)), A_BODY]])

_SQRT_HALF = math.sqrt(0.5)
_PI = math.pi
_TWO_PI = 2.0 * math.pi


def ssa(angle: Any) -> Any:
    """
    Return the smallest signed angle (rad) equivalent to ``angle``, in (-pi, pi].

    Fossen's MSS ``ssa`` (mod(angle + pi, 2 pi) - pi) but with the interval closed
    at +pi, and exact: angles already in (-pi, pi] are returned unchanged (no rounding through
    angle + pi), the reduction uses the exact IEEE remainder/fmod (the scalar and the array
    body give the same bits: both return angle - k 2pi, exactly, in (-pi, pi]). +-inf gives
    NaN. A scalar gives a Python float, an array a float64 array.
    """
    if is_scalar(angle):
        angle = float(angle)
        if -_PI < angle <= _PI or angle != angle:
            return angle
        if math.isinf(angle):
            return math.nan
        wrapped = math.remainder(angle, _TWO_PI)
        return _PI if wrapped <= -_PI else wrapped
    arr = np.asarray(angle, dtype=float)
    with np.errstate(invalid='ignore'):
        wrapped = np.fmod(arr, _TWO_PI)
        wrapped = np.where(wrapped > _PI, wrapped - _TWO_PI, wrapped)
        return np.where(wrapped <= -_PI, wrapped + _TWO_PI, wrapped)


def stamp_to_ns(sec: int, nanosec: int) -> int:
    """Return a builtin_interfaces/Time (sec, nanosec) as integer nanoseconds (exact)."""
    return int(sec) * NS_PER_S + int(nanosec)


def ns_to_stamp(ns: int) -> tuple[int, int]:
    """Return integer nanoseconds as (sec, nanosec) with 0 <= nanosec < 1e9 (ROS's form)."""
    sec, nanosec = divmod(int(ns), NS_PER_S)
    return sec, nanosec


def _as_last(a: ArrayLike, n: int, name: str) -> FloatArray:
    """Return ``a`` as a float array of shape (..., n), or raise ValueError naming it."""
    arr = np.asarray(a, dtype=float)
    if arr.shape[-1:] != (n,):
        raise ValueError(f'{name} must have shape (..., {n}), got {arr.shape}')
    return arr


def _swap_world(v: ArrayLike) -> FloatArray:
    """Return (y, x, -z) of (x, y, z), shape (..., 3)."""
    arr = _as_last(v, 3, 'v')
    return np.stack([arr[..., 1], arr[..., 0], -arr[..., 2]], axis=-1)


def _flip_body(v: ArrayLike) -> FloatArray:
    """Return (x, -y, -z) of (x, y, z), shape (..., 3)."""
    arr = _as_last(v, 3, 'v')
    return arr * np.array([1.0, -1.0, -1.0])


def swap_world3(x: float, y: float, z: float) -> tuple[float, float, float]:
    """
    Return (y, x, -z): one world vector NED -> ENU or ENU -> NED, as floats.

    The scalar kernel of :func:`ned_to_enu` / :func:`enu_to_ned` (an involution) for the
    per-message builders; the same numbers (the tests compare them).
    """
    return y, x, -z


def flip_body3(x: float, y: float, z: float) -> tuple[float, float, float]:
    """
    Return (x, -y, -z): one body vector FRD -> FLU or FLU -> FRD, as floats.

    The scalar kernel of :func:`frd_to_flu` / :func:`flu_to_frd` (an involution) for the
    per-message builders and conversions.
    """
    return x, -y, -z


def ned_to_enu(v: ArrayLike) -> FloatArray:
    """Return a world vector (position m, velocity m/s, rate rad/s) NED -> ENU: (y, x, -z)."""
    return _swap_world(v)


def enu_to_ned(v: ArrayLike) -> FloatArray:
    """Return a world vector ENU -> NED: (y, x, -z) (the same map; it is an involution)."""
    return _swap_world(v)


def frd_to_flu(v: ArrayLike) -> FloatArray:
    """Return a body vector (velocity m/s, rate rad/s, acceleration m/s^2) FRD -> FLU."""
    return _flip_body(v)


def flu_to_frd(v: ArrayLike) -> FloatArray:
    """Return a body vector FLU -> FRD: (x, -y, -z) (the same map; it is an involution)."""
    return _flip_body(v)


def quat_xyzw_to_wxyz(q_xyzw: ArrayLike) -> FloatArray:
    """Return a ROS/scipy scalar-last quaternion [x, y, z, w] in scalar-first order."""
    arr = _as_last(q_xyzw, 4, 'q_xyzw')
    return arr[..., [3, 0, 1, 2]]


def quat_wxyz_to_xyzw(q_wxyz: ArrayLike) -> FloatArray:
    """Return a scalar-first quaternion [w, x, y, z] in ROS/scipy scalar-last order."""
    arr = _as_last(q_wxyz, 4, 'q_wxyz')
    return arr[..., [1, 2, 3, 0]]


def swap_attitude4(w: float, x: float, y: float, z: float) -> tuple[float, float, float, float]:
    """
    Return [w + z, x + y, x - y, w - z] / sqrt2: q_nb <-> q_enu_flu, both scalar first.

    The one body of the Fossen <-> ROS attitude swap (an involution), as a pure-Python kernel
    for per-message callers: floats in, a tuple of floats out. The array functions below
    apply the same formula.
    """
    return (_SQRT_HALF * (w + z), _SQRT_HALF * (x + y), _SQRT_HALF * (x - y),
            _SQRT_HALF * (w - z))


def _swap_attitude(q: FloatArray) -> FloatArray:
    """Return :func:`swap_attitude4` of a scalar-first q (..., 4) as an array."""
    if q.ndim == 1:
        return np.array(swap_attitude4(*q.tolist()))
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return _SQRT_HALF * np.stack([w + z, x + y, x - y, w - z], axis=-1)


def q_nb_to_ros_wxyz(q_nb: ArrayLike) -> FloatArray:
    """
    Return q_enu_flu (scalar first) of Fossen's q_nb (FRD -> NED, scalar first).

    q_enu_flu = q_(ENU<-NED) (x) q_nb (x) q_(FRD<-FLU), equal up to sign to the closed form
    [w + z, x + y, x - y, w - z] / sqrt2 used here. Shape (..., 4).
    """
    return _swap_attitude(_as_last(q_nb, 4, 'q_nb'))


def q_nb_from_ros_wxyz(q_enu_flu: ArrayLike) -> FloatArray:
    """Return Fossen's q_nb (scalar first) of a scalar-first q_enu_flu; inverse of the above."""
    return _swap_attitude(_as_last(q_enu_flu, 4, 'q_enu_flu'))


def q_nb_to_ros(q_nb: ArrayLike) -> FloatArray:
    """
    Return the ROS orientation [x, y, z, w] (FLU -> ENU) of Fossen's q_nb [eta, eps] (FRD->NED).

    What goes into geometry_msgs/Quaternion. Shape (..., 4) -> (..., 4).
    """
    return quat_wxyz_to_xyzw(_swap_attitude(_as_last(q_nb, 4, 'q_nb')))


def q_nb_from_ros(q_xyzw: ArrayLike) -> FloatArray:
    """
    Return Fossen's q_nb [eta, eps] (FRD -> NED) of a ROS orientation [x, y, z] + [w].

    The inverse of :func:`q_nb_to_ros`: ``q_nb_from_ros(q_nb_to_ros(q)) == q`` (to round-off).
    The input is not normalised; see :func:`vessel_kinematics.core.quaternion.normalize`.
    """
    return _swap_attitude(quat_xyzw_to_wxyz(q_xyzw))


def yaw_ned_to_enu(psi: Any) -> Any:
    """
    Return the ROS yaw (ENU, from east, counter-clockwise) of a heading psi (NED), rad.

    yaw = ssa(pi/2 - psi) in (-pi, pi] for scalars and arrays alike (west: +pi).
    """
    if is_scalar(psi):
        return ssa(0.5 * _PI - float(psi))
    return ssa(0.5 * _PI - np.asarray(psi, dtype=float))


def yaw_enu_to_ned(yaw: Any) -> Any:
    """Return the heading psi (NED, from north, clockwise) of a ROS yaw (ENU), rad."""
    return yaw_ned_to_enu(yaw)


def euler_ned_to_enu(phi: Any, theta: Any, psi: Any) -> tuple[Any, Any, Any]:
    """
    Return ROS (roll, pitch, yaw) (FLU -> ENU) of Fossen's zyx (phi, theta, psi) (FRD -> NED).

    roll = phi, pitch = -theta, yaw = pi/2 - psi wrapped to (-pi, pi]; the same map inverts.
    Scalars give a tuple of floats, arrays a tuple of broadcast float64 arrays.
    """
    if is_scalar(phi) and is_scalar(theta) and is_scalar(psi):
        return float(phi), -float(theta), yaw_ned_to_enu(float(psi))
    roll, pitch, yaw = np.broadcast_arrays(*(np.asarray(a, dtype=float)
                                             for a in (phi, theta, psi)))
    return roll.copy(), -pitch, yaw_ned_to_enu(yaw)


def euler_enu_to_ned(roll: Any, pitch: Any, yaw: Any) -> tuple[Any, Any, Any]:
    """Return Fossen's (phi, theta, psi) of ROS (roll, pitch, yaw); the same map."""
    return euler_ned_to_enu(roll, pitch, yaw)


def yaw_from_q(q: Any) -> Any:
    """
    Return the zyx yaw (rad, (-pi, pi]) of scalar-first quaternions q = [eta, eps] (..., 4).

    psi = atan2(2 (eps1 eps2 + eta eps3), eta^2 + eps1^2 - eps2^2 - eps3^2): the yaw of
    R(q) (R[1, 0], R[0, 0] of Fossen eq. 2.72 times |q|^2), so q needs no normalisation. Of
    Fossen's q_nb it is the heading psi (NED); of a ROS orientation (ENU/FLU, reordered to
    scalar first) the ROS yaw. At theta = +-90 deg exactly (both zero) the yaw for phi = 0,
    atan2(-R[0, 1], R[1, 1]), is returned. One quaternion (a 4-sequence) gives a float, a
    batch a float64 array. The pure-Python body is the per-message path.
    """
    if is_point(q, 4):
        eta, e1, e2, e3 = (float(c) for c in q)
        r10 = 2.0 * (e1 * e2 + eta * e3)
        r00 = eta * eta + e1 * e1 - e2 * e2 - e3 * e3
        if r10 == 0.0 and r00 == 0.0:
            r10 = -2.0 * (e1 * e2 - eta * e3)
            r00 = eta * eta - e1 * e1 + e2 * e2 - e3 * e3
        angle = math.atan2(r10, r00)
        return _PI if angle == -_PI else angle
    arr = _as_last(q, 4, 'q')
    a_w, a_x, a_y, a_z = arr[..., 0], arr[..., 1], arr[..., 2], arr[..., 3]
    a10 = 2.0 * (a_x * a_y + a_w * a_z)
    a00 = a_w * a_w + a_x * a_x - a_y * a_y - a_z * a_z
    locked = (a10 == 0.0) & (a00 == 0.0)
    yaw = np.arctan2(np.where(locked, -2.0 * (a_x * a_y - a_w * a_z), a10),
                     np.where(locked, a_w * a_w - a_x * a_x + a_y * a_y - a_z * a_z, a00))
    return np.where(yaw == -_PI, _PI, yaw)


def yaw_from_ros(q_xyzw: Any) -> Any:
    """Return the ROS yaw (ENU, rad, (-pi, pi]) of ROS orientations [x, y, z, w] (..., 4)."""
    if is_point(q_xyzw, 4):
        x, y, z, w = q_xyzw
        return yaw_from_q((w, x, y, z))
    return yaw_from_q(quat_xyzw_to_wxyz(q_xyzw))


def cov_transform(cov: ArrayLike, a: ArrayLike) -> FloatArray:
    """Return A C A^T for covariances C (..., n, n) and a transform A (n, n) or (..., n, n)."""
    c = np.asarray(cov, dtype=float)
    m = np.asarray(a, dtype=float)
    return m @ c @ np.swapaxes(m, -1, -2)


def _cov(cov: ArrayLike, a: FloatArray) -> FloatArray:
    """Return A C A^T after checking the covariance shape against A."""
    c = np.asarray(cov, dtype=float)
    n = a.shape[0]
    if c.shape[-2:] != (n, n):
        raise ValueError(f'covariance must have shape (..., {n}, {n}), got {c.shape}')
    return a @ c @ a.T


def cov3_ned_to_enu(cov: ArrayLike) -> FloatArray:
    """Return a 3x3 world covariance (position m^2, velocity) NED -> ENU: A_W C A_W^T."""
    return _cov(cov, A_WORLD)


def cov3_enu_to_ned(cov: ArrayLike) -> FloatArray:
    """Return a 3x3 world covariance ENU -> NED: A_W C A_W^T (an involution)."""
    return _cov(cov, A_WORLD)


def cov3_frd_to_flu(cov: ArrayLike) -> FloatArray:
    """Return a 3x3 body covariance (velocity, rate, attitude angles) FRD -> FLU: A_B C A_B^T."""
    return _cov(cov, A_BODY)


def cov3_flu_to_frd(cov: ArrayLike) -> FloatArray:
    """Return a 3x3 body covariance FLU -> FRD: A_B C A_B^T (an involution)."""
    return _cov(cov, A_BODY)


def cov6_ned_to_enu(cov: ArrayLike) -> FloatArray:
    """Return a 6x6 covariance of [linear, angular] both in world axes, NED -> ENU."""
    return _cov(cov, A6_WORLD)


def cov6_enu_to_ned(cov: ArrayLike) -> FloatArray:
    """Return a 6x6 covariance of [linear, angular] both in world axes, ENU -> NED."""
    return _cov(cov, A6_WORLD)


def cov6_frd_to_flu(cov: ArrayLike) -> FloatArray:
    """Return a 6x6 twist covariance [u, v, w, p, q, r] in body axes, FRD -> FLU."""
    return _cov(cov, A6_BODY)


def cov6_flu_to_frd(cov: ArrayLike) -> FloatArray:
    """Return a 6x6 twist covariance [vx, vy, vz, wx, wy, wz] in body axes, FLU -> FRD."""
    return _cov(cov, A6_BODY)


def cov6_pose_to_ros(cov: ArrayLike) -> FloatArray:
    """
    Return a 6x6 pose covariance [N, E, D, phi, theta, psi] as ROS [x, y, z, roll, pitch, yaw].

    Position block NED -> ENU (A_W); attitude block by A_B = diag(1, -1, -1), which is both
    the Jacobian of (roll, pitch, yaw) = (phi, -theta, pi/2 - psi) and the FRD -> FLU map of a
    body-axis small attitude error; cross terms follow. For nav_msgs/Odometry pose.covariance.
    """
    return _cov(cov, A6_POSE)


def cov6_pose_from_ros(cov: ArrayLike) -> FloatArray:
    """Return a ROS pose covariance [x, y, z, roll, pitch, yaw] in Fossen's order and frames."""
    return _cov(cov, A6_POSE)

"""
Unit quaternions: Fossen (2011), Sections 2.2.2-2.2.4.

q = [eta, eps1, eps2, eps3], SCALAR FIRST, unit norm, Hamilton product; q rotates BODY (FRD)
into NED: v_n = R(q) v_b with R(q) = Fossen's R_b^n. Attitude kinematics q_dot = T(q) omega_b.
ROS ``xyzw`` order and ENU/FLU frames live in :mod:`vessel_kinematics.core.frames`, not here.

Every function accepts one quaternion (4,) or a batch (..., 4) (vectors (..., 3), matrices
(..., 3, 3)) and has one vectorised numpy body; results follow the output rule of
:mod:`vessel_kinematics.core.dispatch` (quaternions, vectors and matrices are float64 ndarrays, the
Euler triple of one quaternion a tuple of floats). The pure-Python kernels :func:`mul4`,
:func:`normalize4`, :func:`half_sinc`, :func:`rquat9`, :func:`integrate_euler4` and
:func:`integrate_exp4` (floats in, floats out) are the per-message hot path of the estimator
(the last two are also the one-point bodies of :func:`integrate_euler` and
:func:`integrate_exp`); the numpy bodies use the same formulas.

Invalid input policy (NaN out, no exception): :func:`normalize` of a quaternion that has no
direction (zero, any component NaN or infinite) returns four NaN, and NaN input gives NaN output
everywhere. Check cheaply with :func:`is_unit` (False for NaN) or ``numpy.isfinite``.
Functions that expect a unit quaternion (``rquat``, ``quat_rotate``, ``q2euler``) do not
normalise it: pass ``normalize(q)`` if it may have drifted.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from vessel_kinematics.core.dispatch import (FloatArray, is_point, is_scalar, stack_matrix,
                                             to_float, to_floats)
from vessel_kinematics.core.rotation import euler_from_rows, EULER_LOCK_TOL

__all__ = ['Quat4', 'axis_angle2q', 'euler2q', 'half_sinc', 'integrate_euler',
           'integrate_euler4', 'integrate_exp', 'integrate_exp4', 'is_unit', 'mul4',
           'normalization_term', 'normalize', 'normalize4', 'q2euler',
           'q2rotvec', 'quat_conjugate', 'quat_derivative', 'quat_multiply', 'quat_rotate',
           'quatern', 'rot2q', 'rotvec2q', 'rquat', 'rquat9', 'tquat']

#: A scalar-first quaternion as four Python floats (the kernels' type).
Quat4 = tuple[float, float, float, float]

_NAN4 = (math.nan, math.nan, math.nan, math.nan)


def _as_quat(q: ArrayLike, name: str = 'q') -> FloatArray:
    """Return ``q`` as a float array of shape (..., 4), or raise ValueError naming it."""
    arr = np.asarray(q, dtype=float)
    if arr.shape[-1:] != (4,):
        raise ValueError(f'{name} must have shape (..., 4) [eta, eps1, eps2, eps3], '
                         f'got {arr.shape}')
    return arr


def _as_vec3(v: ArrayLike, name: str) -> FloatArray:
    """Return ``v`` as a float array of shape (..., 3), or raise ValueError naming it."""
    arr = np.asarray(v, dtype=float)
    if arr.shape[-1:] != (3,):
        raise ValueError(f'{name} must have shape (..., 3), got {arr.shape}')
    return arr


def _split(q: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Return the four components of a (..., 4) array."""
    return q[..., 0], q[..., 1], q[..., 2], q[..., 3]


def normalize4(w: float, x: float, y: float, z: float) -> Quat4:
    """Return (w, x, y, z) / |(w, x, y, z)| or four NaN: the scalar kernel of :func:`normalize`."""
    n = math.hypot(w, x, y, z)
    if 1e-290 < n < math.inf:
        return w / n, x / n, y / n, z / n
    if 0.0 < n <= 1e-290 or (n == math.inf and all(map(math.isfinite, (w, x, y, z)))):
        # Denormal or overflowing norm: rescale by a power of two (exact), then normalise.
        k = -math.frexp(max(abs(w), abs(x), abs(y), abs(z)))[1]
        return normalize4(math.ldexp(w, k), math.ldexp(x, k), math.ldexp(y, k),
                          math.ldexp(z, k))
    return _NAN4


def normalize(q: ArrayLike) -> FloatArray:
    """
    Return q / |q| (Fossen Section 2.2.2: q^T q = 1).

    Accurate for any finite non-zero q, from denormal (1e-320) to huge (1e300) components
    (the norm is computed with scaling). A quaternion without direction (zero, NaN or infinite
    components) gives [nan, nan, nan, nan]: the documented NaN-out policy, never an exception,
    so a batch keeps its good rows. Detect it with :func:`is_unit` or ``numpy.isnan``.
    """
    arr = _as_quat(q)
    with np.errstate(invalid='ignore', divide='ignore', over='ignore'):
        scale = np.max(np.abs(arr), axis=-1, keepdims=True)
        # Rescale by a power of two (exact, also for denormals), then normalise.
        unit = np.ldexp(arr, -np.frexp(scale)[1])
        unit = unit / np.sqrt(np.sum(unit * unit, axis=-1, keepdims=True))
    bad = ~((scale > 0.0) & np.isfinite(scale))
    return np.where(bad, np.nan, unit)


def is_unit(q: ArrayLike, tol: float = 1e-9) -> bool | NDArray[np.bool_]:
    """
    Return True where | |q| - 1 | <= ``tol``; False for NaN or infinite components.

    The cheap validity check for quaternions from outside (messages, integrators).
    Returns a bool for one quaternion, a boolean array (...) for a batch.
    """
    arr = _as_quat(q)
    unit = np.abs(np.sqrt(np.sum(arr * arr, axis=-1)) - 1.0) <= tol
    return bool(unit) if arr.ndim == 1 else unit


def quat_conjugate(q: ArrayLike) -> FloatArray:
    """Return q* = [eta, -eps] (the inverse of a unit quaternion)."""
    arr = _as_quat(q)
    return arr * np.array([1.0, -1.0, -1.0, -1.0])


def mul4(p: Any, q: Any) -> Quat4:
    """Return the Hamilton product p (x) q of two scalar-first 4-tuples (the scalar kernel)."""
    pw, px, py, pz = p
    qw, qx, qy, qz = q
    return (pw * qw - px * qx - py * qy - pz * qz,
            pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw)


def quat_multiply(p: ArrayLike, q: ArrayLike) -> FloatArray:
    """
    Return the Hamilton product p (x) q (Fossen Section 2.2.2), scalar first.

    [p_eta q_eta - p_eps . q_eps, p_eta q_eps + q_eta p_eps + p_eps x q_eps]. Composition:
    R(p (x) q) = R(p) R(q); q_a^c = q_b^c (x) q_a^b. Shapes (..., 4) broadcast.
    """
    a, b = _as_quat(p, 'p'), _as_quat(q, 'q')
    pw, px, py, pz = _split(a)
    qw, qx, qy, qz = _split(b)
    return np.stack(np.broadcast_arrays(pw * qw - px * qx - py * qy - pz * qz,
                                        pw * qx + px * qw + py * qz - pz * qy,
                                        pw * qy - px * qz + py * qw + pz * qx,
                                        pw * qz + px * qy - py * qx + pz * qw), axis=-1)


def rquat(q: ArrayLike) -> FloatArray:
    """
    Return R(q) = I_3 + 2 eta S(eps) + 2 S(eps)^2 (Fossen eq. 2.72), BODY -> NED.

    ``q`` must be a unit quaternion (not normalised here); q and -q give the same R.
    Shape (..., 4) -> (..., 3, 3).
    """
    return stack_matrix(list(rquat9(*_split(_as_quat(q)))), 3, 3)


def rquat9(w: Any, x: Any, y: Any, z: Any) -> tuple[Any, ...]:
    """
    Return R(q) (Fossen eq. 2.72) row-major as nine entries: the one body of R(q).

    R = I_3 + 2 eta S(eps) + 2 S(eps)^2 for unit q = [w, x, y, z] (w = eta). Used by
    :func:`rquat`, :func:`q2euler`, :func:`vessel_kinematics.core.flow.heading` and the estimator:
    Python floats in, floats out (the per-message kernel); float64 arrays of the components
    broadcast the same way and give the same numbers.
    """
    return (1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - z * w), 2.0 * (x * z + y * w),
            2.0 * (x * y + z * w), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - x * w),
            2.0 * (x * z - y * w), 2.0 * (y * z + x * w), 1.0 - 2.0 * (x * x + y * y))


def tquat(q: ArrayLike) -> FloatArray:
    """
    Return T(q), q_dot = T(q) omega_b (Fossen eq. 2.78), a 4x3 matrix.

    T(q) = 1/2 [[-eps^T], [eta I_3 + S(eps)]]; for unit q, T(q)^T T(q) = I_3 / 4.
    Shape (..., 4) -> (..., 4, 3).
    """
    w, x, y, z = _split(0.5 * _as_quat(q))
    return stack_matrix([-x, -y, -z, w, -z, y, z, w, -x, -y, x, w], 4, 3)


def quatern(q: ArrayLike) -> FloatArray:
    """
    Return J_q(eta) = diag(R(q), T(q)), eta_dot = J_q nu (Fossen Section 2.2.2), 7x6.

    eta = [x, y, z, eta, eps1, eps2, eps3] (m, -) in NED, nu = [u, v, w, p, q, r]
    (m/s, rad/s) in BODY. Shape (..., 4) -> (..., 7, 6).
    """
    arr = _as_quat(q)
    j = np.zeros(arr.shape[:-1] + (7, 6))
    j[..., :3, :3] = rquat(arr)
    j[..., 3:, 3:] = tquat(arr)
    return j


def quat_rotate(q: ArrayLike, v: ArrayLike) -> FloatArray:
    """
    Return R(q) v: a BODY vector v_b in NED, v_n = R(q) v_b, for unit q.

    Uses t = 2 eps x v, R(q) v = v + eta t + eps x t (no matrix). Shapes (..., 4) and
    (..., 3) broadcast; the result has shape (..., 3).
    """
    arr, vec = _as_quat(q), _as_vec3(v, 'v')
    eps = arr[..., 1:]
    t = 2.0 * np.cross(eps, vec)
    return vec + arr[..., :1] * t + np.cross(eps, t)


def rot2q(r: ArrayLike) -> FloatArray:
    """
    Return the unit quaternion of a rotation matrix by Shepperd's algorithm (Sec. 2.2.3).

    Of 4 eta^2 = 1 + tr R and 4 eps_i^2 = 1 + 2 R_ii - tr R the largest is taken for the square
    root (the pivot), the other three components follow from sums and differences of
    off-diagonal elements divided by the pivot, so no division by a small number occurs.
    The result is normalised and has eta >= 0. Shape (..., 3, 3) -> (..., 4).
    """
    m = np.asarray(r, dtype=float)
    if m.shape[-2:] != (3, 3):
        raise ValueError(f'R must have shape (..., 3, 3), got {m.shape}')
    r11, r12, r13 = m[..., 0, 0], m[..., 0, 1], m[..., 0, 2]
    r21, r22, r23 = m[..., 1, 0], m[..., 1, 1], m[..., 1, 2]
    r31, r32, r33 = m[..., 2, 0], m[..., 2, 1], m[..., 2, 2]
    tr = r11 + r22 + r33
    pivots = np.stack([1.0 + tr, 1.0 + 2.0 * r11 - tr, 1.0 + 2.0 * r22 - tr,
                       1.0 + 2.0 * r33 - tr], axis=-1)
    choice = np.argmax(pivots, axis=-1)
    with np.errstate(invalid='ignore', divide='ignore'):
        s = np.sqrt(np.take_along_axis(pivots, choice[..., None], axis=-1)[..., 0])
        h = 0.5 / s
        candidates = np.stack([
            np.stack([0.5 * s, (r32 - r23) * h, (r13 - r31) * h, (r21 - r12) * h], axis=-1),
            np.stack([(r32 - r23) * h, 0.5 * s, (r21 + r12) * h, (r13 + r31) * h], axis=-1),
            np.stack([(r13 - r31) * h, (r21 + r12) * h, 0.5 * s, (r32 + r23) * h], axis=-1),
            np.stack([(r21 - r12) * h, (r13 + r31) * h, (r32 + r23) * h, 0.5 * s], axis=-1),
        ], axis=-2)
    q = np.take_along_axis(candidates, choice[..., None, None], axis=-2)[..., 0, :]
    q = normalize(q)
    return np.where(q[..., :1] < 0.0, -q, q)


def euler2q(phi: ArrayLike, theta: ArrayLike, psi: ArrayLike) -> FloatArray:
    """
    Return the unit quaternion of the zyx Euler angles (rad), i.e. of rzyx(phi, theta, psi).

    q = q_z(psi) (x) q_y(theta) (x) q_x(phi) in closed form (half angles), sign chosen so that
    eta >= 0 like Shepperd's rot2q (and Fossen's MSS euler2q). Angles broadcast; (..., 4).
    """
    half = [0.5 * np.asarray(a, dtype=float) for a in (phi, theta, psi)]
    cr, sr = np.cos(half[0]), np.sin(half[0])
    cp, sp = np.cos(half[1]), np.sin(half[1])
    cy, sy = np.cos(half[2]), np.sin(half[2])
    q = np.stack(np.broadcast_arrays(cr * cp * cy + sr * sp * sy,
                                     sr * cp * cy - cr * sp * sy,
                                     cr * sp * cy + sr * cp * sy,
                                     cr * cp * sy - sr * sp * cy), axis=-1)
    return np.where(q[..., :1] < 0.0, -q, q)


def q2euler(q: ArrayLike, lock_tol: float = EULER_LOCK_TOL) -> tuple[Any, Any, Any]:
    """
    Return the zyx Euler angles (phi, theta, psi) in rad of a unit quaternion.

    The same atan2 form and gimbal-lock rule as :func:`~vessel_kinematics.core.rotation.rot2euler`
    applied to the elements of R(q): theta = atan2(-R31, sqrt(R32^2 + R33^2)) never takes an
    asin of a rounded value above 1, so theta = +-90 deg gives +-pi/2 and no NaN; at gimbal
    lock phi = 0 and psi carries the rotation about the vertical. Returns a tuple of floats for
    one quaternion, of arrays (...) for a batch. NaN gives NaN.
    """
    arr = _as_quat(q)
    r11, r12, r13, r21, r22, r23, r31, r32, r33 = rquat9(*_split(arr))
    return euler_from_rows(r12, r13, r22, r23, r31, r32, r33, lock_tol)


def axis_angle2q(axis: ArrayLike, beta: ArrayLike) -> FloatArray:
    """
    Return q = [cos(beta/2), lambda sin(beta/2)] for a rotation of ``beta`` rad about axis.

    lambda = axis/|axis| (Fossen Section 2.2.2). Same rotation as
    ``rotation_axis_angle(axis, beta)``. A zero axis gives NaN (see :func:`normalize`).
    """
    ax = _as_vec3(axis, 'axis')
    with np.errstate(invalid='ignore', divide='ignore', over='ignore'):
        scale = np.max(np.abs(ax), axis=-1, keepdims=True)
        unit = ax / scale
        lam = unit / np.linalg.norm(unit, axis=-1, keepdims=True)
    half = 0.5 * np.asarray(beta, dtype=float)[..., None]
    eps = np.sin(half) * lam
    q = np.concatenate([np.broadcast_to(np.cos(half), eps.shape[:-1] + (1,)), eps], axis=-1)
    return np.where(np.isfinite(scale) & (scale > 0.0), q, np.nan)


def half_sinc(a: float) -> float:
    """Return sin(a)/a, by its Taylor series for |a| < 1e-4 (exactly 1 at a = 0); a kernel."""
    if abs(a) < 1e-4:
        a2 = a * a
        return 1.0 - a2 / 6.0 * (1.0 - a2 / 20.0)
    return math.sin(a) / a


def rotvec2q(rv: ArrayLike) -> FloatArray:
    """
    Return exp of a rotation vector: q = [cos(|rv|/2), sin(|rv|/2) rv/|rv|] (rad).

    The quaternion exponential map used by :func:`integrate_exp`; smooth at rv = 0 (a series
    for small angles, exactly [1, 0, 0, 0] at 0) and unit to round-off. Shape (..., 3) ->
    (..., 4).
    """
    vec = _as_vec3(rv, 'rv')
    half = 0.5 * np.linalg.norm(vec, axis=-1)
    small = half < 1e-4
    with np.errstate(invalid='ignore', divide='ignore'):
        sinc = np.where(small, 1.0 - half * half / 6.0 * (1.0 - half * half / 20.0),
                        np.sin(half) / np.where(small, 1.0, half))
    return np.concatenate([np.cos(half)[..., None], (0.5 * sinc)[..., None] * vec], axis=-1)


def q2rotvec(q: ArrayLike) -> FloatArray:
    """
    Return the rotation vector (rad) of a unit quaternion: the log map, inverse of rotvec2q.

    rv = 2 atan2(|eps|, eta) eps/|eps| with the sign of q chosen so eta >= 0, so |rv| <= pi;
    accurate for tiny and for near-pi angles. Shape (..., 4) -> (..., 3).
    """
    arr = _as_quat(q)
    arr = np.where(arr[..., :1] < 0.0, -arr, arr)
    eps = arr[..., 1:]
    n = np.linalg.norm(eps, axis=-1)
    angle = 2.0 * np.arctan2(n, arr[..., 0])
    with np.errstate(invalid='ignore', divide='ignore'):
        # Small angle: 2 atan2(n, eta)/n -> 2/eta (n -> 0).
        k = np.where(n < 1e-8, 2.0 / arr[..., 0], angle / np.where(n == 0.0, 1.0, n))
    return k[..., None] * eps


def normalization_term(q: ArrayLike, gamma: ArrayLike) -> FloatArray:
    """
    Return (gamma/2) (1 - q^T q) q, the continuous-time normalisation term (Fossen Sec. 2.2.4).

    Added to T(q) omega it makes |q| = 1 an attracting set for ODE solvers; ``gamma`` >= 0
    (1/s), typically 100, broadcasts with the batch (...). Shape (..., 4).
    """
    arr = _as_quat(q)
    defect = 1.0 - np.sum(arr * arr, axis=-1, keepdims=True)
    return 0.5 * np.asarray(gamma, dtype=float)[..., None] * defect * arr


def quat_derivative(q: ArrayLike, omega: ArrayLike, gamma: float = 0.0) -> FloatArray:
    """
    Return q_dot = T(q) omega + (gamma/2) (1 - q^T q) q (Fossen eqs. 2.78 and Sec. 2.2.4).

    ``omega`` is the BODY angular rate (p, q, r) in rad/s; gamma = 0 gives the plain
    kinematics. Shapes (..., 4) and (..., 3) broadcast -> (..., 4).
    """
    arr, w = _as_quat(q), _as_vec3(omega, 'omega')
    pure = np.concatenate([np.zeros(w.shape[:-1] + (1,)), w], axis=-1)
    qdot = 0.5 * quat_multiply(arr, pure)
    if gamma:
        qdot = qdot + normalization_term(arr, gamma)
    return qdot


def integrate_euler(q: ArrayLike, omega: ArrayLike, h: ArrayLike) -> FloatArray:
    """
    Return Fossen's discrete step q + h T(q) omega followed by normalisation (Sec. 2.2.4).

    First order: the attitude error per step is O(|omega h|^2). Kept for reference and
    comparison; prefer :func:`integrate_exp`. ``omega`` rad/s (BODY), ``h`` s.
    """
    if is_point(q, 4) and is_point(omega, 3) and is_scalar(h):
        return np.array(integrate_euler4(to_floats(q), to_floats(omega), to_float(h)),
                        dtype=np.float64)
    arr, w = _as_quat(q), _as_vec3(omega, 'omega')
    step = np.asarray(h, dtype=float)[..., None]
    return normalize(arr + step * quat_derivative(arr, w))


def integrate_exp(q: ArrayLike, omega: ArrayLike, h: ArrayLike) -> FloatArray:
    """
    Return q (x) exp(omega h / 2): exact for a constant BODY rate ``omega`` over the step.

    q_{k+1} = q_k (x) [cos(|omega| h/2), sin(|omega| h/2) omega/|omega|] (the solution of
    q_dot = T(q) omega for constant omega), with a series for small |omega| h so omega = 0
    returns q exactly (normalised) and the map is smooth there. The result is normalised:
    a unit quaternion. q (..., 4), omega (..., 3) rad/s, h s (...).
    """
    if is_point(q, 4) and is_point(omega, 3) and is_scalar(h):
        return np.array(integrate_exp4(to_floats(q), to_floats(omega), to_float(h)),
                        dtype=np.float64)
    arr, w = _as_quat(q), _as_vec3(omega, 'omega')
    step = np.asarray(h, dtype=float)[..., None]
    return normalize(quat_multiply(arr, rotvec2q(w * step)))


def integrate_euler4(q: Any, omega: Any, h: float) -> Quat4:
    """
    Return :func:`integrate_euler` of one quaternion as four floats: the per-step kernel.

    normalize4(q + (h/2) q (x) [0, omega]) written out (Fossen Sec. 2.2.4); ``q`` a scalar-first
    4-sequence, ``omega`` (p, q, r) rad/s, ``h`` s. The attitude integrator of the estimator
    runs this per IMU sample.
    """
    qw, qx, qy, qz = q
    hp, hq, hr = 0.5 * h * omega[0], 0.5 * h * omega[1], 0.5 * h * omega[2]
    return normalize4(qw - qx * hp - qy * hq - qz * hr,
                      qx + qw * hp - qz * hq + qy * hr,
                      qy + qz * hp + qw * hq - qx * hr,
                      qz - qy * hp + qx * hq + qw * hr)


def integrate_exp4(q: Any, omega: Any, h: float) -> Quat4:
    """
    Return :func:`integrate_exp` of one quaternion as four floats: the per-step kernel.

    normalize4(q (x) [cos(|omega| h/2), (h/2) sinc(|omega| h/2) omega]) with
    :func:`half_sinc`, so omega = 0 returns q (normalised); the same map as the numpy body.
    """
    a, b, c = omega
    half = 0.5 * h * math.hypot(a, b, c)
    k = 0.5 * h * half_sinc(half)
    return normalize4(*mul4(q, (math.cos(half), k * a, k * b, k * c)))

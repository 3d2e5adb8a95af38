"""
Rotation matrices and Euler angles: Fossen (2011), Sections 2.2 and 2.2.1.

Conventions (the whole core): radians; NED world frame {n}; BODY frame {b} with x forward,
y starboard, z down (FRD). ``R`` is Fossen's R_b^n, rotating BODY vectors into NED:
v_n = R v_b. The Euler angles Theta = [phi, theta, psi] (roll, pitch, yaw) follow the zyx
convention, R_b^n = R_z,psi R_y,theta R_x,phi (eq. 2.18).

Every function accepts scalars or arrays with leading batch axes (angles broadcast against each
other, vectors have shape (..., 3), matrices (..., 3, 3)) and has one vectorised numpy body;
results follow the output rule of :mod:`vessel_kinematics.core.dispatch` (matrices and vectors are
float64 ndarrays, the Euler triple of one matrix a tuple of floats). NaN in gives NaN out; the
only exception raised on numeric input is :class:`GimbalLockError` from :func:`tzyx` and
:func:`eulerang`, whose contract is to refuse the singularity.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from vessel_kinematics.core.dispatch import FloatArray, one_point, stack_matrix, to_output

__all__ = ['EULER_LOCK_TOL', 'GIMBAL_LOCK_TOL', 'GimbalLockError', 'euler_from_rows',
           'eulerang', 'rot2euler', 'rot_x', 'rot_y', 'rot_z', 'rotation_axis_angle',
           'rotation_rate', 'rzyx', 'rzyx_small_angle', 'skew', 'tzyx', 'vee']

#: ``tzyx`` refuses |cos(theta)| below this (rad, the distance to theta = +-90 deg), so the
#: entries of T_Theta stay below 1/GIMBAL_LOCK_TOL = 1e6 and are never silently 1e16 or NaN.
GIMBAL_LOCK_TOL = 1e-6

#: ``rot2euler``/``q2euler`` treat cos(theta) below this as gimbal lock: roll is set to 0 and
#: all of the rotation about the vertical goes into yaw. The matrix rebuilt from the returned
#: angles then differs from the input by at most about this much.
EULER_LOCK_TOL = 1e-10


class GimbalLockError(ValueError):
    """Raised where T_Theta (eq. 2.28) is requested within the tolerance of theta = +-90 deg."""


def _as_vec3(a: ArrayLike, name: str) -> FloatArray:
    """Return ``a`` as a float array of shape (..., 3), or raise ValueError naming it."""
    arr = np.asarray(a, dtype=float)
    if arr.shape[-1:] != (3,):
        raise ValueError(f'{name} must have shape (..., 3), got {arr.shape}')
    return arr


def _as_mat3(m: ArrayLike, name: str) -> FloatArray:
    """Return ``m`` as a float array of shape (..., 3, 3), or raise ValueError naming it."""
    arr = np.asarray(m, dtype=float)
    if arr.shape[-2:] != (3, 3):
        raise ValueError(f'{name} must have shape (..., 3, 3), got {arr.shape}')
    return arr


def skew(a: ArrayLike) -> FloatArray:
    """
    Return the skew-symmetric matrix S(a) with S(a) b = a x b (Fossen Section 2.2).

    ``a`` has shape (..., 3); the result has shape (..., 3, 3) and S(a)^T = -S(a).
    """
    v = _as_vec3(a, 'a')
    zero = np.zeros(v.shape[:-1])
    a1, a2, a3 = v[..., 0], v[..., 1], v[..., 2]
    return stack_matrix([zero, -a3, a2, a3, zero, -a1, -a2, a1, zero], 3, 3)


def vee(s: ArrayLike) -> FloatArray:
    """
    Return the vector a of a skew-symmetric matrix S(a): the inverse of :func:`skew`.

    Uses the antisymmetric part, a = vee((S - S^T) / 2), so a nearly skew matrix gives the
    nearest vector. Shape (..., 3, 3) -> (..., 3).
    """
    m = _as_mat3(s, 's')
    return 0.5 * np.stack([m[..., 2, 1] - m[..., 1, 2],
                           m[..., 0, 2] - m[..., 2, 0],
                           m[..., 1, 0] - m[..., 0, 1]], axis=-1)


def rot_x(phi: ArrayLike) -> FloatArray:
    """Return R_x,phi, the principal rotation about x by ``phi`` rad (Fossen Sec. 2.2.1)."""
    angle = np.asarray(phi, dtype=float)
    c, s = np.cos(angle), np.sin(angle)
    one, zero = np.ones_like(c), np.zeros_like(c)
    return stack_matrix([one, zero, zero, zero, c, -s, zero, s, c], 3, 3)


def rot_y(theta: ArrayLike) -> FloatArray:
    """Return R_y,theta, the principal rotation about y by ``theta`` rad (Fossen Sec. 2.2.1)."""
    angle = np.asarray(theta, dtype=float)
    c, s = np.cos(angle), np.sin(angle)
    one, zero = np.ones_like(c), np.zeros_like(c)
    return stack_matrix([c, zero, s, zero, one, zero, -s, zero, c], 3, 3)


def rot_z(psi: ArrayLike) -> FloatArray:
    """Return R_z,psi, the principal rotation about z by ``psi`` rad (Fossen Sec. 2.2.1)."""
    angle = np.asarray(psi, dtype=float)
    c, s = np.cos(angle), np.sin(angle)
    one, zero = np.ones_like(c), np.zeros_like(c)
    return stack_matrix([c, -s, zero, s, c, zero, zero, zero, one], 3, 3)


def rzyx(phi: ArrayLike, theta: ArrayLike, psi: ArrayLike) -> FloatArray:
    """
    Return R_b^n(Theta) = R_z,psi R_y,theta R_x,phi (Fossen eq. 2.18), BODY -> NED.

    Angles in rad, broadcast against each other; the result has shape (..., 3, 3).
    """
    phi, theta, psi = (np.asarray(x, dtype=float) for x in (phi, theta, psi))
    cphi, sphi = np.cos(phi), np.sin(phi)
    cth, sth = np.cos(theta), np.sin(theta)
    cpsi, spsi = np.cos(psi), np.sin(psi)
    return stack_matrix([
        cpsi * cth, -spsi * cphi + cpsi * sth * sphi, spsi * sphi + cpsi * cphi * sth,
        spsi * cth, cpsi * cphi + sphi * sth * spsi, -cpsi * sphi + sth * spsi * cphi,
        -sth, cth * sphi, cth * cphi], 3, 3)


def rzyx_small_angle(phi: ArrayLike, theta: ArrayLike, psi: ArrayLike) -> FloatArray:
    """
    Return the small-angle approximation R_b^n ~ I_3 + S(Theta) (Fossen Section 2.2.1).

    Theta = [phi, theta, psi] rad; first order in the angles (error O(|Theta|^2)), so the
    result is not orthogonal. Shape (..., 3, 3).
    """
    theta_vec = np.stack(np.broadcast_arrays(*[np.asarray(x, dtype=float)
                                               for x in (phi, theta, psi)]), axis=-1)
    return np.eye(3) + skew(theta_vec)


def tzyx(phi: ArrayLike, theta: ArrayLike, tol: float = GIMBAL_LOCK_TOL) -> FloatArray:
    """
    Return T_Theta(Theta), Theta_dot = T_Theta omega_b (Fossen eq. 2.28), zyx convention.

    T_Theta = [[1, sin(phi) tan(theta), cos(phi) tan(theta)],
               [0, cos(phi), -sin(phi)],
               [0, sin(phi)/cos(theta), cos(phi)/cos(theta)]]

    Raises :class:`GimbalLockError` (a ValueError) where |cos(theta)| < ``tol`` for any element
    (theta within about ``tol`` rad of +-90 deg), instead of returning 1e16 or inf. NaN angles
    give NaN entries. Shape (..., 3, 3).
    """
    phi, theta = np.asarray(phi, dtype=float), np.asarray(theta, dtype=float)
    cth = np.cos(theta)
    locked = np.abs(cth) < tol
    if np.any(locked):
        bad = np.broadcast_to(theta, np.broadcast_shapes(phi.shape, theta.shape))[
            np.broadcast_to(locked, np.broadcast_shapes(phi.shape, theta.shape))]
        raise GimbalLockError(
            f'T_Theta is singular at theta = {bad.ravel()[0]!r} rad (|cos(theta)| < {tol:g}, '
            f'{bad.size} element(s)): use quaternions (tquat) near pitch +-90 deg')
    cphi, sphi = np.cos(phi), np.sin(phi)
    tth = np.sin(theta) / cth
    one, zero = np.ones_like(cphi * cth), np.zeros_like(cphi * cth)
    return stack_matrix([one, sphi * tth, cphi * tth,
                         zero, cphi, -sphi,
                         zero, sphi / cth, cphi / cth], 3, 3)


def eulerang(phi: ArrayLike, theta: ArrayLike, psi: ArrayLike,
             tol: float = GIMBAL_LOCK_TOL) -> FloatArray:
    """
    Return J_Theta(eta) = diag(R_b^n(Theta), T_Theta(Theta)), eta_dot = J_Theta nu (Sec. 2.2.1).

    eta = [x, y, z, phi, theta, psi] (m, rad) in NED, nu = [u, v, w, p, q, r] (m/s, rad/s)
    in BODY. Raises :class:`GimbalLockError` like :func:`tzyx`. Shape (..., 6, 6).
    """
    r = rzyx(phi, theta, psi)
    t = tzyx(phi, theta, tol)
    shape = np.broadcast_shapes(r.shape[:-2], t.shape[:-2])
    j = np.zeros(shape + (6, 6))
    j[..., :3, :3] = r
    j[..., 3:, 3:] = t
    return j


def rotation_axis_angle(axis: ArrayLike, beta: ArrayLike) -> FloatArray:
    """
    Return Euler's rotation R_lambda,beta = I + sin(b) S(l) + (1 - cos(b)) S(l)^2 (Sec. 2.2).

    A rotation by ``beta`` rad about the unit vector lambda = axis/|axis| (right hand).
    1 - cos(beta) is evaluated as 2 sin^2(beta/2) for accuracy at small angles. ``axis``
    (..., 3) broadcasts against ``beta`` (...). A zero axis raises ValueError (the rotation is
    undefined); NaN gives NaN.
    """
    ax = _as_vec3(axis, 'axis')
    scale = np.max(np.abs(ax), axis=-1, keepdims=True)
    if np.any(scale == 0.0):
        raise ValueError('rotation_axis_angle: an axis is the zero vector')
    with np.errstate(invalid='ignore'):
        unit = ax / scale
        lam = unit / np.linalg.norm(unit, axis=-1, keepdims=True)
    beta = np.asarray(beta, dtype=float)[..., None, None]
    s_lam = skew(lam)
    return np.eye(3) + np.sin(beta) * s_lam + 2.0 * np.sin(0.5 * beta) ** 2 * (s_lam @ s_lam)


def euler_from_rows(r12: ArrayLike, r13: ArrayLike, r22: ArrayLike, r23: ArrayLike,
                    r31: ArrayLike, r32: ArrayLike, r33: ArrayLike,
                    lock_tol: float = EULER_LOCK_TOL
                    ) -> tuple[Any, Any, Any]:
    """
    Return (phi, theta, psi) (rad, arrays) from the seven elements of R_b^n they need.

    The one body of the zyx Euler extraction (Fossen Section 2.2.1), shared by
    :func:`rot2euler` and :func:`vessel_kinematics.core.quaternion.q2euler`: phi = atan2(R32, R33),
    theta = atan2(-R31, sqrt(R32^2 + R33^2)), psi = atan2(sin(phi) R13 - cos(phi) R12,
    cos(phi) R22 - sin(phi) R23); at gimbal lock (cos(theta) < ``lock_tol``) phi = 0 and psi =
    atan2(-R12, R22). Elements broadcast; scalars give a tuple of floats, arrays a tuple of
    float64 arrays (the rule of :mod:`vessel_kinematics.core.dispatch`).
    """
    one = one_point(r12, r13, r22, r23, r31, r32, r33)
    r12, r13, r22, r23, r31, r32, r33 = (np.asarray(e, dtype=float)
                                         for e in (r12, r13, r22, r23, r31, r32, r33))
    cth = np.hypot(r32, r33)
    locked = cth < lock_tol
    phi = np.where(locked, 0.0, np.arctan2(r32, r33))
    cphi, sphi = np.cos(phi), np.sin(phi)
    theta = np.arctan2(-r31, cth)
    psi = np.arctan2(sphi * r13 - cphi * r12, cphi * r22 - sphi * r23)
    return to_output((phi, theta, psi), one)


def rot2euler(r: ArrayLike, lock_tol: float = EULER_LOCK_TOL) -> tuple[Any, Any, Any]:
    """
    Return the zyx Euler angles (phi, theta, psi) in rad of R_b^n (Fossen Section 2.2.1).

    The atan2 form: phi = atan2(R32, R33) in (-pi, pi], theta = atan2(-R31, sqrt(R32^2 +
    R33^2)) in [-pi/2, pi/2] (accurate at +-90 deg, unlike asin), and psi from the rows left
    after removing R_x,phi, psi = atan2(sin(phi) R13 - cos(phi) R12, cos(phi) R22 -
    sin(phi) R23), so rzyx(phi, theta, psi) reproduces R even close to the singularity.

    Gimbal lock (cos(theta) < ``lock_tol``): only psi -+ phi is defined there; the answer is
    phi = 0, theta = +-pi/2 and psi = atan2(-R12, R22) (all of it in yaw). Returns a tuple of
    floats for one (3, 3) matrix, of arrays (...) for a stack (..., 3, 3). NaN gives NaN.
    """
    m = _as_mat3(r, 'R')
    return euler_from_rows(m[..., 0, 1], m[..., 0, 2], m[..., 1, 1], m[..., 1, 2],
                           m[..., 2, 0], m[..., 2, 1], m[..., 2, 2], lock_tol)


def rotation_rate(r: ArrayLike, omega: ArrayLike) -> FloatArray:
    """
    Return R_dot = R S(omega) (Fossen Sec. 2.2), omega the BODY angular rate in rad/s.

    ``r`` (..., 3, 3) and ``omega`` (..., 3) broadcast; the result has shape (..., 3, 3).
    """
    return _as_mat3(r, 'R') @ skew(omega)

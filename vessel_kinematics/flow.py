"""
Course, heading, speed, sideslip, angle of attack and the FLOW axes (Fossen 2.4).

Fossen, *Handbook of Marine Craft Hydrodynamics and Motion Control*, 2nd ed., Section 2.4.
Angles in rad, wrapped to (-pi, pi]; velocities in m/s. BODY is x forward, y starboard, z down;
NED is the world frame. The attitude is either a rotation matrix R_b^n (..., 3, 3) or a unit
quaternion q = [eta, eps1, eps2, eps3] (..., 4), scalar first, rotating BODY to NED.

Sign conventions (the seed's, i.e. Fossen's book):

* sideslip beta = asin(v / U), so for horizontal motion ahead (phi = theta = 0, w = 0,
  u >= 0, no current) the course is chi = psi + beta (astern, chi = psi + pi - beta). SNAME
  (1950) and much of the aircraft literature define the drift angle with the opposite sign,
  beta_SNAME = -beta: a vessel heading 10 deg and moving along course 0 deg (crabbing to
  port) has beta = -10 deg here, +10 deg in SNAME's sign.
* angle of attack alpha = atan2(w, u).
* With U = sqrt(u^2 + v^2 + w^2): u = U cos(alpha) cos(beta), v = U sin(beta),
  w = U sin(alpha) cos(beta) (Fossen Section 2.4).

At rest the angles are defined, never NaN: for U = 0, beta = 0 and alpha = 0; the course at
zero horizontal ground speed is the heading (``course(v, heading=psi)`` returns psi, default 0),
which keeps chi = psi + beta. NaN in gives NaN out.

Scalar inputs (floats, tuples of floats) take pure-Python :mod:`math` paths and return floats;
numpy arrays broadcast over leading axes.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np

_PI = math.pi
_TWO_PI = 2.0 * math.pi
_SCALAR_TYPES = (float, int)


def _is_scalar(*values: Any) -> bool:
    """Return True when every value is a Python/numpy scalar number (the math path)."""
    for value in values:
        if not isinstance(value, _SCALAR_TYPES):
            return False
    return True


def _is_vector(value: Any, size: int) -> bool:
    """Return True for a tuple/list of ``size`` scalar numbers (the math path)."""
    return (isinstance(value, (tuple, list)) and len(value) == size
            and _is_scalar(*value))


def ssa(angle: Any) -> Any:
    """
    Return the smallest signed angle (rad) equivalent to ``angle``, in (-pi, pi].

    Fossen's MSS ``ssa`` (mod(angle + pi, 2 pi) - pi) but with the interval closed
    at +pi, and exact: angles already in (-pi, pi] are returned unchanged (no rounding through
    angle + pi), the reduction uses the exact IEEE remainder/fmod. +-inf gives NaN.
    """
    if isinstance(angle, _SCALAR_TYPES):
        if -_PI < angle <= _PI or angle != angle:
            return float(angle)
        if math.isinf(angle):
            return math.nan
        wrapped = math.remainder(angle, _TWO_PI)
        return _PI if wrapped <= -_PI else wrapped
    angle = np.asarray(angle, dtype=float)
    with np.errstate(invalid='ignore'):
        wrapped = np.fmod(angle, _TWO_PI)
        wrapped = np.where(wrapped > _PI, wrapped - _TWO_PI, wrapped)
        return np.where(wrapped <= -_PI, wrapped + _TWO_PI, wrapped)


def _atan2_wrapped(y: Any, x: Any) -> Any:
    """Return atan2(y, x) in (-pi, pi] (atan2(-0, x<0) = -pi mapped to +pi)."""
    if _is_scalar(y, x):
        angle = math.atan2(y, x)
        return _PI if angle == -_PI else angle
    angle = np.arctan2(y, x)
    return np.where(angle == -_PI, _PI, angle)


def speed(velocity: Any) -> Any:
    """Return the speed U = |v| (m/s) of velocities (..., 3) (BODY or NED; any frame)."""
    if _is_vector(velocity, 3):
        return math.sqrt(velocity[0] ** 2 + velocity[1] ** 2 + velocity[2] ** 2)
    velocity = np.asarray(velocity, dtype=float)
    return np.sqrt(np.einsum('...i,...i->...', velocity, velocity))


def course(v_ned: Any, heading: Any = 0.0) -> Any:
    """
    Return the course over ground chi = atan2(v_E, v_N) (rad) of NED velocities (..., 2 or 3).

    Fossen Section 2.4. Where the horizontal ground speed is zero the course is undefined and
    ``heading`` (psi, rad, default 0) is returned instead, wrapped to (-pi, pi], consistent
    with chi = psi + beta and beta = 0 at rest.
    """
    if _is_scalar(heading) and isinstance(v_ned, (tuple, list)) and _is_scalar(*v_ned[:2]):
        v_n, v_e = v_ned[0], v_ned[1]
        if v_n == 0.0 and v_e == 0.0:
            return ssa(heading)
        return _atan2_wrapped(v_e, v_n)
    v_ned = np.asarray(v_ned, dtype=float)
    v_n = v_ned[..., 0]
    v_e = v_ned[..., 1]
    rest = (v_n == 0.0) & (v_e == 0.0)
    return np.where(rest, ssa(np.asarray(heading, dtype=float)), _atan2_wrapped(v_e, v_n))


def sideslip(v_body: Any) -> Any:
    """
    Return the drift angle beta = asin(v / U) (rad) of BODY velocities (..., 3).

    Fossen Section 2.4 with the seed's sign (chi = psi + beta; SNAME's beta is -beta). Computed
    as atan2(v, sqrt(u^2 + w^2)), equal to asin(v / U) but well conditioned near +-pi/2 and
    free of |v / U| > 1 round-off. beta = 0 at U = 0.
    """
    if _is_vector(v_body, 3):
        u, v, w = v_body
        return math.atan2(v, math.sqrt(u * u + w * w))
    v_body = np.asarray(v_body, dtype=float)
    u = v_body[..., 0]
    w = v_body[..., 2]
    return np.arctan2(v_body[..., 1], np.sqrt(u * u + w * w))


def angle_of_attack(v_body: Any) -> Any:
    """
    Return the angle of attack alpha = atan2(w, u) (rad) of BODY velocities (..., 3).

    Fossen Section 2.4; in (-pi, pi] (near +-pi when moving astern). alpha = 0 when u = w = 0
    (including u = -0.0, which atan2 alone would send to pi).
    """
    if _is_vector(v_body, 3):
        u, w = v_body[0], v_body[2]
        if u == 0.0 and w == 0.0:
            return 0.0
        return _atan2_wrapped(w, u)
    v_body = np.asarray(v_body, dtype=float)
    u = v_body[..., 0]
    w = v_body[..., 2]
    return np.where((u == 0.0) & (w == 0.0), 0.0, _atan2_wrapped(w, u))


def _rotation_matrix(attitude: Any) -> np.ndarray:
    """Return R_b^n (..., 3, 3) from a rotation matrix or a (not necessarily unit) quaternion."""
    attitude = np.asarray(attitude, dtype=float)
    if attitude.shape[-2:] == (3, 3):
        return attitude
    if attitude.shape[-1] != 4:
        raise ValueError(f'attitude must be a (..., 3, 3) rotation matrix or a (..., 4) '
                         f'quaternion [eta, eps1, eps2, eps3], got shape {attitude.shape}')
    q = attitude / np.linalg.norm(attitude, axis=-1, keepdims=True)
    eta, e1, e2, e3 = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    rot = np.empty(q.shape[:-1] + (3, 3))
    rot[..., 0, 0] = 1.0 - 2.0 * (e2 * e2 + e3 * e3)
    rot[..., 0, 1] = 2.0 * (e1 * e2 - e3 * eta)
    rot[..., 0, 2] = 2.0 * (e1 * e3 + e2 * eta)
    rot[..., 1, 0] = 2.0 * (e1 * e2 + e3 * eta)
    rot[..., 1, 1] = 1.0 - 2.0 * (e1 * e1 + e3 * e3)
    rot[..., 1, 2] = 2.0 * (e2 * e3 - e1 * eta)
    rot[..., 2, 0] = 2.0 * (e1 * e3 - e2 * eta)
    rot[..., 2, 1] = 2.0 * (e2 * e3 + e1 * eta)
    rot[..., 2, 2] = 1.0 - 2.0 * (e1 * e1 + e2 * e2)
    return rot


def heading(attitude: Any) -> Any:
    """
    Return the yaw angle psi (rad) of an attitude: R_b^n (..., 3, 3) or q (..., 4).

    psi = atan2(R[1, 0], R[0, 0]) (the zyx Euler yaw, Fossen Section 2.2.1); for a quaternion
    psi = atan2(2 (eps1 eps2 + eta eps3), eta^2 + eps1^2 - eps2^2 - eps3^2), which needs no
    normalisation. At theta = +-90 deg exactly (R[0, 0] = R[1, 0] = 0) the zyx yaw is not
    unique; the value for phi = 0 is returned, psi = atan2(-R[0, 1], R[1, 1]).
    """
    if _is_vector(attitude, 4):
        eta, e1, e2, e3 = attitude
        r10 = 2.0 * (e1 * e2 + eta * e3)
        r00 = eta * eta + e1 * e1 - e2 * e2 - e3 * e3
        if r10 == 0.0 and r00 == 0.0:
            r10 = -2.0 * (e1 * e2 - eta * e3)
            r00 = eta * eta - e1 * e1 + e2 * e2 - e3 * e3
        return _atan2_wrapped(r10, r00)
    attitude = np.asarray(attitude, dtype=float)
    if attitude.shape[-2:] == (3, 3):
        r10, r00 = attitude[..., 1, 0], attitude[..., 0, 0]
        alt10, alt00 = -attitude[..., 0, 1], attitude[..., 1, 1]
    elif attitude.shape[-1] == 4:
        eta, e1, e2, e3 = (attitude[..., i] for i in range(4))
        r10 = 2.0 * (e1 * e2 + eta * e3)
        r00 = eta * eta + e1 * e1 - e2 * e2 - e3 * e3
        alt10 = -2.0 * (e1 * e2 - eta * e3)
        alt00 = eta * eta - e1 * e1 + e2 * e2 - e3 * e3
    else:
        raise ValueError(f'attitude must be a (..., 3, 3) rotation matrix or a (..., 4) '
                         f'quaternion [eta, eps1, eps2, eps3], got shape {attitude.shape}')
    locked = (r10 == 0.0) & (r00 == 0.0)
    return _atan2_wrapped(np.where(locked, alt10, r10), np.where(locked, alt00, r00))


def current_ned(speed_c: Any, direction: Any) -> Any:
    """
    Return the NED velocity (..., 3) (m/s) of a horizontal current of speed V_c and direction.

    v_c^n = [V_c cos(beta_c), V_c sin(beta_c), 0] with beta_c the direction the current flows
    towards (rad, from north, clockwise), as in Fossen's ocean-current model.
    """
    if _is_scalar(speed_c, direction):
        return (speed_c * math.cos(direction), speed_c * math.sin(direction), 0.0)
    speed_c, direction = np.broadcast_arrays(np.asarray(speed_c, dtype=float),
                                             np.asarray(direction, dtype=float))
    return np.stack((speed_c * np.cos(direction), speed_c * np.sin(direction),
                     np.zeros_like(speed_c)), axis=-1)


def relative_velocity(v_body: Any, attitude: Any, v_current_ned: Any) -> np.ndarray:
    """
    Return the BODY velocity relative to the water nu_r = nu - R^T v_c (..., 3) (m/s).

    ``v_body`` = [u, v, w] over ground (BODY, m/s), ``attitude`` R_b^n (..., 3, 3) or
    q (..., 4), ``v_current_ned`` the current velocity in NED (m/s) (Fossen Section 2.4, with
    the current's BODY velocity v_c^b = (R_b^n)^T v_c^n).
    """
    rot = _rotation_matrix(attitude)
    v_c = np.asarray(v_current_ned, dtype=float)
    return np.asarray(v_body, dtype=float) - np.einsum('...ji,...j->...i', rot, v_c)


class RelativeFlow(NamedTuple):
    """Velocities and angles relative to the water (m/s, rad); fields broadcast alike."""

    u_r: Any
    v_r: Any
    w_r: Any
    U_r: Any  # noqa: N815 (Fossen's symbol)
    alpha_r: Any
    beta_r: Any


def relative_flow(v_body: Any, attitude: Any, v_current_ned: Any) -> RelativeFlow:
    """
    Return (u_r, v_r, w_r, U_r, alpha_r, beta_r) relative to an ocean current.

    nu_r = nu - (R_b^n)^T v_c^n (:func:`relative_velocity`), U_r = |nu_r|,
    alpha_r = atan2(w_r, u_r), beta_r = asin(v_r / U_r), with the conventions of
    :func:`angle_of_attack` and :func:`sideslip` (0 at U_r = 0).
    """
    nu_r = relative_velocity(v_body, attitude, v_current_ned)
    return RelativeFlow(nu_r[..., 0], nu_r[..., 1], nu_r[..., 2], speed(nu_r),
                        angle_of_attack(nu_r), sideslip(nu_r))


def rotation_flow2body(alpha: Any, beta: Any) -> np.ndarray:
    """
    Return R_flow^b(alpha, beta) (..., 3, 3), the rotation from FLOW to BODY axes.

    R_flow^b = R_y(alpha)^T R_z(beta) (Fossen eqs. 2.118-2.121 with the seed's sign of beta;
    Fossen writes R_z(-beta) with SNAME's beta), so nu = R_flow^b [U, 0, 0]^T: the FLOW x
    axis points along the velocity (relative to the water when alpha_r, beta_r are used).
    """
    alpha, beta = np.broadcast_arrays(np.asarray(alpha, dtype=float),
                                      np.asarray(beta, dtype=float))
    ca, sa = np.cos(alpha), np.sin(alpha)
    cb, sb = np.cos(beta), np.sin(beta)
    rot = np.empty(alpha.shape + (3, 3))
    rot[..., 0, 0] = ca * cb
    rot[..., 0, 1] = -ca * sb
    rot[..., 0, 2] = -sa
    rot[..., 1, 0] = sb
    rot[..., 1, 1] = cb
    rot[..., 1, 2] = 0.0
    rot[..., 2, 0] = sa * cb
    rot[..., 2, 1] = -sa * sb
    rot[..., 2, 2] = ca
    return rot


def flow_transform(alpha: Any, beta: Any) -> np.ndarray:
    """
    Return the 6-DOF FLOW transform T_U(alpha, beta) (..., 6, 6): BODY to FLOW axes.

    T_U = diag(R_b^flow, R_b^flow) with R_b^flow = (R_flow^b)^T (:func:`rotation_flow2body`):
    it maps a BODY generalised velocity or force [linear; angular] to FLOW axes, so that
    M_flow = T_U M T_U^-1 = T_U M T_U^T is a BODY-axes matrix M expressed in FLOW axes
    (:func:`flow_matrix`). T_U is orthogonal, T_U^-1 = T_U^T.
    """
    r_bf = np.swapaxes(rotation_flow2body(alpha, beta), -1, -2)
    t_u = np.zeros(r_bf.shape[:-2] + (6, 6))
    t_u[..., :3, :3] = r_bf
    t_u[..., 3:, 3:] = r_bf
    return t_u


def flow_matrix(matrix: Any, alpha: Any, beta: Any) -> np.ndarray:
    """
    Return M_flow = T_U M T_U^-1 for a BODY-axes matrix M (..., 6, 6) or (..., 3, 3).

    E.g. the mass matrix or the damping matrix in FLOW axes, where lift and drag are defined.
    A 3x3 matrix uses the 3x3 block R_b^flow of :func:`flow_transform`.
    """
    matrix = np.asarray(matrix, dtype=float)
    if matrix.shape[-2:] == (3, 3):
        t = np.swapaxes(rotation_flow2body(alpha, beta), -1, -2)
    elif matrix.shape[-2:] == (6, 6):
        t = flow_transform(alpha, beta)
    else:
        raise ValueError(f'matrix must be (..., 3, 3) or (..., 6, 6), got {matrix.shape}')
    return t @ matrix @ np.swapaxes(t, -1, -2)

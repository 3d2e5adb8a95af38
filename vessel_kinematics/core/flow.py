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

Return types follow :mod:`vessel_kinematics.core.dispatch`: a one-point call (scalars, one vector
as a tuple/list or a (3,) array) returns Python floats (tuples of floats for velocities), a
batch float64 arrays. :func:`ssa`, :func:`course`, :func:`sideslip` and
:func:`angle_of_attack` keep a pure-Python body for the estimator's per-message calls; the
others have one numpy body. :func:`ssa` is defined with the other conventions in
:mod:`vessel_kinematics.core.frames` and re-exported here.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np

from vessel_kinematics.core.dispatch import (FloatArray, is_point, one_point, stack_matrix,
                                             to_output)
from vessel_kinematics.core.frames import ssa, yaw_from_q
from vessel_kinematics.core.quaternion import rquat9

__all__ = ['RelativeFlow', 'angle_of_attack', 'course', 'current_ned', 'flow_matrix',
           'flow_transform', 'heading', 'relative_flow', 'relative_velocity',
           'rotation_flow2body', 'sideslip', 'speed', 'ssa']

_PI = math.pi


def _atan2_wrapped(y: Any, x: Any) -> Any:
    """Return atan2(y, x) in (-pi, pi] (atan2(-0, x<0) = -pi mapped to +pi)."""
    if one_point(y, x):
        angle = math.atan2(float(y), float(x))
        return _PI if angle == -_PI else angle
    angle = np.arctan2(y, x)
    return np.where(angle == -_PI, _PI, angle)


def speed(velocity: Any) -> Any:
    """Return the speed U = |v| (m/s) of velocities (..., 3) (BODY or NED; any frame)."""
    v = np.asarray(velocity, dtype=float)
    return to_output(np.sqrt(np.einsum('...i,...i->...', v, v)), v.ndim == 1)


def course(v_ned: Any, heading: Any = 0.0) -> Any:
    """
    Return the course over ground chi = atan2(v_E, v_N) (rad) of NED velocities (..., 2 or 3).

    Fossen Section 2.4. Where the horizontal ground speed is zero the course is undefined and
    ``heading`` (psi, rad, default 0) is returned instead, wrapped to (-pi, pi], consistent
    with chi = psi + beta and beta = 0 at rest.
    """
    if one_point(heading) and (is_point(v_ned, 3) or is_point(v_ned, 2)):
        v_n, v_e = float(v_ned[0]), float(v_ned[1])
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
    if is_point(v_body, 3):
        u, v, w = (float(c) for c in v_body)
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
    if is_point(v_body, 3):
        u, w = float(v_body[0]), float(v_body[2])
        if u == 0.0 and w == 0.0:
            return 0.0
        return _atan2_wrapped(w, u)
    v_body = np.asarray(v_body, dtype=float)
    u = v_body[..., 0]
    w = v_body[..., 2]
    return np.where((u == 0.0) & (w == 0.0), 0.0, _atan2_wrapped(w, u))


def _rotation_matrix(attitude: Any) -> FloatArray:
    """Return R_b^n (..., 3, 3) from a rotation matrix or a (not necessarily unit) quaternion."""
    att = np.asarray(attitude, dtype=float)
    if att.shape[-2:] == (3, 3):
        return att
    if att.shape[-1:] != (4,):
        raise ValueError(f'attitude must be a (..., 3, 3) rotation matrix or a (..., 4) '
                         f'quaternion [eta, eps1, eps2, eps3], got shape {att.shape}')
    q = att / np.linalg.norm(att, axis=-1, keepdims=True)
    return stack_matrix(list(rquat9(q[..., 0], q[..., 1], q[..., 2], q[..., 3])), 3, 3)


def heading(attitude: Any) -> Any:
    """
    Return the yaw angle psi (rad) of an attitude: R_b^n (..., 3, 3) or q (..., 4).

    psi = atan2(R[1, 0], R[0, 0]) (the zyx Euler yaw, Fossen Section 2.2.1); for a quaternion
    psi = atan2(2 (eps1 eps2 + eta eps3), eta^2 + eps1^2 - eps2^2 - eps3^2), which needs no
    normalisation. At theta = +-90 deg exactly (R[0, 0] = R[1, 0] = 0) the zyx yaw is not
    unique; the value for phi = 0 is returned, psi = atan2(-R[0, 1], R[1, 1]).
    """
    if is_point(attitude, 4) or np.shape(attitude)[-1:] == (4,):
        return yaw_from_q(attitude)
    att = np.asarray(attitude, dtype=float)
    if att.shape[-2:] != (3, 3):
        raise ValueError(f'attitude must be a (..., 3, 3) rotation matrix or a (..., 4) '
                         f'quaternion [eta, eps1, eps2, eps3], got shape {att.shape}')
    r10, r00 = att[..., 1, 0], att[..., 0, 0]
    locked = (r10 == 0.0) & (r00 == 0.0)
    psi = _atan2_wrapped(np.where(locked, -att[..., 0, 1], r10),
                         np.where(locked, att[..., 1, 1], r00))
    return to_output(psi, att.ndim == 2)


def current_ned(speed_c: Any, direction: Any) -> Any:
    """
    Return the NED velocity (..., 3) (m/s) of a horizontal current of speed V_c and direction.

    v_c^n = [V_c cos(beta_c), V_c sin(beta_c), 0] with beta_c the direction the current flows
    towards (rad, from north, clockwise), as in Fossen's ocean-current model.
    """
    v_c, beta_c = np.broadcast_arrays(np.asarray(speed_c, dtype=float),
                                      np.asarray(direction, dtype=float))
    out = np.stack((v_c * np.cos(beta_c), v_c * np.sin(beta_c), np.zeros_like(v_c)), axis=-1)
    return to_output(out, one_point(speed_c, direction))


def _relative_velocity(v_body: Any, attitude: Any, v_current_ned: Any) -> FloatArray:
    """Return nu_r = nu - R^T v_c (..., 3) as an array (the body of relative_velocity)."""
    rot = _rotation_matrix(attitude)
    v_c = np.asarray(v_current_ned, dtype=float)
    return np.asarray(v_body, dtype=float) - np.einsum('...ji,...j->...i', rot, v_c)


def _one_flow_point(v_body: Any, attitude: Any, v_current_ned: Any) -> bool:
    """Return True when the three arguments are one velocity, one attitude, one current."""
    return (is_point(v_body, 3) and is_point(v_current_ned, 3)
            and np.shape(attitude) in ((3, 3), (4,)))


def relative_velocity(v_body: Any, attitude: Any, v_current_ned: Any) -> Any:
    """
    Return the BODY velocity relative to the water nu_r = nu - R^T v_c (..., 3) (m/s).

    ``v_body`` = [u, v, w] over ground (BODY, m/s), ``attitude`` R_b^n (..., 3, 3) or
    q (..., 4), ``v_current_ned`` the current velocity in NED (m/s) (Fossen Section 2.4, with
    the current's BODY velocity v_c^b = (R_b^n)^T v_c^n).
    """
    return to_output(_relative_velocity(v_body, attitude, v_current_ned),
                     _one_flow_point(v_body, attitude, v_current_ned))


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
    nu_r = _relative_velocity(v_body, attitude, v_current_ned)
    one = _one_flow_point(v_body, attitude, v_current_ned)
    u_r, v_r, w_r = (to_output(nu_r[..., i], one) for i in range(3))
    if one:
        nu = (u_r, v_r, w_r)
        return RelativeFlow(u_r, v_r, w_r, speed(nu), angle_of_attack(nu), sideslip(nu))
    return RelativeFlow(u_r, v_r, w_r, speed(nu_r), angle_of_attack(nu_r), sideslip(nu_r))


def rotation_flow2body(alpha: Any, beta: Any) -> FloatArray:
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


def flow_transform(alpha: Any, beta: Any) -> FloatArray:
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


def flow_matrix(matrix: Any, alpha: Any, beta: Any) -> FloatArray:
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

"""Tests of vessel_kinematics.core.flow (Fossen 2.4) against scipy's Rotation and identities."""

from __future__ import annotations

import math

from hypothesis import example, given, settings
from hypothesis import strategies as st
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from vessel_kinematics.core import flow

ANGLE = st.floats(-math.pi, math.pi)
SPEED = st.floats(-20.0, 20.0)


def scipy_attitude(phi: float, theta: float, psi: float) -> tuple[np.ndarray, np.ndarray]:
    """Return R_b^n = R_z(psi) R_y(theta) R_x(phi) and q = [eta, eps] from scipy."""
    rot = Rotation.from_euler('ZYX', [psi, theta, phi])
    x, y, z, w = rot.as_quat()
    return rot.as_matrix(), np.array([w, x, y, z])


# --- ssa -------------------------------------------------------------------------------------

@given(angle=st.floats(-1e6, 1e6))
def test_ssa_range_and_equivalence(angle):
    wrapped = flow.ssa(angle)
    assert -math.pi < wrapped <= math.pi
    turns = (angle - wrapped) / (2 * math.pi)
    assert turns == pytest.approx(round(turns), abs=1e-9)
    assert flow.ssa(wrapped) == wrapped                    # idempotent
    assert flow.ssa(np.array([angle]))[0] == pytest.approx(wrapped, abs=1e-9)
    if abs(abs(wrapped) - math.pi) > 1e-6:
        # Fossen's MSS ssa: mod(angle + pi, 2 pi) - pi, away from the +-pi boundary.
        assert wrapped == pytest.approx((angle + math.pi) % (2 * math.pi) - math.pi, abs=1e-9)


def test_ssa_boundaries_and_exactness():
    assert flow.ssa(math.pi) == math.pi
    assert flow.ssa(-math.pi) == math.pi
    assert flow.ssa(3 * math.pi) == pytest.approx(math.pi)
    assert flow.ssa(-3 * math.pi) == pytest.approx(math.pi)
    assert flow.ssa(1e-300) == 1e-300                      # not lost in angle + pi
    assert flow.ssa(2 * math.pi) == 0.0
    assert flow.ssa(math.radians(350.0)) == pytest.approx(math.radians(-10.0))
    assert math.isnan(flow.ssa(math.nan)) and math.isnan(flow.ssa(math.inf))
    got = flow.ssa(np.array([math.pi, -math.pi, 1e-300, 7.0, np.nan, -np.inf]))
    assert got[:3].tolist() == [math.pi, math.pi, 1e-300]
    assert got[3] == pytest.approx(7.0 - 2 * math.pi)
    assert np.isnan(got[4:]).all()
    assert flow.ssa(np.zeros((2, 3))).shape == (2, 3)


# --- course, sideslip, angle of attack, speed ------------------------------------------------

@settings(max_examples=200)
@given(psi=ANGLE, u=SPEED, v=SPEED)
def test_course_equals_heading_plus_sideslip_for_horizontal_motion(psi, u, v):
    rot, q = scipy_attitude(0.0, 0.0, psi)
    v_body = np.array([u, v, 0.0])
    v_ned = rot @ v_body
    beta = flow.sideslip(v_body)
    chi = flow.course(v_ned, heading=psi)
    if math.hypot(u, v) > 1e-9:
        # In general chi = psi + atan2(v, u); with beta = asin(v / U) in [-pi/2, pi/2] this is
        # chi = psi + beta when going ahead (u >= 0), chi = psi + pi - beta astern.
        assert flow.ssa(chi - psi - math.atan2(v, u)) == pytest.approx(0.0, abs=1e-9)
        ahead_or_astern = beta if u >= 0.0 else math.pi - beta
        assert flow.ssa(chi - psi - ahead_or_astern) == pytest.approx(0.0, abs=1e-9)
    assert flow.heading(rot) == pytest.approx(flow.ssa(psi), abs=1e-12) or abs(psi) > 3.14
    assert flow.ssa(flow.heading(q) - psi) == pytest.approx(0.0, abs=1e-12)
    assert flow.ssa(flow.course(tuple(v_ned), psi) - chi) == pytest.approx(0.0, abs=1e-15)


def test_crab_example_heading_10_course_0():
    # A vessel heading 10 deg that moves due north (course 0) crabs to port: beta = -10 deg in
    # the seed's convention (chi = psi + beta); SNAME's drift angle would be +10 deg.
    psi = math.radians(10.0)
    rot, q = scipy_attitude(0.0, 0.0, psi)
    v_ned = np.array([2.0, 0.0, 0.0])
    v_body = rot.T @ v_ned
    assert math.degrees(flow.sideslip(v_body)) == pytest.approx(-10.0, abs=1e-12)
    assert math.degrees(flow.sideslip(tuple(v_body))) == pytest.approx(-10.0, abs=1e-12)
    assert flow.course(v_ned) == 0.0
    assert math.degrees(flow.heading(q)) == pytest.approx(10.0, abs=1e-12)
    rel = flow.relative_flow(v_body, q, np.zeros(3))
    assert math.degrees(rel.beta_r) == pytest.approx(-10.0, abs=1e-12)
    assert rel.U_r == pytest.approx(2.0, abs=1e-15)


def test_at_rest_the_angles_are_defined():
    for zero in (0.0, -0.0):
        at_rest = (zero, zero, zero)
        assert flow.sideslip(at_rest) == 0.0
        assert flow.angle_of_attack(at_rest) == 0.0
        assert flow.speed(at_rest) == 0.0
        assert flow.course(at_rest, heading=0.7) == 0.7
        assert flow.course(at_rest) == 0.0
        arr = np.array([at_rest, [1.0, 0.0, 0.0]])
        assert flow.sideslip(arr).tolist() == [0.0, 0.0]
        assert flow.angle_of_attack(arr).tolist() == [0.0, 0.0]
        assert flow.course(arr, heading=0.7).tolist() == [0.7, 0.0]
    # The heading given for the rest case is wrapped like every angle.
    assert flow.course((0.0, 0.0, 1.0), heading=3 * math.pi) == pytest.approx(math.pi)
    # Vertical motion only: no horizontal course, the heading is returned.
    assert flow.course(np.array([[0.0, 0.0, 3.0]]), heading=np.array([0.2]))[0] == 0.2


@settings(max_examples=200)
@given(speed=st.floats(0.01, 30.0), alpha=ANGLE, beta=st.floats(-1.5707, 1.5707))
def test_alpha_beta_recover_the_flow_decomposition(speed, alpha, beta):
    # u = U cos(alpha) cos(beta), v = U sin(beta), w = U sin(alpha) cos(beta).
    v_body = speed * np.array([math.cos(alpha) * math.cos(beta), math.sin(beta),
                               math.sin(alpha) * math.cos(beta)])
    assert flow.speed(v_body) == pytest.approx(speed, rel=1e-14)
    assert flow.sideslip(v_body) == pytest.approx(beta, abs=1e-9)
    assert flow.sideslip(tuple(v_body)) == pytest.approx(math.asin(v_body[1] / speed), abs=1e-9)
    assert flow.ssa(flow.angle_of_attack(v_body) - alpha) == pytest.approx(0.0, abs=1e-8)
    assert flow.angle_of_attack(tuple(v_body)) == pytest.approx(
        flow.angle_of_attack(v_body), abs=1e-15)
    # The FLOW rotation maps [U, 0, 0] to the BODY velocity.
    assert np.allclose(flow.rotation_flow2body(alpha, beta) @ [speed, 0.0, 0.0], v_body,
                       atol=1e-12)


def test_sideslip_never_exceeds_half_pi_and_angle_of_attack_wraps():
    # Pure sway: asin(v/U) with v/U = 1 +- round-off would be NaN; the atan2 form is exact.
    assert flow.sideslip((0.0, 3.0, 0.0)) == math.pi / 2
    assert flow.sideslip(np.array([0.0, -3.0, 0.0])) == -math.pi / 2
    assert flow.angle_of_attack((-1.0, 0.0, -0.0)) == math.pi    # astern: +pi, not -pi
    assert flow.angle_of_attack(np.array([-1.0, 0.0, -0.0])) == math.pi


def test_nan_in_nan_out():
    nan = math.nan
    assert math.isnan(flow.sideslip((1.0, nan, 0.0)))
    assert math.isnan(flow.angle_of_attack((nan, 0.0, 0.0)))
    assert math.isnan(flow.course((nan, 1.0, 0.0)))
    assert math.isnan(flow.speed((nan, 1.0, 0.0)))
    assert math.isnan(flow.heading((nan, 0.0, 0.0, 0.0)))
    assert np.isnan(flow.course(np.array([[nan, 0.0, 0.0]]), heading=0.3)).all()
    assert np.isnan(flow.sideslip(np.array([[0.0, nan, 0.0]]))).all()
    rel = flow.relative_flow(np.array([1.0, 0.0, 0.0]), np.eye(3), np.array([nan, 0.0, 0.0]))
    assert all(np.isnan(value) for value in (rel.u_r, rel.U_r, rel.alpha_r, rel.beta_r))
    assert np.isnan(flow.rotation_flow2body(nan, 0.0)).any()


# --- heading from attitude -------------------------------------------------------------------

@settings(max_examples=100)
@given(phi=ANGLE, theta=st.floats(-1.5, 1.5), psi=ANGLE)
def test_heading_against_scipy(phi, theta, psi):
    rot, q = scipy_attitude(phi, theta, psi)
    yaw = Rotation.from_matrix(rot).as_euler('ZYX')[0]
    for attitude in (rot, q, -q, 3.0 * q, tuple(q)):
        assert flow.ssa(flow.heading(attitude) - yaw) == pytest.approx(0.0, abs=1e-9)
    batch = flow.heading(np.stack([q, q]))
    assert batch.shape == (2,)
    assert flow.heading(np.stack([rot] * 3)).shape == (3,)


def test_heading_at_gimbal_lock():
    # theta = +90 deg exactly: R = R_z(psi) R_y(90 deg) R_x(phi) depends on psi - phi only;
    # the heading returned is the phi = 0 solution, psi - phi.
    psi, phi = 0.9, 0.3
    s, c = math.sin(psi - phi), math.cos(psi - phi)
    rot = np.array([[0.0, -s, c], [0.0, c, s], [-1.0, 0.0, 0.0]])
    assert np.allclose(rot, scipy_attitude(phi, math.pi / 2, psi)[0], atol=1e-15)
    assert flow.heading(rot) == pytest.approx(psi - phi, abs=1e-15)
    with pytest.raises(ValueError, match='attitude'):
        flow.heading(np.zeros(5))


# --- ocean current ---------------------------------------------------------------------------

@settings(max_examples=100)
@given(phi=st.floats(-0.5, 0.5), theta=st.floats(-0.5, 0.5), psi=ANGLE,
       u=SPEED, v=SPEED, w=SPEED, v_c=st.floats(0.0, 3.0), beta_c=ANGLE)
@example(phi=0.0, theta=0.0, psi=1.0, u=1.0, v=0.0, w=0.0, v_c=1.0, beta_c=1.0)
@example(phi=0.0, theta=6.103515625e-05, psi=1.0, u=1.0, v=0.0, w=0.0, v_c=1.0, beta_c=1.0)
def test_relative_velocity_is_nu_minus_rt_vc(phi, theta, psi, u, v, w, v_c, beta_c):
    rot, q = scipy_attitude(phi, theta, psi)
    current = flow.current_ned(v_c, beta_c)
    assert np.allclose(current, [v_c * math.cos(beta_c), v_c * math.sin(beta_c), 0.0])
    nu = np.array([u, v, w])
    expected = nu - Rotation.from_quat(np.roll(q, -1)).inv().apply(current)
    for attitude in (rot, q):
        rel = flow.relative_flow(nu, attitude, np.asarray(current))
        got = np.array([rel.u_r, rel.v_r, rel.w_r])
        assert np.allclose(got, expected, atol=1e-12)
        assert rel.U_r == pytest.approx(np.linalg.norm(expected), abs=1e-12)
        # The angles give the relative velocity back along FLOW x, however slow it is.
        assert np.allclose(flow.rotation_flow2body(rel.alpha_r, rel.beta_r)
                           @ [rel.U_r, 0.0, 0.0], got, atol=1e-12)
        if rel.U_r > 1e-3:
            # Below, drifting with the current, the direction of a rounding-sized nu_r (ours
            # or scipy's) is arbitrary: the two need not agree (hypothesis found u = v_c = 1,
            # beta_c = psi, where ours is exactly 0 and scipy's 1e-16 abeam).
            assert rel.alpha_r == pytest.approx(flow.angle_of_attack(expected), abs=1e-12) or (
                abs(abs(rel.alpha_r) - math.pi) < 1e-9)
            assert rel.beta_r == pytest.approx(flow.sideslip(expected), abs=1e-12)
    # The NED velocity relative to the water is the ground velocity minus the current.
    assert np.allclose(rot @ flow.relative_velocity(nu, q, current), rot @ nu - current,
                       atol=1e-12)


def test_relative_flow_drifting_with_the_current_is_at_rest():
    current = np.asarray(flow.current_ned(1.5, -0.4))
    rel = flow.relative_flow(current, np.array([1.0, 0.0, 0.0, 0.0]), current)
    assert (rel.U_r, rel.alpha_r, rel.beta_r) == (0.0, 0.0, 0.0)
    rot, q = scipy_attitude(0.1, -0.2, 2.0)
    nu = rot.T @ current          # moving with the water, up to round-off
    batch = flow.relative_flow(np.stack([nu] * 4), np.stack([q] * 4), current)
    assert batch.U_r.shape == (4,) and np.all(batch.U_r < 1e-15)
    assert np.isfinite(batch.alpha_r).all() and np.isfinite(batch.beta_r).all()


# --- FLOW axes -------------------------------------------------------------------------------

@settings(max_examples=100)
@given(alpha=ANGLE, beta=ANGLE)
def test_flow_transform_orthogonal_and_against_scipy(alpha, beta):
    r_fb = flow.rotation_flow2body(alpha, beta)
    expected = (Rotation.from_rotvec([0.0, -alpha, 0.0])
                * Rotation.from_rotvec([0.0, 0.0, beta])).as_matrix()    # R_y(a)^T R_z(b)
    assert np.allclose(r_fb, expected, atol=1e-15)
    t_u = flow.flow_transform(alpha, beta)
    assert t_u.shape == (6, 6)
    assert np.allclose(t_u @ t_u.T, np.eye(6), atol=1e-15)
    assert np.linalg.det(t_u) == pytest.approx(1.0, abs=1e-14)
    assert np.allclose(t_u[:3, :3], r_fb.T) and np.allclose(t_u[3:, 3:], r_fb.T)
    assert not t_u[:3, 3:].any() and not t_u[3:, :3].any()


@settings(max_examples=50)
@given(alpha=ANGLE, beta=ANGLE, seed=st.integers(0, 2**32 - 1))
def test_flow_matrix_is_the_body_matrix_in_flow_axes(alpha, beta, seed):
    rng = np.random.default_rng(seed)
    m = rng.normal(size=(6, 6))
    m = m @ m.T + 6 * np.eye(6)               # a mass-like SPD matrix
    nu_dot = rng.normal(size=6)
    t_u = flow.flow_transform(alpha, beta)
    m_flow = flow.flow_matrix(m, alpha, beta)
    assert np.allclose(m_flow, t_u @ m @ np.linalg.inv(t_u), atol=1e-12)
    # tau = M nu_dot in BODY axes <=> tau_flow = M_flow nu_dot_flow in FLOW axes.
    assert np.allclose(m_flow @ (t_u @ nu_dot), t_u @ (m @ nu_dot), atol=1e-12)
    assert np.allclose(np.linalg.eigvalsh(m_flow), np.linalg.eigvalsh(m), atol=1e-10)
    assert np.allclose(flow.flow_matrix(m[:3, :3], alpha, beta), m_flow[:3, :3], atol=1e-12)


def test_flow_transform_identity_and_batches():
    assert np.allclose(flow.flow_transform(0.0, 0.0), np.eye(6))
    assert flow.flow_transform(np.zeros(4), np.zeros((2, 1))).shape == (2, 4, 6, 6)
    m = np.diag([10.0, 20.0, 30.0, 1.0, 2.0, 3.0])
    # Pure sideslip of 90 deg swaps the surge and sway entries (x_flow = y_body).
    assert np.allclose(np.diag(flow.flow_matrix(m, 0.0, math.pi / 2)),
                       [20.0, 10.0, 30.0, 2.0, 1.0, 3.0])
    with pytest.raises(ValueError, match='matrix'):
        flow.flow_matrix(np.eye(4), 0.0, 0.0)

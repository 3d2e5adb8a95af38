"""Tests of vessel_kinematics.core.quaternion against scipy's Rotation and first principles."""

from __future__ import annotations

import math

from hypothesis import given, settings
from hypothesis import strategies as st
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from vessel_kinematics.core import quaternion as qu
from vessel_kinematics.core import rotation as ro

SETTINGS = settings(deadline=None, max_examples=60)
ANGLE = st.floats(-math.pi, math.pi)
PITCH = st.floats(-math.pi / 2, math.pi / 2)
VEC = st.lists(st.floats(-10.0, 10.0), min_size=3, max_size=3).map(np.array)
RAW_QUAT = st.lists(st.floats(-1.0, 1.0), min_size=4, max_size=4).map(np.array).filter(
    lambda q: np.linalg.norm(q) > 0.1)
QUAT = RAW_QUAT.map(lambda q: q / np.linalg.norm(q))
IDENTITY = np.array([1.0, 0.0, 0.0, 0.0])


def to_scipy(q: np.ndarray) -> Rotation:
    """Return scipy's Rotation of a scalar-first q (scipy is scalar last, xyzw)."""
    return Rotation.from_quat(np.asarray(q)[..., [1, 2, 3, 0]])


def from_scipy(rot: Rotation, canonical: bool = True) -> np.ndarray:
    """Return scalar-first q of a scipy Rotation, with eta >= 0 when ``canonical``."""
    return rot.as_quat(canonical=canonical)[..., [3, 0, 1, 2]]


def same_rotation(p: np.ndarray, q: np.ndarray, atol: float) -> None:
    """Assert that p = +-q (the same rotation)."""
    sign = np.where(np.sum(p * q, axis=-1, keepdims=True) < 0.0, -1.0, 1.0)
    np.testing.assert_allclose(p, sign * q, atol=atol, rtol=0)


def angle_between(p: np.ndarray, q: np.ndarray) -> float:
    """Return the rotation angle (rad) between unit quaternions p and q."""
    d = qu.quat_multiply(qu.quat_conjugate(p), q)
    return 2.0 * math.atan2(np.linalg.norm(d[1:]), abs(d[0]))


# --- normalize and validity ----------------------------------------------------------------

@SETTINGS
@given(RAW_QUAT, st.sampled_from([1.0, 1e-300, 1e300, 5e-310]))
def test_normalize_unit_and_direction(q, scale):
    raw = q * scale
    u = qu.normalize(raw)
    # Scaling by a power of two is exact (raw may have lost bits as a denormal).
    exact = np.ldexp(raw, -math.floor(math.log2(np.abs(raw).max())))
    np.testing.assert_allclose(u, exact / np.linalg.norm(exact), atol=3e-16, rtol=0)
    assert qu.is_unit(u, 1e-15)
    ub = qu.normalize(np.stack([raw, raw]))
    np.testing.assert_allclose(ub, np.stack([u, u]), atol=3e-16, rtol=0)


def test_normalize_invalid_inputs_give_nan():
    for bad in ([0.0, 0.0, 0.0, 0.0], [math.nan, 1.0, 0.0, 0.0], [math.inf, 0.0, 0.0, 0.0],
                [math.inf, math.nan, 0.0, 0.0]):
        assert np.isnan(qu.normalize(bad)).all()
        assert not qu.is_unit(qu.normalize(bad))
    batch = qu.normalize([[0.0, 0.0, 0.0, 0.0], [2.0, 0.0, 0.0, 0.0], [math.nan, 0, 0, 0]])
    assert np.isnan(batch[0]).all() and np.isnan(batch[2]).all()
    np.testing.assert_array_equal(batch[1], IDENTITY)
    np.testing.assert_array_equal(qu.is_unit(batch), [False, True, False])
    np.testing.assert_array_equal(qu.normalize([5e-324, 0.0, 0.0, 0.0]), IDENTITY)
    np.testing.assert_array_equal(qu.normalize([1e308, 1e308, 1e308, 1e308]), [0.5] * 4)
    with pytest.raises(ValueError, match='shape'):
        qu.normalize([1.0, 0.0, 0.0])


def test_is_unit_tolerance():
    assert qu.is_unit(IDENTITY)
    assert qu.is_unit([1.0 + 1e-10, 0, 0, 0])
    assert not qu.is_unit([1.0 + 1e-8, 0, 0, 0])
    assert qu.is_unit([1.0 + 1e-8, 0, 0, 0], tol=1e-7)
    assert not qu.is_unit([math.nan, 0, 0, 0])


# --- product, conjugate, R(q), T(q), J_q ---------------------------------------------------

@SETTINGS
@given(QUAT, QUAT)
def test_quat_multiply_against_scipy(p, q):
    pq = qu.quat_multiply(p, q)
    expected = from_scipy(to_scipy(p) * to_scipy(q), canonical=False)
    same_rotation(pq, expected, 1e-15)
    np.testing.assert_allclose(qu.rquat(pq), qu.rquat(p) @ qu.rquat(q), atol=1e-14)
    np.testing.assert_allclose(qu.quat_multiply(np.stack([p, q]), q)[0], pq, atol=1e-16)
    # Hamilton product of pure quaternions: [-a.b, a x b].
    a, b = p[1:], q[1:]
    np.testing.assert_allclose(qu.quat_multiply(np.r_[0, a], np.r_[0, b]),
                               np.r_[-a @ b, np.cross(a, b)], atol=1e-15)


@SETTINGS
@given(QUAT, QUAT, QUAT)
def test_quat_multiply_associative_identity_conjugate(p, q, r):
    np.testing.assert_allclose(qu.quat_multiply(qu.quat_multiply(p, q), r),
                               qu.quat_multiply(p, qu.quat_multiply(q, r)), atol=1e-15)
    np.testing.assert_allclose(qu.quat_multiply(p, IDENTITY), p, atol=0)
    np.testing.assert_allclose(qu.quat_multiply(p, qu.quat_conjugate(p)), IDENTITY, atol=3e-16)
    np.testing.assert_array_equal(qu.quat_conjugate(p), p * [1, -1, -1, -1])


def test_quat_multiply_known_basis():
    i, j, k = np.eye(4)[1], np.eye(4)[2], np.eye(4)[3]
    np.testing.assert_array_equal(qu.quat_multiply(i, j), k)   # Hamilton: ij = k
    np.testing.assert_array_equal(qu.quat_multiply(j, i), -k)
    np.testing.assert_array_equal(qu.quat_multiply(i, i), -IDENTITY)


@SETTINGS
@given(QUAT)
def test_rquat_against_scipy_and_so3(q):
    r = qu.rquat(q)
    np.testing.assert_allclose(r, to_scipy(q).as_matrix(), atol=1e-15)
    np.testing.assert_allclose(qu.rquat(-q), r, atol=0)
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-15)
    assert np.linalg.det(r) == pytest.approx(1.0, abs=4e-15)
    eta, eps = q[0], q[1:]
    s = ro.skew(eps)
    np.testing.assert_allclose(r, np.eye(3) + 2 * eta * s + 2 * s @ s, atol=1e-15)  # eq 2.72
    np.testing.assert_allclose(qu.rquat(np.stack([q, -q])), np.stack([r, r]), atol=1e-16)


@SETTINGS
@given(QUAT, VEC)
def test_tquat_properties_and_finite_difference(q, omega):
    t = qu.tquat(q)
    assert t.shape == (4, 3)
    np.testing.assert_allclose(t.T @ t, np.eye(3) / 4, atol=1e-15)
    np.testing.assert_allclose(t.T @ q, 0.0, atol=1e-15)  # q_dot is orthogonal to q
    # d/dt [q (x) exp(omega t / 2)] at t = 0 by central differences of scipy's rotations.
    d = 1e-6
    plus = from_scipy(to_scipy(q) * Rotation.from_rotvec(omega * d), canonical=False)
    minus = from_scipy(to_scipy(q) * Rotation.from_rotvec(-omega * d), canonical=False)
    plus *= np.sign(plus @ q)
    minus *= np.sign(minus @ q)
    np.testing.assert_allclose(t @ omega, (plus - minus) / (2 * d), atol=1e-8)
    np.testing.assert_allclose(qu.quat_derivative(q, omega), t @ omega, atol=1e-15)
    np.testing.assert_allclose(qu.tquat(np.stack([q, q]))[1], t, atol=0)


@SETTINGS
@given(QUAT)
def test_quatern_blocks(q):
    j = qu.quatern(q)
    assert j.shape == (7, 6)
    np.testing.assert_array_equal(j[:3, :3], qu.rquat(q))
    np.testing.assert_array_equal(j[3:, 3:], qu.tquat(q))
    np.testing.assert_array_equal(j[:3, 3:], 0.0)
    np.testing.assert_array_equal(j[3:, :3], 0.0)
    assert qu.quatern(np.stack([q] * 5)).shape == (5, 7, 6)


@SETTINGS
@given(QUAT, VEC)
def test_quat_rotate_against_scipy(q, v):
    expected = to_scipy(q).apply(v)
    np.testing.assert_allclose(qu.quat_rotate(q, v), expected, atol=1e-13)
    np.testing.assert_allclose(qu.quat_rotate(q, v), qu.rquat(q) @ v, atol=1e-13)
    np.testing.assert_allclose(qu.quat_rotate(np.stack([q, q]), v)[0], qu.quat_rotate(q, v),
                               atol=1e-14)
    np.testing.assert_allclose(qu.quat_rotate(q, np.stack([v, 2 * v]))[1], 2 * expected,
                               atol=1e-13)


# --- conversions ---------------------------------------------------------------------------

@SETTINGS
@given(QUAT)
def test_rot2q_against_scipy(q):
    r = to_scipy(q).as_matrix()
    got = qu.rot2q(r)
    assert got[0] >= 0.0
    same_rotation(got, q, 1e-15)
    np.testing.assert_allclose(qu.rquat(got), r, atol=1e-15)
    np.testing.assert_allclose(qu.rot2q(np.stack([r, r]))[1], got, atol=1e-16)


@pytest.mark.parametrize('rotvec', [
    [0.0, 0.0, 0.0], [math.pi, 0, 0], [0, math.pi, 0], [0, 0, math.pi],
    [math.pi - 1e-9, 0, 0], [0, 0, -math.pi + 1e-12],
    list(np.array([1.0, -2.0, 3.0]) / math.sqrt(14) * math.pi),
    list(np.array([1.0, 1.0, 0.0]) / math.sqrt(2) * (math.pi - 1e-7)),
    [1e-300, 0, 0], [2.0, 0.3, -0.5]])
def test_rot2q_every_pivot_branch(rotvec):
    rot = Rotation.from_rotvec(rotvec)
    r = rot.as_matrix()
    for got in (qu.rot2q(r), qu.rot2q(r[None])[0]):
        assert got[0] >= 0.0
        assert np.linalg.norm(got) == pytest.approx(1.0, abs=2e-16)
        same_rotation(got, from_scipy(rot), 2e-15)
        np.testing.assert_allclose(qu.rquat(got), r, atol=2e-15)


def test_rot2q_nan_and_shape():
    assert np.isnan(qu.rot2q(np.full((3, 3), math.nan))).all()
    batch = qu.rot2q(np.stack([np.eye(3), np.full((3, 3), math.nan)]))
    np.testing.assert_array_equal(batch[0], IDENTITY)
    assert np.isnan(batch[1]).all()
    with pytest.raises(ValueError, match='shape'):
        qu.rot2q(np.eye(4))


def test_euler2q_known_value_from_mss():
    # Fossen's MSS toolbox: q = euler2q(10*pi/180, 20*pi/180, 30*pi/180). Digits computed
    # independently with scipy 1.17.1: Rotation.from_euler('ZYX', [30, 20, 10],
    # degrees=True).as_quat() = [x, y, z, w], reordered to [eta, eps1, eps2, eps3].
    expected = [0.9515485246437885, 0.03813457647485015, 0.189307857412, 0.2392983377447303]
    got = qu.euler2q(*np.deg2rad([10.0, 20.0, 30.0]).tolist())
    np.testing.assert_allclose(got, expected, atol=3e-16, rtol=0)


@SETTINGS
@given(st.floats(-4.0, 4.0), st.floats(-4.0, 4.0), st.floats(-4.0, 4.0))
def test_euler2q_against_scipy_and_rzyx(phi, theta, psi):
    q = qu.euler2q(phi, theta, psi)
    assert q[0] >= 0.0
    np.testing.assert_allclose(q, from_scipy(Rotation.from_euler('ZYX', [psi, theta, phi])),
                               atol=1e-15)
    np.testing.assert_allclose(qu.rquat(q), ro.rzyx(phi, theta, psi), atol=1e-15)
    # Composition of the principal rotations: q_z(psi) (x) q_y(theta) (x) q_x(phi).
    qz = np.array([math.cos(psi / 2), 0, 0, math.sin(psi / 2)])
    qy = np.array([math.cos(theta / 2), 0, math.sin(theta / 2), 0])
    qx = np.array([math.cos(phi / 2), math.sin(phi / 2), 0, 0])
    same_rotation(q, qu.quat_multiply(qz, qu.quat_multiply(qy, qx)), 1e-15)
    qb = qu.euler2q(np.array([phi, 0.0]), theta, np.array([psi, 0.0]))
    np.testing.assert_allclose(qb[0], q, atol=1e-16)
    assert qb.shape == (2, 4)


def test_euler2q_yaw_only():
    q = qu.euler2q(0.0, 0.0, 1.2)
    np.testing.assert_allclose(q, [math.cos(0.6), 0.0, 0.0, math.sin(0.6)], atol=1e-16)


@SETTINGS
@given(ANGLE, st.floats(-1.57, 1.57), ANGLE)
def test_q2euler_round_trip_and_scipy(phi, theta, psi):
    q = qu.euler2q(phi, theta, psi)
    angles = qu.q2euler(q)
    wrap = np.remainder(np.subtract(angles, (phi, theta, psi)) + math.pi, 2 * math.pi) - math.pi
    np.testing.assert_allclose(wrap, 0.0, atol=1e-11)
    sp = to_scipy(q).as_euler('ZYX')[::-1]
    wrap = np.remainder(np.subtract(angles, sp) + math.pi, 2 * math.pi) - math.pi
    np.testing.assert_allclose(wrap, 0.0, atol=1e-11)
    # q and -q are the same attitude.
    np.testing.assert_allclose(qu.q2euler(-q), angles, atol=1e-15)
    batch = qu.q2euler(np.stack([q, -q]))
    np.testing.assert_allclose([b[0] for b in batch], angles, atol=1e-15)


@pytest.mark.parametrize('sign', [1.0, -1.0])
@pytest.mark.parametrize('offset', [0.0, 1e-15, 1e-12, 1e-9])
def test_q2euler_at_gimbal_lock_no_nan(sign, offset):
    theta = sign * (math.pi / 2 - offset)
    q = qu.euler2q(0.7, theta, -0.4)
    angles = qu.q2euler(q)
    assert all(math.isfinite(a) for a in angles)
    assert angles[1] == pytest.approx(theta, abs=1e-15)
    np.testing.assert_allclose(ro.rzyx(*angles), qu.rquat(q),
                               atol=max(2e-15, 2 * ro.EULER_LOCK_TOL))
    # Same rule as rot2euler: phi = 0 at lock, psi the vertical rotation.
    np.testing.assert_allclose(angles, ro.rot2euler(qu.rquat(q)), atol=1e-12)
    if offset < 1e-11:
        assert angles[0] == 0.0
        assert angles[2] == pytest.approx(-0.4 - sign * 0.7, abs=1e-12)
    batch = qu.q2euler(np.stack([q, q]))
    np.testing.assert_allclose([b[1] for b in batch], angles, atol=1e-15)
    # A pitch quaternion slightly off the unit sphere whose asin argument would exceed 1.
    q_over = np.array([math.sqrt(0.5), 0.0, math.sqrt(0.5) * sign, 0.0]) * (1 + 4e-16)
    assert all(math.isfinite(a) for a in qu.q2euler(q_over))


def test_q2euler_nan():
    assert all(math.isnan(a) for a in qu.q2euler([math.nan, 0.0, 0.0, 0.0]))
    out = qu.q2euler(np.array([IDENTITY, [math.nan, 0, 0, 0]]))
    assert [a[0] for a in out] == [0.0, 0.0, 0.0]
    assert all(math.isnan(a[1]) for a in out)


@SETTINGS
@given(VEC.filter(lambda v: np.linalg.norm(v) > 1e-3), st.floats(-7.0, 7.0))
def test_axis_angle_and_rotation_vector_maps(axis, beta):
    q = qu.axis_angle2q(axis, beta)
    np.testing.assert_allclose(qu.rquat(q), ro.rotation_axis_angle(axis, beta), atol=1e-14)
    rv = beta * axis / np.linalg.norm(axis)
    expected = from_scipy(Rotation.from_rotvec(rv), canonical=False)
    same_rotation(qu.rotvec2q(rv), expected, 1e-15)
    same_rotation(qu.rotvec2q(rv[None])[0], expected, 1e-15)
    np.testing.assert_allclose(qu.q2rotvec(qu.rotvec2q(rv)), Rotation.from_rotvec(rv).as_rotvec(),
                               atol=1e-12)


def test_rotation_vector_maps_small_and_zero():
    np.testing.assert_array_equal(qu.rotvec2q([0.0, 0.0, 0.0]), IDENTITY)
    np.testing.assert_array_equal(qu.rotvec2q(np.zeros((2, 3))), [IDENTITY, IDENTITY])
    np.testing.assert_array_equal(qu.q2rotvec(IDENTITY), [0.0, 0.0, 0.0])
    for size in (1e-300, 1e-12, 1e-4 * (1 - 1e-12), 2e-4 * (1 + 1e-12), 1e-2):
        rv = size * np.array([0.6, -0.8, 0.0])
        expected = from_scipy(Rotation.from_rotvec(rv))
        np.testing.assert_allclose(qu.rotvec2q(rv), expected, rtol=1e-15, atol=0)
        np.testing.assert_allclose(qu.rotvec2q(rv[None])[0], expected, rtol=1e-15, atol=0)
        np.testing.assert_allclose(qu.q2rotvec(qu.rotvec2q(rv)), rv, rtol=1e-14, atol=0)
    assert np.isnan(qu.axis_angle2q([0.0, 0.0, 0.0], 1.0)).all()


# --- normalisation term and integrators ----------------------------------------------------

@SETTINGS
@given(QUAT, st.floats(0.5, 1.5), VEC)
def test_normalization_term(q, scale, omega):
    raw = scale * q
    term = qu.normalization_term(raw, 100.0)
    np.testing.assert_allclose(term, 50.0 * (1 - scale ** 2) * raw, atol=1e-12)
    assert raw @ term <= 1e-12 if scale >= 1 else raw @ term >= -1e-12  # points to |q| = 1
    np.testing.assert_allclose(qu.normalization_term(q, 100.0), 0.0, atol=1e-12)
    np.testing.assert_allclose(qu.quat_derivative(raw, omega, 100.0),
                               qu.tquat(raw) @ omega + term, atol=1e-12)


def test_normalization_term_drives_norm_to_one():
    q = 1.2 * qu.euler2q(0.1, 0.2, 0.3)
    omega = np.array([0.3, -0.2, 0.1])
    for _ in range(2000):  # forward Euler, h = 1 ms, gamma = 100 1/s
        q = q + 1e-3 * qu.quat_derivative(q, omega, 100.0)
    assert abs(np.linalg.norm(q) - 1.0) < 1e-6
    q = 1.2 * qu.euler2q(0.1, 0.2, 0.3)
    for _ in range(2000):  # without the term the norm stays off
        q = q + 1e-3 * qu.quat_derivative(q, omega)
    assert abs(np.linalg.norm(q) - 1.0) > 0.1


@SETTINGS
@given(QUAT, VEC, st.floats(1e-4, 0.1))
def test_integrate_euler_is_fossens_step(q, omega, h):
    got = qu.integrate_euler(q, omega, h)
    step = q + h * qu.tquat(q) @ omega
    np.testing.assert_allclose(got, step / np.linalg.norm(step), atol=1e-15)
    np.testing.assert_allclose(qu.integrate_euler(q[None], omega[None], h)[0], got, atol=1e-15)
    # Euler + normalise turns by 2 atan(|w| h / 2): an error of (|w| h)^3 / 12 per step.
    wh = np.linalg.norm(omega) * h
    exact = from_scipy(to_scipy(q) * Rotation.from_rotvec(omega * h), canonical=False)
    assert angle_between(got, exact) == pytest.approx(wh - 2 * math.atan(wh / 2),
                                                      rel=1e-3, abs=1e-12)


@SETTINGS
@given(QUAT, VEC, st.floats(1e-4, 1.0))
def test_integrate_exp_against_scipy(q, omega, h):
    got = qu.integrate_exp(q, omega, h)
    expected = from_scipy(to_scipy(q) * Rotation.from_rotvec(omega * h), canonical=False)
    same_rotation(got, expected, 2e-15)
    assert abs(np.linalg.norm(got) - 1.0) <= 2.3e-16
    np.testing.assert_allclose(qu.integrate_exp(q[None], omega[None], np.array([h]))[0], got,
                               atol=1e-15)
    # Exact for a constant rate: two half steps equal one full step.
    half = qu.integrate_exp(qu.integrate_exp(q, omega, h / 2), omega, h / 2)
    same_rotation(half, got, 2e-15)


def test_integrate_exp_zero_small_denormal_and_nan():
    q = qu.euler2q(0.3, -0.2, 1.1)
    np.testing.assert_allclose(qu.integrate_exp(q, [0.0, 0.0, 0.0], 0.01), q, atol=2e-16)
    np.testing.assert_array_equal(qu.integrate_exp(IDENTITY, [0.0, 0.0, 0.0], 0.01), IDENTITY)
    np.testing.assert_array_equal(qu.integrate_exp(np.stack([IDENTITY] * 2), np.zeros(3), 0.01),
                                  [IDENTITY, IDENTITY])
    np.testing.assert_array_equal(qu.integrate_exp(IDENTITY, [5e-324, 0.0, 0.0], 1.0), IDENTITY)
    # Across the series threshold (|omega| h / 2 = 1e-4) the step is continuous and exact.
    axis = np.array([2.0, -1.0, 2.0]) / 3.0
    for half_angle in (1e-4 * (1 - 1e-9), 1e-4, 1e-4 * (1 + 1e-9)):
        omega = axis * 2 * half_angle / 0.01
        expected = from_scipy(to_scipy(q) * Rotation.from_rotvec(omega * 0.01), canonical=False)
        same_rotation(qu.integrate_exp(q, omega, 0.01), expected, 3e-16)
        same_rotation(qu.integrate_exp(q[None], omega[None], 0.01)[0], expected, 3e-16)
    assert np.isnan(qu.integrate_exp(q, [math.nan, 0.0, 0.0], 0.01)).all()
    assert np.isnan(qu.integrate_exp([math.nan, 0, 0, 0], [0.1, 0.0, 0.0], 0.01)).all()
    assert np.isnan(qu.integrate_euler(q, [math.nan, 0.0, 0.0], 0.01)).all()


def test_integrate_exp_huge_rate():
    # 1e8 rad/s for 10 ms: a rotation of 1e6 rad about x, still a unit quaternion on the
    # closed form [cos(5e5), sin(5e5), 0, 0].
    got = qu.integrate_exp(IDENTITY, [1e8, 0.0, 0.0], 0.01)
    np.testing.assert_allclose(got, [math.cos(5e5), math.sin(5e5), 0.0, 0.0], atol=1e-10)
    assert abs(np.linalg.norm(got) - 1.0) <= 2.3e-16
    got_b = qu.integrate_exp(IDENTITY[None], np.array([[1e8, 0.0, 0.0]]), 0.01)[0]
    np.testing.assert_allclose(got_b, got, atol=1e-10)


def test_integrate_exp_long_run_stays_on_closed_form():
    # Ten minutes at 100 Hz, 1 rad/s about a skew axis (the hour-long run is in the bench).
    axis = np.array([1.0, 2.0, 3.0]) / math.sqrt(14.0)
    q0 = qu.euler2q(0.3, -0.2, 1.1)
    q = q0
    n = 60000
    for _ in range(n):
        q = qu.integrate_exp(q, axis, 0.01)
    half = n * 0.01 / 2
    closed = qu.quat_multiply(q0, np.r_[math.cos(half), math.sin(half) * axis])
    assert angle_between(q, closed) < 1e-11
    assert abs(np.linalg.norm(q) - 1.0) <= 1e-15
    q = q0
    for _ in range(n):
        q = qu.integrate_euler(q, axis, 0.01)
    assert angle_between(q, closed) > 1e-3  # Fossen's first-order step drifts

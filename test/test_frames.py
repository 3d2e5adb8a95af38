"""Tests of vessel_kinematics.core.frames: REP-103 conversions against scipy and by hand."""

from __future__ import annotations

import math

from hypothesis import assume, given, settings
from hypothesis import strategies as st
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from vessel_kinematics.core import frames as fr
from vessel_kinematics.core import quaternion as qu
from vessel_kinematics.core import rotation as ro

SETTINGS = settings(deadline=None, max_examples=60)
VEC = st.lists(st.floats(-1e6, 1e6), min_size=3, max_size=3).map(np.array)
QUAT = st.lists(st.floats(-1.0, 1.0), min_size=4, max_size=4).map(np.array).filter(
    lambda q: np.linalg.norm(q) > 0.1).map(lambda q: q / np.linalg.norm(q))
ANGLE = st.floats(-math.pi, math.pi)
PITCH = st.floats(-1.5, 1.5)
# Written out here, independently of the module's constants.
NED_ENU = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
FRD_FLU = np.diag([1.0, -1.0, -1.0])


def random_cov(n: int, seed: int) -> np.ndarray:
    """Return a random symmetric positive definite n x n matrix."""
    a = np.random.default_rng(seed).normal(size=(n, n))
    return a @ a.T + n * np.eye(n)


# --- vectors -------------------------------------------------------------------------------

def test_vector_known_values():
    np.testing.assert_array_equal(fr.ned_to_enu([1.0, 2.0, 3.0]), [2.0, 1.0, -3.0])
    np.testing.assert_array_equal(fr.enu_to_ned([2.0, 1.0, -3.0]), [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(fr.frd_to_flu([1.0, 2.0, 3.0]), [1.0, -2.0, -3.0])
    np.testing.assert_array_equal(fr.flu_to_frd([1.0, -2.0, -3.0]), [1.0, 2.0, 3.0])
    # North-going at 5 m/s is ENU y = 5; a 1 m/s climb is NED z = -1.
    np.testing.assert_array_equal(fr.ned_to_enu([5.0, 0.0, -1.0]), [0.0, 5.0, 1.0])
    with pytest.raises(ValueError, match='shape'):
        fr.ned_to_enu([1.0, 2.0])


@SETTINGS
@given(VEC)
def test_vector_conversions_are_involutions(v):
    for fn in (fr.ned_to_enu, fr.enu_to_ned, fr.frd_to_flu, fr.flu_to_frd):
        np.testing.assert_array_equal(fn(fn(v)), v)
    np.testing.assert_array_equal(fr.enu_to_ned(fr.ned_to_enu(v)), v)
    np.testing.assert_array_equal(fr.flu_to_frd(fr.frd_to_flu(v)), v)
    np.testing.assert_array_equal(fr.ned_to_enu(v), NED_ENU @ v)
    np.testing.assert_array_equal(fr.frd_to_flu(v), FRD_FLU @ v)
    batch = np.stack([v, 2 * v, -v]).reshape(3, 1, 3)
    np.testing.assert_array_equal(fr.ned_to_enu(batch)[1, 0], fr.ned_to_enu(2 * v))
    np.testing.assert_array_equal(fr.frd_to_flu(batch)[2, 0], fr.frd_to_flu(-v))
    # The scalar kernels of the per-message builders: the same numbers, as floats.
    x, y, z = v.tolist()
    assert fr.swap_world3(x, y, z) == tuple(fr.ned_to_enu(v).tolist())
    assert fr.flip_body3(x, y, z) == tuple(fr.frd_to_flu(v).tolist())
    assert fr.swap_world3(*fr.swap_world3(x, y, z)) == (x, y, z)
    assert fr.flip_body3(*fr.flip_body3(x, y, z)) == (x, y, z)
    assert all(type(c) is float for c in fr.swap_world3(x, y, z) + fr.flip_body3(x, y, z))


def test_vectors_pass_nan_through():
    out = fr.ned_to_enu([[math.nan, 1.0, 2.0], [1.0, 2.0, 3.0]])
    np.testing.assert_array_equal(out[1], [2.0, 1.0, -3.0])
    assert math.isnan(out[0, 1])
    assert math.isnan(fr.frd_to_flu([math.nan, 0.0, 0.0])[0])


# --- quaternions ---------------------------------------------------------------------------

def test_quaternion_order_converters():
    np.testing.assert_array_equal(fr.quat_wxyz_to_xyzw([1.0, 2.0, 3.0, 4.0]), [2, 3, 4, 1])
    np.testing.assert_array_equal(fr.quat_xyzw_to_wxyz([2.0, 3.0, 4.0, 1.0]), [1, 2, 3, 4])
    q = np.arange(24.0).reshape(2, 3, 4)
    np.testing.assert_array_equal(fr.quat_xyzw_to_wxyz(fr.quat_wxyz_to_xyzw(q)), q)
    with pytest.raises(ValueError, match='shape'):
        fr.quat_wxyz_to_xyzw([1.0, 0.0, 0.0])


@SETTINGS
@given(QUAT)
def test_q_nb_to_ros_against_scipy(q_nb):
    q_ros = fr.q_nb_to_ros(q_nb)  # xyzw, FLU -> ENU
    expected = NED_ENU @ Rotation.from_quat(q_nb[[1, 2, 3, 0]]).as_matrix() @ FRD_FLU
    np.testing.assert_allclose(Rotation.from_quat(q_ros).as_matrix(), expected, atol=1e-15)
    assert np.linalg.norm(q_ros) == pytest.approx(1.0, abs=1e-15)
    # The product form q_(ENU<-NED) (x) q_nb (x) q_(FRD<-FLU), up to sign.
    q_enu_ned = np.array([0.0, math.sqrt(0.5), math.sqrt(0.5), 0.0])
    q_frd_flu = np.array([0.0, 1.0, 0.0, 0.0])
    product = qu.quat_multiply(q_enu_ned, qu.quat_multiply(q_nb, q_frd_flu))
    wxyz = fr.q_nb_to_ros_wxyz(q_nb)
    sign = 1.0 if product @ wxyz >= 0 else -1.0
    np.testing.assert_allclose(wxyz, sign * product, atol=1e-15)
    np.testing.assert_array_equal(fr.quat_wxyz_to_xyzw(wxyz), q_ros)


@SETTINGS
@given(QUAT, VEC)
def test_ros_orientation_rotates_flu_vectors_consistently(q_nb, v_frd):
    # Rotating a body vector in ROS frames equals rotating it in Fossen's and converting.
    v_enu = Rotation.from_quat(fr.q_nb_to_ros(q_nb)).apply(fr.frd_to_flu(v_frd))
    np.testing.assert_allclose(v_enu, fr.ned_to_enu(qu.quat_rotate(q_nb, v_frd)),
                               atol=1e-9 * (1 + np.abs(v_frd).max()))


@SETTINGS
@given(QUAT)
def test_quaternion_conversion_is_an_involution(q_nb):
    np.testing.assert_allclose(fr.q_nb_from_ros(fr.q_nb_to_ros(q_nb)), q_nb, atol=3e-16)
    np.testing.assert_allclose(fr.q_nb_from_ros_wxyz(fr.q_nb_to_ros_wxyz(q_nb)), q_nb,
                               atol=3e-16)
    xyzw = q_nb[[1, 2, 3, 0]]
    np.testing.assert_allclose(fr.q_nb_to_ros(fr.q_nb_from_ros(xyzw)), xyzw, atol=3e-16)
    batch = np.stack([q_nb, -q_nb])
    np.testing.assert_allclose(fr.q_nb_to_ros(batch), [fr.q_nb_to_ros(q_nb),
                                                       -fr.q_nb_to_ros(q_nb)], atol=1e-16)


def test_quaternion_known_headings():
    # Level, heading north (psi = 0): ROS yaw = +90 deg about ENU z.
    np.testing.assert_allclose(fr.q_nb_to_ros([1.0, 0.0, 0.0, 0.0]),
                               [0.0, 0.0, math.sqrt(0.5), math.sqrt(0.5)], atol=1e-16)
    # Heading east (psi = 90 deg): ROS yaw = 0, the identity.
    q = fr.q_nb_to_ros(qu.euler2q(0.0, 0.0, math.pi / 2))
    same = np.allclose(q, [0, 0, 0, 1], atol=1e-16) or np.allclose(q, [0, 0, 0, -1], atol=1e-16)
    assert same, q
    # Bow up 10 deg (theta > 0 in NED/FRD) is negative pitch in ROS (FLU y points to port).
    roll, pitch, yaw = Rotation.from_quat(
        fr.q_nb_to_ros(qu.euler2q(0.0, math.radians(10.0), 0.0))).as_euler('ZYX')[::-1]
    assert pitch == pytest.approx(math.radians(-10.0), abs=1e-15)
    assert yaw == pytest.approx(math.pi / 2, abs=1e-15)
    assert np.isnan(fr.q_nb_to_ros([math.nan, 0.0, 0.0, 0.0])).any()


@SETTINGS
@given(ANGLE, PITCH, ANGLE)
def test_euler_and_yaw_conversions_match_the_quaternion_one(phi, theta, psi):
    roll, pitch, yaw = fr.euler_ned_to_enu(phi, theta, psi)
    assert -math.pi <= yaw <= math.pi
    ros = Rotation.from_euler('ZYX', [yaw, pitch, roll]).as_matrix()
    expected = Rotation.from_quat(fr.q_nb_to_ros(qu.euler2q(phi, theta, psi))).as_matrix()
    np.testing.assert_allclose(ros, expected, atol=1e-14)
    back = fr.euler_enu_to_ned(roll, pitch, yaw)
    assert back[0] == phi and back[1] == theta
    assert math.remainder(back[2] - psi, 2 * math.pi) == pytest.approx(0.0, abs=1e-15)
    assert fr.yaw_enu_to_ned(fr.yaw_ned_to_enu(psi)) == pytest.approx(psi, abs=1e-15) or \
        abs(abs(psi) - math.pi) < 1e-15
    arr = fr.euler_ned_to_enu(np.array([phi]), np.array([theta]), np.array([psi]))
    np.testing.assert_allclose(np.ravel(arr), [roll, pitch, yaw], atol=1e-15)


def test_yaw_known_values():
    assert fr.yaw_ned_to_enu(0.0) == pytest.approx(math.pi / 2)
    assert fr.yaw_ned_to_enu(math.pi / 2) == pytest.approx(0.0)
    assert fr.yaw_ned_to_enu(math.pi) == pytest.approx(-math.pi / 2)
    assert fr.yaw_ned_to_enu(-math.pi / 2) == pytest.approx(math.pi)  # west: +-180 deg
    np.testing.assert_allclose(fr.yaw_ned_to_enu(np.array([0.0, math.pi / 2, math.pi])),
                               [math.pi / 2, 0.0, -math.pi / 2], atol=1e-15)


# --- covariances ---------------------------------------------------------------------------

def test_cov3_known_permutation():
    c = random_cov(3, 1)  # indices 0, 1, 2 = N, E, D
    e = fr.cov3_ned_to_enu(c)  # indices 0, 1, 2 = E, N, U
    assert e[0, 0] == c[1, 1] and e[1, 1] == c[0, 0] and e[2, 2] == c[2, 2]
    assert e[0, 1] == c[1, 0] and e[0, 2] == -c[1, 2] and e[1, 2] == -c[0, 2]
    b = fr.cov3_frd_to_flu(c)
    assert b[0, 0] == c[0, 0] and b[0, 1] == -c[0, 1] and b[1, 2] == c[1, 2]
    with pytest.raises(ValueError, match='shape'):
        fr.cov3_ned_to_enu(np.eye(6))


@pytest.mark.parametrize('seed', range(5))
def test_covariances_transform_like_the_vectors(seed):
    # The variance of any linear functional a^T x is the same whichever frame x is written in.
    rng = np.random.default_rng(100 + seed)
    c3, c6 = random_cov(3, seed), random_cov(6, seed)
    a = rng.normal(size=3)
    for to, vec in ((fr.cov3_ned_to_enu, fr.ned_to_enu), (fr.cov3_enu_to_ned, fr.enu_to_ned),
                    (fr.cov3_frd_to_flu, fr.frd_to_flu), (fr.cov3_flu_to_frd, fr.flu_to_frd)):
        assert vec(a) @ to(c3) @ vec(a) == pytest.approx(a @ c3 @ a, rel=1e-14)
        np.testing.assert_array_equal(to(to(c3)), c3)
    a6 = rng.normal(size=6)
    cases = ((fr.cov6_ned_to_enu, fr.ned_to_enu, fr.ned_to_enu),
             (fr.cov6_enu_to_ned, fr.enu_to_ned, fr.enu_to_ned),
             (fr.cov6_frd_to_flu, fr.frd_to_flu, fr.frd_to_flu),
             (fr.cov6_flu_to_frd, fr.flu_to_frd, fr.flu_to_frd),
             (fr.cov6_pose_to_ros, fr.ned_to_enu, fr.frd_to_flu),
             (fr.cov6_pose_from_ros, fr.enu_to_ned, fr.flu_to_frd))
    for to, lin, ang in cases:
        b6 = np.r_[lin(a6[:3]), ang(a6[3:])]
        assert b6 @ to(c6) @ b6 == pytest.approx(a6 @ c6 @ a6, rel=1e-14)
        np.testing.assert_array_equal(to(to(c6)), c6)
        out = to(c6)
        np.testing.assert_array_equal(out, out.T)
        assert np.linalg.eigvalsh(out).min() > 0
    batch = np.stack([c6, 2 * c6])
    np.testing.assert_allclose(fr.cov6_pose_to_ros(batch)[1], 2 * fr.cov6_pose_to_ros(c6))
    np.testing.assert_allclose(fr.cov_transform(c6, fr.A6_POSE), fr.cov6_pose_to_ros(c6))


def test_cov6_pose_attitude_block_is_the_euler_jacobian():
    # (roll, pitch, yaw) = (phi, -theta, pi/2 - psi): a yaw variance stays, the yaw-roll
    # covariance flips sign, the north-yaw covariance becomes (ENU y, yaw) with its sign flipped.
    c = random_cov(6, 7)
    out = fr.cov6_pose_to_ros(c)
    assert out[5, 5] == c[5, 5] and out[3, 3] == c[3, 3] and out[4, 4] == c[4, 4]
    assert out[3, 5] == -c[3, 5] and out[3, 4] == -c[3, 4] and out[4, 5] == c[4, 5]
    assert out[1, 5] == -c[0, 5] and out[0, 3] == c[1, 3]
    # Numerically: the Jacobian of euler_ned_to_enu equals the attitude block.
    x0 = np.array([0.1, 0.2, 0.3])
    jac = np.empty((3, 3))
    for k in range(3):
        d = np.zeros(3)
        d[k] = 1e-6
        plus = np.array(fr.euler_ned_to_enu(*(x0 + d)))
        minus = np.array(fr.euler_ned_to_enu(*(x0 - d)))
        jac[:, k] = (plus - minus) / 2e-6
    np.testing.assert_allclose(jac, fr.A6_POSE[3:, 3:], atol=1e-9)


def test_constants_are_proper_rotations():
    for a in (fr.A_WORLD, fr.A_BODY):
        np.testing.assert_array_equal(a @ a, np.eye(3))
        np.testing.assert_array_equal(a, a.T)
        assert np.linalg.det(a) == pytest.approx(1.0)
    np.testing.assert_array_equal(fr.A_WORLD, NED_ENU)
    np.testing.assert_array_equal(fr.A_BODY, FRD_FLU)
    # A_WORLD is the rotation of pi about (1, 1, 0)/sqrt2 and A_BODY of pi about x.
    np.testing.assert_allclose(ro.rotation_axis_angle([1.0, 1.0, 0.0], math.pi), NED_ENU,
                               atol=1e-15)
    np.testing.assert_allclose(ro.rot_x(math.pi), FRD_FLU, atol=1e-15)


@SETTINGS
@given(QUAT)
def test_yaw_from_quaternions_against_scipy(q_nb):
    # Fossen's q_nb gives the heading psi; the ROS orientation of the same attitude gives the
    # ROS yaw, pi/2 - psi: both the zyx yaw of scipy's Rotation, one convention. (At pitch
    # +-90 deg the yaw is not unique: test_flow's gimbal-lock test covers that case.)
    assume(abs(Rotation.from_quat(q_nb[[1, 2, 3, 0]]).as_matrix()[2, 0]) < 1.0 - 1e-6)
    psi = Rotation.from_quat(q_nb[[1, 2, 3, 0]]).as_euler('ZYX')[0]
    assert fr.ssa(fr.yaw_from_q(tuple(q_nb)) - psi) == pytest.approx(0.0, abs=1e-9)
    q_ros = fr.q_nb_to_ros(q_nb)
    yaw = Rotation.from_quat(q_ros).as_euler('ZYX')[0]
    assert fr.ssa(fr.yaw_from_ros(tuple(q_ros)) - yaw) == pytest.approx(0.0, abs=1e-9)
    assert fr.ssa(fr.yaw_ned_to_enu(psi) - yaw) == pytest.approx(0.0, abs=1e-9)
    assert fr.yaw_from_ros(np.stack([q_ros, q_ros]))[1] == pytest.approx(
        fr.yaw_from_ros(tuple(q_ros)), abs=1e-15)

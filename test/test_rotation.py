"""Tests of vessel_kinematics.core.rotation against scipy's Rotation and first principles."""

from __future__ import annotations

import math

from hypothesis import given, settings
from hypothesis import strategies as st
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from vessel_kinematics.core import rotation as ro

SETTINGS = settings(deadline=None, max_examples=60)
ANGLE = st.floats(-math.pi, math.pi)
PITCH = st.floats(-math.pi / 2, math.pi / 2)
VEC = st.lists(st.floats(-10.0, 10.0), min_size=3, max_size=3).map(np.array)
EYE = np.eye(3)


def scipy_rzyx(phi, theta, psi) -> np.ndarray:
    """Return R_b^n from scipy: intrinsic 'ZYX' with angles [psi, theta, phi] = Fossen zyx."""
    return Rotation.from_euler('ZYX', np.stack(np.broadcast_arrays(psi, theta, phi), -1)
                               ).as_matrix()


def assert_so3(r: np.ndarray, tol: float = 1e-14) -> None:
    """Assert R R^T = I and det R = 1 for a stack of matrices."""
    np.testing.assert_allclose(r @ np.swapaxes(r, -1, -2), np.broadcast_to(EYE, r.shape),
                               atol=tol, rtol=0)
    np.testing.assert_allclose(np.linalg.det(r), 1.0, atol=tol, rtol=0)


# --- skew ----------------------------------------------------------------------------------

@SETTINGS
@given(VEC, VEC)
def test_skew_is_the_cross_product(a, b):
    np.testing.assert_allclose(ro.skew(a) @ b, np.cross(a, b), atol=1e-12, rtol=0)
    np.testing.assert_array_equal(ro.skew(a).T, -ro.skew(a))
    np.testing.assert_array_equal(ro.vee(ro.skew(a)), a)


def test_skew_known_and_batched():
    np.testing.assert_array_equal(ro.skew([1.0, 2.0, 3.0]),
                                  [[0, -3, 2], [3, 0, -1], [-2, 1, 0]])
    a = np.arange(24.0).reshape(2, 4, 3)
    s = ro.skew(a)
    assert s.shape == (2, 4, 3, 3)
    np.testing.assert_array_equal(s[1, 2], ro.skew(a[1, 2]))
    with pytest.raises(ValueError, match='shape'):
        ro.skew([1.0, 2.0])


# --- principal rotations and rzyx ----------------------------------------------------------

@pytest.mark.parametrize('fn, axis', [(ro.rot_x, 'x'), (ro.rot_y, 'y'), (ro.rot_z, 'z')])
def test_principal_rotations_against_scipy(fn, axis):
    angles = np.linspace(-4.0, 4.0, 17)
    expected = Rotation.from_euler(axis, angles[:, None]).as_matrix()
    np.testing.assert_allclose(fn(angles), expected, atol=1e-15, rtol=0)
    for a, e in zip(angles, expected):
        np.testing.assert_allclose(fn(float(a)), e, atol=1e-15, rtol=0)


@SETTINGS
@given(ANGLE, PITCH, ANGLE)
def test_rzyx_against_scipy_and_product(phi, theta, psi):
    r = ro.rzyx(phi, theta, psi)
    np.testing.assert_allclose(r, scipy_rzyx(phi, theta, psi), atol=1e-15, rtol=0)
    np.testing.assert_allclose(r, ro.rot_z(psi) @ ro.rot_y(theta) @ ro.rot_x(phi),
                               atol=1e-15, rtol=0)
    assert_so3(r)
    # The vectorised path gives the same numbers as the scalar one.
    np.testing.assert_allclose(ro.rzyx(np.array([phi]), np.array([theta]), np.array([psi]))[0],
                               r, atol=1e-16, rtol=0)


def test_rzyx_known_value():
    # Fossen's MSS Rzyx(10 deg, 20 deg, 30 deg); digits computed independently with
    # scipy 1.17.1: Rotation.from_euler('ZYX', [30, 20, 10], degrees=True).as_matrix().
    expected = [[0.8137976813493736, -0.44096961052988237, 0.37852230636979245],
                [0.4698463103929541, 0.8825641192593855, 0.01802831123629728],
                [-0.34202014332566866, 0.16317591116653482, 0.9254165783983233]]
    np.testing.assert_allclose(ro.rzyx(*np.deg2rad([10.0, 20.0, 30.0]).tolist()), expected,
                               atol=5e-16, rtol=0)
    # BODY x (forward) of a vessel heading east (psi = 90 deg) points east in NED.
    np.testing.assert_allclose(ro.rzyx(0.0, 0.0, math.pi / 2) @ [1, 0, 0], [0, 1, 0],
                               atol=1e-16)


def test_rzyx_broadcasting_nan_and_extreme_inputs():
    r = ro.rzyx(np.zeros((4, 1)), np.linspace(-1, 1, 5), 0.3)
    assert r.shape == (4, 5, 3, 3)
    np.testing.assert_allclose(r, scipy_rzyx(np.zeros((4, 1)), np.linspace(-1, 1, 5), 0.3),
                               atol=1e-15)
    assert np.isnan(ro.rzyx(math.nan, 0.1, 0.2)).any()
    assert np.isnan(ro.rzyx(np.array([0.0, math.nan]), 0.1, 0.2)[1]).any()
    assert not np.isnan(ro.rzyx(np.array([0.0, math.nan]), 0.1, 0.2)[0]).any()
    assert_so3(ro.rzyx(1e10, -3e12, 7e15))
    np.testing.assert_array_equal(ro.rzyx(5e-324, 5e-324, 0.0)[np.diag_indices(3)], 1.0)


@SETTINGS
@given(st.floats(-1e-3, 1e-3), st.floats(-1e-3, 1e-3), st.floats(-1e-3, 1e-3))
def test_small_angle_approximation_is_first_order(phi, theta, psi):
    size = math.sqrt(phi * phi + theta * theta + psi * psi)
    error = np.abs(ro.rzyx_small_angle(phi, theta, psi) - ro.rzyx(phi, theta, psi)).max()
    assert error <= size * size + 1e-16
    np.testing.assert_allclose(ro.rzyx_small_angle(phi, theta, psi),
                               [[1, -psi, theta], [psi, 1, -phi], [-theta, phi, 1]])


def test_small_angle_error_grows_quadratically():
    e1 = np.abs(ro.rzyx_small_angle(1e-2, 1e-2, 1e-2) - ro.rzyx(1e-2, 1e-2, 1e-2)).max()
    e2 = np.abs(ro.rzyx_small_angle(2e-2, 2e-2, 2e-2) - ro.rzyx(2e-2, 2e-2, 2e-2)).max()
    assert 3.5 < e2 / e1 < 4.5


# --- T_Theta and J_Theta -------------------------------------------------------------------

def euler_partials(phi: float, theta: float, psi: float, d: float = 1e-6) -> list:
    """Return dR/dphi, dR/dtheta, dR/dpsi by central differences of scipy's matrix."""
    out = []
    for k in range(3):
        step = np.zeros(3)
        step[k] = d
        plus = scipy_rzyx(*(np.array([phi, theta, psi]) + step))
        minus = scipy_rzyx(*(np.array([phi, theta, psi]) - step))
        out.append((plus - minus) / (2 * d))
    return out


@SETTINGS
@given(ANGLE, st.floats(-1.4, 1.4), ANGLE, VEC)
def test_tzyx_maps_body_rate_to_euler_rates(phi, theta, psi, omega):
    # R_dot = sum_i dR/dTheta_i Theta_dot_i must equal R S(omega) when Theta_dot = T omega.
    theta_dot = ro.tzyx(phi, theta) @ omega
    partials = euler_partials(phi, theta, psi)
    r_dot = sum(p * td for p, td in zip(partials, theta_dot))
    expected = scipy_rzyx(phi, theta, psi) @ ro.skew(omega)
    np.testing.assert_allclose(r_dot, expected, atol=1e-7 * (1 + np.abs(omega).max()) * 10)


@SETTINGS
@given(ANGLE, st.floats(-4.0, 4.0).filter(lambda t: abs(math.cos(t)) > 0.05))
def test_tzyx_inverse_and_batch(phi, theta):
    t = ro.tzyx(phi, theta)
    sp, cp, st_, ct = math.sin(phi), math.cos(phi), math.sin(theta), math.cos(theta)
    t_inv = np.array([[1, 0, -st_], [0, cp, ct * sp], [0, -sp, ct * cp]])  # Fossen's T^-1
    np.testing.assert_allclose(t @ t_inv, EYE, atol=1e-12)
    np.testing.assert_allclose(ro.tzyx(np.array([phi, phi]), np.array([theta, theta]))[1], t,
                               atol=1e-15)


@pytest.mark.parametrize('theta', [math.pi / 2, -math.pi / 2, math.pi / 2 - 1e-12,
                                   -math.pi / 2 + 1e-12, math.pi / 2 + 5e-7, 3 * math.pi / 2])
def test_tzyx_raises_near_gimbal_lock(theta):
    with pytest.raises(ro.GimbalLockError, match='singular'):
        ro.tzyx(0.3, theta)
    with pytest.raises(ValueError):
        ro.tzyx(np.array([0.1, 0.3]), np.array([0.2, theta]))
    with pytest.raises(ro.GimbalLockError):
        ro.eulerang(0.1, theta, 0.2)


def test_tzyx_tolerance_edge_and_nan():
    t = ro.tzyx(0.3, math.pi / 2 - 2 * ro.GIMBAL_LOCK_TOL)
    assert np.isfinite(t).all() and np.abs(t).max() < 1.0 / ro.GIMBAL_LOCK_TOL
    with pytest.raises(ro.GimbalLockError):
        ro.tzyx(0.3, math.pi / 2 - 1e-7, tol=1e-6)
    ro.tzyx(0.3, math.pi / 2 - 1e-7, tol=1e-8)  # a tighter tolerance lets it through
    assert np.isnan(ro.tzyx(0.3, math.nan)).any()
    assert np.isnan(ro.tzyx(np.array([0.3, 0.1]), np.array([math.nan, 0.2]))[0]).any()
    assert issubclass(ro.GimbalLockError, ValueError)


@SETTINGS
@given(ANGLE, st.floats(-1.5, 1.5), ANGLE)
def test_eulerang_blocks(phi, theta, psi):
    j = ro.eulerang(phi, theta, psi)
    assert j.shape == (6, 6)
    np.testing.assert_array_equal(j[:3, :3], ro.rzyx(phi, theta, psi))
    np.testing.assert_array_equal(j[3:, 3:], ro.tzyx(phi, theta))
    np.testing.assert_array_equal(j[:3, 3:], 0.0)
    np.testing.assert_array_equal(j[3:, :3], 0.0)
    jb = ro.eulerang(np.array([phi, 0.0]), np.array([theta, 0.0]), np.array([psi, 0.0]))
    assert jb.shape == (2, 6, 6)
    np.testing.assert_allclose(jb[0], j, atol=1e-15)
    np.testing.assert_array_equal(jb[1], np.eye(6))


# --- axis-angle ----------------------------------------------------------------------------

@SETTINGS
@given(VEC.filter(lambda v: np.linalg.norm(v) > 1e-3), st.floats(-7.0, 7.0))
def test_axis_angle_against_scipy(axis, beta):
    lam = axis / np.linalg.norm(axis)
    expected = Rotation.from_rotvec(beta * lam).as_matrix()
    r = ro.rotation_axis_angle(axis, beta)
    np.testing.assert_allclose(r, expected, atol=1e-14)
    assert_so3(r)
    np.testing.assert_allclose(r @ lam, lam, atol=1e-14)  # the axis is fixed
    np.testing.assert_allclose(ro.rotation_axis_angle(axis[None], np.array([beta]))[0], r,
                               atol=1e-15)
    # Fossen's form I + sin(b) S + (1 - cos(b)) S^2 evaluated literally.
    s = ro.skew(lam)
    np.testing.assert_allclose(r, EYE + math.sin(beta) * s + (1 - math.cos(beta)) * s @ s,
                               atol=1e-14)


def test_axis_angle_small_huge_zero_and_nan():
    r = ro.rotation_axis_angle([0.0, 0.0, 1e-300], 1e-20)
    assert r[1, 0] == 1e-20 and r[0, 0] == 1.0
    np.testing.assert_allclose(ro.rotation_axis_angle([0, 0, 1e300], 0.5), ro.rot_z(0.5),
                               atol=1e-16)
    np.testing.assert_allclose(ro.rotation_axis_angle(np.array([[0, 0, 1e300]]), [0.5])[0],
                               ro.rot_z(0.5), atol=1e-16)
    with pytest.raises(ValueError, match='zero'):
        ro.rotation_axis_angle([0.0, 0.0, 0.0], 0.3)
    with pytest.raises(ValueError, match='zero'):
        ro.rotation_axis_angle(np.array([[1.0, 0, 0], [0, 0, 0]]), 0.3)
    assert np.isnan(ro.rotation_axis_angle([math.nan, 0.0, 1.0], 0.3)).any()
    assert np.isnan(ro.rotation_axis_angle([1.0, 0.0, 0.0], math.nan)).any()


# --- rot2euler -----------------------------------------------------------------------------

@SETTINGS
@given(ANGLE, st.floats(-1.57, 1.57), ANGLE)
def test_rot2euler_round_trip_and_scipy(phi, theta, psi):
    r = scipy_rzyx(phi, theta, psi)
    angles = ro.rot2euler(r)
    assert all(isinstance(a, float) for a in angles)
    # Angles are recovered modulo 2 pi (phi and psi = +-pi are the same angle).
    wrap = np.remainder(np.subtract(angles, (phi, theta, psi)) + math.pi, 2 * math.pi) - math.pi
    np.testing.assert_allclose(wrap, 0.0, atol=1e-11)
    sp = Rotation.from_matrix(r).as_euler('ZYX')[::-1]
    wrap = np.remainder(np.subtract(angles, sp) + math.pi, 2 * math.pi) - math.pi
    np.testing.assert_allclose(wrap, 0.0, atol=1e-11)
    batch = ro.rot2euler(np.stack([r, r]))
    np.testing.assert_allclose([b[1] for b in batch], angles, atol=1e-15)


@SETTINGS
@given(ANGLE, ANGLE, st.sampled_from([1.0, -1.0]),
       st.sampled_from([0.0, 1e-15, 1e-12, 1e-11, 1e-9, 1e-6]))
def test_rot2euler_at_and_near_gimbal_lock(phi, psi, sign, offset):
    theta = sign * (math.pi / 2 - offset)
    r = ro.rzyx(phi, theta, psi)
    e_phi, e_theta, e_psi = ro.rot2euler(r)
    assert math.isfinite(e_phi) and math.isfinite(e_psi)
    assert abs(e_theta) <= math.pi / 2
    # Whatever split of phi and psi is returned, it rebuilds the matrix.
    np.testing.assert_allclose(ro.rzyx(e_phi, e_theta, e_psi), r,
                               atol=max(2e-15, 2 * ro.EULER_LOCK_TOL))
    if math.cos(theta) < ro.EULER_LOCK_TOL / 2:
        # The documented answer at lock: phi = 0, all rotation about the vertical in psi
        # (psi - phi at theta = +90 deg, psi + phi at -90 deg).
        assert e_phi == 0.0
        assert e_theta == pytest.approx(theta, abs=1e-15)
        expected = psi - phi if sign > 0 else psi + phi
        assert math.remainder(e_psi - expected, 2 * math.pi) == pytest.approx(0.0, abs=1e-9)
    batch = ro.rot2euler(r[None])
    np.testing.assert_allclose([b[0] for b in batch], (e_phi, e_theta, e_psi), atol=1e-15)


def test_rot2euler_exact_gimbal_lock_values():
    r = ro.rzyx(0.4, math.pi / 2, 1.0)
    assert ro.rot2euler(r) == pytest.approx((0.0, math.pi / 2, 0.6), abs=1e-15)
    r = ro.rzyx(0.4, -math.pi / 2, 1.0)
    assert ro.rot2euler(r) == pytest.approx((0.0, -math.pi / 2, 1.4), abs=1e-15)
    # A hand-built locked matrix with signed zeros: Ry(90 deg) exactly.
    r = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, -0.0], [-1.0, 0.0, -0.0]])
    assert ro.rot2euler(r) == (0.0, math.pi / 2, 0.0)


def test_rot2euler_nan_and_shape():
    assert all(math.isnan(a) for a in ro.rot2euler(np.full((3, 3), math.nan)))
    phi, theta, psi = ro.rot2euler(np.full((2, 3, 3), math.nan))
    assert np.isnan(phi).all() and np.isnan(theta).all() and np.isnan(psi).all()
    with pytest.raises(ValueError, match='shape'):
        ro.rot2euler(np.eye(4))


# --- rotation_rate -------------------------------------------------------------------------

@SETTINGS
@given(ANGLE, PITCH, ANGLE, VEC)
def test_rotation_rate_matches_finite_difference(phi, theta, psi, omega):
    # R(t) = R0 exp(S(omega) t) for a constant body rate; central difference at t = 0.
    r0 = scipy_rzyx(phi, theta, psi)
    d = 1e-6
    r_plus = r0 @ Rotation.from_rotvec(omega * d).as_matrix()
    r_minus = r0 @ Rotation.from_rotvec(-omega * d).as_matrix()
    np.testing.assert_allclose(ro.rotation_rate(r0, omega), (r_plus - r_minus) / (2 * d),
                               atol=1e-8 * (1 + np.abs(omega).max() ** 3))
    assert ro.rotation_rate(np.stack([r0] * 3), omega).shape == (3, 3, 3)

"""
Tests of vessel_kinematics.core.geodesy against mpmath (50 digits), pyproj and pymap3d.

The ECEF -> LLH reference solves the foot-point problem independently in mpmath: the
geodetic latitude phi of the nearest surface point is the root of
g(phi) = r sin(phi) - z cos(phi) - e^2 R_E(phi) sin(phi) cos(phi) (the point lies on the
ellipsoid normal at phi), bracketed on the point's side of the equator, or, near the centre
(inside the evolute, where up to three normals exist), the root with the largest height.
"""

from __future__ import annotations

import math

from hypothesis import given, settings
from hypothesis import strategies as st
import mpmath
import numpy as np
import pymap3d
import pyproj
import pytest

from vessel_kinematics.core import geodesy as geo
from vessel_kinematics.core.flow import ssa

MP = mpmath.MPContext()  # a private 50-digit context: the global mpmath.mp is left alone
MP.dps = 50
A_MP = MP.mpf(6378137)
F_MP = 1 / MP.mpf('298.257223563')
E2_MP = F_MP * (2 - F_MP)
B_MP = A_MP * (1 - F_MP)
HALF_PI = MP.pi / 2

NM = 1e-9
#: The accuracy target of the issue: 10 nm x max(1, r / a).
TOL_NM = 10.0


def mp_llh2ecef(lat, lon, h):
    """Return the ECEF point (mpf, mpf, mpf) of (lat, lon, h) to 50 digits."""
    lat, lon, h = MP.mpf(lat), MP.mpf(lon), MP.mpf(h)
    n = A_MP / MP.sqrt(1 - E2_MP * MP.sin(lat) ** 2)
    return ((n + h) * MP.cos(lat) * MP.cos(lon), (n + h) * MP.cos(lat) * MP.sin(lon),
            (n * (1 - E2_MP) + h) * MP.sin(lat))


def mp_ecef2llh(x: float, y: float, z: float):
    """Return the exact (lat, lon, h) (mpf) of a double ECEF point, solved in mpmath."""
    x, y, z = MP.mpf(x), MP.mpf(y), MP.mpf(z)
    r = MP.hypot(x, y)
    lon = MP.atan2(y, x) if r != 0 else MP.mpf(0)
    if r == 0:
        return (HALF_PI if z >= 0 else -HALF_PI), lon, abs(z) - B_MP

    def g(phi):
        s, c = MP.sin(phi), MP.cos(phi)
        return r * s - z * c - E2_MP * A_MP / MP.sqrt(1 - E2_MP * s * s) * s * c

    def height(phi):
        s = MP.sin(phi)
        return r * MP.cos(phi) + z * s - A_MP * MP.sqrt(1 - E2_MP * s * s)

    if r > 1e5 or abs(z) > 1e5:
        # Outside the evolute: exactly one normal meets the half meridian on this side.
        bracket = (MP.mpf(0), HALF_PI) if z >= 0 else (-HALF_PI, MP.mpf(0))
        roots = [MP.findroot(g, bracket, solver='anderson')]
    else:
        grid = [-HALF_PI + MP.pi * i / 200 for i in range(201)]
        roots = []
        for lo, hi in zip(grid[:-1], grid[1:]):
            if g(lo) == 0:
                roots.append(lo)
            elif g(lo) * g(hi) < 0:
                roots.append(MP.findroot(g, (lo, hi), solver='anderson'))
        roots.append(HALF_PI if z >= 0 else -HALF_PI)  # guard: the poles (g ~ 0 there)
        roots = [phi for phi in roots if abs(g(phi)) < 1e-30 * A_MP]
    # The nearest surface point has the largest height; ties (z = 0) go north, as ecef2llh.
    phi = max(roots, key=lambda p: (height(p), p))
    return phi, lon, height(phi)


def forward_error(llh, p) -> float:
    """Return |F(llh) - p| (m): how far the exact forward image of llh is from the point."""
    q = mp_llh2ecef(*llh)
    return float(MP.sqrt(sum((qi - MP.mpf(pi)) ** 2 for qi, pi in zip(q, p))))


def scale(p) -> float:
    """Return max(1, r / a) for a point p."""
    return max(1.0, math.hypot(*p) / geo.WGS84_A)


def check_reverse(p) -> None:
    """Check ecef2llh(p) against the mpmath reference to 10 nm x max(1, r/a)."""
    lat, lon, h = geo.ecef2llh(tuple(p))
    tol = TOL_NM * NM * scale(p)
    assert forward_error((lat, lon, h), p) <= tol
    lat_ref, lon_ref, h_ref = mp_ecef2llh(*p)
    assert abs(h - float(h_ref)) <= tol
    r = math.hypot(p[0], p[1])
    if r > 1e5 or abs(p[2]) > 1e5:
        # Away from the evolute the latitude is well conditioned: compare it directly.
        assert abs(lat - float(lat_ref)) * max(math.hypot(*p), 1.0) <= tol
    if r != 0.0:
        assert abs(ssa(lon - float(lon_ref))) <= 1e-15 * math.pi
    # The numpy path agrees with the math path.
    lat_v, lon_v, h_v = geo.ecef2llh(np.array([p, p]))
    assert abs(h_v[0] - h) <= tol
    assert abs(lat_v[1] - lat) <= 4e-16 * math.pi
    assert lon_v[0] == pytest.approx(lon, abs=4e-16 * math.pi)


# --- constants -------------------------------------------------------------------------------

def test_wgs84_derived_constants():
    # NIMA TR8350.2 (WGS-84), Table 3.3: b = 6356752.3142 m, e^2 = 6.69437999014e-3,
    # e'^2 = 6.73949674228e-3.
    assert geo.WGS84_B == pytest.approx(6356752.3142, abs=1e-4)
    # The table's values are rounded to 1e-14: compare to that, and to 50 digits exactly.
    assert geo.WGS84_E2 == pytest.approx(6.69437999014e-3, abs=5e-15)
    assert geo.WGS84_EP2 == pytest.approx(6.73949674228e-3, abs=5e-15)
    assert geo.WGS84_E2 == pytest.approx(float(E2_MP), rel=2e-16)
    assert geo.WGS84_EP2 == pytest.approx(float(E2_MP / (1 - E2_MP)), rel=2e-16)
    assert geo.OMEGA_E == 7.292115e-5
    assert geo.WGS84_B == pytest.approx(float(B_MP), rel=1e-16)


# --- llh2ecef ---------------------------------------------------------------------------------

def test_llh2ecef_known_values():
    # By definition of the ellipsoid: the equator at lon 0 and 90 deg, and the poles.
    assert geo.llh2ecef(0.0, 0.0, 0.0) == (geo.WGS84_A, 0.0, 0.0)
    x, y, z = geo.llh2ecef(0.0, math.pi / 2, 100.0)
    assert (abs(x), y, z) == pytest.approx((0.0, geo.WGS84_A + 100.0, 0.0), abs=1e-9)
    x, y, z = geo.llh2ecef(-math.pi / 2, 0.0, -10.0)
    assert (abs(x), y, z) == pytest.approx((0.0, 0.0, -geo.WGS84_B + 10.0), abs=1e-9)


@settings(max_examples=60, deadline=None)
@given(lat=st.floats(-math.pi / 2, math.pi / 2), lon=st.floats(-math.pi, math.pi),
       h=st.floats(-5e6, 1e8))
def test_llh2ecef_against_mpmath(lat, lon, h):
    p = geo.llh2ecef(lat, lon, h)
    p_vec = geo.llh2ecef(np.array([lat]), np.array([lon]), np.array([h]))[0]
    q = [float(c) for c in mp_llh2ecef(lat, lon, h)]
    # About six roundings (sin, cos, sqrt, the sum n + h, two products): up to ~3 ulp of |p|,
    # i.e. 4 nm x r/a; 2 nm failed by 2 ulp at h = 8.3e7 m (lat = lon = 0.198) on both bodies.
    tol = 4 * NM * scale(q)
    assert np.allclose(p, q, rtol=0, atol=tol)
    assert np.allclose(p_vec, q, rtol=0, atol=tol)


def test_llh2ecef_against_pyproj():
    rng = np.random.default_rng(1)
    lat = rng.uniform(-math.pi / 2, math.pi / 2, 500)
    lon = rng.uniform(-math.pi, math.pi, 500)
    h = rng.uniform(-1e4, 1e5, 500)
    fwd = pyproj.Transformer.from_crs('EPSG:4979', 'EPSG:4978', always_xy=True)
    ref = np.stack(fwd.transform(np.degrees(lon), np.degrees(lat), h), axis=-1)
    # Degree round-off (1e-16 relative of the angle) is well below this tolerance.
    assert np.max(np.abs(geo.llh2ecef(lat, lon, h) - ref)) < 1e-7


def test_llh2ecef_broadcasts_and_shapes():
    lat = np.zeros((4, 1))
    lon = np.linspace(-3, 3, 5)
    assert geo.llh2ecef(lat, lon, 0.0).shape == (4, 5, 3)
    assert geo.llh2ecef(np.float64(0.1), 0.2, 0.3) == geo.llh2ecef(0.1, 0.2, 0.3)
    # A 0-d array is a scalar (vessel_kinematics.core.dispatch): a tuple of floats, the same bits.
    p0 = geo.llh2ecef(np.array(0.1), 0.2, 0.3)
    assert isinstance(p0, tuple) and p0 == geo.llh2ecef(0.1, 0.2, 0.3)
    assert geo.llh2ecef(np.array([0.1]), 0.2, 0.3).shape == (1, 3)


# --- ecef2llh ---------------------------------------------------------------------------------

@settings(max_examples=80, deadline=None)
@given(lat=st.floats(-math.pi / 2, math.pi / 2), lon=st.floats(-math.pi, math.pi),
       h=st.floats(-5e6, 1e8))
def test_ecef2llh_against_mpmath(lat, lon, h):
    p = [float(c) for c in mp_llh2ecef(lat, lon, h)]
    check_reverse(p)


@settings(max_examples=30, deadline=None)
@given(x=st.floats(-6e4, 6e4), y=st.floats(-6e4, 6e4), z=st.floats(-6e4, 6e4))
def test_ecef2llh_near_the_centre_against_mpmath(x, y, z):
    # Inside and around the evolute (|r| < a e^2 = 42.7 km, |z| < 42.9 km): several normals.
    check_reverse([x, y, z])


EDGE_POINTS = [
    (0.0, 0.0, 0.0),                         # the centre: the north pole, h = -b
    (0.0, 0.0, -0.0),
    (0.0, 0.0, float(B_MP)),                 # exactly the north pole
    (0.0, 0.0, -float(B_MP)),
    (-0.0, 0.0, 1e3),                        # polar axis, inside
    (0.0, -0.0, -3e6),
    (0.0, 0.0, 1e8),                         # polar axis, far
    (geo.WGS84_A, 0.0, 0.0),                 # equator
    (-geo.WGS84_A, 0.0, 0.0),                # equator at lon = 180 deg
    (1e3, 0.0, 0.0),                         # equatorial plane inside the evolute
    (4.2e4, 1e3, 0.0),
    (4.2e4, 1e3, 1e-3),
    (4.3e4, 0.0, 0.0),                       # just outside the evolute's cusp (a e^2)
    (1e-300, 0.0, 1e-300),                   # tiny
    (5e-324, 5e-324, 0.0),                   # denormal
    (1.378e6, 0.0, 1.0),                     # 5000 km deep at the equator
    (0.0, 1.4e6, 1.4e6),
    (1e8, -1e8, 3e7),                        # far
    (-1e8 - 6e6, 0.0, 0.0),
    (1e5, 1e5, 1e5),
]


def test_ecef2llh_batch_mixing_every_branch_equals_the_math_path():
    # One array holding NaN, far, interior, axis and ordinary points: the numpy path decides
    # its branches per element (and skips them by reductions), the math kernel of ned2llh
    # (geo._ecef2llh_scalar) per point.
    points = EDGE_POINTS + [(math.nan, 1.0, 1.0), (1e300, -1e300, 1.0), (2e6, 3e6, -5e6),
                            (1.0, 2.0, math.nan), (-3e6, -0.0, 1e6)]
    for order in (points, points[::-1]):
        lat_v, lon_v, h_v = geo.ecef2llh(np.array(order))
        for i, p in enumerate(order):
            lat, lon, h = geo._ecef2llh_scalar(*p)
            assert lat_v[i] == pytest.approx(lat, abs=1e-15, nan_ok=True)
            assert lon_v[i] == pytest.approx(lon, abs=1e-15, nan_ok=True)
            assert h_v[i] == pytest.approx(h, abs=1e-8, rel=1e-15, nan_ok=True)
    assert [v.shape for v in geo.ecef2llh(np.zeros((0, 3)))] == [(0,)] * 3
    assert [v.shape for v in geo.ecef2llh(np.ones((2, 5, 3)) * 7e6)] == [(2, 5)] * 3


@pytest.mark.parametrize('p', EDGE_POINTS)
def test_ecef2llh_edge_cases_against_mpmath(p):
    check_reverse(list(p))


def test_ecef2llh_exact_poles_and_axis():
    lat, lon, h = geo.ecef2llh((0.0, 0.0, geo.WGS84_B + 5.0))
    assert (lat, lon, h) == (math.pi / 2, 0.0, pytest.approx(5.0, abs=1e-9))
    lat, lon, h = geo.ecef2llh(np.array([[0.0, 0.0, -geo.WGS84_B - 5.0]]))
    assert (lat[0], lon[0]) == (-math.pi / 2, 0.0)
    assert h[0] == pytest.approx(5.0, abs=1e-9)
    # The pole of llh2ecef comes back as the exact pole.
    assert geo.ecef2llh(geo.llh2ecef(math.pi / 2, 1.0, 100.0))[0] == pytest.approx(
        math.pi / 2, abs=1e-15)


def test_ecef2llh_longitude_wrapped_to_half_open_interval():
    assert geo.ecef2llh((-geo.WGS84_A, -0.0, 0.0))[1] == math.pi
    assert geo.ecef2llh(np.array([[-geo.WGS84_A, -0.0, 0.0]]))[1][0] == math.pi
    assert geo.ecef2llh((-geo.WGS84_A, -1e-3, 0.0))[1] < 0.0


def test_ecef2llh_huge_inputs():
    for p in ((1e300, 1e300, 1e300), (1e30, 0.0, -1e30), (1e308, 1e308, 0.0)):
        lat, lon, h = geo.ecef2llh(p)
        assert lat == pytest.approx(math.atan2(p[2], math.hypot(p[0], p[1])), abs=1e-15)
        assert lon == pytest.approx(math.atan2(p[1], p[0]), abs=1e-15)
        assert h == pytest.approx(math.hypot(*p), rel=1e-15)
        lat_v, lon_v, h_v = geo.ecef2llh(np.array([p]))
        assert (lat_v[0], lon_v[0], h_v[0]) == (lat, lon, pytest.approx(h, rel=1e-15))


def test_nan_in_nan_out():
    nan = math.nan
    assert all(math.isnan(v) for v in geo.ecef2llh((nan, 1.0, 2.0)))
    assert all(np.isnan(v).all() for v in geo.ecef2llh(np.array([[1e6, nan, 0.0]] * 2)))
    assert all(math.isnan(v) for v in geo.llh2ecef(nan, 0.1, 0.0))
    assert np.isnan(geo.llh2ecef(np.array([0.1]), np.array([nan]), 0.0)).any()
    assert all(math.isnan(v) for v in geo.llh2ned(nan, 0.1, 0.0, 0.1, 0.1, 0.0))
    assert all(math.isnan(v) for v in geo.ned2llh((nan, 0.0, 0.0), 0.1, 0.1, 0.0))
    assert math.isnan(geo.llh2flat(0.1, nan, 0.0, 0.1, 0.1, 0.0)[1])
    assert math.isnan(geo.flat2llh((0.0, nan, 0.0), 0.1, 0.1, 0.0)[1])
    assert np.isnan(geo.llh2flat(np.array([0.1]), np.array([nan]), 0.0, 0.1, 0.1, 0.0)[0, 1])
    ned = geo.llh2ned(np.array([0.1, nan]), 0.1, 0.0, 0.1, 0.1, 0.0)
    assert np.isfinite(ned[0]).all() and np.isnan(ned[1]).all()


@settings(max_examples=50, deadline=None)
@given(lat=st.floats(-1.55, 1.55), lon=st.floats(-math.pi, math.pi), h=st.floats(-1e4, 1e5))
def test_ecef2llh_fossen_agrees_near_the_surface(lat, lon, h):
    p = geo.llh2ecef(lat, lon, h)
    ref = geo.ecef2llh(p)
    got = geo.ecef2llh_fossen(np.array(p), tol=1e-13)
    assert got[0] == pytest.approx(ref[0], abs=1e-13)
    assert ssa(got[1] - ref[1]) == pytest.approx(0.0, abs=1e-15)
    assert got[2] == pytest.approx(ref[2], abs=1e-6)


def test_ecef2llh_fossen_fails_where_documented():
    # Far from the surface the textbook iteration is not accurate to round-off (here: at the
    # pole, where it divides by cos(lat) ~ 6e-17): the reason ecef2llh uses the closed form.
    p = (0.0, 0.0, geo.WGS84_B + 100.0)
    assert geo.ecef2llh(p)[2] == pytest.approx(100.0, abs=1e-9)
    h_fossen = geo.ecef2llh_fossen(np.array(p))[2]
    assert not abs(h_fossen - 100.0) <= 1e-6      # wrong or NaN


def test_ecef2llh_vs_pyproj_and_pymap3d_near_the_surface():
    rng = np.random.default_rng(2)
    lat = rng.uniform(-math.pi / 2, math.pi / 2, 300)
    lon = rng.uniform(-math.pi, math.pi, 300)
    h = rng.uniform(-1e3, 1e4, 300)
    p = geo.llh2ecef(lat, lon, h)
    got = geo.ecef2llh(p)
    inv = pyproj.Transformer.from_crs('EPSG:4978', 'EPSG:4979', always_xy=True)
    lon_p, lat_p, h_p = inv.transform(p[:, 0], p[:, 1], p[:, 2])
    assert np.max(np.abs(got[2] - h_p)) < 1e-6
    assert np.max(np.abs(got[0] - np.radians(lat_p))) < 1e-12     # PROJ: ~1e-13 rad
    lat_m, lon_m, h_m = pymap3d.ecef2geodetic(p[:, 0], p[:, 1], p[:, 2], deg=False)
    assert np.max(np.abs(got[2] - h_m)) < 1e-6
    assert np.max(np.abs(got[0] - lat_m)) < 1e-13


# --- rll, NED ---------------------------------------------------------------------------------

@settings(max_examples=50, deadline=None)
@given(lat=st.floats(-math.pi / 2, math.pi / 2), lon=st.floats(-4.0, 4.0))
def test_rll_in_so3_and_against_pymap3d(lat, lon):
    rot = geo.rll(lon, lat)
    assert np.allclose(rot @ rot.T, np.eye(3), atol=1e-15)
    assert np.linalg.det(rot) == pytest.approx(1.0, abs=1e-15)
    assert np.allclose(geo.rll(np.array([lon]), np.array([lat]))[0], rot, atol=1e-16)
    # Columns: north, east, down in ECEF; pymap3d.enu2uvw rotates ENU vectors to ECEF.
    for ned, enu in (((1, 0, 0), (0, 1, 0)), ((0, 1, 0), (1, 0, 0)), ((0, 0, 1), (0, 0, -1))):
        uvw = pymap3d.enu2uvw(*enu, lat, lon, deg=False)
        assert np.allclose(rot @ np.array(ned, float), uvw, atol=1e-15)


def test_velocity_rotation_round_trip_and_scalar_path():
    v = (1.0, -2.0, 0.5)
    lat, lon = 0.9, -2.5
    v_e = geo.ned2ecef_velocity(v, lat, lon)
    assert isinstance(v_e, tuple)
    assert np.allclose(v_e, geo.rll(lon, lat) @ np.array(v), atol=1e-15)
    assert np.allclose(geo.ecef2ned_velocity(v_e, lat, lon), v, atol=1e-15)
    v_arr = geo.ned2ecef_velocity(np.array([v] * 3), lat, lon)
    assert v_arr.shape == (3, 3) and np.allclose(v_arr[2], v_e, atol=1e-15)
    # Transport: same vector in ECEF before and after changing the NED axes.
    v_0 = geo.rotate_ned(v, lat, lon, 0.1, 0.2)
    assert np.allclose(geo.ned2ecef_velocity(v_0, 0.1, 0.2), v_e, atol=1e-15)
    assert np.allclose(geo.rotate_ned(np.array(v), lat, lon, 0.1, 0.2), v_0, atol=1e-15)
    assert np.allclose(geo.rotate_ned(v, lat, lon, lat, lon), v, atol=1e-15)


@settings(max_examples=60, deadline=None)
@given(lat0=st.floats(-1.5, 1.5), lon0=st.floats(-math.pi, math.pi), h0=st.floats(-100, 1e3),
       north=st.floats(-5e4, 5e4), east=st.floats(-5e4, 5e4), down=st.floats(-1e3, 1e3))
def test_ned_against_pymap3d_and_round_trips(lat0, lon0, h0, north, east, down):
    lat, lon, h = geo.ned2llh((north, east, down), lat0, lon0, h0)
    lat_m, lon_m, h_m = pymap3d.ned2geodetic(north, east, down, lat0, lon0, h0, deg=False)
    assert lat == pytest.approx(lat_m, abs=1e-12)
    assert ssa(lon - lon_m) == pytest.approx(0.0, abs=1e-12)
    assert h == pytest.approx(h_m, abs=1e-5)       # pymap3d's reverse is good to ~1 um here
    assert -math.pi < lon <= math.pi
    ned = geo.llh2ned(lat, lon, h, lat0, lon0, h0)
    assert np.allclose(ned, (north, east, down), rtol=0, atol=1e-8)
    ned_m = pymap3d.geodetic2ned(lat, lon, h, lat0, lon0, h0, deg=False)
    assert np.allclose(ned, ned_m, rtol=0, atol=1e-8)
    # numpy paths agree with the math paths
    ned_v = geo.llh2ned(np.array([lat]), np.array([lon]), np.array([h]), lat0, lon0, h0)
    assert np.allclose(ned_v[0], ned, rtol=0, atol=1e-8)
    llh_v = geo.ned2llh(np.array([[north, east, down]]), lat0, lon0, h0)
    # (the two paths may round differently: a few nm in h, as any closed form near the surface)
    assert np.allclose([llh_v[0][0], llh_v[1][0]], [lat, lon], rtol=0, atol=1e-15)
    assert llh_v[2][0] == pytest.approx(h, abs=1e-8)
    p = geo.ned2ecef((north, east, down), lat0, lon0, h0)
    assert np.allclose(geo.ecef2ned(p, lat0, lon0, h0), (north, east, down), atol=1e-8)
    assert np.allclose(geo.ecef2ned(np.array(p), lat0, lon0, h0), (north, east, down),
                       atol=1e-8)


def test_ned2llh_across_the_antimeridian():
    lat0, lon0 = math.radians(-17.0), math.radians(179.99)
    lat, lon, h = geo.ned2llh((0.0, 5000.0, 0.0), lat0, lon0, 0.0)
    assert -math.pi < lon < -math.radians(179.9)
    lat_m, lon_m, _ = pymap3d.ned2geodetic(0.0, 5000.0, 0.0, lat0, lon0, 0.0, deg=False)
    assert ssa(lon - lon_m) == pytest.approx(0.0, abs=1e-12)
    assert geo.llh2ned(lat, lon, h, lat0, lon0, 0.0)[1] == pytest.approx(5000.0, abs=1e-8)
    lats, lons, _ = geo.ned2llh(np.array([[0.0, 5000.0, 0.0], [0.0, -5000.0, 0.0]]),
                                lat0, lon0, 0.0)
    assert lons[0] < 0.0 < lons[1] <= math.pi


def test_ned_at_the_pole():
    # Origin at the exact north pole: NED is defined by R_n^e(lon0, pi/2), north along -x
    # for lon0 = 0.
    ned = geo.llh2ned(math.radians(89.0), 0.0, 0.0, math.pi / 2, 0.0, 0.0)
    assert ned[0] < -1e5 and abs(ned[1]) < 1e-6 and ned[2] > 0.0
    back = geo.ned2llh(ned, math.pi / 2, 0.0, 0.0)
    assert back[0] == pytest.approx(math.radians(89.0), abs=1e-14)


# --- flat earth -------------------------------------------------------------------------------

def test_flat_earth_matches_tangent_plane_within_documented_errors():
    table = geo._flat_error_table(lats_deg=(0.0, 45.0, 60.0, 80.0), n_bearings=36)
    # The docstring table, to its printed precision (maxima over the same latitudes).
    documented = {100.0: (5.1e-3, 7.9e-4), 1e3: (0.51, 0.079), 1e4: (51.0, 7.9),
                  1e5: (5270.0, 789.0)}
    for d, horizontal, vertical in table:
        h_doc, v_doc = documented[d]
        assert horizontal == pytest.approx(h_doc, rel=0.05)
        assert vertical == pytest.approx(v_doc, rel=0.05)


@settings(max_examples=60, deadline=None)
@given(lat0=st.floats(-1.4, 1.4), lon0=st.floats(-math.pi, math.pi), h0=st.floats(-10, 100),
       north=st.floats(-1e4, 1e4), east=st.floats(-1e4, 1e4), down=st.floats(-50, 50))
def test_flat_round_trip_and_radii(lat0, lon0, h0, north, east, down):
    lat, lon, h = geo.flat2llh((north, east, down), lat0, lon0, h0)
    assert -math.pi < lon <= math.pi
    flat = geo.llh2flat(lat, lon, h, lat0, lon0, h0)
    assert np.allclose(flat, (north, east, down), rtol=0, atol=1e-7)
    flat_v = geo.llh2flat(np.array([lat]), np.array([lon]), h, lat0, lon0, h0)
    assert np.allclose(flat_v[0], flat, rtol=0, atol=1e-8)
    llh_v = geo.flat2llh(np.array([[north, east, down]]), lat0, lon0, h0)
    assert np.allclose([v[0] for v in llh_v], [lat, lon, h], rtol=0, atol=1e-12)
    # Radii (Fossen 2.105-2.106) against the mpmath definitions.
    s2 = MP.sin(MP.mpf(lat0)) ** 2
    r_e = A_MP / MP.sqrt(1 - E2_MP * s2)
    r_n = A_MP * (1 - E2_MP) / (1 - E2_MP * s2) ** MP.mpf(1.5)
    assert geo.radius_prime_vertical(lat0) == pytest.approx(float(r_e), rel=1e-15)
    assert geo.radius_meridian(lat0) == pytest.approx(float(r_n), rel=1e-15)
    assert geo.radius_meridian(np.array([lat0]))[0] == pytest.approx(float(r_n), rel=1e-15)


def test_flat_across_the_antimeridian():
    lat0, lon0 = math.radians(-17.0), math.radians(179.999)
    lon = math.radians(-179.999)
    x, y, z = geo.llh2flat(lat0, lon, 5.0, lat0, lon0, 0.0)
    expected = math.radians(0.002) * geo.radius_prime_vertical(lat0) * math.cos(lat0)
    assert y == pytest.approx(expected, rel=1e-9)
    assert (x, z) == (0.0, -5.0)
    flat = geo.llh2flat(np.array([lat0]), np.array([lon]), 5.0, lat0, lon0, 0.0)
    assert flat[0, 1] == pytest.approx(expected, rel=1e-9)
    back = geo.flat2llh((0.0, y, -5.0), lat0, lon0, 0.0)
    assert back[1] == pytest.approx(lon, abs=1e-14)
    back_v = geo.flat2llh(np.array([[0.0, y, -5.0], [0.0, -y, 0.0]]), lat0, lon0, 0.0)
    assert back_v[1][0] == pytest.approx(lon, abs=1e-14) and back_v[1][1] > 3.0


def test_ecef2llh_denormal_heights_on_the_axis():
    # e^4 q denormal (z ~ 1e-150 m near the centre): the equatorial-plane limit, exact, in the
    # math kernel and the numpy body alike (the general formula was 0.83 m off here).
    for p in ((0.0, 0.0, 2.678156692201906e-150), (1e-140, 3e-141, -2e-150)):
        lat, lon, h = geo.ecef2llh(p)
        assert h == pytest.approx(-geo.WGS84_B, abs=1e-8)
        assert lat == math.copysign(math.pi / 2, p[2])
        lat_v, lon_v, h_v = geo.ecef2llh(np.array([p]))
        assert (lat_v[0], lon_v[0]) == (lat, lon) and h_v[0] == pytest.approx(h, abs=1e-8)

"""
Transformations between ECEF, geodetic (LLH), NED and flat-earth coordinates (Fossen 2.3).

Fossen, *Handbook of Marine Craft Hydrodynamics and Motion Control*, 2nd ed., Section 2.3. The
WGS-84 ellipsoid is defined once below from its two defining numbers (a, 1/f); every other
constant is derived from them. Latitude ``lat`` (mu in Fossen) and longitude ``lon`` (l in
Fossen) are in radians, heights and positions in metres, velocities in m/s. Longitudes returned
by this module are wrapped to (-pi, pi].

Input conventions, shared by every function (the rule of :mod:`vessel_kinematics.core.dispatch`):

* numpy arrays broadcast over leading axes: points are ``(..., 3)`` arrays, angles ``(...)``;
  the result is a float64 numpy array (or a tuple of arrays).
* A one-point call (every angle and height a Python/numpy scalar or 0-d array, every point a
  3-sequence or a ``(3,)`` array) returns plain floats: a ``tuple`` of three floats where a
  batch gives a ``(..., 3)`` array (wrap it in ``numpy.asarray`` for vector arithmetic).
  :func:`rll` always returns an ndarray (a matrix).
* :func:`llh2ned`, :func:`ned2llh`, :func:`llh2flat` and :func:`flat2llh` keep a pure-Python
  :mod:`math` body for the estimator's per-message calls (``bench/bench_geodesy.py``); every
  other function has one numpy body.
* NaN in gives NaN out, never an exception.

ECEF to LLH (:func:`ecef2llh`) uses Vermeille's closed-form solution (H. Vermeille, "An
analytical method to transform geocentric into geodetic coordinates", J. Geodesy 85, 2011) in
the formulation of C. F. F. Karney's GeographicLib (``Geocentric::IntReverse``), including its
treatment of the polar axis, of the interior of the evolute near the centre and of very distant
points. It is accurate to round-off everywhere: the test suite checks it against a 50-digit
mpmath solution of the foot-point problem from 5000 km below the surface to 1e8 m above it,
at the exact poles, on the equator and on the polar axis (measured worst case 2.6 nm x
max(1, r/a) for the reverse alone, 3.3 nm for the round trip; ``bench/bench_geodesy.py``).
:func:`ecef2llh_fossen` is the textbook iteration (Fossen
Section 2.3.1, MSS ``ecef2llh``), kept for reference: it divides by cos(lat), so it returns
wrong heights or NaN at and near the poles, and it is not meant for the earth's interior.

Flat-earth navigation (:func:`llh2flat`, :func:`flat2llh`, Fossen eqs. 2.105-2.108) scales
latitude and longitude differences by the meridian radius R_N and the prime-vertical radius R_E
at the origin, and takes z = h0 - h. Its error against the exact tangent plane
(:func:`llh2ned`), the maximum over 72 bearings for a point at horizontal tangent-plane
distance d at the origin's height (computed by ``_flat_error_table``; m):

======  =========  =========  =========  =========  =============
  d     horizontal error at origin latitude            vertical
------  ---------------------------------------------  -------------
  m     0 deg      45 deg     60 deg     80 deg        (all lat)
======  =========  =========  =========  =========  =============
100     8.4e-9     9.1e-4     1.6e-3     5.1e-3     7.9e-4
1 k     8.4e-6     0.091      0.16       0.51       0.079
10 k    8.4e-3     9.1        16         51         7.9
100 k   8.4        910        1580       5270       789
======  =========  =========  =========  =========  =============

The vertical error is the earth's curvature d^2 / (2 R) that the flat model ignores (z = h0 -
h); the horizontal error grows as d^2 tan(lat0) / R (the meridians converge towards the pole,
which the constant east scale R_E cos(lat0) ignores). Use the exact tangent plane
(``llh2ned``) beyond a few kilometres.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from vessel_kinematics.core.dispatch import FloatArray, is_point, one_point, to_output
from vessel_kinematics.core.frames import ssa

__all__ = ['OMEGA_E', 'WGS84_A', 'WGS84_B', 'WGS84_E2', 'WGS84_EP2', 'WGS84_F', 'WGS84_INV_F',
           'ecef2llh', 'ecef2llh_fossen', 'ecef2ned', 'ecef2ned_velocity', 'flat2llh',
           'llh2ecef', 'llh2flat', 'llh2ned', 'ned2ecef', 'ned2ecef_velocity', 'ned2llh',
           'radius_meridian', 'radius_prime_vertical', 'rll', 'rotate_ned']

# --- WGS-84 (NIMA TR8350.2): the two defining numbers, everything else derived. -----------
#: Semi-major axis a (m).
WGS84_A = 6378137.0
#: Inverse flattening 1/f.
WGS84_INV_F = 298.257223563
#: Flattening f = (a - b) / a.
WGS84_F = 1.0 / WGS84_INV_F
#: Semi-minor axis b = a (1 - f) (m).
WGS84_B = WGS84_A * (1.0 - WGS84_F)
#: First eccentricity squared e^2 = f (2 - f).
WGS84_E2 = WGS84_F * (2.0 - WGS84_F)
#: Second eccentricity squared e'^2 = e^2 / (1 - e^2).
WGS84_EP2 = WGS84_E2 / (1.0 - WGS84_E2)
#: Earth rotation rate omega_e (rad/s) (WGS-84; Fossen Section 2.3).
OMEGA_E = 7.292115e-5

_E2M = (1.0 - WGS84_F) ** 2          # 1 - e^2
_E4 = WGS84_E2 * WGS84_E2            # e^4
_MAXRAD = 2.0 * WGS84_A / np.finfo(float).eps   # beyond this, treat the earth as a point
#: e^4 q below this (|z| < ~1e-136 m) is the equatorial-plane limit: GeographicLib tests
#: e^4 q == 0, but for denormal e^4 q the general formula loses its digits (h off by 0.8 m
#: at z = 2.7e-150 m on the polar axis), while the limit is exact to round-off there.
_E4Q_TINY = 1e-290
_PI = math.pi
_TWO_PI = 2.0 * math.pi
_sin, _cos, _sqrt, _hypot = math.sin, math.cos, math.sqrt, math.hypot
_atan2, _cbrt = math.atan2, math.cbrt


def _floats(*values: Any) -> tuple[float, ...]:
    """Return scalars as Python floats (exact; the entry of the math bodies)."""
    return tuple(float(v) for v in values)


def radius_prime_vertical(lat: Any) -> Any:
    """
    Return the prime-vertical radius of curvature R_E(lat) = a / sqrt(1 - e^2 sin^2 lat) (m).

    Fossen eq. 2.105 (R_E; N in many geodesy texts, ``Rn`` in the MSS code).
    """
    s = np.sin(np.asarray(lat, dtype=float))
    return to_output(WGS84_A / np.sqrt(1.0 - WGS84_E2 * s * s), one_point(lat))


def radius_meridian(lat: Any) -> Any:
    """
    Return the meridian radius of curvature R_N(lat) = a (1 - e^2) / (1 - e^2 sin^2 lat)^1.5 (m).

    Fossen eq. 2.106 (R_N; M in many geodesy texts, ``Rm`` in the MSS code).
    """
    s = np.sin(np.asarray(lat, dtype=float))
    w = 1.0 - WGS84_E2 * s * s
    return to_output(WGS84_A * _E2M / (w * np.sqrt(w)), one_point(lat))


# --- geodetic <-> ECEF -------------------------------------------------------------------------

def _llh2ecef_scalar(lat: float, lon: float, h: float) -> tuple[float, float, float]:
    """Return (x, y, z) of floats (the math kernel of the per-message bodies)."""
    slat = _sin(lat)
    n = WGS84_A / _sqrt(1.0 - WGS84_E2 * slat * slat)
    t = (n + h) * _cos(lat)
    return t * _cos(lon), t * _sin(lon), (n * _E2M + h) * slat


def llh2ecef(lat: Any, lon: Any, h: Any) -> Any:
    """
    Return the ECEF position of geodetic latitude, longitude (rad) and ellipsoidal height (m).

    Fossen Section 2.3.1: x = (R_E + h) cos(lat) cos(lon), y = (R_E + h) cos(lat) sin(lon),
    z = (R_E (1 - e^2) + h) sin(lat). Array inputs broadcast and give a ``(..., 3)`` array (m);
    scalars give a tuple ``(x, y, z)`` of floats.
    """
    one = one_point(lat, lon, h)
    lat, lon, h = np.broadcast_arrays(np.asarray(lat, dtype=float), np.asarray(lon, dtype=float),
                                      np.asarray(h, dtype=float))
    shape = lat.shape
    if not shape:  # 0-d: numpy returns scalars, not arrays, from 0-d arithmetic
        lat, lon, h = lat.reshape(1), lon.reshape(1), h.reshape(1)
    slat = np.sin(lat)
    clat = np.cos(lat)
    # n = a / sqrt(1 - e^2 sin^2 lat), built in place to limit temporaries.
    n = slat * slat
    n *= -WGS84_E2
    n += 1.0
    np.sqrt(n, out=n)
    np.divide(WGS84_A, n, out=n)
    out = np.empty(lat.shape + (3,))
    t = n + h
    t *= clat
    np.multiply(t, np.cos(lon), out=out[..., 0])
    np.multiply(t, np.sin(lon), out=out[..., 1])
    n *= _E2M
    n += h
    np.multiply(n, slat, out=out[..., 2])
    return to_output(out.reshape(shape + (3,)), one)


def _llh2ecef_array(lat: Any, lon: Any, h: Any) -> FloatArray:
    """Return llh2ecef as a float64 array (..., 3) for any input (internal)."""
    return np.asarray(llh2ecef(np.atleast_1d(np.asarray(lat, dtype=float)), lon, h)).reshape(
        np.broadcast_shapes(np.shape(lat), np.shape(lon), np.shape(h)) + (3,))


def _ecef2llh_scalar(x: float, y: float, z: float) -> tuple[float, float, float]:
    """Return (lat, lon, h) of floats: the math twin of ecef2llh (the kernel of ned2llh)."""
    # The math-path twin of the numpy code in ecef2llh (GeographicLib Geocentric::IntReverse).
    # NaN propagates through every branch (comparisons with NaN are False), no test needed.
    r = _hypot(x, y)
    lon = _atan2(y, x) if r != 0.0 else 0.0
    if lon == -_PI:
        lon = _PI
    if r > _MAXRAD or z > _MAXRAD or z < -_MAXRAD:
        # Far beyond the ellipsoid (or overflowing): the earth is a point (GeographicLib).
        return _atan2(0.5 * z, _hypot(0.5 * x, 0.5 * y)), lon, _hypot(r, z)
    p = r / WGS84_A
    p *= p
    q = z / WGS84_A
    q *= _E2M * q
    rr = (p + q - _E4) / 6.0
    e4q = _E4 * q
    if e4q < _E4Q_TINY and rr <= 0.0:
        # Equatorial plane inside the evolute (|r| <= a e^2): limit of the general formula.
        zz = _sqrt((_E4 - p) / _E2M)
        xx = _sqrt(p)
        lat = _atan2(zz, xx)
        return (-lat if z < 0.0 else lat), lon, -WGS84_A * _E2M / WGS84_E2 * _hypot(zz, xx)
    s = 0.25 * e4q * p
    r2 = rr * rr
    r3 = rr * r2
    disc = s * (2.0 * r3 + s)
    if disc >= 0.0:
        t3 = s + r3
        # Sign of the square root chosen to maximise |t3| (no cancellation).
        t3 += -_sqrt(disc) if t3 < 0.0 else _sqrt(disc)
        t = _cbrt(t3)
        u = rr + t + (r2 / t if t != 0.0 else 0.0)
    else:
        # Three real roots (inside the evolute, rr < 0): the one free of cancellation.
        u = rr + 2.0 * rr * _cos(_atan2(_sqrt(-disc), -(s + r3)) / 3.0)
    v = _sqrt(u * u + e4q)
    uv = e4q / (v - u) if u < 0.0 else u + v
    w = WGS84_E2 * (uv - q) / (2.0 * v)
    if w < 0.0:
        w = 0.0
    k = uv / (_sqrt(uv + w * w) + w)
    k2 = k + WGS84_E2
    return _atan2(z * k2, r * k), lon, (1.0 - _E2M / k) * _hypot(k * r / k2, z)


def ecef2llh(p: Any) -> tuple[Any, Any, Any]:
    """
    Return geodetic (lat, lon, h) in (rad, rad, m) of ECEF positions ``p`` (..., 3) (m).

    The inverse of :func:`llh2ecef` (Fossen 2.3.1) by Vermeille's closed form as implemented in
    GeographicLib's ``Geocentric::IntReverse`` (Karney): a cubic resolvent solved without
    cancellation, then the foot point and height. Accurate to round-off everywhere, including
    the exact poles (lat = +-pi/2), the polar axis (x = y = 0, where lon = 0 by convention),
    the equator, points deep inside the earth (inside the evolute, the nearest surface point
    is returned; on the equatorial plane the northern one for z >= +0) and points far away.
    lon is wrapped to (-pi, pi].
    """
    one = is_point(p, 3)
    pts = np.asarray(p, dtype=float)
    if pts.shape[-1:] != (3,):
        raise ValueError(f'p must have shape (..., 3), got {pts.shape}')
    lat, lon, h = _ecef2llh_array(pts.reshape(1, 3) if pts.ndim == 1 else pts)
    if pts.ndim == 1:
        lat, lon, h = lat[0], lon[0], h[0]
    return to_output((lat, lon, h), one)


def _ecef2llh_array(p: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Return (lat, lon, h) arrays of ECEF points (n..., 3) (the one numpy body)."""
    x = p[..., 0]
    y = p[..., 1]
    z = p[..., 2]
    if x.size == 0:
        return np.empty(x.shape), np.empty(x.shape), np.empty(x.shape)
    with np.errstate(invalid='ignore', divide='ignore', over='ignore', under='ignore'):
        # r = sqrt(x^2 + y^2) rather than hypot (3x faster; within an ulp). Overflow (|x| >
        # 1e154) lands in the far branch below, which recomputes with hypot.
        r = x * x
        r += y * y
        np.sqrt(r, out=r)
        lon = np.arctan2(y, x)
        lon[lon == -_PI] = _PI
        if not r.min() > 0.0:  # (written so that NaN also enters)
            lon[(x == 0.0) & (y == 0.0)] = 0.0     # the polar axis: lon = 0 by convention
        pp = r / WGS84_A
        pp *= pp
        q = z / WGS84_A
        q *= q
        q *= _E2M
        rr = pp + q
        rr -= _E4
        rr *= 1.0 / 6.0
        # Only points within ~43 km of the centre (rr <= 0, around the evolute) can take the
        # inner, negative-u, t = 0 and equatorial-limit branches: one reduction skips them all.
        interior = not rr.min() > 0.0
        e4q = q * _E4
        s = pp * e4q
        s *= 0.25
        r2 = rr * rr
        r3 = rr * r2
        disc = 2.0 * r3
        disc += s
        disc *= s
        t3 = s + r3
        u = np.sqrt(disc)
        np.copysign(u, t3, out=u)
        t3 += u
        t = np.cbrt(t3, out=t3)
        np.divide(r2, t, out=u)
        if interior:
            u[t == 0.0] = 0.0
        u += t
        u += rr
        if interior:
            # Three real roots (inside the evolute): take the one free of cancellation.
            inner = disc < 0.0
            ri = rr[inner]
            ang = np.arctan2(np.sqrt(-disc[inner]), -(s[inner] + r3[inner]))
            u[inner] = ri + 2.0 * ri * np.cos(ang / 3.0)
        v = np.multiply(u, u, out=r2)
        v += e4q
        np.sqrt(v, out=v)
        uv = np.add(u, v, out=r3)
        if interior:
            negative = u < 0.0
            uv[negative] = e4q[negative] / (v[negative] - u[negative])
        w = np.subtract(uv, q, out=disc)
        w *= WGS84_E2 / 2.0
        w /= v
        np.maximum(w, 0.0, out=w)
        k = np.multiply(w, w, out=s)
        k += uv
        np.sqrt(k, out=k)
        k += w
        np.divide(uv, k, out=k)
        k2 = np.add(k, WGS84_E2, out=t)
        lat = np.arctan2(z * k2, r * k)
        d = np.multiply(k, r, out=uv)
        d /= k2
        h = np.multiply(d, d, out=d)
        h += z * z
        np.sqrt(h, out=h)
        np.divide(_E2M, k, out=k)
        np.subtract(1.0, k, out=k)
        h *= k
        special = (e4q < _E4Q_TINY) & (rr <= 0.0) if interior else None
        if special is not None and special.any():
            # Equatorial plane inside the evolute: limit of the general formula.
            ps = pp[special]
            zz = np.sqrt((_E4 - ps) / _E2M)
            xx = np.sqrt(ps)
            lat[special] = np.where(z[special] < 0.0, -1.0, 1.0) * np.arctan2(zz, xx)
            h[special] = -WGS84_A * _E2M / WGS84_E2 * np.hypot(zz, xx)
        if not (r.max() <= _MAXRAD and z.max() <= _MAXRAD and z.min() >= -_MAXRAD):
            far = (r > _MAXRAD) | (np.abs(z) > _MAXRAD)
            # Far beyond the ellipsoid or overflowing: the earth is a point (GeographicLib).
            r_far = np.hypot(0.5 * x[far], 0.5 * y[far])
            lat[far] = np.arctan2(0.5 * z[far], r_far)
            h[far] = 2.0 * np.hypot(r_far, 0.5 * z[far])
    return lat, lon, h


def ecef2llh_fossen(p: Any, tol: float = 1e-12, max_iter: int = 100) -> tuple[Any, Any, Any]:
    """
    Return (lat, lon, h) of ECEF ``p`` (..., 3) by Fossen's iteration (Section 2.3.1, MSS).

    The textbook fixed-point iteration on the latitude, kept for reference and compared with
    :func:`ecef2llh` in the tests: lat_0 = atan2(z, r (1 - e^2)), then h = r / cos(lat) - R_E
    and lat = atan2(z, r (1 - e^2 R_E / (R_E + h))) until |delta lat| < ``tol`` (rad) or
    ``max_iter`` steps. Near the surface it converges to round-off; it divides by cos(lat)
    (wrong heights at and near the poles) and converges slowly or not at all deep inside the
    earth. Use :func:`ecef2llh`.
    """
    p = np.asarray(p, dtype=float)
    x = p[..., 0]
    y = p[..., 1]
    z = p[..., 2]
    lon = ssa(np.arctan2(np.atleast_1d(y), np.atleast_1d(x))).reshape(x.shape)
    r = np.hypot(x, y)
    with np.errstate(invalid='ignore', divide='ignore'):
        lat = np.arctan2(z, r * (1.0 - WGS84_E2))
        h = np.zeros_like(lat)
        for _ in range(max_iter):
            n = radius_prime_vertical(lat)
            h = r / np.cos(lat) - n
            lat_new = np.arctan2(z, r * (1.0 - WGS84_E2 * n / (n + h)))
            done = np.all(~(np.abs(lat_new - lat) >= tol))
            lat = lat_new
            if done:
                break
        n = radius_prime_vertical(lat)
        h = r / np.cos(lat) - n
    return to_output((lat, lon, h), p.ndim == 1)


# --- ECEF <-> NED ------------------------------------------------------------------------------

def rll(lon: Any, lat: Any) -> FloatArray:
    """
    Return R_n^e(lon, lat) (..., 3, 3), the rotation from NED to ECEF (Fossen eq. 2.84).

    R_n^e = R_z(lon) R_y(-lat - pi/2); v^e = R_n^e v^n. Columns are the north, east and down
    unit vectors in ECEF. Argument order (longitude first) as in Fossen's ``Rll(l, mu)``.
    """
    lon, lat = np.broadcast_arrays(np.asarray(lon, dtype=float), np.asarray(lat, dtype=float))
    cl, sl = np.cos(lon), np.sin(lon)
    cm, sm = np.cos(lat), np.sin(lat)
    out = np.empty(lon.shape + (3, 3))
    out[..., 0, 0] = -cl * sm
    out[..., 0, 1] = -sl
    out[..., 0, 2] = -cl * cm
    out[..., 1, 0] = -sl * sm
    out[..., 1, 1] = cl
    out[..., 1, 2] = -sl * cm
    out[..., 2, 0] = cm
    out[..., 2, 1] = 0.0
    out[..., 2, 2] = -sm
    return out


def _ned2ecef_rotate_scalar(n: float, e: float, d: float, lat: float,
                            lon: float) -> tuple[float, float, float]:
    """Return R_n^e (n, e, d) of floats (math kernel)."""
    cl, sl = math.cos(lon), math.sin(lon)
    cm, sm = math.cos(lat), math.sin(lat)
    t = -sm * n - cm * d      # horizontal (equatorial-plane) component along lon
    return cl * t - sl * e, sl * t + cl * e, cm * n - sm * d


def _ecef2ned_rotate_scalar(x: float, y: float, z: float, lat: float,
                            lon: float) -> tuple[float, float, float]:
    """Return (R_n^e)^T (x, y, z) of floats (math kernel)."""
    cl, sl = math.cos(lon), math.sin(lon)
    cm, sm = math.cos(lat), math.sin(lat)
    t = cl * x + sl * y
    return -sm * t + cm * z, -sl * x + cl * y, -cm * t - sm * z


def ned2ecef_velocity(v_ned: Any, lat: Any, lon: Any) -> Any:
    """
    Rotate NED vectors (e.g. velocity, m/s) at (lat, lon) (rad) into ECEF axes: R_n^e v^n.

    Fossen Section 2.3.1 (the velocity part of the NED-ECEF transformation); works for any free
    vector (velocity, acceleration, force). ``v_ned`` (..., 3) broadcasts with lat, lon.
    """
    out = np.einsum('...ij,...j->...i', rll(lon, lat), np.asarray(v_ned, dtype=float))
    return to_output(out, is_point(v_ned, 3) and one_point(lat, lon))


def ecef2ned_velocity(v_ecef: Any, lat: Any, lon: Any) -> Any:
    """Rotate ECEF vectors (..., 3) into the NED axes at (lat, lon) (rad): (R_n^e)^T v^e."""
    out = np.einsum('...ji,...j->...i', rll(lon, lat), np.asarray(v_ecef, dtype=float))
    return to_output(out, is_point(v_ecef, 3) and one_point(lat, lon))


def rotate_ned(v_ned: Any, lat: Any, lon: Any, lat0: Any, lon0: Any) -> Any:
    """
    Transport NED vectors from the local NED axes at (lat, lon) to the NED axes at (lat0, lon0).

    Returns R_n^e(lon0, lat0)^T R_n^e(lon, lat) v^n: e.g. a GNSS velocity given in the local
    NED frame of the receiver, expressed in the tangent-plane axes of the navigation origin.
    """
    v_e = np.einsum('...ij,...j->...i', rll(lon, lat), np.asarray(v_ned, dtype=float))
    out = np.einsum('...ji,...j->...i', rll(lon0, lat0), v_e)
    return to_output(out, is_point(v_ned, 3) and one_point(lat, lon, lat0, lon0))


def ecef2ned(p: Any, lat0: Any, lon0: Any, h0: Any) -> Any:
    """
    Return NED positions (..., 3) (m) of ECEF points ``p`` about the origin (lat0, lon0, h0).

    Exact tangent plane through ECEF (Fossen Section 2.3.2): p^n = (R_n^e)^T (p^e - p0^e) with
    R_n^e at the origin.
    """
    d = np.asarray(p, dtype=float) - _llh2ecef_array(lat0, lon0, h0)
    out = np.einsum('...ji,...j->...i', rll(lon0, lat0), d)
    return to_output(out, is_point(p, 3) and one_point(lat0, lon0, h0))


def ned2ecef(ned: Any, lat0: Any, lon0: Any, h0: Any) -> Any:
    """Return ECEF positions (..., 3) (m) of NED positions about (lat0, lon0, h0): the inverse."""
    out = (np.einsum('...ij,...j->...i', rll(lon0, lat0), np.asarray(ned, dtype=float))
           + _llh2ecef_array(lat0, lon0, h0))
    return to_output(out, is_point(ned, 3) and one_point(lat0, lon0, h0))


def llh2ned(lat: Any, lon: Any, h: Any, lat0: Any, lon0: Any, h0: Any) -> Any:
    """
    Return NED positions (..., 3) (m) of geodetic points about the origin (lat0, lon0, h0).

    Exact (through ECEF; Fossen 2.3.2): ecef2ned(llh2ecef(lat, lon, h), lat0, lon0, h0).
    Angles in rad, heights in m.
    """
    if one_point(lat, lon, h, lat0, lon0, h0):
        lat, lon, h, lat0, lon0, h0 = _floats(lat, lon, h, lat0, lon0, h0)
        x, y, z = _llh2ecef_scalar(lat, lon, h)
        x0, y0, z0 = _llh2ecef_scalar(lat0, lon0, h0)
        return _ecef2ned_rotate_scalar(x - x0, y - y0, z - z0, lat0, lon0)
    return ecef2ned(_llh2ecef_array(lat, lon, h), lat0, lon0, h0)


def ned2llh(ned: Any, lat0: Any, lon0: Any, h0: Any) -> tuple[Any, Any, Any]:
    """Return geodetic (lat, lon, h) (rad, rad, m) of NED positions (..., 3) about an origin."""
    if is_point(ned, 3) and one_point(lat0, lon0, h0):
        lat0, lon0, h0 = _floats(lat0, lon0, h0)
        x0, y0, z0 = _llh2ecef_scalar(lat0, lon0, h0)
        n, e, d = _floats(*ned)
        dx, dy, dz = _ned2ecef_rotate_scalar(n, e, d, lat0, lon0)
        return _ecef2llh_scalar(x0 + dx, y0 + dy, z0 + dz)
    return ecef2llh(np.asarray(ned2ecef(np.asarray(ned, dtype=float), lat0, lon0, h0)))


# --- flat-earth navigation ---------------------------------------------------------------------

def llh2flat(lat: Any, lon: Any, h: Any, lat0: Any, lon0: Any, h0: Any) -> Any:
    """
    Return flat-earth NED positions (..., 3) (m) about the origin (Fossen eqs. 2.105-2.108).

    x = (lat - lat0) R_N(lat0), y = ssa(lon - lon0) R_E(lat0) cos(lat0), z = h0 - h, with the
    meridian radius R_N and the prime-vertical radius R_E at the origin (the MSS code writes
    dmu / atan2(1, Rm); 1 / atan2(1, R) = R to a relative 1e-14, so R is used directly). The
    longitude difference is wrapped to (-pi, pi], so tracks across the antimeridian stay
    continuous. Accuracy against the exact tangent plane: see the module docstring.
    """
    if one_point(lat, lon, h, lat0, lon0, h0):
        lat, lon, h, lat0, lon0, h0 = _floats(lat, lon, h, lat0, lon0, h0)
        s0 = math.sin(lat0)
        w = 1.0 - WGS84_E2 * s0 * s0
        r_e = WGS84_A / math.sqrt(w)
        r_n = r_e * _E2M / w
        return ((lat - lat0) * r_n, ssa(lon - lon0) * r_e * math.cos(lat0), h0 - h)
    lat, lon, h, lat0, lon0, h0 = np.broadcast_arrays(
        *(np.asarray(a, dtype=float) for a in (lat, lon, h, lat0, lon0, h0)))
    s0 = np.sin(lat0)
    w = 1.0 - WGS84_E2 * s0 * s0
    r_e = WGS84_A / np.sqrt(w)
    r_n = r_e * _E2M / w
    return np.stack(((lat - lat0) * r_n, ssa(lon - lon0) * r_e * np.cos(lat0), h0 - h),
                    axis=-1)


def flat2llh(ned: Any, lat0: Any, lon0: Any, h0: Any) -> tuple[Any, Any, Any]:
    """
    Return (lat, lon, h) (rad, rad, m) of flat-earth NED positions (..., 3): the inverse.

    lat = lat0 + x / R_N(lat0), lon = lon0 + y / (R_E(lat0) cos(lat0)) wrapped to (-pi, pi],
    h = h0 - z (Fossen eqs. 2.105-2.108, MSS ``flat2llh``).
    """
    if is_point(ned, 3) and one_point(lat0, lon0, h0):
        lat0, lon0, h0 = _floats(lat0, lon0, h0)
        ned = _floats(*ned)
        s0 = math.sin(lat0)
        w = 1.0 - WGS84_E2 * s0 * s0
        r_e = WGS84_A / math.sqrt(w)
        r_n = r_e * _E2M / w
        return (lat0 + ned[0] / r_n, ssa(lon0 + ned[1] / (r_e * math.cos(lat0))),
                h0 - ned[2])
    ned = np.asarray(ned, dtype=float)
    lat0 = np.asarray(lat0, dtype=float)
    s0 = np.sin(lat0)
    w = 1.0 - WGS84_E2 * s0 * s0
    r_e = WGS84_A / np.sqrt(w)
    r_n = r_e * _E2M / w
    return (lat0 + ned[..., 0] / r_n, ssa(lon0 + ned[..., 1] / (r_e * np.cos(lat0))),
            h0 - ned[..., 2])


def _flat_error_table(distances: tuple[float, ...] = (100.0, 1e3, 1e4, 1e5),
                      lats_deg: tuple[float, ...] = (0.0, 30.0, 60.0, 80.0),
                      n_bearings: int = 72) -> list[tuple[float, float, float]]:
    """
    Return (d, max horizontal error, max down error) (m) of flat-earth vs the tangent plane.

    For each origin latitude and bearing, the point at horizontal tangent-plane distance d
    (on the tangent plane, at the origin's height h0 = 0) is mapped to LLH exactly
    (:func:`ned2llh`) and back with :func:`llh2flat`; the error is the difference to the
    tangent-plane NED. Used to produce the table in the module docstring.
    """
    table = []
    bearings = np.linspace(0.0, _TWO_PI, n_bearings, endpoint=False)
    for d in distances:
        worst_h = worst_v = 0.0
        for lat0_deg in lats_deg:
            lat0 = math.radians(lat0_deg)
            ned = np.stack((d * np.cos(bearings), d * np.sin(bearings),
                            np.zeros_like(bearings)), axis=-1)
            lat, lon, h = ned2llh(ned, lat0, 0.3, 0.0)
            flat = llh2flat(lat, lon, h, lat0, 0.3, 0.0)
            err = flat - ned
            worst_h = max(worst_h, float(np.max(np.hypot(err[:, 0], err[:, 1]))))
            worst_v = max(worst_v, float(np.max(np.abs(err[:, 2]))))
        table.append((d, worst_h, worst_v))
    return table

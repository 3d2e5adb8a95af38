"""
The sea surface in the map frame: where a surface vessel is, at any distance from the origin.

The map frame is the origin's tangent plane (NED, Fossen 2.3; or Fossen's flat earth with
``projection: flat``, eqs. 2.105-2.108). A surface vessel's horizontal position (N, E) in it is
a filter state; its height is not: the vessel lies on the sea surface, the ellipsoid raised by
the surface's ellipsoidal height h_s (:class:`SurfaceHeight`, from the fixes' own heights, else
the origin's). In the tangent plane that surface curves away below the plane, by d²/2R at a
distance d (0.8 m at 3.2 km, 785 m at 100 km), so the vessel's down coordinate is the surface's
there (:func:`surface_point`), not zero: every geodetic output stays on the fixes.

Far from the origin the vessel's own north and vertical turn away from the map's axes: by the
meridians' convergence γ about the vertical (:func:`convergence`: 0.5° at 10 km east at 45°
latitude) and by d/R in tilt. The heading that rotates the velocity into the map is ψ + γ, and
the attitude published in the map is q_m(lat, lon) ⊗ q (:func:`map_quaternion`). On flat earth the
meridians are the map's x lines: γ = 0 and the surface is D = h0 − h_s.
"""

from __future__ import annotations

import math

from vessel_kinematics.core import geodesy
from vessel_kinematics.core.quaternion import mul4
from vessel_kinematics.estimation.config import (Projection, SURFACE_HEIGHT_DRIFT,
                                                 SURFACE_HEIGHT_SIGMA)

__all__ = ['SurfaceHeight', 'convergence', 'map_quaternion', 'surface_point']

Origin = tuple[float, float, float]

#: Mean earth radius (m) for the first guess of the surface's drop below the tangent plane.
_EARTH_RADIUS = 6_371_000.0
#: The surface point's height is found to this (m): a tenth of a millimetre, one step within
#: tens of kilometres of the origin.
_HEIGHT_TOLERANCE = 1e-4


def surface_point(n: float, e: float, height: float, origin: Origin,
                  projection: Projection) -> tuple[float, float, float, float]:
    """
    Return (d, lat, lon, h): the map-down coordinate of the surface at map (n, e) and its LLH.

    The point at ellipsoidal height ``height`` (m) whose map horizontal coordinates are n, e
    (m): on the tangent plane found by Newton steps along the map's down axis, each moving the
    height by (h − height) cos(d/R) (three steps reach a micrometre at 300 km); on flat earth
    d = h0 − height in closed form.
    """
    lat0, lon0, h0 = origin
    if projection == Projection.FLAT:
        d = h0 - height
        lat, lon, h = geodesy.flat2llh((n, e, d), lat0, lon0, h0)
        return d, float(lat), float(lon), float(h)
    d = (n * n + e * e) / (2.0 * _EARTH_RADIUS) + (h0 - height)
    for _ in range(6):
        lat, lon, h = geodesy.ned2llh((n, e, d), lat0, lon0, h0)
        step = h - height
        if abs(step) < _HEIGHT_TOLERANCE:
            break
        d += step
    return d, float(lat), float(lon), float(height)


def convergence(lat: float, lon: float, origin: Origin, projection: Projection) -> float:
    """
    Return γ (rad): the direction of the vessel's north in the map (clockwise from the map's x).

    γ = atan2(n·E₀, n·N₀) with n the local north at (lat, lon) and N₀, E₀ the map's axes, all
    in ECEF: γ = atan2(−sin φ sin Δλ, sin φ sin φ₀ cos Δλ + cos φ cos φ₀). Zero on flat earth.
    """
    if projection == Projection.FLAT:
        return 0.0
    lat0, lon0, _ = origin
    dlon = lon - lon0
    s = math.sin(lat)
    return math.atan2(-s * math.sin(dlon),
                      s * math.sin(lat0) * math.cos(dlon) + math.cos(lat) * math.cos(lat0))


def _q_ne(lat: float, lon: float) -> tuple[float, float, float, float]:
    """Return the unit quaternion of R_n^e(lon, lat) = R_z(lon) R_y(−lat − π/2) (eq. 2.84)."""
    a, b = 0.5 * lon, 0.5 * (-lat - 0.5 * math.pi)
    ca, sa, cb, sb = math.cos(a), math.sin(a), math.cos(b), math.sin(b)
    return ca * cb, -sa * sb, ca * sb, sa * cb


def map_quaternion(lat: float, lon: float, origin: Origin,
                   projection: Projection) -> tuple[float, float, float, float]:
    """
    Return q_m, the rotation local NED -> map NED: R_m = R_n^e(origin)ᵀ R_n^e(lat, lon).

    q_m = q(R_n^e(origin))* ⊗ q(R_n^e(lat, lon)); the identity on flat earth (its axes are the
    local ones by construction).
    """
    if projection == Projection.FLAT:
        return 1.0, 0.0, 0.0, 0.0
    w, x, y, z = _q_ne(origin[0], origin[1])
    return mul4((w, -x, -y, -z), _q_ne(lat, lon))


class SurfaceHeight:
    """
    The sea surface's ellipsoidal height h_s (m) at the vessel and its variance (m²).

    A random walk of density :data:`~.config.SURFACE_HEIGHT_DRIFT` (the tide, the geoid's slope)
    measured by each fix's height of the base, of variance the fix's vertical one plus the
    waves' :data:`~.config.SURFACE_HEIGHT_SIGMA`²; a height more than 5σ off is left out (a
    receiver's altitude jump). Until a fix gives a height it is the origin's, σ = the waves'.
    """

    __slots__ = ('height', 'variance', 't_ns', 'measured')

    def __init__(self, height: float) -> None:
        self.height = height
        self.variance = SURFACE_HEIGHT_SIGMA ** 2
        self.t_ns: int | None = None
        self.measured = False

    def update(self, t_ns: int, height: float, variance: float) -> None:
        """Take a fix's height of the base (m) and its variance (m²) at ``t_ns``."""
        if self.t_ns is not None and t_ns > self.t_ns:
            self.variance += SURFACE_HEIGHT_DRIFT ** 2 * (t_ns - self.t_ns) * 1e-9
        self.t_ns = t_ns if self.t_ns is None else max(self.t_ns, t_ns)
        r = variance + SURFACE_HEIGHT_SIGMA ** 2
        if not self.measured:
            self.height, self.variance, self.measured = height, r, True
            return
        s = self.variance + r
        y = height - self.height
        if y * y > 25.0 * s:
            return
        k = self.variance / s
        self.height += k * y
        self.variance *= 1.0 - k
